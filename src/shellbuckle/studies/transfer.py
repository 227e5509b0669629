"""A conformation carried from one mesh of a shell to another mesh of the same shell, and
relaxed there: is a state of one mesh a state of the shell?

Method. A vertex of a mesh is a material point, named by its direction from the centre of the
mesh's fitted reference sphere (:func:`~shellbuckle.protocol.imperfection.reference_directions`;
the material points of the shape imperfection and of the dent axis). The target mesh's
material points are located in the source mesh's reference triangles (the triangle that the
ray in that direction crosses, and the barycentric coordinates of the crossing), and the
source conformation is interpolated linearly there (:func:`material_interpolation`): the
target vertices sample the source's piecewise-linear surface at their own material points.
That start is then minimized, at the source step's volume fraction, with the target run's own
energy (its convention, c0 and shape imperfection) by the protocol's minimization (Newton's
method at fixed volume, certified: inertia 0; no jiggle and no zero-curvature cycle)
(:func:`transfer`).

A conformation that belongs to the shell relaxes to the same class, at an energy within the
discretization error of the target's own; one that belongs to the source mesh only (a state
the coarse mesh cannot resolve, or a metastable state of its path) relaxes to another class,
or lies above a state of the same class the target reached by itself. Both runs must be the
same shell: the same parameters and the same shape imperfection (amplitude, degree and seed).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

#: Vertices of the source mesh nearest to a material point whose triangles are searched.
NEAREST = 4
#: A barycentric coordinate below this (of the best triangle found) is no crossing.
INSIDE_TOL = 1e-9


def _vertex_faces(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR ``(indptr, face ids)`` of the faces at each vertex."""
    flat = faces.ravel()
    order = np.argsort(flat, kind="stable")
    counts = np.bincount(flat, minlength=n_vertices)
    return np.concatenate([[0], np.cumsum(counts)]), order // 3


def locate_directions(X_reference: np.ndarray, faces: np.ndarray,
                      directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each unit vector of ``directions (M, 3)``, the triangle of the mesh ``(X_reference,
    faces)`` that the ray from the reference sphere's centre in that direction crosses, and the
    barycentric coordinates of the crossing: ``(face (M,), weights (M, 3))``, weights summing
    to 1, each >= 0 up to round-off. ValueError if a ray crosses none of the triangles at its
    :data:`NEAREST` nearest vertices (a mesh that is no closed star-shaped surface there)."""
    from scipy.spatial import cKDTree

    from ..protocol.imperfection import reference_directions

    faces = np.asarray(faces, dtype=np.int64)
    U = reference_directions(X_reference)
    directions = np.asarray(directions, dtype=float)
    indptr, face_ids = _vertex_faces(faces, len(U))
    _, near = cKDTree(U).query(directions, k=min(NEAREST, len(U)))
    near = np.atleast_2d(near)
    candidates = [np.unique(np.concatenate([face_ids[indptr[v]:indptr[v + 1]] for v in row]))
                  for row in near]
    width = max(len(c) for c in candidates)
    cand = np.array([np.pad(c, (0, width - len(c)), mode="edge") for c in candidates])
    a, b, c = (U[faces[cand, i]] for i in range(3))  # (M, width, 3) each
    p = np.broadcast_to(directions[:, None, :], a.shape)
    # the ray t p meets the plane of a face at a - c, b - c coordinates (w0, w1): solve
    # w0 (a - c) + w1 (b - c) - t p = -c
    system = np.stack([a - c, b - c, -p], axis=-1)
    solved = np.linalg.solve(system, -c[..., None])[..., 0]
    w = np.stack([solved[..., 0], solved[..., 1], 1.0 - solved[..., 0] - solved[..., 1]], -1)
    w[solved[..., 2] <= 0] = -np.inf  # the plane behind the centre
    best = np.argmax(w.min(axis=-1), axis=1)
    rows = np.arange(len(directions))
    weights = w[rows, best]
    if not (weights.min(axis=1) >= -INSIDE_TOL).all():
        bad = int(np.argmin(weights.min(axis=1)))
        raise ValueError(f"the ray in direction {directions[bad].tolist()} crosses no triangle "
                         f"at its {near.shape[1]} nearest vertices")
    return cand[rows, best], weights


def material_interpolation(X_reference: np.ndarray, faces: np.ndarray, values: np.ndarray,
                           directions: np.ndarray) -> np.ndarray:
    """``values`` given at the vertices of the mesh ``(X_reference, faces)`` (``(V,)`` or
    ``(V, k)``, e.g. a conformation's positions), interpolated linearly at the material points
    ``directions (M, 3)`` (unit vectors from the reference sphere's centre) in the reference
    triangles that contain them (:func:`locate_directions`)."""
    face, weights = locate_directions(X_reference, faces, directions)
    values = np.asarray(values, dtype=float)
    corners = values[np.asarray(faces)[face]]  # (M, 3) or (M, 3, k)
    return np.einsum("mi,mi...->m...", weights, corners)


class Transferred(NamedTuple):
    """A conformation carried to another mesh and relaxed there: the relaxed positions ``X``,
    ``E_over_kappa``, the volume fraction ``dV_over_V`` held, the start's ``E_start_over_kappa``
    (the interpolated surface), and the minimization's ``result``
    (:class:`~shellbuckle.solve.result.MinimizeResult`)."""

    X: np.ndarray
    E_over_kappa: float
    dV_over_V: float
    E_start_over_kappa: float
    result: object


SAME_SHELL_PROTOCOL = ("shape_imperfection", "shape_degree")


def check_same_shell(source, target) -> None:
    """ValueError unless the two runs are the same shell: equal parameters (gamma, nu,
    convention and the rest) and the same shape imperfection (amplitude and degree, and the
    seed that draws it)."""
    from ..store.view import Run

    a, b = Run.of(source).store, Run.of(target).store
    if a.params != b.params:
        differ = sorted(k for k in set(a.params) | set(b.params)
                        if a.params.get(k) != b.params.get(k))
        raise ValueError(f"the runs are not the same shell: their parameters differ in "
                         f"{', '.join(differ)}")
    pa, pb = a.protocol, b.protocol
    names = list(SAME_SHELL_PROTOCOL) + (["seed"] if pa.get("shape_imperfection") else [])
    differ = [k for k in names if pa.get(k) != pb.get(k)]
    if differ:
        raise ValueError(f"the runs are not the same shell: their shape imperfections differ "
                         f"in {', '.join(differ)}")


def transfer(source, step: int, target, *, threads: int | None = 1) -> Transferred:
    """Step ``step`` of the run ``source`` (a :class:`~shellbuckle.store.view.Run` or its
    folder) carried to the mesh of the run ``target`` of the same shell
    (:func:`check_same_shell`) and minimized there at the source step's volume fraction with
    the target's energy (module docstring). ``threads``: PARDISO's, as for a run."""
    from ..locate import _context
    from ..protocol import deflate as protocol_mod
    from ..protocol.imperfection import reference_directions
    from ..store.view import Run

    source, target = Run.of(source), Run.of(target)
    check_same_shell(source, target)
    record = source.store.record(source.step(step))
    dv = float(record["dV_over_V"])
    if not math.isfinite(dv):
        raise ValueError(f"step {step} of {source.path} has no finite volume fraction")
    X = material_interpolation(source.store.X0, source.store.faces, source.positions(step),
                               reference_directions(target.store.X0))
    ctx = _context(target, threads)
    kappa = float(ctx.params.kappa)
    E_start = float(ctx.energy.value(X))
    result = protocol_mod._minimize(ctx, ctx.energy, X, ctx.V0 * (1.0 - dv))
    return Transferred(result.x, float(result.fun) / kappa, dv, E_start / kappa, result)
