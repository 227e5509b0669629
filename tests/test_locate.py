"""Located bifurcations: the lowest eigenvalue of the constrained Hessian against a dense
computation, and the primary buckling of a gamma = 271 icosphere located by bisection within
its tolerance, between the energy crossing and the classical threshold, on the old branch."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as la

from shellbuckle import theory
from shellbuckle.analysis.collect import collect_runs, threshold_points
from shellbuckle.analysis.events import events, thresholds
from shellbuckle.analysis.classify import classify
from shellbuckle.cli import main
from shellbuckle import locate as locate_mod
from shellbuckle.locate import _eigenvalue_zero, _old_branch, located, locate
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.protocol import deflate as protocol_mod
from shellbuckle.protocol.stored import stored_context
from shellbuckle.run import deflate
from shellbuckle.solve.gauge import free_dofs
from shellbuckle.solve.spectrum import lowest_eigenvalues, multiplier
from shellbuckle.store.located import LOCATED_JSON

GAMMA = 271.0
TOL = 1e-4


@pytest.fixture(scope="module")
def params():
    return ShellParameters.from_gamma(GAMMA, nu=1 / 3)


@pytest.fixture(scope="module")
def runs(tmp_path_factory, params):
    """The same deflation without and with location (a small jiggle: the sphere branch holds
    part of the way into the bracket, so the bisection moves both ends)."""
    base = tmp_path_factory.mktemp("locate")
    kwargs = dict(until=0.22, temperature=0.01, seed=0, threads=1)
    plain = deflate(icosphere(8), params, out=base / "plain", locate=False, **kwargs)
    found = deflate(icosphere(8), params, out=base / "located", locate_tol=TOL, **kwargs)
    return plain, found


def test_lowest_eigenvalues_equal_the_dense_constrained_spectrum(params):
    mesh = icosphere(4)
    ctx, state = protocol_mod.init(mesh, params, protocol_mod.Protocol.paper(until=0.1),
                                   threads=1)
    state, record = protocol_mod.step(ctx, state)
    X = state.X
    free = free_dofs(X.size, ctx.pinned)
    lam = multiplier(ctx.energy, ctx.volume, X, free)
    assert lam == pytest.approx(-record["pressure"], rel=1e-6)
    K = sum(ctx.energy.hessian_terms(X)) - lam * ctx.volume.hessian(X)
    K = K.toarray()[np.ix_(free, free)]
    tangent = la.null_space(ctx.volume.gradient(X).ravel()[free][None, :])
    dense = la.eigvalsh(tangent.T @ K @ tangent)[:3]
    assert lowest_eigenvalues(ctx.energy, ctx.volume, X, ctx.pinned, k=3) == \
        pytest.approx(dense, rel=1e-8, abs=1e-10)


def test_primary_buckling_is_located_within_tol_between_crossing_and_classical(runs, params):
    _, run = runs
    points = located(run)
    assert set(points) == {"primary_buckling"}
    p = points["primary_buckling"]
    k = p["step"]
    table = run.table.set_index("step")
    assert table.loc[k - 1, "dV_over_V"] <= p["lo"] < p["hi"] <= table.loc[k, "dV_over_V"]
    assert p["hi"] - p["lo"] <= TOL
    assert p["complete"] and p["lo"] < p["dV_over_V"] < p["hi"]
    assert p["uncertainty"] == pytest.approx((p["hi"] - p["lo"]) / 2)
    assert p["old"]["shape"] == "sphere" and p["new"]["shape"] != "sphere"
    assert theory.crossing(params) < p["lo"]
    assert p["hi"] < theory.classical_threshold(params).dV_over_V_exact
    # the bisection moved both ends: the sphere branch held inside the original step
    assert len(p["evaluations"]) == 8
    assert any(e["shows_event"] for e in p["evaluations"])
    assert not all(e["shows_event"] for e in p["evaluations"])
    # the old branch is still a proper minimum at the located point ...
    assert p["old"]["lowest_eigenvalue"] > 0 and p["old"]["inertia"] == 0


def test_the_located_point_lies_on_the_sphere_branch_just_before_its_end(runs):
    """On this mesh the sphere branch ends 0.002-0.005 after the located point: the step made
    without any jiggle (no help over a barrier) keeps the sphere at the located bracket's upper
    end and at 0.194, and loses it at 0.197, within one step after the bracket. The jiggled
    step buckles where the sphere is still a proper minimum, 1-3 % before the branch ends: an
    instability that the jiggle anticipates, which the location finds by following the branch
    itself (the two-point extrapolation of the lowest eigenvalue puts its zero a step later,
    near 0.24: near a fold the eigenvalue falls like a square root)."""
    from shellbuckle.locate import StepFromStored

    _, run = runs
    p = located(run)["primary_buckling"]
    k = p["step"]
    step = p["step_dV_over_V"] - run.table.set_index("step").loc[k - 1, "dV_over_V"]
    step_to = StepFromStored(run, k)

    def shape_without_jiggle(v):
        return step_to.shape(v, jiggle=False)

    assert shape_without_jiggle(p["lo"]) == "sphere"
    assert shape_without_jiggle(p["hi"]) == "sphere"  # the sphere branch goes on
    assert shape_without_jiggle(p["hi"] + step) != "sphere"
    # where the branch ends, 0.002-0.005 after the located point (docs/analysis.md)
    assert shape_without_jiggle(0.194) == "sphere"
    assert shape_without_jiggle(0.197) != "sphere"
    assert p["hi"] < 0.194 < 0.197 < p["lo"] + step
    assert p["old"]["lowest_eigenvalue"] > 0
    # the location's own walk along the branch found its end there, within a step of where
    # the steps without jiggle from the stored start (another path) find it
    branch = p["old_branch"]
    assert p["mechanism"] == "instability"
    assert 0.194 - 0.0015 <= branch["end_lo"] < branch["end_hi"] <= 0.197 + 0.0015
    assert branch["end_hi"] - branch["end_lo"] <= 0.01 * branch["end_hi"]
    walk = branch["evaluations"]
    assert all(e["ends"] for e in walk if not e["converged"])  # no minimum: no branch
    # the walk made again from the bracket's old end: the same states to the last bit, its
    # last state at end_lo a converged sphere and a proper minimum (the branch holds there),
    # and end_hi a step that ended it
    state, record = step_to(p["lo"])
    X = state.X
    for e in walk:
        state, rec = step_to(e["dV_over_V"], jiggle=False, start=(X, record))
        assert rec["E_total"] == e["E_total"] and rec["converged"] == e["converged"]
        if not e["ends"]:
            X, record = state.X, rec
    assert record["dV_over_V"] == pytest.approx(branch["end_lo"], abs=1e-12)
    assert record["converged"] and classify(X, run.faces).shape == "sphere"
    ctx = step_to.ctx
    lowest = lowest_eigenvalues(ctx.energy, ctx.volume, X, ctx.pinned, k=1)[0]
    # a proper minimum, and nearer the fold than the located point: the branch's lowest
    # eigenvalue falls towards zero along it
    assert 0 < lowest < 0.5 * p["old"]["lowest_eigenvalue"], (lowest, p["old"])
    assert [e["ends"] for e in walk if e["dV_over_V"] == branch["end_hi"]] == [True]
    middle = 0.5 * (branch["end_lo"] + branch["end_hi"])
    assert branch["anticipation"] == pytest.approx(1 - p["dV_over_V"] / middle)
    assert 0.005 < branch["anticipation"] < 0.03
    assert p["eigenvalue_zero_at"] > p["hi"] + step


def test_located_point_lies_on_the_old_branch(runs):
    """The energy and pressure of the last old state follow the sphere branch of the stored
    steps (a quadratic through the three steps before the bracket, extrapolated into it)."""
    _, run = runs
    p = located(run)["primary_buckling"]
    assert p["lo"] > run.table.set_index("step").loc[p["step"] - 1, "dV_over_V"]  # moved
    before = run.table[run.table["step"].between(p["step"] - 3, p["step"] - 1)]
    dv = before["dV_over_V"].to_numpy()
    for column, key in (("E_total", "E_total"), ("pressure", "pressure")):
        fit = np.polyfit(dv, before[column].to_numpy(), 2)
        assert p["old"][key] == pytest.approx(np.polyval(fit, p["lo"]), rel=1e-3)
    # and the new branch is far below it in pressure (the snap-through)
    assert p["new"]["pressure"] < 0.6 * p["old"]["pressure"]


def test_the_bisection_is_the_step_from_the_stored_step(runs):
    """Every evaluation starts from the stored step before the event: the located bracket is
    that of an independent bisection of the protocol's step from that stored step (the oracle),
    and the last old state equals that step made to the bracket's lower end."""

    _, run = runs
    p = located(run)["primary_buckling"]
    k = p["step"]
    table = run.table.set_index("step")
    ctx = stored_context(run, 1)
    start = (run.positions(k - 1), run.store.record(k - 1))

    def step_to(v):
        schedule = list(ctx.protocol.schedule)
        schedule[k - 1] = v
        at = dataclasses.replace(ctx, protocol=dataclasses.replace(ctx.protocol,
                                                                   schedule=tuple(schedule)))
        return protocol_mod.step(at, protocol_mod.state_after(k - 1, *start))

    lo, hi = table.loc[k - 1, "dV_over_V"], table.loc[k, "dV_over_V"]
    while hi - lo > TOL:
        mid = 0.5 * (lo + hi)
        buckled = classify(step_to(mid)[0].X, run.faces).shape != "sphere"
        lo, hi = (lo, mid) if buckled else (mid, hi)
    assert (p["lo"], p["hi"]) == (lo, hi)
    assert lo > table.loc[k - 1, "dV_over_V"]  # the lower end moved: its state is a new step
    assert p["old"]["E_total"] == step_to(lo)[1]["E_total"]


def test_the_step_from_the_stored_step_remakes_the_stored_step(runs):
    """StepFromStored to the stored volume of step k is the run's own step k, to the bit; made
    without its jiggle it is another minimization that stays on the sphere branch."""
    from shellbuckle.locate import StepFromStored

    _, run = runs
    k = located(run)["primary_buckling"]["step"]
    step_to = StepFromStored(run, k - 1)
    table = run.table.set_index("step")
    state, record = step_to(table.loc[k - 1, "dV_over_V"])
    assert np.array_equal(state.X, run.positions(k - 1))
    assert record["E_total"] == table.loc[k - 1, "E_total"]
    quiet, quiet_record = step_to(table.loc[k - 1, "dV_over_V"], jiggle=False)
    assert not np.array_equal(quiet.X, state.X)
    assert quiet_record["E_total"] == pytest.approx(record["E_total"], rel=1e-8)
    with pytest.raises(ValueError, match="no stored step before it"):
        StepFromStored(run, 0)
    with pytest.raises(ValueError, match="not in the schedule"):
        StepFromStored(run, len(run.protocol.schedule) + 1)


def test_a_run_not_located_has_the_same_table(runs):
    plain, found = runs
    assert not (plain.path / LOCATED_JSON).exists() and (found.path / LOCATED_JSON).exists()
    a, b = plain.table.drop(columns="wall_s"), found.table.drop(columns="wall_s")
    assert "shape" in b and "shape" not in a  # the location stored the steps' classes
    assert a.equals(b[a.columns])
    assert (plain.positions(-1) == found.positions(-1)).all()


def test_thresholds_and_collect_use_located_values(runs):
    plain, found = runs
    p = located(found)["primary_buckling"]
    stepped = {e.name: e for e in events(found, located=False)}["primary_buckling"]
    assert stepped.dV_over_V == found.table.set_index("step").loc[p["step"], "dV_over_V"]
    assert thresholds(found)["primary_buckling"] == p["dV_over_V"]
    assert thresholds(plain)["primary_buckling"] == stepped.dV_over_V
    df = collect_runs([plain.path, found.path])
    by_name = df.set_index("name")
    assert by_name.loc["located", "located"] and not by_name.loc["plain", "located"]
    assert by_name.loc["located", "primary_resolution"] == pytest.approx(p["hi"] - p["lo"])
    assert by_name.loc["plain", "primary_resolution"] == pytest.approx(0.019)
    pts = threshold_points(df[df["name"] == "located"], "primary")
    assert pts["resolution"].iloc[0] <= TOL


def test_location_is_kept_reproducible_and_recovers_from_damage(runs, caplog):
    _, run = runs
    first = located(run)
    again = locate(run, tol=TOL, threads=1, again=True)
    assert again["primary_buckling"]["dV_over_V"] == first["primary_buckling"]["dV_over_V"]
    assert again["primary_buckling"]["old"]["E_total"] == first["primary_buckling"]["old"]["E_total"]
    # a coarser request keeps the finer stored point without any evaluation
    kept = locate(run, tol=10 * TOL, threads=1)
    assert kept["primary_buckling"]["wall_s"] == again["primary_buckling"]["wall_s"]
    (run.path / LOCATED_JSON).write_text("{not json")
    assert located(run) == {}
    assert "cannot be read" in caplog.text
    assert thresholds(run)["primary_buckling"] == events(run, located=False)[0].dV_over_V
    redone = locate(run, tol=TOL, threads=1)
    assert redone["primary_buckling"]["dV_over_V"] == first["primary_buckling"]["dV_over_V"]
    stored = json.loads((run.path / LOCATED_JSON).read_text())
    assert stored["version"] == 2
    # a file of the bisection that advanced its start is not used, and is located again
    (run.path / LOCATED_JSON).write_text(json.dumps(stored | {"version": 1}))
    caplog.clear()
    assert located(run) == {}
    assert "advanced its start" in caplog.text
    redone = locate(run, tol=TOL, threads=1)["primary_buckling"]
    assert redone["lo"] == first["primary_buckling"]["lo"]
    assert json.loads((run.path / LOCATED_JSON).read_text())["version"] == 2
    # a point whose old branch was followed through a step that did not converge (as the walk
    # did before such a step ended it) is located again
    stored = json.loads((run.path / LOCATED_JSON).read_text())
    walk = stored["events"]["primary_buckling"]["old_branch"]["evaluations"]
    next(e for e in walk if not e["ends"])["converged"] = False
    (run.path / LOCATED_JSON).write_text(json.dumps(stored))
    again = locate(run, tol=TOL, threads=1)["primary_buckling"]
    assert again["wall_s"] != redone["wall_s"] and again["lo"] == redone["lo"]
    assert all(e["ends"] or e["converged"] for e in again["old_branch"]["evaluations"])


def test_locate_command(runs, capsys):
    _, run = runs
    assert main(["locate", str(run.path), "--threads", "1"]) == 0
    out = capsys.readouterr().out
    assert "primary_buckling" in out and "sphere -> capsule" in out
    assert main(["locate", str(run.path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["primary_buckling"]["step"] == \
        located(run)["primary_buckling"]["step"]


@pytest.mark.parametrize("argv, fragment", [
    (["--tol", "0"], "--tol 0: allowed"),
    (["--tol", "1e-9"], "--tol 1e-9: allowed"),
    (["--tol", "abc"], "--tol abc: not a number"),
])
def test_locate_refuses_bad_tolerances(runs, argv, fragment, capsys):
    _, run = runs
    before = (run.path / LOCATED_JSON).read_bytes()
    assert main(["locate", str(run.path), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0]
    assert (run.path / LOCATED_JSON).read_bytes() == before


def test_eigenvalue_zero_extrapolates_the_lowest_eigenvalue_linearly():
    # lambda falls from 1.0 at 0.10 to 0.2 at 0.18: zero at 0.20
    assert _eigenvalue_zero(0.10, 1.0, 0.18, 0.2) == pytest.approx(0.20)
    assert _eigenvalue_zero(0.10, 0.5, 0.18, 0.6) is None  # rising: no zero ahead
    assert _eigenvalue_zero(0.18, 0.5, 0.18, 0.6) is None  # one old state only
    assert _eigenvalue_zero(0.10, 0.5, 0.18, -0.1) == 0.18  # already unstable


class _Branch:
    """A stand-in for the step from a stored state: the old branch (a sphere at pressure 2,
    its energy the pressure's work) ends at ``end`` with a jump of the pressure to 1; from
    ``turns`` on it is classified ``polygonal`` without a jump; a step to a volume in the
    interval ``leaves_domain`` leaves the physical domain. The conformation is the volume
    reached. Records each call (volume, jiggle, the start's volume)."""

    ctx = type("Ctx", (), {"V0": 1.0})()

    def __init__(self, end, leaves_domain=None, turns=None, stalls=None):
        self.end, self.leaves, self.turns, self.calls = end, leaves_domain, turns, []
        self.stalls = stalls  # an interval where a minimization does not converge

    def ended(self, v):
        return self.end is not None and v >= self.end

    def shape(self, v):
        if self.ended(v):
            return "capsule"
        return "polygonal" if self.turns is not None and v >= self.turns else "sphere"

    def __call__(self, v, *, jiggle=True, start=None):
        self.calls.append((v, jiggle, float(start[0][0])))
        if self.leaves is not None and self.leaves[0] <= v < self.leaves[1]:
            raise locate_mod.LeftDomain(3, "a test")
        state = protocol_mod.state_after(3, np.array([v]), {})
        if self.ended(v):
            return state, {"E_total": 2.0 * v - 0.5, "pressure": 1.0, "converged": True}
        converged = self.stalls is None or not self.stalls[0] <= v < self.stalls[1]
        return state, {"E_total": 2.0 * v, "pressure": 2.0, "converged": converged}


def _follow(monkeypatch, branch, lo=0.0076, hi=0.0077, step=0.019, tol=1e-4):
    monkeypatch.setattr(locate_mod, "classify", lambda X, faces: dataclasses.make_dataclass(
        "C", ["shape"])(branch.shape(X[0])))
    start = (np.array([lo]), {"E_total": 2.0 * lo, "pressure": 2.0})
    return _old_branch(branch, lambda shape: shape != "sphere", type("R", (), {"faces": None})(),
                       start, lo, hi, step, tol)


@pytest.mark.parametrize("end, mechanism", [
    (0.0149, "barrier crossing"),   # ends between hi + step / 2 and hi + step
    (0.0120, "barrier crossing"),   # ends before hi + step / 2
    (0.0080, "instability"),        # ends 4 % after the located point
    (None, "barrier crossing"),     # goes on past the step
])
def test_old_branch_follows_the_branch_without_jiggle_and_brackets_its_end(monkeypatch, end,
                                                                          mechanism):
    lo, hi, step, tol = 0.0076, 0.0077, 0.019, 1e-4
    branch = _Branch(end)
    found = _follow(monkeypatch, branch, lo, hi, step, tol)
    assert found["mechanism"] == mechanism and "failure" not in found
    # every step without jiggle, each from the furthest state found on the old branch
    reached = lo
    for v, jiggle, start in branch.calls:
        assert jiggle is False and start == reached
        if not branch.ended(v):
            reached = max(reached, v)
    assert found["followed_to"] == reached
    assert len(found["evaluations"]) == len(branch.calls)
    if end is None:
        assert found["followed_to"] == pytest.approx(hi + step) and found["end_lo"] is None
        return
    assert found["end_lo"] < end <= found["end_hi"] and found["ended_by"] == "jump"
    assert found["end_hi"] - found["end_lo"] <= max(tol, 0.01 * found["end_hi"])
    located_at = 0.5 * (lo + hi)
    assert found["anticipation"] == pytest.approx(
        1 - located_at / (0.5 * (found["end_lo"] + found["end_hi"])))
    assert abs(found["anticipation"] - (1 - located_at / end)) < 0.02


def test_old_branch_is_followed_far_enough_to_tell_an_instability(monkeypatch):
    """A short step (0.001 at dV/V 0.1): one step past the located point is short of where an
    end 10 % later would be; the walk goes there, and finds the end at 0.109 (8 % after)."""
    branch = _Branch(0.109)
    found = _follow(monkeypatch, branch, lo=0.1, hi=0.1001, step=0.001, tol=1e-4)
    assert max(v for v, _, _ in branch.calls) > 0.1 / 0.9
    assert found["mechanism"] == "instability"
    assert found["end_lo"] < 0.109 <= found["end_hi"]
    gone_on = _follow(monkeypatch, _Branch(None), lo=0.1, hi=0.1001, step=0.001, tol=1e-4)
    assert gone_on["mechanism"] == "barrier crossing"
    assert gone_on["followed_to"] >= 0.10005 / 0.9  # the 10 % line, passed on the branch


def test_old_branch_turning_class_without_a_jump_goes_on(monkeypatch):
    """The old branch crosses the classifier's line continuously at 0.012 (same pressure, the
    energy its work): no end there; it ends at 0.020 with a jump."""
    branch = _Branch(0.020, turns=0.012)
    found = _follow(monkeypatch, branch)
    assert found["end_lo"] < 0.020 <= found["end_hi"]
    assert any(e["shows_event"] and not e["ends"] for e in found["evaluations"])
    assert found["mechanism"] == "barrier crossing"


def test_old_branch_that_leaves_the_domain(monkeypatch):
    # before an end is bracketed: undetermined
    found = _follow(monkeypatch, _Branch(None, leaves_domain=(0.02, 1.0)))
    assert found["mechanism"] == "undetermined" and "left the physical domain" in found["failure"]
    assert found["followed_to"] == pytest.approx(0.0077 + 0.0095)
    # inside the bisection of the end: the bracket had so far is kept, and the failure said
    found = _follow(monkeypatch, _Branch(0.0149, leaves_domain=(0.0120, 0.0130)))
    assert found["end_lo"] < 0.0149 <= found["end_hi"] and "only" in found["failure"]
    assert found["mechanism"] == "barrier crossing"


def test_old_branch_ends_where_no_minimum_is_found(monkeypatch):
    """From 0.0120 on the minimizations stall (a sphere, not converged: near a fold the
    lowest eigenvalue vanishes): the certified branch ends there, 0.0149's jump is not reached,
    and the walk's last state is a converged one."""
    branch = _Branch(0.0149, stalls=(0.0120, 0.0149))
    found = _follow(monkeypatch, branch)
    assert found["end_lo"] < 0.0120 <= found["end_hi"] and "failure" not in found
    assert found["ended_by"] == "no minimum"
    assert found["end_hi"] - found["end_lo"] <= 0.01 * found["end_hi"]
    walk = found["evaluations"]
    assert all(e["ends"] for e in walk if not e["converged"])
    assert any(not e["converged"] and e["shape"] == "sphere" for e in walk)
    reached = [e for e in walk if e["dV_over_V"] == found["end_lo"]]
    assert len(reached) == 1 and reached[0]["converged"] and not reached[0]["ends"]
    # each step starts from the last converged state
    last = 0.0076
    for v, _, start in branch.calls:
        assert start == last
        if not branch.ended(v) and not branch.stalls[0] <= v < branch.stalls[1]:
            last = max(last, v)


def test_an_unconverged_evaluation_stops_the_bisection(runs, tmp_path, monkeypatch):
    """The third evaluation of the bisection does not converge: the bisection stops there,
    keeps the bracket made of converged ends, and says so."""
    import shutil

    from shellbuckle.locate import StepFromStored, locate

    plain, found = runs
    copy = Path(shutil.copytree(plain.path, tmp_path / "plain"))
    real, calls = StepFromStored.__call__, []

    def third_stalls(self, v, *, jiggle=True, start=None):
        state, record = real(self, v, jiggle=jiggle, start=start)
        if jiggle:
            calls.append(v)
            if len(calls) == 3:
                record = dict(record, converged=False)
        return state, record

    monkeypatch.setattr(StepFromStored, "__call__", third_stalls)
    point = locate(copy, tol=TOL, threads=1)["primary_buckling"]
    full = located(found)["primary_buckling"]
    assert not point["complete"] and "did not converge" in point["failure"]
    assert len(point["evaluations"]) == 3 and not point["evaluations"][-1]["converged"]
    assert all(e["converged"] for e in point["evaluations"][:2])
    # the bracket of the first two evaluations, which holds the full location's bracket
    assert point["lo"] <= full["lo"] < full["hi"] <= point["hi"]
    table = plain.table.set_index("step")
    k = point["step"]
    width = table.loc[k, "dV_over_V"] - table.loc[k - 1, "dV_over_V"]
    assert point["hi"] - point["lo"] == pytest.approx(width / 4, rel=1e-9)
    assert calls[2] not in (point["lo"], point["hi"])


def test_jump_compares_the_energy_difference_with_the_pressure_work():
    from shellbuckle.locate import _jump

    old = {"pressure": 50.0, "E_total": 70.0}
    dV = 1e-3
    # on one branch: E rises by the work p dV of the pressure
    assert not _jump(old, {"pressure": 50.2, "E_total": 70.0 + 50.1 * dV}, dV)
    # a snap-through: the pressure halves
    assert _jump(old, {"pressure": 25.0, "E_total": 70.0 + 40 * dV}, dV)
    # the same pressure, but the energy off the branch by half the work
    assert _jump(old, {"pressure": 50.0, "E_total": 70.0 + 75.0 * dV}, dV)


def test_run_figure_marks_the_located_events_and_splits_the_energy(runs):
    from shellbuckle.plots.run import plot_deflation

    _, run = runs
    p = located(run)["primary_buckling"]
    fig = plot_deflation(run)
    ax_e, ax_p = fig.axes[0], fig.axes[1]
    lines = {ln.get_gid(): ln for ln in ax_e.get_lines() + ax_p.get_lines() if ln.get_gid()}
    table = run.table
    bend, stretch = lines["E_bend"].get_ydata(), lines["E_stretch"].get_ydata()
    assert bend + stretch == pytest.approx(table["E_over_kappa"].to_numpy(), rel=1e-12)
    marks = [ln for ln in ax_p.get_lines() if ln.get_gid() == "located_primary_buckling"]
    assert len(marks) == 1
    x, y = marks[0].get_data()
    p_c = theory.classical_threshold(run.params).pressure
    assert list(x) == [p["dV_over_V"]] * 2
    assert y == pytest.approx([p["old"]["pressure"] / p_c, p["new"]["pressure"] / p_c])
    # the strip: one band per step after the first, in the colour of its class
    strip = next(ax for ax in fig.axes if ax.get_ylabel() == "shape")
    bands = [patch for patch in strip.patches if (patch.get_gid() or "").startswith("shape_")]
    assert len(bands) == len(table) - 1


def test_locate_command_takes_several_runs_and_study_folders(runs, tmp_path, capsys):
    import shutil

    plain, found = runs
    study = tmp_path / "study"
    shutil.copytree(plain.path, study / "a")
    shutil.copytree(found.path, study / "b")
    assert main(["locate", str(study), "--threads", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert {Path(k).resolve() for k in out} == {(study / "a").resolve(), (study / "b").resolve()}
    # the copy of the run made without location now has the same located point as the other
    a, b = located(study / "a"), located(found)
    assert a["primary_buckling"]["dV_over_V"] == b["primary_buckling"]["dV_over_V"]
    # a folder that holds no run is refused before any work, in one line
    (tmp_path / "empty").mkdir()
    assert main(["locate", str(study / "a"), str(tmp_path / "empty")]) == 2
    assert "empty" in capsys.readouterr().err


def test_locate_command_waits_for_another_process_locating_the_run(runs, tmp_path, capsys,
                                                                    caplog):
    import logging
    import shutil
    import threading

    from shellbuckle.run import deflate as make_run
    from shellbuckle.store.atomic import FileLock
    from shellbuckle.store.names import LOCATING_LOCK

    plain, found = runs
    study = tmp_path / "study"
    shutil.copytree(plain.path, study / "a")
    # a run whose events cannot be located (a fixed budget of gradient steps): named on
    # stderr, so that --json's stdout stays one JSON document
    make_run(icosphere(3), plain.params, out=study / "gd", until=0.04, method="gd", max_iter=3,
             c0_cycle=False, locate=False, threads=1, progress=False)
    other = FileLock(study / "a" / LOCATING_LOCK)
    assert other.acquire()

    class Releases(logging.Handler):  # the other process finishes once this one waits
        def emit(self, record):
            if "waiting for it" in record.getMessage():
                threading.Timer(0.5, other.release).start()

    handler = Releases()
    logging.getLogger("shellbuckle.store.located").addHandler(handler)
    try:
        with caplog.at_level("WARNING"):
            assert main(["locate", str(study), "--threads", "1", "--json"]) == 0
    finally:
        logging.getLogger("shellbuckle.store.located").removeHandler(handler)
        other.release()
    captured = capsys.readouterr()
    assert "another process is locating the events of" in caplog.text
    assert "waiting for it" in caplog.text
    assert "gd: not located: its minimizer is 'gd'" in captured.err
    out = json.loads(captured.out)
    assert [Path(k).name for k in out] == ["a"]
    assert located(study / "a")["primary_buckling"]["lo"] == \
        located(found)["primary_buckling"]["lo"]


@pytest.mark.slow
def test_the_sphere_branch_without_imperfection_ends_at_the_same_volume_on_two_meshes(
        tmp_path, params):
    """Without any imperfection the located primary buckling is the end of the sphere branch
    itself (the walk past it finds the end at once: anticipation ~ 0), a property of the
    shell: the same to the bisection's 1e-4 on 642 and 2562 vertices (0.1945), below the
    thin-shell classical threshold (0.2155, continuous mode number; at gamma = 271 the
    buckling mode has degree about 4) by less than 10 %."""
    ends = []
    for n in (8, 16):
        run = deflate(icosphere(n), params, out=tmp_path / f"ico{n}", until=0.25,
                      temperature=0.0, seed=0, threads=1, locate_tol=TOL)
        p = located(run)["primary_buckling"]
        branch = p["old_branch"]
        assert p["mechanism"] == "instability" and abs(branch["anticipation"]) < 0.01
        assert branch["end_lo"] - TOL <= p["dV_over_V"] <= branch["end_hi"]
        ends.append(p["dV_over_V"])
    assert ends[1] == pytest.approx(ends[0], abs=TOL)
    classical = theory.classical_threshold(params).dV_over_V_exact
    assert 0.9 * classical < ends[1] < classical


def test_the_printed_line_says_where_the_old_branch_ends():
    from shellbuckle.commands._output import _old_branch_text

    ends = {"followed_to": 0.0764, "end_lo": 0.0764, "end_hi": 0.0770,
            "anticipation": 1 - 0.07285 / 0.0767}
    assert _old_branch_text(ends) == (" (the old branch without jiggle ends at 0.0767; the "
                                      "located point is 5 % of that volume short of it)")
    assert _old_branch_text({"followed_to": 0.0267, "end_lo": None, "end_hi": None}) == \
        " (the old branch without jiggle goes on past 0.0267)"
    failed = _old_branch_text({"followed_to": 0.0172, "end_lo": None, "end_hi": None,
                               "failure": "the step to dV/V = 0.026700 ... left"})
    assert failed.startswith(" (the old branch without jiggle reached 0.0172; the step")
    assert _old_branch_text(None) == ""


def test_a_stored_point_is_located_again_only_for_its_own_unconverged_evaluations():
    """A bracket end that is the run's own stored step (never moved by an evaluation) is the
    run's, converged or not: such a point is kept. An unconverged evaluation inside the
    bisection, or ending a complete one, or a walk step that went on from one, is not."""
    from shellbuckle.locate import _ends_converged, ended_by

    run_end = {"old": {"converged": True}, "new": {"converged": False}, "complete": False,
               "evaluations": [{"converged": False}], "old_branch": None}
    assert _ends_converged(run_end)
    inside = dict(run_end, evaluations=[{"converged": False}, {"converged": True}])
    assert not _ends_converged(inside)
    completed = dict(run_end, complete=True)
    assert not _ends_converged(completed)
    walk = [{"dV_over_V": 0.1, "converged": False, "ends": False}]
    assert not _ends_converged(dict(run_end, old_branch={"evaluations": walk}))
    # what ended a walk stored before it was recorded: read from its step at end_hi
    older = {"end_hi": 0.2, "evaluations": [{"dV_over_V": 0.2, "converged": False,
                                              "ends": True}]}
    assert ended_by(older) == "no minimum"
    assert ended_by(dict(older, evaluations=[dict(older["evaluations"][0], converged=True)])) \
        == "jump"
    assert ended_by({"end_hi": None}) is None
