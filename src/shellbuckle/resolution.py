"""How fine a triangulated sphere is, and how fine it must be for a shell: the mean edge of a
sphere of N vertices, the largest spontaneous curvature it draws, and the vertices that
resolve the elastic length ``l_el = R gamma^(-1/4)`` (a mean edge at most ``pi l_el``, two
edges per classical buckling wavelength ``2 pi l_el``; Hutchinson, J. Appl. Mech. 34, 49
(1967)).

A light module (the standard library only): the command line refuses a mesh or a ``c0`` with
it before it loads anything, and :func:`shellbuckle.run.deflate` applies the same rules.
"""

from __future__ import annotations

import math


def mean_edge(n_vertices: int) -> float:
    """Mean edge / R of a closed triangulated sphere of ``n_vertices``: its 2 (N - 2) faces,
    near equilateral, cover 4 pi R^2, so a^2 = 8 pi / (sqrt(3) (N - 2))."""
    return math.sqrt(8.0 * math.pi / (math.sqrt(3.0) * max(n_vertices - 2, 1)))


def c0_limit(n_vertices: int, R: float = 1.0) -> float:
    """The largest |c0| a sphere of radius ``R`` and ``n_vertices`` takes: a preferred radius
    ``2/|c0|`` no shorter than its mean edge (:func:`mean_edge`), below which the mesh cannot
    draw the curvature it is asked for."""
    return 2.0 / (mean_edge(n_vertices) * R)


def vertices_needed(gamma_effective: float) -> int:
    """Vertices of a sphere whose mean edge is at most pi l_el, half the classical buckling
    wavelength 2 pi l_el (l_el = R gamma^(-1/4)): N >= 8 sqrt(gamma) / (sqrt(3) pi) + 2."""
    return math.ceil(8.0 * math.sqrt(gamma_effective) / (math.sqrt(3.0) * math.pi)) + 2


def gamma_resolved(n_vertices: int) -> float:
    """The largest (effective) gamma a mesh of ``n_vertices`` resolves."""
    return (math.sqrt(3.0) * math.pi * (n_vertices - 2) / 8.0) ** 2
