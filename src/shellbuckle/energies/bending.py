"""Helfrich bending energy, discretized with Jülicher's edge-based mean curvature.

Model
-----
    E = ∫ 1/2 kappa (c - c0)^2 dS,   c = c1 + c2 = 2 H,

so the stress-free sphere of radius R has ``c0 = 2 / R`` and a sphere with ``c0 = 0`` has
``E = 8 pi kappa`` whatever its radius. (Surface Evolver's ``star_perp_sq_mean_curvature``
writes ``modulus (h - h_zero)^2`` with the mean curvature ``h``: ``h_zero = c0 / 2``,
``modulus = 2 kappa``. The paper's "c0 = 1/R" is in that convention.)

Discretization (Jülicher 1996)
------------------------------
Per vertex ``i``, with ``theta_e`` the signed dihedral angle between the outward normals of
the two faces of edge ``e`` (positive where convex, :mod:`.hinge`) and ``l_e`` its length,

    M_i = 1/4 sum_{e at i} l_e theta_e      (integrated mean curvature, H = (c1 + c2) / 2),
    A_i = 1/3 sum_{f at i} area_f,          H_i = M_i / A_i,
    E   = sum_i kappa/2 (2 H_i - c0)^2 A_i
        = sum_i kappa/2 (4 M_i^2 / A_i - 4 c0 M_i + c0^2 A_i).

A shell whose stress-free shape is not a sphere (:mod:`shellbuckle.protocol.imperfection`,
"Shape imperfection") has a spontaneous curvature per vertex, ``c0_i = c0 p_i`` with a fixed
profile ``p_i`` (``c0 = 2/R`` gives the stress-free shape's curvature ``2 p_i / R``; ``c0 = 0``
gives zero everywhere, as the c0 cycle needs); the formulas below hold vertex by vertex.

``sum_i M_i = 1/2 sum_e l_e theta_e`` is the exact integrated mean curvature of a convex
polyhedron (Steiner). References: F. Jülicher, "The morphology of vesicles of higher
topological genus: conformal degeneracy and conformal modes", J. Phys. II France 6, 1797
(1996); X. Bian, S. Litvinov, P. Koumoutsakos, "Bending models of lipid bilayer membranes:
spontaneous curvature and area-difference elasticity", Comput. Methods Appl. Mech. Engrg.
(2020), who call it the "Jülicher" model and implement it with exactly these ``M_i``, ``A_i``
and ``2 kappa (H_i - c0/2)^2 A_i`` in their code ``corpuscles`` (``lib/f/juelicher.c``).

Derivatives (exact)
-------------------
``E = sum_i f(M_i, A_i)`` with ``f_M = 2 kappa (2 H - c0)``, ``f_A = kappa/2 (c0^2 - 4 H^2)``
and a rank-one second derivative ``[[f_MM, f_MA], [f_MA, f_AA]] = 4 kappa / A (1, -H)(1, -H)^T``
(``M^2 / A`` is homogeneous of degree one). Hence

    grad E = sum_e w_e grad(l_e theta_e) + sum_f u_f grad(area_f),
    Hess E = sum_e w_e Hess(l_e theta_e) + sum_f u_f Hess(area_f)
             + sum_i (4 kappa / A_i) g_i g_i^T,       g_i = grad M_i - H_i grad A_i,

with ``w_e = (f_M,i + f_M,j) / 4`` over the edge's end points and ``u_f = sum_{v in f} f_A,v / 3``.
``g_i`` lives on the star of ``i`` (``i`` and its neighbours), so the last term couples
vertices up to two edges apart; the Hessian pattern is the union of the stars' squares.

Implementation
--------------
The value and the gradient come from one compiled loop over hinges and faces
(:func:`.kernels.juelicher`, Numba), the Hessian from another
(:func:`.kernels.juelicher_hessian`), which adds every hinge's, face's and star's 3x3 blocks
straight into the data of a CSR matrix whose pattern (sorted indices, the union of the stars'
squares) and whose block offsets per element are built once (:class:`_Plan`); the element
formulas are those of the NumPy kernels of :mod:`.hinge`, against which the tests compare
both, and against central differences. Elements are ordered by a reverse Cuthill-McKee
numbering of the vertices, so that the scatters touch memory locally whatever the mesh's own
vertex numbering. Dofs are vertex-major (``3 v + c``).
"""

from __future__ import annotations

import dataclasses
import threading
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from . import hinge as hg
from . import kernels
from .assembly import block_layout


@dataclass(frozen=True, eq=False)
class Bending:
    """Helfrich bending ``sum_i kappa/2 (2 H_i - c0)^2 A_i`` with Jülicher mean curvature.

    ``faces (F, 3)`` and ``hinges (E, 4)`` as in :class:`shellbuckle.mesh.Topology` (closed,
    outward oriented), ``n_vertices``, bending modulus ``kappa`` (energy) and spontaneous
    curvature ``c0`` in the convention ``c = c1 + c2`` (``c0 = 2/R`` for a stress-free sphere
    of radius ``R``; ``c0 = 0`` gives ``8 pi kappa`` on any sphere). ``c0_profile (V,)``, if
    given, makes the spontaneous curvature of vertex ``i`` ``c0 * c0_profile[i]`` (a shell
    whose stress-free shape is not a sphere; module docstring). Build it with
    :meth:`from_mesh`; change ``c0`` with :meth:`with_c0`, which shares the precomputed plan
    and keeps the profile.
    """

    faces: np.ndarray
    hinges: np.ndarray
    n_vertices: int
    kappa: float = 1.0
    c0: float = 2.0
    c0_profile: np.ndarray | None = None
    _plan: "_Plan" = field(default=None, repr=False)
    _c0v: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        kappa, c0 = float(self.kappa), float(self.c0)
        if not (np.isfinite(kappa) and kappa > 0):
            raise ValueError(f"bending modulus kappa must be a positive finite number, got {self.kappa!r}")
        if not np.isfinite(c0):
            raise ValueError(f"spontaneous curvature c0 must be a finite number, got {self.c0!r}")
        object.__setattr__(self, "kappa", kappa)
        object.__setattr__(self, "c0", c0)
        if self._plan is None:
            FT = hg._elements(self.faces, 3, "faces")
            HT = hg._elements(self.hinges, 4, "hinges")
            n = int(self.n_vertices)
            for name, arr in (("faces", FT), ("hinges", HT)):
                if arr.size == 0:
                    raise ValueError(f"{name} is empty")
                if arr.min() < 0 or arr.max() >= n:
                    raise ValueError(f"{name} vertex indices must lie in [0, {n}), got "
                                     f"[{arr.min()}, {arr.max()}]")
            object.__setattr__(self, "faces", np.ascontiguousarray(FT.T))
            object.__setattr__(self, "hinges", np.ascontiguousarray(HT.T))
            object.__setattr__(self, "n_vertices", n)
            object.__setattr__(self, "_plan", _Plan(FT, HT, n))
        object.__setattr__(self, "_c0v", c0_per_vertex(c0, self.c0_profile, self.n_vertices))

    @classmethod
    def from_mesh(cls, mesh_or_topology, kappa: float = 1.0, c0: float = 2.0,
                  c0_profile=None) -> "Bending":
        """From a :class:`~shellbuckle.mesh.Mesh` or a :class:`~shellbuckle.mesh.Topology`."""
        t = getattr(mesh_or_topology, "topology", mesh_or_topology)
        return cls(faces=t.faces, hinges=t.hinges, n_vertices=t.n_vertices, kappa=kappa, c0=c0,
                   c0_profile=c0_profile)

    def with_c0(self, c0: float) -> "Bending":
        """The same term with spontaneous curvature ``c0`` (convention ``c = c1 + c2``; times
        the profile, if any)."""
        return dataclasses.replace(self, c0=c0)

    @property
    def c0_vertices(self) -> np.ndarray:
        """The spontaneous curvature of each vertex, ``c0`` times the profile, ``(V,)``."""
        return self._c0v.copy()

    # ------------------------------------------------------------------ per-vertex quantities

    def _XT(self, X):
        return np.ascontiguousarray(kernels.positions(X, self.n_vertices).T)

    def _MA(self, XT):
        p = self._plan
        hk = hg.hinge_kernel(XT, p.HT, order=0)
        fk = hg.face_kernel(XT, p.FT, order=0)
        return p.vertex_sums(hk.phi, fk.area)

    def vertex_areas(self, X) -> np.ndarray:
        """``A_i = 1/3 sum_{f at i} area_f``, shape ``(V,)``."""
        return self._MA(self._XT(X))[1]

    def mean_curvature(self, X) -> np.ndarray:
        """Discrete mean curvature ``H_i = M_i / A_i = (c1 + c2) / 2`` (``1/R`` on a sphere), ``(V,)``."""
        M, A = self._MA(self._XT(X))
        return M / A

    def vertex_energy(self, X) -> np.ndarray:
        """Bending energy of each vertex, ``kappa/2 (2 H_i - c0_i)^2 A_i``, shape ``(V,)``."""
        M, A = self._MA(self._XT(X))
        return 0.5 * self.kappa * (2.0 * M / A - self._c0v) ** 2 * A

    # ------------------------------------------------------------------ energy interface

    def _compiled(self, X, gradient: bool):
        """``(value, gradient or (0, 3))`` from :func:`.kernels.juelicher`."""
        p, X = self._plan, kernels.positions(X, self.n_vertices)
        value, G = kernels.juelicher(X, p.HT, p.FT, self.kappa, self._c0v, gradient)
        return float(value), G

    def value(self, X) -> float:
        return self._compiled(X, False)[0]

    def _weights(self, M, A):
        p, kappa, c0 = self._plan, self.kappa, self._c0v
        H = M / A
        f_M = 2.0 * kappa * (2.0 * H - c0)
        f_A = 0.5 * kappa * (c0 * c0 - 4.0 * H * H)
        w_hinge = 0.25 * (f_M[p.HT[0]] + f_M[p.HT[1]])
        w_face = (f_A[p.FT[0]] + f_A[p.FT[1]] + f_A[p.FT[2]]) / 3.0
        return H, w_hinge, w_face

    def gradient(self, X) -> np.ndarray:
        """Exact gradient ``(V, 3)``."""
        return self.value_and_gradient(X)[1]

    def value_and_gradient(self, X) -> tuple[float, np.ndarray]:
        """Energy and gradient ``(V, 3)`` from one compiled pass over the mesh
        (:func:`.kernels.juelicher`; the value is :meth:`value`'s, bit for bit)."""
        return self._compiled(X, True)

    def hessian(self, X) -> sp.csr_matrix:
        """Exact (indefinite in general) Hessian, CSR ``(3V, 3V)``, vertex-major dofs; the
        same pattern (sorted indices) at every call (:func:`.kernels.juelicher_hessian`)."""
        p, X = self._plan, kernels.positions(X, self.n_vertices)
        p.prepare_hessian()
        s = p.pattern
        data = kernels.juelicher_hessian(X, p.HT, p.FT, self.kappa, self._c0v, p.hinge_off,
                                         p.face_off, p.hinge_slot, p.face_slot, s.star_ptr,
                                         s.star_member, s.star_sq_ptr, s.star_off, s.stride,
                                         s.mirror, np.empty(s.n_data))
        return s.matrix(data)


def c0_per_vertex(c0: float, profile, n_vertices: int) -> np.ndarray:
    """The spontaneous curvature of each vertex, ``c0 * profile`` (``(V,)``; ``c0``
    everywhere without a profile)."""
    if profile is None:
        return np.full(int(n_vertices), float(c0))
    p = np.asarray(profile, dtype=np.float64)
    if p.shape != (int(n_vertices),) or not np.isfinite(p).all():
        raise ValueError(f"c0_profile must be a ({int(n_vertices)},) array of finite numbers, "
                         f"got shape {p.shape}")
    return float(c0) * p


class StarPattern:
    """The CSR layout of a Hessian that couples the vertices of every *star* (a vertex, in slot
    0, followed by its neighbours in increasing order): block ``(a, b)`` exists iff ``a`` and
    ``b`` lie in a common star, so it reaches two edges apart. Built once per mesh from its
    edges ``(2, E)`` (each once, either direction) and shared by the compiled bending Hessians
    (:func:`.kernels.juelicher_hessian`, :func:`.kernels.star_perp_hessian`).

    The star slots of all vertices are numbered consecutively (``star_ptr (V + 1)``,
    ``star_member`` the vertex in each slot). Block row ``a`` holds its blocks ``(a, b)``, ``b``
    increasing, each with ``d = 0..2`` in every one of its three rows: entry ``(c, d)`` of
    block ``(a, b)`` lies at ``offset(a, b) + c stride[a] + d`` of the data, with sorted CSR
    ``indices`` and ``indptr`` over the ``3V`` dofs (vertex-major). ``star_off`` gives the
    offset of every pair of slots of every star (``n^2`` pairs of a star of ``n`` slots,
    from ``star_sq_ptr``), ``mirror (2, m)`` every entry above the diagonal with its transpose.
    """

    def __init__(self, edges: np.ndarray, n_vertices: int):
        V = int(n_vertices)
        centers = np.concatenate([edges[0], edges[1]])
        members = np.concatenate([edges[1], edges[0]])
        valence = np.bincount(centers, minlength=V)
        order = np.lexsort((members, centers))
        star_ptr = np.zeros(V + 1, dtype=np.int64)
        np.cumsum(valence + 1, out=star_ptr[1:])
        n_slots = int(star_ptr[-1])
        star_center = np.repeat(np.arange(V), valence + 1)
        star_member = np.empty(n_slots, dtype=np.int64)
        is_self = np.zeros(n_slots, dtype=bool)
        is_self[star_ptr[:-1]] = True
        star_member[is_self] = np.arange(V)
        star_member[~is_self] = members[order]
        slot_keys = star_center * V + star_member
        self._slot_sorter = np.argsort(slot_keys)
        self._slot_keys = slot_keys[self._slot_sorter]
        self.V, self.star_ptr, self.star_member = V, star_ptr, star_member
        # the blocks: every pair of slots of every star, i.e. the pattern of S S with
        # S = I + adjacency (two vertices lie in a common star iff they are at most two edges
        # apart), sorted row by row
        n = np.diff(star_ptr)
        S = sp.csr_matrix((np.ones(n_slots, dtype=np.int32), star_member, star_ptr),
                          shape=(V, V))
        S2 = (S @ S).tocsr()
        S2.sort_indices()
        self._bptr = bptr = S2.indptr.astype(np.int64)
        bcol = S2.indices.astype(np.int64)
        brow = np.repeat(np.arange(V), np.diff(bptr))
        n_blocks = len(bcol)
        # block number + 1 at (a, b): offset() looks blocks up row by row (a few entries each)
        self._block = sp.csr_matrix((np.arange(1, n_blocks + 1), bcol, bptr), shape=(V, V))
        first, self.stride, self.indices, self.indptr = block_layout(bptr, bcol)
        self.n_data = len(self.indices)
        self.star_sq_ptr = np.zeros(V + 1, dtype=np.int64)
        np.cumsum(n * n, out=self.star_sq_ptr[1:])
        owner = np.repeat(np.arange(V), n * n)
        within = np.arange(self.star_sq_ptr[-1]) - self.star_sq_ptr[owner]
        row = star_member[star_ptr[owner] + within // n[owner]]
        col = star_member[star_ptr[owner] + within % n[owner]]
        self.star_off = self.offset(row, col)
        # entry (c, d) of block k = (a, b) lies at first[k] + c stride[a] + d; its transpose,
        # entry (d, c) of block (b, a), at first[k'] + d stride[b] + c
        first_t = self.offset(bcol, brow)
        transpose = np.empty(self.n_data, dtype=np.int64)
        for c in range(3):
            for d in range(3):
                transpose[first + c * self.stride[brow] + d] = first_t + d * self.stride[bcol] + c
        row_of = np.repeat(np.arange(3 * V), np.diff(self.indptr))
        upper = np.flatnonzero(self.indices > row_of)
        self.mirror = np.stack([upper, transpose[upper]])

    def slot(self, center, member):
        """Global star slot of vertex ``member`` in the star of ``center`` (arrays)."""
        return self._slot_sorter[np.searchsorted(self._slot_keys, center * self.V + member)]

    def offset(self, a, b):
        """Position of entry ``(0, 0)`` of block ``(a, b)`` in the CSR data (arrays)."""
        a, b = np.asarray(a), np.asarray(b)
        k = np.asarray(self._block[a.ravel(), b.ravel()]).reshape(a.shape) - 1
        return 9 * self._bptr[a] + 3 * (k - self._bptr[a])

    def element_maps(self, FT: np.ndarray):
        """For faces ``FT (3, F)``: the star slot of every corner in the stars of the three
        corners ``(3 centres, 3 corners, F)`` and the offsets of the blocks of every pair of
        corners ``(3, 3, F)``."""
        centers = np.repeat(FT[:, None, :], 3, axis=1)  # [p, a, f] = FT[p, f]
        corners = np.repeat(FT[None, :, :], 3, axis=0)  # [p, a, f] = FT[a, f]
        return self.slot(centers, corners), self.offset(centers, corners)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        n = 3 * self.V
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(n, n))


class _Plan:
    """Index arrays of one mesh, built once: hinges and faces in a memory-local order, and the
    Hessian's :class:`StarPattern` with the offsets of every element's blocks in it."""

    def __init__(self, FT: np.ndarray, HT: np.ndarray, n_vertices: int):
        V = n_vertices
        centers = np.concatenate([HT[0], HT[1]])
        members = np.concatenate([HT[1], HT[0]])
        valence = np.bincount(centers, minlength=V)
        if (valence < 3).any():
            v = int(np.flatnonzero(valence < 3)[0])
            raise ValueError(f"vertex {v} has {valence[v]} edges; a closed surface needs at least 3")
        # a bandwidth-reducing vertex order (reverse Cuthill-McKee) used only internally: it
        # orders elements and pattern blocks so that the scatters and the transposition touch
        # memory locally, whatever the mesh's own numbering
        adjacency = sp.csr_matrix((np.ones(len(centers), dtype=np.int8), (centers, members)), shape=(V, V))
        rank = np.empty(V, dtype=np.int64)
        rank[reverse_cuthill_mckee(adjacency, symmetric_mode=True)] = np.arange(V)
        HT = np.ascontiguousarray(HT[:, np.argsort(rank[HT].min(axis=0), kind="stable")])
        FT = np.ascontiguousarray(FT[:, np.argsort(rank[FT].min(axis=0), kind="stable")])
        self.V, self.FT, self.HT = V, FT, HT
        self._lock = threading.Lock()
        self._hessian_ready = False

    def __getstate__(self):  # picklable (e.g. for process pools): drop the lock
        state = self.__dict__.copy()
        del state["_lock"]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._lock = threading.Lock()

    def prepare_hessian(self):
        """Build the Hessian's index arrays on first use (value and gradient do not need them)."""
        if not self._hessian_ready:
            with self._lock:
                if not self._hessian_ready:
                    self._build_hessian_plan()
                    self._hessian_ready = True

    def _build_hessian_plan(self):
        """The star pattern of the Hessian and the offsets of every hinge's and face's blocks
        in its CSR data (:func:`.kernels.juelicher_hessian`)."""
        HT, FT = self.HT, self.FT
        pattern = self.pattern = StarPattern(HT[:2], self.V)
        self.hinge_slot = np.stack([np.stack([pattern.slot(HT[s], HT[a]) for a in range(4)])
                                    for s in range(2)])  # (2 end points, 4 hinge vertices, E)
        self.hinge_off = np.stack([np.stack([pattern.offset(HT[p], HT[q]) for q in range(4)])
                                   for p in range(4)])
        self.face_slot, self.face_off = pattern.element_maps(FT)

    # -------------------------------------------------------------- reductions

    def vertex_sums(self, phi, area):
        """``M_i = 1/4 sum l theta`` and ``A_i = 1/3 sum area`` over the edges/faces at ``i``."""
        V = self.V
        M = np.bincount(self.HT[0], weights=phi, minlength=V)
        M += np.bincount(self.HT[1], weights=phi, minlength=V)
        A = np.bincount(self.FT[0], weights=area, minlength=V)
        A += np.bincount(self.FT[1], weights=area, minlength=V)
        A += np.bincount(self.FT[2], weights=area, minlength=V)
        return 0.25 * M, A / 3.0
