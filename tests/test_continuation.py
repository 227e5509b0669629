"""Paths in gamma and c0 at fixed volume: invariances, consistency, resuming, bad input."""

import json
from pathlib import Path

import numpy as np
import pytest

from shellbuckle.analysis import classify
from shellbuckle.cli import main
from shellbuckle.energies.total import ShellEnergy
from shellbuckle.energies.volume import Volume
from shellbuckle.mesh import icosphere
from shellbuckle.mesh.mesh import Mesh
from shellbuckle.params import ShellParameters
from shellbuckle.protocol.deflate import Protocol
from shellbuckle.run import (Run, compare_paths, continue_from, continue_in_parameter, deflate,
                             resume)

from test_run import _compare, kill_9_after_steps  # tables identical but for the wall time

GAMMA0 = 271.0
PARENT = dict(dv=0.03, until=0.27, jiggle=0.02, seed=7)


@pytest.fixture(scope="module")
def parent(tmp_path_factory):
    """A capsule: gamma = 271 deflated past primary buckling on a 162-vertex icosphere."""
    return deflate(icosphere(4), ShellParameters.from_gamma(GAMMA0, nu=1 / 3),
                   out=tmp_path_factory.mktemp("parent") / "run", **PARENT)


@pytest.fixture(scope="module")
def gamma_path(parent, tmp_path_factory):
    return continue_in_parameter(parent, -1, tmp_path_factory.mktemp("path") / "run",
                                 gamma=2333.0, increments=4)


def _volume(run, X):
    return Volume(run.faces, len(X)).value(X)


def _fresh_parts(run, k):
    """Energy of the stored positions of step k, evaluated from scratch at that step's gamma."""
    mesh = Mesh.from_arrays(run.store.X0, run.faces)
    energy = ShellEnergy.build(mesh, run.params_at(k), c0=run.c0_at(k))
    return energy.parts(run.positions(k))


def test_zero_increments_store_the_start_only(parent, tmp_path):
    run = continue_in_parameter(parent, -1, tmp_path / "p", gamma=15163.0, increments=0)
    assert run.steps == [0] and run.status == "finished"
    np.testing.assert_array_equal(run.positions(0), parent.positions(-1))
    E0, E = parent.table["E_total"].iloc[-1], run.table["E_total"].iloc[0]
    assert abs(E - E0) <= 1e-10 * abs(E0)
    assert run.params_at(0).gamma == GAMMA0


@pytest.mark.parametrize("kind", ["gamma", "c0"])
def test_a_path_to_the_same_value_leaves_the_state_unchanged(parent, tmp_path, kind):
    same = {"gamma": GAMMA0} if kind == "gamma" else {"c0": parent.c0_at(-1)}
    run = continue_in_parameter(parent, -1, tmp_path / "p", increments=3, jiggle=0.0,
                                c0_cycle=False, **same)
    E0 = parent.table["E_total"].iloc[-1]
    E = run.table["E_total"].to_numpy()
    assert len(E) == 4
    np.testing.assert_allclose(E, E0, rtol=1e-10, atol=0)
    for k in run.steps:
        assert np.abs(run.positions(k) - parent.positions(-1)).max() < 1e-8


def test_the_stress_free_sphere_stays_a_sphere_at_every_gamma(parent, tmp_path):
    """The rest state is the initial sphere at any gamma: the stretching energy vanishes there
    and only the discretization error of the bending energy remains, the same at every gamma.
    So along the path the energy stays between 0 and that floor (the initial mesh is feasible
    at V0), and the shape stays a sphere."""
    run = continue_in_parameter(parent, 0, tmp_path / "p", gamma=29160.0, increments=3,
                                jiggle=0.0)
    table = run.table
    floor = table["E_total"].iloc[0]
    assert table["E_stretch"].iloc[0] < 1e-20
    assert floor < 1e-2 * 8 * np.pi  # a discretization error, small against 8 pi kappa
    assert ((table["E_total"] >= 0) & (table["E_total"] <= floor * (1 + 1e-12))).all()
    edge = np.linalg.norm(np.diff(run.store.X0[run.faces[:, :2]], axis=1), axis=-1).mean()
    for k in run.steps:
        X = run.positions(k)
        r = np.linalg.norm(X - X.mean(axis=0), axis=1)
        assert np.ptp(r) < 0.1 * edge
        assert classify(X, run.faces).shape == "sphere"
    np.testing.assert_allclose(table["gamma"], GAMMA0 * (29160.0 / GAMMA0) ** (np.arange(4) / 3),
                               rtol=1e-12)


def test_stored_energies_equal_a_fresh_evaluation_at_each_gamma(gamma_path):
    table = gamma_path.table
    expected = GAMMA0 * (2333.0 / GAMMA0) ** (np.arange(5) / 4)  # equal ratios
    np.testing.assert_allclose(table["gamma"], expected, rtol=1e-12)
    for k in gamma_path.steps:
        parts = _fresh_parts(gamma_path, k)
        row = table.iloc[k]
        assert parts["E_stretch"] == pytest.approx(row["E_stretch"], rel=1e-12)
        assert parts["E_bend"] == pytest.approx(row["E_bend"], rel=1e-12)
        assert row["E_total"] == pytest.approx(row["E_stretch"] + row["E_bend"], rel=1e-12)


def test_the_volume_is_held_along_the_path(gamma_path, parent):
    V_start = _volume(parent, parent.positions(-1))
    for k in gamma_path.steps:
        V = _volume(gamma_path, gamma_path.positions(k))
        assert abs(V / V_start - 1) < 1e-12
    protocol = gamma_path.protocol
    assert protocol.control == "gamma"
    assert protocol.fixed_dV_over_V == parent.table["dV_over_V"].iloc[-1]


def test_the_store_describes_the_path(gamma_path, parent):
    meta = gamma_path.store.meta
    assert meta["parent"]["step"] == parent.steps[-1]
    assert meta["parent"]["run_id"] == parent.store.run_id
    path = meta["extra"]["path"]
    assert path["parameter"] == "gamma" and path["increments"] == 4
    assert path["start"] == GAMMA0 and path["end"] == 2333.0
    assert list(meta["protocol"]["schedule"]) == list(gamma_path.table["gamma"].iloc[1:])
    # read back without the package: run.json holds the schedule and the volume held
    raw = json.loads((gamma_path.path / "run.json").read_text())
    assert raw["protocol"]["control"] == "gamma"
    assert raw["protocol"]["fixed_dV_over_V"] == path["fixed_dV_over_V"]


def test_a_c0_path_follows_equal_differences(parent, tmp_path):
    run = continue_in_parameter(parent, -1, tmp_path / "p", c0=1.0, increments=2)
    table = run.table
    np.testing.assert_allclose(table["c0"], [2.0, 1.5, 1.0], rtol=0, atol=1e-15)
    assert (table["gamma"] == GAMMA0).all()
    for k in run.steps:
        parts = _fresh_parts(run, k)
        assert parts["E_bend"] == pytest.approx(table["E_bend"].iloc[k], rel=1e-12)
    # continuing in volume afterwards keeps the c0 reached
    after = continue_from(run, -1, tmp_path / "v", dv=0.03, until=0.3)
    assert after.protocol.c0 == 1.0 and after.c0_at(-1) == 1.0


def test_deflating_after_a_gamma_path_uses_the_final_gamma(gamma_path, tmp_path):
    after = continue_from(gamma_path, -1, tmp_path / "v", dv=0.03, until=0.33)
    assert after.params.gamma == 2333.0 and after.protocol.control == "volume"
    assert after.table["E_total"].iloc[0] == gamma_path.table["E_total"].iloc[-1]
    parts = _fresh_parts(after, after.steps[-1])
    assert parts["E_stretch"] == pytest.approx(after.table["E_stretch"].iloc[-1], rel=1e-12)


def test_compare_paths_reports_the_energy_ratio(gamma_path, parent):
    same = compare_paths(gamma_path, -1, gamma_path, -1)
    assert same["ratio"] == 1.0 and same["same_parameters"] and not same["differences"]
    result = compare_paths(gamma_path, -1, parent, -1)
    Ea, Eb = gamma_path.table["E_total"].iloc[-1], parent.table["E_total"].iloc[-1]
    assert result["ratio"] == pytest.approx(Eb / Ea, rel=1e-15)
    assert not result["same_parameters"] and "gamma" in result["differences"][0]
    assert result["a"]["gamma"] == 2333.0 and result["b"]["gamma"] == GAMMA0
    assert result["a"]["shape"] in ("capsule", "polygonal", "wrinkled", "dimples", "other")


_CHILD = """
import sys
from shellbuckle.run import continue_in_parameter
continue_in_parameter(sys.argv[1], -1, sys.argv[2], gamma=2333.0, increments=6)
"""


def test_kill_9_then_resume_gives_the_same_table(parent, tmp_path):
    whole = continue_in_parameter(parent, -1, tmp_path / "whole", gamma=2333.0, increments=6)
    out = tmp_path / "killed"
    kill_9_after_steps([_CHILD, str(parent.path), str(out)], out)
    before = Run.open(out).steps
    assert before == list(range(len(before))) and len(before) >= 1
    done = resume(out)
    _compare(done.table, whole.table)
    # calling the same continuation again reopens the finished run and recomputes nothing
    again = continue_in_parameter(parent, -1, out, gamma=2333.0, increments=6)
    _compare(again.table, whole.table)


def test_old_volume_protocols_keep_their_stored_form():
    """Runs stored before parameter paths existed have no fixed_dV_over_V in run.json; a
    volume protocol must serialize without it so that they still resume."""
    protocol = Protocol.paper(dv=0.03, until=0.3)
    assert "fixed_dV_over_V" not in protocol.to_dict()
    assert Protocol.from_dict(protocol.to_dict()) == protocol


@pytest.mark.parametrize("kwargs, fragment", [
    (dict(gamma=0.0, increments=2), "positive"),
    (dict(gamma=-5.0, increments=2), "positive"),
    (dict(gamma=[500.0, -1.0]), "gamma"),
    (dict(gamma=float("nan"), increments=2), "finite"),
    (dict(gamma=500.0), "increments"),
    (dict(gamma=500.0, increments=-1), "increments"),
    (dict(gamma=500.0, c0=1.0, increments=2), "exactly one"),
    (dict(increments=2), "exactly one"),
])
def test_bad_input_is_refused_before_anything_is_written(parent, tmp_path, kwargs, fragment):
    with pytest.raises(ValueError, match=fragment):
        continue_in_parameter(parent, -1, tmp_path / "x", **kwargs)
    assert not (tmp_path / "x").exists()


def test_a_step_not_in_the_run_is_refused(parent, tmp_path):
    with pytest.raises(ValueError, match="not a finished step"):
        continue_in_parameter(parent, 99, tmp_path / "x", gamma=500.0, increments=2)
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("argv, fragment", [
    (["--gamma", "-3", "--increments", "2"], "--gamma -3: allowed: a number in [1, 1e11]"),
    (["--gamma", "500"], "increments"),
    (["--gamma", "300:500", "--increments", "2"], "starts at"),
    (["--gamma", "abc", "--increments", "2"], "must be a number"),
    (["--step", "99", "--gamma", "500", "--increments", "2"], "not a finished step"),
])
def test_cli_bad_input_exits_2(parent, tmp_path, capsys, argv, fragment):
    code = main(["continue", str(parent.path), *argv, "--out", str(tmp_path / "x"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and fragment in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()


def test_cli_path_then_deflation_and_comparison(parent, tmp_path, capsys):
    out = tmp_path / "path"
    code = main(["continue", str(parent.path), "--gamma", f"{GAMMA0:g}:2333", "--increments",
                 "2", "--then-deflate-to", "0.33", "--dv", "0.03", "--out", str(out),
                 "--compare", str(parent.path), "--compare-step", "3", "--json", "--quiet"])
    assert code == 0
    text = capsys.readouterr().out
    result = json.loads(text[text.index("{"):])
    deflated = Run.open(f"{out}_deflated")
    # the volume part has the figures of a run, the path in gamma (fixed dV/V) has none
    assert {p.name for p in Path(deflated.path).glob("*.png")} == {"deflation.png", "pv.png"}
    assert not list(out.glob("*.png"))
    assert deflated.params.gamma == 2333.0
    assert deflated.table["dV_over_V"].iloc[-1] == pytest.approx(0.33, abs=1e-12)
    Ea, Eb = deflated.table["E_total"].iloc[-1], parent.table["E_total"].iloc[3]
    assert result["ratio"] == pytest.approx(Eb / Ea, rel=1e-12)
