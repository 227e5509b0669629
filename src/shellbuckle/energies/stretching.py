"""In-plane stretching: constant-strain-triangle St Venant–Kirchhoff membrane energy.

This is Surface Evolver's ``linear_elastic`` method (Brakke, *Surface Evolver Manual*, named
method ``linear_elastic``; source ``method4.c``, ``linear_elastic_all``), used by Quilliet et
al., EPJE 27, 13 (2008), §3-4.

Formula
-------
For a face ``(x0, x1, x2)`` let ``s = x1 - x0`` and ``t = x2 - x0``. Its metric (Gram matrix) is
``a = [[s.s, s.t], [s.t, t.t]]`` now and ``abar`` in the rest (unstrained) shape. The
Green–Lagrange strain as a mixed tensor is

    e = 1/2 (abar^{-1} a - I),

and the energy per rest area is

    W = A / (2 (1 + nu)) [Tr(e^2) + nu / (1 - nu) (Tr e)^2],

with ``A`` the 2D Young modulus (energy / length^2) and ``nu`` the 2D Poisson ratio. The energy
is ``sum_f W_f * rest_area_f`` with ``rest_area = sqrt(det abar) / 2``.

Surface Evolver's facet attribute ``form_factors[3] = {s11, s12, s22}`` holds the rest metric
``abar`` (``s11 = s.s``, ``s12 = s.t``, ``s22 = t.t`` in the unstrained shape, ``s`` and ``t``
taken from the facet's *first* vertex). Its method writes ``C = F Q - I`` with ``Q = abar^{-1}``
and ``F = a`` and multiplies by ``area / (8 (1 + nu))``, which is the formula above
(``F Q`` and ``Q F`` have the same traces of powers). Differences from Surface Evolver:

- ``nu`` is one number here; Evolver's ``poisson_ratio`` is a per-facet attribute.
- ``A`` plays the role of the quantity's ``modulus``.
- A rest triangle with ``det abar <= 0`` makes Evolver return zero energy for that facet (and
  fail on the gradient); here it is refused when the term is built.

Derivatives (exact)
-------------------
With the covariant strain ``E = (a - abar) / 2`` and ``Q = abar^{-1}`` (so ``e = Q E``) the
energy of a face is ``rest_area [c1 Tr(Q E Q E) + c2 (Q:E)^2]`` with ``c1 = A / (2 (1 + nu))``,
``c2 = c1 nu / (1 - nu)``. This is the quadratic form ``1/2 eps^T D eps`` in the Voigt vector
``eps = (E11, E22, 2 E12)``, with the rest-state stiffness (times area, precomputed)

    D = 2 rest_area [c1 L + c2 q q^T],   q = (Q11, Q22, Q12),
    L = [[Q11^2, Q12^2, Q11 Q12], [Q12^2, Q22^2, Q12 Q22], [Q11 Q12, Q12 Q22, (Q11 Q22 + Q12^2)/2]].

The stress times area is ``(S11, S22, S12) = D eps`` (``S = 2 rest_area (c1 QEQ + c2 (Q:E) Q)``,
the second Piola–Kirchhoff stress) and the energy ``(E : S) / 2``. Since
``dE11 = s.ds``, ``dE12 = (s.dt + t.ds)/2``, ``dE22 = t.dt``,

    dW/ds = S11 s + S12 t,   dW/dt = S12 s + S22 t,   dW/dx0 = -(dW/ds + dW/dt).

The Hessian in ``(s, t)`` is the material part ``B^T D B`` (``B`` the derivative of ``eps``:
rows ``(s, 0)``, ``(0, t)``, ``(t, s)``) plus the geometric part ``S_ab I``; it is mapped to the
three vertices by ``s = x1 - x0``, ``t = x2 - x0``. It is the true Hessian (indefinite under
compression, never projected). Assembly: see :class:`FaceAssembler`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from . import kernels
from .assembly import ElementAssembler

# smallest accepted sin^2 of a rest-triangle angle: det(abar) / (abar_11 abar_22)
_DEGENERATE_SIN2 = 1e-14


def _check_faces(faces, n_vertices) -> np.ndarray:
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise ValueError(f"faces must be an integer (F, 3) array, got {faces.dtype} {faces.shape}")
    if len(faces) == 0:
        raise ValueError("faces is empty: a membrane needs at least one triangle")
    if faces.min() < 0 or faces.max() >= n_vertices:
        raise ValueError(f"face vertex indices must lie in [0, {n_vertices}), got "
                         f"[{faces.min()}, {faces.max()}]")
    return faces.astype(np.int64, copy=False)


def _check_moduli(A, nu) -> tuple[float, float]:
    A, nu = float(A), float(nu)
    if not (np.isfinite(A) and A > 0):
        raise ValueError(f"2D Young modulus A must be a positive finite number, got {A!r}")
    if not (np.isfinite(nu) and -1.0 < nu < 1.0):
        raise ValueError(f"2D Poisson ratio nu must lie in the open interval (-1, 1), got {nu!r}")
    return A, nu


def _rest_from_metric(s11, s12, s22, what: str):
    """Inverse rest metric ``(F, 2, 2)`` and rest areas ``(F,)`` from metric entries."""
    s11, s12, s22 = (np.asarray(c, dtype=np.float64) for c in (s11, s12, s22))
    det = s11 * s22 - s12 * s12
    bad = ~(np.isfinite(det) & (s11 > 0) & (s22 > 0)
            & (det > _DEGENERATE_SIN2 * np.abs(s11 * s22)))
    if bad.any():
        f = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{what}: rest triangle of face {f} is degenerate or invalid "
                         f"(s11={s11[f]!r}, s12={s12[f]!r}, s22={s22[f]!r}, det={det[f]!r}); "
                         f"{int(bad.sum())} such face(s) in all")
    abar_inv = np.empty((len(det), 2, 2))
    abar_inv[:, 0, 0] = s22 / det
    abar_inv[:, 0, 1] = abar_inv[:, 1, 0] = -s12 / det
    abar_inv[:, 1, 1] = s11 / det
    return abar_inv, 0.5 * np.sqrt(det)


def _hessian_coefficients(k) -> np.ndarray:
    """Rest-state coefficients of the off-diagonal face blocks, shape ``(2, 2, 3, F)``.

    Block ``b`` (corners ``b+1, b+2``) is ``alpha I + y s^T + z t^T`` with
    ``y = C[0, 0, b] s + C[0, 1, b] t`` and ``z = C[1, 0, b] s + C[1, 1, b] t``. In ``(s, t)``
    the material blocks are ``Hss = D11 ss + D13 (st + ts) + D33 tt``,
    ``Hst = D13 ss + D12 st + D33 ts + D23 tt``, ``Htt = D33 ss + D23 (st + ts) + D22 tt``
    (``st = s t^T``), and the vertex blocks are ``H_12 = Hst``, ``H_20 = -(Hts + Htt)``,
    ``H_01 = -(Hss + Hts)``.
    """
    D11, D22, D12, D13, D23, D33 = (k[n] for n in ("D11", "D22", "D12", "D13", "D23", "D33"))
    C = np.empty((2, 2, 3, len(D11)))
    C[:, :, 0] = [[D13, D33], [D12, D23]]
    C[:, :, 1] = [[-(D13 + D33), -(D12 + D23)], [-(D33 + D23), -(D23 + D22)]]
    C[:, :, 2] = [[-(D11 + D13), -(D13 + D12)], [-(D13 + D33), -(D33 + D23)]]
    return C


_TRANSPOSE9 = np.array([0, 3, 6, 1, 4, 7, 2, 5, 8])  # flat index of the transposed 3x3 entry


class FaceAssembler:
    """Fast scatter of per-face gradients and Hessians of a translation-invariant face energy.

    Gradients come as ``dW/ds`` and ``dW/dt`` per face (``s = x1 - x0``, ``t = x2 - x0``) in a
    component-major ``(3, 2F)`` array and are summed by one signed incidence matrix
    ``(V, 2F)``. Hessians come as the three off-diagonal vertex blocks of every face,
    ``blocks (3 c, 3 d, 3 b, F)`` = d^2 W / dx_{b+1, c} dx_{b+2, d}; the other blocks follow
    from symmetry and from translation invariance (a face's block rows sum to zero; so do
    the global ones, which gives the diagonal blocks as minus the sum of the edge blocks).

    On a closed, consistently oriented surface every edge ``i < j`` is run ``i -> j`` by
    exactly one face and ``j -> i`` by one other, so the ``(i, j)`` block is one gather and
    add, the diagonal blocks nine ``bincount`` sums over edges, and the CSR data one
    precomputed gather (the pattern is built once). Other meshes (boundaries, non-manifold
    edges) fall back to :class:`ElementAssembler` on full 9x9 face Hessians.
    """

    def __init__(self, faces: np.ndarray, n_vertices: int):
        faces = np.asarray(faces, dtype=np.int64)
        V, F = int(n_vertices), len(faces)
        self.n_vertices, self.n_faces = V, F
        f0, f1, f2 = faces[:, 0], faces[:, 1], faces[:, 2]
        cols = np.arange(2 * F)
        self._edge_incidence = sp.csr_matrix(
            (np.repeat([1.0, -1.0, 1.0, -1.0], F),
             (np.concatenate([f1, f0, f2, f0]), np.concatenate([cols[:F], cols[:F], cols[F:], cols[F:]]))),
            shape=(V, 2 * F))
        # half-edge h = b F + f runs i = faces[f, b+1] -> j = faces[f, b+2]
        i = faces[:, [1, 2, 0]].T.ravel()
        j = faces[:, [2, 0, 1]].T.ravel()
        key = np.minimum(i, j) * V + np.maximum(i, j)
        ukey, uidx, ucount = np.unique(key, return_inverse=True, return_counts=True)
        uidx = uidx.ravel()
        forward = i < j
        self.closed = bool((ucount == 2).all() and
                           (np.bincount(uidx[forward], minlength=len(ukey)) == 1).all())
        if not self.closed:
            self._fallback = ElementAssembler(faces, V)
            return
        U = len(ukey)
        ui, uj = ukey // V, ukey % V
        h_fwd, h_bwd = np.empty(U, np.int64), np.empty(U, np.int64)
        h_fwd[uidx[forward]] = np.flatnonzero(forward)
        h_bwd[uidx[~forward]] = np.flatnonzero(~forward)
        # edge block (ui, uj) = forward block + transpose of backward block, (9, U) gathers
        cd = np.arange(9)[:, None]
        self._gather_fwd = cd * (3 * F) + h_fwd[None, :]
        self._gather_bwd = _TRANSPOSE9[:, None] * (3 * F) + h_bwd[None, :]
        self._ui, self._uj = ui, uj
        # CSR pattern over 3x3 blocks: diagonal (v, v), upper (ui, uj), lower (uj, ui) = upper^T
        # sources in the component-major buffer (9, V + U): diagonal blocks, then edge blocks
        brow = np.concatenate([np.arange(V), ui, uj])
        bcol = np.concatenate([np.arange(V), uj, ui])
        bsrc = np.concatenate([np.arange(V), V + np.arange(U), V + np.arange(U)])
        btr = np.concatenate([np.zeros(V + U, bool), np.ones(U, bool)])
        order = np.lexsort((bcol, brow))
        brow, bcol, bsrc, btr = brow[order], bcol[order], bsrc[order], btr[order]
        per_row = np.bincount(brow, minlength=V)
        bptr = np.concatenate([[0], np.cumsum(per_row)])
        pos = np.arange(len(brow)) - bptr[brow]
        c, d = np.arange(3)[None, :, None], np.arange(3)[None, None, :]
        n_in_row = per_row[brow][:, None, None]
        slot = (9 * bptr[brow][:, None, None] + 3 * n_in_row * c + 3 * pos[:, None, None] + d).ravel()
        comp = np.where(btr[:, None, None], 3 * d + c, 3 * c + d)
        self._n_blocks = V + U
        self._data_gather = np.empty(slot.size, np.int64)
        self._data_gather[slot] = (comp * (V + U) + bsrc[:, None, None]).ravel()
        self._indices = np.empty(slot.size, np.int32)
        self._indices[slot] = np.broadcast_to(3 * bcol[:, None, None] + d, comp.shape).ravel()
        self._indptr = np.concatenate([[0], np.cumsum(np.repeat(3 * per_row, 3))]).astype(np.int32)

    def gradient_from_edges(self, g: np.ndarray) -> np.ndarray:
        """``(V, 3)`` gradient from ``g (3, 2F) = [dW/ds | dW/dt]`` of every face."""
        return np.stack([self._edge_incidence @ g[c] for c in range(3)], axis=1)

    def hessian_from_blocks(self, blocks: np.ndarray) -> sp.csr_matrix:
        """CSR ``(3V, 3V)`` Hessian from off-diagonal face blocks ``(3, 3, 3, F)`` (see class)."""
        V, n = self.n_vertices, 3 * self.n_vertices
        if not self.closed:
            return self._fallback.hessian(_full_face_hessians(blocks))
        flat = blocks.reshape(-1)
        buf = np.empty((9, self._n_blocks))
        edge = buf[:, V:]
        np.add(np.take(flat, self._gather_fwd), np.take(flat, self._gather_bwd), out=edge)
        for cd in range(9):
            buf[cd, :V] = np.bincount(self._ui, edge[cd], V)
            buf[cd, :V] += np.bincount(self._uj, edge[_TRANSPOSE9[cd]], V)
        np.negative(buf[:, :V], out=buf[:, :V])
        data = np.take(buf, self._data_gather)
        return sp.csr_matrix((data, self._indices, self._indptr), shape=(n, n))


def _full_face_hessians(blocks: np.ndarray) -> np.ndarray:
    """``(F, 9, 9)`` face Hessians from the off-diagonal blocks ``(3, 3, 3, F)``."""
    F = blocks.shape[-1]
    H = np.empty((F, 3, 3, 3, 3))  # (f, a, c, b, d)
    for b in range(3):
        a, a2 = (b + 1) % 3, (b + 2) % 3
        H[:, a, :, a2, :] = blocks[:, :, b].transpose(2, 0, 1)
        H[:, a2, :, a, :] = blocks[:, :, b].transpose(2, 1, 0)
    for a in range(3):
        H[:, a, :, a, :] = -(H[:, a, :, (a + 1) % 3, :] + H[:, a, :, (a + 2) % 3, :])
    return H.reshape(F, 9, 9)


def rotate_form_factors(form_factors, shift) -> np.ndarray:
    """Form factors of the same rest triangles with the face vertex order rotated.

    ``form_factors (F, 3) = (s.s, s.t, t.t)`` are taken from the first vertex of each face. If
    face ``(v0, v1, v2)`` is rewritten ``(v1, v2, v0)`` (``shift = 1``; ``shift`` may be an
    ``(F,)`` array of 0, 1, 2), the new edge vectors are ``s' = t - s`` and ``t' = -s``.
    """
    ff = np.asarray(form_factors, dtype=np.float64)
    shift = np.broadcast_to(np.asarray(shift) % 3, ff.shape[:1])
    s11, s12, s22 = ff[:, 0], ff[:, 1], ff[:, 2]
    one = np.stack([s22 - 2 * s12 + s11, s11 - s12, s11], axis=1)
    # shift 2: (v2, v0, v1): s'' = -t, t'' = s - t
    two = np.stack([s22, s22 - s12, s11 - 2 * s12 + s22], axis=1)
    return np.where((shift == 0)[:, None], ff, np.where((shift == 1)[:, None], one, two))


@dataclass(frozen=True, eq=False)
class Stretching:
    """Constant-strain-triangle St Venant–Kirchhoff membrane energy (Evolver ``linear_elastic``).

    W = A / (2 (1 + nu)) [Tr(e^2) + nu / (1 - nu) (Tr e)^2] per rest area, with
    e = (abar^{-1} a - I) / 2 the Green–Lagrange strain of each face relative to its rest shape
    (by default the initial sphere); energy = sum_f W_f rest_area_f. See the module docstring.

    Fields: ``faces (F, 3)`` int, ``n_vertices``, ``abar_inv (F, 2, 2)`` inverse rest metric,
    ``rest_area (F,)``, ``A`` 2D Young modulus (energy / length^2; with kappa = R = 1, A = gamma),
    ``nu`` 2D Poisson ratio in (-1, 1). Build with :meth:`from_reference` or
    :meth:`from_form_factors`.

    Methods: ``value(X) -> float``, ``gradient(X) -> (V, 3)``,
    ``value_and_gradient(X) -> (float, (V, 3))``, ``hessian(X) -> csr (3V, 3V)`` (exact, true
    Hessian, vertex-major dofs) and ``density(X) -> (F,)`` energy per rest area.
    """

    faces: np.ndarray
    n_vertices: int
    abar_inv: np.ndarray
    rest_area: np.ndarray
    A: float
    nu: float
    _k: dict = field(init=False, repr=False)
    _assembler: "FaceAssembler" = field(init=False, repr=False)

    def __post_init__(self):
        faces = _check_faces(self.faces, self.n_vertices)
        A, nu = _check_moduli(self.A, self.nu)
        Q = np.asarray(self.abar_inv, dtype=np.float64)
        area = np.asarray(self.rest_area, dtype=np.float64)
        if Q.shape != (len(faces), 2, 2) or area.shape != (len(faces),):
            raise ValueError(f"abar_inv must be ({len(faces)}, 2, 2) and rest_area "
                             f"({len(faces)},), got {Q.shape} and {area.shape}")
        if not (np.isfinite(area).all() and (area > 0).all()):
            f = int(np.flatnonzero(~(np.isfinite(area) & (area > 0)))[0])
            raise ValueError(f"rest_area of face {f} must be positive, got {area[f]!r}")
        q11, q12, q22 = Q[:, 0, 0], Q[:, 0, 1], Q[:, 1, 1]
        asym = np.abs(Q[:, 1, 0] - q12) > 1e-12 * np.abs(Q).max(axis=(1, 2))
        if asym.any():
            f = int(np.flatnonzero(asym)[0])
            raise ValueError(f"abar_inv of face {f} is not symmetric: {Q[f].tolist()}")
        det = q11 * q22 - q12 * q12
        if not (np.isfinite(det).all() and (det > 0).all() and (q11 > 0).all()):
            f = int(np.flatnonzero(~(np.isfinite(det) & (det > 0) & (q11 > 0)))[0])
            raise ValueError(f"abar_inv of face {f} is not symmetric positive definite: {Q[f]}")
        # kernels run over the faces sorted by their smallest vertex, for memory locality of
        # the gathers from X and the scatters into (V, 3); public fields keep the given order
        order = np.argsort(faces.min(axis=1), kind="stable")
        sfaces, area_s = faces[order], area[order]
        q11, q12, q22, det = q11[order], q12[order], q22[order], det[order]
        c1 = A / (2.0 * (1.0 + nu))
        c2 = c1 * nu / (1.0 - nu)
        w1, w2 = 2.0 * c1 * area_s, 2.0 * c2 * area_s
        k = dict(
            order=order,
            f0=sfaces[:, 0].copy(), f1=sfaces[:, 1].copy(), f2=sfaces[:, 2].copy(),
            q11=q11.copy(), q12=q12.copy(), q22=q22.copy(),
            a11=q22 / det, a12=-q12 / det, a22=q11 / det,  # rest metric abar
            area=area_s,
            # Voigt stiffness D (x area) on (E11, E22, 2 E12); depends only on the rest state
            D11=(w1 + w2) * q11 * q11, D22=(w1 + w2) * q22 * q22,
            D12=w1 * q12 * q12 + w2 * q11 * q22,
            D13=(w1 + w2) * q11 * q12, D23=(w1 + w2) * q12 * q22,
            D33=0.5 * w1 * (q11 * q22 + q12 * q12) + w2 * q12 * q12,
        )
        k.update({"2D13": 2.0 * k["D13"], "2D23": 2.0 * k["D23"], "2D33": 2.0 * k["D33"]})
        k["hess_coef"] = _hessian_coefficients(k)
        k["rest"] = np.stack([k[name] for name in ("a11", "a12", "a22", "D11", "D12", "D13",
                                                   "D22", "D23", "D33")])
        object.__setattr__(self, "faces", faces)
        object.__setattr__(self, "n_vertices", int(self.n_vertices))
        object.__setattr__(self, "abar_inv", Q)
        object.__setattr__(self, "rest_area", area)
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "nu", nu)
        object.__setattr__(self, "_k", k)
        object.__setattr__(self, "_assembler", FaceAssembler(sfaces, self.n_vertices))

    # ---------------------------------------------------------------- constructors
    @classmethod
    def from_reference(cls, X0, faces, n_vertices, A, nu) -> "Stretching":
        """Rest shape = the positions ``X0 (V, 3)`` (by default the initial sphere)."""
        X0 = np.asarray(X0, dtype=np.float64)
        if X0.shape != (n_vertices, 3):
            raise ValueError(f"reference positions must have shape ({n_vertices}, 3), "
                             f"got {X0.shape}")
        faces = _check_faces(faces, n_vertices)
        s = X0[faces[:, 1]] - X0[faces[:, 0]]
        t = X0[faces[:, 2]] - X0[faces[:, 0]]
        abar_inv, area = _rest_from_metric((s * s).sum(1), (s * t).sum(1), (t * t).sum(1),
                                           "reference shape")
        return cls(faces, n_vertices, abar_inv, area, A, nu)

    @classmethod
    def from_form_factors(cls, faces, n_vertices, form_factors, A, nu) -> "Stretching":
        """Rest metric from Surface Evolver's ``form_factors (F, 3) = (s.s, s.t, t.t)``.

        ``s = x1 - x0`` and ``t = x2 - x0`` in the unstrained shape, with ``x0`` the first
        vertex of each face as listed in ``faces`` (use :func:`rotate_form_factors` if the
        faces were rotated after reading).
        """
        faces = _check_faces(faces, n_vertices)
        ff = np.asarray(form_factors, dtype=np.float64)
        if ff.shape != (len(faces), 3):
            raise ValueError(f"form_factors must have shape ({len(faces)}, 3), got {ff.shape}")
        abar_inv, area = _rest_from_metric(ff[:, 0], ff[:, 1], ff[:, 2], "form_factors")
        return cls(faces, n_vertices, abar_inv, area, A, nu)

    # ---------------------------------------------------------------- kernels
    def _edges(self, X):
        """Edge vectors ``s = x1 - x0``, ``t = x2 - x0``, component-major ``(3, F)`` each."""
        k = self._k
        Xt = np.ascontiguousarray(kernels.positions(X, self.n_vertices).T)
        x0 = np.take(Xt, k["f0"], axis=1)
        s = np.take(Xt, k["f1"], axis=1)
        s -= x0
        t = np.take(Xt, k["f2"], axis=1)
        t -= x0
        return s, t

    def _strain(self, s, t):
        """Covariant Green–Lagrange strain ``E = (a - abar) / 2``: ``E11, E12, E22``, each ``(F,)``."""
        k = self._k
        E11 = s[0] * s[0] + s[1] * s[1] + s[2] * s[2] - k["a11"]
        E12 = s[0] * t[0] + s[1] * t[1] + s[2] * t[2] - k["a12"]
        E22 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2] - k["a22"]
        E11 *= 0.5
        E12 *= 0.5
        E22 *= 0.5
        return E11, E12, E22

    def _stress(self, E):
        """Area-weighted stress ``S = D (E11, E22, 2 E12)`` = 2 rest_area (c1 QEQ + c2 (Q:E) Q)."""
        k = self._k
        E11, E12, E22 = E
        S11 = k["D11"] * E11 + k["D12"] * E22 + k["2D13"] * E12
        S22 = k["D12"] * E11 + k["D22"] * E22 + k["2D23"] * E12
        S12 = k["D13"] * E11 + k["D23"] * E22 + k["2D33"] * E12
        return S11, S12, S22

    @staticmethod
    def _face_energy(E, S):
        """Energy of every face, ``(E : S) / 2``, shape ``(F,)``."""
        (E11, E12, E22), (S11, S12, S22) = E, S
        return 0.5 * (E11 * S11 + E22 * S22) + E12 * S12

    # ---------------------------------------------------------------- public API
    def density(self, X) -> np.ndarray:
        """Energy per rest area of every face, shape ``(F,)`` (for colouring a viewer)."""
        E = self._strain(*self._edges(X))
        out = np.empty(len(self.faces))
        out[self._k["order"]] = self._face_energy(E, self._stress(E)) / self._k["area"]
        return out

    def _compiled(self, X, gradient: bool):
        """``(value, gradient or (0, 3))`` from :func:`.kernels.stretching`."""
        k, X = self._k, kernels.positions(X, self.n_vertices)
        value, G = kernels.stretching(X, k["f0"], k["f1"], k["f2"], k["rest"], gradient)
        return float(value), G

    def value(self, X) -> float:
        return self._compiled(X, False)[0]

    def gradient(self, X) -> np.ndarray:
        """Exact gradient, shape ``(V, 3)``."""
        return self.value_and_gradient(X)[1]

    def value_and_gradient(self, X) -> tuple[float, np.ndarray]:
        """Energy and its exact gradient ``(V, 3)`` from one compiled pass over the faces
        (:func:`.kernels.stretching`; the value is :meth:`value`'s, bit for bit)."""
        return self._compiled(X, True)

    def hessian(self, X) -> sp.csr_matrix:
        """Exact (true, possibly indefinite) Hessian, CSR ``(3V, 3V)``, vertex-major dofs.

        Every off-diagonal vertex block of a face is ``alpha I + y s^T + z t^T`` with ``y, z``
        combinations of ``s, t`` whose coefficients come from the rest-state stiffness ``D``
        (precomputed) and ``alpha`` from the stress; diagonal blocks follow from translation
        invariance (each block row of a face sums to zero).
        """
        k = self._k
        s, t = self._edges(X)
        S11, S12, S22 = self._stress(self._strain(s, t))
        C = k["hess_coef"]  # (2 [y, z], 2 [s, t], 3 blocks, F)
        Y = C[0, 0] * s[:, None] + C[0, 1] * t[:, None]  # (3 c, 3 blocks, F)
        Z = C[1, 0] * s[:, None] + C[1, 1] * t[:, None]
        blocks = Y[:, None] * s[None, :, None]  # (3 c, 3 d, 3 blocks, F)
        blocks += Z[:, None] * t[None, :, None]
        # block b couples corners (b+1, b+2): H_12 = Hst, H_20 = -(Hts + Htt), H_01 = -(Hss + Hts)
        for b, alpha in enumerate((S12, -(S12 + S22), -(S11 + S12))):
            for c in range(3):
                blocks[c, c, b] += alpha
        return self._assembler.hessian_from_blocks(blocks)
