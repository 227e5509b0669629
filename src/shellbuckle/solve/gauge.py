"""The rigid-motion gauge of Newton's method: six pinned dofs, and steps without rigid motion.

Translations and rotations leave a shell's energy and enclosed volume unchanged, so the
Hessian of the Lagrangian ``K = Hess E - lam Hess V`` is exactly singular along the
translations and, at equilibrium, along the rotations. A factorization without numerical
pivoting (QDLDL) eliminates the sparse block ``K`` before the dense constraint row, so ``K``
itself must not be singular. The gauge is fixed by pinning six dofs (``dx = 0`` there): the
first six pivots of a column-pivoted QR factorization of the transposed rigid modes
(Businger & Golub, Numer. Math. 7, 269 (1965)), so that the rigid modes restricted to them are
well conditioned and no rigid motion leaves them all unchanged (:func:`pinned_dofs`). This is
sparse and exact: any rigid motion can be added to a step without changing the energy, so
pinning removes exactly the six null modes, and inertia counts are on the tangent space modulo
rigid motions (Surface Evolver's ``eigenneg``).

A given set of pins is kept while the rigid modes on it are conditioned to ``max_cond`` (or to
twice the condition of the best choice at the point), :func:`fixes_gauge`; otherwise the dofs
are chosen again at the current point, a function of the point alone, so a resumed run repeats
the same choices.

A step solved with pinned dofs carries whatever infinitesimal rotation makes the pinned dofs
vanish; over many steps the shell would rotate until the pins hardly fix the rotations. Every
step is therefore taken without its least-squares rigid-motion part at the current point,
:func:`remove_rigid` (the translation is the mean, the rotation solves ``I w = sum c x p`` with
the inertia tensor ``I`` of the centred positions: translations and rotations about the
centroid are orthogonal, so the projection is closed-form). Removing it changes neither
``r . p`` (the projected gradient is orthogonal to rigid motions) nor the linearized
constraint.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from numba import njit

from .options import NewtonOptions


def rigid_modes(X: np.ndarray) -> np.ndarray:
    """The six infinitesimal rigid motions at ``X (V, 3)`` as columns of a ``(3V, 6)`` array:
    translations ``e_k`` and rotations ``e_k x (x - centroid)`` (vertex-major dofs)."""
    c = X - X.mean(axis=0)
    modes = np.zeros((len(X), 3, 6))
    for k in range(3):
        e = np.zeros(3)
        e[k] = 1.0
        modes[:, k, k] = 1.0
        modes[:, :, 3 + k] = np.cross(e, c)
    return modes.reshape(-1, 6)


def remove_rigid(X: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``p (V, 3)`` minus its least-squares component along the rigid motions at ``X``: the
    translation is the mean ``t`` of ``p`` and the rotation ``w`` solves ``I w = sum_i c_i x
    p_i`` with ``I = sum_i (|c_i|^2 1 - c_i c_i^T)`` over the centred positions ``c``; the
    result is ``p - t - w x c``, the least-squares solve with :func:`rigid_modes` in closed
    form (compiled, :func:`_remove_rigid`)."""
    return _remove_rigid(np.ascontiguousarray(X, dtype=np.float64),
                         np.ascontiguousarray(p, dtype=np.float64))


@njit(cache=True, nogil=True)
def _remove_rigid(X, p):
    """:func:`remove_rigid`: sums in vertex order, the 3x3 system by its adjugate."""
    n = X.shape[0]
    m0 = m1 = m2 = t0 = t1 = t2 = 0.0
    for i in range(n):
        m0, m1, m2 = m0 + X[i, 0], m1 + X[i, 1], m2 + X[i, 2]
        t0, t1, t2 = t0 + p[i, 0], t1 + p[i, 1], t2 + p[i, 2]
    m0, m1, m2, t0, t1, t2 = m0 / n, m1 / n, m2 / n, t0 / n, t1 / n, t2 / n
    s00 = s01 = s02 = s11 = s12 = s22 = b0 = b1 = b2 = 0.0  # sum c c^T, sum c x p
    for i in range(n):
        c0, c1, c2 = X[i, 0] - m0, X[i, 1] - m1, X[i, 2] - m2
        s00, s01, s02 = s00 + c0 * c0, s01 + c0 * c1, s02 + c0 * c2
        s11, s12, s22 = s11 + c1 * c1, s12 + c1 * c2, s22 + c2 * c2
        b0 += c1 * p[i, 2] - c2 * p[i, 1]
        b1 += c2 * p[i, 0] - c0 * p[i, 2]
        b2 += c0 * p[i, 1] - c1 * p[i, 0]
    # the inertia tensor I = tr(S) 1 - S and the adjugate of I (symmetric)
    a00, a11, a22, a01, a02, a12 = s11 + s22, s00 + s22, s00 + s11, -s01, -s02, -s12
    i00, i01, i02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
    i11, i12, i22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
    det = a00 * i00 + a01 * i01 + a02 * i02
    w0 = (i00 * b0 + i01 * b1 + i02 * b2) / det
    w1 = (i01 * b0 + i11 * b1 + i12 * b2) / det
    w2 = (i02 * b0 + i12 * b1 + i22 * b2) / det
    out = np.empty_like(p)
    for i in range(n):
        c0, c1, c2 = X[i, 0] - m0, X[i, 1] - m1, X[i, 2] - m2
        out[i, 0] = p[i, 0] - t0 - (w1 * c2 - w2 * c1)
        out[i, 1] = p[i, 1] - t1 - (w2 * c0 - w0 * c2)
        out[i, 2] = p[i, 2] - t2 - (w0 * c1 - w1 * c0)
    return out


def pinned_dofs(X: np.ndarray) -> np.ndarray:
    """Six dofs that fix the rigid-motion gauge: the first pivots of a column-pivoted QR of the
    transposed rigid modes, so that the rigid modes restricted to them are well conditioned."""
    piv = scipy.linalg.qr(rigid_modes(X).T, pivoting=True, mode="r")[1]
    return np.sort(piv[:6])


def fixes_gauge(X: np.ndarray, pinned,
                max_cond: float = NewtonOptions.gauge_max_cond) -> bool:
    """Whether the dofs ``pinned`` fix the rigid-motion gauge at ``X``: six distinct valid
    dofs on which the rigid modes are conditioned to ``max_cond``
    (:attr:`~.options.NewtonOptions.gauge_max_cond`), or to twice the condition of the best
    choice at ``X`` (:func:`pinned_dofs`; above 10 only on very elongated shapes)."""
    pinned = np.asarray(pinned)
    if pinned.shape != (6,) or len(np.unique(pinned)) != 6 or pinned.min() < 0 \
            or pinned.max() >= X.size:
        return False
    cond = np.linalg.cond(rigid_rows(X, pinned))
    return bool(cond <= max_cond
                or cond <= 2.0 * np.linalg.cond(rigid_rows(X, pinned_dofs(X))))


def rigid_rows(X: np.ndarray, dofs: np.ndarray) -> np.ndarray:
    """The rows ``dofs`` of :func:`rigid_modes` at ``X`` (the same numbers), without the
    ``(3V, 6)`` array."""
    dofs = np.asarray(dofs)
    rows, coordinate = np.arange(len(dofs)), dofs % 3
    c = X[dofs // 3] - X.mean(axis=0)
    out = np.zeros((len(dofs), 6))
    out[rows, coordinate] = 1.0
    for k in range(3):
        e = np.zeros(3)
        e[k] = 1.0
        out[:, 3 + k] = np.cross(e, c)[rows, coordinate]
    return out


def free_dofs(n_dofs: int, pinned) -> np.ndarray:
    """The dofs ``0 .. n_dofs - 1`` other than ``pinned``, in order."""
    free = np.ones(n_dofs, dtype=bool)
    free[pinned] = False
    return np.flatnonzero(free)
