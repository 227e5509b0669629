"""Durable runs: the deflation protocol driven step by step into a run store.

``deflate`` creates (or reopens, to resume) a run folder and writes every finished step to it
atomically before the next begins, so Ctrl-C or ``kill -9`` loses at most the step in progress;
``resume`` continues a stored run from its last finished step and, because the random stream of
a step depends only on the seed and the step index, ends with exactly the table of an
uninterrupted run. ``continue_from`` starts a new run from any stored step with another volume
schedule (re-inflation, arbitrary paths) while keeping the original stress-free reference;
``continue_in_parameter`` follows a path in gamma or in c0 at the fixed volume of a stored step
(the paper's Fig. 11 conformation, reached from a capsule at lower gamma), and
``compare_paths`` puts two conformations reached by different paths side by side.
:class:`Run`, a stored run read back (:mod:`shellbuckle.store.view`), is re-exported here.
"""

from __future__ import annotations

import logging
import os
import signal
import threading
import time
from contextlib import nullcontext
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from .mesh.mesh import Mesh
from .params import DEFAULT_CONVENTION, MAIN_JOB_GAMMA, ShellParameters, bending_factor
from .protocol import deflate as protocol_mod
from .protocol.deflate import Protocol, State
from .protocol.schedule import geometric_schedule, linear_values
from .protocol.spec import DEFAULT_MAX_ITER
from .protocol.stored import init_stored
from .solve.linear import check_mode, check_threads, default_threads
from .solve.listen import listening
from .store.layout import SOLVER_MODE
from .store.located import LOCATE_TOL
from .store.run import RunStore
from .store.view import Run, described
from .util import interrupt_of

log = logging.getLogger(__name__)


def default_out(params: ShellParameters, seed: int) -> Path:
    stamp = datetime.now(timezone.utc).strftime("%Y%m%d-%H%M%S")
    return Path("runs") / f"gamma{params.gamma:g}_nu{params.nu:.3g}_seed{seed}_{stamp}"


def deflate(mesh: Mesh | None = None, params: ShellParameters | None = None, *,
            dv: float | None = None, until: float | None = None, schedule=None,
            c0_cycle: bool = True,
            jiggle: float | None = None, temperature: float | None = None, seed: int = 0,
            bending: str = "juelicher", method: str = "newton", tol: float = 1e-9,
            max_iter: int = DEFAULT_MAX_ITER, stop_at_contact: bool = True,
            c0: float | None = None, prerelax: bool = True, direct_return: bool = True,
            rescale_start: bool = False,
            smooth_jiggle: float | None = None, smooth_degree: int | None = None,
            shape_imperfection: float | None = None, shape_degree: int | None = None,
            out=None,
            progress: bool = False, max_steps: int | None = None,
            form_factors=None, pressures=None, threads: int | None = None,
            locate: bool = True, locate_tol: float = LOCATE_TOL) -> Run:
    """Deflate a shell with the paper's protocol and store every step in ``out``.

    ``mesh`` defaults to the paper's randomized sphere with 3594 vertices (seeded with
    ``seed``); ``params`` to gamma = 15163, nu = 1/3 (it wrinkles). The schedule is
    ``dv, 2 dv, ...`` up to ``until`` (defaults: the paper's step 0.019 and 0.95) unless
    ``schedule`` (a list of target dV/V) or ``pressures`` is given, which exclude them. If
    ``out`` already holds this same run it is resumed; if it holds a different run a
    ``ValueError`` says so.
    ``max_steps`` stops after that many new steps (the run stays resumable).
    ``pressures`` (a list of external overpressures in the shell's units: kappa/R^3, Pa for a
    material) switches to pressure
    control: each step minimizes ``E + p V`` at free volume.
    ``form_factors (F, 3)`` sets the stretching rest state (Surface Evolver's rest metrics)
    instead of the initial mesh. The jiggle is Surface Evolver's at ``temperature`` (default
    0.05, sigma = 0.028 R) or ``jiggle`` times the mean edge length, or the smooth
    imperfection of rms ``smooth_jiggle`` (units of R) up to degree ``smooth_degree``
    (:mod:`shellbuckle.protocol.imperfection`, the same field on any mesh); give at most one.
    ``shape_imperfection`` (units of R) and ``shape_degree`` make the shell itself imperfect:
    its stress-free shape is the sphere moved radially by a seeded field of that rms, the same
    shell on any mesh (:meth:`~shellbuckle.protocol.spec.Protocol.stress_free`); the run
    starts there, whatever the jiggle (``smooth_jiggle=0`` for none).
    ``max_iter`` bounds each minimization (Newton steps, i.e. factorizations, with Newton's
    method; iterations with the others): with ``method="cg"`` or ``"gd"``
    a small budget quenches the shell as a fixed-iteration Surface Evolver script does (the
    paper's multi-dimple "potato" without the c0 cycle); Newton converges well within it.
    ``prerelax`` starts every Newton minimization with the preconditioned relaxation (see
    :class:`~shellbuckle.protocol.spec.Protocol`); off, Newton starts at once (slower).
    ``direct_return``: after the zero-curvature cycle the last minimization starts at the
    minimum before the cycle when the way there is downhill (see
    :func:`~shellbuckle.protocol.deflate.downhill_path`); off, always at the flat minimum.
    ``rescale_start``: a volume step starts from the last minimum scaled uniformly to its
    volume (:func:`~shellbuckle.protocol.deflate.scaled_to_volume`), faster on fine meshes
    (three times per step before buckling on 40000 vertices); off (the default), the
    minimizer moves it along the volume gradient, a move as uneven as the vertex areas.
    ``locate``: when the run has finished, locate its buckling events by bisection in volume
    to ``locate_tol`` in dV/V (:mod:`shellbuckle.locate`; stored in ``located.json``, the
    steps unchanged).
    ``threads``: threads of the sparse factorization (default: the cores this process may
    use). On one thread PARDISO runs in its plain mode, on several in its reproducible mode,
    which gives the same bits on any number of threads; the plain mode is 6-10 % faster and
    gives other bits (:mod:`shellbuckle.solve.linear`). The run stores the mode it was made
    with (``meta["extra"]["pardiso_mode"]``, :func:`solver_mode`) and a resumed run uses it
    whatever its threads: a run made on one thread goes on on one thread, and one made on
    several goes on bit for bit on any number (one included). ``deflate(..., threads=1)``
    repeats a sweep's run (its workers have one thread each).
    """
    from .mesh.random_sphere import random_sphere

    if threads is not None:
        threads = check_threads(threads)

    params = params or ShellParameters.from_gamma(MAIN_JOB_GAMMA, nu=1.0 / 3.0)
    if not isinstance(params, ShellParameters):
        raise TypeError(f"params must be a ShellParameters (ShellParameters.from_gamma(...) or "
                        f".from_material(...)), got {type(params).__name__} {params!r}")
    mesh = mesh or random_sphere(3594, seed=seed, R=params.R)
    if not isinstance(mesh, Mesh):
        raise TypeError(f"mesh must be a Mesh (shellbuckle.mesh.icosphere, random_sphere, "
                        f"read_mesh or Mesh.from_arrays), got {type(mesh).__name__}")
    check_mesh_fits(mesh, params, form_factors)
    options = dict(c0=c0, c0_cycle=c0_cycle, jiggle=jiggle, temperature=temperature, seed=seed,
                   bending=bending, method=method, tol=tol, max_iter=max_iter,
                   stop_at_contact=stop_at_contact, prerelax=prerelax,
                   direct_return=direct_return, rescale_start=rescale_start)
    if smooth_jiggle is not None:  # the smooth imperfection replaces the per-vertex jiggle
        options.update(smooth_jiggle=smooth_jiggle)
        if smooth_degree is not None:
            options.update(smooth_degree=smooth_degree)
    elif smooth_degree is not None:
        raise ValueError("smooth_degree needs smooth_jiggle (the amplitude of the smooth "
                         "imperfection)")
    if shape_imperfection is not None or shape_degree is not None:
        options.update(shape_imperfection=shape_imperfection, shape_degree=shape_degree)
        if form_factors is not None and shape_imperfection:
            raise ValueError("a shape imperfection sets the rest state itself: give it or "
                             "form_factors (Surface Evolver's rest metrics), not both")
        if shape_imperfection:
            _check_on_sphere(mesh)
    if pressures is not None:
        if schedule is not None:
            raise ValueError("give either a volume schedule or pressures, not both")
        protocol = Protocol(schedule=tuple(np.atleast_1d(pressures)), control="pressure", **options)
    elif schedule is None:
        paper = {"dv": dv, "until": until}  # the paper's step and last target where not given
        protocol = Protocol.paper(**{k: v for k, v in paper.items() if v is not None},
                                  **options)
    else:
        protocol = Protocol(schedule=tuple(np.atleast_1d(schedule)), **options)
    check_shell_options(mesh, params, c0=c0, pressures=pressures)
    listed = "schedule" if schedule is not None else (
        "pressures" if pressures is not None else None)
    _not_beside_targets(listed, dv, until)
    out = Path(out) if out is not None else default_out(params, seed)
    rest = None if form_factors is None else {"form_factors": np.asarray(form_factors, float)}
    def setup():
        store = RunStore.create(out, params=params.to_dict(), protocol=protocol.to_dict(),
                                X0=mesh.X, faces=mesh.faces, rest=rest,
                                extra_meta={SOLVER_MODE: solver_mode(threads)})
        return store, mesh, params, protocol

    return _drive(setup, progress=progress, max_steps=max_steps, threads=threads,
                  locate=locate_tol if locate else None)


def resume(path, *, progress: bool = False, max_steps: int | None = None,
           threads: int | None = None, locate: bool = True,
           locate_tol: float = LOCATE_TOL) -> Run:
    """Continue a stored run from its last finished step (``threads``, ``locate`` and
    ``locate_tol`` as in :func:`deflate`)."""
    if threads is not None:
        threads = check_threads(threads)
    def setup():
        # the description and the mesh checked before the store records a session
        params, protocol = described(RunStore.open(path))
        store = RunStore.resume(path)  # checks mesh.h5 before it records a session
        return store, Mesh.from_arrays(store.X0, store.faces), params, protocol

    return _drive(setup, progress=progress, max_steps=max_steps, threads=threads,
                  locate=locate_tol if locate else None)


def continue_from(run, step: int, out, *, schedule=None, dv: float | None = None,
                  until: float | None = None, progress: bool = False,
                  max_steps: int | None = None, threads: int | None = None,
                  locate: bool = False, locate_tol: float = LOCATE_TOL, **options) -> Run:
    """A new run in ``out`` starting from step ``step`` of ``run`` with a new volume schedule.

    Give ``schedule`` (target dV/V list), or ``dv`` and ``until`` (``dv < 0`` re-inflates).
    Other protocol options default to the parent's (an unknown one is a TypeError). The
    stress-free reference stays the parent's initial sphere. ``max_steps``, ``threads``,
    ``locate`` and ``locate_tol`` as in :func:`deflate` (not located unless asked).
    """
    if threads is not None:
        threads = check_threads(threads)
    parent = Run.of(run)
    step = parent.step(step)
    start = float(parent.store.record(step)["dV_over_V"])
    _not_beside_targets("schedule" if schedule is not None else None, dv, until)
    if schedule is None:
        if dv is None or until is None:
            raise ValueError("give either schedule=[...] or both dv and until")
        from .protocol.schedule import linear_schedule

        schedule = linear_schedule(dv, until, start=start)
    fields = _branch_fields(parent, step, options)
    fields |= {"schedule": list(np.atleast_1d(schedule)), "control": "volume",
               "fixed_dV_over_V": None}
    protocol = Protocol.from_dict(fields)
    params = parent.params_at(step)
    def setup():
        store = parent.store.branch(out, step, params=params.to_dict(),
                                    protocol=protocol.to_dict(),
                                    extra_meta={SOLVER_MODE: solver_mode(threads)})
        return store, Mesh.from_arrays(store.X0, store.faces), params, protocol

    return _drive(setup, progress=progress, max_steps=max_steps, threads=threads,
                  locate=locate_tol if locate else None)


def continue_in_parameter(run, step: int, out, *, gamma=None, c0=None,
                          increments: int | None = None, progress: bool = False,
                          max_steps: int | None = None, threads: int | None = None,
                          locate: bool = False, locate_tol: float = LOCATE_TOL,
                          **options) -> Run:
    """A path in gamma or in c0 at the fixed volume of step ``step`` of ``run``, in ``out``.

    Give ``gamma`` or ``c0``: a target value with ``increments`` (gamma in equal ratios from
    the step's gamma, :func:`~shellbuckle.protocol.schedule.geometric_schedule`; c0 in equal
    differences from the step's c0, convention c = c1 + c2), or a list of values, one per
    increment. Each increment is one stored step: jiggle, minimization at the enclosed
    volume of the start step (its measured dV/V, held exactly) and the c0 cycle, as in the
    deflation protocol, whose options (``c0_cycle``, ``jiggle``, ``temperature``, ``seed``,
    ``method``, ``tol``, ...) default to the parent run's. ``increments = 0`` stores the
    start only. The table has a ``gamma`` column; :meth:`Run.params_at` gives the parameters
    of each step, and ``continue_from`` on the result deflates further at the path's end.
    The run stays resumable (call again with the same arguments, or :func:`resume`).
    ``max_steps``, ``threads``, ``locate`` and ``locate_tol`` as in :func:`deflate` (not
    located unless asked); an unknown option is a TypeError.
    """
    if threads is not None:
        threads = check_threads(threads)
    parent = Run.of(run)
    if (gamma is None) == (c0 is None):
        raise ValueError("give exactly one of gamma=... and c0=... (the parameter to follow)")
    step = parent.step(step)
    control, value = ("gamma", gamma) if gamma is not None else ("c0", c0)
    start = parent.params_at(step).gamma if control == "gamma" else parent.c0_at(step)
    values = _parameter_values(control, value, start, increments)
    fixed = float(parent.store.record(step)["dV_over_V"])
    fields = _branch_fields(parent, step, options)
    fields |= {"schedule": list(values), "control": control, "fixed_dV_over_V": fixed}
    protocol = Protocol.from_dict(fields)
    params = parent.params_at(step)
    path = {"parameter": control, "start": float(start),
            "end": float(values[-1]) if len(values) else float(start),
            "increments": len(values),
            "spacing": ("geometric" if control == "gamma" else "linear")
            if np.ndim(value) == 0 else "given",
            "fixed_dV_over_V": fixed, "parent": str(parent.path.resolve()), "parent_step": step}
    def setup():
        store = parent.store.branch(out, step, params=params.to_dict(),
                                    protocol=protocol.to_dict(),
                                    extra_meta={"path": path,
                                                SOLVER_MODE: solver_mode(threads)},
                                    record={"gamma": params.gamma})
        return store, Mesh.from_arrays(store.X0, store.faces), params, protocol

    return _drive(setup, progress=progress, max_steps=max_steps, threads=threads,
                  locate=locate_tol if locate else None)


def _parameter_values(control: str, value, start: float, increments) -> np.ndarray:
    if np.ndim(value) == 0:
        if increments is None:
            raise ValueError(f"{control} = {value!r} is a target: give increments=N (the number "
                             f"of steps from the start value {start:g}), or a list of values")
        spaced = geometric_schedule if control == "gamma" else linear_values
        return spaced(start, value, increments)
    if increments is not None:
        raise ValueError(f"give increments only with a target {control}, not with a list of "
                         "values")
    values = np.asarray(value, dtype=float).ravel()
    if control == "gamma" and not (np.isfinite(values) & (values > 0)).all():
        raise ValueError(f"gamma = A R^2/kappa must be > 0 at every increment, got "
                         f"{values.tolist()!r}")
    return values


def _branch_fields(parent: Run, step: int, options: dict) -> dict:
    """The protocol fields of a branch from step ``step``: the parent's, with ``options``
    replacing them and the c0 in force at that step (after a c0 path)."""
    import dataclasses

    names = {f.name for f in dataclasses.fields(Protocol)} - {"schedule", "control",
                                                              "fixed_dV_over_V"}
    unknown = sorted(set(options) - names)
    if unknown:
        raise TypeError(f"unknown option(s) {', '.join(unknown)}: a continued run takes the "
                        f"protocol's options ({', '.join(sorted(names))}), progress, "
                        "max_steps, threads, locate and locate_tol")
    base = parent.protocol
    if base.shape_imperfection and options.get("seed", base.seed) != base.seed:
        raise ValueError(f"seed {options['seed']!r}: a continued run keeps the seed "
                         f"{base.seed} of its parent, whose shape imperfection it draws")
    # a jiggle option left at None keeps the parent's; one given replaces the parent's others
    kinds = {"jiggle": ("jiggle",), "temperature": ("temperature",),
             "smooth": ("smooth_jiggle", "smooth_degree")}
    options = {k: v for k, v in options.items()
               if not (k in ("jiggle", "temperature", "smooth_jiggle", "smooth_degree")
                       and v is None)}
    fields = base.to_dict() | options
    given = [kind for kind, names in kinds.items() if any(n in options for n in names)]
    if len(given) == 1:
        for kind, names in kinds.items():
            for name in names if kind != given[0] else ():
                if kind == "smooth":
                    fields.pop(name, None)  # unset: to_dict leaves them out
                else:
                    fields[name] = None
    if base.control == "c0" and "c0" not in options:
        fields["c0"] = parent.c0_at(step)
    return fields


def compare_paths(run_a, step_a: int, run_b, step_b: int) -> dict:
    """Two conformations reached by different paths, side by side (the paper's Fig. 11).

    Returns ``{"a": {...}, "b": {...}, "ratio": E_b / E_a, "same_parameters": bool,
    "differences": [...]}`` where each side holds ``path``, ``step``, ``gamma``, ``nu``,
    ``c0``, ``dV_over_V``, ``E_total``, ``E_bend``, ``E_stretch``, ``E_over_kappa`` (as
    stored) and the shape (``shape``, ``n_dimples``, ``corners``, ``W``, ``dent_depth``,
    ``asphericity``; stored analysis, or classified now). The paper's number: a = the
    conformation reached from a capsule at lower gamma, b = the W = 7 wrinkled bowl of
    progressive deflation at gamma = 15163, dV/V = 0.645: ratio 1.42. ``same_parameters`` is
    False (and ``differences`` says why) when gamma, nu or c0 differ by more than 1e-9
    (relative) or dV/V by more than 1e-6.
    """
    sides = {"a": _side(run_a, step_a), "b": _side(run_b, step_b)}
    a, b = sides["a"], sides["b"]
    differences = []
    for name in ("gamma", "nu", "c0"):
        if not np.isclose(a[name], b[name], rtol=1e-9, atol=0.0):
            differences.append(f"{name}: {a[name]:.10g} vs {b[name]:.10g}")
    if abs(a["dV_over_V"] - b["dV_over_V"]) > 1e-6:
        differences.append(f"dV/V: {a['dV_over_V']:.8f} vs {b['dV_over_V']:.8f}")
    ratio = b["E_total"] / a["E_total"] if a["E_total"] != 0 else float("nan")
    return {"a": a, "b": b, "ratio": float(ratio), "same_parameters": not differences,
            "differences": differences}


def _side(run, step: int) -> dict:
    run = Run.of(run)
    k = run.step(step)
    record = run.store.record(k)
    params = run.params_at(k)
    out = {"path": str(run.path), "step": k, "gamma": params.gamma, "nu": params.nu,
           "c0": run.c0_at(k)}
    out |= {name: float(record[name]) for name in ("dV_over_V", "E_total", "E_bend",
                                                   "E_stretch", "E_over_kappa")}
    shape = run.store.analysis().get(k)
    if not shape or "shape" not in shape:
        from .analysis import classify

        shape = classify(run.positions(k), run.faces).columns()
    out |= {name: shape.get(name) for name in ("shape", "n_dimples", "corners", "W",
                                               "dent_depth", "asphericity")}
    return out


def solver_mode(threads: int | None) -> str:
    """PARDISO's mode for a new run on ``threads`` threads (default
    :func:`~shellbuckle.solve.linear.default_threads`): plain on one, reproducible on several."""
    return "reproducible" if check_mode(None, threads or default_threads()) else "plain"


def _not_beside_targets(given: str | None, dv, until) -> None:
    """ValueError if ``dv`` or ``until`` is given beside a list of targets (``given``: the
    name of that list, ``schedule`` or ``pressures``; None: no list), which would ignore
    them."""
    if given is not None and (dv is not None or until is not None):
        raise ValueError(f"give either {given} or dv and until (a schedule dv, 2 dv, ... up to "
                         f"until), not both: dv = {dv!r}, until = {until!r} would be ignored")


def check_max_steps(max_steps) -> None:
    """``TypeError``/``ValueError`` unless ``max_steps`` is None or an integer >= 0."""
    import numbers

    if max_steps is None:
        return
    if not isinstance(max_steps, numbers.Integral) or isinstance(max_steps, bool):
        raise TypeError(f"max_steps must be an integer >= 0 (new steps before the run pauses) "
                        f"or None, got {type(max_steps).__name__} {max_steps!r}")
    if max_steps < 0:
        raise ValueError(f"max_steps = {max_steps!r}: allowed: an integer >= 0 (new steps "
                         "before the run pauses) or None")


def _drive(setup, *, progress: bool, max_steps: int | None = None,
           threads: int | None = None, locate: float | None = None) -> Run:
    """Run a protocol into a store from its last step; ``setup()`` opens the store and gives
    ``(store, mesh, params, protocol)``. The store's status tells how the run ended: finished,
    paused (``max_steps``), failed (an error, or a step that left the physical domain,
    :class:`~shellbuckle.protocol.deflate.LeftDomain`, which is not stored) or interrupted
    (Ctrl-C or SIGTERM, wherever it arrived: see :class:`_Interrupts` and
    :func:`interrupt_of`). A finished run's events are then located to the tolerance
    ``locate`` (None: not located), :func:`_locate`."""
    check_max_steps(max_steps)
    if locate is not None:
        from .locate import check_tol

        check_tol(locate)
    interrupts = _Interrupts()
    try:
        store, mesh, params, protocol = setup()
    except BaseException:
        interrupts.restore()
        raise
    try:
        interrupts.start()
        _drive_steps(store, mesh, params, protocol, progress=progress, max_steps=max_steps,
                     threads=threads, checkpoint=interrupts.check)
    except (Exception, KeyboardInterrupt) as exc:
        interrupts.restore()
        interrupt = interrupt_of(exc)
        if interrupt is None:
            store.set_status("failed", f"{type(exc).__name__}: {exc}")
            store.close()
            raise
        how = f" ({interrupt})" if str(interrupt) else ""
        where = ("before step 0 was stored" if store.last_step is None
                 else f"after step {store.last_step}")
        store.set_status("interrupted", f"interrupted{how} {where}; "
                         f"`shellbuckle resume {store.path}` continues it")
        store.close()
        if interrupt is exc:
            raise
        raise interrupt from exc
    interrupts.restore()
    store.close()
    run = Run(RunStore.open(store.path))
    if locate is not None and run.status == "finished":
        _locate(run, locate, threads, progress)
    return run


def _locate(run: Run, tol: float, threads: int | None, progress: bool) -> None:
    """Locate the finished run's events (:func:`shellbuckle.locate.locate`). The run stands
    whatever happens here: a failure is logged (``shellbuckle locate DIR`` tries again); an
    interrupt leaves the events located so far and is raised."""
    from .locate import locatable, locate

    if locatable(run) is not None:
        return
    if progress:
        print(f"locating the buckling events of {run.path} to dV/V ± {tol / 2:.0e} "
              "(--no-locate skips it)", flush=True)
    try:
        locate(run, tol=tol, threads=threads)
    except Exception as exc:  # noqa: BLE001 - the run is finished and stored
        log.warning("the run is finished, but its events could not be located: %s: %s; "
                    "`shellbuckle locate %s` tries again", type(exc).__name__, exc, run.path)


class _Interrupts:
    """SIGINT and SIGTERM during a run (main thread only; elsewhere handlers cannot be
    installed and this does nothing), so that each ends the run as interrupted.

    From construction to :meth:`start` (while the run folder is written) a signal is only
    recorded; :meth:`start` hands it to its former handler (Python's raises
    ``KeyboardInterrupt``, the CLI's SIGTERM handler its subclass; ``SIG_DFL`` takes the
    default action), inside the run's ``try``. After :meth:`start` a signal is recorded and
    handed on at once; :meth:`check`, called between steps, hands it on again if it has not
    ended the run: an exception raised inside a callback from compiled code is printed and
    dropped ("Exception ignored on calling ctypes callback function", Numba loading a kernel
    from its cache), and the step then finishes normally. :meth:`restore` puts the former
    handlers back. A signal that is ignored (``SIG_IGN``) stays ignored."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.pending: list[int] = []
        self.previous: dict = {}
        self.holding = True
        if threading.current_thread() is not threading.main_thread():
            return
        for signum in self.SIGNALS:
            handler = signal.getsignal(signum)
            if handler is not None and handler != signal.SIG_IGN:
                self.previous[signum] = signal.signal(signum, self._record)

    def _record(self, signum, frame) -> None:
        self.pending.append(signum)
        if not self.holding:
            self._hand_on(signum)

    def start(self) -> None:
        self.holding = False
        self.check()

    def check(self) -> None:
        if self.pending:
            self._hand_on(self.pending[0])

    def restore(self) -> None:
        previous, self.previous = self.previous, {}
        for signum, handler in previous.items():
            signal.signal(signum, handler)

    def _hand_on(self, signum: int) -> None:
        handler = self.previous.get(signum)
        if callable(handler):
            handler(signum, None)
        elif handler == signal.SIG_DFL:
            self.restore()
            os.kill(os.getpid(), signum)


def _drive_steps(store: RunStore, mesh: Mesh, params, protocol: Protocol, *, progress: bool,
                 max_steps: int | None, threads: int | None, checkpoint) -> None:
    """The run loop; ``checkpoint()`` is called before each step and before the final status
    (:meth:`_Interrupts.check`)."""
    ctx, state = init_stored(store, mesh, params, protocol, threads)
    last = store.last_step
    if last is None:
        why = protocol_mod.domain_exit(ctx, state.X)
        if why is not None:
            raise protocol_mod.LeftDomain(0, why)
        record = protocol_mod.measure(ctx, state.X, 0.0)
        store.append_step(0, state.X, record)
    else:
        record = store.record(last)
        state = protocol_mod.state_after(last, store.positions(last), record)
        stopped = protocol_mod.stop_message(protocol, last, record)  # the run had ended
        if stopped is not None:
            state = State(step=last, X=state.X, stopped=stopped)
    bar = _progress(progress, len(protocol.schedule), state.step, mesh, params)
    done, ended = 0, True
    try:
        with _FoldWarnings() as folds:
            while state.stopped is None and (max_steps is None or done < max_steps):
                checkpoint()
                folds.count = 0
                within = bar is not None and bar.within
                if within:
                    bar.begin(state.step + 1)
                with listening(bar.accepted) if within else nullcontext():
                    state, record = protocol_mod.step(ctx, state)
                store.append_step(state.step, state.X, record)
                done += 1
                if folds.count:
                    log.warning("%s", _fold_verdict(state.step, record))
                if bar is not None:
                    bar.update(state.X, record)
                log.info("step %d: dV/V = %.4f, E = %.6g, p = %.6g, %d it, %.2f s", state.step,
                         record["dV_over_V"], record["E_total"], record["pressure"],
                         record["iterations"], record["wall_s"])
        ended = state.stopped is not None
    except BaseException as exc:
        ended = interrupt_of(exc) is None  # a failure ends the run; an interrupt pauses it
        raise
    finally:
        if bar is not None:
            bar.close(ended)
    checkpoint()
    if state.stopped is not None:
        store.set_status("finished", state.stopped)
    else:
        store.set_status("paused", f"stopped after {done} new steps; resume to continue")


def _progress(enabled: bool, total: int, initial: int, mesh: Mesh, params) -> _Progress | None:
    """The progress bar of a run of ``total`` steps from step ``initial`` (None unless
    ``enabled``)."""
    return _Progress(total, initial, mesh, params) if enabled else None


def interactive(bar) -> bool:
    """Whether a tqdm ``bar`` is seen as it is redrawn (a terminal, a notebook), not written
    frame after frame to a file or a pipe, where a refresh every second fills a log."""
    if any(c.__module__.startswith("tqdm.notebook") for c in type(bar).__mro__):
        return True  # tqdm.auto's class in a notebook is a subclass defined in tqdm.auto
    fp = getattr(bar, "fp", None)
    if type(fp).__module__.startswith("ipykernel"):  # a kernel's stream: shown in a notebook
        return True
    try:
        return bool(fp.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class _Progress:
    """A run's progress bar: the steps done out of the schedule's, and the last step's dV/V,
    E/kappa, pressure in units of the classical buckling pressure p_c (the unit of the run
    figure, :func:`shellbuckle.plots.run.plot_run`; at the step's gamma on a path in gamma),
    and its shape and W (:func:`~shellbuckle.analysis.classify.classify_descriptors`, about
    0.09 s a step at 3594 vertices, 2-4 % of a step of the main job). :meth:`close` with
    ``ended`` sets the total to the steps done, so a run that ends early (self-contact, a
    failure) ends at 100 %. While it is shown, log records are written above it.

    Within a step that lasts more than :attr:`EVERY_S` (a step on a fine mesh: minutes), the
    bar also shows the step's accepted minimizer iterations so far and its time, refreshed
    every :attr:`EVERY_S` on a terminal or in a notebook, every :attr:`EVERY_S_LOG` where the
    bar is written to a file or a pipe (a batch job's log) (:meth:`accepted`, called by the
    minimizers through :mod:`shellbuckle.solve.listen`)."""

    EVERY_S = 1.0
    EVERY_S_LOG = 60.0

    def __init__(self, total: int, initial: int, mesh: Mesh, params):
        from tqdm.auto import tqdm
        from tqdm.contrib.logging import logging_redirect_tqdm

        from .analysis.descriptors import ShapeAnalyzer

        self.params = params
        self.analyzer = ShapeAnalyzer(mesh.faces, n_vertices=mesh.n_vertices)
        self.bar = tqdm(total=total, initial=initial, unit="step", desc="deflation",
                        dynamic_ncols=True)
        self.redirect = logging_redirect_tqdm(tqdm_class=tqdm)
        self.redirect.__enter__()
        self.last, self.step, self.iterations, self.t0, self.shown = "", None, 0, 0.0, 0.0
        self.every = self.EVERY_S if interactive(self.bar) else self.EVERY_S_LOG
        self.within = True  # show the iterations within a step (off after a failure)

    def begin(self, step: int) -> None:
        """Step ``step`` begins: its iterations are counted from 0."""
        self.step, self.iterations = step, 0
        self.t0 = self.shown = time.monotonic()

    def accepted(self, E: float, r_norm: float) -> None:
        """A minimizer step was accepted within the current step (:mod:`.solve.listen`)."""
        self.iterations += 1
        t = time.monotonic()
        if t - self.shown < self.every:
            return
        self.shown = t
        minutes, seconds = divmod(int(t - self.t0), 60)
        now = f"step {self.step}: {self.iterations} it, {minutes}:{seconds:02d}"
        try:
            self.bar.set_postfix_str(f"{self.last} | {now}" if self.last else now, refresh=True)
        except Exception as exc:  # noqa: BLE001 - the bar never stops a run
            log.warning("the progress bar cannot show the iterations within a step: %s: %s",
                        type(exc).__name__, exc)
            self.within = False

    def update(self, X, record: dict) -> None:
        from .theory import classical_pressure

        params = self.params if "gamma" not in record else self.params.with_gamma(
            record["gamma"])
        p_c = classical_pressure(params)
        self.last = (f"dV/V={record['dV_over_V']:.3f} E/kappa={record['E_over_kappa']:.4g} "
                     f"p/p_c={record['pressure'] / p_c:.3f} {self._shape(X)}")
        self.bar.set_postfix_str(self.last, refresh=False)
        self.bar.update(1)

    def _shape(self, X) -> str:
        from .analysis.classify import classify_descriptors

        try:
            found = classify_descriptors(self.analyzer.describe(X))
        except Exception as exc:  # noqa: BLE001 - the bar never stops a run
            log.debug("the progress bar could not classify the step: %s", exc)
            return "shape=?"
        return f"shape={found.shape} W={found.W}"

    def close(self, ended: bool) -> None:
        if ended:
            self.bar.total = self.bar.n
            self.bar.refresh()
        self.bar.close()
        self.redirect.__exit__(None, None, None)


class _FoldWarnings(logging.Handler):
    """Counts, in ``count``, the warnings of a folded mesh that shellbuckle logs in this
    thread (runs of a sweep may share the process) while it is entered: faces folded onto
    each other (:func:`shellbuckle.protocol.deflate.folded_flat`) or neighbouring faces
    intersecting (``folded_locally``, ``only_local``), after which the step is jiggled again."""

    TEXTS = ("folded onto each other", "a fold of the mesh", "(a fold)")

    def __init__(self):
        super().__init__(logging.WARNING)
        self.count = 0
        self.thread = threading.get_ident()

    def emit(self, record: logging.LogRecord) -> None:
        if record.thread == self.thread and any(t in record.getMessage() for t in self.TEXTS):
            self.count += 1

    def __enter__(self) -> _FoldWarnings:
        logging.getLogger("shellbuckle").addHandler(self)
        return self

    def __exit__(self, *exc) -> None:
        logging.getLogger("shellbuckle").removeHandler(self)


def _fold_verdict(k: int, record: dict) -> str:
    """The closing line of a step that logged fold warnings: whether it still ended at a
    proper minimum (converged, inertia 0: no negative eigenvalue of the constrained
    Hessian)."""
    inertia = record.get("inertia")
    if not record.get("converged"):
        return (f"step {k} did not converge to a minimum; the fold may remain in its stored "
                "state (converged False in the table)")
    if inertia is None or inertia < 0:
        return (f"step {k} converged, but its inertia was not computed: whether it is a "
                "minimum is not known")
    if inertia > 0:
        return (f"step {k} converged to a saddle point, not a minimum (inertia {inertia}: "
                "negative eigenvalues of the constrained Hessian)")
    return f"step {k} converged to a minimum (inertia 0); the fold was left behind"


ON_SPHERE_TOL = 1e-9
"""Largest relative spread of the vertex radii about the fitted sphere of a mesh that a shape
imperfection may start from: its material points are the vertices' directions on that sphere,
so any other mesh would first be moved onto it."""


#: How far the radius of a stress-free mesh (that of the sphere of its volume) may lie from
#: the shell's R: a coarse icosphere's is 2-4 % below; a mesh in other units is off by
#: factors.
RADIUS_TOL = 0.2


def check_mesh_fits(mesh: Mesh, params: ShellParameters, form_factors=None) -> None:
    """``ValueError`` unless ``mesh`` can be the shell of ``params``: its faces point outward
    (it encloses a positive volume), ``form_factors`` (if given) are a valid rest metric of
    its faces, and without them (the mesh is the stress-free shell) the radius of the sphere
    of its volume is ``params.R`` within :data:`RADIUS_TOL`. Checked before a run folder is
    made."""
    from .energies.stretching import Stretching
    from .energies.volume import Volume

    V = Volume(mesh.faces, mesh.n_vertices).value(mesh.X)
    if not V > 0:
        raise ValueError(f"mesh encloses a non-positive volume {V!r}: its faces must point "
                         "outward (reverse them: Mesh.from_arrays(X, faces[:, ::-1]))")
    if form_factors is not None:
        Stretching.from_form_factors(mesh.faces, mesh.n_vertices, form_factors, 1.0, 0.0)
        return
    R_mesh = (3.0 * V / (4.0 * np.pi)) ** (1.0 / 3.0)
    if not abs(R_mesh / params.R - 1.0) <= RADIUS_TOL:
        raise ValueError(f"mesh radius {R_mesh:.6g} (the sphere of its volume) is not the "
                         f"shell's R = {params.R:.6g} (allowed: within {RADIUS_TOL:.0%}): "
                         f"build the mesh with R=params.R (icosphere(n, R=...), "
                         "random_sphere(n, R=...)) or give the parameters its radius")


def check_shell_options(mesh: Mesh, params: ShellParameters, *, c0=None,
                        pressures=None) -> None:
    """``ValueError`` for a spontaneous curvature or pressures the shell of ``params`` on
    ``mesh`` cannot take (the command line's rules): a preferred radius ``2/|c0|`` shorter
    than the mean edge of a sphere of as many vertices (:func:`~.resolution.c0_limit`; the
    command line checks it before the mesh exists), an overpressure at or above the classical
    buckling pressure (the shell turns inside out) or below ``-gamma`` (it more than doubles
    its volume). A mesh that does not resolve the elastic length
    (:mod:`shellbuckle.resolution`) is only warned about: a coarse mesh is a legitimate, if
    rough, model. ``c0`` and ``pressures`` are
    numbers already (a :class:`Protocol` was built of them)."""
    from .resolution import c0_limit, gamma_resolved, mean_edge, vertices_needed

    n = mesh.n_vertices
    if c0 is not None and abs(c0) > c0_limit(n, params.R):
        raise ValueError(f"c0 = {c0!r}: allowed |c0| <= {c0_limit(n, params.R):.4g} on {n} "
                         f"vertices (the preferred radius 2/|c0| must be at least the mean "
                         f"edge {mean_edge(n) * params.R:.3g} of a sphere of {n} vertices; "
                         f"c0 = 2/R = {2.0 / params.R:g} is the stress-free sphere)")
    if pressures is not None:
        from .theory import pressure_bounds

        low, high = pressure_bounds(params)
        for p in np.atleast_1d(np.asarray(pressures, dtype=float)):
            if not low <= p < high:
                raise ValueError(f"pressure {float(p)!r}: allowed overpressures in "
                                 f"[{low:.6g}, {high:.6g}) in the shell's units (kappa/R^3 = "
                                 f"{params.kappa / params.R ** 3:.6g}) at gamma = "
                                 f"{params.gamma:g}: [-gamma, p_c) (above the classical "
                                 "buckling pressure p_c the shell turns inside out; below "
                                 "-gamma kappa/R^3 it more than doubles its volume)")
    need = vertices_needed(params.gamma_effective)
    if n < need:
        log.warning("the mesh of %d vertices does not resolve the elastic length at "
                    "(effective) gamma %g: about %d vertices are needed (it resolves gamma <= "
                    "%.4g); its buckling is the mesh's more than the shell's", n,
                    params.gamma_effective, need, gamma_resolved(n))


def _check_on_sphere(mesh: Mesh) -> None:
    """``ValueError`` unless the vertices of ``mesh`` lie on one sphere (:data:`ON_SPHERE_TOL`):
    the reference of a shape imperfection."""
    from .protocol.imperfection import reference_sphere

    X = np.asarray(mesh.X, dtype=float)
    centre, R = reference_sphere(X)
    spread = float(np.abs(np.linalg.norm(X - centre, axis=1) - R).max()) / R
    if not spread <= ON_SPHERE_TOL:
        raise ValueError(f"a shape imperfection needs a mesh whose vertices lie on a sphere "
                         f"(the shell's reference); this mesh's vertices lie up to "
                         f"{spread:.3g} R off their fitted sphere (allowed: {ON_SPHERE_TOL:g} R): "
                         "use a randomized or icosahedral sphere")


def shell_from_file(path) -> tuple[Mesh, dict]:
    """Read a starting mesh from a file, with what the file says about the shell.

    A Surface Evolver datafile or dump (``.fe``, ``.dmp``) brings its own moduli: the returned
    dict may hold ``A`` (``linear_elastic`` modulus), ``nu`` (``poisson_ratio``, if uniform),
    ``kappa`` (``star_perp_sq_mean_curvature`` modulus / 2), ``c0`` (2 ``h_zero``; an
    ``h_zero`` that varies from vertex to vertex is refused),
    ``form_factors`` (the rest metrics) and ``bending = "evolver"`` when the file bends with
    ``star_perp_sq_mean_curvature`` (so that a run keeps the file's discretization). An energy
    quantity of another method is refused by name: the run could not keep the file's model.
    Any other format (through meshio) gives positions and faces only; the mesh is then taken
    as the stress-free shape.
    """
    from pathlib import Path as _Path

    path = _Path(path)
    if not path.is_file():
        raise ValueError(f"mesh file {str(path)!r} does not exist")
    if path.suffix.lower() not in (".fe", ".dmp"):
        from .mesh.io import read_mesh

        return read_mesh(path), {}
    from .mesh.evolver_io import read_evolver

    evf = read_evolver(path)
    modelled = ("linear_elastic", "star_perp_sq_mean_curvature")
    other = [q for q in evf.quantities if q.kind == "energy" and q.method not in modelled]
    if other:
        names = ", ".join(f"{q.name} (method {q.method})" for q in other)
        raise ValueError(f"mesh file {str(path)!r} has energy quantities shellbuckle does not "
                         f"model: {names}; allowed: {', '.join(modelled)}")
    found: dict = {}
    elastic = evf.energy_quantities("linear_elastic")
    if elastic:
        found["A"] = float(elastic[0].modulus)
        if evf.poisson_ratio is not None and np.ptp(evf.poisson_ratio) == 0:
            found["nu"] = float(evf.poisson_ratio[0])
        if evf.form_factors is not None:
            ff = np.asarray(evf.form_factors, float)
            if (ff[:, 0] * ff[:, 2] - ff[:, 1] ** 2 > 0).all():
                found["form_factors"] = ff
    bending = evf.energy_quantities("star_perp_sq_mean_curvature")
    if bending:
        found["kappa"] = float(bending[0].modulus) / 2.0
        found["bending"] = "evolver"
        if evf.h_zero is not None:
            h_zero = np.asarray(evf.h_zero, dtype=float)
            if np.ptp(h_zero) != 0:  # e.g. the export of a run with a shape imperfection
                raise ValueError(
                    f"mesh file {str(path)!r} has an h_zero that varies from vertex to vertex "
                    f"(from {h_zero.min():.6g} to {h_zero.max():.6g}); allowed: one h_zero for "
                    "the whole shell (a run from a file has a uniform spontaneous curvature; "
                    "continue the run itself with --from, or give the shape as "
                    "--shape-imperfection)")
            found["c0"] = 2.0 * float(h_zero.ravel()[0])
    return evf.mesh, found


def params_for_mesh(mesh: Mesh, from_file: dict, gamma=None, nu=None,
                    energy_convention: str | None = None) -> ShellParameters:
    """Shell parameters for a mesh read from a file: options override the file's moduli.

    ``R`` is the radius of the sphere with the mesh's initial volume; ``gamma = A R^2/kappa``.
    The file's bending energy is kept under any ``energy_convention`` (default helfrich): its
    helfrich modulus (twice Surface Evolver's modulus) is ``f kappa``, so ``kappa`` is that
    modulus over ``f`` (under evolver-modulus, the file's own modulus).
    """
    from .energies.volume import Volume

    V = Volume(mesh.faces, mesh.n_vertices).value(mesh.X)
    if not V > 0:
        raise ValueError(f"the mesh encloses a non-positive volume {V!r}: faces must point outward")
    R = (3.0 * V / (4.0 * np.pi)) ** (1.0 / 3.0)
    convention = energy_convention or DEFAULT_CONVENTION
    kappa = from_file["kappa"] / bending_factor(convention) if "kappa" in from_file else 1.0
    if gamma is None:
        gamma = from_file["A"] * R ** 2 / kappa if "A" in from_file else MAIN_JOB_GAMMA
    nu = nu if nu is not None else from_file.get("nu", 1.0 / 3.0)
    return ShellParameters.from_gamma(gamma, nu=nu, kappa=kappa, R=R,
                                      energy_convention=convention)
