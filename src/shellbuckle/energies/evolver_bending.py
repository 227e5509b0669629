"""Surface Evolver's ``star_perp_sq_mean_curvature`` bending energy, exactly as Evolver 2.70 computes it.

Definition (Surface Evolver manual, "star_perp_sq_mean_curvature", and source ``sqcurve3.c``,
function ``star_sqcurve_method_all``, case ``PERP_SQ``). For every vertex ``i`` with the
star of faces ``f`` around it:

- ``F_i = sum_f d a_f / d x_i``, the area gradient at the vertex (3-vector);
- ``M_i = sum_f n_f / 2`` with ``n_f = (x1 - x0) x (x2 - x0)``, the sum of the face area
  vectors; on a closed star ``M_i = 3 N_i`` with ``N_i = dV / dx_i`` the volume gradient;
- ``S_i = sum_f a_f``, the area of the whole star (full face areas, not a third);
- ``h_i = (3/2) F_i . M_i / M_i . M_i = (1/2) F_i . N_i / N_i . N_i`` (mean curvature,
  ``+1/R`` on a sphere of radius ``R`` whose faces are oriented outwards);
- ``E = modulus * sum_i (h_i - h_zero)^2 S_i / 3``.

Evolver evaluates it as ``modulus * 0.75 * S * (fn/nn - 2 h_zero / 3)^2`` with
``fn = F.M``, ``nn = M.M``, which is the same number. Where ``M_i = 0`` Evolver sets ``h_i = 0``;
so do we.

Convention of this package: the bending energy is ``(1/2) kappa (c - c0)^2`` per area with
``c = c1 + c2 = 2 H``, so ``2 kappa (H - c0/2)^2``. Hence

    modulus = 2 kappa,      h_zero = c0 / 2,

and the stress-free sphere of radius ``R`` has ``c0 = 2/R`` (``h_zero = 1/R``).

Derivatives. ``E = sum_i g(q_i)`` with ``q_i = (F_i, M_i, S_i)`` in R^7, each a sum over the
(face, corner) pairs of vertex ``i`` of functions of the face's 9 coordinates. With ``J`` the
sparse ``(7V, 3V)`` Jacobian of all ``q_i`` and ``D_i`` the ``7 x 7`` Hessian of ``g`` at
``q_i``::

    grad E = J^T (dg/dq),      Hess E = J^T D J + sum_i sum_k (dg/dq_ik) Hess(q_ik).

The per-face pieces are written with the constant tensor ``B (3, 9, 9)`` such that
``n_k = (1/2) y^T B_k y`` for the face coordinates ``y = (x0, x1, x2)``: ``dn/dy = N`` with rows
``B_k y``, ``grad a = (1/2) N^T n_hat`` and ``Hess a = (1/2)[N^T (I - n_hat n_hat^T) N / |n| +
sum_k n_hat_k B_k]``. ``F`` is a block of ``grad a``, so the Hessian of ``lambda . F`` needs the
third derivative of the area contracted with ``v`` (``lambda`` at the corner's block):
with ``m = N v`` and ``psi = v . grad a = (1/2) m . n_hat``,

    Hess psi = (1/2)[Mv^T P N / |n| + N^T P Mv / |n| + sum_k (P m / |n|)_k B_k + N^T Q N],
    Q = [-(m n_hat^T + n_hat m^T) - (n_hat.m) I + 3 (n_hat.m) n_hat n_hat^T] / |n|^2,

where ``P = I - n_hat n_hat^T`` and ``Mv`` has rows ``B_k v``. All of this is exact (no finite
differences); the tests compare it with central differences and with energies Surface Evolver
computed.

Implementation: the value with the gradient and the Hessian are compiled loops over the faces
and the vertices (:func:`.kernels.star_perp`, :func:`.kernels.star_perp_hessian`, Numba); the
Hessian is added straight into the data of a CSR matrix whose pattern couples the vertices of
every star (:class:`.bending.StarPattern`, built on the first call and shared by the copies
that ``dataclasses.replace`` makes, :func:`.total.with_c0` in the c0 cycle).

Reference: K. A. Brakke, "The Surface Evolver", Experimental Mathematics 1 (1992) 141-165;
Surface Evolver 2.70 manual, section "Named methods", ``star_perp_sq_mean_curvature``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from . import kernels
from .bending import StarPattern, c0_per_vertex


@dataclass(frozen=True, eq=False)
class StarPerpBending:
    """Surface Evolver's ``star_perp_sq_mean_curvature`` in the package's bending convention.

    ``E = 2 kappa * sum_i (h_i - c0_i / 2)^2 S_i / 3`` over the vertices that carry the energy,
    i.e. Evolver's ``modulus (h - h_zero)^2 S / 3`` with ``modulus = 2 kappa`` and
    ``h_zero = c0 / 2`` (``c = c1 + c2``; ``c0 = 2/R`` is the stress-free sphere). See the module
    docstring for ``h_i`` and ``S_i``. Faces must be oriented outwards (then ``h = +1/R`` on a
    sphere); Evolver measures ``h`` along the facets' own orientation.

    ``value(X) -> float``, ``gradient(X) -> (V, 3)``, ``hessian(X) -> csr (3V, 3V)`` (exact,
    not projected), ``mean_curvature(X) -> (V,)``.

    Parameters
    ----------
    faces : (F, 3) int
        Triangles of a closed surface.
    n_vertices : int
    kappa : float
        Bending modulus (energy). Evolver's quantity modulus is ``2 kappa``.
    c0 : float or (V,) array
        Spontaneous curvature in the ``c1 + c2`` convention, one value or one per vertex
        (Evolver's ``h_zero`` parameter or vertex attribute is ``c0 / 2``).
    vertices : (k,) int or None
        Vertices whose term is counted (a non-global Evolver quantity); ``None`` means all.
    c0_profile : (V,) array or None
        Multiplies ``c0`` vertex by vertex (a shell whose stress-free shape is not a sphere,
        :class:`.bending.Bending`); kept by ``with_c0``.
    """

    faces: np.ndarray
    n_vertices: int
    kappa: float = 1.0
    c0: float | np.ndarray = 2.0
    vertices: np.ndarray | None = None
    c0_profile: np.ndarray | None = None
    _tables: dict | None = field(default=None, repr=False)
    """Topology tables (faces coordinate-major; the Hessian's pattern once built), shared by the
    copies that ``dataclasses.replace`` makes (``with_c0`` in the c0 cycle), as
    ``Bending._plan`` is."""
    _weight: np.ndarray = field(init=False, repr=False)
    _h0: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        faces = np.ascontiguousarray(self.faces, dtype=np.int64)
        V = int(self.n_vertices)
        if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
            raise ValueError(f"faces must be a non-empty (F, 3) integer array, got shape {faces.shape}")
        if not np.isfinite(self.kappa):
            raise ValueError(f"kappa must be a finite number, got {self.kappa!r}")
        c0 = np.asarray(self.c0, dtype=np.float64)
        if c0.ndim == 0:
            c0 = np.full(V, float(c0))
        if c0.shape != (V,) or not np.isfinite(c0).all():
            raise ValueError(f"c0 must be a finite number or a ({V},) array of finite numbers")
        if self.c0_profile is not None:
            c0 = c0_per_vertex(1.0, self.c0_profile, V) * c0
        weight = np.ones(V)
        if self.vertices is not None:
            chosen = np.asarray(self.vertices, dtype=np.int64)
            if chosen.size and (chosen.min() < 0 or chosen.max() >= V):
                raise ValueError(f"vertices must be indices in [0, {V}), got range "
                                 f"[{chosen.min()}, {chosen.max()}]")
            weight = np.zeros(V)
            weight[chosen] = 1.0
        object.__setattr__(self, "faces", faces)
        object.__setattr__(self, "n_vertices", V)
        object.__setattr__(self, "_h0", 0.5 * c0)
        object.__setattr__(self, "_weight", weight)
        if self._tables is None:  # the Hessian pattern is added on the first hessian() call
            if faces.min() < 0 or faces.max() >= V:
                raise ValueError(f"faces must index vertices in [0, {V}), got range "
                                 f"[{faces.min()}, {faces.max()}]")
            object.__setattr__(self, "_tables", {"FT": np.ascontiguousarray(faces.T)})

    @classmethod
    def from_evolver(cls, faces, n_vertices, modulus: float, h_zero=0.0, vertices=None):
        """Build from Evolver's quantity ``modulus`` and ``h_zero`` (kappa = modulus/2, c0 = 2 h_zero)."""
        return cls(faces, n_vertices, kappa=0.5 * float(modulus),
                   c0=2.0 * np.asarray(h_zero, dtype=np.float64), vertices=vertices)

    @property
    def modulus(self) -> float:
        """Evolver's quantity modulus, ``2 kappa``."""
        return 2.0 * float(self.kappa)

    @property
    def c0_vertices(self) -> np.ndarray:
        """The spontaneous curvature of each vertex, ``2 h_zero``, ``(V,)``."""
        return 2.0 * self._h0

    @property
    def h_zero(self) -> np.ndarray:
        """Evolver's ``h_zero`` per vertex, ``c0 / 2``, shape ``(V,)``."""
        return self._h0.copy()

    # -- energy interface --------------------------------------------------------------------
    def _positions(self, X):
        return kernels.positions(X, self.n_vertices)

    def mean_curvature(self, X) -> np.ndarray:
        """Evolver's vertex mean curvature ``h = (1/2) F.N / N.N``, shape ``(V,)``."""
        F, M, _ = kernels._star_perp_sums(self._positions(X), self._tables["FT"])
        u = np.einsum("vk,vk->v", F, M)
        w = np.einsum("vk,vk->v", M, M)
        return np.where(w > 0.0, 1.5 * u / np.where(w > 0.0, w, 1.0), 0.0)

    def _compiled(self, X, gradient: bool):
        value, G = kernels.star_perp(self._positions(X), self._tables["FT"], self.modulus,
                                     self._h0, self._weight, gradient)
        return float(value), G

    def value(self, X) -> float:
        return self._compiled(X, False)[0]

    def gradient(self, X) -> np.ndarray:
        return self._compiled(X, True)[1]

    def value_and_gradient(self, X) -> tuple[float, np.ndarray]:
        """Energy and gradient ``(V, 3)`` from one compiled pass (the value is :meth:`value`'s,
        bit for bit)."""
        return self._compiled(X, True)

    def _pattern(self):
        t = self._tables
        if "pattern" not in t:  # benign race: two threads may both build the same tables
            FT = t["FT"]
            lo = np.minimum(FT, np.roll(FT, -1, axis=0)).ravel()
            hi = np.maximum(FT, np.roll(FT, -1, axis=0)).ravel()
            keys = np.unique(lo * self.n_vertices + hi)
            edges = np.stack([keys // self.n_vertices, keys % self.n_vertices])
            pattern = StarPattern(edges, self.n_vertices)
            t["face_maps"] = pattern.element_maps(FT)
            t["pattern"] = pattern
        return t["pattern"], t["face_maps"]

    def hessian(self, X) -> sp.csr_matrix:
        """Exact Hessian (not projected), CSR ``(3V, 3V)`` with a fixed pattern."""
        s, (face_slot, face_off) = self._pattern()
        data = kernels.star_perp_hessian(self._positions(X), self._tables["FT"], self.modulus,
                                         self._h0, self._weight, face_slot, face_off,
                                         s.star_ptr, s.star_member, s.star_sq_ptr, s.star_off,
                                         s.stride, s.mirror, np.empty(s.n_data))
        return s.matrix(data)
