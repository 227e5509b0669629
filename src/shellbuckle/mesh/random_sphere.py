"""Isotropic randomized sphere meshes with a prescribed number of vertices.

An icosahedral mesh has twelve valence-5 vertices at the icosahedron's corners and rows of
edges along its great circles; under deflation these can decide where dimples and wrinkles
form. Quilliet et al. (EPJE 27, 13 (2008), §4.1, after Tsapis et al., PRL 94, 018302 (2005))
therefore also used an *isotropic randomized mesh* of 3594 vertices, on which no direction or
site is special.

Construction
------------
1. ``n_vertices`` points uniform on the unit sphere, from a seeded ``numpy`` Generator
   (normalized standard normal triples).
2. Spherical centroidal Voronoi relaxation (Lloyd's algorithm; Du, Faber & Gunzburger,
   SIAM Rev. 41, 637 (1999); Du, Gunzburger & Ju, SIAM J. Numer. Anal. 40, 1445 (2002)):
   each iteration triangulates the points as their convex hull (the spherical Delaunay
   triangulation), computes the centroid ``c_v`` of every Voronoi cell and moves the point to
   ``x_v <- normalize(x_v + omega (c_v - x_v))``. ``omega = 1`` is plain Lloyd; ``omega = 1.8``
   (over-relaxation, used after the first iterations) reaches the same quality in about half
   the iterations. A fixed, finite number of iterations spreads the points evenly but keeps
   the random positions of the valence-5/7 defects: the result does not approach any
   symmetric configuration.
3. The final convex hull, faces oriented outward (counter-clockwise seen from outside),
   scaled to radius ``R``. The hull of points on a sphere is their Delaunay triangulation,
   which maximizes the minimum angle over all triangulations of those points, so no
   further flipping can improve it.

Voronoi cell centroids are computed without building the cells: the cell of vertex ``v`` is
the signed union, over the faces ``f`` at ``v`` and the two edges of ``f`` at ``v``, of the
triangles ``(x_v, m_vw, c_f)`` where ``m_vw`` is the (spherical) midpoint of edge ``vw`` and
``c_f`` the circumcentre of ``f`` on the sphere (its outward unit normal). Each such triangle
is taken flat; its signed area is measured along ``x_v``.

Typical quality (see :func:`shellbuckle.mesh.mesh_quality`): minimum angle about 38 deg and
edge-length relative spread about 0.085 at 3594 vertices (36.6-39.2 deg over seeds 0-5),
built in one to two seconds; 10k vertices in about 5 s, 40k in about 25 s.
"""

from __future__ import annotations

import logging
import numbers

import numpy as np
from scipy.spatial import ConvexHull

from .checks import validate_surface
from .mesh import Mesh
from .topology import MeshError

log = logging.getLogger(__name__)

_PLAIN_LLOYD_ITERATIONS = 3   # omega = 1 while the initial random clumps spread out
_MIN_OVERRELAXED = 32         # below this, cells are so large that over-relaxed steps overshoot


def random_sphere(n_vertices: int = 3594, seed: int = 0, R: float = 1.0, *,
                  iterations: int = 50, omega: float = 1.8) -> Mesh:
    """Isotropic randomized triangulated sphere with exactly ``n_vertices`` vertices.

    Parameters
    ----------
    n_vertices : int >= 4
        Number of vertices (Quilliet et al. 2008 used 3594). The mesh has ``2 n - 4`` faces
        and ``3 n - 6`` edges.
    seed : int >= 0
        Seed of the ``numpy.random.Generator``; the same seed gives a bitwise identical mesh.
    R : float > 0
        Radius; all vertices lie on the sphere of radius ``R``.
    iterations : int >= 0
        Number of Lloyd (centroidal Voronoi) iterations. 0 gives the Delaunay triangulation
        of the raw uniform random points (badly shaped; for tests and illustration).
    omega : float in [1, 2)
        Over-relaxation factor of the Lloyd steps after the first three (meshes of 32 or more
        vertices; smaller ones use plain Lloyd steps throughout).

    Returns
    -------
    Mesh
        Vertex positions ``(n_vertices, 3)`` and outward-oriented faces ``(2 n - 4, 3)``,
        faces sorted canonically (each rotated to start at its smallest vertex index, rows in
        lexicographic order).

    Cost: one convex hull per iteration, about 20 ms at 3594 vertices and 0.25 s at 40k.
    """
    n_vertices = _check_int("n_vertices", n_vertices, minimum=4)
    seed = _check_int("seed", seed, minimum=0)
    iterations = _check_int("iterations", iterations, minimum=0)
    if not (isinstance(R, numbers.Real) and np.isfinite(R) and R > 0):
        raise ValueError(f"radius R must be a positive finite number, got {R!r}")
    if not (isinstance(omega, numbers.Real) and 1.0 <= omega < 2.0):
        raise ValueError(f"over-relaxation omega must be in [1, 2), got {omega!r}")

    rng = np.random.default_rng(seed)
    X = _normalize(rng.standard_normal((n_vertices, 3)))
    for it in range(iterations):
        faces = _hull_faces(X)
        C = _voronoi_centroids(X, faces)
        relaxed = it >= _PLAIN_LLOYD_ITERATIONS and n_vertices >= _MIN_OVERRELAXED
        w = float(omega) if relaxed else 1.0
        X = _normalize(X + w * (C - X))
    faces = _canonical_faces(_hull_faces(X))
    used = np.bincount(faces.ravel(), minlength=n_vertices) > 0
    if not used.all():
        v = int(np.flatnonzero(~used)[0])
        raise MeshError(f"random_sphere: vertex {v} is not on the convex hull (coincident points); "
                        "try another seed or more iterations")
    X = float(R) * X
    validate_surface(X, faces)
    log.debug("random_sphere: %d vertices, %d faces, seed %d, %d iterations",
              n_vertices, len(faces), seed, iterations)
    return Mesh.from_arrays(X, faces)


def _check_int(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _normalize(v: np.ndarray) -> np.ndarray:
    """Rows of ``v (..., 3)`` scaled to unit length."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _hull_faces(X: np.ndarray) -> np.ndarray:
    """Convex hull of ``X (V, 3)`` as faces ``(F, 3)`` with ``(x1 - x0) x (x2 - x0)`` outward.

    Outward is taken from Qhull's facet hyperplanes, so it is right even when the origin lies
    outside the hull (possible for a few raw random points).
    """
    hull = ConvexHull(X)
    faces = hull.simplices.astype(np.int64)
    x0, x1, x2 = X[faces[:, 0]], X[faces[:, 1]], X[faces[:, 2]]
    inward = np.einsum("ij,ij->i", np.cross(x1 - x0, x2 - x0), hull.equations[:, :3]) < 0
    faces[inward] = faces[inward][:, ::-1]
    return faces


def _canonical_faces(faces: np.ndarray) -> np.ndarray:
    """Rotate each face to start at its smallest index (orientation kept), sort the rows."""
    shift = np.argmin(faces, axis=1)
    cols = (shift[:, None] + np.arange(3)[None, :]) % 3
    faces = np.take_along_axis(faces, cols, axis=1)
    return np.ascontiguousarray(faces[np.lexsort(faces.T[::-1])])


def _voronoi_centroids(X: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Centroids ``(V, 3)`` of the Voronoi cells of unit vectors ``X`` on the sphere.

    Sum over faces ``(a, b, c)`` and corners: the corner ``a`` collects the flat triangles
    ``(x_a, m_ab, c_f)`` and ``(x_a, c_f, m_ca)`` with signed area ``½ ((p - x_a) x (q - x_a)) . x_a``
    and centroid ``(x_a + p + q) / 3``. The result is not normalized; a vertex with no face
    (absent from the hull) keeps its position.
    """
    n = len(X)
    x = X[faces]                                             # (F, 3 corners, 3)
    circ = _normalize(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]))  # (F, 3)
    nxt = np.roll(x, -1, axis=1)
    prv = np.roll(x, 1, axis=1)
    m_next = _normalize(x + nxt)                             # midpoint of edge corner -> next
    m_prev = _normalize(x + prv)                             # midpoint of edge prev -> corner
    c = np.broadcast_to(circ[:, None, :], x.shape)
    area1 = 0.5 * np.einsum("fki,fki->fk", np.cross(m_next - x, c - x), x)
    area2 = 0.5 * np.einsum("fki,fki->fk", np.cross(c - x, m_prev - x), x)
    moment = (area1[..., None] * (x + m_next + c) + area2[..., None] * (x + c + m_prev)) / 3.0
    idx = faces.ravel()
    weight = np.bincount(idx, (area1 + area2).ravel(), minlength=n)
    moment = moment.reshape(-1, 3)
    acc = np.stack([np.bincount(idx, moment[:, k], minlength=n) for k in range(3)], axis=1)
    out = X.copy()
    has_cell = weight > 0
    out[has_cell] = acc[has_cell] / weight[has_cell, None]
    return out

