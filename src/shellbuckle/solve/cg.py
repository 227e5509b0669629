"""Projected gradient descent and nonlinear conjugate gradient on the constraint surface.

Minimize ``E(x)`` subject to ``V(x) = V_target`` with first derivatives only, as Surface
Evolver's ``g`` (gradient descent) and ``U`` (conjugate gradient) commands do. At each
iterate (kept on the constraint surface by :func:`~.linesearch.restore_volume`):

- ``r = grad E - lam grad V`` with the least-squares multiplier ``lam`` (the gradient projected
  on the tangent space);
- direction ``p = -r`` (gradient descent) or ``p = -r + beta P p_prev`` (Polak–Ribière+,
  ``beta = max(0, r.(r - r_prev) / |r_prev|^2)``; ``P`` projects on the current tangent
  space), restarted with ``-r`` when ``p`` is not a descent direction or successive gradients
  are far from orthogonal (Powell: ``|r . r_prev| >= 0.2 |r|^2``); Nocedal & Wright,
  *Numerical Optimization*, 2nd ed., §5.2;
- a line search on the restored path (:func:`~.linesearch.secant_search`: Armijo
  backtracking, then secant steps on the slope computed from gradients), initial step from
  the previous one (Nocedal & Wright eq. 3.60).

Convergence uses the same criteria as :func:`~.newton.newton` (projected gradient relative
to ``|grad E|`` plus ``atol_grad``, and energy change), with ``tol_energy`` the change of one
step. First-order methods need many iterations on the stiff membrane problem; they are meant
for cheap relaxation before Newton (``minimize(method="alternate")``) and for checks.
The result's ``pressure`` is ``-lam`` (Surface Evolver's body pressure is ``lam``), and the
inertia is not computed (``None``).
"""

from __future__ import annotations

import logging
import time

import numpy as np

from .linesearch import (RestoredPath, check_problem, mean_edge_length, projected_gradient,
                         restore_volume, secant_search)
from .listen import accepted
from .result import MinimizeResult

log = logging.getLogger(__name__)


def conjugate_gradient(energy, volume, X0, V_target, *, tol_grad: float = 1e-8,
                       atol_grad: float = 1e-10, tol_energy: float = 1e-14,
                       max_iter: int = 5000, conjugate: bool = True, history: bool = False,
                       initial_displacement: float = 0.01) -> MinimizeResult:
    """Polak–Ribière+ conjugate gradient (``conjugate=True``) or steepest descent at fixed
    volume. ``initial_displacement`` is the largest vertex displacement of the first trial
    step, as a fraction of the mean edge length. See the module docstring."""
    t_start = time.perf_counter()
    method = "cg" if conjugate else "gd"
    X, V_target = check_problem(X0, V_target)
    X, verr = restore_volume(volume, X, V_target)
    if not verr <= 1e-12:
        raise ValueError(f"cannot bring X0 to V_target={V_target!r} along the volume gradient "
                         f"(relative volume error {verr:.1e})")
    E = energy.value(X)
    edge = mean_edge_length(np.asarray(volume.faces), X)
    p_prev = r_prev = None
    alpha_prev = slope_prev = None
    dE, nit, records = None, 0, []
    success, message = False, ""
    t_search = 0.0
    gE, gV = energy.gradient(X), volume.gradient(X)
    stalled = 0
    for k in range(max_iter + 1):
        lam, r = projected_gradient(gE, gV)
        rr = float(np.einsum("ij,ij->", r, r))
        r_norm = np.sqrt(rr)
        if r_norm <= tol_grad * float(np.linalg.norm(gE)) + atol_grad and (
                dE is None or abs(dE) <= tol_energy * abs(E)):
            success, message = True, "converged"
            break
        if k == max_iter:
            message = f"maximum number of iterations ({max_iter}) reached"
            break
        p = -r
        if conjugate and p_prev is not None:
            rr_prev = float(np.einsum("ij,ij->", r_prev, r_prev))
            cross = float(np.einsum("ij,ij->", r, r_prev))
            if abs(cross) < 0.2 * rr:
                beta = max(0.0, (rr - cross) / rr_prev)
                n = gV / np.linalg.norm(gV)
                transported = p_prev - np.einsum("ij,ij->", p_prev, n) * n
                p = -r + beta * transported
        slope = float(np.einsum("ij,ij->", r, p))
        if not slope < 0:
            p, slope = -r, -rr
        if alpha_prev is None:
            alpha0 = initial_displacement * edge / np.sqrt(np.einsum("ij,ij->i", p, p).max())
        else:
            alpha0 = alpha_prev * slope_prev / slope
        def slope_at(Y, p=p):
            gE_y, gV_y = energy.gradient(Y), volume.gradient(Y)
            return float(np.einsum("ij,ij->", projected_gradient(gE_y, gV_y)[1], p)), (gE_y, gV_y)

        t0 = time.perf_counter()
        found = secant_search(RestoredPath(energy, volume, X, p, V_target), slope_at, E, slope,
                              alpha0)
        t_search += time.perf_counter() - t0
        if found is None:
            if p_prev is not None:  # retry once along steepest descent
                p_prev = None
                gE, gV = energy.gradient(X), volume.gradient(X)
                continue
            success = bool(r_norm <= 100 * (tol_grad * float(np.linalg.norm(gE)) + atol_grad))
            message = ("converged (no further decrease within round-off)" if success
                       else "line search failed to decrease the energy")
            break
        alpha, E_new, X, (gE, gV) = found
        dE, E = E_new - E, E_new
        stalled = stalled + 1 if abs(dE) <= 1e-14 * abs(E) else 0
        if stalled >= 20:
            lam, r = projected_gradient(gE, gV)
            r_norm = float(np.linalg.norm(r))
            success = bool(r_norm <= 100 * (tol_grad * float(np.linalg.norm(gE)) + atol_grad))
            message = ("converged (energy stationary within round-off for 20 steps)" if success
                       else "stalled: energy stationary within round-off for 20 steps")
            nit += 1
            accepted(E, r_norm)
            break
        p_prev, r_prev, alpha_prev, slope_prev = p, r, alpha, slope
        nit += 1
        accepted(E, r_norm)
        if history:
            records.append(dict(iteration=k, energy=E, grad_norm=r_norm, lam=lam, alpha=alpha))
        if k % 100 == 0:
            log.debug("%s %5d  E=%.15g  |r|=%.3e  lam=%.9g", method, k, E, r_norm, lam)
    volume_error = abs(volume.value(X) - V_target) / V_target
    log.info("%s: %s after %d iterations, E=%.15g, |r|=%.3e, pressure=%.9g",
             method, message, nit, E, r_norm, -lam)
    return MinimizeResult(x=X, fun=E, grad_norm=float(r_norm), nit=nit, success=success,
                          message=message, pressure=-lam, volume_error=volume_error,
                          inertia=None, method=method, history=records if history else None,
                          timings=dict(line_search=t_search, total=time.perf_counter() - t_start))


def gradient_descent(energy, volume, X0, V_target, **options) -> MinimizeResult:
    """Projected steepest descent at fixed volume (``conjugate_gradient(conjugate=False)``)."""
    return conjugate_gradient(energy, volume, X0, V_target, conjugate=False, **options)
