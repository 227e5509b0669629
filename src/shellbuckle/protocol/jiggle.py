"""Jiggle: seeded random vertex displacements at the start of each volume step.

As in Surface Evolver's ``jiggle`` (Quilliet et al. 2008, §4.1: "stochasticity was introduced
by jiggling the position of the vertices at the beginning of each minimization"), every vertex
moves by an independent isotropic Gaussian displacement of standard deviation ``sigma`` per
coordinate. Two ways to set ``sigma``:

- ``temperature`` T, Surface Evolver's own scale (the paper's runs):
  ``sigma = EVOLVER_JIGGLE_SCALE * T * L``, with ``L`` the largest bounding-box extent of the
  initial surface (Evolver's ``overall_size``, 2R for the sphere). Surface Evolver 2.70
  (``iterate.c``: ``jiggle``) moves each coordinate by ``gaussian() * temperature * max_len *
  overall_size``, where ``gaussian()`` (a sum of five uniform numbers) has standard deviation
  0.2 and ``max_len`` keeps its default 1.4 unless the datafile sets a maximum edge length, so
  the factor is ``0.2 * 1.4 = 0.28``. Its default temperature 0.05 gives sigma = 0.028 R,
  whatever the mesh: 0.44 mean edge lengths on the paper's 3594-vertex mesh. Measured on
  ``evolver`` 2.70 itself (``j`` with temperature 0.05 on 642- and 2562-vertex spheres of
  radius 1 and 2): sigma = 0.0279 R and 0.0280 R.
- a ``jiggle`` amplitude a: ``sigma = a * mean edge length`` of the current mesh.

The random stream of step ``k`` of a run with seed ``s`` is ``numpy.random.default_rng([s, k])``,
so a resumed run draws exactly the numbers an uninterrupted one would.

Either way the displacements are white noise at the vertices: on a finer mesh the same
``sigma`` is another, rougher perturbation. The smooth imperfection
(:mod:`.imperfection`, ``Protocol.smooth_jiggle``) is a field on the reference sphere instead,
the same on any mesh, drawn from the same streams.
"""

from __future__ import annotations

import numpy as np

EVOLVER_JIGGLE_SCALE = 0.2 * 1.4
"""Surface Evolver's jiggle displacement per unit temperature and unit ``overall_size``."""

EVOLVER_DEFAULT_TEMPERATURE = 0.05
"""Surface Evolver's default jiggle temperature."""


def step_rng(seed: int, step: int) -> np.random.Generator:
    """The random stream of volume step ``step`` of a run seeded with ``seed``."""
    return np.random.default_rng([int(seed), int(step)])


def mean_edge_length(X: np.ndarray, edges: np.ndarray) -> float:
    return float(np.linalg.norm(X[edges[:, 0]] - X[edges[:, 1]], axis=1).mean())


def overall_size(X: np.ndarray) -> float:
    """Largest bounding-box extent of ``X`` (V, 3), Surface Evolver's ``overall_size``."""
    return float(np.ptp(np.asarray(X, float), axis=0).max())


def evolver_sigma(temperature: float, X_reference: np.ndarray) -> float:
    """Per-coordinate displacement std of Surface Evolver's jiggle at ``temperature``."""
    return EVOLVER_JIGGLE_SCALE * float(temperature) * overall_size(X_reference)


def jiggle(X: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Return ``X`` plus Gaussian displacements of std ``sigma`` per coordinate
    (:func:`evolver_sigma`, or a fraction of :func:`mean_edge_length`). No random numbers are
    drawn for ``sigma = 0``."""
    if sigma == 0:
        return X.copy()
    return X + float(sigma) * rng.standard_normal(X.shape)
