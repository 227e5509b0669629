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
(:func:`.kernels.juelicher`, Numba), the Hessian from NumPy kernels vectorized over hinges,
faces and stars (:mod:`.hinge`); the tests check each gradient against the other and against
central differences. The 3x3 block pattern, the map from every element block to its pattern
block and the CSR layout are built once (:class:`_Plan`). A Hessian evaluation writes only
the upper local blocks of every hinge, face and star (diagonal blocks halved) into a work
array, reduces them with one ``np.bincount`` per block entry into blocks ``U``, and returns
``U + U^T`` gathered straight into CSR order (sorted indices, same pattern at every call). Internally, elements and blocks
are ordered by a reverse Cuthill-McKee numbering of the vertices, and each block is stored
next to its transpose, so that the reductions touch memory locally whatever the mesh's own
vertex numbering. The work array (``9 x 8 bytes`` per element block, about 5 kB per vertex)
is kept per thread. Dofs are vertex-major (``3 v + c``).
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


@dataclass(frozen=True, eq=False)
class Bending:
    """Helfrich bending ``sum_i kappa/2 (2 H_i - c0)^2 A_i`` with Jülicher mean curvature.

    ``faces (F, 3)`` and ``hinges (E, 4)`` as in :class:`shellbuckle.mesh.Topology` (closed,
    outward oriented), ``n_vertices``, bending modulus ``kappa`` (energy) and spontaneous
    curvature ``c0`` in the convention ``c = c1 + c2`` (``c0 = 2/R`` for a stress-free sphere
    of radius ``R``; ``c0 = 0`` gives ``8 pi kappa`` on any sphere). Build it with
    :meth:`from_mesh`; change ``c0`` with :meth:`with_c0`, which shares the precomputed plan.
    """

    faces: np.ndarray
    hinges: np.ndarray
    n_vertices: int
    kappa: float = 1.0
    c0: float = 2.0
    _plan: "_Plan" = field(default=None, repr=False)

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

    @classmethod
    def from_mesh(cls, mesh_or_topology, kappa: float = 1.0, c0: float = 2.0) -> "Bending":
        """From a :class:`~shellbuckle.mesh.Mesh` or a :class:`~shellbuckle.mesh.Topology`."""
        t = getattr(mesh_or_topology, "topology", mesh_or_topology)
        return cls(faces=t.faces, hinges=t.hinges, n_vertices=t.n_vertices, kappa=kappa, c0=c0)

    def with_c0(self, c0: float) -> "Bending":
        """The same term with spontaneous curvature ``c0`` (convention ``c = c1 + c2``)."""
        return dataclasses.replace(self, c0=c0)

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
        """Bending energy of each vertex, ``kappa/2 (2 H_i - c0)^2 A_i``, shape ``(V,)``."""
        M, A = self._MA(self._XT(X))
        return 0.5 * self.kappa * (2.0 * M / A - self.c0) ** 2 * A

    # ------------------------------------------------------------------ energy interface

    def _compiled(self, X, gradient: bool):
        """``(value, gradient or (0, 3))`` from :func:`.kernels.juelicher`."""
        p, X = self._plan, kernels.positions(X, self.n_vertices)
        value, G = kernels.juelicher(X, p.HT, p.FT, self.kappa, self.c0, gradient)
        return float(value), G

    def value(self, X) -> float:
        return self._compiled(X, False)[0]

    def _weights(self, M, A):
        p, kappa, c0 = self._plan, self.kappa, self.c0
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
        """Exact (indefinite in general) Hessian, CSR ``(3V, 3V)``, vertex-major dofs."""
        p = self._plan
        XT = self._XT(X)
        p.prepare_hessian()
        hk = hg.hinge_kernel(XT, p.HT, order=2)
        fk = hg.face_kernel(XT, p.FT, order=2)
        M, A = p.vertex_sums(hk.phi, fk.area)
        H, w, u = self._weights(M, A)
        buf = p.buffer()
        hk.hess.upper_blocks(w, out=p.hinge_view(buf), half_diagonal=True)
        fk.hess.upper_blocks(u, out=p.face_view(buf), half_diagonal=True)
        G = p.star_gradients(0.25 * hk.dphi, fk.grad, H)
        p.star_blocks(G, (4.0 * self.kappa) / A, buf)
        return p.assemble(buf)


class _Plan:
    """Index arrays of one mesh, built once: stars, block pattern, scatter maps, CSR layout.

    A vertex's *star* is the vertex itself (slot 0) followed by its neighbours; the star slots
    of all vertices are numbered consecutively (``V + 2E`` slots). Block ``(a, b)`` of the
    Hessian pattern exists iff ``a`` and ``b`` lie in a common star.
    """

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
        self._valence, self._rank = valence, rank
        self._lock = threading.Lock()
        self._local = threading.local()
        self._hessian_ready = False

    def __getstate__(self):  # picklable (e.g. for process pools): drop the lock and scratch
        state = self.__dict__.copy()
        del state["_lock"], state["_local"]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._lock = threading.Lock()
        self._local = threading.local()

    def prepare_hessian(self):
        """Build the Hessian's index arrays on first use (value and gradient do not need them)."""
        if not self._hessian_ready:
            with self._lock:
                if not self._hessian_ready:
                    self._build_hessian_plan()
                    self._hessian_ready = True

    def _build_hessian_plan(self):
        V, FT, HT, valence, rank = self.V, self.FT, self.HT, self._valence, self._rank
        n_faces, n_hinges = FT.shape[1], HT.shape[1]
        coord = np.arange(3)[:, None, None]
        # stars: slot 0 the vertex, then its neighbours
        centers = np.concatenate([HT[0], HT[1]])
        members = np.concatenate([HT[1], HT[0]])
        order = np.lexsort((members, centers))
        star_ptr = np.zeros(V + 1, dtype=np.int64)
        np.cumsum(valence + 1, out=star_ptr[1:])
        self.n_slots = int(star_ptr[-1])
        star_center = np.repeat(np.arange(V), valence + 1)
        star_member = np.empty(self.n_slots, dtype=np.int64)
        is_self = np.zeros(self.n_slots, dtype=bool)
        is_self[star_ptr[:-1]] = True
        star_member[is_self] = np.arange(V)
        star_member[~is_self] = members[order]
        key = star_center * V + star_member
        sorter = np.argsort(key)
        skey = key[sorter]

        def slot(c, m):
            return sorter[np.searchsorted(skey, c * V + m)]

        # star slot of every hinge vertex in the stars of both end points, of every face corner
        # in the stars of all three corners
        # (flat index c * n_slots + slot, matching the (3, ...) coordinate-first layouts)
        S = self.n_slots
        self.star_hinge = [(coord * S + np.stack([slot(HT[s], HT[a]) for a in range(4)])[None]).ravel()
                           for s in range(2)]  # (3 coords, 4 hinge vertices, E), per end point s
        fslot = np.stack([np.stack([slot(FT[p], FT[a]) for a in range(3)]) for p in range(3)])
        self.star_face = (coord[..., None] * S + fslot[None]).ravel()  # (3 coords, 3 centers, 3 corners, F)
        # block pattern: union of star x star, numbered in the internal order
        groups = []
        pair_keys = []
        for n in np.unique(valence):
            verts = np.flatnonzero(valence == n)
            verts = verts[np.argsort(rank[verts])]
            slots = star_ptr[verts][:, None] + np.arange(n + 1)
            mem = rank[star_member[slots]]
            pair_keys.append((mem[:, :, None] * V + mem[:, None, :]).ravel())
            P, Q = np.triu_indices(n + 1)
            groups.append((verts, slots, P, Q, mem))
        ukeys = np.unique(np.concatenate(pair_keys))
        self.n_blocks = nb = len(ukeys)
        # internal block order: each off-diagonal block (a, b) next to its transpose (b, a),
        # pairs ordered by (min, max) rank, first the one whose row has the lower rank; then
        # the diagonal blocks. U + U^T is then a sum of strided slices.
        ra, rb = ukeys // V, ukeys % V
        off = ra != rb
        self.n_pair_blocks = int(off.sum())
        order_off = np.flatnonzero(off)[np.lexsort((ra[off] > rb[off], np.maximum(ra, rb)[off],
                                                    np.minimum(ra, rb)[off]))]
        relabel = np.empty(nb, dtype=np.int64)
        relabel[np.concatenate([order_off, np.flatnonzero(~off)])] = np.arange(nb)

        def block(ra, rb):  # internal block number of ranked vertices (ra, rb)
            return relabel[np.searchsorted(ukeys, ra * V + rb)]

        # element upper blocks -> pattern blocks, in the buffer's column order
        rH, rF = rank[HT], rank[FT]
        maps = [np.stack([block(rH[p], rH[q]) for p, q in hg.HINGE_UPPER_BLOCKS]).ravel(),
                np.stack([block(rF[p], rF[q]) for p, q in hg.FACE_UPPER_BLOCKS]).ravel()]
        self._hinge_cols = (0, 9 * n_hinges, n_hinges)
        self._face_cols = (9 * n_hinges, 9 * n_hinges + 6 * n_faces, n_faces)
        start = self._face_cols[1]
        self.star_groups = []
        for verts, slots, P, Q, mem in groups:
            maps.append(block(mem[:, P], mem[:, Q]).ravel())
            stop = start + len(verts) * len(P)
            half = np.where(P == Q, 0.5, 1.0)
            self.star_groups.append((verts, slots[:, P], slots[:, Q], half, start, stop))
            start = stop
        self.n_contrib = start
        self.block_map = np.concatenate(maps)
        # CSR layout of the full symmetric matrix in the mesh's numbering: row 3a + c holds the
        # blocks (a, b), b increasing, each with d = 0..2
        inverse = np.empty(V, dtype=np.int64)
        inverse[rank] = np.arange(V)
        ba, bb = inverse[ukeys // V], inverse[ukeys % V]
        by_csr = np.argsort(ba * V + bb)
        csr_order = relabel[by_csr]  # CSR block -> internal block
        ba, bb = ba[by_csr], bb[by_csr]
        bptr = np.zeros(V + 1, dtype=np.int64)
        np.cumsum(np.bincount(ba, minlength=V), out=bptr[1:])
        nbl = np.diff(bptr)
        within = np.arange(nb) - bptr[ba]
        c = np.arange(3)[:, None, None]
        d = np.arange(3)[None, :, None]
        pos = (9 * bptr[ba] + 3 * c * nbl[ba] + 3 * within + d).ravel()  # (c, d, block) order
        csr_from = np.empty(9 * nb, dtype=np.int64)
        indices = np.empty(9 * nb, dtype=np.int32)
        csr_from[pos] = ((3 * c + d) * nb + csr_order).ravel()  # from component-major (9, nb)
        indices[pos] = np.broadcast_to(3 * bb + d, (3, 3, nb)).ravel()
        indptr = np.empty(3 * V + 1, dtype=np.int32)
        indptr[:-1] = (9 * bptr[:-1, None] + 3 * np.arange(3) * nbl[:, None]).ravel()
        indptr[-1] = 9 * nb
        self.csr_from, self.indices, self.indptr = csr_from, indices, indptr

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

    def star_gradients(self, dM_hinge, dA_face, H):
        """``g_i = grad M_i - H_i grad A_i`` on the star slots, ``(3, n_slots)``.

        ``dM_hinge (3, 4, E)`` is ``grad(l theta) / 4``, ``dA_face (3, 3, F)`` the area gradient.
        """
        n = 3 * self.n_slots
        w = dM_hinge.ravel()
        G = np.bincount(self.star_hinge[0], weights=w, minlength=n)
        G += np.bincount(self.star_hinge[1], weights=w, minlength=n)
        fw = np.take(H, self.FT) * (-1.0 / 3.0)  # (3 centers, F)
        G += np.bincount(self.star_face, weights=(fw[None, :, None, :] * dA_face[:, None]).ravel(),
                         minlength=n)
        return G.reshape(3, self.n_slots)

    def hinge_view(self, buf):
        lo, hi, n = self._hinge_cols
        return _view(buf, lo, hi, (3, 3, 9, n))

    def face_view(self, buf):
        lo, hi, n = self._face_cols
        return _view(buf, lo, hi, (3, 3, 6, n))

    def star_blocks(self, G, weight, buf):
        """Upper blocks of ``sum_i weight_i g_i g_i^T`` into ``buf``."""
        for verts, sP, sQ, half, lo, hi in self.star_groups:
            gP = np.take(G, sP, axis=1)  # (3, n_g, pairs)
            gP *= np.take(weight, verts)[:, None] * half
            gQ = np.take(G, sQ, axis=1)
            np.multiply(gP[:, None], gQ[None, :], out=_view(buf, lo, hi, (3, 3) + sP.shape))

    def buffer(self):
        """Work array ``(9, n_contrib)`` for the element blocks, kept per thread."""
        buf = getattr(self._local, "buf", None)
        if buf is None:
            buf = self._local.buf = np.empty((9, self.n_contrib))
        return buf

    def assemble(self, buf) -> sp.csr_matrix:
        """``U + U^T`` of the upper blocks in ``buf (9, n_contrib)`` as a CSR matrix."""
        nb = self.n_blocks
        U = np.empty((9, nb))
        for k in range(9):
            U[k] = np.bincount(self.block_map, weights=buf[k], minlength=nb)
        full = np.empty((9, nb))
        n2 = self.n_pair_blocks
        for k in range(9):  # U + U^T: block (a, b) entry (c, d) gets block (b, a) entry (d, c)
            kt = 3 * (k % 3) + k // 3
            np.add(U[k, 0:n2:2], U[kt, 1:n2:2], out=full[k, 0:n2:2])
            np.add(U[k, 1:n2:2], U[kt, 0:n2:2], out=full[k, 1:n2:2])
            np.add(U[k, n2:], U[kt, n2:], out=full[k, n2:])
        data = np.take(full, self.csr_from)
        n = 3 * self.V
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(n, n))


def _view(buf, lo, hi, shape):
    """Columns ``lo:hi`` of ``buf (9, n)`` seen as ``shape`` without copying (written into)."""
    out = buf[:, lo:hi].reshape(shape)
    if not np.may_share_memory(out, buf):
        raise RuntimeError("internal error: block buffer view would be a copy")
    return out
