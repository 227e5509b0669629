"""The paper's numerical experiment: stepwise deflation with minimization at each step.

Protocol (Quilliet et al., EPJE 27, 13 (2008), §4.1), one volume step ``k``:

1. the target volume becomes ``V0 (1 - dV/V_k)`` (steps of ``dv = 0.0190 V0`` by default);
2. jiggle: seeded Gaussian vertex displacements (:mod:`shellbuckle.protocol.jiggle`), or a
   seeded smooth normal displacement defined on the reference sphere, the same field on any
   mesh (:mod:`shellbuckle.protocol.imperfection`);
3. minimize the elastic energy at fixed volume with ``c0 = 2/R`` (stress-free sphere); the
   energy reached is ``E_before_c0_cycle``;
4. zero-spontaneous-curvature cycle (on by default): ``c0 -> 0``, minimize, ``c0 -> 2/R``,
   minimize. Without it the paper finds multi-dimple "potato" shapes. The last minimization
   first tries the straight path back to the minimum before the cycle (``direct_return``,
   :func:`downhill_path`);
5. measure self-contact; stop at self-intersection of the surface (the paper stopped at 7-11 %
   of V0) or at the end of the schedule.

A step whose minimizations leave the physical domain (the surface turned inside out or grown
beyond 8 V0, a face flipped over, a non-finite energy, gradient or multiplier, an energy far
above that of the reference sphere scaled to the same volume: :func:`domain_exit`) raises
:class:`LeftDomain` instead of returning a record: the run fails there
(:func:`shellbuckle.run.deflate`).

A path in parameter space at fixed volume uses the same step with ``control = "gamma"`` or
``"c0"``: step ``k`` holds the enclosed volume at ``fixed_dV_over_V`` and sets the Foppl-von
Karman number (``A = gamma kappa / R^2``; kappa, R and the rest state unchanged) or the
spontaneous curvature to the ``k``-th value of the schedule before the jiggle, the
minimization and the c0 cycle (which returns to that step's c0). The paper's Fig. 11
conformation is reached this way, from a capsule at lower gamma.

The init/step pair follows JAX MD: ``ctx, state = init(mesh, params, protocol)`` then
``state, record = step(ctx, state)``. A state is the step index and the positions only; the
random stream of step ``k`` depends on ``(seed, k)`` alone, so a run resumed from its last
stored step computes exactly what an uninterrupted run computes.

Neither does a run depend on the machine's number of cores: ``init`` and ``step`` run NumPy's
and SciPy's BLAS on one thread (a threaded dot product sums in another order: the main job's
energies differed in the 15th digit with two OpenBLAS threads from step 1 on, and after
buckling such differences choose another trajectory), and PARDISO, which may use several
threads (``init(..., threads=)``), gives the same bits on any number of them in its
reproducible mode (``init(..., reproducible=True)``, the default on several threads); its
plain mode, the default on one thread, is faster and gives other bits
(:mod:`shellbuckle.solve.linear`), so a run stores its mode and a resumed run uses it
(:func:`shellbuckle.run.deflate`).
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import time
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import ThreadpoolController

from ..energies.hinge import dihedral_angles
from ..energies.total import ShellEnergy
from ..energies.volume import Volume
from ..mesh.contact import ContactChecker
from ..mesh.mesh import Mesh
from ..solve import minimize
from ..solve.gauge import pinned_dofs
from ..solve.linear import check_mode, check_threads, default_threads
from ..solve.linesearch import RestoredPath
from ..solve.newton import ABANDONED
from ..solve.pressure import minimize_at_pressure
from ..solve.workspace import Workspace
from .imperfection import reference_directions, smooth_jiggle
from .jiggle import jiggle, mean_edge_length, step_rng
from .spec import PARAMETER_CONTROLS, Protocol

log = logging.getLogger(__name__)


def _blas_controller() -> ThreadpoolController:
    """The BLAS libraries loaded now (0.4 ms; not kept: a library loaded later, e.g. by a
    SciPy module imported after the first step, would run on all cores)."""
    return ThreadpoolController()


def one_blas_thread(function):
    """Run ``function`` with NumPy's and SciPy's BLAS on one thread (restored afterwards), so
    that its floating-point results do not depend on the number of cores."""
    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with _blas_controller().limit(limits=1, user_api="blas"):
            return function(*args, **kwargs)
    return wrapper


JIGGLE_RETRIES = 3
"""A Newton minimization that does not converge after the jiggle and stays far above the
energy of an admissible state (the shrunk reference sphere, or the step's start shrunk to the
target volume; a large jiggle can fold a triangle over one of its edges, which
keeps the triangle's metric and so costs no stretching energy, and the minimizer may stay
tangled; see ``_tangled``), or that is abandoned because two faces lie folded onto each
other (``folded_flat``), is started again from the step's start with a jiggle of half the
amplitude drawn from ``default_rng([seed, step, attempt])``, at most this many times; so is a
step whose surface intersects itself only in a fold (``only_local``), or that intersects itself
without having converged (not a minimum, so its contact does not end the run). The table
records the std used (``jiggle_sigma``) and the attempts (``jiggle_attempts``)."""

@dataclass(frozen=True)
class State:
    """Where a run is: the last finished step and its positions; ``stopped`` says why it ended;
    ``certify_single``: whether the next step's minimizations try to show their minimum
    positive definite with a single-precision factorization first (Newton's
    ``certify_single``; :mod:`shellbuckle.solve.newton`, "Single-precision certificates"). True
    at the start of a run, then whether the last step's minimum was certified so (its record's
    ``certificate``, :func:`state_after`): where a certificate needed double precision (soft
    modes after buckling, or a stiff shell on a fine mesh), the next one will too, and a
    single-precision try would only cost a factorization more."""

    step: int
    X: np.ndarray
    stopped: str | None = None
    certify_single: bool = True


FOLD_RINGS = 5
"""Intersecting faces whose vertices are at most this many edges apart on the mesh are a fold
(:func:`only_local`), on the paper's mesh and coarser ones (:func:`fold_rings`)."""

FOLD_LENGTH = 0.32
"""The size of a fold, in units of the radius: ``FOLD_RINGS`` mean edges of the paper's
3594-vertex mesh (0.0636 R), the number of rings a finer mesh counts over it
(:func:`fold_rings`)."""


@dataclass(frozen=True, eq=False)
class Context:
    """Everything fixed during a run: mesh, parameters, protocol, energy, constraint, contact."""

    mesh: Mesh
    params: object
    protocol: Protocol
    energy: ShellEnergy
    volume: Volume
    V0: float
    contact: ContactChecker
    workspace: Workspace
    """The linear solver, KKT assemblers and held factorizations of the run's minimizations
    (:class:`~shellbuckle.solve.workspace.Workspace`); its ``kept`` token is the factorization
    the last step's final minimization ended with, which a smooth start of the next step uses
    if the solver still holds it and it was made at exactly that step's start. A cache, never
    stored: without it Newton's method factors the same matrix, with the same bits."""
    c0: float = field(default=2.0)
    pinned: np.ndarray | None = None
    """The six dofs that fix the rigid-motion gauge of every minimization of the run (chosen on
    the reference mesh, :func:`~shellbuckle.solve.gauge.pinned_dofs`)."""
    fold_rings: int = FOLD_RINGS
    """Intersecting faces at most this many edges apart on the mesh are a fold, not a contact
    (:func:`fold_rings`, :func:`only_local`)."""
    X_rest: np.ndarray | None = None
    """The stress-free shape (:meth:`Protocol.stress_free`): the run's first state, the
    stretching rest state and the volume ``V0``; ``mesh.X`` (the reference sphere, whose
    vertices' directions are their material points) when None."""

    @property
    def rest(self) -> np.ndarray:
        """The stress-free shape's positions (:attr:`X_rest`, else ``mesh.X``)."""
        return self.mesh.X if self.X_rest is None else self.X_rest


def state_after(step: int, X: np.ndarray, record: dict, stopped: str | None = None) -> State:
    """The state after the step ``step`` whose positions are ``X`` and record ``record``, with
    the choice of certificate for the next step (:attr:`State.certify_single`). :func:`step`
    makes its state with it and a resumed run from the stored record, so that both make the
    same choice and the resumed run factors the same matrices in the same precision."""
    return State(step=step, X=X, stopped=stopped,
                 certify_single=record.get("certificate", "single") == "single")


@one_blas_thread
def init(mesh: Mesh, params, protocol: Protocol, form_factors=None, threads: int | None = None,
         reproducible: bool | None = None):
    """Build the run context and the step-0 state: the stress-free shape, which is the initial
    mesh ``mesh.X`` or, with the protocol's shape imperfection, that mesh's vertices moved to
    the imperfect surface (:meth:`Protocol.stress_free`).

    The stretching rest state is the stress-free shape, or ``form_factors`` (Surface Evolver's
    per-face rest metrics) when given; ``V0`` is its volume. ``threads``:
    the sparse factorization's threads (default
    :func:`~shellbuckle.solve.linear.default_threads`), ``reproducible`` PARDISO's mode
    (default: reproducible on several threads, plain on one); the results depend on the mode,
    not on the threads.
    """
    if threads is not None:
        threads = check_threads(threads)
    check_mode(reproducible, default_threads() if threads is None else threads)
    c0 = 2.0 / params.R if protocol.c0 is None else float(protocol.c0)
    if form_factors is not None and protocol.shape_imperfection:
        raise ValueError("a shape imperfection sets the rest state itself: give it or "
                         "form_factors (Surface Evolver's rest metrics), not both")
    X_rest, profile = protocol.stress_free(mesh.X)
    if profile is not None and not profile.min() > 0:
        raise ValueError(f"the shape imperfection inverts the curvature at a vertex (lowest "
                         f"{profile.min():.3g} times the sphere's): not an imperfect sphere")
    energy = ShellEnergy.build(mesh, params, bending=protocol.bending, c0=c0, reference=X_rest,
                               form_factors=form_factors, c0_profile=profile)
    volume = Volume(mesh.faces, mesh.n_vertices)
    V0 = volume.value(X_rest)
    if not V0 > 0:
        raise ValueError(f"the reference mesh encloses a non-positive volume {V0!r}: faces must "
                         "be oriented outward")
    ctx = Context(mesh=mesh, params=params, protocol=protocol, energy=energy, volume=volume,
                  V0=V0, contact=ContactChecker(mesh.topology),
                  workspace=Workspace(threads=threads, reproducible=reproducible),
                  c0=c0,
                  pinned=pinned_dofs(X_rest),
                  fold_rings=fold_rings(X_rest, mesh.topology.edges, V0),
                  X_rest=None if profile is None else X_rest)
    return ctx, State(step=0, X=np.array(X_rest, float))


def measure(ctx: Context, X: np.ndarray, target: float, result=None, *, E_before=None,
            iterations=0, wall_s=0.0, contact=None) -> dict:
    """The per-step record (SPEC §7 columns) of the conformation ``X``; ``contact``, if
    given, is ``ctx.contact.check(X)`` already computed."""
    parts = ctx.energy.parts(X)
    E = parts["E_stretch"] + parts["E_bend"]
    contact = contact if contact is not None else ctx.contact.check(X)
    dV = 1.0 - ctx.volume.value(X) / ctx.V0
    return {
        "target_dV_over_V": float(target), "dV_over_V": float(dV),
        "E_total": float(E), "E_bend": float(parts["E_bend"]),
        "E_stretch": float(parts["E_stretch"]), "E_over_kappa": float(E / ctx.params.kappa),
        "E_before_c0_cycle": float(E if E_before is None else E_before),
        "pressure": float(result.pressure) if result is not None else 0.0,
        "grad_norm": float(result.grad_norm) if result is not None else 0.0,
        "iterations": int(iterations),
        "inertia": None if result is None or result.inertia is None else int(result.inertia),
        "min_distance": float(contact.min_distance), "wall_s": float(wall_s),
        "self_intersecting": bool(contact.intersects),
        "converged": bool(result.success) if result is not None else True,
        "c0": float(ctx.c0),
    }


def at_parameter(ctx: Context, value: float) -> Context:
    """The context of one step of a parameter path: gamma (``A = gamma kappa / R^2`` in the
    stretching term, the rest state unchanged) or c0 set to ``value``."""
    if ctx.protocol.control == "gamma":
        old = ctx.params
        params = old.with_gamma(float(value))
        stretching = dataclasses.replace(ctx.energy.stretching, A=params.A)
        energy = ShellEnergy(stretching, ctx.energy.bending)
        return dataclasses.replace(ctx, params=params, energy=energy)
    return dataclasses.replace(ctx, energy=ctx.energy.with_c0(float(value)), c0=float(value))


FLAT_FOLD_TOL = 1e-3
"""A hinge whose dihedral angle is within this many radians of 180 degrees is folded flat
(:func:`folded_flat`)."""


def folded_flat(X: np.ndarray, hinges: np.ndarray, tol: float = FLAT_FOLD_TOL) -> str | None:
    """Why ``X`` is tangled, or None: two faces sharing an edge lie on each other (the
    dihedral angle between their outward normals is within ``tol`` of 180 degrees).

    A large jiggle can flip a vertex across the opposite edge; the minimizer then drives the
    angle of that hinge to exactly 180 degrees, the cut of the signed angle where the bending
    energy jumps, and stays there with a large gradient (gamma = 271, dV/V = 0.55: 140
    iterations and 40 factorizations before the stall test stops it). Converged shells stay far
    from it (up to 45 degrees in the capsule regime, 145 degrees on the sharpest ridges of the
    wrinkled regime on the paper's mesh)."""
    theta = np.abs(dihedral_angles(X, hinges))
    i = int(np.argmax(theta))
    if np.pi - theta[i] > tol:
        return None
    return (f"the two faces at edge {int(hinges[i, 0])}-{int(hinges[i, 1])} are folded onto "
            f"each other (dihedral angle {np.degrees(theta[i]):.3f} degrees), where the energy "
            f"is not differentiable")


#: The absolute part of the gradient test in the units of a shell of bending modulus 1 and
#: radius 1 (:attr:`~shellbuckle.solve.options.NewtonOptions.atol_grad`).
ATOL_GRAD = 1e-10


def gradient_atol(params) -> float:
    """The absolute part of the protocol's gradient test, ``ATOL_GRAD kappa / R``: a force
    in the shell's own units (energy over length), so that a shell given in SI units (kappa
    of order 1e-19 J, R of 1e-8 m) stops where the same shell in reduced units does. A fixed
    1e-10 would exceed its forces and end its minimizations after a few steps."""
    return ATOL_GRAD * float(params.kappa) / float(params.R)


def _minimize(ctx: Context, energy, X, V_target, pressure=None, relaxed=None, warm=None,
              certify: bool = True, relaxed_token=None, certify_single: bool = True,
              jiggle: float | None = None):
    """One minimization of the protocol; ``relaxed`` is the relaxed state the start ``X`` came
    from (before the jiggle, or at the previous c0), which preconditions the first
    iterations of Newton's method when the protocol's ``prerelax`` is on; ``warm``, results of
    earlier minimizations (the c0 cycle: the previous one ended at ``X``), the first of whose
    factorizations the linear solver still holds Newton's method then reuses for its first
    steps instead (same ``prerelax`` switch; :mod:`shellbuckle.solve.newton`, "Warm start");
    ``certify=False``: Newton's method stops without factoring to certify the minimum (the
    c0 = 0 stage of the cycle, whose minimum is neither reported nor kept); ``relaxed_token``,
    the factorization the minimization that ended at ``relaxed`` ended with (Newton's
    ``precondition_token``, for a start without a jiggle); ``certify_single``, Newton's option
    (:attr:`State.certify_single`); ``jiggle``: ``X`` is ``relaxed`` plus the step's
    imperfection, of this size (:meth:`Protocol.jiggle_sigma`; ``None``: ``X`` is no jiggled
    start). With the protocol's ``relax_imperfection`` a start with an imperfection of nonzero
    size is always relaxed (Newton's ``smooth_start=False``), however small it is against the
    mesh, so that every mesh takes the same path from it (the shifted relaxation of
    :mod:`shellbuckle.solve.relax`) and the outcome of a step near an instability (sphere or
    dent) does not switch with the imperfection's size in mesh units
    (:mod:`shellbuckle.solve.newton`, "Smooth starts")."""
    p = ctx.protocol
    atol = gradient_atol(ctx.params)
    if pressure is not None:
        return minimize_at_pressure(energy, ctx.volume, X, pressure, tol_grad=p.tol,
                                    atol_grad=atol, max_iter=p.max_iter,
                                    solver=ctx.workspace.solver)
    options = {"atol_grad": atol}
    if p.method == "alternate":
        options["cg_options"] = {"atol_grad": atol}
    if p.method in ("newton", "alternate"):
        # one rigid gauge for the whole run (from the reference mesh): the KKT pattern, and so
        # the linear solver's symbolic analysis, stay the same from minimization to minimization
        hinges = ctx.mesh.topology.hinges
        options |= {"workspace": ctx.workspace, "pinned": ctx.pinned, "certify": certify,
                   "certify_single": certify_single,
                   "abandon": lambda X: folded_flat(X, hinges),
                   "abandon_thorough": lambda X: (folded_flat(X, hinges)
                                               or folded_locally(ctx.contact, X,
                                                                 rings=ctx.fold_rings))}
        if p.prerelax and relaxed is not None:
            options["precondition_at"] = relaxed
            options["precondition_token"] = relaxed_token
            if jiggle is not None and p.smooth_jiggle is not None:
                # a smooth imperfection has no mesh-scale roughness for the relaxation's
                # rough stage to damp (:mod:`shellbuckle.solve.relax`): skipped
                options["relax_rough_shift"] = 0.0
            if jiggle is not None and jiggle > 0 and p.relax_imperfection:
                options["smooth_start"] = False
        tokens = [w.factorization for w in warm or () if w.factorization is not None]
        if p.prerelax and tokens:
            options["warm_start"] = tokens
    return minimize(energy, ctx.volume, X, V_target, method=p.method, tol=p.tol,
                    max_iter=p.max_iter, **options)


@one_blas_thread
def minimize_at_volume(ctx: Context, X: np.ndarray, V_target: float):
    """``X`` minimized at the volume ``V_target`` with the run's energy by the protocol's
    minimizer (its method and tolerance; Newton's method certifies the minimum), without the
    step's jiggle and zero-curvature cycle: a conformation that did not come from the run's
    own path, e.g. one carried from another mesh (:mod:`shellbuckle.studies.transfer`); BLAS
    on one thread, as a step. Returns the minimizer's
    :class:`~shellbuckle.solve.result.MinimizeResult`."""
    return _minimize(ctx, ctx.energy, np.asarray(X, dtype=float), V_target)


MAX_VOLUME_RATIO = 8.0
"""The largest enclosed volume of the physical domain, in units of the reference volume V0:
the reference sphere of twice the radius (a linear strain of 100 %, far outside thin-shell
elasticity; :func:`domain_exit`)."""

ENERGY_BOUND_FACTOR = 10.0
"""A step whose energy exceeds this many times the energy of the reference sphere uniformly
scaled to the step's enclosed volume (plus the bending energy 8 pi kappa of a sphere) has left
the physical domain (:func:`domain_exit`)."""


class LeftDomain(RuntimeError):
    """A step left the physical domain (:func:`domain_exit`): the run fails there and the
    step is not stored. ``step`` is the step, ``reason`` what left the domain."""

    def __init__(self, step: int, reason: str):
        super().__init__(f"step {step} left the physical domain: {reason}")
        self.step = step
        self.reason = reason


def inverted_faces(X: np.ndarray, topology) -> np.ndarray:
    """The faces whose normal points against the normals of all their edge neighbours (the
    angle between the outward normals above 90 degrees at each of the three edges): a
    triangle flipped over, whose orientation no longer follows the surface's (the reference
    sphere's outward one). Converged shells stay far from it: the sharpest ridges of the
    wrinkled regime bend one edge of a face by up to 145 degrees, never all three."""
    corners = X[topology.faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    faces = topology.edge_faces
    cosine = np.einsum("ij,ij->i", normals[faces[:, 0]], normals[faces[:, 1]])
    return np.flatnonzero((cosine[topology.face_edges] < 0).all(axis=1))


def domain_exit(ctx: Context, X: np.ndarray, E: float | None = None, *, grad_norm=None,
                pressure=None, thorough: bool = True, faces: bool = True) -> str | None:
    """Why the conformation ``X`` is outside the physical domain of a run, or None.

    Outside: non-finite positions, energy ``E`` (default: computed), ``grad_norm`` or
    ``pressure`` (the multiplier); an enclosed volume ``V`` outside ``(0, MAX_VOLUME_RATIO
    V0]`` (``V <= 0``: the surface turned inside out); with ``thorough``, also a face flipped
    against its neighbours (:func:`inverted_faces`; unless ``faces`` is False) or an energy
    above ``ENERGY_BOUND_FACTOR (E_s + 8 pi kappa)``, where ``E_s`` is the energy of the
    reference sphere uniformly scaled to the volume ``V``: an admissible state at that volume,
    so the minimum there lies below it (the unbuckled shell is at it, a buckled one far below).
    Energies in the run's units. In the stored runs of our studies (6276 steps, 224 runs) the
    largest energy was 0.57 (E_s + 8 pi kappa), and the only flipped faces were two in the last
    step of a run that ended at self-intersection (gamma = 7465, dV/V = 0.836; the protocol
    does not ask about faces there, see :func:`step`)."""
    if not np.isfinite(X).all():
        return "non-finite vertex positions"
    V = ctx.volume.value(X)
    if not np.isfinite(V):
        return f"non-finite enclosed volume {V!r}"
    if V <= 0:
        return (f"the enclosed volume changed sign (V = {V:.6g}, V0 = {ctx.V0:.6g}): the "
                f"surface turned inside out")
    if V > MAX_VOLUME_RATIO * ctx.V0:
        return (f"the enclosed volume V = {V:.6g} exceeds {MAX_VOLUME_RATIO:g} V0 = "
                f"{MAX_VOLUME_RATIO * ctx.V0:.6g} (dV/V = {1.0 - V / ctx.V0:.6g})")
    E = ctx.energy.value(X) if E is None else float(E)
    for name, value in (("energy", E), ("gradient norm", grad_norm),
                        ("pressure (volume multiplier)", pressure)):
        if value is not None and not np.isfinite(value):
            return f"non-finite {name} {value!r}"
    if not thorough:
        return None
    flipped = inverted_faces(X, ctx.mesh.topology) if faces else ()
    if len(flipped):
        return (f"{len(flipped)} inverted face(s), e.g. face {int(flipped[0])}, whose normal "
                f"points against those of its three neighbours (a triangle flipped over)")
    scaled = ctx.energy.value(ctx.rest * (V / ctx.V0) ** (1.0 / 3.0))
    bound = ENERGY_BOUND_FACTOR * (abs(scaled) + 8.0 * np.pi * ctx.params.kappa)
    if not E <= bound:
        return (f"energy E = {E:.6g} above the bound {bound:.6g} ({ENERGY_BOUND_FACTOR:g} "
                f"times the energy {scaled:.6g} of the reference sphere scaled to the same "
                f"volume, plus 8 pi kappa)")
    return None


def _check_domain(ctx: Context, k: int, result, *, thorough: bool = False,
                  faces: bool = True) -> None:
    """Raise :class:`LeftDomain` if the end ``result`` of a minimization of step ``k`` is
    outside the physical domain (:func:`domain_exit`)."""
    why = domain_exit(ctx, result.x, result.fun, grad_norm=result.grad_norm,
                      pressure=result.pressure, thorough=thorough, faces=faces)
    if why is not None:
        raise LeftDomain(k, why)


DIRECT_RETURN_SAMPLES = 10
"""Points of the straight path at which :func:`downhill_path` asks the energy to fall."""


def downhill_path(energy, volume, X0: np.ndarray, X1: np.ndarray, V_target: float,
                  samples: int = DIRECT_RETURN_SAMPLES) -> bool:
    """Whether the energy falls from each point to the next of ``samples`` evenly spaced
    points of the straight path from ``X0`` to ``X1`` (``X0`` excluded, ``X1`` included), each
    brought to the volume ``V_target`` along the volume gradient as in the line searches.

    The protocol asks it of the flat minimum ``X0`` of the zero-curvature cycle and the minimum
    ``X1`` before the cycle, under the energy at the step's c0: if it holds, ``X1`` is reached
    from ``X0`` by descent along that line, and the minimization back at the step's c0 starts
    (and, ``X1`` being a certified minimum of that energy, ends) there. In the paper's
    protocol on the paper's mesh the full minimization from ``X0`` ended at ``X1`` in every
    step tried (29 steps at gamma = 271, 2333 and 20995: energies equal to 2e-12 relative,
    positions to 5e-3 mean edge lengths; docs/protocol.md) after 5-60 iterations and up to
    six factorizations. Where the energy rises somewhere along the line (``X0`` may lie in
    the basin of another minimum), the minimization starts at ``X0``, as without this test.
    Costs ``samples`` energy evaluations."""
    if not (isinstance(samples, (int, np.integer)) and samples >= 1):
        raise ValueError(f"samples must be an integer >= 1, got {samples!r}")
    path = RestoredPath(energy, volume, np.asarray(X0, dtype=float),
                        np.asarray(X1, dtype=float) - X0, V_target)
    E_previous = energy.value(X0)
    for k in range(1, samples + 1):
        E, X = path(k / samples)
        if X is None or not E < E_previous:
            return False
        E_previous = E
    return True


def _tangled(ctx: Context, E: float, V_target, X_start: np.ndarray) -> bool:
    """Whether an unconverged minimization is stuck far above any sensible state: above the
    energy of an admissible state at the same volume, the lower of the uniformly shrunk
    reference sphere and the step's start ``X_start`` (the previous conformation) uniformly
    shrunk to the target volume, by more than 5 % of it plus kappa. A minimization that merely
    crawls along a soft mode ends below these and is not retried. Under pressure control (no
    volume target) every failure counts as tangled."""
    if V_target is None:
        return True
    admissible = min(ctx.energy.value(X * (V_target / ctx.volume.value(X)) ** (1.0 / 3.0))
                     for X in (ctx.rest, X_start))
    return E > admissible + 0.05 * abs(admissible) + ctx.params.kappa


def _start_again(ctx: Context, result, V_target, X_start: np.ndarray) -> bool:
    """Whether a minimization's end calls for a new jiggle: it gave up on a fold
    (``ABANDONED``), or did not converge and is :func:`_tangled` or :func:`folded_locally`."""
    return not result.success and (result.message.startswith(ABANDONED)
                                   or _tangled(ctx, result.fun, V_target, X_start)
                                   or folded_locally(ctx.contact, result.x,
                                                     rings=ctx.fold_rings) is not None)


def fold_rings(X: np.ndarray, edges: np.ndarray, V0: float) -> int:
    """The rings of the fold test on the reference mesh ``X`` (enclosing ``V0``): the mean
    edges in ``FOLD_LENGTH`` radii, and never fewer than ``FOLD_RINGS``. A crease that folds
    through itself spans a length of the shell, not a number of edges (on 40000 vertices a
    ridge's fold at γ = 29160 reached 6 rings, 0.11 R, where the paper's mesh has two); the
    contact of distant parts of the shell that ends a run is tens of paper-mesh edges apart
    on every mesh."""
    radius = (3.0 * V0 / (4.0 * np.pi)) ** (1.0 / 3.0)
    return max(FOLD_RINGS, round(FOLD_LENGTH * radius / mean_edge_length(X, edges)))


def only_local(checker: ContactChecker, contact, *, rings: int) -> bool:
    """Whether the surface intersects itself (``contact``, a result of ``checker.check``) only
    where nearby faces meet (a vertex of each within ``rings`` edges): a fold left by the jiggle
    (a triangle folded over an edge keeps its metric, so at large gamma the fold can be a local
    minimum; on the thin shells of the wrinkled regime a crumple spans up to three rings), not
    the contact of distant parts of the shell that ends a run (opposite walls of a dent are
    tens of edges apart on the mesh). Such a step is jiggled again with half the amplitude,
    like a tangled one."""
    return bool(contact.intersects) and _all_near(checker, contact.pairs, rings)


def _all_near(checker: ContactChecker, pairs, rings: int) -> bool:
    pairs = np.asarray(pairs).reshape(-1, 2)
    return len(pairs) > 0 and bool(
        (checker.face_distance(pairs[:, 0], pairs[:, 1], rings) <= rings).all())


def folded_locally(checker: ContactChecker, X: np.ndarray, *, rings: int) -> str | None:
    """Why ``X`` is tangled, or None: its surface passes through itself, and only where
    nearby faces meet (:func:`only_local`), as where the jiggle pushed a vertex through a face
    a few rings away. The minimizer's steps stall there without any hinge folded flat
    (gamma = 2333, dV/V = 0.70: 133 iterations and 37 factorizations, then the c0 cycle with
    25 more, before the contact check at the end of the step saw the fold). Costs a
    self-intersection search (~7 ms on a smooth shell of the paper's mesh), so Newton's
    method asks it only after its relaxation and where its steps are stuck
    (``abandon_thorough``), and the protocol of a minimization that stopped unconverged. In
    replays of every second step of whole runs (gamma = 271, 2333, 20995; 99 relaxations) it
    held after the relaxation in the three attempts that ended on a fold, and in no other."""
    pairs, n = checker.intersecting_pairs(X)
    if not n or not _all_near(checker, pairs, rings):
        return None
    f, g = (int(i) for i in pairs[0])
    return (f"faces {f} and {g} intersect, {n} pair(s) in all, each within {rings} edges of "
            f"each other on the mesh (a fold)")


def scaled_to_volume(volume, X: np.ndarray, V_target: float) -> np.ndarray:
    """``X`` scaled uniformly about its vertex centroid to the enclosed volume ``V_target``
    (a volume scales as the cube of the factor): the start of a volume step with the
    protocol's ``rescale_start``. The minimizer's own way to a new volume, along the volume
    gradient (:meth:`~shellbuckle.energies.volume.Volume.restore`), moves each vertex in
    proportion to its area: on a randomized mesh that move is as uneven as the vertex areas,
    a strain of order ``dV/V R/h`` that grows as the mesh is refined (mean edge ``h``) and
    that the minimization then has to remove. A uniform scaling strains the shell uniformly,
    as the spherical shell's own response before buckling does."""
    c = X.mean(axis=0)
    f = (float(V_target) / volume.value(X)) ** (1.0 / 3.0)
    return c + f * (X - c)


def _jiggled(ctx: Context, X: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """``X`` jiggled by the protocol's jiggle of size ``sigma`` (:meth:`Protocol.jiggle_sigma`)
    with the random stream ``rng``: Surface Evolver's per-vertex jiggle, or the smooth
    imperfection evaluated at the material points of the reference mesh."""
    p = ctx.protocol
    if p.smooth_jiggle is None:
        return jiggle(X, sigma, rng)
    return smooth_jiggle(X, ctx.mesh.faces, reference_directions(ctx.mesh.X), sigma,
                         p.smooth_degree, rng)


@one_blas_thread
def step(ctx: Context, state: State):
    """One step (a volume, pressure, gamma or c0 increment): jiggle, minimize, c0 cycle,
    measure. Returns ``(state, record)``; a parameter path's record also has ``gamma``.
    Raises :class:`LeftDomain` when a minimization ends outside the physical domain (its
    volume, finiteness and multiplier after each one; the energy bound and flipped faces at
    the step's end too, faces unless the step ends the run at self-contact:
    :func:`domain_exit`)."""
    p = ctx.protocol
    k = state.step + 1
    if k > len(p.schedule):
        raise ValueError(f"the schedule has {len(p.schedule)} steps; step {k} does not exist")
    t0 = time.perf_counter()
    if p.control == "pressure":
        target, V_target, pressure = float("nan"), None, p.schedule[k - 1]
    elif p.control in PARAMETER_CONTROLS:
        ctx = at_parameter(ctx, p.schedule[k - 1])
        target, pressure = p.fixed_dV_over_V, None
        V_target = ctx.V0 * (1.0 - target)
    else:
        target, pressure = p.schedule[k - 1], None
        V_target = ctx.V0 * (1.0 - target)
    sigma = p.jiggle_sigma(ctx.mesh.X, state.X, ctx.mesh.topology.edges)
    iterations = 0
    retries = JIGGLE_RETRIES if p.method in ("newton", "alternate") and sigma > 0 else 0
    start, token = state.X, ctx.workspace.kept
    if p.rescale_start and p.control == "volume":
        start, token = scaled_to_volume(ctx.volume, state.X, V_target), None
    for attempt in range(retries + 1):
        contact = None
        rng = step_rng(p.seed, k) if attempt == 0 else np.random.default_rng([p.seed, k, attempt])
        X = _jiggled(ctx, start, sigma, rng)
        result = _minimize(ctx, ctx.energy, X, V_target, pressure, relaxed=start,
                           relaxed_token=token,
                           certify_single=state.certify_single, jiggle=sigma)
        _check_domain(ctx, k, result)
        iterations += result.nit
        E_before = result.fun
        # a minimization that gave up on a fold or a tangle is jiggled again at once; one that
        # stopped without converging otherwise (it stalled on soft modes) goes through the
        # cycle, which often converges it
        again = attempt < retries and _start_again(ctx, result, V_target, state.X)
        if p.c0_cycle and not again:
            # the flat minimum is a waypoint (neither reported nor kept): not certified
            flat = _minimize(ctx, ctx.energy.with_c0(0.0), result.x, V_target, pressure,
                             relaxed=result.x, warm=(result,), certify=False,
                             certify_single=state.certify_single)
            _check_domain(ctx, k, flat)
            # back at c0 = 2/R: from the minimum before the cycle if the way there is downhill
            # (it is where the shell returns; its factorization, which the linear solver
            # keeps, certifies it at once), else from the flat minimum, starting with that
            # factorization (the Hessian where the shell most often returns; else a
            # double-precision one of the flat stage, if any)
            start = flat.x
            if (p.direct_return and V_target is not None and result.success
                    and downhill_path(ctx.energy, ctx.volume, flat.x, result.x, V_target)):
                start = result.x
            result = _minimize(ctx, ctx.energy, start, V_target, pressure, relaxed=flat.x,
                               warm=(result, flat), certify_single=state.certify_single)
            _check_domain(ctx, k, result)
            iterations += flat.nit + result.nit
            again = attempt < retries and _start_again(ctx, result, V_target, state.X)
        if attempt == retries:
            break
        if again:
            why = f"no convergence ({result.message}; E = {result.fun:.6g})"
        else:
            contact = ctx.contact.check(result.x)
            if not contact.intersects:
                break
            if only_local(ctx.contact, contact, rings=ctx.fold_rings):
                why = "a fold of the mesh (only neighbouring faces intersect)"
            elif not result.success:  # not a minimum: its contact cannot end the run
                why = (f"no convergence ({result.message}; E = {result.fun:.6g}) and a "
                       f"self-intersection")
            else:
                break
        log.warning("step %d: %s after a jiggle of std %.3g; jiggling again with half of it",
                    k, why, sigma)
        sigma *= 0.5
    ctx.workspace.kept = result.factorization
    if not result.success:
        log.warning("step %d: minimizer did not converge: %s", k, result.message)
    record = measure(ctx, result.x, target, result, E_before=E_before, iterations=iterations,
                     wall_s=time.perf_counter() - t0, contact=contact)
    # a step that ends the run at self-contact keeps the protocol's end even with faces flipped
    # over in the contact (a flipped triangle passes through its neighbours)
    _check_domain(ctx, k, result, thorough=True,
                  faces=not (p.stop_at_contact and record["self_intersecting"]))
    record["step"] = k
    record["jiggle_sigma"] = float(sigma)
    record["jiggle_attempts"] = attempt + 1
    record["certificate"] = result.certificate or "none"  # (methods other than Newton: none)
    if p.control in PARAMETER_CONTROLS:
        record["gamma"] = float(ctx.params.gamma)
    if pressure is not None:
        record["target_pressure"] = float(pressure)
    return state_after(k, result.x, record, stop_message(p, k, record)), record


def stop_message(protocol: Protocol, k: int, record: dict) -> str | None:
    """Why a run ends at its step ``k`` (its record ``record``), or None: the run's message
    at the end, also when a resumed run finds it had ended."""
    at = f"(dV/V = {record['dV_over_V']:.4f})"
    if protocol.stop_at_contact and record.get("self_intersecting"):
        return f"self-intersection at step {k} {at}"
    if k >= len(protocol.schedule):
        return f"end of the schedule {at}"
    return None
