"""Connectivity of a closed triangulated surface, computed once per mesh.

Only vertex positions ``X`` (float64, shape ``(V, 3)``) change during a run; everything here
is integer arrays derived from ``faces`` and is frozen.

Conventions
-----------
- ``faces (F, 3)``: vertex indices, counter-clockwise seen from outside (outward normals
  ``(x1 - x0) x (x2 - x0)``).
- ``edges (E, 2)``: each undirected edge once, ``edges[:, 0] < edges[:, 1]``, sorted.
- ``face_edges (F, 3)``: ``face_edges[f, k]`` is the edge opposite corner ``k`` of face ``f``,
  i.e. joining ``faces[f, (k+1) % 3]`` and ``faces[f, (k+2) % 3]``.
- ``edge_faces (E, 2)``: column 0 is the face in which the edge runs ``edges[e,0] -> edges[e,1]``,
  column 1 the face in which it runs backwards.
- ``hinges (E, 4)``: ``(i, j, k, l)`` with ``(i, j) = edges[e]``, ``k`` the vertex opposite the
  edge in ``edge_faces[e, 0]`` (that face is ``(i, j, k)`` up to rotation) and ``l`` the one in
  ``edge_faces[e, 1]`` (face ``(j, i, l)``).
- Vertex stars are CSR-like: the faces around vertex ``v`` are
  ``vertex_faces[vertex_faces_ptr[v]:vertex_faces_ptr[v+1]]``; the same for
  ``vertex_neighbors``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class MeshError(ValueError):
    """An input mesh is not a closed, oriented, manifold triangulated surface."""


@dataclass(frozen=True, eq=False)
class Topology:
    faces: np.ndarray
    n_vertices: int
    edges: np.ndarray = field(repr=False)
    face_edges: np.ndarray = field(repr=False)
    edge_faces: np.ndarray = field(repr=False)
    hinges: np.ndarray = field(repr=False)
    vertex_faces_ptr: np.ndarray = field(repr=False)
    vertex_faces: np.ndarray = field(repr=False)
    vertex_neighbors_ptr: np.ndarray = field(repr=False)
    vertex_neighbors: np.ndarray = field(repr=False)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    @property
    def n_edges(self) -> int:
        return len(self.edges)

    @property
    def euler_characteristic(self) -> int:
        return self.n_vertices - self.n_edges + self.n_faces

    def valence(self) -> np.ndarray:
        """Number of edges at each vertex, shape ``(V,)``."""
        return np.diff(self.vertex_neighbors_ptr)

    def mean_edge_length(self, X: np.ndarray) -> float:
        """Mean length of the edges at positions ``X (V, 3)``, each undirected edge once: the
        length scale of the jiggle and of the shape analysis' resolution (same bits as
        ``norm(X[edges[:, 1]] - X[edges[:, 0]]).mean()``)."""
        X = np.asarray(X, dtype=np.float64)
        return float(np.linalg.norm(X[self.edges[:, 1]] - X[self.edges[:, 0]], axis=1).mean())

    @classmethod
    def from_faces(cls, faces, n_vertices: int | None = None) -> "Topology":
        """Build the connectivity of a closed, consistently oriented, manifold surface.

        Raises :class:`MeshError` naming the first offending edge when an edge does not have
        exactly two faces, or when two faces traverse an edge in the same direction.
        """
        faces = np.ascontiguousarray(faces, dtype=np.int64)
        if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
            raise MeshError(f"faces must be a non-empty (F, 3) integer array, got shape {faces.shape}")
        if faces.min() < 0:
            raise MeshError(f"faces contain a negative vertex index ({faces.min()})")
        if n_vertices is None:
            n_vertices = int(faces.max()) + 1
        if faces.max() >= n_vertices:
            raise MeshError(f"faces use vertex {faces.max()} but there are only {n_vertices} vertices")
        degenerate = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
        if degenerate.any():
            f = int(np.flatnonzero(degenerate)[0])
            raise MeshError(f"face {f} {faces[f].tolist()} repeats a vertex")
        n_faces = len(faces)
        # directed half-edges: corner k -> edge opposite to k, from (k+1) to (k+2)
        tail = faces[:, [1, 2, 0]].ravel()
        head = faces[:, [2, 0, 1]].ravel()
        lo, hi = np.minimum(tail, head), np.maximum(tail, head)
        key = lo * n_vertices + hi
        order = np.argsort(key, kind="stable")
        skey = key[order]
        starts = np.flatnonzero(np.r_[True, skey[1:] != skey[:-1]])
        counts = np.diff(np.r_[starts, len(skey)])
        if (counts != 2).any():
            bad = int(np.flatnonzero(counts != 2)[0])
            k = skey[starts[bad]]
            raise MeshError(
                f"edge ({k // n_vertices}, {k % n_vertices}) belongs to {counts[bad]} faces; "
                "a closed manifold surface needs exactly 2 faces on every edge")
        first, second = order[starts], order[starts + 1]
        edges = np.stack([skey[starts] // n_vertices, skey[starts] % n_vertices], axis=1)
        forward_first = tail[first] == edges[:, 0]
        forward_second = tail[second] == edges[:, 0]
        same = forward_first == forward_second
        if same.any():
            e = int(np.flatnonzero(same)[0])
            raise MeshError(
                f"edge ({edges[e, 0]}, {edges[e, 1]}) is traversed in the same direction by faces "
                f"{first[e] // 3} and {second[e] // 3}: faces are not consistently oriented")
        fwd = np.where(forward_first, first, second)  # half-edge running i -> j
        bwd = np.where(forward_first, second, first)
        n_edges = len(edges)
        face_edges = np.empty(3 * n_faces, dtype=np.int64)
        face_edges[first] = np.arange(n_edges)
        face_edges[second] = np.arange(n_edges)
        face_edges = face_edges.reshape(n_faces, 3)
        edge_faces = np.stack([fwd // 3, bwd // 3], axis=1)
        hinges = np.stack([edges[:, 0], edges[:, 1],
                           faces.ravel()[fwd], faces.ravel()[bwd]], axis=1)
        vf_ptr, vf = _csr_groups(faces.ravel(), np.repeat(np.arange(n_faces), 3), n_vertices)
        both = np.concatenate([edges, edges[:, ::-1]])
        vn_ptr, vn = _csr_groups(both[:, 0], both[:, 1], n_vertices)
        if (np.diff(vf_ptr) == 0).any():
            v = int(np.flatnonzero(np.diff(vf_ptr) == 0)[0])
            raise MeshError(f"vertex {v} belongs to no face")
        for a in (faces, edges, face_edges, edge_faces, hinges, vf_ptr, vf, vn_ptr, vn):
            a.setflags(write=False)
        return cls(faces=faces, n_vertices=int(n_vertices), edges=edges, face_edges=face_edges,
                   edge_faces=edge_faces, hinges=hinges, vertex_faces_ptr=vf_ptr,
                   vertex_faces=vf, vertex_neighbors_ptr=vn_ptr, vertex_neighbors=vn)


def _csr_groups(group: np.ndarray, value: np.ndarray, n_groups: int):
    """Group ``value`` by ``group`` into CSR arrays ``(ptr, values)``."""
    order = np.argsort(group, kind="stable")
    ptr = np.zeros(n_groups + 1, dtype=np.int64)
    np.cumsum(np.bincount(group, minlength=n_groups), out=ptr[1:])
    return ptr, np.ascontiguousarray(value[order], dtype=np.int64)
