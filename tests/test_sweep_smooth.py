"""Sweeps with the smooth imperfection as axes: the grid, the names, the exclusivity with the
per-vertex jiggle, old sweep folders resuming unchanged, and the value reaching the run.

Oracles: a sweep point and a ``sweep.json`` written by hand in the layout documented in
:mod:`shellbuckle.store.catalogue` before the smooth axes existed; the run folder's
``run.json`` read with json only.
"""

from __future__ import annotations

import json

import pytest

from shellbuckle.cli import main as cli_main
from shellbuckle.store.catalogue import SWEEP_JSON, write_sweep_file
from shellbuckle.sweep import SweepSpec, run_point

#: A point of the default sweep as sweep.json held it before the smooth axes.
OLD_POINT = {"gamma": 2333.0, "nu": 1 / 3, "seed": 0, "mesh": "random", "n_vertices": 3594,
             "icosphere": None, "dv": 0.019, "until": 0.95, "c0_cycle": True, "jiggle": None,
             "temperature": 0.05, "bending": "juelicher", "method": "newton",
             "energy_convention": "helfrich", "tol": 1e-9, "max_iter": 200,
             "stop_at_contact": True}
OLD_SPEC = {"gamma": [2333.0], "nu": [1 / 3], "seeds": [0], "vertices": [3594], "icosphere": [],
            "dv": [0.019], "until": [0.95], "c0_cycle": [True], "jiggle": [None],
            "temperature": [0.05], "bending": ["juelicher"], "method": ["newton"],
            "energy_convention": ["helfrich"], "tol": 1e-9, "max_iter": 200,
            "stop_at_contact": True}


def test_unset_smooth_axes_leave_points_and_description_as_before():
    spec = SweepSpec()
    (point,) = spec.points()
    assert {k: v for k, v in point.items() if k != "name"} == OLD_POINT
    assert point["name"] == "g2333_nu0.333_v3594_s0"
    assert spec.to_dict() == OLD_SPEC


def test_an_old_sweep_folder_resumes_with_its_description_unchanged(tmp_path):
    out = tmp_path / "old"
    out.mkdir()
    name = "g2333_nu0.333_v3594_s0"
    (out / SWEEP_JSON).write_text(json.dumps({
        "format": "shellbuckle-sweep", "format_version": 1, "created": "2024-01-01T00:00:00",
        "updated": "2024-01-01T00:00:00", "specs": [OLD_SPEC], "runs": {name: OLD_POINT}}))
    spec = SweepSpec()
    data = write_sweep_file(out, spec.to_dict(),
                            {p["name"]: {k: v for k, v in p.items() if k != "name"}
                             for p in spec.points()})
    assert data["specs"] == [OLD_SPEC] and data["runs"] == {name: OLD_POINT}


def test_smooth_axes_make_one_run_per_amplitude_and_degree_named_by_them():
    spec = SweepSpec(gamma=271, vertices=[300, 600], smooth_jiggle=[0.01, 0.02],
                     smooth_degree=[4, 6])
    points = spec.points()
    assert len(points) == len(spec) == 2 * 2 * 2
    for p in points:
        assert p["jiggle"] is None and p["temperature"] is None
        assert p["name"].endswith(f"_sj{p['smooth_jiggle']:g}_L{p['smooth_degree']}")
    assert {(p["n_vertices"], p["smooth_jiggle"], p["smooth_degree"]) for p in points} == {
        (n, a, L) for n in (300, 600) for a in (0.01, 0.02) for L in (4, 6)}
    assert spec.to_dict()["smooth_jiggle"] == [0.01, 0.02]


def test_none_among_the_amplitudes_adds_the_per_vertex_runs():
    names = [p["name"] for p in SweepSpec(gamma=271, vertices=300,
                                          smooth_jiggle=[None, 0.01]).points()]
    assert names == ["g271_nu0.333_v300_s0", "g271_nu0.333_v300_s0_sj0.01"]


@pytest.mark.parametrize("bad, named", [
    (dict(smooth_jiggle=0.01, temperature=0.1), "not both"),
    (dict(smooth_jiggle=0.01, jiggle=0.1), "not both"),
    (dict(smooth_degree=6), "give it with smooth_jiggle"),
    (dict(smooth_jiggle=0.2), "smooth_jiggle = 0.2"),
    (dict(smooth_jiggle=0.01, smooth_degree=1), "smooth_degree = 1"),
    (dict(smooth_jiggle=0.01, smooth_degree=401), "smooth_degree = 401"),
])
def test_bad_smooth_axes_are_refused_by_name(bad, named):
    with pytest.raises(ValueError, match=named):
        SweepSpec(**bad)


@pytest.mark.parametrize("argv, named", [
    (["--smooth-jiggle", "0.5"], "--smooth-jiggle 0.5"),
    (["--smooth-jiggle", "0.01", "--vertices", "300"], "--smooth-jiggle 0.01"),
    (["--smooth-jiggle", "0.01", "--smooth-degree", "9", "--vertices", "300"],
     "--smooth-degree 9"),
])
def test_cli_bad_smooth_input_exits_2_before_any_work(tmp_path, capsys, argv, named):
    out = tmp_path / "sweep"
    assert cli_main(["sweep", "--gamma", "271", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert named in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_the_smooth_imperfection_reaches_the_run(tmp_path):
    (point,) = SweepSpec(gamma=271, icosphere=3, until=0.019, smooth_jiggle=0.004,
                         smooth_degree=3).points()
    result = run_point(point, tmp_path, analyze=False)
    assert result["outcome"] == "finished", result
    protocol = json.loads((tmp_path / point["name"] / "run.json").read_text())["protocol"]
    assert protocol["smooth_jiggle"] == 0.004 and protocol["smooth_degree"] == 3
    assert protocol["jiggle"] is None and protocol["temperature"] is None
