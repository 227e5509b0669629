"""Preconditioned L-BFGS relaxation before Newton's method, and the smooth start.

A jiggle leaves a shell far above its minimum with many negative eigenvalues of the Hessian;
started there, the shifted Newton method spends most of its factorizations removing that
roughness. The roughness is the stiff part of the perturbation, which the Hessian of the
relaxed state the jiggle started from (``X_ref``) describes well. :func:`relax` therefore
takes L-BFGS steps (Nocedal & Wright, *Numerical Optimization*, 2nd ed., Algorithm 7.4) whose
initial inverse Hessian ``H0`` is the tangent KKT solve with ``K(X_ref) + mu I``,
``mu = relax_shift mean|diag K|``: one factorization serves every step, and the shift keeps
the soft modes (those along which a dent forms or slides) from dominating the steps, so that
they relax as in a gradient flow. When the energy falls by less than ``relax_tol`` relative
over ``relax_window`` steps, Newton's method takes over.

The relaxation starts in a rough stage with the larger shift ``relax_rough_shift mean|diag
K|``, which damps the soft components of the first, huge forces, and factors again with
``relax_shift`` once ``relax_rough_full`` consecutive steps were taken in full (or the energy
test holds); the secant pairs are kept (they describe the energy, not the preconditioner).
The rough stage runs only for a start between ``relax_rough_min_move`` and
``relax_rough_max_move`` mean edge lengths (rms) from ``X_ref``: farther, the mesh is tangled
and the stage's local full steps lock the tangles in. After it, ``H0`` is scaled by ``tau``
as L-BFGS scales its initial matrix (Nocedal & Wright §7.2): after each
step ``tau`` is multiplied by the minimizer of the parabola through the energy, the slope and
the accepted point along the step (:func:`rescaled`), so the steps are taken in full.

A start closer than ``relax_rough_min_move`` to ``X_ref`` (no jiggle, or a small one) has
nothing rough to remove (:func:`smooth_start`): unless Newton's ``smooth_start`` is off (the
protocol turns it off for a start with a jiggle, however small), its first steps are
quasi-Newton steps whose ``H0`` is the unshifted Hessian of the Lagrangian at ``X_ref``
(:func:`exact_preconditioner`), the factorization that certified that minimum if the solver
still holds it, else the same matrix factored again (the same bits, so a resumed run repeats
an uninterrupted one); with it off, such a start is relaxed, without the rough stage.
"""

from __future__ import annotations

import logging

import numpy as np

from .damping import factor_positive
from .lbfgs import SecantPairs
from .linesearch import mean_edge_length, parabola_minimizer, quasi_newton_search
from .listen import accepted
from .workspace import Factorization

log = logging.getLogger(__name__)


def move(volume, X: np.ndarray, X_ref: np.ndarray) -> float:
    """How far ``X`` lies from ``X_ref``: the root mean square over the vertices of their
    displacements, in mean edge lengths of ``X_ref``."""
    rms = float(np.sqrt(np.mean(np.sum((X - X_ref) ** 2, axis=1))))
    return rms / mean_edge_length(np.asarray(volume.faces), X_ref)


def smooth_start(volume, X: np.ndarray, X_ref: np.ndarray, min_move: float) -> bool:
    """Whether ``X`` lies closer to ``X_ref`` than ``min_move`` mean edge lengths (rms,
    :func:`move`): such a start is not relaxed at all where Newton's ``smooth_start`` is on."""
    return move(volume, X, X_ref) < min_move


def exact_preconditioner(system, X_ref: np.ndarray, token, single: bool = False):
    """The factorization that certifies the Hessian of the Lagrangian at ``X_ref`` positive
    definite on the tangent space, for the first quasi-Newton steps of a smooth start:
    ``token`` if the workspace still holds it and it was made at exactly ``X_ref`` with this
    energy, else a new one (``single``: a single-precision certificate where it holds, else
    unshifted in double precision); ``None`` where that matrix has a negative direction."""
    if (isinstance(token, Factorization) and token.definite_for(system.raw_energy)
            and token.X is not None and np.array_equal(token.X, X_ref)
            and system.workspace.holds(token, system.kkt)):
        return token
    lam, _, _, gV = system.gradients(X_ref)
    system.assemble(X_ref, lam, gV)
    if single and system.certify_single():
        return system.token
    ok, inertia = system.factor(0.0)
    return system.token if ok and inertia == 0 else None


def rescaled(tau: float, E: float, E_new: float, slope: float, alpha: float) -> float:
    """The next scale of an L-BFGS initial inverse Hessian: ``tau`` times the minimizer
    (clipped to [0.1, 2]; ``2 alpha`` where it is not convex) of the parabola through
    ``(0, E)`` with slope ``slope`` and the accepted point ``(alpha, E_new)`` of the step it
    gave (:func:`~.linesearch.parabola_minimizer`), within [1e-3, 1]."""
    best = parabola_minimizer(alpha, E_new, E, slope)
    if best is None:
        best = 2.0 * alpha
    return float(np.clip(tau * min(max(best, 0.1), 2.0), 1e-3, 1.0))


def relax(system, X, E, X_ref, options, max_step, abandon=None):
    """Preconditioned relaxation (module docstring) of ``system``'s problem from ``X`` (energy
    ``E``) with the Hessian at ``X_ref``, raised x4 until positive definite on the tangent
    space, and the relaxation options of ``options`` (:class:`~.options.NewtonOptions`):
    until the energy test holds, the projected gradient has converged (``tol_grad``,
    ``atol_grad``), a step fails, or ``max_iter // 2`` steps. After ``relax_ask_steps``
    consecutive steps cut below ``relax_ask_alpha`` of their length, ``abandon(X)`` is asked,
    and a reason ends the relaxation (Newton's method then asks again and stops).
    Returns ``(X, E, steps, history records)``."""
    o = options
    energy, volume, V_target = system.energy, system.volume, system.V_target
    rough, shift = o.relax_rough_shift, o.relax_shift
    distance = move(volume, X, X_ref)
    rough = (rough if rough > shift and o.relax_rough_min_move <= distance <= o.relax_rough_max_move
             else None)
    lam, r, gE, gV = system.gradients(X_ref)
    system.assemble(X_ref, lam, gV)
    if factor_positive(system, (rough or shift) * system.diag_scale, escape_saddles=True,
                       approximate=True) is None:
        return X, E, 0, []
    pairs, previous, energies, records = SecantPairs(X.size, o.relax_memory), None, [E], []
    n, full, cut, tau = 0, 0, 0, 1.0
    while n < o.max_iter // 2:
        if rough is not None and full >= o.relax_rough_full:
            rough, energies = None, [E]
            if factor_positive(system, shift * system.diag_scale, escape_saddles=True,
                               approximate=True) is None:
                break
        lam, r, gE, gV = system.gradients(X)
        r_norm = float(np.linalg.norm(r))
        if r_norm <= o.tol_grad * float(np.linalg.norm(gE)) + o.atol_grad:
            break
        if previous is not None:
            pairs.add(X - previous[0], r - previous[1])
        verr = volume.value(X) - V_target
        quasi = (system.quasi_newton_step(X, r, pairs, verr, tau)
                 or system.quasi_newton_step(X, r, None, verr, tau))
        if quasi is None:
            break
        with system.clock("line_search"):
            found = quasi_newton_search(energy, volume, X, V_target, E, r_norm, *quasi, max_step)
        if found is None:
            break
        alpha, E_new, X_new = found
        full = full + 1 if alpha == 1.0 else 0
        # a cut step is judged against the unscaled step's length (the abandon test below)
        cut = cut + 1 if alpha * tau < o.relax_ask_alpha else 0
        if o.relax_scaling and rough is None:
            tau = rescaled(tau, E, E_new, quasi[1], alpha)
        previous, X, E = (X, r), X_new, E_new
        n += 1
        accepted(E, r_norm)
        energies.append(E)
        if o.history:
            records.append(dict(iteration=n - 1, energy=E, grad_norm=r_norm, lam=lam,
                                inertia=None, mu=np.nan, step="relax", alpha=alpha, rho=np.nan))
        if abandon is not None and cut >= o.relax_ask_steps and abandon(X):
            break
        if len(energies) > o.relax_window and \
                energies[-1 - o.relax_window] - E <= o.relax_tol * abs(E):
            if rough is None:
                break
            full = o.relax_rough_full  # the rough stage has done what it can
    log.debug("preconditioned relaxation: %d steps, E=%.15g", n, E)
    return X, E, n, records
