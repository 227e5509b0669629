"""Located bifurcations: the volume of a buckling event to a set tolerance, by bisection.

The paper's protocol (Quilliet et al., EPJE 27, 13 (2008), §4.1) sees a transition only at its
volume steps (dV/V = 0.019): the primary buckling of a thin shell lies somewhere between the
sphere and the first step. Here each threshold event of a deflation run (the primary buckling,
the loss of axisymmetry and the onset of wrinkles of :mod:`shellbuckle.analysis.events`) found
at step ``k`` is located between the stored steps ``k - 1`` and ``k`` by bisection in volume:

1. the bracket is ``[lo, hi] = [dV/V of step k - 1, dV/V of step k]``; the start of every
   evaluation is the last state of the old branch the run stored, the conformation of step
   ``k - 1``;
2. at ``mid = (lo + hi) / 2`` the protocol's step is made from that start exactly as the run
   made step ``k`` (the same jiggle, drawn from the step's seeded stream and scaled to the
   step, the same minimizations and zero-curvature cycle), only to the volume ``mid``: the
   state the paper's protocol would reach there from the old branch;
3. the result is classified (:func:`shellbuckle.analysis.classify.classify`); if it shows the
   event (``sphere -> not sphere``, a rim ``polygonal`` or ``wrinkled``, ``wrinkled``) the
   bracket becomes ``[lo, mid]``, else ``[mid, hi]``;
4. until ``hi - lo <= tol`` (default ``1e-4``: eight evaluations for the paper's step).

The start does not move with the bracket. Where the old branch is still a minimum (a barrier
crossing, below) the outcome of a step depends on where it starts: a step from an old-branch
state nearer the barrier crosses it earlier, so a bisection that advanced its start would close
on a point of its own grid (docs/analysis.md, "Located events"). From the stored step the
outcome is a function of the volume alone, the threshold of the protocol's own step.

The located threshold is the bracket's middle, with an uncertainty of half its width. Stored
with it (:mod:`shellbuckle.store.located`) are both ends' energies, pressures and shapes, each
evaluation, and the lowest eigenvalue of the constrained Hessian (:mod:`shellbuckle.solve.spectrum`)
at the start of the bracket and at both ends. Where both ends lie on one branch (the pressure
continuous and the energy difference the pressure's work over the bracket, :func:`_jump`) the
event is *continuous*: the shape crosses the classifier's line (a rim turning concave between
its apices, say) without a jump. Otherwise the old branch is followed from its last state
without any jiggle (no help over a barrier), to half a step and to one original step past the
located point (further if that is short of 10 % beyond it); it ends where the event shows with
a jump (:func:`_jump`) or where a step finds no minimum (its minimization does not converge:
near a fold the branch's lowest eigenvalue vanishes and the minimizer stalls there), so that
its last state is a certified minimum of the old branch, and its end is then bisected to 1 %
(:func:`_old_branch`). If
the branch ends less than 10 % of that volume after the located point, the event is an
*instability*: a fold or bifurcation of the branch (Thompson & Hunt, *A General Theory of
Elastic Stability*, 1973) that the jiggle only anticipates. If it ends later or goes on past
the step, it is a *barrier crossing*: the old branch is still a minimum well past the located
point and the step's jiggle carries the shell over the energy barrier to a lower branch, as in
the paper's runs, between the energy crossing of the two branches and the classical
threshold. The lowest eigenvalue's linear extrapolation to zero
(``eigenvalue_zero_at``) is kept as an estimate; it is no test: near a fold the eigenvalue
falls like the square root of the distance to it, and the line reaches zero late.

Every end of a bracket is a converged minimization: an evaluation of the bisection whose
minimization does not converge stops it, with the bracket had so far (``complete`` false and a
``failure`` that says so), as does one that leaves the physical domain.

The location is a refinement of the run: the table and the stored steps are not changed, and a
run located or not has the same steps. It assumes the event is monotone in volume within one
step (the old branch gives way once); the evaluations are stored so that this can be checked.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable

import numpy as np

from .analysis.classify import ANALYSIS_VERSION, analyze_run, classify, is_current
from .analysis.events import events as run_events
from .protocol import deflate as protocol_mod
from .protocol.deflate import LeftDomain
from .protocol.stored import stored_context
from .solve.spectrum import lowest_eigenvalues
from .store.located import LOCATE_TOL, locating, read_located, write_located
from .store.view import Run

log = logging.getLogger(__name__)

#: Default tolerance of a located threshold, in dV/V (the bracket's final width).
DEFAULT_TOL = LOCATE_TOL
#: Smallest tolerance: below it the bisection would resolve the minimizer's tolerance.
MIN_TOL = 1e-7

#: The events located, and what each looks for in a classified conformation.
EVENT_SHAPES: dict[str, Callable[[str], bool]] = {
    "primary_buckling": lambda shape: shape != "sphere",
    "axisymmetry_loss": lambda shape: shape in ("polygonal", "wrinkled"),
    "wrinkles": lambda shape: shape == "wrinkled",
}
LOCATED_EVENTS = tuple(EVENT_SHAPES)
#: Both ends of a located bracket lie on one branch (the event is a shape crossing the
#: classifier's line, not a jump) when the pressure differs by at most this fraction ...
CONTINUOUS_PRESSURE = 0.01
#: ... and the energy by the pressure's work over the bracket to this fraction of that work.
CONTINUOUS_WORK = 0.1
#: A jump is an instability when the old branch, followed without jiggle, ends less than this
#: fraction of its end's volume after the located point (:func:`_old_branch`) ...
ANTICIPATION = 0.1
#: ... that end located to this fraction of its volume.
BRANCH_END_RTOL = 0.01


def check_tol(tol: float) -> float:
    """``tol`` as a float in ``[MIN_TOL, 0.1]`` (ValueError otherwise)."""
    tol = float(tol)
    if not (math.isfinite(tol) and MIN_TOL <= tol <= 0.1):
        raise ValueError(f"the location tolerance must be in [{MIN_TOL:g}, 0.1] (in dV/V), "
                         f"got {tol!r}")
    return tol


def locatable(run: Run) -> str | None:
    """Why the events of ``run`` cannot be located (None if they can): only deflations under
    volume control, with a rising schedule, minimized to convergence (Newton's method, alone
    or after CG), are."""
    protocol = run.protocol
    if protocol.method not in ("newton", "alternate"):
        return (f"its minimizer is {protocol.method!r}, whose fixed budget of iterations does "
                "not reach the minimum the bisection compares (Newton's method does)")
    if protocol.control != "volume":
        return f"a {protocol.control}-controlled run (only volume-controlled deflations are)"
    if len(protocol.schedule) and np.any(np.diff((0.0,) + protocol.schedule) <= 0):
        return "its volume schedule does not rise (a re-inflation)"
    return None


def locate(run_or_path, *, tol: float = DEFAULT_TOL, names=LOCATED_EVENTS,
           threads: int | None = None, again: bool = False) -> dict[str, dict]:
    """Locate the threshold events ``names`` of a stored deflation run and store them.

    Returns ``{name: point}`` for every event of ``names`` that the run shows (module
    docstring; the keys of a point are those :func:`_locate_event` returns). An event already
    located in the folder at the same step, analysis version and a tolerance at least as fine,
    with its old branch followed, is kept unless ``again``. ``threads`` as in
    :func:`shellbuckle.run.deflate`; the run's PARDISO mode is used, so the location is
    reproducible. A run that cannot be located (:func:`locatable`) gives ``{}``. One process
    at a time locates a run: this one waits while another is locating it, then keeps what
    that one stored (:func:`~shellbuckle.store.located.locating`).
    """
    tol = check_tol(tol)
    run = Run.of(run_or_path)
    why = locatable(run)
    if why is not None:
        log.info("%s: events not located: %s", run.path, why)
        return {}
    analysis = run.store.analysis()
    missing = [k for k in run.steps if not is_current(analysis.get(k))]
    if missing:  # the classes of the steps, stored: the events, the figure and the table use them
        analyze_run(run, steps=missing)
    out, todo = _kept_and_todo(run, {} if again else read_located(run.path), tol, names)
    if not todo:
        return out
    with locating(run.path):
        # read again under the lock: a process that held it may have located some just now
        stored = {} if again else read_located(run.path, warn=False)  # warned above
        out, todo = _kept_and_todo(run, stored, tol, names)
        ctx = stored_context(run, threads) if todo else None
        for event in sorted(todo, key=lambda e: e.step):
            point = _locate_event(ctx, run, event, tol)
            write_located(run.path, {event.name: point})
            out[event.name] = point
    return out


def _kept_and_todo(run: Run, stored: dict, tol: float, names) -> tuple[dict, list]:
    """The located points of ``stored`` that stand for the run's events ``names``, and the
    events still to locate (:func:`locate`)."""
    out, todo = {}, []
    for event in run_events(run, located=False):
        if event.name not in names:
            continue
        point = stored.get(event.name)
        # (a point located before the old branch was followed, without "old_branch", is
        # located again: its mechanism came from an extrapolation of the lowest eigenvalue)
        if (point and point.get("step") == event.step and point.get("tol", 1.0) <= tol * 1.000001
                and point.get("analysis_version") == ANALYSIS_VERSION and "old_branch" in point
                and _ends_converged(point)):
            out[event.name] = point
        else:
            todo.append(event)
    return out, todo


def pending(run_or_path, *, tol: float = DEFAULT_TOL, names=LOCATED_EVENTS) -> list:
    """The events of a finished, analysed run that :func:`locate` would locate now (none for
    a run that cannot be located): a location that was interrupted, or never made. Reads
    only."""
    run = Run.of(run_or_path)
    if locatable(run) is not None:
        return []
    return _kept_and_todo(run, read_located(run.path, warn=False), check_tol(tol), names)[1]


class StepFromStored:
    """The protocol's step ``k`` of a stored deflation run, made again from its stored step
    ``k - 1`` to any volume: what every evaluation of the bisection does (module docstring).

    ``StepFromStored(run, k)(dV_over_V)`` gives ``(state, record)`` as
    :func:`shellbuckle.protocol.deflate.step` does; with ``jiggle=False`` the step is made
    without its imperfection (no help over a barrier: the old branch followed), and ``start``
    (positions and record of a state at step ``k - 1``) replaces the stored start. ``threads``
    as in :func:`shellbuckle.run.deflate`. :meth:`shape` classifies the result. Only runs that
    :func:`locatable` accepts (volume-controlled deflations minimized to convergence) can be
    stepped so; ValueError otherwise, or when the run has no step ``k`` or no stored step
    ``k - 1``."""

    def __init__(self, run_or_path, k: int, *, threads: int | None = 1, ctx=None):
        self.run = Run.of(run_or_path)
        why = locatable(self.run)
        if why is not None:
            raise ValueError(f"{self.run.path} cannot be stepped again: {why}")
        if k < 1:
            raise ValueError(f"step {k} has no stored step before it in {self.run.path}")
        if k > len(self.run.protocol.schedule):
            raise ValueError(f"step {k} is not in the schedule of {self.run.path} "
                             f"({len(self.run.protocol.schedule)} steps)")
        self.k = k
        self.start = (self.run.positions(k - 1), self.run.store.record(k - 1))
        self.ctx = stored_context(self.run, threads) if ctx is None else ctx

    def __call__(self, dV_over_V: float, *, jiggle: bool = True, start=None):
        protocol = self.ctx.protocol
        schedule = list(protocol.schedule)
        schedule[self.k - 1] = float(dV_over_V)
        protocol = dataclasses.replace(protocol, schedule=tuple(schedule))
        if not jiggle:
            protocol = dataclasses.replace(protocol, **{
                name: 0.0 for name in ("temperature", "jiggle", "smooth_jiggle")
                if getattr(protocol, name) is not None})
        X, record = self.start if start is None else start
        return protocol_mod.step(dataclasses.replace(self.ctx, protocol=protocol),
                                 protocol_mod.state_after(self.k - 1, X, record))

    def shape(self, dV_over_V: float, **kwargs) -> str:
        """The class of the step's result (:func:`shellbuckle.analysis.classify.classify`)."""
        return classify(self(dV_over_V, **kwargs)[0].X, self.run.faces).shape


def _ends_converged(point: dict) -> bool:
    """Whether a stored point's brackets rest on converged minimizations wherever they come
    from an evaluation (a location made before unconverged evaluations stopped the bisection
    and ended the old branch's walk may not; it is located again). The run's own stored steps,
    the bracket's ends until an evaluation moves them, are the run's and not judged here."""
    bisection = point.get("evaluations") or []
    if any(not e.get("converged", True) for e in bisection[:-1]) or (
            bisection and not bisection[-1].get("converged", True) and point.get("complete")):
        return False
    walk = (point.get("old_branch") or {}).get("evaluations") or []
    return all(e.get("ends") or e.get("converged", True) for e in walk)


def ended_by(branch: dict | None) -> str | None:
    """What ended an old branch's walk (``"jump"`` or ``"no minimum"``, :func:`_old_branch`),
    also for a point stored before the walk recorded it (from its evaluation at ``end_hi``);
    None where no end was bracketed."""
    if not branch or branch.get("end_hi") is None:
        return None
    if branch.get("ended_by"):
        return branch["ended_by"]
    at_end = [e for e in branch.get("evaluations") or []
              if e.get("dV_over_V") == branch["end_hi"] and e.get("ends")]
    return "no minimum" if at_end and not at_end[-1].get("converged", True) else "jump"


def located(run_or_path) -> dict[str, dict]:
    """The located points stored with a run, ``{name: point}`` (empty if none)."""
    return read_located(Run.of(run_or_path).path)


def _side(ctx, X, record: dict, shape: str, lowest: float | None = None) -> dict:
    """One end of a bracket: its record's values, its class and the lowest eigenvalue at
    ``X`` (``lowest`` when already known)."""
    keys = ("dV_over_V", "E_total", "E_bend", "E_stretch", "E_over_kappa", "pressure",
            "grad_norm", "converged", "inertia")
    side = {key: record.get(key) for key in keys}
    side["shape"] = shape
    side["lowest_eigenvalue"] = _lowest(ctx, X) if lowest is None else lowest
    return side


def _lowest(ctx, X) -> float:
    try:
        return float(lowest_eigenvalues(ctx.energy, ctx.volume, X, ctx.pinned, k=1)[0])
    except Exception as exc:  # a singular matrix or ARPACK not converging: say so, go on
        log.warning("lowest eigenvalue not found (%s)", exc)
        return math.nan


def _locate_event(ctx, run: Run, event, tol: float) -> dict:
    """Bisection of one event (module docstring)."""
    t0 = time.perf_counter()
    k = event.step
    wanted = EVENT_SHAPES[event.name]
    step_to = StepFromStored(run, k, ctx=ctx)  # every evaluation starts from step k - 1
    X_lo, rec_lo = step_to.start
    X_hi, rec_hi = run.positions(k), run.store.record(k)
    # the volumes reached (a branch's step 0 is its parent's step, not the sphere)
    lo, hi = float(rec_lo["dV_over_V"]), float(rec_hi["dV_over_V"])
    lo_start, hi_start = lo, hi
    analysis = run.store.analysis()  # current for every step: locate() made sure of it
    shape_lo, shape_hi = str(analysis[k - 1]["shape"]), str(analysis[k]["shape"])
    lowest_start = _lowest(ctx, X_lo)
    # the old branch one stored step earlier, for the eigenvalue's trend if lo does not move
    before = float(run.store.record(k - 2)["dV_over_V"]) if k >= 2 else math.nan
    lowest_before = _lowest(ctx, run.positions(k - 2)) if k >= 2 else math.nan
    evaluations, failure = [], None
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        try:
            state, record = step_to(mid)
        except LeftDomain as exc:
            failure = f"the step to dV/V = {mid:.6f} left the physical domain: {exc.reason}"
            log.warning("%s: %s; %s located to [%.6f, %.6f] only", run.path, failure,
                        event.name, lo, hi)
            break
        shape = classify(state.X, run.faces).shape
        shows = wanted(shape)
        evaluations.append({"dV_over_V": mid, "shape": shape, "shows_event": shows,
                            "E_total": record["E_total"], "pressure": record["pressure"],
                            "converged": record["converged"]})
        if not record["converged"]:  # no minimum: neither end of a bracket
            failure = (f"the step to dV/V = {mid:.6f} did not converge (|r| = "
                       f"{record['grad_norm']:.3g})")
            log.warning("%s: %s; %s located to [%.6f, %.6f] only", run.path, failure,
                        event.name, lo, hi)
            break
        log.info("%s %s: dV/V = %.6f gives %s (%s)", run.path.name, event.name, mid, shape,
                 "the event" if shows else "the old branch")
        if shows:
            hi, X_hi, rec_hi, shape_hi = mid, state.X, record, shape
        else:
            lo, X_lo, rec_lo, shape_lo = mid, state.X, record, shape
    old = _side(ctx, X_lo, rec_lo, shape_lo, lowest=lowest_start if lo == lo_start else None)
    new = _side(ctx, X_hi, rec_hi, shape_hi)
    if lo > lo_start:
        trend = (lo_start, lowest_start, lo, old["lowest_eigenvalue"])
    else:
        trend = (before, lowest_before, lo, lowest_start)
    jump = _jump(old, new, ctx.V0 * (hi - lo))
    branch = None
    if jump:
        zero_at = _eigenvalue_zero(*trend)
        branch = _old_branch(step_to, wanted, run, (X_lo, rec_lo), lo, hi,
                             hi_start - lo_start, tol)
        mechanism = branch.pop("mechanism")
    else:
        mechanism, zero_at = "continuous", None
    return {
        "step": k, "tol": tol, "analysis_version": ANALYSIS_VERSION,
        "dV_over_V": 0.5 * (lo + hi), "uncertainty": 0.5 * (hi - lo), "lo": lo, "hi": hi,
        "step_dV_over_V": event.dV_over_V, "old": old, "new": new,
        "lowest_eigenvalue_start": lowest_start, "lowest_eigenvalue_before": lowest_before,
        "mechanism": mechanism, "old_branch": branch,
        "eigenvalue_zero_at": zero_at, "evaluations": evaluations,
        "complete": failure is None, "failure": failure,
        "wall_s": time.perf_counter() - t0,
    }


def _jump(old: dict, new: dict, dV: float) -> bool:
    """Whether the two ends of a bracket lie on different branches: the pressure jumps by more
    than ``CONTINUOUS_PRESSURE`` of itself, or the energy differs from the work of the
    pressure over the volume between them (``E_new - E_old = p dV`` with ``p`` their mean,
    ``dV`` the volume removed) by more than ``CONTINUOUS_WORK`` of that work."""
    p_old, p_new = float(old["pressure"]), float(new["pressure"])
    if abs(p_new - p_old) > CONTINUOUS_PRESSURE * max(abs(p_old), abs(p_new)):
        return True
    work = 0.5 * (p_old + p_new) * dV
    scale = abs(work) + 1e-9 * abs(float(old["E_total"]))
    return abs(float(new["E_total"]) - float(old["E_total"]) - work) > CONTINUOUS_WORK * scale


def _old_branch(step_to: StepFromStored, wanted, run: Run, start, lo: float, hi: float,
                step: float, tol: float) -> dict:
    """The old branch of a jump located in ``[lo, hi]``, followed without any jiggle (no help
    over a barrier) from its last state ``start`` at ``lo``: to ``hi + step / 2`` and then to
    ``reach``, one original ``step`` past the located point or, if that is farther, just past
    where a branch ending ``ANTICIPATION`` of its volume after it would end; each step from the
    state before. The branch ends where a step shows the event with a jump from the state before
    (:func:`_jump`), or where its minimization does not converge (no minimum found there: the
    last state of the walk is always a converged one); one that shows the event continuously
    (the old branch crossing the classifier's line) goes on. Where it ends, its end is bisected
    (from the last old state, without jiggle) to ``max(tol, BRANCH_END_RTOL * end)``.

    Returns ``mechanism``: ``instability`` when the branch ends less than ``ANTICIPATION`` of
    its end's volume after the located point (the jiggle only anticipates a fold or
    bifurcation), ``barrier crossing`` when it ends later or goes on past ``reach``,
    ``undetermined`` when a step of the walk leaves the physical domain before an end is
    bracketed (``failure`` says which; a failure inside the bisection keeps the bracket had
    so far and says so too); ``followed_to``, the furthest volume reached on the old branch;
    ``end_lo``, ``end_hi``, the bracket of its end, ``ended_by``, what the step at ``end_hi``
    found (``"jump"``: the event with a jump; ``"no minimum"``: its minimization did not
    converge, the fold's signature, but also that of a minimizer out of iterations), and
    ``anticipation``, ``1 - located /
    end`` with the bracket's middle as the end (all None when it goes on); ``evaluations``,
    each step (volume, class, whether it shows the event, whether it ended the branch, energy,
    pressure, convergence)."""
    located_at = 0.5 * (lo + hi)
    reach = max(hi + step, located_at / (1.0 - ANTICIPATION) * (1.0 + BRANCH_END_RTOL))
    X, record = start
    last, walk = lo, []  # the furthest volume reached on the old branch, and every step
    V0 = step_to.ctx.V0

    def found(**values) -> dict:
        return {"followed_to": last, "end_lo": None, "end_hi": None, "anticipation": None,
                "ended_by": None,
                "evaluations": walk} | values

    def follow(v):
        """The step to ``v`` from the last old state: (state, record, ended, failure)."""
        try:
            state, rec = step_to(v, jiggle=False, start=(X, record))
        except LeftDomain as exc:
            why = f"the step to dV/V = {v:.6f} without jiggle left the physical domain"
            return None, None, False, f"{why}: {exc.reason}"
        shape = classify(state.X, run.faces).shape
        shows = wanted(shape)
        ended = not rec["converged"] or (shows and _jump(record, rec, V0 * (v - last)))
        walk.append({"dV_over_V": v, "shape": shape, "shows_event": shows, "ends": ended,
                     "E_total": rec["E_total"], "pressure": rec["pressure"],
                     "converged": rec["converged"]})
        return state, rec, ended, None

    for end in (min(hi + 0.5 * step, reach), reach):
        state, rec, ended, failure = follow(end)
        if failure is not None:
            return found(mechanism="undetermined", failure=failure)
        if ended:
            break
        X, record, last = state.X, rec, end
    else:
        return found(mechanism="barrier crossing")
    failed = {}
    while end - last > max(tol, BRANCH_END_RTOL * end):
        mid = 0.5 * (last + end)
        state, rec, ended, failure = follow(mid)
        if failure is not None:
            failed = {"failure": f"{failure}; the end bracketed to [{last:.6f}, {end:.6f}] only"}
            break
        if ended:
            end = mid
        else:
            X, record, last = state.X, rec, mid
    anticipation = 1.0 - located_at / (0.5 * (last + end))
    branch = found(end_lo=last, end_hi=end, anticipation=anticipation, **failed,
                   mechanism="instability" if anticipation <= ANTICIPATION
                   else "barrier crossing")
    return branch | {"ended_by": ended_by(branch)}


def _eigenvalue_zero(v_start: float, lowest_start: float, v_old: float,
                     lowest_old: float) -> float | None:
    """Where the old branch's lowest eigenvalue, extrapolated linearly from ``v_start`` (the
    bracket's start, or the stored step before it when the bracket's lower end did not move)
    to its last old state ``v_old``, reaches zero: ``v_old`` itself if it is not positive
    there, None if it does not fall or without two old states and eigenvalues. An estimate,
    not a test: near a fold the eigenvalue falls like a square root and the line reaches zero
    late (the mechanism is found by :func:`_old_branch`)."""
    if not (math.isfinite(v_start) and math.isfinite(lowest_start)
            and math.isfinite(lowest_old)) or v_old <= v_start:
        return None
    if lowest_old <= 0:
        return v_old
    slope = (lowest_old - lowest_start) / (v_old - v_start)
    if slope >= 0:
        return None
    return float(v_old - lowest_old / slope)
