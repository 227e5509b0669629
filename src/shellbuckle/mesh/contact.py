"""Self-contact of a closed triangulated surface: distances between distant parts, intersections.

The paper stops each deflation when the surface touches itself (Quilliet et al., EPJE 27, 13
(2008), §4.1: at 7-11 % of V0 remaining). :class:`ContactChecker` answers, for positions
``X (V, 3)`` of a fixed :class:`~shellbuckle.mesh.topology.Topology`, three questions at every
volume step:

``min_distance``
    the smallest Euclidean distance ``|x_i - x_j|`` between two vertices whose graph distance on
    the mesh (number of edges on the shortest edge path) is greater than ``rings``. Neighbours
    along the surface are excluded, so this is how close two distant parts of the surface (the
    inner dent and the opposite side) have come. On an undeformed sphere it is of the order of
    ``(rings + 1) h`` for mean edge length ``h``: 1.25, 2.0, 2.7, 3.5 ``h`` for ``rings`` = 1,
    2, 3, 4 on icospheres and randomized spheres (a perfect triangular lattice would give
    ``(rings + 1) sqrt(3)/2 h``; valence-5 vertices bring the next ring closer).
``min_face_distance``
    the smallest exact point-triangle distance between a vertex ``v`` and a face ``f`` none of
    whose three vertices lies within ``rings`` edges of ``v``: the gap between two sheets,
    without the up-to-``h/sqrt(3)`` overestimate of the vertex-vertex value when the vertices
    of the two sheets are not aligned. It is exact whenever it is below ``face_cutoff``;
    otherwise it is reported as ``inf`` ("no non-adjacent face within the cutoff"), which keeps
    its cost small on a surface far from contact.
``pairs``
    all pairs of faces that share no vertex and intersect (closed triangles), sorted.

Intersection test
-----------------
Candidate face pairs come from a broad phase: a k-d tree on face centroids gives the pairs
with ``|c_a - c_b| <= 2 rho_q`` (``rho_f`` is the largest centroid-vertex distance of face
``f``, so every point of ``f`` lies in the ball of radius ``rho_f`` about ``c_f``; ``rho_q``
is 1.2 times the median ``rho_f``, and the larger faces are searched with a second tree); pairs
sharing a vertex are dropped, then pairs with ``|c_a - c_b| > rho_a + rho_b`` and pairs whose
axis-aligned bounding boxes do not overlap. The exact test is Devillers & Guigue's
(O. Devillers, P. Guigue, "Faster triangle-triangle intersection tests", INRIA RR-4488 (2002);
P. Guigue, O. Devillers, J. Graphics Tools 8(1), 25 (2003)), vectorized over candidate pairs.
Every decision is the sign of an orientation determinant
``[a, b, c, d] = ((b - a) x (c - a)) . (d - a)`` of input points, which is the same
plane-side classification as Möller's test (T. Möller, "A fast triangle-triangle intersection
test", J. Graphics Tools 2(2), 25 (1997)) without computing interval end points by division:

1. reject when the three vertices of one triangle lie strictly on one side of the other's plane;
2. coplanar pairs (all three vertices of one triangle on the other's plane): 2D test in the
   coordinate plane most orthogonal to the normal (edge-edge crossings and vertex containment);
3. otherwise permute each triangle so that its first vertex is alone on its side of the other's
   plane (orienting the other triangle so that this side is positive); the triangles meet iff
   ``[q1, p2, p1, q2] <= 0`` and ``[p1, p2, r1, r2] <= 0``.

Convention and tolerance: triangles are closed, so touching counts as intersecting. An
orientation determinant is taken as zero when its magnitude is below ``tol`` times its scale:
``tol * |n| * L`` for a vertex against a plane with normal ``n = (b - a) x (c - a)`` (i.e. a
vertex within ``tol * L`` of the plane is on it), ``tol * L**3`` for the final determinants and
``tol * L**2`` in 2D, where ``L`` is the longest edge of the two triangles. With the default
``tol = 1e-10`` a pair is reported as intersecting when it touches within about ``1e-10 L``;
a pair separated by more than about that is not. Near-coplanar pairs (every vertex of one
triangle within ``tol * L`` of the other's plane) take the coplanar branch. The test is exact
for inputs whose determinants are computed without rounding (e.g. small integer coordinates).

Limitation: faces that share a vertex or an edge touch by construction and are never tested,
so a crossing between two faces of one vertex star (a star folded over onto itself) is not
reported; such folds are excluded by the bending energy long before contact. Degenerate
(zero-area) faces are not supported.

Point-triangle distance: orthogonal projection onto the plane when its barycentric coordinates
are all non-negative, else the smallest of the three point-segment distances (C. Ericson,
*Real-Time Collision Detection*, Morgan Kaufmann 2005, §5.1.5, regions folded into one formula).

Cost: the k-ring adjacency (keys ``i * V + j`` of the pattern of ``(I + A)^rings``) and the
pairs of faces sharing a vertex are built once per topology, as hashed key sets; each call
builds k-d trees on vertices and face centroids and does vectorized work linear in the number
of candidate pairs (about 6 per face on a smooth surface: the faces around each face's
vertices). See ``benchmarks/bench_contact.py``.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import chain

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from .topology import Topology

DEFAULT_TOL = 1e-10

__all__ = ["ContactChecker", "ContactResult", "DEFAULT_TOL", "min_nonadjacent_distance",
           "min_vertex_face_distance", "point_triangle_distance", "self_intersections",
           "triangles_intersect"]


# ----------------------------------------------------------------------------------------------
# vector kernels


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Row-wise cross product of ``(..., 3)`` arrays."""
    return np.stack([u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1],
                     u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2],
                     u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]], axis=-1)


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("...k,...k->...", u, v)


def _orient3d(a, b, c, d) -> np.ndarray:
    """``[a, b, c, d] = ((b - a) x (c - a)) . (d - a)``, six times the signed tetrahedron volume."""
    return _dot(_cross(b - a, c - a), d - a)


def _orient2d(a, b, c) -> np.ndarray:
    """``(b - a) x (c - a)`` for ``(..., 2)`` points, twice the signed triangle area."""
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) \
        - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])


def _band_sign(value: np.ndarray, eps) -> np.ndarray:
    """Sign of ``value`` with ``|value| <= eps`` taken as 0, int8."""
    return ((value > eps).astype(np.int8) - (value < -eps).astype(np.int8))


def _longest_edge(T: np.ndarray) -> np.ndarray:
    """Longest edge length of triangles ``T (n, 3, 3)``, shape ``(n,)``."""
    e = T[:, [1, 2, 0]] - T
    return np.sqrt(_dot(e, e).max(axis=1))


def _canonical_table():
    """Rotation and flip that put a plane-side sign pattern in Devillers-Guigue canonical form.

    For the signs ``s = (s_p, s_q, s_r)`` of a triangle's vertices against the other triangle's
    plane, find a cyclic rotation ``k`` (new first vertex = old vertex ``k``) and a flip (of
    the other triangle's orientation, which negates ``s``) such that the rotated signs
    ``(x0, x1, x2)`` satisfy ``x0 > 0, x1 <= 0, x2 <= 0`` or ``x0 == 0, x1 < 0, x2 < 0``: the
    first vertex is alone on the positive side and the triangle crosses the plane along the
    segment between edges ``(0, 1)`` and ``(0, 2)``. Patterns strictly on one side or all on
    the plane get ``k = -1``. Index: ``9 (s_p + 1) + 3 (s_q + 1) + (s_r + 1)``.
    """
    rot = np.full(27, -1, dtype=np.int64)
    flip = np.zeros(27, dtype=bool)
    for code in range(27):
        s = np.array([code // 9, (code // 3) % 3, code % 3]) - 1
        for k in range(3):
            for f in (False, True):
                x = np.roll(s, -k) * (-1 if f else 1)
                if (x[0] > 0 and x[1] <= 0 and x[2] <= 0) or (x[0] == 0 and x[1] < 0 and x[2] < 0):
                    rot[code], flip[code] = k, f
                    break
            if rot[code] >= 0:
                break
    return rot, flip


_ROT, _FLIP = _canonical_table()
_SWAP12 = np.array([[0, 1, 2], [0, 2, 1]])
_KEEP_AXES = np.array([[1, 2], [0, 2], [0, 1]])


def _rotate(T: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Cyclically rotate the vertices of each triangle so that vertex ``k`` comes first."""
    perm = (k[:, None] + np.arange(3)) % 3
    return np.take_along_axis(T, perm[:, :, None], axis=1)


def triangles_intersect(T1, T2, tol: float = DEFAULT_TOL) -> np.ndarray:
    """Whether closed triangles ``T1[n]`` and ``T2[n]`` (each ``(n, 3, 3)``) intersect.

    Devillers-Guigue orientation-predicate test, vectorized over the pairs; see the module
    docstring for the algorithm, the tolerance convention (touching, within ``tol`` times the
    longest edge, counts as intersecting) and references. Returns a bool array ``(n,)``.
    """
    T1 = np.asarray(T1, dtype=np.float64)
    T2 = np.asarray(T2, dtype=np.float64)
    if T1.shape != T2.shape or T1.ndim != 3 or T1.shape[1:] != (3, 3):
        raise ValueError(f"triangles must be two (n, 3, 3) arrays, got {T1.shape} and {T2.shape}")
    out = np.zeros(len(T1), dtype=bool)
    if len(T1) == 0:
        return out
    L = np.maximum(_longest_edge(T1), _longest_edge(T2))
    n2 = _cross(T2[:, 1] - T2[:, 0], T2[:, 2] - T2[:, 0])
    d1 = _dot(n2[:, None, :], T1 - T2[:, None, 0])
    s1 = _band_sign(d1, (tol * L * np.linalg.norm(n2, axis=1))[:, None])
    live = np.flatnonzero(np.abs(s1.sum(axis=1)) != 3)
    T1, T2, L, n2, s1 = T1[live], T2[live], L[live], n2[live], s1[live]
    n1 = _cross(T1[:, 1] - T1[:, 0], T1[:, 2] - T1[:, 0])
    d2 = _dot(n1[:, None, :], T2 - T1[:, None, 0])
    s2 = _band_sign(d2, (tol * L * np.linalg.norm(n1, axis=1))[:, None])
    keep = np.abs(s2.sum(axis=1)) != 3
    live, T1, T2, L, n1, n2, s1, s2 = (a[keep] for a in (live, T1, T2, L, n1, n2, s1, s2))
    coplanar = (s1 == 0).all(axis=1) | (s2 == 0).all(axis=1)
    if coplanar.any():
        c = coplanar
        normal = np.where((_dot(n1[c], n1[c]) >= _dot(n2[c], n2[c]))[:, None], n1[c], n2[c])
        out[live[c]] = _coplanar_overlap(T1[c], T2[c], normal, L[c], tol)
    g = ~coplanar
    out[live[g]] = _general_overlap(T1[g], T2[g], s1[g], s2[g], L[g], tol)
    return out


def _general_overlap(T1, T2, s1, s2, L, tol):
    """Devillers-Guigue decision for non-coplanar pairs that straddle both planes."""
    code1 = 9 * (s1[:, 0] + 1) + 3 * (s1[:, 1] + 1) + (s1[:, 2] + 1)
    T1 = _rotate(T1, _ROT[code1])
    order2 = _SWAP12[_FLIP[code1].astype(np.int64)]  # flip T2 so that T1's lone vertex is positive
    T2 = np.take_along_axis(T2, order2[:, :, None], axis=1)
    s2 = np.take_along_axis(s2, order2, axis=1)
    code2 = 9 * (s2[:, 0] + 1) + 3 * (s2[:, 1] + 1) + (s2[:, 2] + 1)
    T2 = _rotate(T2, _ROT[code2])
    order1 = _SWAP12[_FLIP[code2].astype(np.int64)]
    T1 = np.take_along_axis(T1, order1[:, :, None], axis=1)
    p1, q1, r1 = T1[:, 0], T1[:, 1], T1[:, 2]
    p2, q2, r2 = T2[:, 0], T2[:, 1], T2[:, 2]
    eps = tol * L ** 3
    separated = (_orient3d(q1, p2, p1, q2) > eps) | (_orient3d(p1, p2, r1, r2) > eps)
    return ~separated


def _coplanar_overlap(T1, T2, normal, L, tol):
    """Closed-triangle overlap of coplanar pairs, in the coordinate plane most orthogonal to
    ``normal``: some pair of edges meets, or a vertex of one triangle lies in the other."""
    keep = _KEEP_AXES[np.argmax(np.abs(normal), axis=1)]
    P1 = np.take_along_axis(T1, keep[:, None, :], axis=2)  # (m, 3, 2)
    P2 = np.take_along_axis(T2, keep[:, None, :], axis=2)
    eps2 = (tol * L ** 2)[:, None, None]
    a, b = P1[:, :, None, :], P1[:, [1, 2, 0], None, :]  # edges of T1 (m, 3, 1, 2)
    c, d = P2[:, None, :, :], P2[:, None, [1, 2, 0], :]  # edges of T2 (m, 1, 3, 2)
    o1, o2 = _band_sign(_orient2d(a, b, c), eps2), _band_sign(_orient2d(a, b, d), eps2)
    o3, o4 = _band_sign(_orient2d(c, d, a), eps2), _band_sign(_orient2d(c, d, b), eps2)
    collinear = ((o1 == 0) & (o2 == 0)) | ((o3 == 0) & (o4 == 0))
    crossing = (o1 * o2 <= 0) & (o3 * o4 <= 0) & ~collinear
    epsL = (tol * L)[:, None, None, None]
    lo = np.maximum(np.minimum(a, b), np.minimum(c, d))
    hi = np.minimum(np.maximum(a, b), np.maximum(c, d))
    overlapping = collinear & (lo <= hi + epsL).all(axis=-1)
    edges_meet = (crossing | overlapping).any(axis=(1, 2))
    return edges_meet | _inside_2d(P1[:, 0], P2, eps2[:, 0, 0]) | _inside_2d(P2[:, 0], P1, eps2[:, 0, 0])


def _inside_2d(p, P, eps):
    """Whether 2D points ``p (m, 2)`` lie in closed triangles ``P (m, 3, 2)``."""
    s = np.stack([_band_sign(_orient2d(P[:, k], P[:, (k + 1) % 3], p), eps) for k in range(3)], 1)
    return (s >= 0).all(axis=1) | (s <= 0).all(axis=1)


def point_triangle_distance(P, T) -> np.ndarray:
    """Euclidean distance from points ``P (n, 3)`` to closed triangles ``T (n, 3, 3)``, ``(n,)``.

    If the orthogonal projection of ``p`` onto the triangle's plane has barycentric coordinates
    ``(u, v, w) >= 0`` the distance is ``|(p - a) . n| / |n|``; otherwise the closest point is
    on the boundary and the distance is the smallest point-segment distance
    ``|p - (x + t (y - x))|`` with ``t = clip((p - x).(y - x) / |y - x|^2, 0, 1)`` over the
    three edges (Ericson 2005, §5.1.5).
    """
    P = np.asarray(P, dtype=np.float64)
    T = np.asarray(T, dtype=np.float64)
    a, b, c = T[:, 0], T[:, 1], T[:, 2]
    ab, ac, ap = b - a, c - a, P - a
    d00, d01, d11 = _dot(ab, ab), _dot(ab, ac), _dot(ac, ac)
    d20, d21 = _dot(ap, ab), _dot(ap, ac)
    denom = d00 * d11 - d01 * d01
    with np.errstate(divide="ignore", invalid="ignore"):
        v = (d11 * d20 - d01 * d21) / denom
        w = (d00 * d21 - d01 * d20) / denom
        inside = (v >= 0) & (w >= 0) & (v + w <= 1)
        n = _cross(ab, ac)
        plane = np.abs(_dot(ap, n)) / np.sqrt(_dot(n, n))
    edge = np.minimum(np.minimum(_point_segment(P, a, b), _point_segment(P, b, c)),
                      _point_segment(P, c, a))
    return np.where(inside, plane, edge)


def _point_segment(p, x, y):
    e = y - x
    ee = _dot(e, e)
    t = np.clip(_dot(p - x, e) / np.where(ee > 0, ee, 1.0), 0.0, 1.0)
    r = p - x - t[:, None] * e
    return np.sqrt(_dot(r, r))


# ----------------------------------------------------------------------------------------------
# the checker


class _KeySet:
    """A fixed set of non-negative int64 keys with vectorized membership tests.

    Linear probing in a table of ``2^b >= 2 n`` home slots (load factor <= 1/2) plus an
    overflow tail, with multiplicative (Fibonacci) hashing: the home slot of a key is the top
    ``b`` bits of ``key * 0x9E3779B97F4A7C15 mod 2^64``. Built in one sort: with keys ordered by
    home slot ``h_k``, key ``k`` goes to ``p_k = max(h_k, p_{k-1} + 1)``, so every slot
    between a key's home and its place is occupied and a lookup scans from the home slot to
    the key or to the first empty slot. A lookup costs about 1.5 gathers on average.
    """

    _MULT = np.uint64(0x9E3779B97F4A7C15)

    def __init__(self, keys: np.ndarray):
        keys = np.sort(np.asarray(keys, dtype=np.int64).ravel())
        keys = keys[np.r_[True, keys[1:] != keys[:-1]]] if len(keys) else keys
        bits = max(4, int(np.ceil(np.log2(2 * max(len(keys), 1)))))
        self._shift = np.uint64(64 - bits)
        home = self._slot(keys)
        order = np.argsort(home)
        rank = np.arange(len(keys))
        place = rank + np.maximum.accumulate(home[order] - rank) if len(keys) else rank
        size = max(1 << bits, int(place.max(initial=0)) + 2)  # a trailing empty slot ends scans
        self._table = np.full(size, -1, dtype=np.int64)
        self._table[place] = keys[order]
        self.size = len(keys)

    def _slot(self, keys: np.ndarray) -> np.ndarray:
        with np.errstate(over="ignore"):
            return ((keys.astype(np.uint64) * self._MULT) >> self._shift).astype(np.int64)

    def contains(self, keys) -> np.ndarray:
        """Membership of each of ``keys`` (int64 array), as a bool array of the same shape."""
        keys = np.asarray(keys, dtype=np.int64)
        flat = keys.ravel()
        slot = self._slot(flat)
        t = self._table[slot]
        out = t == flat
        idx = np.flatnonzero(~out & (t != -1))
        slot = slot[idx]
        while len(idx):
            slot = slot + 1
            t = self._table[slot]
            hit = t == flat[idx]
            out[idx[hit]] = True
            more = ~hit & (t != -1)
            idx, slot = idx[more], slot[more]
        return out.reshape(keys.shape)


@dataclass(frozen=True)
class ContactResult:
    """Self-contact measures of one conformation (see :class:`ContactChecker`).

    ``intersects``: some pair of faces sharing no vertex intersects. ``pairs (n, 2)``: those
    pairs ``(f, g)`` with ``f < g``, sorted lexicographically (at most ``max_pairs`` of them);
    ``first_pair`` is ``pairs[0]`` (``None`` without intersection) and ``n_pairs`` the total
    count. ``min_distance``/``min_pair``: smallest vertex-vertex distance over pairs ``(i, j)``
    (``i < j``) more than ``rings`` edges apart. ``min_face_distance``/``min_face_pair``:
    smallest distance over non-adjacent ``(vertex, face)`` pairs, exact below ``face_cutoff``
    and ``inf``/``None`` above it. Lengths are in the units of ``X``.
    """

    intersects: bool
    first_pair: tuple[int, int] | None
    n_pairs: int
    pairs: np.ndarray
    min_distance: float
    min_pair: tuple[int, int] | None
    min_face_distance: float
    min_face_pair: tuple[int, int] | None
    face_cutoff: float


class ContactChecker:
    """Self-contact measures of a fixed topology, for changing positions ``X (V, 3)``.

    ``rings`` (int >= 0): two vertices are *adjacent* when their graph distance is at most
    ``rings``; a vertex and a face are adjacent when any vertex of the face is adjacent to the
    vertex. ``tol``: relative tolerance of the triangle-triangle test (module docstring).

    Built once per topology: the k-ring adjacency (pairs ``i < j`` of ``(I + A)^rings``, ``A``
    the vertex adjacency matrix) and the pairs of faces sharing a vertex, both as hashed key
    sets. The checker holds no state between calls.
    """

    def __init__(self, topology: Topology, rings: int = 2, tol: float = DEFAULT_TOL):
        if not isinstance(topology, Topology):
            raise TypeError(f"topology must be a Topology, got {type(topology).__name__}")
        if not isinstance(rings, (int, np.integer)) or isinstance(rings, bool) or rings < 0:
            raise ValueError(f"rings must be an integer >= 0, got {rings!r}")
        if not (np.isfinite(tol) and 0 <= tol < 1e-3):
            raise ValueError(f"tol must be a finite number in [0, 1e-3), got {tol!r}")
        self.topology = topology
        self.rings = int(rings)
        self.tol = float(tol)
        V, F = topology.n_vertices, topology.n_faces
        adjacency = sp.csr_matrix((np.ones(len(topology.vertex_neighbors), dtype=np.int32),
                                   topology.vertex_neighbors, topology.vertex_neighbors_ptr),
                                  shape=(V, V))
        self._adjacency = adjacency  # symmetric; also the graph of face_distance
        step = (adjacency + sp.identity(V, dtype=np.int32, format="csr")).tocsr()
        ring = sp.identity(V, dtype=np.int32, format="csr")
        for _ in range(self.rings):
            ring = (ring @ step).tocsr()
            ring.data[:] = 1  # path counts are not needed, only reachability
        self.ring_sizes = np.diff(ring.indptr)  # (V,) vertices within `rings` edges, self included
        ring = sp.triu(ring, k=1).tocoo()
        self._ring = _KeySet(ring.row.astype(np.int64) * V + ring.col)
        # faces sharing a vertex: the pattern of M M^T, M the (F, V) face-vertex incidence
        incidence = sp.csr_matrix((np.ones(3 * F, dtype=np.int32), topology.faces.ravel(),
                                   np.arange(0, 3 * F + 1, 3)), shape=(F, V))
        sharing = sp.triu(incidence @ incidence.T, k=1).tocoo()
        self._sharing = _KeySet(sharing.row.astype(np.int64) * F + sharing.col)

    # -- helpers -------------------------------------------------------------------------------

    def _check_positions(self, X) -> np.ndarray:
        X = np.asarray(X, dtype=np.float64)
        V = self.topology.n_vertices
        if X.shape != (V, 3):
            raise ValueError(f"positions must have shape ({V}, 3), got {X.shape}")
        if not np.isfinite(X).all():
            v = int(np.flatnonzero(~np.isfinite(X).all(axis=1))[0])
            raise ValueError(f"vertex {v} has a non-finite coordinate {X[v].tolist()}")
        return X

    def adjacent(self, i, j) -> np.ndarray:
        """Whether vertices ``i`` and ``j`` (int arrays, same shape) are within ``rings`` edges."""
        i, j = np.asarray(i, dtype=np.int64), np.asarray(j, dtype=np.int64)
        lo, hi = np.minimum(i, j), np.maximum(i, j)
        return (lo == hi) | self._ring.contains(lo * self.topology.n_vertices + hi)

    def face_distance(self, f, g, limit: int) -> np.ndarray:
        """Edges on the shortest mesh path between a vertex of face ``f`` and one of face
        ``g`` (int arrays, same shape), or ``inf`` when more than ``limit``; a breadth-first
        search from the vertices of the ``f`` faces, meant for a few pairs."""
        F = self.topology.faces
        a, b = F[np.asarray(f, dtype=np.int64)], F[np.asarray(g, dtype=np.int64)]
        if a.size == 0:
            return np.zeros(a.shape[:-1])
        sources, row = np.unique(a, return_inverse=True)
        dist = csgraph.dijkstra(self._adjacency, unweighted=True, indices=sources,
                                limit=float(limit))
        d = dist[row.reshape(a.shape)[..., :, None], b[..., None, :]]
        return d.min(axis=(-2, -1))

    def share_vertex(self, f, g) -> np.ndarray:
        """Whether faces ``f`` and ``g`` (int arrays, same shape) have a vertex in common."""
        f, g = np.asarray(f, dtype=np.int64), np.asarray(g, dtype=np.int64)
        lo, hi = np.minimum(f, g), np.maximum(f, g)
        return (lo == hi) | self._sharing.contains(lo * self.topology.n_faces + hi)

    def _edge_lengths(self, X):
        e = X[self.topology.edges[:, 1]] - X[self.topology.edges[:, 0]]
        return np.sqrt(_dot(e, e))

    # -- distances -----------------------------------------------------------------------------

    def _far_pairs(self, X, tree, r):
        """Non-adjacent vertex pairs ``(n, 2)`` (``i < j``) within ``r`` and their distances."""
        pairs = tree.query_pairs(r, output_type="ndarray").astype(np.int64)
        if len(pairs):
            pairs = pairs[~self._ring.contains(pairs[:, 0] * self.topology.n_vertices + pairs[:, 1])]
        diff = X[pairs[:, 0]] - X[pairs[:, 1]]
        return pairs, np.sqrt(_dot(diff, diff))

    def _distances(self, X, tree, face_cutoff):
        """Vertex-vertex minimum (always) and vertex-face minimum (below ``face_cutoff``).

        Vertex-vertex: all non-adjacent vertex pairs within a radius ``r`` (k-d tree
        ``query_pairs``, then the k-ring set); the minimum is exact as soon as the list is not
        empty. ``r`` starts at 0.75 (rings + 1) mean edge lengths and grows by 1.25 until then.

        Vertex-face: every point of a face ``f`` lies within its covering radius, at most
        ``l_f / sqrt(3)`` (``l_f``: longest edge; the circumradius if ``f`` is acute, less than
        ``l_f / 2`` if obtuse), of a vertex ``j`` of ``f``, and ``j`` is non-adjacent to ``v``
        when ``f`` is. With ``cover_j`` the largest such radius over the faces at ``j``, the
        faces at the far partners ``j`` of ``v`` with ``|x_v - x_j| <= c + cover_j`` contain
        every non-adjacent face within ``c`` of ``x_v``: the minimum over them is exact when
        it is ``<= c``. ``c`` starts at ``min(face_cutoff, mean edge)`` and is raised (to the
        best value found, or by 1.25) until the minimum is below it or ``c`` reaches the cutoff.
        """
        lengths = self._edge_lengths(X)
        mean = float(lengths.mean())
        extent = float(np.linalg.norm(X.max(axis=0) - X.min(axis=0)))
        fe = lengths[self.topology.face_edges]
        face_cover = np.maximum(np.maximum(fe[:, 0], fe[:, 1]), fe[:, 2]) / np.sqrt(3.0)
        ptr = self.topology.vertex_faces_ptr
        cover = np.maximum.reduceat(face_cover[self.topology.vertex_faces], ptr[:-1])
        median, p99 = np.percentile(cover, [50, 99])
        q = min(float(cover.max()), min(max(p99, 1.2 * median), 2.0 * median))  # above: balls
        c = min(float(face_cutoff), mean)
        r = max(0.75 * (self.rings + 1) * mean, c + q)
        while True:
            pairs, d = self._far_pairs(X, tree, r)
            if len(pairs) or r > extent:
                break
            r *= 1.25
        if len(pairs) == 0:
            return (np.inf, None), (np.inf, None)
        k = _first_argmin(d, pairs)
        vertex = (float(d[k]), (int(pairs[k, 0]), int(pairs[k, 1])))
        face = self._face_min(X, self._face_candidates(X, tree, c, cover, q, pairs, d))
        while face[0] > c and c < face_cutoff and c <= extent:
            c = min(float(face_cutoff), face[0] if np.isfinite(face[0]) else 1.25 * c)
            face = self._face_min(X, self._face_candidates(X, tree, c, cover, q))
        return vertex, (face if face[0] <= face_cutoff else (np.inf, None))

    def _face_candidates(self, X, tree, c, cover, q, pairs=None, d=None):
        """Ordered non-adjacent pairs ``(v, j)`` with ``|x_v - x_j| <= c + cover_j``: from the
        far pairs within ``c + q`` (given, or queried), plus ball queries around the vertices
        with ``cover_j > q``."""
        if pairs is None:
            pairs, d = self._far_pairs(X, tree, c + q)
        both = np.concatenate([pairs, pairs[:, ::-1]])
        both = both[np.concatenate([d, d]) <= c + cover[both[:, 1]]]
        big = np.flatnonzero(cover > q)
        if len(big):
            balls = tree.query_ball_point(X[big], c + cover[big], return_sorted=False)
            counts = np.fromiter(map(len, balls), dtype=np.int64, count=len(big))
            v = np.fromiter(chain.from_iterable(balls), dtype=np.int64, count=int(counts.sum()))
            j = np.repeat(big, counts)
            far = ~self.adjacent(v, j)
            both = np.concatenate([both, np.stack([v[far], j[far]], axis=1)])
        return both

    def _face_min(self, X, pairs):
        """Smallest distance from ``v`` to a face at ``j`` with no vertex adjacent to ``v``, over
        ordered pairs ``(v, j)``; ties: smallest ``(v, f)``."""
        if len(pairs) == 0:
            return np.inf, None
        ptr, vf = self.topology.vertex_faces_ptr, self.topology.vertex_faces
        m = np.diff(ptr)[pairs[:, 1]]
        v = np.repeat(pairs[:, 0], m)
        f = vf[np.repeat(ptr[pairs[:, 1]], m) + np.arange(m.sum()) - np.repeat(np.cumsum(m) - m, m)]
        F = self.topology.faces
        keep = ~(self.adjacent(v, F[f, 0]) | self.adjacent(v, F[f, 1]) | self.adjacent(v, F[f, 2]))
        v, f = v[keep], f[keep]
        if len(v) == 0:
            return np.inf, None
        d = point_triangle_distance(X[v], X[F[f]])
        k = _first_argmin(d, np.stack([v, f], axis=1), ordered=True)
        return float(d[k]), (int(v[k]), int(f[k]))

    def min_vertex_distance(self, X):
        """``(d, (i, j))``: the smallest ``|x_i - x_j|`` over vertices more than ``rings`` edges
        apart, ``i < j`` (ties: smallest pair); ``(inf, None)`` if every pair is adjacent."""
        X = self._check_positions(X)
        return self._distances(X, cKDTree(X, balanced_tree=False, compact_nodes=False), 0.0)[0]

    def min_face_distance(self, X, cutoff: float = np.inf):
        """``(d, (v, f))``: the smallest point-triangle distance from a vertex ``v`` to a face
        ``f`` none of whose vertices is within ``rings`` edges of ``v`` (ties: smallest
        ``(v, f)``); ``(inf, None)`` if it exceeds ``cutoff`` or no such pair exists."""
        X = self._check_positions(X)
        if not cutoff >= 0:
            raise ValueError(f"cutoff must be a non-negative length, got {cutoff!r}")
        return self._distances(X, cKDTree(X, balanced_tree=False, compact_nodes=False),
                               float(cutoff))[1]

    # -- face-face -----------------------------------------------------------------------------

    def intersecting_pairs(self, X, max_pairs: int | None = None) -> tuple[np.ndarray, int]:
        """``(pairs, n)``: the face pairs ``(f, g)``, ``f < g``, sharing no vertex that intersect,
        sorted lexicographically and truncated to ``max_pairs``; ``n`` is the total count.

        Broad phase: centroid pairs that may be within ``rho_f + rho_g``
        (:meth:`_centroid_pairs`), minus pairs sharing a vertex, minus pairs with ``|c_f - c_g| > rho_f + rho_g``, minus pairs whose bounding
        boxes (widened by ``tol`` times the larger ``rho``) are disjoint; then
        :func:`triangles_intersect`.
        """
        X = self._check_positions(X)
        if max_pairs is not None and (isinstance(max_pairs, bool)
                                      or not isinstance(max_pairs, (int, np.integer))
                                      or max_pairs < 1):
            raise ValueError(f"max_pairs must be None or an integer >= 1, got {max_pairs!r}")
        T = X[self.topology.faces]
        centroids = (T[:, 0] + T[:, 1] + T[:, 2]) / 3.0
        rel = T - centroids[:, None]
        r2 = _dot(rel, rel)
        rho = np.sqrt(np.maximum(np.maximum(r2[:, 0], r2[:, 1]), r2[:, 2]))
        cand = self._centroid_pairs(centroids, rho)
        if len(cand):
            cand = cand[~self._sharing.contains(cand[:, 0] * self.topology.n_faces + cand[:, 1])]
        if len(cand):
            a, b = cand[:, 0], cand[:, 1]
            dc = centroids[a] - centroids[b]
            cand = cand[_dot(dc, dc) <= ((rho[a] + rho[b]) * (1 + 1e-9)) ** 2]
        if len(cand):
            Ta, Tb = T[cand[:, 0]], T[cand[:, 1]]
            lo_a = np.minimum(np.minimum(Ta[:, 0], Ta[:, 1]), Ta[:, 2])
            hi_a = np.maximum(np.maximum(Ta[:, 0], Ta[:, 1]), Ta[:, 2])
            lo_b = np.minimum(np.minimum(Tb[:, 0], Tb[:, 1]), Tb[:, 2])
            hi_b = np.maximum(np.maximum(Tb[:, 0], Tb[:, 1]), Tb[:, 2])
            slack = (2 * self.tol * np.maximum(rho[cand[:, 0]], rho[cand[:, 1]]))[:, None]
            cand = cand[((lo_a <= hi_b + slack) & (lo_b <= hi_a + slack)).all(axis=1)]
        if len(cand):
            cand = cand[triangles_intersect(T[cand[:, 0]], T[cand[:, 1]], self.tol)]
        cand = np.unique(np.sort(cand.reshape(-1, 2), axis=1), axis=0).reshape(-1, 2)
        n = len(cand)
        return (cand if max_pairs is None else cand[:max_pairs]), n

    @staticmethod
    def _centroid_pairs(centroids, rho):
        """Face pairs ``(f, g)``, ``f < g``, that may satisfy ``|c_f - c_g| <= rho_f + rho_g``
        (a superset; duplicates possible). With ``rho_q`` = min(max rho, 1.2 median rho): one
        ``query_pairs`` at ``2 rho_q`` over all faces; the faces with ``rho_f > rho_q`` against
        all faces within ``max rho + rho_q``; those faces among themselves within ``2 max rho``.
        A few large faces thus do not inflate the search radius for all."""
        rho_max = float(rho.max())
        rho_q = min(rho_max, 1.2 * float(np.median(rho)))
        tree = cKDTree(centroids, balanced_tree=False, compact_nodes=False)
        cand = tree.query_pairs(2.0 * rho_q, output_type="ndarray").astype(np.int64, copy=False)
        big = np.flatnonzero(rho > rho_q)
        if len(big):
            big_tree = cKDTree(centroids[big], balanced_tree=False, compact_nodes=False)
            near = big_tree.sparse_distance_matrix(tree, rho_max + rho_q, output_type="ndarray")
            among = big_tree.query_pairs(2.0 * rho_max, output_type="ndarray")
            f = np.concatenate([big[near["i"]], big[among[:, 0]]])
            g = np.concatenate([near["j"].astype(np.int64), big[among[:, 1]]])
            extra = np.stack([np.minimum(f, g), np.maximum(f, g)], axis=1)[f != g]
            cand = np.concatenate([cand.reshape(-1, 2), extra])
        return cand

    # -- all together --------------------------------------------------------------------------

    def check(self, X, max_pairs: int | None = None, face_cutoff: float | None = None) -> ContactResult:
        """All self-contact measures of ``X``: intersections, vertex-vertex and vertex-face gaps.

        ``face_cutoff`` defaults to the mean edge length of ``X``: ``min_face_distance`` is
        exact below it and ``inf`` above (no contact within an edge length).
        """
        X = self._check_positions(X)
        if face_cutoff is None:
            face_cutoff = float(self._edge_lengths(X).mean())
        elif not face_cutoff >= 0:
            raise ValueError(f"face_cutoff must be a non-negative length, got {face_cutoff!r}")
        pairs, n = self.intersecting_pairs(X, max_pairs)
        tree = cKDTree(X, balanced_tree=False, compact_nodes=False)
        (d, pair), (df, fpair) = self._distances(X, tree, float(face_cutoff))
        first = (int(pairs[0, 0]), int(pairs[0, 1])) if n else None
        return ContactResult(intersects=bool(n), first_pair=first, n_pairs=int(n), pairs=pairs,
                             min_distance=d, min_pair=pair, min_face_distance=df,
                             min_face_pair=fpair, face_cutoff=float(face_cutoff))


def _first_argmin(values: np.ndarray, keys: np.ndarray, ordered: bool = False) -> int:
    """Index of the smallest value; ties broken by the lexicographically smallest key row
    (rows sorted first unless ``ordered``)."""
    ties = np.flatnonzero(values == values.min())
    if len(ties) == 1:
        return int(ties[0])
    k = keys[ties] if ordered else np.sort(keys[ties], axis=1)
    return int(ties[np.lexsort((k[:, 1], k[:, 0]))[0]])


# ----------------------------------------------------------------------------------------------
# one-shot functions


def min_nonadjacent_distance(X, topology: Topology, rings: int = 2):
    """``(d, (i, j))``: smallest distance between vertices more than ``rings`` edges apart.

    One-shot form of :meth:`ContactChecker.min_vertex_distance`; build a
    :class:`ContactChecker` once to call it repeatedly on one topology.
    """
    return ContactChecker(topology, rings).min_vertex_distance(X)


def min_vertex_face_distance(X, topology: Topology, rings: int = 2, cutoff: float = np.inf):
    """``(d, (v, f))``: smallest distance from a vertex to a face with no vertex within
    ``rings`` edges of it (:meth:`ContactChecker.min_face_distance`)."""
    return ContactChecker(topology, rings).min_face_distance(X, cutoff)


def self_intersections(X, topology: Topology, max_pairs: int | None = None,
                       tol: float = DEFAULT_TOL) -> np.ndarray:
    """Intersecting face pairs ``(n, 2)`` (``f < g``, sorted, no shared vertex) of a surface.

    One-shot form of :meth:`ContactChecker.intersecting_pairs`; ``max_pairs`` truncates the
    sorted list.
    """
    return ContactChecker(topology, rings=0, tol=tol).intersecting_pairs(X, max_pairs)[0]
