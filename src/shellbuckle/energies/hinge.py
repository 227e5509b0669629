"""Dihedral angles of hinges and triangle areas, with exact first and second derivatives.

These are the geometric kernels of the edge-based bending energy (:mod:`.bending`).

Hinge convention
----------------
A hinge is ``(i, j, k, l)`` as in :class:`shellbuckle.mesh.Topology`: the edge ``i -> j``, the
face ``(i, j, k)`` on one side and the face ``(j, i, l)`` on the other, both counter-clockwise
seen from outside. With ``x0, x1, x2, x3 = X[i], X[j], X[k], X[l]`` and

    e = x1 - x0,   a = x2 - x0,   b = x3 - x0,
    n0 = e x a     (outward area vector of face (i, j, k), |n0| = 2 area),
    n1 = b x e     (outward area vector of face (j, i, l)),

the signed dihedral angle is the angle between the outward normals, measured about ``e``:

    theta = atan2((n0 x n1) . e / |e|, n0 . n1) = atan2(-|e| (n0 . b), n0 . n1),

in ``(-pi, pi]``; ``theta > 0`` where the surface is convex (a ridge seen from outside), 0 where
the two faces are coplanar, ``< 0`` in a valley. ``atan2`` keeps it accurate at all angles.

Derivatives
-----------
The gradient is the classical one (Bridson, Marino, Fedkiw, "Simulation of clothing with folds
and wrinkles", SCA 2003; Tamstorf & Grinspun, "Discrete bending forces and their Jacobians",
Graphical Models 75 (2013)): with ``L = |e|``, ``t0 = a.e / L^2``, ``t1 = b.e / L^2``,

    g2 = d theta / dx2 = -L n0 / |n0|^2,      g3 = d theta / dx3 = -L n1 / |n1|^2,
    g1 = d theta / dx1 = -(t0 g2 + t1 g3),    g0 = -(g1 + g2 + g3).

The Hessian is derived here by differentiating these once more in the relative coordinates
``(e, a, b)``, using ``d(n/|n|^2)/dn = (I - 2 nhat nhat^T) / |n|^2``. With ``[v]_x`` the
cross-product matrix, ``S(u, v) = u v^T + v u^T``, ``s0 = 1/|n0|^2``, ``s1 = 1/|n1|^2``,
``m0 = n0 x a``, ``m1 = n1 x b``:

    d2/da2  = L s0^2 S(n0, n0 x e),            d2/db2 = -L s1^2 S(n1, n1 x e),   d2/da db = 0,
    d2/da de = n0 y0^T + L s0 [a]_x,           y0 = -s0 ehat - 2 L s0^2 m0,
    d2/db de = n1 y1^T - L s1 [b]_x,           y1 = -s1 ehat + 2 L s1^2 m1,
    d2/de2  = -(S(n0, p) + S(n1, q)) / 2,
        p = -(L s0 grad t0 + t0 s0 ehat + 2 t0 L s0^2 m0),
        q = -(L s1 grad t1 + t1 s1 ehat - 2 t1 L s1^2 m1),   grad t = (a - 2 t e) / L^2 (resp. b).

(``d2/de2 = -(g2 grad t0^T + t0 d2/da de + g3 grad t1^T + t1 d2/db de)`` is symmetric, so only
the symmetric part of the rank-two terms survives.) The blocks of vertex ``i`` follow from
``e, a, b = x - x_i``: they are minus the row/column sums of the others. The edge-length-weighted
angle ``phi = L theta`` of the Jülicher mean curvature follows by the product rule with
``grad L = ehat``, ``d2 L / de2 = (I - ehat ehat^T) / L``; it has the same form with extra
``S(ehat, g1 - theta ehat / (2L)) + (theta / L) I`` in ``d2/de2`` (:class:`HingeHessian`).

Triangle areas: for a face ``(x0, x1, x2)``, ``u = x1 - x0``, ``v = x2 - x0``, ``n = u x v``,
``area = |n| / 2``, ``d area/du = v x nhat / 2``, ``d area/dv = nhat x u / 2``, and the
``(p, q)`` block of the Hessian over the corners is

    c (E_p . E_q) nhat nhat^T + s_pq [nhat]_x / 2,   c = 1 / (2 |n|),

with ``E_p`` the edge opposite corner ``p`` (``E_0 = x2 - x1``, ``E_1 = x0 - x2``,
``E_2 = x1 - x0``) and ``s_pq = -1`` for ``q = p + 1``, ``+1`` for ``q = p - 1`` (mod 3), 0 for
``p = q`` (:class:`FaceAreaHessian`).

Every formula is checked against central differences in ``tests/test_hinge.py``.

Layout
------
The public functions take ``X (V, 3)`` and return vertex-major arrays: gradients ``(n, 4, 3)``
(or ``(n, 3, 3)`` for faces), Hessians ``(n, 12, 12)`` (``(n, 9, 9)``) with local dof
``3 a + c``. Internally the kernels work coordinate-major (vectors ``(3, n)``, gradients
``(3, k, n)``, 3x3 blocks ``(3, 3, n)``) so that the bending energy can scatter them without
transposing. All angles and derivatives are undefined for degenerate (zero-area) triangles.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np


# ----------------------------------------------------------------------------- small helpers
# vectors are (3, n), matrices (3, 3, n): coordinate axes first, element axis last


def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def _cross(u, v):
    out = np.empty(np.broadcast_shapes(u.shape, v.shape))
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        np.multiply(u[j], v[k], out=out[i])
        out[i] -= u[k] * v[j]
    return out


def _outer(u, v):
    return u[:, None, :] * v[None, :, :]


def _T(m):
    return m.transpose(1, 0, 2)


def _coords(X):
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != 3:
        raise ValueError(f"positions must be a (V, 3) array, got shape {X.shape}")
    return np.ascontiguousarray(X.T)


def _elements(elements, k, name):
    elements = np.asarray(elements)
    if elements.ndim != 2 or elements.shape[1] != k or not np.issubdtype(elements.dtype, np.integer):
        raise ValueError(f"{name} must be an integer (n, {k}) array, got {elements.dtype} {elements.shape}")
    return np.ascontiguousarray(elements.T, dtype=np.int64)


# ----------------------------------------------------------------------------- hinge kernels


def hinge_kernel(XT: np.ndarray, HT: np.ndarray, order: int = 1, weighted_by_length: bool = True):
    """Dihedral angle, ``phi = L theta`` and their derivatives, coordinate-major.

    ``XT (3, V)`` positions, ``HT (4, n)`` hinge vertices ``(i, j, k, l)``. Returns a namespace
    with ``theta, L (n,)`` and ``phi = L theta``; with ``order >= 1`` also ``ehat (3, n)`` and
    the gradient of ``phi``, ``dphi (3, 4, n)`` (coordinate, hinge vertex), or with
    ``weighted_by_length=False`` that of ``theta``, ``g (3, 4, n)``; with ``order=2`` also
    ``hess``, a :class:`HingeHessian` of the same scalar.
    """
    x = np.take(XT, HT, axis=1)  # (3, 4, n)
    e = x[:, 1] - x[:, 0]
    a = x[:, 2] - x[:, 0]
    b = x[:, 3] - x[:, 0]
    n0 = _cross(e, a)
    n1 = _cross(b, e)
    LL = _dot(e, e)
    L = np.sqrt(LL)
    theta = np.arctan2(-L * _dot(n0, b), _dot(n0, n1))
    if order < 1:
        return SimpleNamespace(theta=theta, L=L, phi=L * theta)
    s0 = 1.0 / _dot(n0, n0)
    s1 = 1.0 / _dot(n1, n1)
    t0 = _dot(a, e) / LL
    t1 = _dot(b, e) / LL
    ehat = e / L
    Ls0, Ls1 = L * s0, L * s1
    g2 = -Ls0 * n0
    g3 = -Ls1 * n1
    g1 = -(t0 * g2 + t1 * g3)
    out = SimpleNamespace(theta=theta, L=L, phi=L * theta, ehat=ehat)
    if weighted_by_length:  # gradient of phi only
        d = np.empty((3, 4, len(L)))
        np.multiply(L, g1, out=d[:, 1])
        d[:, 1] += theta * ehat
        np.multiply(L, g2, out=d[:, 2])
        np.multiply(L, g3, out=d[:, 3])
        out.dphi = d
    else:  # gradient of theta only
        d = np.empty((3, 4, len(L)))
        d[:, 1], d[:, 2], d[:, 3] = g1, g2, g3
        out.g = d
    np.add(d[:, 1], d[:, 2], out=d[:, 0])
    d[:, 0] += d[:, 3]
    np.negative(d[:, 0], out=d[:, 0])
    if order < 2:
        return out
    # angle Hessian in (e, a, b), see the module docstring; d2/de2 = -(S(n0, p) + S(n1, q)) / 2
    m0 = _cross(n0, a)
    m1 = _cross(n1, b)
    x_aa = (Ls0 * s0) * _cross(n0, e)
    x_bb = -(Ls1 * s1) * _cross(n1, e)
    y0 = -s0 * ehat - (2.0 * Ls0 * s0) * m0
    y1 = -s1 * ehat + (2.0 * Ls1 * s1) * m1
    grad_t0 = (a - (2.0 * t0) * e) / LL
    grad_t1 = (b - (2.0 * t1) * e) / LL
    p = -(Ls0 * grad_t0 + (t0 * s0) * ehat + (2.0 * t0 * Ls0 * s0) * m0)
    q = -(Ls1 * grad_t1 + (t1 * s1) * ehat - (2.0 * t1 * Ls1 * s1) * m1)
    if not weighted_by_length:
        out.hess = HingeHessian(n0, n1, ehat, a, b, x_aa, x_bb, y0, Ls0, y1, -Ls1,
                                -0.5 * p, -0.5 * q, None, None)
        return out
    # phi = L theta: product rule, grad L = (ehat, 0, 0), d2L/de2 = (I - ehat ehat^T) / L
    out.hess = HingeHessian(n0, n1, ehat, a, b, L * x_aa, L * x_bb,
                            L * y0 - Ls0 * ehat, L * Ls0, L * y1 - Ls1 * ehat, -L * Ls1,
                            (-0.5 * L) * p, (-0.5 * L) * q, g1 - (0.5 * theta / L) * ehat, theta / L)
    return out


class HingeHessian:
    """Second derivatives of one scalar per hinge, in low-rank form.

    In relative coordinates ``(e, a, b)``, with ``S(u, v) = u v^T + v u^T`` and ``[v]_x`` the
    cross-product matrix:

        d2/da2 = S(n0, x_aa),  d2/db2 = S(n1, x_bb),  d2/da db = 0,
        d2/da de = n0 y0^T + gamma0 [a]_x,  d2/db de = n1 y1^T + gamma1 [b]_x,
        d2/de2 = S(n0, p) + S(n1, q) + S(ehat, r) + delta I,

    vectors ``(3, n)``, scalars ``(n,)`` (``r`` and ``delta`` may be ``None``, i.e. zero).
    """

    def __init__(self, n0, n1, ehat, a, b, x_aa, x_bb, y0, gamma0, y1, gamma1, p, q, r, delta):
        self.n0, self.n1, self.ehat, self.a, self.b = n0, n1, ehat, a, b
        self.x_aa, self.x_bb = x_aa, x_bb
        self.y0, self.gamma0, self.y1, self.gamma1 = y0, gamma0, y1, gamma1
        self.p, self.q, self.r, self.delta = p, q, r, delta

    def upper_blocks(self, weight=None, out=None, half_diagonal=False):
        """``weight`` times the upper 3x3 blocks over the vertices ``(i, j, k, l)``, ``(3, 3, 9, n)``.

        Block order ``HINGE_UPPER_BLOCKS`` (the ``(k, l)`` block is identically zero and left
        out). With ``half_diagonal`` the diagonal blocks are halved, so that ``U + U^T`` is the
        weighted Hessian.
        """
        n = self.n0.shape[1]
        w = np.ones(n) if weight is None else weight
        if out is None:
            out = np.empty((3, 3, 9, n))
        O = [out[:, :, k] for k in range(9)]
        tmp, tmp2 = np.empty((3, 3, n)), np.empty((3, 3, n))
        # (j, j) = d2/de2
        np.multiply(self.n0[:, None], (w * self.p)[None], out=tmp)
        np.multiply(self.n1[:, None], (w * self.q)[None], out=tmp2)
        tmp += tmp2
        if self.r is not None:
            np.multiply(self.ehat[:, None], (w * self.r)[None], out=tmp2)
            tmp += tmp2
        np.add(tmp, _T(tmp), out=O[4])
        if self.delta is not None:
            wd = w * self.delta
            for c in range(3):
                O[4][c, c] += wd
        # (j, k), (j, l): transposes of d2/da de, d2/db de
        for blk, y, nrm, gam, v in ((O[5], self.y0, self.n0, self.gamma0, self.a),
                                    (O[6], self.y1, self.n1, self.gamma1, self.b)):
            np.multiply((w * y)[:, None], nrm[None], out=blk)
            _add_skew(blk, -(w * gam), v)
        # (k, k), (l, l)
        for blk, nrm, x in ((O[7], self.n0, self.x_aa), (O[8], self.n1, self.x_bb)):
            np.multiply(nrm[:, None], (w * x)[None], out=tmp)
            np.add(tmp, _T(tmp), out=blk)
        # vertex i enters through e, a, b = x - x_i: its blocks are minus the row/column sums
        np.add(_T(O[5]), _T(O[6]), out=O[1])
        O[1] += O[4]
        np.negative(O[1], out=O[1])
        np.add(O[5], O[7], out=O[2])
        np.negative(O[2], out=O[2])
        np.add(O[6], O[8], out=O[3])
        np.negative(O[3], out=O[3])
        np.add(O[1], O[2], out=O[0])
        O[0] += O[3]
        if half_diagonal:
            O[0] *= -0.5
            for k in (4, 7, 8):
                O[k] *= 0.5
        else:
            np.negative(O[0], out=O[0])
        return out


def _add_skew(M, s, v):
    """``M += s [v]_x`` in place, for ``M (3, 3, n)``, ``s (n,)``, ``v (3, n)``."""
    sv = s * v
    M[0, 1] -= sv[2]
    M[0, 2] += sv[1]
    M[1, 0] += sv[2]
    M[1, 2] -= sv[0]
    M[2, 0] -= sv[1]
    M[2, 1] += sv[0]


HINGE_UPPER_BLOCKS = ((0, 0), (0, 1), (0, 2), (0, 3), (1, 1), (1, 2), (1, 3), (2, 2), (3, 3))
FACE_UPPER_BLOCKS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def _dense(blocks, pairs, k):
    """Symmetric dense ``(n, 3k, 3k)`` from upper blocks ``(3, 3, m, n)``."""
    n = blocks.shape[-1]
    H = np.zeros((n, k, 3, k, 3))
    for m, (p, q) in enumerate(pairs):
        B = blocks[:, :, m].transpose(2, 0, 1)
        H[:, p, :, q, :] = B if p != q else 0.5 * (B + B.transpose(0, 2, 1))
        if p != q:
            H[:, q, :, p, :] = B.transpose(0, 2, 1)
    return H.reshape(n, 3 * k, 3 * k)


def dihedral_angles(X, hinges) -> np.ndarray:
    """Signed dihedral angles ``theta (n,)`` of hinges ``(n, 4)``; positive where convex."""
    return hinge_kernel(_coords(X), _elements(hinges, 4, "hinges"), order=0).theta


def dihedral_angle_gradient(X, hinges):
    """``theta (n,)`` and its gradient ``(n, 4, 3)`` w.r.t. the hinge vertices ``(i, j, k, l)``."""
    k = hinge_kernel(_coords(X), _elements(hinges, 4, "hinges"), order=1, weighted_by_length=False)
    return k.theta, k.g.transpose(2, 1, 0)


def dihedral_angle_hessian(X, hinges):
    """``theta (n,)``, gradient ``(n, 4, 3)`` and Hessian ``(n, 12, 12)`` (local dof ``3 a + c``)."""
    k = hinge_kernel(_coords(X), _elements(hinges, 4, "hinges"), order=2, weighted_by_length=False)
    return k.theta, k.g.transpose(2, 1, 0), _dense(k.hess.upper_blocks(), HINGE_UPPER_BLOCKS, 4)


def length_angle_hessian(X, hinges):
    """``phi = |x_j - x_i| theta (n,)``, gradient ``(n, 4, 3)`` and Hessian ``(n, 12, 12)``.

    ``sum_e phi_e / 2`` is the integrated mean curvature of a polyhedral surface (Steiner).
    """
    k = hinge_kernel(_coords(X), _elements(hinges, 4, "hinges"), order=2)
    return k.phi, k.dphi.transpose(2, 1, 0), _dense(k.hess.upper_blocks(), HINGE_UPPER_BLOCKS, 4)


# ----------------------------------------------------------------------------- triangle areas


def face_kernel(XT: np.ndarray, FT: np.ndarray, order: int = 1) -> SimpleNamespace:
    """Face areas and derivatives, coordinate-major.

    ``FT (3, n)`` face vertices. Returns ``area (n,)``; with ``order >= 1`` also
    ``grad (3, 3, n)`` (coordinate, corner); with ``order=2`` also ``hess``, a
    :class:`FaceAreaHessian`.
    """
    x = np.take(XT, FT, axis=1)  # (3, 3, n)
    u = x[:, 1] - x[:, 0]
    v = x[:, 2] - x[:, 0]
    n = _cross(u, v)
    norm = np.sqrt(_dot(n, n))
    if order < 1:
        return SimpleNamespace(area=0.5 * norm)
    nhat = n / norm
    gu = 0.5 * _cross(v, nhat)
    gv = 0.5 * _cross(nhat, u)
    grad = np.empty((3, 3, len(norm)))
    grad[:, 1], grad[:, 2] = gu, gv
    np.negative(gu + gv, out=grad[:, 0])
    out = SimpleNamespace(area=0.5 * norm, grad=grad)
    if order >= 2:
        out.hess = FaceAreaHessian(nhat, 0.5 / norm, (v - u, -v, u))
    return out


class FaceAreaHessian:
    """Hessian of a triangle's area, ``(p, q)`` block over its corners:

        d2 area / dx_p dx_q = c (E_p . E_q) nhat nhat^T + s_pq [nhat]_x / 2,

    with ``E_p`` the edge opposite corner ``p`` (counter-clockwise: ``E_0 = x2 - x1``, ...),
    ``c = 1 / (2 |n|)``, ``s_pq = -1`` if ``q = p + 1``, ``+1`` if ``q = p - 1`` (mod 3), 0 if
    ``p = q``. (In-plane, ``[v]_x (I - nhat nhat^T) [u]_x = -(u . v) nhat nhat^T``, which reduces
    the general formula ``J_p^T (I - nhat nhat^T) J_q / (2|n|) + ...`` to this.)
    """

    def __init__(self, nhat, c, opposite_edges):
        self.nhat, self.c, self.E = nhat, c, opposite_edges

    def upper_blocks(self, weight=None, out=None, half_diagonal=False):
        """``weight`` times the upper blocks ``(3, 3, 6, n)``, order ``FACE_UPPER_BLOCKS``."""
        n = self.nhat.shape[1]
        if out is None:
            out = np.empty((3, 3, 6, n))
        wc = self.c if weight is None else weight * self.c
        ws = 0.5 * (np.ones(n) if weight is None else weight)
        NN = _outer(self.nhat, self.nhat)
        h = 0.5 if half_diagonal else 1.0
        for k, (p, q) in enumerate(FACE_UPPER_BLOCKS):
            coef = wc * _dot(self.E[p], self.E[q])
            if p == q:
                coef = h * coef
            np.multiply(NN, coef, out=out[:, :, k])
            if p != q:
                _add_skew(out[:, :, k], -ws if q == (p + 1) % 3 else ws, self.nhat)
        return out


def face_areas(X, faces) -> np.ndarray:
    """Triangle areas ``(n,)``."""
    return face_kernel(_coords(X), _elements(faces, 3, "faces")).area


def face_area_hessian(X, faces):
    """Areas ``(n,)``, gradients ``(n, 3, 3)`` and Hessians ``(n, 9, 9)`` (local dof ``3 a + c``)."""
    k = face_kernel(_coords(X), _elements(faces, 3, "faces"), order=2)
    return k.area, k.grad.transpose(2, 1, 0), _dense(k.hess.upper_blocks(), FACE_UPPER_BLOCKS, 3)
