"""Volume restoration and line searches on the constraint surface ``V(x) = V_target``.

All minimizers in :mod:`shellbuckle.solve` are feasible methods: every iterate satisfies the
volume constraint to round-off. A trial point ``x + alpha p`` (``p`` tangent to the constraint)
is brought back onto the surface by :func:`restore_volume`, a move along the constraint normal
``n = grad V(x)`` at the trial point: ``V(x + t n)`` is an exact cubic in ``t``
(:meth:`~shellbuckle.energies.volume.Volume.along`), whose root next to the first-order
correction ``t = -(V(x) - V_target) / |n|^2`` is found by a scalar Newton iteration (for a
sphere the move is a uniform radial scaling; :meth:`~shellbuckle.energies.volume.Volume.restore`
runs the whole restoration compiled). Volumes without that cubic are restored by the
Newton iteration ``x <- x - (V(x) - V_target) grad V(x) / |grad V(x)|^2``. The energy along
the restored curve ``phi(alpha) = E(R(x + alpha p))`` is the merit function: its slope at 0
is ``r . p`` with ``r = grad E - lam grad V`` the projected gradient, and its curvature is
that of the Lagrangian ``Hess E - lam Hess V``, so a Newton step is accepted in full near a
minimum.

A step is accepted when it satisfies the Armijo condition
``phi(alpha) <= phi(0) + c1 alpha phi'(0) + slack`` where ``slack = ENERGY_ROUNDOFF |phi(0)|``
absorbs the round-off of an energy evaluation (without it the test is decided by noise once
the predicted decrease falls below ``1e-16 |E|``).

Close to a minimum the predicted decrease of a Newton step falls below the evaluation error of
the energy itself (shell energies are sums of large terms that nearly cancel, e.g.
``kappa/2 (4 M^2/A - 4 c0 M + c0^2 A)`` per vertex, so that error can reach ``1e-13 |E|``).
There the energy cannot rank two points, and the Newton method accepts a full step when the
energy changes by less than ``ENERGY_NOISE |E|`` and the projected gradient decreases (a
gradient-norm merit, as in Newton's method for the stationarity equations). Hence no
accepted step raises the energy at fixed volume by more than ``ENERGY_NOISE`` relative
(``ENERGY_ROUNDOFF`` for every step whose predicted decrease is resolvable).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..energies.kernels import face_side_lengths

log = logging.getLogger(__name__)

#: relative round-off allowance of one energy evaluation in the acceptance tests
ENERGY_ROUNDOFF = 1e-14

#: relative energy change below which energies are not compared (gradient merit instead)
ENERGY_NOISE = 1e-12


def restore_volume(volume, X: np.ndarray, V_target: float, *, rtol: float = 1e-15,
                   max_iter: int = 30) -> tuple[np.ndarray, float]:
    """Move ``X`` along the constraint normal until ``V(X) = V_target``.

    Returns ``(X, relative_error)`` (``X`` is a new array). A volume with a ``restore`` method
    (:meth:`~shellbuckle.energies.volume.Volume.restore`) does it itself: the root of the exact
    cubic along the normal of ``X`` (it leaves round-off), then at most two first-order
    corrections along that same normal, as one compiled loop (0.16 ms in a run on the paper's
    mesh, once per line-search trial). Any other volume (``value`` and
    ``gradient``) takes the Newton iteration of the module docstring, until
    ``|V - V_target| <= rtol |V_target|`` or until round-off stops the decrease (at most
    ``max_iter`` passes). The ``relative_error`` is then typically ``1e-16``; the caller
    decides what to do when it stays large (a trial point too far from the surface).
    """
    restore = getattr(volume, "restore", None)
    if restore is not None:
        return restore(X, V_target, rtol)
    X = np.array(X, dtype=np.float64)
    previous = np.inf
    err = np.inf
    for it in range(max_iter):
        residual = volume.value(X) - V_target
        err = abs(residual) / abs(V_target)
        if not np.isfinite(err):
            return X, np.inf
        if err <= rtol or (it >= 2 and err >= 0.5 * previous):
            break
        previous = err
        g = volume.gradient(X)
        gg = float(np.einsum("ij,ij->", g, g))
        if gg == 0.0:
            return X, np.inf
        X += (-residual / gg) * g
    return X, err


@dataclass
class RestoredPath:
    """``phi(alpha) = E(restore(x + alpha p))`` with the last evaluated point kept."""

    energy: object
    volume: object
    X: np.ndarray
    p: np.ndarray
    V_target: float
    volume_rtol: float = 1e-12
    n_evals: int = 0

    def __call__(self, alpha: float) -> tuple[float, np.ndarray | None]:
        self.n_evals += 1
        X, err = restore_volume(self.volume, self.X + alpha * self.p, self.V_target)
        if not err <= self.volume_rtol:
            return np.inf, None
        E = self.energy.value(X)
        if not np.isfinite(E):
            return np.inf, None
        return float(E), X


def _slack(E0: float) -> float:
    return ENERGY_ROUNDOFF * max(abs(E0), np.finfo(float).tiny)


def parabola_minimizer(alpha, E, E0, slope) -> float | None:
    """Minimizer of the parabola through ``(0, E0)`` with slope ``slope`` and ``(alpha, E)``;
    ``None`` when that parabola is not convex (or ``E`` is not finite)."""
    curv = E - E0 - slope * alpha
    if not np.isfinite(E) or curv <= 0:
        return None
    return -slope * alpha * alpha / (2.0 * curv)


def _interpolate(alpha, E, E0, slope, lo=0.1, hi=0.5):
    """:func:`parabola_minimizer` clamped to ``[lo alpha, hi alpha]`` (a safeguarded
    backtracking factor); ``hi alpha`` where the parabola is not convex."""
    best = parabola_minimizer(alpha, E, E0, slope)
    if best is None:
        return hi * alpha
    return float(np.clip(best, lo * alpha, hi * alpha))


def backtracking(phi, E0: float, slope: float, alpha0: float = 1.0, *, c1: float = 1e-4,
                 max_evals: int = 40):
    """Armijo backtracking with safeguarded quadratic interpolation.

    ``phi(alpha) -> (E, X)``; ``slope = phi'(0) < 0``. Returns ``(alpha, E, X)`` of the first
    acceptable point, or ``None`` when ``max_evals`` trials fail.
    """
    alpha, slack = alpha0, _slack(E0)
    for _ in range(max_evals):
        E, X = phi(alpha)
        if X is not None and E <= E0 + c1 * alpha * slope + slack:
            return alpha, E, X
        alpha = _interpolate(alpha, E, E0, slope)
    return None


def secant_search(phi, slope_at, E0: float, slope0: float, alpha0: float, *, c1: float = 1e-4,
                  max_evals: int = 20, max_growth: float = 4.0):
    """Approximate exact line search for CG and gradient descent.

    Backtracks to an Armijo point, then takes secant steps on the slope
    ``phi'(alpha) = slope_at(X(alpha))`` (from gradients, which stay accurate far below the
    round-off of energy differences, so the search keeps working close to a minimum): each
    secant point is accepted if its energy is not higher than the current one (within
    round-off), extrapolating by at most ``max_growth``. ``slope_at(X) -> (slope, extra)``;
    returns ``(alpha, E, X, extra)`` or ``None``.
    """
    found = backtracking(phi, E0, slope0, alpha0, c1=c1, max_evals=max_evals)
    if found is None:
        return None
    alpha, E, X = found
    slope, extra = slope_at(X)
    slack = _slack(E0)
    a_prev, s_prev = 0.0, slope0
    for _ in range(3):
        if abs(slope) <= 0.1 * abs(slope0):
            break
        if slope < 0 and slope <= s_prev:  # not flattening: extrapolate by the cap
            target = max_growth * alpha
        else:  # zero of the secant through (a_prev, s_prev) and (alpha, slope)
            target = alpha - slope * (alpha - a_prev) / (slope - s_prev)
            target = float(np.clip(target, 0.1 * alpha, max_growth * alpha))
        E_t, X_t = phi(target)
        if X_t is None or E_t > E + slack or E_t > E0 + c1 * target * slope0 + slack:
            break
        a_prev, s_prev = alpha, slope
        alpha, E, X = target, E_t, X_t
        slope, extra = slope_at(X)
    return alpha, E, X, extra


def curvature_search(phi, E0: float, slope: float, curvature: float, alpha0: float = 1.0, *,
                     c1: float = 1e-4, max_evals: int = 40, max_alpha: float = np.inf):
    """Line search along a direction of negative curvature (Moré & Sorensen, Math. Prog. 16,
    1 (1979)): accept ``alpha`` when ``phi(alpha) <= E0 + c1 (alpha slope + alpha^2 curvature/2)``
    with ``slope <= 0`` and ``curvature < 0``; expand (doubling, up to ``max_alpha``) while the
    energy keeps decreasing, else halve. Returns ``(alpha, E, X)`` or ``None``.
    """
    slack = _slack(E0)

    def ok(a, E):
        return E <= E0 + c1 * (a * slope + 0.5 * a * a * curvature) + slack

    alpha = min(alpha0, max_alpha)
    best = None
    evals = 0
    for _ in range(max_evals):
        evals += 1
        E, X = phi(alpha)
        if X is not None and ok(alpha, E):
            best = (alpha, E, X)
            break
        alpha *= 0.5
    if best is None:
        return None
    while 2 * best[0] <= max_alpha and evals < max_evals:
        alpha = 2 * best[0]
        evals += 1
        E, X = phi(alpha)
        if X is None or E >= best[1] or not ok(alpha, E):
            break
        best = (alpha, E, X)
    return best


def quasi_newton_search(energy, volume, X, V_target, E, r_norm, p, slope, max_step):
    """Armijo backtracking along a quasi-Newton step ``p`` (slope ``slope = r.p``), its first
    trial capped at ``max_step`` of vertex displacement; below the energy noise
    (``-slope <= ENERGY_NOISE |E|``) the full step is taken if the energy stays within the noise
    and the projected gradient falls below ``r_norm`` (module docstring). ``(alpha, E, X)`` or
    ``None``."""
    alpha0 = min(1.0, max_step / max(max_displacement(p), np.finfo(float).tiny))
    path = RestoredPath(energy, volume, X, p, V_target)
    noise = ENERGY_NOISE * abs(E)
    if -slope > noise:
        return backtracking(path, E, slope, alpha0)
    E1, X1 = path(alpha0)
    if X1 is not None and E1 <= E + noise:
        if np.linalg.norm(projected_gradient(energy.gradient(X1), volume.gradient(X1))[1]) < r_norm:
            return alpha0, E1, X1
    return None


def max_displacement(p: np.ndarray) -> float:
    """The largest vertex displacement ``max_i |p_i|`` of ``p (V, 3)``."""
    return float(np.sqrt(np.einsum("ij,ij->i", p, p).max()))


def projected_gradient(gE: np.ndarray, gV: np.ndarray) -> tuple[float, np.ndarray]:
    """Least-squares multiplier ``lam = (gE . gV) / |gV|^2`` and ``r = gE - lam gV``.

    ``r`` is the gradient of the energy projected on the tangent space of the constraint; it
    vanishes at a constrained stationary point, where ``lam = dE/dV``.
    """
    lam = float(np.einsum("ij,ij->", gE, gV) / np.einsum("ij,ij->", gV, gV))
    return lam, gE - lam * gV


def mean_edge_length(faces: np.ndarray, X: np.ndarray) -> float:
    """Mean length of the face sides (every interior edge counted twice)."""
    return float(face_side_lengths(np.ascontiguousarray(X, dtype=np.float64),
                                   np.ascontiguousarray(faces, dtype=np.int64)).mean())


def check_problem(X0, V_target) -> tuple[np.ndarray, float]:
    """Validate the starting positions and target volume of a constrained minimization."""
    X = np.array(X0, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != 3:
        raise ValueError(f"X0 must be a (V, 3) array of vertex positions, got shape {X.shape}")
    if not np.isfinite(X).all():
        raise ValueError("X0 contains non-finite coordinates")
    V_target = float(V_target)
    if not (np.isfinite(V_target) and V_target > 0):
        raise ValueError(f"V_target must be a positive finite volume, got {V_target!r}")
    return X, V_target
