"""A triangulated surface: vertex positions plus frozen topology."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .topology import Topology


@dataclass(frozen=True, eq=False)
class Mesh:
    """Vertex positions ``X (V, 3)`` float64 and the :class:`Topology` of a closed surface."""

    X: np.ndarray
    topology: Topology

    @classmethod
    def from_arrays(cls, X, faces) -> "Mesh":
        X = np.array(X, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != 3:
            raise ValueError(f"vertex positions must be a (V, 3) array, got shape {X.shape}")
        if not np.isfinite(X).all():
            v = int(np.flatnonzero(~np.isfinite(X).all(axis=1))[0])
            raise ValueError(f"vertex {v} has a non-finite coordinate {X[v].tolist()}")
        return cls(X=X, topology=Topology.from_faces(faces, n_vertices=len(X)))

    @property
    def faces(self) -> np.ndarray:
        return self.topology.faces

    @property
    def n_vertices(self) -> int:
        return self.topology.n_vertices

    def with_positions(self, X) -> "Mesh":
        X = np.asarray(X, dtype=np.float64)
        if X.shape != self.X.shape:
            raise ValueError(f"positions must have shape {self.X.shape}, got {X.shape}")
        return Mesh(X=X, topology=self.topology)
