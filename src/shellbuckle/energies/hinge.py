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
The gradient is the classical one (e.g. Bridson, Marino, Fedkiw, SCA 2003; Tamstorf & Grinspun,
"Discrete bending forces and their Jacobians", Graphical Models 75, 362 (2013)): with
``L = |e|``, ``t0 = a.e / L^2``, ``t1 = b.e / L^2``,

    g2 = d theta / dx2 = -L n0 / |n0|^2,      g3 = d theta / dx3 = -L n1 / |n1|^2,
    g1 = d theta / dx1 = -(t0 g2 + t1 g3),    g0 = -(g1 + g2 + g3).

The Hessian is obtained by differentiating these once more in the relative coordinates
``(e, a, b)`` (``d(n/|n|^2)/dn = (I - 2 nhat nhat^T) / |n|^2``); with ``[v]_x`` the
cross-product matrix and ``S(u, v) = u v^T + v u^T``:

    d2/da2 = L S(n0, n0 x e) / |n0|^4,         d2/db2 = -L S(n1, n1 x e) / |n1|^4,
    d2/da de = -n0 ehat^T / |n0|^2 + L ([a]_x - 2 n0 (n0 x a)^T / |n0|^2) / |n0|^2,
    d2/db de = -n1 ehat^T / |n1|^2 - L ([b]_x - 2 n1 (n1 x b)^T / |n1|^2) / |n1|^2,
    d2/de2 = -(g2 (grad t0)^T + t0 d2/da de + g3 (grad t1)^T + t1 d2/db de),
    d2/da db = 0,

and mapped to the four vertices by ``x0 = -(e + a + b)`` bookkeeping (the rows/columns of
vertex 0 are minus the sums of the others). The edge-length-weighted angle ``phi = L theta``
of the Jülicher mean curvature follows by the product rule with ``grad L = ehat`` and
``d2 L / de2 = (I - ehat ehat^T) / L``.

Triangle areas: for a face ``(x0, x1, x2)``, ``u = x1 - x0``, ``v = x2 - x0``, ``n = u x v``,
``area = |n| / 2``, ``d area/du = v x nhat / 2``, ``d area/dv = nhat x u / 2`` and

    d2 area/du2 = |v|^2 nhat nhat^T / (2|n|),   d2 area/dv2 = |u|^2 nhat nhat^T / (2|n|),
    d2 area/du dv = ([v]_x (I - nhat nhat^T) [u]_x / |n| - [nhat]_x) / 2.

Layout
------
The public functions take ``X (V, 3)`` and return vertex-major arrays: gradients ``(n, 4, 3)``
(or ``(n, 3, 3)`` for faces), Hessians ``(n, 12, 12)`` (``(n, 9, 9)``) with local dof
``3 a + c``. Internally the kernels work coordinate-major (vectors ``(3, n)``, 3x3 blocks
``(3, 3, n)``) so that the bending energy can scatter blocks without transposing. All angles
and derivatives are undefined for degenerate (zero-area) triangles.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np


# ----------------------------------------------------------------------------- small helpers
# vectors are (3, n), matrices (3, 3, n): coordinate axes first, element axis last


def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def _cross(u, v):
    return np.stack([u[1] * v[2] - u[2] * v[1],
                     u[2] * v[0] - u[0] * v[2],
                     u[0] * v[1] - u[1] * v[0]])


def _outer(u, v):
    return u[:, None, :] * v[None, :, :]


def _sym(u, v):
    o = _outer(u, v)
    return o + o.transpose(1, 0, 2)


def _skew(v):
    """Cross-product matrices ``[v]_x`` (``[v]_x w = v x w``), shape ``(3, 3, n)``."""
    z = np.zeros_like(v[0])
    return np.stack([np.stack([z, -v[2], v[1]]),
                     np.stack([v[2], z, -v[0]]),
                     np.stack([-v[1], v[0], z])])


def _T(m):
    return m.transpose(1, 0, 2)


_EYE = np.eye(3)[:, :, None]


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


def hinge_kernel(XT: np.ndarray, HT: np.ndarray, order: int = 1) -> SimpleNamespace:
    """Dihedral angle, ``phi = L theta`` and their derivatives, coordinate-major.

    ``XT (3, V)`` positions, ``HT (4, n)`` hinge vertices ``(i, j, k, l)``. Returns a namespace
    with ``theta, L (n,)``, ``phi = L theta``, ``ehat (3, n)``, the angle gradient ``g (4, 3, n)``
    (per hinge vertex) and the ``phi`` gradient ``dphi (4, 3, n)``. With ``order=2`` also the
    ``phi`` Hessian blocks in relative coordinates ``(e, a, b)``: ``P_ee, P_ae, P_be, P_aa,
    P_bb`` (each ``(3, 3, n)``, row index first; ``P_ab = 0``) and the angle Hessian blocks
    ``K_ee, K_ae, K_be, K_aa, K_bb``.
    """
    x0 = XT[:, HT[0]]
    e = XT[:, HT[1]] - x0
    a = XT[:, HT[2]] - x0
    b = XT[:, HT[3]] - x0
    n0 = _cross(e, a)
    n1 = _cross(b, e)
    LL = _dot(e, e)
    L = np.sqrt(LL)
    theta = np.arctan2(-L * _dot(n0, b), _dot(n0, n1))
    s0 = 1.0 / _dot(n0, n0)
    s1 = 1.0 / _dot(n1, n1)
    t0 = _dot(a, e) / LL
    t1 = _dot(b, e) / LL
    ehat = e / L
    g2 = -(L * s0) * n0
    g3 = -(L * s1) * n1
    g1 = -(t0 * g2 + t1 * g3)
    g0 = -(g1 + g2 + g3)
    dphi1 = L * g1 + theta * ehat
    dphi2, dphi3 = L * g2, L * g3
    out = SimpleNamespace(theta=theta, L=L, phi=L * theta, ehat=ehat,
                          g=np.stack([g0, g1, g2, g3]),
                          dphi=np.stack([-(dphi1 + dphi2 + dphi3), dphi1, dphi2, dphi3]))
    if order < 2:
        return out
    # angle Hessian in (e, a, b)
    K_aa = (L * s0 * s0) * _sym(n0, _cross(n0, e))
    K_bb = -(L * s1 * s1) * _sym(n1, _cross(n1, e))
    K_ae = s0 * (-_outer(n0, ehat) + L * (_skew(a) - (2.0 * s0) * _outer(n0, _cross(n0, a))))
    K_be = -s1 * (_outer(n1, ehat) + L * (_skew(b) - (2.0 * s1) * _outer(n1, _cross(n1, b))))
    grad_t0 = (a - (2.0 * t0) * e) / LL
    grad_t1 = (b - (2.0 * t1) * e) / LL
    K_ee = -(_outer(g2, grad_t0) + t0 * K_ae + _outer(g3, grad_t1) + t1 * K_be)
    K_ee = 0.5 * (K_ee + _T(K_ee))
    out.K_ee, out.K_ae, out.K_be, out.K_aa, out.K_bb = K_ee, K_ae, K_be, K_aa, K_bb
    # phi = L theta: product rule, grad L = (ehat, 0, 0), d2L/de2 = (I - ehat ehat^T) / L
    out.P_ee = L * K_ee + _sym(ehat, g1) + (theta / L) * (_EYE - _outer(ehat, ehat))
    out.P_ae = L * K_ae + _outer(g2, ehat)
    out.P_be = L * K_be + _outer(g3, ehat)
    out.P_aa = L * K_aa
    out.P_bb = L * K_bb
    return out


def hinge_upper_blocks(P_ee, P_ae, P_be, P_aa, P_bb, out=None, half_diagonal=False):
    """Upper 3x3 blocks of a hinge Hessian over vertices ``(0, 1, 2, 3) = (i, j, k, l)``.

    Input: blocks in relative coordinates ``(e, a, b)`` (``e = x1 - x0``, ``a = x2 - x0``,
    ``b = x3 - x0``, zero ``ab`` block). Output ``(3, 3, 9, n)`` in the order
    ``HINGE_UPPER_BLOCKS`` (the ``(2, 3)`` block is identically zero and omitted); with
    ``half_diagonal`` the diagonal blocks are halved, so that ``U + U^T`` is the full Hessian.
    """
    if out is None:
        out = np.empty((3, 3, 9) + P_ee.shape[2:])
    h = 0.5 if half_diagonal else 1.0
    P_ea, P_eb = _T(P_ae), _T(P_be)
    H01 = -(P_ee + P_ae + P_be)
    H02 = -(P_ea + P_aa)
    H03 = -(P_eb + P_bb)
    np.multiply(-h, H01 + H02 + H03, out=out[:, :, 0])
    out[:, :, 1], out[:, :, 2], out[:, :, 3] = H01, H02, H03
    np.multiply(h, P_ee, out=out[:, :, 4])
    out[:, :, 5], out[:, :, 6] = P_ea, P_eb
    np.multiply(h, P_aa, out=out[:, :, 7])
    np.multiply(h, P_bb, out=out[:, :, 8])
    return out


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
    XT, HT = _coords(X), _elements(hinges, 4, "hinges")
    x0 = XT[:, HT[0]]
    e, a, b = (XT[:, HT[c]] - x0 for c in (1, 2, 3))
    n0, n1 = _cross(e, a), _cross(b, e)
    return np.arctan2(-np.sqrt(_dot(e, e)) * _dot(n0, b), _dot(n0, n1))


def dihedral_angle_gradient(X, hinges):
    """``theta (n,)`` and its gradient ``(n, 4, 3)`` w.r.t. the hinge vertices ``(i, j, k, l)``."""
    k = hinge_kernel(_coords(X), _elements(hinges, 4, "hinges"), order=1)
    return k.theta, k.g.transpose(2, 0, 1)


def dihedral_angle_hessian(X, hinges):
    """``theta (n,)``, gradient ``(n, 4, 3)`` and Hessian ``(n, 12, 12)`` (local dof ``3 a + c``)."""
    k = hinge_kernel(_coords(X), _elements(hinges, 4, "hinges"), order=2)
    up = hinge_upper_blocks(k.K_ee, k.K_ae, k.K_be, k.K_aa, k.K_bb)
    return k.theta, k.g.transpose(2, 0, 1), _dense(up, HINGE_UPPER_BLOCKS, 4)


def length_angle_hessian(X, hinges):
    """``phi = |x_j - x_i| theta (n,)``, gradient ``(n, 4, 3)`` and Hessian ``(n, 12, 12)``.

    ``sum_e phi_e / 2`` is the integrated mean curvature of a polyhedral surface (Steiner).
    """
    k = hinge_kernel(_coords(X), _elements(hinges, 4, "hinges"), order=2)
    up = hinge_upper_blocks(k.P_ee, k.P_ae, k.P_be, k.P_aa, k.P_bb)
    return k.phi, k.dphi.transpose(2, 0, 1), _dense(up, HINGE_UPPER_BLOCKS, 4)


# ----------------------------------------------------------------------------- triangle areas


def face_kernel(XT: np.ndarray, FT: np.ndarray, order: int = 1) -> SimpleNamespace:
    """Face areas and derivatives, coordinate-major.

    ``FT (3, n)`` face vertices. Returns ``area (n,)``, ``grad (3, 3, n)`` (corner, coordinate)
    and with ``order=2`` the Hessian blocks in ``(u, v) = (x1 - x0, x2 - x0)``: ``Q_uu, Q_uv,
    Q_vv`` (``(3, 3, n)``).
    """
    x0 = XT[:, FT[0]]
    u = XT[:, FT[1]] - x0
    v = XT[:, FT[2]] - x0
    n = _cross(u, v)
    norm = np.sqrt(_dot(n, n))
    nhat = n / norm
    gu = 0.5 * _cross(v, nhat)
    gv = 0.5 * _cross(nhat, u)
    out = SimpleNamespace(area=0.5 * norm, grad=np.stack([-(gu + gv), gu, gv]))
    if order < 2:
        return out
    c = 0.5 / norm
    NN = _outer(nhat, nhat)
    out.Q_uu = (c * _dot(v, v)) * NN
    out.Q_vv = (c * _dot(u, u)) * NN
    # [v]_x (I - nn^T) [u]_x = [v]_x [u]_x - (v x nhat)(nhat x u)^T,  [v]_x [u]_x = u v^T - (u.v) I
    out.Q_uv = c * (_outer(u, v) - _dot(u, v) * _EYE - _outer(_cross(v, nhat), _cross(nhat, u))) \
        - 0.5 * _skew(nhat)
    return out


def face_upper_blocks(Q_uu, Q_uv, Q_vv, out=None, half_diagonal=False):
    """Upper 3x3 blocks ``(3, 3, 6, n)`` of a face Hessian over its corners, order ``FACE_UPPER_BLOCKS``."""
    if out is None:
        out = np.empty((3, 3, 6) + Q_uu.shape[2:])
    h = 0.5 if half_diagonal else 1.0
    H01 = -(Q_uu + _T(Q_uv))
    H02 = -(Q_uv + Q_vv)
    np.multiply(-h, H01 + H02, out=out[:, :, 0])
    out[:, :, 1], out[:, :, 2] = H01, H02
    np.multiply(h, Q_uu, out=out[:, :, 3])
    out[:, :, 4] = Q_uv
    np.multiply(h, Q_vv, out=out[:, :, 5])
    return out


def face_areas(X, faces) -> np.ndarray:
    """Triangle areas ``(n,)``."""
    return face_kernel(_coords(X), _elements(faces, 3, "faces")).area


def face_area_hessian(X, faces):
    """Areas ``(n,)``, gradients ``(n, 3, 3)`` and Hessians ``(n, 9, 9)`` (local dof ``3 a + c``)."""
    k = face_kernel(_coords(X), _elements(faces, 3, "faces"), order=2)
    up = face_upper_blocks(k.Q_uu, k.Q_uv, k.Q_vv)
    return k.area, k.grad.transpose(2, 0, 1), _dense(up, FACE_UPPER_BLOCKS, 3)
