"""Jiggle: seeded random vertex displacements at the start of each volume step.

As in Surface Evolver's ``jiggle`` (Quilliet et al. 2008, §4.1: "stochasticity was introduced
by jiggling the position of the vertices at the beginning of each minimization"), every vertex
moves by an independent isotropic Gaussian displacement. Here its standard deviation per
coordinate is ``amplitude`` times the mean edge length of the current mesh. The random stream
of step ``k`` of a run with seed ``s`` is ``numpy.random.default_rng([s, k])``, so a resumed
run draws exactly the numbers an uninterrupted one would.
"""

from __future__ import annotations

import numpy as np


def step_rng(seed: int, step: int) -> np.random.Generator:
    """The random stream of volume step ``step`` of a run seeded with ``seed``."""
    return np.random.default_rng([int(seed), int(step)])


def mean_edge_length(X: np.ndarray, edges: np.ndarray) -> float:
    return float(np.linalg.norm(X[edges[:, 0]] - X[edges[:, 1]], axis=1).mean())


def jiggle(X: np.ndarray, edges: np.ndarray, amplitude: float, rng: np.random.Generator) -> np.ndarray:
    """Return ``X`` plus Gaussian displacements of std ``amplitude * mean edge length``."""
    if amplitude == 0:
        return X.copy()
    scale = amplitude * mean_edge_length(X, edges)
    return X + scale * rng.standard_normal(X.shape)
