"""Sweeps: the grid, the catalogue against the run folders, Dask execution, kill and resume.

Oracles: the run folders read with h5py and json only (the store's documented layout, not the
catalogue code); an uninterrupted sweep for the interrupted one; file hashes and mtimes for
"nothing finished is recomputed"; the grid's product size and hand-made pressure tables.
"""

from __future__ import annotations

import glob
import hashlib
import itertools
import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

from shellbuckle.cli import main as cli_main
from shellbuckle.store.atomic import TEMP_PREFIX
from shellbuckle.store.catalogue import (CATALOGUE_CSV, SWEEP_JSON, TIMING_COLUMNS, Catalogue,
                                         pressure_drop_dV_over_V, write_sweep_file)
from shellbuckle.sweep import SweepSpec, run_name, run_point, run_sweep

ROOT = Path(__file__).resolve().parents[1]

# 8 points: 4 runs of 5 volume steps on the 92-vertex icosphere, and 4 whose `until` is below
# `dv` (an empty schedule: deflate raises for these grid points only).
SMALL = dict(gamma=[271, 2333], seeds=[0, 1], icosphere=3, until=[0.1, 0.015])


def _small_spec() -> SweepSpec:
    return SweepSpec(**SMALL)


def _valid(point) -> bool:
    return point["until"] >= point["dv"]


# --------------------------------------------------------------------------- oracles

def _records(folder: Path) -> list[dict]:
    """The step records of a run folder, read with json and h5py only."""
    records = []
    for name in sorted(glob.glob(str(folder / "steps" / "step_*.h5"))):
        with h5py.File(name, "r") as f:
            records.append(json.loads(f.attrs["record_json"]))
    return records


def _folder_truth(folder: Path) -> dict:
    """Status, last step and last dV/V of a run folder, read with json and h5py only."""
    meta = json.loads((folder / "run.json").read_text())
    records = _records(folder)
    return {"status": meta["status"], "message": meta["message"], "gamma": meta["params"]["gamma"],
            "seed": meta["protocol"]["seed"], "steps": records[-1]["step"],
            "final_dV_over_V": records[-1]["dV_over_V"], "n_steps": len(records),
            "wall_s": sum(r["wall_s"] for r in records)}


def _file_states(folder: Path) -> dict:
    """{relative path: (mtime_ns, sha256)} of every file under ``folder``."""
    out = {}
    for path in sorted(folder.rglob("*")):
        if path.is_file():
            out[str(path.relative_to(folder))] = (path.stat().st_mtime_ns,
                                                  hashlib.sha256(path.read_bytes()).hexdigest())
    return out


def _results(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.drop(columns=list(TIMING_COLUMNS)).reset_index(drop=True)


# --------------------------------------------------------------------------- the grid

def test_grid_is_the_product_of_the_axes_with_unique_stable_names():
    axes = dict(gamma=[271, 2333, 29160], nu=[1 / 3, 0.2], seeds=[0, 1], vertices=[642],
                icosphere=[3, 4], until=[0.3, 0.5], c0_cycle=[True, False])
    spec = SweepSpec(**axes)
    points = spec.points()
    assert len(points) == 3 * 2 * 2 * (1 + 2) * 2 * 2 == len(spec)
    assert len({p["name"] for p in points}) == len(points)
    expected = set(itertools.product(axes["gamma"], axes["nu"], axes["seeds"], axes["until"],
                                     axes["c0_cycle"]))
    assert {(p["gamma"], p["nu"], p["seed"], p["until"], p["c0_cycle"]) for p in points} == expected
    # a run's name depends on its own parameters only: a sub-grid gives the same names
    sub = SweepSpec(gamma=2333, nu=0.2, seeds=1, icosphere=4, until=0.5, c0_cycle=False)
    (only,) = sub.points()
    assert only["name"] in {p["name"] for p in points}
    assert only["name"] == run_name(only) == "g2333_nu0.2_ico4_s1_until0.5_noc0"
    assert only["n_vertices"] == 10 * 4 ** 2 + 2


def test_default_names_follow_the_paper_run():
    (point,) = SweepSpec().points()
    assert point["name"] == "g2333_nu0.333_v3594_s0"
    assert point["nu"] == 1 / 3 and point["dv"] == 0.019 and point["until"] == 0.95


@pytest.mark.parametrize("bad, named", [
    (dict(gamma=[271, -1]), "gamma"), (dict(gamma=float("nan")), "gamma"),
    (dict(nu=1.0), "nu"), (dict(seeds=[0, -1]), "seed"), (dict(seeds=[0.5]), "seed"),
    (dict(vertices=3), "vertices"), (dict(icosphere=0), "icosphere"), (dict(dv=0), "dv"),
    (dict(dv=0.6), "dv"), (dict(until=0.995), "until"), (dict(jiggle=0.7), "jiggle"),
    (dict(temperature=1.5), "temperature"),
    (dict(bending="helfrich"), "helfrich"), (dict(method="bfgs"), "bfgs"),
    (dict(c0_cycle="yes"), "c0_cycle"), (dict(gamma=[]), "gamma"), (dict(tol=0.5), "tol"),
    (dict(dv=0.05, until=0.03), "until"), (dict(nu=[0.3333, 0.33333]), "share the folder"),
])
def test_bad_values_are_refused_by_name(bad, named):
    with pytest.raises(ValueError, match=named):
        SweepSpec(**bad)


def test_toml_file_gives_the_same_spec_as_keywords(tmp_path):
    example = SweepSpec.from_toml(ROOT / "examples" / "sweep.toml")
    assert example == SweepSpec(gamma=[271, 2333, 29160], nu=0.333, seeds=[0, 1], vertices=642,
                                dv=0.019, until=0.5, c0_cycle=True, temperature=0.05,
                                bending="juelicher", method="newton")
    # command-line values replace the file's, a mesh option replaces both mesh axes
    small = SweepSpec.from_toml(ROOT / "examples" / "sweep.toml", icosphere=[3], until=[0.1])
    assert small.vertices == () and small.icosphere == (3,) and small.until == (0.1,)
    path = tmp_path / "bad.toml"
    path.write_text("gamma = [271]\nvertexes = 642\n")
    with pytest.raises(ValueError, match="vertexes"):
        SweepSpec.from_toml(path)
    path.write_text("gamma = [271\n")
    with pytest.raises(ValueError, match="not valid TOML"):
        SweepSpec.from_toml(path)


def test_pressure_drop_is_the_first_snap_through():
    dv = np.arange(8) * 0.02
    p = np.array([0.0, 5.0, 10.0, 15.0, 14.0, 6.0, 7.0, 2.0])  # 15 -> 14 is < 20 %, 14 -> 6 is not
    assert pressure_drop_dV_over_V(pd.DataFrame({"dV_over_V": dv, "pressure": p})) == dv[5]
    rising = pd.DataFrame({"dV_over_V": dv, "pressure": np.linspace(0, 10, 8)})
    assert math.isnan(pressure_drop_dV_over_V(rising))


def test_a_folder_name_never_changes_meaning(tmp_path):
    spec = SweepSpec(gamma=271, icosphere=3)
    (point,) = spec.points()
    runs = {point["name"]: {k: v for k, v in point.items() if k != "name"}}
    write_sweep_file(tmp_path / "s", spec.to_dict(), runs)
    other = dict(runs[point["name"]], tol=1e-8)
    with pytest.raises(ValueError, match="tol"):
        write_sweep_file(tmp_path / "s", spec.to_dict(), {point["name"]: other})
    (tmp_path / "t").mkdir()
    (tmp_path / "t" / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="not a shellbuckle sweep"):
        write_sweep_file(tmp_path / "t", spec.to_dict(), runs)


@pytest.mark.parametrize("argv, named", [
    (["--gamma", "271,abc"], "'abc'"), (["--nu", "1.5"], "--nu 1.5"),
    (["--seeds", "2-0"], "'2-0'"), (["--icosphere", "three"], "'three'"),
    (["--method", "bfgs"], "'bfgs'"), (["--workers", "0"], "--workers 0"),
    (["--scheduler", "no address"], "no address"), (["--dv", "0.05", "--until", "0.02"], "until"),
    (["--config", "missing.toml"], "missing.toml"),
])
def test_cli_bad_input_exits_2_before_any_work(tmp_path, capsys, argv, named):
    out = tmp_path / "sweep"
    assert cli_main(["sweep", *argv, "--out", str(out)]) == 2
    assert named in capsys.readouterr().err
    assert not out.exists()



def test_cli_refuses_a_folder_of_other_runs_naming_out_before_any_work(tmp_path, capsys,
                                                                       monkeypatch):
    from shellbuckle import sweep as sweep_module

    started = []
    monkeypatch.setattr(sweep_module, "run_sweep", lambda *a, **k: started.append(1))
    argv = ["sweep", "--gamma", "271", "--icosphere", "3", "--quiet"]
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    assert cli_main([*argv, "--out", str(other)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count(f"--out {other}:") == 1 and "not a shellbuckle sweep" in err
    assert len(err.splitlines()) == 1 and [p.name for p in other.iterdir()] == ["notes.txt"]
    # a sweep whose record has a run of this name with other parameters
    spec = SweepSpec(gamma=271, icosphere=3)
    (point,) = spec.points()
    held = {k: v for k, v in point.items() if k != "name"} | {"seed": 7}
    write_sweep_file(tmp_path / "s", spec.to_dict(), {point["name"]: held})
    before = (tmp_path / "s" / SWEEP_JSON).read_text()
    assert cli_main([*argv, "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip()
    assert f"--out {tmp_path / 's'}: already has a run" in err and "seed" in err
    assert len(err.splitlines()) == 1 and not started
    assert (tmp_path / "s" / SWEEP_JSON).read_text() == before


def test_cli_a_value_error_of_the_work_is_a_failure_not_bad_input(tmp_path, capsys,
                                                                  monkeypatch):
    from shellbuckle import sweep as sweep_module

    def fails(*args, **kwargs):
        raise ValueError("a singular matrix in a worker")

    monkeypatch.setattr(sweep_module, "run_sweep", fails)
    assert cli_main(["sweep", "--gamma", "271", "--icosphere", "3", "--quiet",
                     "--out", str(tmp_path / "s")]) == 1
    assert "a singular matrix in a worker" in capsys.readouterr().err


# --------------------------------------------------------------------------- one run, no Dask

def test_run_point_resumes_a_paused_run_and_skips_a_finished_one(tmp_path):
    from shellbuckle.mesh import icosphere
    from shellbuckle.params import ShellParameters
    from shellbuckle.run import deflate

    (point,) = SweepSpec(gamma=271, icosphere=3, until=0.1).points()
    folder = tmp_path / point["name"]
    deflate(icosphere(3), ShellParameters.from_gamma(271, 1 / 3), until=0.1, out=folder,
            max_steps=2)
    before = {k: v for k, v in _file_states(folder).items() if k.startswith("steps")}
    assert len(before) == 3
    result = run_point(point, tmp_path, analyze=False)
    assert result["outcome"] == "finished"
    after = _file_states(folder)
    assert all(after[k] == v for k, v in before.items())  # steps 0..2 kept, not recomputed
    assert _folder_truth(folder)["steps"] == 5
    again = run_point(point, tmp_path, analyze=False)
    assert again["outcome"] == "skipped" and _file_states(folder) == after


def test_a_damaged_attempts_log_is_read_as_none_and_set_aside_by_the_next_attempt(tmp_path,
                                                                                    caplog):
    from shellbuckle.mesh import icosphere
    from shellbuckle.params import ShellParameters
    from shellbuckle.run import deflate
    from shellbuckle.store.catalogue import attempts_path, read_attempts, run_row

    (point,) = SweepSpec(gamma=271, icosphere=3, until=0.1).points()
    deflate(icosphere(3), ShellParameters.from_gamma(271, 1 / 3), until=0.1,
            out=tmp_path / point["name"], max_steps=2)
    log = attempts_path(tmp_path, point["name"])
    log.parent.mkdir()
    for damage in ('{"run": "x", "attempts": [1]}', '{"run": "x", "attem'):
        log.write_text(damage)
        caplog.clear()
        with caplog.at_level("WARNING"):
            assert read_attempts(tmp_path, point["name"]) == []
            row = run_row(tmp_path, point["name"], point)  # the catalogue reads past it
        assert "its attempts are not counted" in caplog.text
        assert row["attempts"] == 0 and row["status"] == "paused"
    result = run_point(point, tmp_path, analyze=False)  # resumes, and records its attempt
    assert result["outcome"] == "finished"
    (attempt,) = read_attempts(tmp_path, point["name"])
    assert attempt["outcome"] == "finished"
    aside = log.with_name(log.name + ".damaged-1")
    assert aside.read_text() == '{"run": "x", "attem'  # kept, never deleted


def test_a_finished_run_whose_location_was_interrupted_is_located_by_the_next_sweep(tmp_path):
    import json
    import logging
    import threading
    import time

    from shellbuckle.locate import pending
    from shellbuckle.store.atomic import FileLock
    from shellbuckle.store.names import LOCATING_LOCK
    from shellbuckle.store.catalogue import read_attempts
    from shellbuckle.store.located import read_located

    (point,) = SweepSpec(gamma=1000, icosphere=4, until=0.15).points()
    folder = tmp_path / point["name"]
    assert run_point(point, tmp_path)["outcome"] == "finished"
    whole = read_located(folder)
    assert "primary_buckling" in whole and not pending(folder)
    # killed during its location: finished, its located.json without the point
    located = folder / "located.json"
    data = json.loads(located.read_text())
    del data["events"]["primary_buckling"]
    located.write_text(json.dumps(data))
    assert [e.name for e in pending(folder)] == ["primary_buckling"]
    steps = {k: v for k, v in _file_states(folder).items() if k.startswith("steps")}
    # while another process locates it, the sweep's task waits for it (and locates what that
    # one leaves)
    other = FileLock(folder / LOCATING_LOCK)
    assert other.acquire()
    kept = located.read_bytes()
    results, waiting = [], threading.Event()

    class Waiting(logging.Handler):
        def emit(self, record):
            if "waiting for it" in record.getMessage():
                waiting.set()

    handler = Waiting()
    logging.getLogger("shellbuckle.store.located").addHandler(handler)
    task = threading.Thread(target=lambda: results.append(run_point(point, tmp_path)),
                            daemon=True)
    try:
        task.start()
        assert waiting.wait(timeout=300)  # it reached the lock, said so, and waits
        time.sleep(0.5)
        assert task.is_alive() and located.read_bytes() == kept
    finally:
        logging.getLogger("shellbuckle.store.located").removeHandler(handler)
        other.release()
    task.join(timeout=600)
    (result,) = results
    assert result["outcome"] == "finished"
    assert read_attempts(tmp_path, point["name"])[-1]["action"] == "locate"
    again = read_located(folder)["primary_buckling"]
    timing = ("wall_s", "cpu_s")  # the same point to the bit, in another time
    assert {k: v for k, v in again.items() if k not in timing} == \
        {k: v for k, v in whole["primary_buckling"].items() if k not in timing}
    assert {k: v for k, v in _file_states(folder).items() if k.startswith("steps")} == steps
    assert run_point(point, tmp_path)["outcome"] == "skipped"


def test_a_damaged_record_of_located_events_is_located_again_by_the_next_sweep(tmp_path,
                                                                               caplog):
    import json

    from shellbuckle.store.catalogue import run_row
    from shellbuckle.store.located import read_located
    from shellbuckle.store.run import RunStore

    (point,) = SweepSpec(gamma=1000, icosphere=4, until=0.15).points()
    assert run_point(point, tmp_path)["outcome"] == "finished"
    located = tmp_path / point["name"] / "located.json"
    whole = read_located(located.parent)["primary_buckling"]
    data = json.loads(located.read_text())
    data["events"]["primary_buckling"] = [1]  # whole JSON, not a located point
    data["events"]["axisymmetry_loss"] = {"step": 3, "complete": True}  # a point cut short
    located.write_text(json.dumps(data))
    with caplog.at_level("WARNING"):
        assert read_located(located.parent) == {}
    assert "axisymmetry_loss, primary_buckling are not located points" in caplog.text
    row = run_row(tmp_path, point["name"], point)  # the catalogue reads past it
    stepped = RunStore.open(located.parent).record(whole["step"])["dV_over_V"]
    assert row["status"] == "finished" and row["primary_dV_over_V"] == stepped  # unlocated
    assert run_point(point, tmp_path)["outcome"] == "finished"
    again = read_located(located.parent)["primary_buckling"]
    assert again["dV_over_V"] == whole["dV_over_V"]


def test_a_location_that_fails_is_recorded_and_named_in_the_catalogue(tmp_path, monkeypatch):
    import json

    from shellbuckle import locate as locate_module
    from shellbuckle.store.catalogue import read_attempts, run_row

    spec = SweepSpec(gamma=1000, icosphere=4, until=0.15)
    (point,) = spec.points()
    write_sweep_file(tmp_path, spec.to_dict(), {point["name"]: point})
    catalogue = Catalogue(tmp_path)  # as a sweep keeps it: rows of unchanged runs cached
    assert run_point(point, tmp_path)["outcome"] == "finished"
    located = tmp_path / point["name"] / "located.json"
    data = json.loads(located.read_text())
    del data["events"]["primary_buckling"]
    located.write_text(json.dumps(data))

    def fails(*args, **kwargs):
        raise FloatingPointError("a bisection that broke")

    monkeypatch.setattr(locate_module, "_locate_event", fails)
    result = run_point(point, tmp_path)
    assert result["outcome"] == "location failed" and result["status"] == "finished"
    assert "location: FloatingPointError: a bisection that broke" in result["message"]
    attempt = read_attempts(tmp_path, point["name"])[-1]
    assert attempt["outcome"] == "location failed" and attempt["action"] == "locate"
    row = run_row(tmp_path, point["name"], point)  # the catalogue says it too
    assert row["status"] == "finished" and row["stop_reason"] == "end of schedule"
    assert row["message"].startswith("end of the schedule")
    assert row["message"].endswith("location: FloatingPointError: a bisection that broke")
    assert row["traceback"]
    assert "location: FloatingPointError" in catalogue.write()["message"].iloc[0]
    monkeypatch.undo()  # located outside the sweep: the row is the run's own again
    locate_module.locate(tmp_path / point["name"])
    row = run_row(tmp_path, point["name"], point)
    assert "location" not in row["message"] and row["traceback"] is None
    assert catalogue.write()["message"].iloc[0] == row["message"]  # seen by the kept rows
    assert run_point(point, tmp_path)["outcome"] == "skipped"


def _finished_with_a_failed_analysis(tmp_path, monkeypatch):
    """A one-run sweep folder whose run finished and whose analysis in the sweep then failed:
    ``(spec, point)``. The run's own analysis (made while it ran) is whole."""
    import shellbuckle.analysis as analysis_module

    spec = SweepSpec(gamma=1000, icosphere=4, until=0.15)
    (point,) = spec.points()
    write_sweep_file(tmp_path, spec.to_dict(),
                     {point["name"]: {k: v for k, v in point.items() if k != "name"}})

    def fails(*args, **kwargs):
        raise FloatingPointError("a classification that broke")

    with monkeypatch.context() as patch:
        patch.setattr(analysis_module, "analyze_run", fails)
        result = run_point(point, tmp_path)
    assert result["outcome"] == "analysis failed" and result["status"] == "finished"
    return spec, point


def test_an_analysis_that_fails_is_left_by_no_retry_and_analysed_by_the_next_sweep(
        tmp_path, monkeypatch):
    from shellbuckle.store.catalogue import read_attempts

    spec, point = _finished_with_a_failed_analysis(tmp_path, monkeypatch)
    (tmp_path / point["name"] / "analysis.json").unlink()  # what the run itself had analysed
    attempts = read_attempts(tmp_path, point["name"])
    catalogue = run_sweep(spec, tmp_path, progress=False, retry_failed=False)
    assert read_attempts(tmp_path, point["name"]) == attempts  # left as it stands
    assert "analysis: FloatingPointError" in catalogue["message"].iloc[0]
    catalogue = run_sweep(spec, tmp_path, workers=1, progress=False)
    assert read_attempts(tmp_path, point["name"])[-1]["outcome"] == "finished"
    assert "analysis:" not in catalogue["message"].iloc[0]
    assert catalogue["primary_source"].iloc[0] == "analysis"  # not the pressure drop


def test_no_retry_locates_a_run_whose_failed_analysis_was_mended_outside(tmp_path,
                                                                         monkeypatch):
    from shellbuckle.store.catalogue import read_attempts
    from shellbuckle.store.located import read_located

    # the run's own analysis is whole: the failure no longer stands
    spec, point = _finished_with_a_failed_analysis(tmp_path, monkeypatch)
    located = tmp_path / point["name"] / "located.json"
    data = json.loads(located.read_text())
    del data["events"]["primary_buckling"]  # but an event is still to locate
    located.write_text(json.dumps(data))
    catalogue = run_sweep(spec, tmp_path, workers=1, progress=False, retry_failed=False)
    assert read_attempts(tmp_path, point["name"])[-1]["outcome"] == "finished"
    assert "primary_buckling" in read_located(located.parent)
    assert "analysis:" not in catalogue["message"].iloc[0]


def test_a_runs_warnings_name_the_run_and_the_labelling_ends_with_it(tmp_path, capsys,
                                                                      monkeypatch):
    # one gradient-descent iteration per minimization (no jiggle retries with it) and no c0
    # cycle: every minimization stops unconverged, so the protocol warns at each step.
    # As in a fresh worker process, nobody has configured logging (pytest's own handlers on
    # the root logger are set aside for the test).
    import logging

    (point,) = SweepSpec(gamma=271, icosphere=3, until=0.04, c0_cycle=False).points()
    point.update(max_iter=1, method="gd")
    logger = logging.getLogger("shellbuckle")
    monkeypatch.setattr(logging.getLogger(), "handlers", [])
    assert not logger.handlers
    result = run_point(point, tmp_path, analyze=False)
    assert result["outcome"] == "finished"
    lines = [l for l in capsys.readouterr().err.splitlines() if l.strip()]
    assert any("did not converge" in l for l in lines)
    assert all(l.startswith(f"{point['name']}: step ") for l in lines)
    assert not logger.handlers  # removed with the run: later warnings are unlabelled again


# --------------------------------------------------------------------------- Dask sweeps

def _worker_environment():
    return {k: os.environ.get(k) for k in ("MALLOC_TRIM_THRESHOLD_", "OMP_NUM_THREADS",
                                           "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")}


def test_local_workers_are_single_threaded_and_keep_glibc_malloc_defaults(monkeypatch):
    # Dask's nanny sets MALLOC_TRIM_THRESHOLD_ = 65536 by default, which freezes glibc's mmap
    # threshold at 128 kB: a deflation step then page-faults ten times as often as in a plain
    # process. The local cluster must leave it unset and pin the BLAS threads.
    from shellbuckle.sweep import _client

    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    client, owned = _client(None, 1)
    try:
        (env,) = client.run(_worker_environment).values()
    finally:
        for obj in owned:
            obj.close()
    assert env == {"MALLOC_TRIM_THRESHOLD_": None, "OMP_NUM_THREADS": "1",
                   "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


@pytest.fixture(scope="module")
def reference_sweep(tmp_path_factory):
    """The small sweep run without interruption on a 2-worker local cluster."""
    out = tmp_path_factory.mktemp("reference") / "sweep"
    catalogue = run_sweep(_small_spec(), out, workers=2, progress=False)
    return out, catalogue


def test_two_worker_sweep_catalogue_matches_the_run_folders(reference_sweep):
    out, catalogue = reference_sweep
    points = {p["name"]: p for p in _small_spec().points()}
    assert list(catalogue["name"]) == list(points)
    for _, row in catalogue.iterrows():
        point = points[row["name"]]
        if not _valid(point):
            continue
        truth = _folder_truth(out / row["name"])
        assert row["status"] == truth["status"] == "finished"
        assert row["message"] == truth["message"]
        assert row["steps"] == truth["steps"] == truth["n_steps"] - 1 == 5
        assert row["final_dV_over_V"] == truth["final_dV_over_V"]
        assert row["gamma"] == truth["gamma"] and row["seed"] == truth["seed"]
        assert row["wall_s"] == pytest.approx(truth["wall_s"], rel=1e-12)
        assert row["stop_reason"] == "end of schedule"
    # catalogue.csv holds the same table; regenerating it from the folders changes nothing
    written = pd.read_csv(out / CATALOGUE_CSV)
    assert list(written["name"]) == list(catalogue["name"])
    np.testing.assert_array_equal(written["final_dV_over_V"].to_numpy(),
                                  catalogue["final_dV_over_V"].to_numpy(dtype=float))
    pd.testing.assert_frame_equal(Catalogue.load(out), catalogue)
    assert json.loads((out / SWEEP_JSON).read_text())["runs"].keys() == points.keys()


def test_catalogue_thresholds_are_the_run_analysis_events(reference_sweep):
    from shellbuckle.analysis import thresholds

    out, catalogue = reference_sweep
    for _, row in catalogue[catalogue["status"] == "finished"].iterrows():
        found = thresholds(out / row["name"])  # the analysis stored in the run folder
        assert row["primary_source"] == "analysis"
        for column, event in (("primary_dV_over_V", "primary_buckling"),
                              ("axisymmetry_loss_dV_over_V", "axisymmetry_loss"),
                              ("wrinkles_dV_over_V", "wrinkles")):
            assert row[column] == found[event] or (math.isnan(row[column])
                                                   and math.isnan(found[event]))
        # the pressure drop, recomputed from the step records
        records = _records(out / row["name"])
        drops = [b["dV_over_V"] for a, b in zip(records, records[1:])
                 if a["pressure"] > 0 and b["pressure"] < 0.8 * a["pressure"]]
        assert row["pressure_drop_dV_over_V"] == (drops[0] if drops else None) or (
            not drops and math.isnan(row["pressure_drop_dV_over_V"]))


def test_a_failing_run_is_recorded_and_the_others_finish(reference_sweep):
    out, catalogue = reference_sweep
    failed = catalogue[catalogue["status"] == "failed"]
    invalid = [name for name, p in ((p["name"], p) for p in _small_spec().points())
               if not _valid(p)]
    assert sorted(failed["name"]) == sorted(invalid)
    assert (catalogue["status"] != "failed").sum() == 4
    for _, row in failed.iterrows():
        assert "less than one step" in row["message"] and \
            row["message"].startswith("ValueError")
        assert "Traceback" in (out / row["traceback"]).read_text()
        assert not (out / row["name"]).exists()


def test_rerun_of_a_finished_sweep_touches_nothing(reference_sweep, capsys):
    out, catalogue = reference_sweep
    states = {p.name: _file_states(p) for p in out.iterdir() if (p / "run.json").exists()}
    code = cli_main(["sweep", "--gamma", "271,2333", "--seeds", "0-1", "--icosphere", "3",
                     "--until", "0.1,0.015", "--no-retry", "--quiet", "--out", str(out)])
    assert code == 1  # the 4 recorded failures are reported
    assert "finished 4, failed 4" in capsys.readouterr().out
    assert {p.name: _file_states(p) for p in out.iterdir() if (p / "run.json").exists()} == states
    pd.testing.assert_frame_equal(Catalogue.load(out), catalogue)


_SWEEP_SCRIPT = textwrap.dedent("""
    import sys
    from shellbuckle.sweep import SweepSpec, run_sweep
    spec = SweepSpec(**{small!r})
    run_sweep(spec, sys.argv[1], workers=2, progress=False)
""")


def _status(out: Path, name: str):
    path = out / name / "run.json"
    return json.loads(path.read_text())["status"] if path.exists() else None


def _sweep_done(out: Path, name: str) -> bool:
    """The sweep's last attempt at the run ended with the run finished (and analysed)."""
    path = out / "logs" / f"{name}.json"
    if not path.exists():
        return False
    return json.loads(path.read_text())["attempts"][-1]["outcome"] == "finished"


def test_killed_sweep_resumes_without_recomputing_finished_work(reference_sweep, tmp_path):
    ref_out, ref_catalogue = reference_sweep
    out = tmp_path / "sweep"
    valid = [p["name"] for p in _small_spec().points() if _valid(p)]
    log = (tmp_path / "sweep.log").open("w")
    proc = subprocess.Popen([sys.executable, "-c", _SWEEP_SCRIPT.format(small=SMALL), str(out)],
                            start_new_session=True, stdout=log, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and proc.poll() is None:
            if any(_sweep_done(out, n) for n in valid):
                break
            time.sleep(0.05)
        assert proc.poll() is None, ("the sweep ended before it could be killed:\n"
                                     + (tmp_path / "sweep.log").read_text()[-3000:])
        os.killpg(proc.pid, signal.SIGKILL)  # the sweep and its worker processes
        proc.wait()
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        log.close()
    finished = [n for n in valid if _sweep_done(out, n)]  # computed and analysed
    started = [n for n in valid if (out / n / "steps").exists()]
    assert finished and len(finished) < len(valid)
    finished_files = {n: _file_states(out / n) for n in finished}
    # steps stored before the kill (and, for a run that ended but was not analysed yet,
    # run.json) are never rewritten; a temporary the kill left behind (a step being written)
    # is not a stored step, and the next writer removes it
    kept = {n: {k: v for k, v in _file_states(out / n).items()
                if (k.startswith("steps") and not Path(k).name.startswith(TEMP_PREFIX))
                or (k == "run.json" and _status(out, n) == "finished")}
            for n in started if n not in finished}
    attempts = {n: json.loads((out / "logs" / f"{n}.json").read_text())["attempts"]
                for n in finished}

    catalogue = run_sweep(_small_spec(), out, workers=2, progress=False)

    for n in finished:  # not reopened, not recomputed, not even a new attempt
        assert _file_states(out / n) == finished_files[n]
        assert json.loads((out / "logs" / f"{n}.json").read_text())["attempts"] == attempts[n]
    for n, files in kept.items():
        now = _file_states(out / n)
        assert all(now[k] == v for k, v in files.items())
    pd.testing.assert_frame_equal(_results(catalogue), _results(ref_catalogue))
    assert (catalogue["status"] == "finished").sum() == len(valid)


def test_a_local_cluster_serves_on_a_free_local_port_without_a_warning(recwarn):
    # a second sweep on the same machine: Dask's default port 8787 is taken
    import socket

    from shellbuckle.sweep import _client

    taken = socket.socket()
    try:
        taken.bind(("127.0.0.1", 8787))
        taken.listen()
    except OSError:
        pass  # taken already, as the test needs
    try:
        client, owned = _client(None, 1)
        try:
            port = client.cluster.scheduler.http_server.port
            assert port not in (0, 8787)
        finally:
            for thing in owned:
                thing.close()
    finally:
        taken.close()
    assert not [w for w in recwarn if "already in use" in str(w.message)]


@pytest.mark.parametrize("damage, said", [
    ("folder", "is a folder"), ("not json", "not valid JSON"), ("latin-1", "not valid JSON"),
    ("a list", "not a shellbuckle-sweep description"), ("no runs", "is damaged"),
    ("runs a list", "is damaged"),
])
def test_a_damaged_sweep_record_is_refused_in_one_line(tmp_path, capsys, damage, said):
    out = tmp_path / "s"
    out.mkdir()
    record = out / SWEEP_JSON
    header = '{"format": "shellbuckle-sweep", "format_version": 1'
    if damage == "folder":
        record.mkdir()
    else:
        record.write_bytes({"not json": b'{"format": 3', "latin-1": b'{"f\xe9": 1}',
                            "a list": b"[1]", "no runs": (header + "}").encode(),
                            "runs a list": (header + ', "runs": [], "specs": []}').encode(),
                            }[damage])
    listing = sorted(p.name for p in out.iterdir())
    for argv in (["sweep", "--gamma", "271", "--icosphere", "3", "--quiet", "--out", str(out)],
                 ["refine", "--report-only", "--out", str(out)]):
        assert cli_main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert f"--out {out}:" in err and said in err and len(err.splitlines()) == 1
    assert cli_main(["report", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert said in err and len(err.splitlines()) == 1
    assert sorted(p.name for p in out.iterdir()) == listing


def test_a_lost_run_of_a_sweep_is_named_and_a_file_in_its_place_refused(reference_sweep,
                                                                         tmp_path, caplog,
                                                                         capsys):
    import shutil

    from shellbuckle.analysis.collect import run_folders

    out, catalogue = reference_sweep
    copy = Path(shutil.copytree(out, tmp_path / "sweep"))
    held = {p.name for p in copy.iterdir() if (p / "run.json").is_file()}
    finished = list(catalogue.loc[catalogue["status"] == "finished", "name"])
    lost, replaced = finished[0], finished[1]
    shutil.rmtree(copy / lost)
    shutil.rmtree(copy / replaced)
    (copy / replaced).write_text("not a run")
    with caplog.at_level("WARNING", logger="shellbuckle.analysis.collect"):
        found = run_folders(copy)
    assert {p.name for p in found} == held - {lost, replaced}
    warned = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warned) == 1 and lost in warned[0] and replaced in warned[0]
    # the command line says so in its one-line warning format (a process of its own: the
    # logging of this one is pytest's)
    done = subprocess.run([sys.executable, "-m", "shellbuckle", "report", str(copy), "--out",
                           str(tmp_path / "r.md"), "--no-figures"], capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    lines = [line for line in done.stderr.splitlines() if lost in line]
    assert len(lines) == 1 and lines[0].startswith("shellbuckle report: warning: ")
    # a file where the sweep keeps a run's folder: the sweep refuses before any work
    before = (copy / SWEEP_JSON).read_text()
    assert cli_main(["sweep", "--gamma", "271", "--icosphere", "3", "--quiet",
                     "--out", str(copy)]) == 2
    err = capsys.readouterr().err.strip()
    assert f"--out {copy}: has a file {replaced}" in err and len(err.splitlines()) == 1
    assert (copy / SWEEP_JSON).read_text() == before


def test_a_finished_run_with_a_damaged_mesh_is_no_success_in_the_catalogue(reference_sweep,
                                                                           tmp_path, caplog):
    import logging
    import shutil

    out, catalogue = reference_sweep
    copy = Path(shutil.copytree(out, tmp_path / "sweep"))
    name = catalogue.loc[catalogue["status"] == "finished", "name"].iloc[0]
    mesh = copy / name / "mesh.h5"
    mesh.write_bytes(mesh.read_bytes()[: mesh.stat().st_size // 2])
    row = Catalogue.load(copy).set_index("name").loc[name]
    assert row["status"] == "failed" and "mesh.h5" in row["message"]
    others = Catalogue.load(copy).set_index("name").drop(index=name)
    assert (others["status"] == catalogue.set_index("name").drop(index=name)["status"]).all()
    # the sweep run again (failed runs retried) names it and leaves it: no attempt can mend it
    attempts = (copy / "logs" / f"{name}.json").read_bytes()
    with caplog.at_level(logging.WARNING, logger="shellbuckle.sweep"):
        again = run_sweep(_small_spec(), copy, workers=1, progress=False)
    assert (copy / "logs" / f"{name}.json").read_bytes() == attempts
    assert f"{name} finished, but its mesh.h5 is not the mesh" in caplog.text
    assert again.set_index("name").loc[name, "status"] == "failed"


def test_a_sweep_stopped_by_sigterm_leaves_its_runs_interrupted_and_resumes_them(tmp_path):
    # SIGTERM to the sweep alone (a batch system's time limit): its local cluster's workers are
    # killed in the middle of their runs, which no longer say "running" (nor the catalogue
    # "pending") of a run nobody computes
    out = tmp_path / "s"
    # runs of 80 steps: Dask lets a worker go on for about 4 s before it kills it
    argv = ["sweep", "--gamma", "2333", "--icosphere", "8", "--seeds", "0,1", "--dv", "0.005",
            "--until", "0.4", "--workers", "2", "--quiet", "--out", str(out)]
    log = (tmp_path / "sweep.log").open("w")
    proc = subprocess.Popen([sys.executable, "-m", "shellbuckle", *argv],
                            start_new_session=True, stdout=log, stderr=subprocess.STDOUT)
    names = [p["name"] for p in SweepSpec(gamma=2333, icosphere=8, seeds=[0, 1], dv=0.005,
                                          until=0.4).points()]
    try:
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and proc.poll() is None:
            if all((out / n / "steps" / "step_000001.h5").exists() for n in names):
                break
            time.sleep(0.05)
        assert proc.poll() is None, (tmp_path / "sweep.log").read_text()[-3000:]
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        log.close()
    assert code == 128 + signal.SIGTERM, (tmp_path / "sweep.log").read_text()[-3000:]
    catalogue = pd.read_csv(out / CATALOGUE_CSV).set_index("name")
    for n in names:
        meta = json.loads((out / n / "run.json").read_text())
        assert meta["status"] == "interrupted", meta
        assert "SIGTERM" in meta["message"] and "resume" in meta["message"]
        last = json.loads((out / "logs" / f"{n}.json").read_text())["attempts"][-1]
        assert last["outcome"] == "interrupted" and last["ended"] is not None
        assert catalogue.loc[n, "status"] == "interrupted"
        stored = len(_records(out / n))
        assert 1 < stored < 81  # stopped in the middle
        assert f"after step {stored - 1}" in meta["message"]  # step 0 is stored too

    assert cli_main(argv) == 0
    for n in names:
        assert _folder_truth(out / n)["status"] == "finished"
    assert (Catalogue.load(out)["status"] == "finished").all()


def _dead_pid() -> int:
    """The pid of a process of this host that has ended."""
    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    return int(done.stdout)


def _left_by_a_killed_worker(out: Path, seed: int, started: str, pid: int) -> str:
    """A run of the sweep folder ``out`` as a worker killed in the middle of it leaves it: two
    steps stored, run.json "running", its attempt (begun at ``started`` by process ``pid`` of
    this host) open. Returns its name."""
    import socket

    from shellbuckle.mesh import icosphere
    from shellbuckle.params import ShellParameters
    from shellbuckle.run import deflate
    from shellbuckle.store.catalogue import record_attempt
    from shellbuckle.store.run import RunStore

    (point,) = SweepSpec(gamma=271, icosphere=3, until=0.1, seeds=seed).points()
    deflate(icosphere(3), ShellParameters.from_gamma(271, 1 / 3), until=0.1, seed=seed,
            out=out / point["name"], max_steps=2)
    store = RunStore.open(out / point["name"])
    store.set_status("running")
    store.close()
    record_attempt(out, point["name"], {"started": started, "ended": None,
                                        "host": socket.gethostname(), "pid": pid,
                                        "outcome": "running", "message": None})
    return point["name"]


def test_a_stopped_sweep_marks_only_the_attempts_it_began_whose_process_ended(tmp_path):
    # what an earlier sweep, killed outright, left open is not this sweep's to end, nor what a
    # live process (another sweep on the same folder) still works on
    from shellbuckle.store.catalogue import read_attempts
    from shellbuckle.sweep import _mark_stopped

    dead = _dead_pid()
    names = [_left_by_a_killed_worker(tmp_path, seed, started, pid)
             for seed, started, pid in ((0, "2026-01-01T00:00:00+00:00", dead),
                                        (1, "2026-01-01T00:00:09+00:00", os.getpid()),
                                        (2, "2026-01-01T00:00:09+00:00", dead))]
    _mark_stopped(tmp_path, names, KeyboardInterrupt(), since="2026-01-01T00:00:05+00:00")
    earlier, alive, ours = names
    for name in (earlier, alive):
        assert _status(tmp_path, name) == "running"
        assert read_attempts(tmp_path, name)[-1]["outcome"] == "running"
    assert _status(tmp_path, ours) == "interrupted"
    last = read_attempts(tmp_path, ours)[-1]
    assert last["outcome"] == "interrupted" and last["status"] == "interrupted"
    assert last["started"] == "2026-01-01T00:00:09+00:00" and last["ended"] is not None
    assert "after step 2" in json.loads((tmp_path / ours / "run.json").read_text())["message"]


def test_a_run_that_cannot_be_marked_does_not_hide_the_interrupt_nor_stop_the_others(
        tmp_path, caplog):
    from shellbuckle.sweep import _mark_stopped

    names = [_left_by_a_killed_worker(tmp_path, seed, "2026-01-01T00:00:09+00:00", _dead_pid())
             for seed in (0, 1)]
    (tmp_path / names[0] / "run.json").write_text("{damaged")
    with caplog.at_level("WARNING"):
        _mark_stopped(tmp_path, names, KeyboardInterrupt(), since="2026-01-01T00:00:05+00:00")
    assert "not recorded as interrupted" in caplog.text and names[0] in caplog.text
    assert _status(tmp_path, names[1]) == "interrupted"


def test_a_run_killed_outright_with_its_sweep_is_listed_interrupted_until_resumed(
        tmp_path, capsys):
    # a sweep killed outright (SIGKILL, a power cut) could mark nothing: run.json says
    # "running"; the catalogue, the run's view and the commands say what it is
    from shellbuckle.commands._output import report_run
    from shellbuckle.run import Run
    from shellbuckle.store.run import RunStore
    from shellbuckle.sweep import _runs

    spec = SweepSpec(gamma=271, icosphere=3, until=0.1)
    (point,) = spec.points()
    write_sweep_file(tmp_path, spec.to_dict(), _runs([point]))
    name = _left_by_a_killed_worker(tmp_path, 0, "2026-01-01T00:00:09+00:00", _dead_pid())
    assert _status(tmp_path, name) == "running"
    catalogue = Catalogue(tmp_path)
    row = catalogue.write().iloc[0]
    assert row["status"] == "interrupted" and "after step 2;" in row["message"]
    assert "shellbuckle resume" in row["message"]
    assert pd.read_csv(tmp_path / CATALOGUE_CSV)["status"].tolist() == ["interrupted"]
    run = Run.open(tmp_path / name)
    assert run.status == "interrupted" and "no process holds its writer lock" in run.message
    report_run(run)
    assert "status: interrupted (run.json says running" in capsys.readouterr().out
    with RunStore.resume(tmp_path / name):  # a live writer again: running, the cache asks anew
        assert catalogue.frame()["status"].tolist() == ["running"]
        assert Run.open(tmp_path / name).status == "running"
    assert catalogue.frame()["status"].tolist() == ["interrupted"]


def test_the_next_attempt_ends_the_attempts_whose_process_was_killed(tmp_path):
    # what a worker killed outright leaves open in logs/ (outcome "running") is ended with the
    # outcome "killed" when the run's next attempt begins; an open attempt whose process lives
    # (or ran on another host) is not touched
    from shellbuckle.store.catalogue import read_attempts, record_attempt

    dead = _dead_pid()
    name = _left_by_a_killed_worker(tmp_path, 0, "2026-01-01T00:00:09+00:00", dead)
    record_attempt(tmp_path, name, {"started": "2026-01-01T00:00:10+00:00", "ended": None,
                                    "host": "elsewhere", "pid": dead, "outcome": "running"})
    (point,) = SweepSpec(gamma=271, icosphere=3, until=0.1, seeds=0).points()
    assert point["name"] == name
    result = run_point(point, tmp_path, analyze=False)
    assert result["outcome"] == "finished"
    killed, remote, last = read_attempts(tmp_path, name)
    assert killed["outcome"] == "killed" and killed["ended"] is None
    assert f"pid {dead} on " in killed["message"] and "killed outright" in killed["message"]
    assert remote["outcome"] == "running"  # its process cannot be asked from here
    assert last["outcome"] == "finished" and last["pid"] == os.getpid()


def test_the_client_of_several_sweeps_marks_their_stopped_runs(tmp_path):
    # the context the paper's reproduction and the convention study run their sweeps in
    from shellbuckle.store.catalogue import read_attempts
    from shellbuckle.sweep import _runs, sweep_client
    from shellbuckle.util import now

    folders = [tmp_path / "sweep", tmp_path / "special", tmp_path / "never"]
    spec = SweepSpec(gamma=271, icosphere=3, until=0.1)
    (point,) = spec.points()
    with pytest.raises(KeyboardInterrupt):
        with sweep_client(None, 1, folders):
            for folder in folders[:2]:  # what a worker leaves when it is killed mid-run
                write_sweep_file(folder, spec.to_dict(), _runs([point]))
                assert _left_by_a_killed_worker(folder, 0, now(), _dead_pid()) == point["name"]
            raise KeyboardInterrupt
    for folder in folders[:2]:
        assert _status(folder, point["name"]) == "interrupted"
        assert read_attempts(folder, point["name"])[-1]["outcome"] == "interrupted"
        assert Catalogue.load(folder)["status"].tolist() == ["interrupted"]
        assert pd.read_csv(folder / CATALOGUE_CSV)["status"].tolist() == ["interrupted"]
    assert not folders[2].exists()


def test_the_sweep_bar_counts_the_steps_its_runs_have_made(tmp_path, monkeypatch, capsys):
    # a run on a fine mesh is hours of steps: the bar says how many the sweep has stored
    import re

    import shellbuckle.sweep as sweep_mod
    from shellbuckle.mesh import icosphere
    from shellbuckle.params import ShellParameters
    from shellbuckle.run import deflate
    from shellbuckle.sweep import _runs

    monkeypatch.setattr(sweep_mod, "STEPS_EVERY_S", 0.0)
    monkeypatch.setattr(sweep_mod, "STEPS_EVERY_S_LOG", 0.0)  # pytest's capture is no terminal
    spec = SweepSpec(gamma=271, icosphere=3, until=0.3)
    (point,) = spec.points()
    write_sweep_file(tmp_path, spec.to_dict(), _runs([point]))
    deflate(icosphere(3), ShellParameters.from_gamma(271, 1 / 3), until=0.3, seed=0,
            out=tmp_path / point["name"], max_steps=3, locate=False)  # made before: not counted
    run_sweep(spec, tmp_path, workers=1, progress=True, analyze=False)
    frames = [f for f in re.split(r"[\r\n]", capsys.readouterr().err) if f.startswith("sweep:")]
    counts = [int(m.group(1)) for f in frames if (m := re.search(r"0/1 .*steps made (\d+)", f))]
    made = len(pd.read_csv(tmp_path / point["name"] / "table.csv")) - 1 - 3
    assert made > 5 and counts and max(counts) >= 1 and counts == sorted(counts)
    assert max(counts) <= made
    assert re.search(rf"1/1 .*failed 0, steps made {made}\b", frames[-1]), frames[-1]
