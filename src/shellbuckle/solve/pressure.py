"""Pressure control: minimize the enthalpy ``G = E + p V`` at a fixed external overpressure.

Instead of holding the enclosed volume, the shell sits in a medium whose pressure exceeds the
inner one by ``p`` (positive compresses). The equilibria are the stationary points of
``G(x) = E(x) + p V(x)``: ``grad E = -p grad V``, the same condition as the volume-controlled
problem with multiplier ``lam = -p``, so ``pressure = p`` is reported with the same sign
convention (``-dE/dV``). Beyond the buckling pressure no nearby minimum exists and the shell
snaps through; the minimizer then follows the collapse until ``max_iter``.

Method: Newton on ``G`` with the six rigid-motion dofs pinned (as in
:mod:`~shellbuckle.solve.gauge`), the inertia of the Hessian read from its ``L D L^T``
factorization, a Levenberg–Marquardt shift ``mu I`` increased until the shifted Hessian is
positive definite when it is not, and Armijo backtracking on ``G``. Convergence:
``|grad G| <= tol_grad |grad E| + atol_grad`` and inertia 0.
"""

from __future__ import annotations

import logging
import time

import numpy as np
import scipy.sparse as sp

from .linear import SingularFactorError, make_solver
from .linesearch import backtracking
from .listen import accepted
from .gauge import pinned_dofs
from .result import MinimizeResult

log = logging.getLogger(__name__)

#: The largest shift tried, relative to the largest diagonal entry of the Hessian: beyond it the
#: step would be a vanishing gradient step, and a matrix that no such shift makes positive
#: definite holds non-finite or absurd entries (a state far outside the physical domain).
MAX_SHIFT = 1e12


def minimize_at_pressure(energy, volume, X0, pressure: float, *, tol_grad: float = 1e-8,
                         atol_grad: float = 1e-10, max_iter: int = 200, solver=None,
                         max_step: float | None = None) -> MinimizeResult:
    """Minimize ``E + p V`` from ``X0 (V, 3)``; returns a :class:`MinimizeResult` with
    ``pressure = p``. ``max_step`` caps the largest vertex displacement of a step (default: a
    tenth of the shell's size)."""
    p = float(pressure)
    if not np.isfinite(p):
        raise ValueError(f"pressure must be a finite number, got {pressure!r}")
    t_start = time.perf_counter()
    X = np.array(X0, dtype=float)
    n = X.size
    free = np.setdiff1d(np.arange(n), pinned_dofs(X))
    linsolver = make_solver(solver)
    size = float(np.ptp(X, axis=0).max())
    max_step = 0.1 * size if max_step is None else float(max_step)

    def enthalpy(Y):
        return energy.value(Y) + p * volume.value(Y)

    G = enthalpy(X)
    mu, inertia, success, message = 0.0, None, False, "maximum number of iterations reached"
    nit = 0  # accepted Newton steps (the same count the listener hears)
    for _ in range(max_iter):
        gE = energy.gradient(X).ravel()
        g = gE + p * volume.gradient(X).ravel()
        g[np.setdiff1d(np.arange(n), free)] = 0.0
        gnorm = float(np.linalg.norm(g))
        H = (energy.hessian(X) + p * volume.hessian(X)).tocsr()[free][:, free]
        try:
            linsolver.factor(H)
            inertia = linsolver.inertia()[1]
        except SingularFactorError:  # a zero or non-finite pivot: shifted as if indefinite
            inertia = None
        if gnorm <= tol_grad * np.linalg.norm(gE) + atol_grad and inertia == 0:
            success, message = True, "converged"
            break
        scale = float(abs(H.diagonal()).max()) if H.shape[0] else 0.0
        shift = 0.0 if inertia == 0 else max(mu / 3.0, 1e-8 * scale)
        if not np.isfinite(shift):
            message = "the Hessian is not finite"
            break
        limit = MAX_SHIFT * max(scale, 1.0)
        while 0.0 < shift <= limit:
            try:
                linsolver.factor(H + shift * sp.eye(H.shape[0], format="csr"))
                if linsolver.inertia()[1] == 0:
                    break
            except SingularFactorError:
                pass
            shift *= 8.0
        if shift > limit:
            message = "no shift of the Hessian makes it positive definite"
            break
        mu = shift
        step = np.zeros(n)
        step[free] = -linsolver.solve(g[free])
        largest = float(np.linalg.norm(step.reshape(-1, 3), axis=1).max())
        alpha0 = min(1.0, max_step / largest) if largest > 0 else 1.0
        slope = float(g @ step)
        if slope >= 0:  # not a descent direction: fall back to steepest descent
            step, slope = -g, -gnorm ** 2
            alpha0 = min(1.0, max_step / max(float(np.abs(step).max()), 1e-300))

        def phi(alpha):
            Y = X + alpha * step.reshape(X.shape)
            return enthalpy(Y), Y

        found = backtracking(phi, G, slope, alpha0)
        if found is None:
            message = "line search failed"
            break
        _, G_new, X = found
        nit += 1
        log.debug("pressure newton %d: G = %.12g, |grad G| = %.3e, inertia %s, mu %.2e",
                  nit, G_new, gnorm, inertia, mu)
        G = G_new
        accepted(G, gnorm)
    E = float(energy.value(X))
    return MinimizeResult(
        x=X, fun=E, grad_norm=float(np.linalg.norm((energy.gradient(X) + p * volume.gradient(X)))),
        nit=nit, success=success, message=message, pressure=p, volume_error=0.0,
        inertia=inertia, method="newton-pressure", history=None,
        timings={"total": time.perf_counter() - t_start})
