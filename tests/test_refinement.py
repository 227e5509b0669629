"""The mesh-refinement study: Richardson extrapolation, E/kappa at a fixed dV/V, and the
whole ``shellbuckle refine`` command on tiny meshes.

Oracles: synthetic sequences q(h) = q0 + c h^p whose limit and order are known; the stored
table value at a stored step; the thresholds and W that ``collect_runs`` reads from the same
run folders, and E/kappa interpolated here with NumPy from each run's table.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from shellbuckle import theory
from shellbuckle.analysis.collect import collect_runs
from shellbuckle.cli import main as cli_main
from shellbuckle.locate import located
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.run import Run
from shellbuckle.store.run import RunStore
from shellbuckle.studies import refinement
from shellbuckle.studies.refinement import energy_at, mean_edge, richardson, rim_amplitude_at
from shellbuckle.studies.transfer import (check_same_shell, locate_directions,
                                          material_interpolation, transfer)


@pytest.mark.parametrize("q0, c, p", [(0.25, 1.3, 2.0), (7.0, -0.4, 1.0), (-3.0, 2.0, 1.5),
                                      (0.6, 0.05, 3.2)])
@pytest.mark.parametrize("vertices", [(3594, 10_000, 40_000), (300, 600, 2000, 9000)])
def test_richardson_recovers_limit_and_order_of_a_power_law(q0, c, p, vertices):
    h = mean_edge(vertices)  # unequal ratios between the meshes
    fit = richardson(h, q0 + c * h ** p)
    assert fit.method == "fitted"
    assert fit.order == pytest.approx(p, rel=1e-9)
    assert fit.value == pytest.approx(q0, rel=1e-9, abs=1e-12)
    assert fit.c == pytest.approx(c, rel=1e-7)


@pytest.mark.parametrize("q0, c", [(0.25, 1.3), (-2.0, -5.0)])
def test_two_meshes_with_assumed_order_2_are_exact_for_p_2(q0, c):
    h = mean_edge([3594, 10_000])
    fit = richardson(h, q0 + c * h ** 2)
    assert fit.method == "assumed" and fit.order == 2.0
    assert fit.value == pytest.approx(q0, rel=1e-12)
    assert "assumed" in fit.describe()


def test_a_sequence_that_is_not_monotone_or_diverges_is_not_extrapolated():
    h = mean_edge([3594, 10_000, 40_000])
    assert richardson(h, [1.0, 2.0, 1.5]).method == "not converged"
    assert richardson(h, [1.0, 1.1, 1.5]).method == "not converged"  # increments grow
    assert math.isnan(richardson(h, [1.0, 2.0, 1.5]).value)
    assert richardson(h, [math.nan] * 3).method == "no value"
    assert richardson(h, [math.nan, 1.0, math.nan]).method == "one mesh"
    # a missing coarse value leaves two meshes: the assumed order
    assert richardson(h, [math.nan, 1.0, 1.2]).method == "assumed"
    # a missing value between two meshes that have it (the paper reading's wrinkle onset at
    # gamma 2333: 0.778 on 3594 vertices, none before contact on 10000, 0.611 on 40000), or on
    # the finest mesh, is no sequence
    for q in ([0.778, math.nan, 0.611], [1.0, 1.2, math.nan], [1.0, 1.1, math.nan, 1.2],
              [math.nan, 1.0, math.nan, 2.0]):
        h4 = mean_edge([3594, 10_000, 40_000, 160_000][:len(q)])
        fit = richardson(h4, q)
        assert fit.method == "gap" and math.isnan(fit.value)
        assert "no value on a finer mesh" in fit.describe()
    # the order of the meshes given does not matter; a mesh of unknown size is left out
    h3 = mean_edge([3594, 10_000, 40_000])
    assert richardson(h3[::-1], [0.611, math.nan, 0.778]).method == "gap"
    fit = richardson(h3[::-1], [1.2, 1.1, 1.0])
    assert fit == richardson(h3, [1.0, 1.1, 1.2]) and fit.method == "fitted"
    assert richardson([*h3[:2], math.nan], [1.0, 1.1, math.nan]).method == "assumed"


@pytest.mark.parametrize("p", [0.1, 0.3, 0.45])
def test_a_sequence_whose_increments_barely_shrink_is_not_extrapolated(p):
    # an exact power law of order below MIN_ORDER: its fit would land far beyond the data (the
    # paper reading's wrinkle onset at gamma 29160, 0.055 -> 0.049 -> 0.041 on 3594 / 10000 /
    # 40000 vertices, "fitted" an order 0.17 and a negative dV/V)
    h = mean_edge([3594, 10_000, 40_000])
    assert p < refinement.MIN_ORDER
    assert richardson(h, 0.04 + 0.3 * h ** p).method == "not converged"
    assert richardson(h, [0.05511, 0.04887, 0.04127]).method == "not converged"
    fit = richardson(h, 0.04 + 0.3 * h ** (refinement.MIN_ORDER + 0.05))
    assert fit.method == "fitted" and fit.value == pytest.approx(0.04, rel=1e-9)


def test_two_finest_values_within_the_locations_bracket_are_equal():
    h = mean_edge([3594, 10000, 40000])
    q = [0.016143, 0.0162910156, 0.0162910157]  # the two finer in one bisection bracket
    # without a bracket: an increment that vanishes is faster than any order fits, converged
    fit = richardson(h, q)
    assert fit.method == "converged" and fit.value == q[-1] and fit.order == np.inf
    # meshes of nearly one size fit a high order to any sequence: equal increments are not
    # converged
    assert richardson(mean_edge([3594, 3700, 40000]), [1.0, 2.0, 3.0]).method == "not converged"
    fit = richardson(h, q, resolution=7.4e-5)
    assert fit.method == "equal" and fit.value == q[-1]
    assert fit.describe() == "two finest meshes equal within 7.4e-05 (the location's bracket)"
    assert richardson(h, [0.0161, 0.0163, 0.0165], resolution=7.4e-5).method == "fitted"


def test_energy_at_a_stored_step_is_the_stored_value_and_linear_between():
    table = pd.DataFrame({"dV_over_V": [0.0, 0.019, 0.038, 0.057],
                          "E_total": [2.0, 3.0, 5.0, 4.0]})
    kappa = 0.5
    for dv, E in zip(table["dV_over_V"], table["E_total"]):
        assert energy_at(table, kappa, dv) == E / kappa
    assert energy_at(table, kappa, 0.0285) == pytest.approx((3.0 + 5.0) / 2 / kappa)
    assert math.isnan(energy_at(table, kappa, 0.06))


def test_rim_amplitude_at_is_interpolated_and_nan_without_a_rim_on_either_side():
    table = pd.DataFrame({"dV_over_V": [0.038, 0.0, 0.057, 0.019, 0.076, 0.095],
                          "rim_amplitude": [0.08, math.nan, 0.06, math.nan, 0.07, 0.2],
                          "n_dimples": [1, 0, 1, 0, 1, 2]})
    assert rim_amplitude_at(table, 0.057) == 0.06  # a stored step: its value
    assert rim_amplitude_at(table, 0.038) == 0.08  # though the step before has no rim
    assert rim_amplitude_at(table, 0.0665) == pytest.approx(0.065, rel=1e-12)
    assert rim_amplitude_at(table, 0.0475) == pytest.approx(0.07, rel=1e-12)
    assert math.isnan(rim_amplitude_at(table, 0.03))  # between the sphere and the dent
    assert math.isnan(rim_amplitude_at(table, 0.08))  # toward two dents (the largest's rim)
    assert math.isnan(rim_amplitude_at(table, 0.1))  # beyond the run
    assert math.isnan(rim_amplitude_at(table.drop(columns="rim_amplitude"), 0.057))
    # a step without a volume fraction is left out, not every value lost
    with_nan = pd.concat([table, pd.DataFrame({"dV_over_V": [math.nan], "rim_amplitude": [0.5],
                                               "n_dimples": [1]})])
    assert rim_amplitude_at(with_nan, 0.0665) == pytest.approx(0.065, rel=1e-12)


def test_default_amplitude_is_the_papers_jiggle_in_the_resolved_degrees():
    # white noise of std sigma at N vertices: sigma^2 M / N in M = (L+1)^2 - 4 harmonics
    assert refinement.paper_equivalent_amplitude(20) == pytest.approx(
        0.028 * math.sqrt(437 / 3594))
    spec = refinement.study_spec(smooth_degree=6, shape_imperfection_d=0)  # spherical shells
    assert spec.smooth_jiggle == (round(0.028 * math.sqrt(45 / 3594), 5),)
    assert spec.shape_imperfection_d == (None,) and spec.shape_imperfection == (None,)


def test_default_study_is_the_imperfect_shell_without_jiggle():
    # 0.1 of the effective thickness, degrees up to the classical buckling band, no jiggle
    points = refinement.study_spec(gammas=[2333.0], vertices=[3594, 10000]).points()
    assert len(points) == 4
    for p in points:
        g_eff = 2333.0 * (4.0 if p["energy_convention"] == "paper" else 1.0)
        d = math.sqrt(8.0 / g_eff)  # gamma = 8 (R/d)^2 at nu = 1/3
        assert p["shape_imperfection"] == pytest.approx(0.1 * d, rel=1e-12)
        assert p["shape_imperfection_d"] == 0.1
        lc = (math.sqrt(1.0 + 4.0 * math.sqrt(g_eff)) - 1.0) / 2.0
        assert p["shape_degree"] == math.ceil(lc) + 1
        assert p["smooth_jiggle"] == 0.0 and p["smooth_degree"] is None


# --------------------------------------------------------------------------- the command

# spherical shells with a smooth jiggle (the study's default is the imperfect shell)
ARGS = ["--gamma", "271", "--energy-convention", "helfrich", "--vertices", "300,600",
        "--shape-imperfection-d", "0", "--smooth-degree", "6", "--until", "0.3",
        "--workers", "1", "--quiet"]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("refine") / "study"
    assert cli_main(["refine", *ARGS, "--out", str(out)]) == 0
    return out


def test_the_command_writes_the_table_equal_to_the_runs(study):
    for name in (refinement.CSV, refinement.MARKDOWN, refinement.FIGURE):
        assert (study / name).stat().st_size > 0
    table = pd.read_csv(study / refinement.CSV)
    runs = collect_runs([study])
    assert sorted(runs["n_vertices"]) == [300, 600]
    assert (runs["status"] == "finished").all()
    for _, run in runs.iterrows():
        rows = table[table["n_vertices"] == run["n_vertices"]].set_index("quantity")
        for name in ("primary_dV_over_V", "axisymmetry_loss_dV_over_V", "wrinkles_dV_over_V",
                     "W_mean"):
            np.testing.assert_equal(rows.loc[name, "mean"], run[name])
        t = Run.open(run["path"]).table
        for at in refinement.ENERGY_AT:
            dv = t["dV_over_V"].to_numpy(float)
            expected = np.interp(at, dv, t["E_total"].to_numpy(float)) \
                if dv.min() <= at <= dv.max() else math.nan
            np.testing.assert_allclose(rows.loc[refinement.energy_column(at), "mean"],
                                       expected, rtol=1e-12)
        # the sphere branch's end is the one the location found by following it without jiggle
        point = located(run["path"])["primary_buckling"]
        end = rows.loc["primary_branch_end_dV_over_V", "mean"]
        if point["old_branch"]["end_lo"] is None:
            assert math.isnan(end)
        else:
            assert point["old_branch"]["end_lo"] < end < point["old_branch"]["end_hi"]
            assert end > run["primary_dV_over_V"]
    # the branch end's resolution: its bracket's width
    collected = refinement.collect([study], ()).set_index("n_vertices")
    for _, run in runs.iterrows():
        branch = located(run["path"])["primary_buckling"]["old_branch"]
        width = collected.loc[run["n_vertices"], "primary_branch_end_resolution"]
        if branch["end_lo"] is None:
            assert math.isnan(width)
        else:
            assert width == branch["end_hi"] - branch["end_lo"] > 0
    # the rim harmonic inside the dented range: the analysis's own, between the steps around
    at = 0.25
    rims = refinement.collect([study], (at,)).set_index("n_vertices")[refinement.rim_column(at)]
    for _, run in runs.iterrows():
        t = Run.open(run["path"]).table
        assert (t.loc[t["dV_over_V"].between(0.2, 0.3), "n_dimples"] == 1).all()
        expected = np.interp(at, t["dV_over_V"].to_numpy(float),
                             t["rim_amplitude"].to_numpy(float))
        assert np.isfinite(expected)
        np.testing.assert_allclose(rims.loc[run["n_vertices"]], expected, rtol=1e-12)
    primary = table[table["quantity"] == "primary_dV_over_V"]
    assert np.isfinite(primary["mean"]).all()  # gamma = 271 buckles before dV/V = 0.3
    assert (primary["method"] == "order 2 assumed (2 meshes)").all()
    text = (study / refinement.MARKDOWN).read_text()
    assert "primary buckling dV/V" in text and "N = 600" in text
    classical = theory.classical_threshold(ShellParameters.from_gamma(
        271, nu=1 / 3, energy_convention="helfrich")).dV_over_V_exact
    assert ("Classical threshold of the perfect sphere (thin-shell theory, to compare with "
            f"the sphere branch's end): dV/V = {classical:.4g}.") in text
    # gamma = 271 buckles by an instability of the sphere branch (docs/analysis.md): its end
    # is had on both meshes
    ends = table[table["quantity"] == "primary_branch_end_dV_over_V"]
    assert np.isfinite(ends["mean"]).all()


def test_the_default_study_deflates_the_same_imperfect_shell_on_every_mesh(tmp_path):
    # the default: 0.1 effective thickness of shape imperfection up to the classical buckling
    # band (gamma 271: l_c (l_c + 1) = sqrt(271), l_c = 3.59, L = 5), no jiggle
    out = tmp_path / "study"
    assert cli_main(["refine", "--gamma", "271", "--energy-convention", "helfrich",
                     "--vertices", "300,600", "--until", "0.171", "--workers", "1", "--quiet",
                     "--out", str(out)]) == 0
    runs = collect_runs([out])
    assert len(runs) == 2 and (runs["status"] == "finished").all()
    for _, run in runs.iterrows():
        protocol = RunStore.open(run["path"]).meta["protocol"]
        assert protocol["shape_imperfection"] == pytest.approx(
            0.1 * math.sqrt(8.0 / 271.0), rel=1e-12)  # gamma = 8 (R/d)^2 at nu = 1/3
        assert protocol["shape_degree"] == 5 and protocol["smooth_jiggle"] == 0.0
    text = (out / refinement.MARKDOWN).read_text()
    assert "imperfect shell's branch end" in text and "(0.1 d)" in text and "no jiggle" in text
    # both meshes dent (primary at dV/V = 0.14) at the same material point: within 3 degrees
    # at dV/V = 0.171, where the 300-vertex mesh has a mean edge of 13 degrees
    table = refinement.report(out, energy_at_values=(0.171,))
    angle = table[table["quantity"] == refinement.angle_column(0.171)].set_index("n_vertices")
    assert angle.loc[600, "mean"] == 0.0 and 0.0 < angle.loc[300, "mean"] < 3.0
    assert (angle["method"] == "measured to the finest mesh").all()


def test_the_dent_axis_is_a_material_direction():
    # a sphere pushed in around the material direction n (rotated afterwards: blind to it)
    X0 = icosphere(8).X
    n = np.array([1.0, 2.0, -2.0]) / 3.0
    U = X0 / np.linalg.norm(X0, axis=1, keepdims=True)
    X = U * (1.0 - 0.3 * np.clip(U @ n - 0.8, 0.0, None))[:, None]
    axis = refinement.material_dent_axis(X0, X)
    np.testing.assert_allclose(axis, n, atol=0.02)
    c, s_ = math.cos(0.7), math.sin(0.7)
    rotation = np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(refinement.material_dent_axis(X0, X @ rotation.T), axis,
                               atol=1e-12)


def test_running_again_computes_nothing_and_report_only_rebuilds(study, capsys):
    steps = {p: p.stat().st_mtime_ns for p in study.glob("g*/steps/*")}
    (study / refinement.CSV).unlink()
    assert cli_main(["refine", *ARGS, "--out", str(study)]) == 0
    assert {p: p.stat().st_mtime_ns for p in study.glob("g*/steps/*")} == steps
    before = (study / refinement.CSV).read_text()
    (study / refinement.CSV).unlink()
    assert cli_main(["refine", "--report-only", "--out", str(study)]) == 0
    assert (study / refinement.CSV).read_text() == before
    # with the study's options: the report of those runs; with another study's: of none
    assert cli_main(["refine", *ARGS, "--report-only", "--out", str(study)]) == 0
    assert (study / refinement.CSV).read_text() == before
    other = [a if a != "271" else "280" for a in ARGS]  # a slip: refused, the report kept
    assert cli_main(["refine", *other, "--report-only", "--out", str(study)]) == 2
    assert (study / refinement.CSV).read_text() == before


@pytest.mark.parametrize("argv, named", [
    (["--gamma", "271,abc"], "'abc'"),
    (["--vertices", "300"], "--vertices 300"),
    (["--vertices", "300,600", "--gamma", "1e6"], "--vertices 300,600"),
    (["--gamma", "271", "--vertices", "300,600", "--shape-imperfection-d", "0",
      "--smooth-degree", "9"], "--smooth-degree 9"),
    (["--gamma", "271", "--vertices", "300,600", "--shape-imperfection-d", "0"],
     "--vertices 300,600"),  # the smooth jiggle's degree 20
    (["--gamma", "271", "--vertices", "300,600", "--smooth-degree", "6"],
     "--smooth-degree 6"),  # no jiggle on imperfect shells: no degree
    (["--gamma", "271", "--vertices", "300,600", "--shape-degree", "8",
      "--shape-imperfection-d", "0.02"], "--shape-degree 8"),  # 300 vertices resolve L <= 7
    (["--gamma", "271", "--vertices", "300,600", "--shape-degree", "12"],
     "--shape-imperfection-d 0.1 (the default)"),  # its curvature inverts at L = 12
    (["--gamma", "2e5", "--energy-convention", "paper", "--vertices", "40000,80000"],
     "--shape-degree critical (the default)"),  # gives L = 31
    (["--gamma", "2333", "--shape-imperfection-d", "2"], "--shape-imperfection-d 2"),
    (["--shape-degree", "critic"], "--shape-degree: 'critic'"),
    (["--shape-imperfection", "0.001", "--shape-imperfection-d", "0.1"],
     "--shape-imperfection-d 0.1"),
    (["--energy-convention", "helfrich,kirchhoff"], "kirchhoff"),
    (["--smooth-jiggle", "0.5"], "--smooth-jiggle 0.5"),
    (["--until", "0.01"], "--until 0.01"),
    (["--workers", "0"], "--workers 0"),
    (["--seeds", "0-200"], "--seeds 0-200"),
    (["--report-only"], "no study"),
    (["--report-only", "--gamma", "abc"], "--gamma: 'abc'"),
    (["--report-only", "--until=0.01"], "--until 0.01"),
])
def test_bad_input_exits_2_in_one_line_and_creates_nothing(tmp_path, capsys, argv, named):
    out = tmp_path / "study"
    assert cli_main(["refine", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert named in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_a_folder_of_other_runs_is_refused_before_any_work(study, tmp_path, capsys,
                                                           monkeypatch):
    import shutil

    from shellbuckle import sweep as sweep_module

    started = []
    monkeypatch.setattr(sweep_module, "run_sweep", lambda *a, **k: started.append(1))
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("not a sweep")
    assert cli_main(["refine", *ARGS, "--out", str(other)]) == 2
    err = capsys.readouterr().err.strip()
    assert f"--out {other}" in err and "not a shellbuckle sweep" in err
    assert len(err.splitlines()) == 1 and sorted(p.name for p in other.iterdir()) == ["notes.txt"]
    # a study folder whose record names a run of these options with other parameters
    study = shutil.copytree(study, tmp_path / "study")
    sweep = json.loads((study / "sweep.json").read_text())
    name = next(iter(sweep["runs"]))
    sweep["runs"][name]["seed"] = 7
    (study / "sweep.json").write_text(json.dumps(sweep))
    before = (study / "sweep.json").read_text()
    assert cli_main(["refine", *ARGS, "--out", str(study)]) == 2
    err = capsys.readouterr().err.strip()
    assert "other parameters" in err and len(err.splitlines()) == 1
    assert (study / "sweep.json").read_text() == before and not started


def test_a_value_error_of_the_work_is_a_failure_not_bad_input(study, capsys, monkeypatch):
    def fails(*args, **kwargs):
        raise ValueError("a singular matrix in the carry")

    monkeypatch.setattr(refinement, "run_study", fails)
    assert cli_main(["refine", *ARGS, "--out", str(study)]) == 1
    assert "a singular matrix in the carry" in capsys.readouterr().err


def test_a_dent_born_polygonal_is_said_so():
    rows = [("primary_dV_over_V", 3594, 0.0428), ("axisymmetry_loss_dV_over_V", 3594, 0.0428),
            ("primary_dV_over_V", 10000, 0.0429), ("axisymmetry_loss_dV_over_V", 10000, 0.2),
            ("primary_dV_over_V", 40000, math.nan), ("axisymmetry_loss_dV_over_V", 40000,
                                                     math.nan)]
    group = pd.DataFrame(rows, columns=["quantity", "n_vertices", "mean"])
    assert refinement.output._born_polygonal(group, [3594, 10000, 40000]) == [3594]


def test_material_interpolation_samples_the_source_surface_along_each_ray():
    from shellbuckle.mesh import random_sphere
    from shellbuckle.protocol.imperfection import reference_directions

    coarse, fine = random_sphere(300, seed=1), random_sphere(2000, seed=2)
    # at its own material points a mesh gives back its own values
    np.testing.assert_allclose(material_interpolation(coarse.X, coarse.faces, coarse.X,
                                                      reference_directions(coarse.X)),
                               coarse.X, rtol=0, atol=1e-12)
    # at another mesh's: the point of the coarse faceted sphere on the ray in each direction
    p = reference_directions(fine.X)
    q = material_interpolation(coarse.X, coarse.faces, coarse.X, p)
    r = np.linalg.norm(q, axis=1)
    np.testing.assert_allclose(q / r[:, None], p, rtol=0, atol=1e-12)
    R = np.linalg.norm(coarse.X, axis=1).mean()
    assert r.max() <= R * (1 + 1e-12) and r.min() > 0.97 * R
    _, weights = locate_directions(coarse.X, coarse.faces, p)
    assert weights.min() >= -1e-9 and np.allclose(weights.sum(axis=1), 1.0, atol=1e-12)


def test_a_state_of_the_sphere_branch_carried_to_another_mesh_is_its_own_minimum(study):
    # before buckling the minimum at a volume is unique: carried either way and relaxed, a
    # step is the other mesh's own step
    runs = {int(r["n_vertices"]): r["path"] for _, r in collect_runs([study]).iterrows()}
    for source, target in ((300, 600), (600, 300)):
        moved = transfer(runs[source], 1, runs[target])
        own = Run.open(runs[target]).store.record(1)
        assert moved.result.success and moved.result.inertia == 0
        assert moved.dV_over_V == pytest.approx(own["dV_over_V"], abs=1e-14)
        assert moved.E_over_kappa == pytest.approx(own["E_over_kappa"], rel=1e-9)
        assert moved.E_start_over_kappa > moved.E_over_kappa


def test_only_the_same_shell_is_carried(study, tmp_path):
    from shellbuckle.mesh import random_sphere
    from shellbuckle.run import deflate

    path = collect_runs([study])["path"].iloc[0]
    other = deflate(random_sphere(200, seed=0), ShellParameters.from_gamma(300, nu=1 / 3),
                    until=0.019, out=tmp_path / "other", locate=False, threads=1)
    with pytest.raises(ValueError, match="not the same shell: their parameters differ in"):
        check_same_shell(path, other)
    with pytest.raises(ValueError, match="not the same shell"):
        transfer(other, 1, path)
    # the same parameters, with a shape imperfection or another spontaneous curvature
    params = ShellParameters.from_dict(Run.open(path).store.params)
    imperfect = deflate(random_sphere(200, seed=0), params, until=0.019, locate=False,
                        threads=1, shape_imperfection=0.01, shape_degree=4,
                        out=tmp_path / "imperfect")
    with pytest.raises(ValueError, match="their shape imperfections differ"):
        check_same_shell(path, imperfect)
    curved = deflate(random_sphere(200, seed=0), params, until=0.019, locate=False, threads=1,
                     c0=1.5, out=tmp_path / "curved")
    with pytest.raises(ValueError, match="spontaneous curvatures c0 differ"):
        check_same_shell(curved, path)
    check_same_shell(path, path)


def test_the_transfer_command_compares_the_carried_minimum_with_the_targets_own(study,
                                                                               tmp_path,
                                                                               capsys):
    # on the sphere branch the carried minimum is the target's own step (the API's oracle
    # above), so the command's relative energy vanishes both ways; the carried minimum it
    # writes is that state, on the target's mesh
    import json

    import meshio

    from shellbuckle.cli import main

    runs = {int(r["n_vertices"]): r["path"] for _, r in collect_runs([study]).iterrows()}
    out = tmp_path / "carried.vtu"
    assert main(["transfer", str(runs[300]), str(runs[600]), "--step", "1", "--both-ways",
                 "--threads", "1", "--json", "--out", str(out)]) == 0
    there, back = json.loads(capsys.readouterr().out)
    for r in (there, back):
        assert r["certified"] and abs(r["relative"]) < 1e-9
        assert (r["carried"]["shape"], r["carried"]["W"]) == (r["own"]["shape"], r["own"]["W"])
        assert r["start_E_over_kappa"] > r["carried"]["E_over_kappa"]
    mesh, own = meshio.read(out), Run.open(runs[600])
    assert len(mesh.points) == own.store.n_vertices
    edges = own.mesh(1).topology.edges  # the same state up to a rigid motion

    def lengths(X):
        return np.linalg.norm(X[edges[:, 0]] - X[edges[:, 1]], axis=1)

    np.testing.assert_allclose(lengths(mesh.points), lengths(own.positions(1)), rtol=0,
                               atol=1e-7)
    # the table printed for a user says the same
    assert main(["transfer", str(runs[600]), str(runs[300]), "--step", "1",
                 "--threads", "1"]) == 0
    text = capsys.readouterr().out
    assert "a certified minimum" in text and "the same class" in text


def test_the_transfer_command_refuses_before_any_work(study, tmp_path, capsys, monkeypatch):
    from shellbuckle.cli import main
    from shellbuckle.mesh import random_sphere
    from shellbuckle.run import deflate
    from shellbuckle.studies import transfer as transfer_module

    path = str(collect_runs([study])["path"].iloc[0])
    other = deflate(random_sphere(200, seed=0), ShellParameters.from_gamma(300, nu=1 / 3),
                    until=0.019, out=tmp_path / "other", locate=False, threads=1)
    monkeypatch.setattr(transfer_module, "compare", None)  # any work would raise TypeError
    for argv, says in (([path, str(other.path)], "TARGET"),
                       ([path, path, "--out", str(tmp_path / "x.txt")], "--out"),
                       ([path, path, "--step", "99"], "--step 99"),
                       ([path, str(tmp_path / "none")], "TARGET")):
        assert main(["transfer", *argv]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and says in err
    assert not (tmp_path / "x.txt").exists()


def test_a_transfer_that_fails_during_its_work_exits_1(study, capsys, monkeypatch):
    # a ValueError of the work (a singular matrix: NumPy's LinAlgError is one) is no bad input
    from shellbuckle.cli import main
    from shellbuckle.studies import transfer as transfer_module

    def singular(*args, **kwargs):
        np.linalg.solve(np.zeros((2, 2)), np.ones(2))

    monkeypatch.setattr(transfer_module, "compare", singular)
    path = str(collect_runs([study])["path"].iloc[0])
    assert main(["transfer", path, path, "--step", "1"]) == 1
    err = capsys.readouterr().err
    assert err == "shellbuckle transfer: failed: LinAlgError: Singular matrix\n"


def test_a_carried_state_is_minimized_with_blas_on_one_thread(study, monkeypatch):
    # as a step of a run: its numbers do not depend on the machine's cores
    from threadpoolctl import threadpool_info, threadpool_limits

    from shellbuckle.protocol import deflate as deflate_module

    seen, minimize = [], deflate_module._minimize

    def spy(*args, **kwargs):
        seen.extend(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas")
        return minimize(*args, **kwargs)

    monkeypatch.setattr(deflate_module, "_minimize", spy)
    runs = {int(r["n_vertices"]): r["path"] for _, r in collect_runs([study]).iterrows()}
    with threadpool_limits(2, user_api="blas"):  # two BLAS threads around it, as on 2 cores
        transfer(runs[300], 1, runs[600], threads=1)
    assert seen and set(seen) == {1}


def test_states_carried_meanwhile_by_another_process_are_kept(study, tmp_path, monkeypatch):
    # each entry is merged, under the file's lock, with what the file holds when it is written
    import shutil

    out = tmp_path / "study"
    shutil.copytree(study, out)
    theirs = {"source": "elsewhere", "target": "there", "step": 3, "at": 0.019,
              "failed": "RuntimeError: theirs"}

    def meanwhile(source, k, target, threads):  # another process keeps its state first
        refinement.carried._keep(out, "theirs", theirs)
        return {"failed": "RuntimeError: ours", "certified": False}

    monkeypatch.setattr(refinement.carried, "_carried_entry", meanwhile)
    kept = refinement.carry(out, at=0.019)
    assert kept["theirs"] == theirs and len(kept) == 2
    assert refinement.read_carried(out) == kept
    # a state carried meanwhile is not replaced by a failure of the same state here
    done = {**theirs, "certified": True, "own_W": 4, "W": 4, "relative": 0.0}
    del done["failed"]
    refinement.carried._keep(out, "theirs", done)
    assert refinement.carried._keep(out, "theirs", theirs)["theirs"] == done


def test_only_the_studys_finest_mesh_is_carried_to(study):
    runs = refinement.collect([study], ())
    assert len(refinement.carry_pairs(runs, 0.019, finest_vertices=600)) == 1
    assert refinement.carry_pairs(runs, 0.019, finest_vertices=2000) == []  # not run yet


def test_the_report_is_written_when_the_carry_fails(study, tmp_path, monkeypatch):
    import shutil

    from shellbuckle import sweep as sweep_module
    from shellbuckle.studies.refinement import study as study_module

    out = tmp_path / "study"
    shutil.copytree(study, out)
    for name in (refinement.CSV, refinement.MARKDOWN):
        (out / name).unlink()

    def dies(*args, **kwargs):
        raise RuntimeError("a process carrying states to the finest mesh died")

    monkeypatch.setattr(study_module, "carry", dies)
    with pytest.raises(RuntimeError, match="died"):
        refinement.run_study(out, gammas=[271], conventions=["helfrich"], vertices=[300, 600],
                             shape_imperfection_d=0, smooth_degree=6, until=0.3, workers=1,
                             progress=False, carry_states=True)
    assert (out / refinement.CSV).exists() and (out / refinement.MARKDOWN).exists()
    # a damaged record of carried states is refused before any run
    (out / refinement.CARRIED_JSON).write_text("[1, 2]")
    monkeypatch.setattr(sweep_module, "run_sweep", None)  # a run would raise TypeError
    with pytest.raises(RuntimeError, match="move it away"):
        refinement.run_study(out, gammas=[271], conventions=["helfrich"], vertices=[300, 600],
                             carry_states=True)


def test_the_study_carries_each_coarse_state_to_the_finest_mesh_once(study, tmp_path,
                                                                     monkeypatch):
    # on the sphere branch (dV/V = 0.019) the coarse step relaxes on the finest mesh to that
    # mesh's own step: the report's carried W is the finest W, its energy 0 % above; carried
    # states are kept and not computed again
    import shutil

    from shellbuckle.studies import transfer as transfer_module

    out = tmp_path / "study"
    shutil.copytree(study, out)
    kept = refinement.carry(out, at=0.019)
    assert len(kept) == 1
    (entry,) = kept.values()
    assert entry["certified"] and abs(entry["relative"]) < 1e-9
    assert (entry["shape"], entry["W"]) == (entry["own_shape"], entry["own_W"]) == ("sphere", 0)
    assert json.loads((out / refinement.CARRIED_JSON).read_text())["carried"] == kept

    def no_work(*args, **kwargs):
        raise AssertionError("a kept state was carried again")

    monkeypatch.setattr(transfer_module, "compare", no_work)
    assert refinement.carry(out, at=0.019) == kept
    runs = refinement.with_carried(refinement.collect([out]), kept, out, at=0.019)
    table = refinement.refinement_table(runs)
    w_col, e_col = refinement.carried_columns(0.019)
    rows = table[table["quantity"] == w_col].set_index("n_vertices")
    assert rows.loc[300, "mean"] == rows.loc[600, "mean"] == 0
    assert rows["method"].eq("measured to the finest mesh").all()
    dE = table[table["quantity"] == e_col].set_index("n_vertices")["mean"]
    assert abs(dE.loc[300]) < 1e-7 and dE.loc[600] == 0
    # an entry applies only to a target that is the finest mesh of the runs reported
    coarse_only = refinement.collect([out])
    coarse_only = coarse_only[coarse_only["n_vertices"] == 300]
    assert refinement.with_carried(coarse_only, kept, out, at=0.019) is coarse_only
    # the command's report reads them only at its own volume fraction (0.645 here)
    assert cli_main(["refine", *ARGS, "--out", str(out), "--report-only"]) == 0
    assert w_col not in set(pd.read_csv(out / refinement.CSV)["quantity"])


def test_a_state_carried_from_runs_made_again_since_is_carried_again(study, tmp_path,
                                                                     monkeypatch, caplog):
    out = tmp_path / "study"
    shutil.copytree(study, out)
    kept = refinement.carry(out, at=0.019)
    ((key, entry),) = kept.items()
    runs = refinement.collect([out])
    ids = {n: refinement.run_identity(p) for n, p in zip(runs["n_vertices"], runs["path"])}
    assert (entry["source_id"], entry["target_id"]) == (ids[300], ids[600])
    # the record says the state came from another run in the finest mesh's folder (a run made
    # again there since): the report leaves it out, the next carry computes it again
    path = out / refinement.CARRIED_JSON
    data = json.loads(path.read_text())
    data["carried"][key]["target_id"] = "0" * 32
    data["carried"][key]["own_W"] = 7
    path.write_text(json.dumps(data))
    stale = refinement.read_carried(out)
    with caplog.at_level(logging.WARNING):
        assert refinement.with_carried(runs, stale, out, at=0.019) is runs
    assert "carried from runs made again since" in caplog.text
    again = refinement.carry(out, at=0.019)
    assert again[key]["target_id"] == ids[600] and again[key]["own_W"] == 0
    # a run whose id could not be read when it was carried: kept without one, read back
    data["carried"][key]["target_id"] = None
    path.write_text(json.dumps(data))
    assert refinement.read_carried(out, strict=True)[key]["target_id"] is None
    # an entry written before run ids were kept is taken as it is
    del data["carried"][key]["source_id"], data["carried"][key]["target_id"]
    path.write_text(json.dumps(data))
    old = refinement.read_carried(out)
    w_col, _ = refinement.carried_columns(0.019)
    W = refinement.with_carried(runs, old, out, at=0.019).set_index("n_vertices")[w_col]
    assert (W.loc[300], W.loc[600]) == (0, 7)


@pytest.fixture(scope="module")
def two_seeds(study, tmp_path_factory):
    import shutil

    out = tmp_path_factory.mktemp("seeds") / "study"
    shutil.copytree(study, out)
    assert cli_main(["refine", *ARGS, "--seeds", "0,1", "--out", str(out)]) == 0
    return out


def test_states_carried_by_worker_processes_are_those_carried_one_at_a_time(two_seeds,
                                                                           tmp_path,
                                                                           monkeypatch,
                                                                           caplog):
    # two seeds: two pairs, relaxed at once by two processes; the same numbers to the bit as
    # in this process, one after the other; what the workers log is handled here
    import shutil

    from shellbuckle.studies import transfer as transfer_module

    serial, parallel = tmp_path / "serial", tmp_path / "parallel"
    shutil.copytree(two_seeds, serial)
    shutil.copytree(two_seeds, parallel)
    one = refinement.carry(serial, at=0.019, workers=1)
    assert len(one) == 2 and {e["source"].split("_s")[1][0] for e in one.values()} == {"0", "1"}

    def not_here(*args, **kwargs):  # the worker processes import their own
        raise AssertionError("carried in the calling process")

    monkeypatch.setattr(transfer_module, "compare", not_here)
    with caplog.at_level(logging.INFO, logger="shellbuckle"):
        two = refinement.carry(parallel, at=0.019, workers=2)
    assert two == one and all(e["certified"] for e in two.values())
    carrying = [r for r in caplog.records if r.getMessage().startswith("carrying step")]
    assert len(carrying) == 2 and all(r.process != os.getpid() for r in carrying)
    assert {re.search(r"_v300_s(\d)_", r.getMessage())[1] for r in carrying} == {"0", "1"}
    assert json.loads((parallel / refinement.CARRIED_JSON).read_text())["carried"] == one


def test_a_worker_that_dies_stops_the_carry_with_its_reason(two_seeds, tmp_path):
    # killed while it starts (out of memory, a signal): no wait for a state that never comes
    import multiprocessing
    import shutil
    import signal
    import threading

    out = tmp_path / "study"
    shutil.copytree(two_seeds, out)

    before = {child.pid for child in multiprocessing.active_children()}
    done = threading.Event()

    def kill_workers():  # each as soon as it is there (they start one after the other)
        while not done.wait(0.01):
            for child in multiprocessing.active_children():
                if child.pid not in before:
                    try:
                        os.kill(child.pid, signal.SIGKILL)
                    except ProcessLookupError:  # reaped meanwhile
                        pass

    killer = threading.Thread(target=kill_workers)
    killer.start()
    try:
        with pytest.raises(RuntimeError, match="died .exit code -9"):
            refinement.carry(out, at=0.019, workers=2)
    finally:
        done.set()
        killer.join()
    assert {c.pid for c in multiprocessing.active_children()} <= before
    assert refinement.read_carried(out) == {}


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads the processes in /proc")
def test_a_worker_ends_with_a_carry_that_is_killed():
    # a SIGKILL of the calling process leaves its worker, waiting for its next state, to end
    # by itself (SIGKILL runs no clean-up: without the worker's own watch it waits forever)
    import signal
    import subprocess
    import sys
    import time

    code = """if True:
        import multiprocessing, os, time
        from shellbuckle.studies.refinement import carried
        context = multiprocessing.get_context("spawn")
        tasks, results = context.Queue(), context.Queue()
        tasks.put((0, ("/nonexistent", 1, "/nonexistent", 1)))  # fails at once, kept as such
        worker = context.Process(target=carried._carry_worker,
                                 args=(tasks, results, 30, os.getpid()), daemon=True)
        worker.start()
        assert "failed" in results.get(timeout=120)[1]  # it works, and waits for more
        print(worker.pid, flush=True)
        time.sleep(600)
    """
    parent = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        worker = int(parent.stdout.readline())
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait()

    def running(pid):
        try:
            with open(f"/proc/{pid}/stat") as f:
                return f.read().rsplit(")", 1)[1].split()[0] != "Z"
        except OSError:
            return False

    for _ in range(300):  # it looks once a second
        if not running(worker):
            break
        time.sleep(0.1)
    assert not running(worker)


def test_a_failed_carry_is_kept_as_failed_reported_as_no_value_and_tried_again(study, tmp_path,
                                                                                monkeypatch):
    import shutil

    from shellbuckle.protocol.deflate import LeftDomain
    from shellbuckle.studies import transfer as transfer_module

    out = tmp_path / "study"
    shutil.copytree(study, out)
    real = transfer_module.compare

    def fails(*args, **kwargs):
        raise LeftDomain(1, "a face flipped over (test)")

    monkeypatch.setattr(transfer_module, "compare", fails)
    (entry,) = refinement.carry(out, at=0.019).values()
    assert "LeftDomain" in entry["failed"] and not entry["certified"]
    runs = refinement.with_carried(refinement.collect([out]), refinement.read_carried(out),
                                   out, at=0.019)
    assert refinement.carried_columns(0.019).keys().isdisjoint(runs.columns)
    monkeypatch.setattr(transfer_module, "compare", real)
    (entry,) = refinement.carry(out, at=0.019).values()
    assert entry["certified"] and "failed" not in entry


def test_only_steps_near_the_volume_fraction_are_carried_and_only_to_the_finest_mesh(study):
    # the study ends at dV/V = 0.3: no step lies within half a step of 0.645
    runs = refinement.collect([study])
    assert refinement.carry_pairs(runs, 0.645) == []
    ((source, k, target),) = refinement.carry_pairs(runs, 0.2)
    assert Run.open(source).store.n_vertices == 300 and Run.open(target).store.n_vertices == 600
    assert Run.open(source).store.record(k)["dV_over_V"] == pytest.approx(0.2, abs=0.0095)
    # a seed whose finest-mesh run is missing has no target, not the next-coarser mesh
    fake = pd.DataFrame({**{c: [runs[c].iloc[0]] * 3 for c in refinement.GROUP},
                         "seed": [0, 0, 1], "n_vertices": [300, 600, 300],
                         "path": ["a", "b", "c"]})
    assert refinement.carried._finest_runs(fake) == {(*fake.loc[0, refinement.GROUP], 0): "b"}


def test_a_damaged_record_of_carried_states_is_never_written_over(study, tmp_path, caplog):
    import shutil

    out = tmp_path / "study"
    shutil.copytree(study, out)
    entry = {"source": "a", "target": "b", "step": 1, "at": 0.645, "certified": True,
             "own_W": 4, "W": 5, "relative": 0.01}
    assert refinement.carried._entry_problem(entry) is None
    damaged = [{"k": [1, 2]}, {"k": {**entry, "W": None}}, {"k": {**entry, "step": "1"}},
               {"k": {key: v for key, v in entry.items() if key != "own_W"}}]
    for text in ("{\"version\": 1, \"carr", "[1, 2]", '{"version": 99, "carried": {}}',
                 *(json.dumps({"version": 1, "carried": c}) for c in damaged)):
        (out / refinement.CARRIED_JSON).write_text(text)
        with pytest.raises(RuntimeError, match="carried.json: .*move it away"):
            refinement.carry(out, at=0.019)
        assert (out / refinement.CARRIED_JSON).read_text() == text
        caplog.clear()
        assert refinement.read_carried(out) == {}  # the report goes on without them
        assert "left out of the report" in caplog.text


def test_the_report_says_when_the_meshes_have_different_seeds(study):
    runs = refinement.collect([study])
    assert "Seeds differ" not in refinement.markdown(refinement.refinement_table(runs))
    extra = runs[runs["n_vertices"] == 300].assign(seed=1)  # a second seed on one mesh only
    text = refinement.markdown(refinement.refinement_table(pd.concat([runs, extra])))
    assert "Seeds differ between the meshes (N = 300: seeds 0, 1; N = 600: seed 0)" in text
    assert "order 2 assumed (2 meshes), seed 0 |" in text
    # as many seeds on each mesh, other ones: said too
    other = pd.concat([runs[runs["n_vertices"] == 300].assign(seed=1), runs], ignore_index=True)
    other = other[~((other["n_vertices"] == 600) & (other["seed"] == 0))]
    other = pd.concat([other, runs[runs["n_vertices"] == 600].assign(seed=2)],
                      ignore_index=True)
    text = refinement.markdown(refinement.refinement_table(other))
    assert "Seeds differ between the meshes (N = 300: seeds 0, 1; N = 600: seed 2)" in text


def test_the_extrapolation_compares_the_seeds_that_every_mesh_has(study):
    runs = refinement.collect([study])
    # the coarse mesh stands for the paper's, so that its error is reported too
    runs["n_vertices"] = runs["n_vertices"].replace({300: refinement.PAPER_VERTICES})
    coarse, fine = refinement.PAPER_VERTICES, 600
    alone = refinement.refinement_table(runs)
    assert (alone["extrapolation_seeds"] == "0").all()
    primary = alone[alone["quantity"] == "primary_dV_over_V"].set_index("n_vertices")
    assert np.isfinite(primary["paper_mesh_error"]).all()
    # a second seed on the coarse mesh only, far from the first: the columns average it, the
    # extrapolation and the paper mesh's error are those of seed 0 alone, to the bit
    shifted = runs[runs["n_vertices"] == coarse].assign(seed=1)
    for column in ("primary_dV_over_V", refinement.energy_column(0.1)):
        shifted[column] = shifted[column] * 1.5
    both = refinement.refinement_table(pd.concat([runs, shifted], ignore_index=True))
    assert (both["extrapolation_seeds"] == "0").all()
    key = ["quantity", "n_vertices"]
    alone, both = alone.set_index(key).sort_index(), both.set_index(key).sort_index()
    for column in ("extrapolated", "order", "method", "paper_mesh_value", "paper_mesh_error",
                   "compared_mean"):
        pd.testing.assert_series_equal(both[column], alone[column])
    row = both.loc[("primary_dV_over_V", coarse)]
    assert row["n_seeds"] == 2 and row["seeds"] == "0 1" and row["mean"] == pytest.approx(
        1.25 * alone.loc[("primary_dV_over_V", coarse), "mean"], rel=1e-12)
    assert row["paper_mesh_value"] == alone.loc[("primary_dV_over_V", coarse), "mean"]
    # the same seed on both meshes: the common seeds are both, the means those of the columns
    again = pd.concat([runs, runs.assign(seed=1)], ignore_index=True)
    table = refinement.refinement_table(again).set_index(key).sort_index()
    assert (table["extrapolation_seeds"] == "0 1").all()
    pd.testing.assert_series_equal(table["extrapolated"], alone["extrapolated"])
    # no seed on both meshes: each mesh's own seeds, said so
    other = runs[runs["n_vertices"] == fine].assign(seed=1)
    other["primary_dV_over_V"] = other["primary_dV_over_V"] * 1.1
    apart = pd.concat([runs[runs["n_vertices"] == coarse], other], ignore_index=True)
    table = refinement.refinement_table(apart)
    primary = table[table["quantity"] == "primary_dV_over_V"].set_index("n_vertices")
    assert (primary["extrapolation_seeds"] == refinement.OWN_SEEDS).all()
    expected = refinement.richardson(refinement.mean_edge([coarse, fine]),
                                     primary["mean"].loc[[coarse, fine]].to_numpy())
    assert primary["extrapolated"].iloc[0] == expected.value
    assert expected.value != alone.loc[("primary_dV_over_V", coarse), "extrapolated"]
    assert "each mesh's own seeds (none is on every mesh)" in refinement.markdown(table)


def test_a_threshold_a_run_has_not_located_is_not_extrapolated(study, tmp_path):
    runs = refinement.collect([study])
    assert runs["primary_located"].all() and pd.api.types.is_bool_dtype(runs["wrinkles_located"])
    fine = runs.loc[runs["n_vertices"].idxmax(), "path"]
    copy = tmp_path / "unlocated"  # the finer run without its located events
    shutil.copytree(study, copy, ignore=shutil.ignore_patterns("carried*"))
    (copy / Path(fine).relative_to(study) / "located.json").unlink()
    runs = refinement.collect([copy])
    by_n = runs.set_index("n_vertices")
    assert not by_n.loc[600, "primary_located"] and by_n.loc[300, "primary_located"]
    step = Run.open(by_n.loc[600, "path"]).table
    assert by_n.loc[600, "primary_dV_over_V"] in step["dV_over_V"].to_numpy()  # a step's end
    table = refinement.refinement_table(runs)
    primary = table[table["quantity"] == "primary_dV_over_V"]
    assert (primary["method"] == "not located on every mesh (known to the volume step "
                                 "only)").all()
    assert primary["extrapolated"].isna().all() and primary["paper_mesh_error"].isna().all()
    energies = table[table["quantity"] == refinement.energy_column(0.1)]
    assert (energies["method"] == "order 2 assumed (2 meshes)").all()  # not a threshold


def test_a_wrinkle_count_is_not_extrapolated(study):
    runs = refinement.collect([study])
    runs["W_mean"] = np.where(runs["n_vertices"] == 300, 5.0, 4.0)  # 5 folds, then 4
    W = refinement.refinement_table(runs).query("quantity == 'W_mean'")
    assert (W["method"] == "a count: not extrapolated").all()
    assert W["extrapolated"].isna().all()
    assert sorted(W["mean"]) == [4.0, 5.0]


def test_two_runs_of_one_seed_on_one_mesh_are_refused(study):
    runs = refinement.collect([study])
    again = runs[runs["n_vertices"] == 300].assign(path="elsewhere/g271")
    with pytest.raises(ValueError, match=r"two or more runs of seed 0 on 300 vertices "
                                         r"\(helfrich, gamma = 271, .*elsewhere/g271; give the "
                                         "folders of one study"):
        refinement.refinement_table(pd.concat([runs, again], ignore_index=True))


def test_refine_carry_is_not_a_report_only_option(study, capsys):
    assert cli_main(["refine", "--out", str(study), "--report-only", "--carry"]) == 2
    assert "--carry: allowed: without --report-only" in capsys.readouterr().err


def test_rays_between_skinny_triangles_are_located_all_the_same():
    # an unrelaxed random Delaunay sphere: some rays cross a triangle none of whose corners is
    # among the nearest vertices of the ray
    from scipy.spatial import cKDTree

    from shellbuckle.mesh import random_sphere
    from shellbuckle.protocol.imperfection import reference_directions
    from shellbuckle.studies import transfer as module

    coarse, fine = random_sphere(500, seed=3, iterations=0), random_sphere(20000, seed=4,
                                                                           iterations=0)
    U, p = reference_directions(coarse.X), reference_directions(fine.X)
    indptr, face_ids = coarse.topology.vertex_faces_ptr, coarse.topology.vertex_faces
    _, near = cKDTree(U).query(p, k=module.NEAREST)
    first = [np.unique(np.concatenate([face_ids[indptr[v]:indptr[v + 1]] for v in row]))
             for row in near]
    _, w = module._crossings(U, np.asarray(coarse.faces), p, first)
    assert (w.min(axis=1) < -module.INSIDE_TOL).sum() > 0  # missed by the first search
    q = material_interpolation(coarse.X, coarse.faces, coarse.X, p)
    np.testing.assert_allclose(q / np.linalg.norm(q, axis=1)[:, None], p, rtol=0, atol=1e-12)
