"""Icosahedral sphere meshes: the icosahedron with each face split into n^2 triangles.

Level ``n`` (``n >= 1``) has ``10 n^2 + 2`` vertices and ``20 n^2`` faces: n = 8 gives 642
vertices, n = 19 gives 3612, n = 32 gives 10242. Twelve vertices have valence 5, all others 6.
Vertices are projected radially onto the sphere of radius ``R``.
"""

from __future__ import annotations

import numpy as np

from .mesh import Mesh


def _icosahedron():
    p = (1.0 + 5.0 ** 0.5) / 2.0
    X = np.array([[-1, p, 0], [1, p, 0], [-1, -p, 0], [1, -p, 0],
                  [0, -1, p], [0, 1, p], [0, -1, -p], [0, 1, -p],
                  [p, 0, -1], [p, 0, 1], [-p, 0, -1], [-p, 0, 1]], dtype=float)
    F = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
                  [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
                  [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
                  [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    return X / np.linalg.norm(X, axis=1, keepdims=True), F


def icosphere(n: int = 8, R: float = 1.0) -> Mesh:
    """Sphere of radius ``R`` from the icosahedron with every edge divided into ``n`` parts."""
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"icosphere subdivision n must be an integer >= 1, got {n!r}")
    if not (np.isfinite(R) and R > 0):
        raise ValueError(f"radius R must be a positive finite number, got {R!r}")
    X0, F0 = _icosahedron()
    # barycentric lattice points (i, j) with i + j <= n on every face, merged by position
    ij = np.array([(i, j) for i in range(n + 1) for j in range(n + 1 - i)])
    idx = {tuple(p): k for k, p in enumerate(ij)}
    tri = []
    for i in range(n):
        for j in range(n - i):
            tri.append((idx[i, j], idx[i + 1, j], idx[i, j + 1]))
            if i + j < n - 1:
                tri.append((idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]))
    tri = np.array(tri)
    a, b, c = X0[F0[:, 0]], X0[F0[:, 1]], X0[F0[:, 2]]
    w = ij / n
    pts = (a[:, None] * (1 - w.sum(1))[None, :, None] + b[:, None] * w[None, :, 0, None]
           + c[:, None] * w[None, :, 1, None])  # (20, P, 3)
    pts = pts.reshape(-1, 3)
    key = np.round(pts * (4 * n), 6)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    faces = (inverse.reshape(20, -1)[:, tri]).reshape(-1, 3)
    X = pts[first]
    X = R * X / np.linalg.norm(X, axis=1, keepdims=True)
    return Mesh.from_arrays(X, faces)
