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
energy (its convention, c0 and shape imperfection) by the protocol's minimization (the
target's method; with Newton's, the default, at fixed volume and certified: inertia 0; no
jiggle and no zero-curvature cycle) (:func:`transfer`).

A conformation that belongs to the shell relaxes to the same class, at an energy within the
discretization error of the target's own; one that belongs to the source mesh only (a state
the coarse mesh cannot resolve, or a metastable state of its path) relaxes to another class,
or lies above a state of the same class the target reached by itself (:func:`compare` puts
the carried minimum, classified, beside the target's own step at the same volume fraction;
``shellbuckle transfer`` prints it). Both runs must be the same shell: the same parameters and
the same shape imperfection (amplitude, degree and seed).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

#: Vertices of the source mesh nearest to a material point whose triangles are searched.
NEAREST = 4
#: A barycentric coordinate below this (of the best triangle found) is no crossing.
INSIDE_TOL = 1e-9


def locate_directions(X_reference: np.ndarray, faces: np.ndarray,
                      directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each unit vector of ``directions (M, 3)``, the triangle of the mesh ``(X_reference,
    faces)`` that the ray from the reference sphere's centre in that direction crosses, and the
    barycentric coordinates of the crossing: ``(face (M,), weights (M, 3))``, weights summing
    to 1, each >= 0 up to round-off. The triangles at the :data:`NEAREST` nearest vertices are
    searched first, then, for the rays none of them holds (skinny triangles), those at more
    vertices, and last every triangle. ValueError if a ray crosses no triangle at all (no
    closed surface star-shaped about the centre there)."""
    from scipy.spatial import cKDTree

    from ..mesh.topology import Topology
    from ..protocol.imperfection import reference_directions

    faces = np.asarray(faces, dtype=np.int64)
    U = reference_directions(X_reference)
    directions = np.asarray(directions, dtype=float)
    topology = Topology.from_faces(faces, len(U))
    indptr, face_ids = topology.vertex_faces_ptr, topology.vertex_faces
    tree = cKDTree(U)
    face = np.zeros(len(directions), dtype=np.int64)
    weights = np.full((len(directions), 3), -np.inf)
    todo = np.arange(len(directions))
    for k in (NEAREST, 4 * NEAREST, 16 * NEAREST):
        if not len(todo):
            break
        _, near = tree.query(directions[todo], k=min(k, len(U)))
        near = near.reshape(len(todo), -1)
        candidates = [np.unique(np.concatenate([face_ids[indptr[v]:indptr[v + 1]]
                                                for v in row])) for row in near]
        found = _crossings(U, faces, directions[todo], candidates)
        face[todo], weights[todo] = found
        todo = todo[~(weights[todo].min(axis=1) >= -INSIDE_TOL)]
    if len(todo):  # every triangle, for the rays left
        every = np.arange(len(faces))
        for chunk in np.array_split(todo, max(1, len(todo) * len(faces) // 200_000)):
            face[chunk], weights[chunk] = _crossings(U, faces, directions[chunk],
                                                     [every] * len(chunk))
        todo = todo[~(weights[todo].min(axis=1) >= -INSIDE_TOL)]
    if len(todo):
        raise ValueError(f"the ray in direction {directions[todo[0]].tolist()} crosses no "
                         "triangle of the mesh")
    return face, weights


def _crossings(U, faces, directions, candidates) -> tuple[np.ndarray, np.ndarray]:
    """Per direction, of its ``candidates`` (face ids), the face whose crossing by the ray has
    the largest smallest barycentric coordinate, and those coordinates (``-inf`` where no
    candidate's plane lies in front of the centre)."""
    width = max(len(c) for c in candidates)
    cand = np.array([np.pad(c, (0, width - len(c)), mode="edge") for c in candidates])
    a, b, c = (U[faces[cand, i]] for i in range(3))  # (M, width, 3) each
    p = np.broadcast_to(directions[:, None, :], a.shape)
    # the ray t p meets the plane of a face where w0 (a - c) + w1 (b - c) - t p = -c
    system = np.stack([a - c, b - c, -p], axis=-1)
    solved = np.linalg.solve(system, -c[..., None])[..., 0]
    w = np.stack([solved[..., 0], solved[..., 1], 1.0 - solved[..., 0] - solved[..., 1]], -1)
    w[~(solved[..., 2] > 0)] = -np.inf  # the plane behind the centre (or no crossing)
    smallest = np.nan_to_num(w.min(axis=-1), nan=-np.inf)
    best = np.argmax(smallest, axis=1)
    rows = np.arange(len(directions))
    return cand[rows, best], w[rows, best]


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


def check_same_shell(source, target) -> None:
    """ValueError unless the two runs are the same shell: equal parameters (gamma, nu,
    convention and the rest), the same spontaneous curvature, and the same shape imperfection
    (amplitude, and with one its degree and the seed that draws it); and unless both hold
    gamma and c0 fixed (a run along a gamma or c0 path changes them from step to step)."""
    from ..protocol.imperfection import DEFAULT_DEGREE
    from ..protocol.spec import PARAMETER_CONTROLS
    from ..store.view import Run

    a, b = Run.of(source).store, Run.of(target).store
    for store in (a, b):
        control = store.protocol.get("control", "volume")
        if control in PARAMETER_CONTROLS:
            raise ValueError(f"{store.path} is a path in {control}: only runs whose gamma and "
                             "c0 are those of every step can be carried")
    if a.params != b.params:
        differ = sorted(k for k in set(a.params) | set(b.params)
                        if a.params.get(k) != b.params.get(k))
        raise ValueError(f"the runs are not the same shell: their parameters differ in "
                         f"{', '.join(differ)}")
    pa, pb = a.protocol, b.protocol
    if pa.get("c0") != pb.get("c0"):
        raise ValueError("the runs are not the same shell: their spontaneous curvatures c0 "
                         "differ")

    def shape(p: dict) -> tuple:
        amplitude = p.get("shape_imperfection") or 0.0
        if not amplitude:
            return (0.0,)
        return amplitude, p.get("shape_degree") or DEFAULT_DEGREE, p.get("seed")

    if shape(pa) != shape(pb):
        raise ValueError(f"the runs are not the same shell: their shape imperfections differ "
                         f"(amplitude, degree, seed: {shape(pa)} and {shape(pb)})")


def transfer(source, step: int, target, *, threads: int | None = 1) -> Transferred:
    """Step ``step`` of the run ``source`` (a :class:`~shellbuckle.store.view.Run` or its
    folder) carried to the mesh of the run ``target`` of the same shell
    (:func:`check_same_shell`) and minimized there at the source step's volume fraction with
    the target's energy (module docstring). ``threads``: PARDISO's, as for a run."""
    from ..protocol.deflate import minimize_at_volume
    from ..protocol.imperfection import reference_directions
    from ..protocol.stored import stored_context
    from ..solve.linear import check_threads
    from ..store.view import Run

    if threads is not None:
        threads = check_threads(threads)
    source, target = Run.of(source), Run.of(target)
    check_same_shell(source, target)
    record = source.store.record(source.step(step))
    dv = float(record["dV_over_V"])
    if not math.isfinite(dv):
        raise ValueError(f"step {step} of {source.path} has no finite volume fraction")
    X = material_interpolation(source.store.X0, source.store.faces, source.positions(step),
                               reference_directions(target.store.X0))
    ctx = stored_context(target, threads)
    kappa = float(ctx.params.kappa)
    E_start = float(ctx.energy.value(X))
    result = minimize_at_volume(ctx, X, ctx.V0 * (1.0 - dv))
    return Transferred(result.x, float(result.fun) / kappa, dv, E_start / kappa, result)


#: Two steps hold the same volume fraction when their dV/V differ by less than this.
SAME_VOLUME = 1e-6


class Conformation(NamedTuple):
    """One conformation of a comparison: ``E_over_kappa``, its class ``shape`` and ``W``
    (:func:`~shellbuckle.analysis.classify.classify`), and where it comes from (``what``)."""

    what: str
    E_over_kappa: float
    shape: str
    W: int


class Comparison(NamedTuple):
    """A step carried to another mesh (:func:`compare`): the source's step ``source``, the
    carried start (``start_E_over_kappa``), the relaxed ``carried`` state and whether its
    minimization converged to a certified minimum (``certified``: converged with inertia 0,
    which Newton's method, the protocol's default, reports; never with ``cg`` or ``gd``),
    and the target run's own step at the same volume fraction (``own``, None if it has none);
    ``relative`` is ``carried.E / own.E - 1`` (NaN without ``own``); ``transferred`` holds the
    relaxed positions (:class:`Transferred`); ``source_path`` and ``target_path`` the runs."""

    source_path: str
    target_path: str
    dV_over_V: float
    source: Conformation
    start_E_over_kappa: float
    carried: Conformation
    certified: bool
    own: Conformation | None
    relative: float
    transferred: Transferred

    def as_dict(self) -> dict:
        """The numbers as plain values (JSON)."""
        def state(s):
            return None if s is None else s._asdict()

        return {"source_path": self.source_path, "target_path": self.target_path,
                "dV_over_V": self.dV_over_V, "source": state(self.source),
                "start_E_over_kappa": self.start_E_over_kappa, "carried": state(self.carried),
                "certified": self.certified, "own": state(self.own),
                "relative": self.relative,
                "message": self.transferred.result.message}


def own_step(target, dV_over_V: float) -> int | None:
    """The stored step of the run ``target`` at the volume fraction ``dV_over_V`` (within
    :data:`SAME_VOLUME`), or None."""
    from ..store.view import Run

    store = Run.of(target).store
    for k in store.steps:
        dv = float(store.record(k)["dV_over_V"])
        if abs(dv - dV_over_V) < SAME_VOLUME:
            return k
    return None


def compare(source, step: int, target, *, threads: int | None = 1) -> Comparison:
    """Step ``step`` of ``source`` carried to the mesh of ``target`` and relaxed there
    (:func:`transfer`), beside the source's step and the target's own step at the same volume
    fraction: their energies and classes. The carried minimum and the target's own are the
    same state where their energies agree to the minimization's tolerance and their classes
    agree; a carried state of another class, or of the same class and a higher energy, is a
    state of the source's mesh that the target's mesh does not hold (module docstring)."""
    from ..analysis.classify import classify
    from ..store.view import Run

    source, target = Run.of(source), Run.of(target)
    k = source.step(step)
    moved = transfer(source, k, target, threads=threads)

    def state(what, X, faces, E):
        c = classify(X, faces)
        return Conformation(what, float(E), c.shape, int(c.W))

    n, m = source.store.n_vertices, target.store.n_vertices
    src = state(f"source's step {k} ({n} vertices)", source.positions(k), source.store.faces,
                source.store.record(k)["E_over_kappa"])
    carried = state(f"carried, minimum ({m} vertices)", moved.X, target.store.faces,
                    moved.E_over_kappa)
    result = moved.result
    certified = bool(result.success) and result.inertia == 0
    j = own_step(target, moved.dV_over_V)
    own = None if j is None else state(f"target's own step {j} ({m} vertices)",
                                       target.positions(j), target.store.faces,
                                       target.store.record(j)["E_over_kappa"])
    relative = math.nan if own is None else carried.E_over_kappa / own.E_over_kappa - 1.0
    return Comparison(str(source.path), str(target.path), moved.dV_over_V, src,
                      moved.E_start_over_kappa, carried, certified, own, relative, moved)
