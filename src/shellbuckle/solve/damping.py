"""Damping of Newton's steps: the Levenberg–Marquardt shift, its trust-region update, the
search along a damped step and along negative curvature.

The tangent Hessian is shifted, ``K + mu I``, for two reasons.

1. Where it is indefinite (or singular) the shift is raised, x4 from ``1e-4 mean|diag K|`` or
   from the current one, until the factorization's inertia shows ``K + mu I`` positive definite
   on the tangent space (:func:`factor_positive`; a modified Newton method, Nocedal & Wright,
   *Numerical Optimization*, 2nd ed., §3.4); the shifted step is then a descent step.
2. Along very soft modes (after buckling the position of a dent is pinned only by the mesh)
   the energy is far from quadratic and undamped steps overshoot. ``mu`` is adapted as in a
   trust-region / Levenberg–Marquardt method by the ratio ``rho`` of the actual to the
   predicted decrease of the step (Moré, Lecture Notes in Math. 630, 105 (1978); Nocedal &
   Wright §4.1, §10.3): :func:`damping_next` and :func:`damping_after`.

:func:`newton_search` backtracks along the damped step (stretching a good damped step while
the energy falls, which sets the next shift) and, at a saddle, searches a direction of negative
curvature with Moré & Sorensen's curvilinear test (Math. Prog. 16, 1 (1979)); the lower energy
wins, so the method leaves a saddle even where the gradient vanishes exactly.
"""

from __future__ import annotations

import numpy as np

from .linesearch import (ENERGY_NOISE, RestoredPath, backtracking, curvature_search,
                         max_displacement, projected_gradient)


def factor_positive(system, mu: float, escape_saddles: bool, approximate: bool = False):
    """Factor ``system`` (:class:`~.system.KKTSystem`) with shift ``mu``; if the tangent Hessian
    plus shift is not positive definite (and saddles are escaped), raise the shift (x4, from
    ``1e-4 mean|diag K|`` when ``mu = 0``) until it is.

    Returns ``(mu, inertia, indefinite)``: ``inertia`` is the number of negative eigenvalues of
    the tangent Hessian when ``mu = 0`` was factored in double precision (else ``None``: an
    ``approximate`` factorization's inertia only guides the shift, it is never reported nor
    used to certify a minimum) and ``indefinite`` whether the tangent Hessian is known to have
    one; ``None`` if no shift up to ``1e12 mean|diag K|`` works, or if that bound or ``mu`` is
    not finite (a Hessian that overflowed: no shift is defined)."""
    limit = 1e12 * system.diag_scale
    if not (np.isfinite(mu) and np.isfinite(limit)):
        return None
    ok, inertia = system.factor(mu, approximate)
    if mu > 0.0:
        inertia0, indefinite = None, not (ok and inertia in (0, None))
    else:
        inertia0, indefinite = inertia, bool(ok and inertia is not None and inertia > 0)
    if approximate:
        inertia0 = None
    if ok and (not escape_saddles or inertia in (0, None)):
        return mu, inertia0, indefinite
    mu = 4.0 * mu if mu > 0.0 else 1e-4 * system.diag_scale
    while mu <= limit:
        ok, inertia = system.factor(mu, approximate)
        if ok and (not escape_saddles or inertia in (0, None)):
            return mu, inertia0, indefinite
        mu *= 4.0
    return None


def damping_next(mu: float, curv_s: float, kind: str, alpha: float, rho: float) -> float:
    """Levenberg–Marquardt shift for the next iteration from the step just accepted.

    ``rho`` is the ratio of the actual to the predicted decrease of the full step. A step cut
    by the line search to ``alpha < 1``, or stretched to ``alpha > 1`` (a damped step whose
    model was good, see :func:`newton_search`), sets the shift that would have given that
    length along the step's own direction; otherwise a good model (``rho > 0.75``) divides the
    shift by 4 and a poor one (``rho < 0.25``) doubles the step's shifted curvature. A shift
    below ``1e-3`` times the curvature along the step is dropped (pure Newton). A full step
    whose predicted decrease is below the energy's noise (``rho`` NaN: near a minimum, where
    the model is good) divides the shift by 4 too, so that the tail converges quadratically.
    Steps other than Newton's (``kind``) leave it unchanged.
    """
    if kind != "newton":
        return mu
    if not np.isfinite(rho):
        if alpha != 1.0:
            return mu
        rho = 1.0
    if alpha != 1.0:
        mu = damping_after(mu, curv_s, alpha)
    elif rho > 0.75:
        mu = mu / 4.0
    elif rho < 0.25:
        mu = damping_after(mu, curv_s, 0.5)
    return 0.0 if mu <= 1e-3 * max(curv_s, 0.0) else mu


def damping_after(mu: float, curv_s: float, factor: float) -> float:
    """The shift that scales a step along its own direction by ``factor``: with
    ``q = s.K s / s.s`` the curvature along the step (computed with shift ``mu``),
    ``(q + mu) / (q + mu') = factor``. A shortening (``factor < 1``) at least doubles it."""
    target = max(curv_s + mu, 0.0) / factor - curv_s
    if factor < 1.0:
        return float(max(target, 2.0 * mu, np.finfo(float).tiny))
    return float(max(target, 0.0))


def newton_search(energy, volume, X, V_target, E, r, s, slope_s, curv_s, d, curv_d, max_step,
                  edge, r_norm, extend=False):
    """Backtracking on the (shifted) Newton step ``s`` and, if given, a curvature search along
    the negative-curvature direction ``d``; returns ``(kind, alpha, E, X, rho)`` of the lower
    energy (``kind`` ``"newton"`` or ``"curvature"``), ``rho`` the ratio of the actual to the
    predicted decrease (quadratic model ``alpha r.s + alpha^2/2 s.K s``) of the Newton step at
    the accepted ``alpha``; ``None`` if neither search finds a decrease.

    With ``extend`` (a damped step), a full step whose decrease is at least 0.9 of the
    prediction is doubled while the energy keeps falling (at most three times, within
    ``max_step``): in a soft valley the damped direction is right and only its length is too
    short, and the length found sets the next shift.

    When the predicted decrease ``-r.s`` is below the energy's evaluation noise
    (``ENERGY_NOISE |E|``), a full step is accepted if the energy stays within that noise and
    the projected gradient decreases (see :mod:`.linesearch`). The curvature search starts at
    the Newton step's length or half the mean edge length ``edge``, whichever is longer."""
    candidates = []
    alpha0 = min(1.0, max_step / max(max_displacement(s), np.finfo(float).tiny))
    noise = ENERGY_NOISE * abs(E)
    ss = float(np.einsum("ij,ij->", s, s))

    def ratio(alpha, E1):
        predicted = -(alpha * slope_s + 0.5 * alpha * alpha * curv_s * ss)
        return (E - E1) / predicted if predicted > noise else np.nan

    if d is None and -slope_s <= noise:
        E1, X1 = RestoredPath(energy, volume, X, s, V_target)(alpha0)
        if X1 is not None and E1 <= E + noise:
            r1 = projected_gradient(energy.gradient(X1), volume.gradient(X1))[1]
            if np.linalg.norm(r1) < r_norm:
                return "newton", alpha0, E1, X1, np.nan
    path = RestoredPath(energy, volume, X, s, V_target)
    found = backtracking(path, E, slope_s, alpha0)
    if found is not None:
        alpha, E1, X1 = found
        rho = ratio(alpha, E1)
        if extend and alpha == 1.0 and rho > 0.9:
            for _ in range(3):
                if 2.0 * alpha * max_displacement(s) > max_step:
                    break
                E2, X2 = path(2.0 * alpha)
                if X2 is None or not E2 < E1 or E2 > E + 1e-4 * 2.0 * alpha * slope_s:
                    break
                alpha, E1, X1 = 2.0 * alpha, E2, X2
        candidates.append(("newton", alpha, E1, X1, rho))
    if d is not None:
        slope_d = float(np.einsum("ij,ij->", r, d))
        if slope_d > 0 or (slope_d == 0 and d.ravel()[np.argmax(np.abs(d))] < 0):
            d, slope_d = -d, -slope_d
        length0 = max(alpha0 * max_displacement(s), 0.5 * edge)
        found = curvature_search(RestoredPath(energy, volume, X, d, V_target), E, slope_d,
                                 curv_d, min(length0, max_step), max_alpha=max_step)
        if found is not None:
            candidates.append(("curvature",) + found + (np.nan,))
    if not candidates:
        return None
    return min(candidates, key=lambda c: c[2])
