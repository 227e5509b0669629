"""Validation of input surfaces and mesh quality reports.

:func:`validate_surface` checks that ``(X, faces)`` is what every energy and solver in
shellbuckle assumes: a closed, manifold, consistently and outward oriented triangulated
surface of genus 0 with finite coordinates and no degenerate, duplicated or unused elements.
It raises :class:`~shellbuckle.mesh.topology.MeshError` naming the first offending vertex,
edge or face, so that a user can find it in their file.

:func:`mesh_quality` summarizes a mesh's shape: triangle angles, edge lengths and their
relative spread, face areas and the vertex valence histogram.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .topology import MeshError, Topology

#: A face is degenerate when its area is below this fraction of the squared mean edge length.
DEGENERATE_AREA_RTOL = 1e-12


def validate_surface(X, faces) -> Topology:
    """Check that ``(X, faces)`` is a closed, oriented, genus-0 manifold surface.

    Parameters
    ----------
    X : (V, 3) float array of vertex positions.
    faces : (F, 3) integer array of vertex indices, counter-clockwise seen from outside.

    Returns
    -------
    Topology
        The connectivity of the surface, built once the checks pass.

    Raises
    ------
    MeshError (a ValueError)
        At the first failed check, in this order, naming the offending element:
        array shapes; non-finite coordinates (vertex); face indices out of range or repeated
        within a face (face); unused vertices (vertex); duplicate faces (both faces); edges
        with other than two faces, i.e. a boundary or a non-manifold edge (edge); edges
        traversed twice in the same direction, i.e. inconsistent orientation (edge and faces);
        non-manifold "bowtie" vertices whose faces do not form one disk (vertex); several
        connected components (a vertex of the second one); Euler characteristic
        ``V - E + F != 2``, i.e. genus > 0; zero-area faces (face); negative enclosed volume
        ``(1/6) sum_f x0 . (x1 x x2)``, i.e. faces oriented inward.
    """
    X, faces = _check_arrays(X, faces)
    n = len(X)
    _check_face_indices(faces, n)
    _check_duplicate_faces(faces)
    _check_edges(faces, n)
    _check_vertex_disks(faces, n)
    _check_genus(faces, n)
    _check_geometry(X, faces)
    return Topology.from_faces(faces, n_vertices=n)


def _check_arrays(X, faces):
    X = np.asarray(X)
    if X.ndim != 2 or X.shape[1] != 3 or len(X) == 0:
        raise MeshError(f"vertex positions must be a non-empty (V, 3) array, got shape {X.shape}")
    if not np.issubdtype(X.dtype, np.number) or np.iscomplexobj(X):
        raise MeshError(f"vertex positions must be real numbers, got dtype {X.dtype}")
    X = X.astype(np.float64, copy=False)
    finite = np.isfinite(X).all(axis=1)
    if not finite.all():
        v = int(np.flatnonzero(~finite)[0])
        raise MeshError(f"vertex {v} has a non-finite coordinate {X[v].tolist()}")
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise MeshError(f"faces must be a non-empty (F, 3) array of vertex indices (triangles), "
                        f"got shape {faces.shape}")
    if not np.issubdtype(faces.dtype, np.integer):
        if not (np.issubdtype(faces.dtype, np.floating) and np.all(faces == np.round(faces))):
            raise MeshError(f"faces must hold integer vertex indices, got dtype {faces.dtype}")
    return X, faces.astype(np.int64)


def _check_face_indices(faces: np.ndarray, n: int) -> None:
    bad = ((faces < 0) | (faces >= n)).any(axis=1)
    if bad.any():
        f = int(np.flatnonzero(bad)[0])
        raise MeshError(f"face {f} {faces[f].tolist()} uses a vertex index outside [0, {n - 1}]")
    repeated = ((faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2])
                | (faces[:, 2] == faces[:, 0]))
    if repeated.any():
        f = int(np.flatnonzero(repeated)[0])
        raise MeshError(f"face {f} {faces[f].tolist()} repeats a vertex")
    unused = np.bincount(faces.ravel(), minlength=n) == 0
    if unused.any():
        v = int(np.flatnonzero(unused)[0])
        raise MeshError(f"vertex {v} belongs to no face ({int(unused.sum())} unused vertices); "
                        "remove unused vertices")


def _check_duplicate_faces(faces: np.ndarray) -> None:
    key = np.sort(faces, axis=1)
    order = np.lexsort(key.T[::-1])
    same = (key[order[1:]] == key[order[:-1]]).all(axis=1)
    if same.any():
        pairs = np.sort(np.stack([order[:-1][same], order[1:][same]], axis=1), axis=1)
        i, j = pairs[np.argmin(pairs[:, 1])]
        raise MeshError(f"face {j} {faces[j].tolist()} duplicates face {i} {faces[i].tolist()} "
                        "(same three vertices)")


def _half_edges(faces: np.ndarray):
    """Half-edge ``h = 3 f + k`` runs ``faces[f, k] -> faces[f, (k+1) % 3]``."""
    tail = faces.ravel()
    head = np.roll(faces, -1, axis=1).ravel()
    return tail, head


def _check_edges(faces: np.ndarray, n: int) -> None:
    tail, head = _half_edges(faces)
    key = np.minimum(tail, head) * n + np.maximum(tail, head)
    order = np.argsort(key, kind="stable")
    skey = key[order]
    starts = np.flatnonzero(np.r_[True, skey[1:] != skey[:-1]])
    counts = np.diff(np.r_[starts, len(skey)])
    if (counts != 2).any():
        e = int(np.flatnonzero(counts != 2)[0])
        a, b = divmod(int(skey[starts[e]]), n)
        fs = (order[starts[e]:starts[e] + counts[e]] // 3).tolist()
        if counts[e] == 1:
            raise MeshError(f"edge ({a}, {b}) belongs to only one face ({fs[0]}): the surface is "
                            "not closed (it has a boundary)")
        raise MeshError(f"edge ({a}, {b}) is shared by {counts[e]} faces {fs}: non-manifold edge "
                        "(a closed manifold surface has exactly 2 faces on every edge)")
    h0, h1 = order[starts], order[starts + 1]
    same = tail[h0] == tail[h1]
    if same.any():
        e = int(np.flatnonzero(same)[0])
        a, b = divmod(int(skey[starts[e]]), n)
        raise MeshError(f"edge ({a}, {b}) is traversed in the same direction by faces "
                        f"{h0[e] // 3} and {h1[e] // 3}: faces are not consistently oriented")


def _check_vertex_disks(faces: np.ndarray, n: int) -> None:
    """Each vertex's faces must form a single fan (one disk), not several touching at it.

    Corners ``c = 3 f + k`` (vertex ``faces[f, k]``) are linked across every edge at their
    vertex: the corner at the tail of half-edge ``h`` and the corner at the head of its twin.
    The fans around a vertex are the connected components of its corners.
    """
    tail, head = _half_edges(faces)
    n_half = len(tail)
    key = tail * n + head
    order = np.argsort(key)
    twin = order[np.searchsorted(key[order], head * n + tail)]  # valid: edges checked before
    f_twin, k_twin = np.divmod(twin, 3)
    corner_at_twin_head = 3 * f_twin + (k_twin + 1) % 3
    graph = sp.coo_matrix((np.ones(n_half), (np.arange(n_half), corner_at_twin_head)),
                          shape=(n_half, n_half))
    n_fans, label = connected_components(graph, directed=False)
    if n_fans == n:
        return
    lo = np.full(n, n_fans)
    hi = np.full(n, -1)
    np.minimum.at(lo, tail, label)
    np.maximum.at(hi, tail, label)
    v = int(np.flatnonzero(lo != hi)[0])
    fans = len(np.unique(label[tail == v]))
    raise MeshError(f"vertex {v} is a non-manifold (bowtie) vertex: its faces form {fans} "
                    "separate fans that touch only at this vertex instead of a single disk")


def _check_genus(faces: np.ndarray, n: int) -> None:
    tail, head = _half_edges(faces)
    graph = sp.coo_matrix((np.ones(len(tail)), (tail, head)), shape=(n, n))
    n_comp, label = connected_components(graph, directed=False)
    if n_comp > 1:
        v = int(np.flatnonzero(label != label[0])[0])
        raise MeshError(f"the surface has {n_comp} connected components (vertex {v} is not "
                        "connected to vertex 0); a single closed surface is required")
    n_edges = len(tail) // 2
    chi = n - n_edges + len(faces)
    if chi != 2:
        raise MeshError(f"Euler characteristic V - E + F = {n} - {n_edges} + {len(faces)} = "
                        f"{chi}, i.e. genus {(2 - chi) // 2}; a closed surface of sphere "
                        "topology (genus 0) has 2")


def _check_geometry(X: np.ndarray, faces: np.ndarray) -> None:
    x0, x1, x2 = X[faces[:, 0]], X[faces[:, 1]], X[faces[:, 2]]
    cross = np.cross(x1 - x0, x2 - x0)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    edge_sq = np.mean([np.sum((x1 - x0) ** 2, 1), np.sum((x2 - x1) ** 2, 1),
                       np.sum((x0 - x2) ** 2, 1)])
    degenerate = area <= DEGENERATE_AREA_RTOL * edge_sq
    if degenerate.any():
        f = int(np.flatnonzero(degenerate)[0])
        raise MeshError(f"face {f} {faces[f].tolist()} is degenerate (area {area[f]:.3g}; "
                        "its vertices are coincident or collinear)")
    volume = float(np.einsum("ij,ij->", x0, np.cross(x1, x2)) / 6.0)
    if volume < 0:
        raise MeshError(f"enclosed volume is negative ({volume:.6g}): the faces are oriented "
                        "inward (clockwise seen from outside); flip them, e.g. faces[:, ::-1]")
    if volume == 0:
        raise MeshError("enclosed volume is zero: the surface encloses no volume")


@dataclass(frozen=True)
class MeshQuality:
    """Shape statistics of a triangulated surface.

    Angles are the interior angles of all faces in degrees; edge lengths are over the unique
    edges, in the mesh's length unit; ``edge_rel_std`` is std / mean of the edge lengths
    (population std); ``area_ratio`` is the largest over the smallest face area;
    ``valence_histogram`` maps a valence (edges at a vertex) to its number of vertices.
    """

    n_vertices: int
    n_edges: int
    n_faces: int
    min_angle_deg: float
    mean_angle_deg: float
    max_angle_deg: float
    edge_min: float
    edge_mean: float
    edge_max: float
    edge_rel_std: float
    area_ratio: float
    valence_histogram: dict[int, int]

    def to_dict(self) -> dict:
        return asdict(self)

    def __str__(self) -> str:
        valences = ", ".join(f"{k}: {v}" for k, v in sorted(self.valence_histogram.items()))
        return "\n".join([
            f"mesh quality: {self.n_vertices} vertices, {self.n_edges} edges, "
            f"{self.n_faces} faces",
            f"  angles (deg):  min {self.min_angle_deg:.2f}  mean {self.mean_angle_deg:.2f}  "
            f"max {self.max_angle_deg:.2f}",
            f"  edge length:   min {self.edge_min:.4g}  mean {self.edge_mean:.4g}  "
            f"max {self.edge_max:.4g}  relative std {self.edge_rel_std:.4f}",
            f"  face area:     max/min {self.area_ratio:.3f}",
            f"  valence:       {valences}",
        ])


def face_angles(X: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Interior angles ``(F, 3)`` in radians; column ``k`` is the angle at corner ``k``."""
    x = X[faces]
    u = np.roll(x, -1, axis=1) - x
    w = np.roll(x, 1, axis=1) - x
    return np.arctan2(np.linalg.norm(np.cross(u, w), axis=2), np.einsum("fki,fki->fk", u, w))


def mesh_quality(mesh) -> MeshQuality:
    """Angles, edge lengths, face areas and valences of ``mesh`` (a :class:`Mesh`)."""
    X, topo = mesh.X, mesh.topology
    angles = np.degrees(face_angles(X, topo.faces))
    e = topo.edges
    length = np.linalg.norm(X[e[:, 1]] - X[e[:, 0]], axis=1)
    x0, x1, x2 = (X[topo.faces[:, k]] for k in range(3))
    area = 0.5 * np.linalg.norm(np.cross(x1 - x0, x2 - x0), axis=1)
    valence, count = np.unique(topo.valence(), return_counts=True)
    return MeshQuality(
        n_vertices=int(topo.n_vertices), n_edges=int(topo.n_edges), n_faces=int(topo.n_faces),
        min_angle_deg=float(angles.min()), mean_angle_deg=float(angles.mean()),
        max_angle_deg=float(angles.max()),
        edge_min=float(length.min()), edge_mean=float(length.mean()),
        edge_max=float(length.max()), edge_rel_std=float(length.std() / length.mean()),
        area_ratio=float(area.max() / area.min()),
        valence_histogram={int(k): int(c) for k, c in zip(valence, count)})
