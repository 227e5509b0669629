"""Collecting runs into one table: consistency with what each Run reports, a scripted run with
known wrinkles, and the aggregation (per-gamma averages, fits, W pooling) on hand-made tables
with known answers.

The tiny real runs (162-vertex icosphere, a few volume steps) are built once per session and
shared with the plot and report tests (:func:`tiny_runs`)."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from shellbuckle.analysis import analyze_run, thresholds
from shellbuckle.analysis.collect import (COLUMNS, collect_runs, load_reference, mesh_kind,
                                          reference_path, threshold_fits, threshold_points,
                                          wrinkles_by_gamma)
from shellbuckle.analysis.fits import fit_power_law, wrinkle_average
from shellbuckle.mesh.icosphere import icosphere
from shellbuckle.mesh.random_sphere import random_sphere
from shellbuckle.params import ShellParameters
from shellbuckle.run import Run, deflate
from shellbuckle.store import RunStore
from shellbuckle.store.catalogue import Catalogue, write_sweep_file

from test_analysis_events import _conformation
from test_analysis_shapes import mesh

_BUILT: dict = {}

# (conformation, dV/V, pressure): the wrinkled steps fall in the W window [0.53, 0.76]
SCRIPT = [("sphere", 0.0, 0.0), ("sphere", 0.1, 10.0), ("sphere", 0.2, 20.0),
          ("cap40", 0.3, 8.0),                        # primary buckling (60 % pressure drop)
          ("cap50", 0.4, 7.5), ("poly4", 0.5, 7.4),   # loss of axisymmetry at 0.5
          ("poly4", 0.55, 7.3), ("wrinkled6", 0.6, 7.2),  # wrinkles at 0.6
          ("wrinkled6", 0.65, 7.1), ("wrinkled5", 0.7, 7.0), ("wrinkled5", 0.75, 6.9),
          ("wrinkled6", 0.8, 6.8)]
SCRIPT_W = np.array([6, 6, 5, 5], float)           # the wrinkled steps inside the window


def _scripted(path):
    m = mesh("random")
    with RunStore.create(path, params={"gamma": 1000.0, "nu": 1 / 3},
                         protocol={"seed": 3, "c0_cycle": True}, X0=m.X,
                         faces=m.faces) as store:
        for k, (name, dv, p) in enumerate(SCRIPT):
            store.append_step(k, _conformation(name, m.X, k),
                              {"dV_over_V": dv, "pressure": p, "E_stretch": 1.0, "E_bend": 1.0,
                               "wall_s": 0.5})
    return path


def _build(root):
    sweep = root / "sweep"
    a = sweep / "g300_s0"
    write_sweep_file(sweep, {"test": "tiny"}, {"g300_s0": {"gamma": 300.0, "seed": 0},
                                                "never_started": {"gamma": 300.0, "seed": 9}})
    runs = {"a": a, "b": root / "g300_s1", "c": root / "g3000_s0"}
    for (gamma, seed), out in zip([(300, 0), (300, 1), (3000, 0)], runs.values()):
        # not located: the location stores the steps' classes, and these runs must have none
        deflate(icosphere(4), ShellParameters.from_gamma(gamma, nu=1 / 3), dv=0.08, until=0.48,
                seed=seed, out=out, locate=False)
    analyze_run(runs["c"])          # stored analysis for one run, computed for the others
    runs["scripted"] = _scripted(root / "scripted")
    runs["sweep"] = sweep
    return runs


@pytest.fixture(scope="session")
def tiny_runs(tmp_path_factory):
    """Three real runs (gamma 300 seeds 0 and 1, gamma 3000), the first inside a sweep folder,
    and a scripted run with known events and W."""
    if "runs" not in _BUILT:
        _BUILT["runs"] = _build(tmp_path_factory.mktemp("tiny_runs"))
    return _BUILT["runs"]


def test_collected_rows_match_each_run(tiny_runs):
    df = collect_runs([tiny_runs["sweep"], tiny_runs["b"], tiny_runs["c"]])
    assert list(df.columns) == list(COLUMNS)
    assert len(df) == 3                               # the pending sweep run has no folder
    for key in ("a", "b", "c"):
        run = Run.open(tiny_runs[key])
        row = df[df["path"] == str(run.path.resolve())].iloc[0]
        table = run.table
        assert row["gamma"] == run.params.gamma and row["nu"] == run.params.nu
        assert row["seed"] == run.protocol.seed
        for name in ("jiggle", "temperature"):   # None in the protocol -> NaN
            value = getattr(run.protocol, name, None)
            assert row[name] == pytest.approx(math.nan if value is None else value, nan_ok=True)
        assert bool(row["c0_cycle"]) == run.protocol.c0_cycle
        assert row["n_vertices"] == len(run.positions(0)) == 162
        assert row["n_steps"] == run.steps[-1]
        assert row["stop_dV_over_V"] == table["dV_over_V"].iloc[-1]
        assert row["status"] == run.status
        assert row["wall_s"] == pytest.approx(table["wall_s"].sum())
        assert row["dv"] == pytest.approx(0.08) and row["until"] == pytest.approx(0.48)
        expected = thresholds(run)   # the analysis module, independently of collect
        for name, column in (("primary_buckling", "primary_dV_over_V"),
                             ("axisymmetry_loss", "axisymmetry_loss_dV_over_V"),
                             ("wrinkles", "wrinkles_dV_over_V")):
            assert row[column] == pytest.approx(expected[name], nan_ok=True)
    assert set(df["mesh"]) == {"icosphere(4)"}


def test_collect_does_not_write_unless_asked(tiny_runs, tmp_path):
    run_b = Run.open(tiny_runs["b"])
    assert "shape" not in run_b.table.columns   # nothing stored by the previous collect
    df = collect_runs(tiny_runs["b"])
    assert df["analysis"].iloc[0] == "computed"
    assert "shape" not in Run.open(tiny_runs["b"]).table.columns
    assert collect_runs(tiny_runs["c"])["analysis"].iloc[0] == "stored"


def test_sweep_rows_agree_with_the_catalogue(tiny_runs):
    analyze_run(tiny_runs["a"])
    catalogue = Catalogue.load(tiny_runs["sweep"]).set_index("name")
    row = collect_runs(tiny_runs["sweep"]).iloc[0]
    cat = catalogue.loc["g300_s0"]
    assert row["primary_dV_over_V"] == pytest.approx(cat["primary_dV_over_V"])
    assert row["stop_dV_over_V"] == pytest.approx(cat["final_dV_over_V"])
    assert row["n_steps"] == cat["steps"] and row["status"] == cat["status"]


def test_scripted_run_known_events_and_W(tiny_runs):
    tables = {}
    row = collect_runs(tiny_runs["scripted"], tables=tables).iloc[0]
    assert row["primary_dV_over_V"] == pytest.approx(0.3)
    assert row["axisymmetry_loss_dV_over_V"] == pytest.approx(0.5)
    assert row["wrinkles_dV_over_V"] == pytest.approx(0.6)
    assert row["W_steps"] == len(SCRIPT_W)
    assert row["W_mean"] == pytest.approx(SCRIPT_W.mean())
    assert row["W_std"] == pytest.approx(SCRIPT_W.std())
    assert math.isnan(row["dv"])                      # no schedule recorded
    table = tables[row["path"]]
    assert wrinkle_average(table) == (row["W_mean"], row["W_std"], row["W_steps"])


def test_parent_folder_of_runs_and_sweeps(tiny_runs):
    # the tiny_runs root holds two runs, the scripted run and the sweep folder
    root = tiny_runs["b"].parent
    df = collect_runs(root)
    assert sorted(df["name"]) == ["g3000_s0", "g300_s0", "g300_s1", "scripted"]


def test_bad_paths(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        collect_runs(tmp_path / "missing")
    with pytest.raises(ValueError, match="neither a run folder"):
        collect_runs(tmp_path)
    (tmp_path / "file.txt").write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        collect_runs(tmp_path / "file.txt")
    with pytest.raises(ValueError, match="no run folder"):
        collect_runs([])


def test_mesh_kind():
    assert mesh_kind(icosphere(5).faces, icosphere(5).n_vertices) == "icosphere(5)"
    m = random_sphere(252, seed=0)
    assert mesh_kind(m.faces, m.n_vertices) == "random"


# --------------------------------------------------------------------------- aggregation

def frame(rows):
    """A collect_runs-like frame from (gamma, seed, primary, axisym, wrinkles, W_mean, W_std,
    W_steps) tuples, with the deflation protocol."""
    cols = ["gamma", "seed", "primary_dV_over_V", "axisymmetry_loss_dV_over_V",
            "wrinkles_dV_over_V", "W_mean", "W_std", "W_steps"]
    df = pd.DataFrame(rows, columns=cols)
    df["nu"] = 1 / 3
    df["control"] = "volume"
    df["parent"] = None
    df["c0_cycle"] = True
    df["n_steps"] = 40
    df["dv"] = 0.019
    return df


def test_threshold_fits_recover_laws_from_seed_averages():
    gammas = [300.0, 1000.0, 3000.0, 10000.0]
    rows = []
    for g in gammas:
        p, s = 2.8 * g ** -0.55, 850.0 / g
        for seed, d in enumerate((-0.02, 0.0, 0.02)):      # means exactly on the laws
            rows.append((g, seed, p + d, s + 2 * d if g >= 1000 else np.nan,
                         s + d if g >= 1000 else np.nan, np.nan, np.nan, 0))
    df = frame(rows)
    # a run with another protocol must not enter the fits
    df.loc[len(df)] = df.iloc[0]
    df.loc[len(df) - 1, ["c0_cycle", "primary_dV_over_V"]] = [False, 0.9]
    fits = threshold_fits(df)
    assert fits["primary"].prefactor == pytest.approx(2.8, rel=1e-9)
    assert fits["primary"].exponent == pytest.approx(-0.55, abs=1e-9)
    assert fits["secondary"].prefactor == pytest.approx(850.0, rel=1e-9)
    assert fits["secondary_free"].exponent == pytest.approx(-1.0, abs=1e-9)
    assert fits["primary_theory"].exponent == -0.6
    # weights: sample std over seeds, floored at dv / sqrt(12)
    pts = threshold_points(df, "primary")
    assert list(pts["n"]) == [3, 3, 3, 3]
    assert pts["std"].to_numpy() == pytest.approx(np.full(4, 0.02))
    assert pts["sigma"].to_numpy() == pytest.approx(np.full(4, 0.02))
    independent = fit_power_law(gammas, [2.8 * g ** -0.55 for g in gammas], sigma=[0.02] * 4)
    assert fits["primary"].exponent_err == pytest.approx(independent.exponent_err, rel=1e-9)
    assert fits["primary"].weighted


def test_threshold_fits_with_one_gamma_skip_free_exponents(caplog):
    df = frame([(2333.0, 0, 0.08, 0.40, 0.45, 6.0, 0.5, 4)])
    with caplog.at_level("INFO"):
        fits = threshold_fits(df)
    assert "primary" not in fits and "secondary_free" not in fits
    assert fits["secondary"].prefactor == pytest.approx(2333.0 * math.sqrt(0.40 * 0.45))
    assert "needs thresholds at 2 gamma" in caplog.text


def test_single_runs_fit_unweighted_and_sigma_floor():
    df = frame([(300.0, 0, 0.12, np.nan, np.nan, np.nan, np.nan, 0),
                (3000.0, 0, 0.035, np.nan, np.nan, np.nan, np.nan, 0),
                (3000.0, 1, 0.035, np.nan, np.nan, np.nan, np.nan, 0)])
    pts = threshold_points(df, "primary")
    assert math.isnan(pts["sigma"].iloc[0])
    assert pts["sigma"].iloc[1] == pytest.approx(0.019 / math.sqrt(12))   # std 0 -> floor
    fit = threshold_fits(df)["primary"]
    assert not fit.weighted
    assert fit.exponent == pytest.approx(math.log(0.035 / 0.12) / math.log(10.0))


def test_wrinkles_pooled_over_runs_equal_pooling_the_steps():
    rng = np.random.default_rng(0)
    steps = {(7465.0, 0): rng.integers(4, 8, 5), (7465.0, 1): rng.integers(5, 9, 7),
             (15163.0, 0): rng.integers(6, 10, 6)}
    rows = [(g, s, 0.05, 0.2, 0.3, float(W.mean()), float(W.std()), len(W))
            for (g, s), W in steps.items()]
    rows.append((2333.0, 0, 0.08, np.nan, np.nan, np.nan, np.nan, 0))   # no wrinkles
    out = wrinkles_by_gamma(frame(rows)).set_index("gamma")
    both = np.concatenate([steps[(7465.0, 0)], steps[(7465.0, 1)]]).astype(float)
    assert list(out.index) == [7465.0, 15163.0]
    assert out.loc[7465.0, "W_mean"] == pytest.approx(both.mean())
    assert out.loc[7465.0, "W_std"] == pytest.approx(both.std())
    assert out.loc[7465.0, "W_steps"] == len(both) and out.loc[7465.0, "runs"] == 2


def test_reference_is_found_and_explicit_paths_checked(tmp_path, monkeypatch):
    try:
        ref = load_reference()
    except ValueError:
        pytest.skip("reference/quilliet2008.json not found next to the repository")
    assert ref["results"]["primary_buckling_fit"]["b"] == -0.55
    copy = tmp_path / "ref.json"
    copy.write_text(json.dumps(ref))
    monkeypatch.setenv("SHELLBUCKLE_REFERENCE", str(copy))
    assert reference_path() == copy
    with pytest.raises(ValueError, match="does not exist"):
        reference_path(tmp_path / "nope.json")
    (tmp_path / "bad.json").write_text("{}")
    with pytest.raises(ValueError, match="results"):
        load_reference(tmp_path / "bad.json")


def test_analysis_stored_by_another_classifier_version_is_computed_again(tmp_path):
    """A stored classification carries the classifier's version; one made by another version
    is stale: the table is classified again and a sweep analyses the run again."""
    from shellbuckle.analysis import analyze_run
    from shellbuckle.analysis.classify import ANALYSIS_VERSION
    from shellbuckle.analysis.collect import analysed_table
    from shellbuckle.mesh import icosphere
    from shellbuckle.params import ShellParameters
    from shellbuckle.run import deflate
    from shellbuckle.store.catalogue import analysis_complete

    run = deflate(icosphere(4), ShellParameters.from_gamma(271.0), schedule=[0.02, 0.04],
                  out=tmp_path / "run", threads=1)
    analyze_run(run)
    assert analysis_complete(run.store)
    assert analysed_table(run)[1] == "stored"
    assert set(run.table["analysis_version"]) == {ANALYSIS_VERSION}
    # an old analysis: a wrong shape, written without a version
    stale = {k: {"shape": "wrinkled", "W": 9} for k in run.steps}
    (tmp_path / "run" / "analysis.json").write_text(
        __import__("json").dumps({str(k): v for k, v in stale.items()}))
    assert not analysis_complete(run.store)
    table, source = analysed_table(run)
    assert source == "computed" and "wrinkled" not in set(table["shape"])


def test_the_shipped_reference_is_the_projects_copy():
    """The package ships the paper's numbers; where the project's copy sits beside the
    repository, the two are the same numbers."""
    from pathlib import Path

    shipped = reference_path()
    assert shipped.name == "quilliet2008.json" and "shellbuckle" in shipped.parts
    beside = Path(__file__).resolve().parents[2] / "shared" / "reference" / "quilliet2008.json"
    if not beside.is_file():
        pytest.skip("no project copy beside the repository (a plain clone)")
    assert json.loads(shipped.read_text()) == json.loads(beside.read_text())
