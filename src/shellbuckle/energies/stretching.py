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
With the covariant strain ``E = (a - abar) / 2`` the energy of a face is
``rest_area [c1 Tr(Q E Q E) + c2 (Q:E)^2]``, ``c1 = A / (2 (1 + nu))``, ``c2 = c1 nu / (1 - nu)``,
``Q = abar^{-1}``. Its derivative with respect to ``E`` is the (contravariant, second
Piola–Kirchhoff) stress times area, ``S = 2 rest_area (c1 Q E Q + c2 (Q:E) Q)``, so

    dW/ds = S11 s + S12 t,   dW/dt = S12 s + S22 t,   dW/dx0 = -(dW/ds + dW/dt).

The Hessian in ``(s, t)`` is the material part ``B^T D B`` (``D`` the Voigt stiffness of the
quadratic form in ``E``, which depends only on the rest state, ``B`` the derivative of
``(E11, E22, 2 E12)``) plus the geometric part ``S_ab I``; it is mapped to the three vertices by
``s = x1 - x0``, ``t = x2 - x0``. The Hessian is the true one (indefinite under compression).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

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
    (by default the initial sphere). See the module docstring for the derivatives.

    Fields: ``faces (F, 3)`` int, ``n_vertices``, ``abar_inv (F, 2, 2)`` inverse rest metric,
    ``rest_area (F,)``, ``A`` 2D Young modulus (energy / length^2), ``nu`` 2D Poisson ratio in
    (-1, 1). Build with :meth:`from_reference` or :meth:`from_form_factors`.
    """

    faces: np.ndarray
    n_vertices: int
    abar_inv: np.ndarray
    rest_area: np.ndarray
    A: float
    nu: float
    _k: dict = field(init=False, repr=False)
    _assembler: ElementAssembler = field(init=False, repr=False)

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
        det = q11 * q22 - q12 * q12
        if not (np.isfinite(det).all() and (det > 0).all() and (q11 > 0).all()):
            f = int(np.flatnonzero(~(np.isfinite(det) & (det > 0) & (q11 > 0)))[0])
            raise ValueError(f"abar_inv of face {f} is not symmetric positive definite: {Q[f]}")
        c1 = A / (2.0 * (1.0 + nu))
        c2 = c1 * nu / (1.0 - nu)
        w1, w2 = 2.0 * c1 * area, 2.0 * c2 * area
        k = dict(
            f0=faces[:, 0].copy(), f1=faces[:, 1].copy(), f2=faces[:, 2].copy(),
            q11=q11.copy(), q12=q12.copy(), q22=q22.copy(),
            a11=q22 / det, a12=-q12 / det, a22=q11 / det,  # rest metric abar
            c1=c1, c2=c2, area=area, w1=w1, w2=w2,
            # Voigt stiffness D (x area) on (E11, E22, 2 E12); depends only on the rest state
            D11=(w1 + w2) * q11 * q11, D22=(w1 + w2) * q22 * q22,
            D12=w1 * q12 * q12 + w2 * q11 * q22,
            D13=(w1 + w2) * q11 * q12, D23=(w1 + w2) * q12 * q22,
            D33=0.5 * w1 * (q11 * q22 + q12 * q12) + w2 * q12 * q12,
        )
        object.__setattr__(self, "faces", faces)
        object.__setattr__(self, "n_vertices", int(self.n_vertices))
        object.__setattr__(self, "abar_inv", Q)
        object.__setattr__(self, "rest_area", area)
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "nu", nu)
        object.__setattr__(self, "_k", k)
        object.__setattr__(self, "_assembler", ElementAssembler(faces, self.n_vertices))

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
    def _check_X(self, X) -> np.ndarray:
        X = np.asarray(X, dtype=np.float64)
        if X.shape != (self.n_vertices, 3):
            raise ValueError(f"positions must have shape ({self.n_vertices}, 3), got {X.shape}")
        return X

    def _edges(self, X):
        """Edge vectors ``s = x1 - x0``, ``t = x2 - x0`` as component-major ``(3, F)``."""
        k = self._k
        Xt = np.ascontiguousarray(self._check_X(X).T)
        x0 = np.take(Xt, k["f0"], axis=1)
        s = np.take(Xt, k["f1"], axis=1)
        s -= x0
        t = np.take(Xt, k["f2"], axis=1)
        t -= x0
        return s, t

    def _strain(self, s, t):
        """Mixed strain ``P = Q E`` entries and its trace, each ``(F,)``."""
        k = self._k
        E11 = 0.5 * (np.einsum("ij,ij->j", s, s) - k["a11"])
        E12 = 0.5 * (np.einsum("ij,ij->j", s, t) - k["a12"])
        E22 = 0.5 * (np.einsum("ij,ij->j", t, t) - k["a22"])
        q11, q12, q22 = k["q11"], k["q12"], k["q22"]
        P11 = q11 * E11 + q12 * E12
        P12 = q11 * E12 + q12 * E22
        P21 = q12 * E11 + q22 * E12
        P22 = q12 * E12 + q22 * E22
        return P11, P12, P21, P22

    def _density(self, P):
        P11, P12, P21, P22 = P
        tr = P11 + P22
        return self._k["c1"] * (P11 * P11 + 2.0 * P12 * P21 + P22 * P22) + self._k["c2"] * tr * tr

    def _stress(self, P):
        """Area-weighted stress ``S = 2 rest_area (c1 Q E Q + c2 Tr(e) Q)``, entries ``(F,)``."""
        k = self._k
        P11, P12, P21, P22 = P
        q11, q12, q22 = k["q11"], k["q12"], k["q22"]
        w1 = k["w1"]
        w2tr = k["w2"] * (P11 + P22)
        S11 = w1 * (P11 * q11 + P12 * q12) + w2tr * q11
        S12 = w1 * (P11 * q12 + P12 * q22) + w2tr * q12
        S22 = w1 * (P21 * q12 + P22 * q22) + w2tr * q22
        return S11, S12, S22

    def _local_gradient(self, s, t, S):
        S11, S12, S22 = S
        gs = S11 * s + S12 * t
        gt = S12 * s + S22 * t
        return np.stack([-(gs + gt), gs, gt], axis=1).transpose(2, 1, 0)  # (F, 3, 3)

    # ---------------------------------------------------------------- public API
    def density(self, X) -> np.ndarray:
        """Energy per rest area of every face, shape ``(F,)`` (for colouring a viewer)."""
        return self._density(self._strain(*self._edges(X)))

    def value(self, X) -> float:
        return float(np.dot(self._density(self._strain(*self._edges(X))), self._k["area"]))

    def gradient(self, X) -> np.ndarray:
        """Exact gradient, shape ``(V, 3)``."""
        return self.value_and_gradient(X)[1]

    def value_and_gradient(self, X) -> tuple[float, np.ndarray]:
        s, t = self._edges(X)
        P = self._strain(s, t)
        E = float(np.dot(self._density(P), self._k["area"]))
        local = self._local_gradient(s, t, self._stress(P))
        return E, self._assembler.gradient(local)

    def hessian(self, X) -> sp.csr_matrix:
        """Exact (true, possibly indefinite) Hessian, CSR ``(3V, 3V)``, vertex-major dofs."""
        k = self._k
        s, t = self._edges(X)
        S11, S12, S22 = self._stress(self._strain(s, t))
        s, t = s.T, t.T  # (F, 3)
        ss = s[:, :, None] * s[:, None, :]
        st = s[:, :, None] * t[:, None, :]
        ts = st.transpose(0, 2, 1)
        tt = t[:, :, None] * t[:, None, :]
        eye = np.eye(3)

        def comb(cI, css, cst, cts, ctt):
            return (cI[:, None, None] * eye + css[:, None, None] * ss + cst[:, None, None] * st
                    + cts[:, None, None] * ts + ctt[:, None, None] * tt)

        D11, D22, D12, D13, D23, D33 = (k[n] for n in ("D11", "D22", "D12", "D13", "D23", "D33"))
        Hss = comb(S11, D11, D13, D13, D33)
        Hst = comb(S12, D13, D12, D33, D23)
        Htt = comb(S22, D33, D23, D23, D22)
        Hts = Hst.transpose(0, 2, 1)
        H = np.empty((len(s), 3, 3, 3, 3))  # (f, a, c, b, d)
        H[:, 1, :, 1, :] = Hss
        H[:, 1, :, 2, :] = Hst
        H[:, 2, :, 1, :] = Hts
        H[:, 2, :, 2, :] = Htt
        H[:, 0, :, 1, :] = -(Hss + Hts)
        H[:, 0, :, 2, :] = -(Hst + Htt)
        H[:, 1, :, 0, :] = -(Hss + Hst)
        H[:, 2, :, 0, :] = -(Hts + Htt)
        H[:, 0, :, 0, :] = Hss + Hst + Hts + Htt
        return self._assembler.hessian(H.reshape(-1, 9, 9))
