"""Run store: the guarantees of shellbuckle.store.run are the oracles.

- positions, records and arrays come back bitwise as written;
- the table has the SPEC §7 column names in the SPEC's order;
- a crash at any moment (an exception inside the atomic replace, or SIGKILL of a writing
  process) leaves only complete step files forming a prefix 0..k, and the run resumes;
- a folder never receives a different run; non-run folders give clear errors;
- a run folder reads with json + h5py alone (the documented snippet, in a fresh interpreter).
"""

from __future__ import annotations

import io
import json
import os
import random
import re
import signal
import subprocess
import sys
import textwrap
import time
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

from shellbuckle import cli
from shellbuckle.store import TABLE_COLUMNS, RunStore
from shellbuckle.store import run as run_module

# SPEC.md §7, typed from the specification (not from the code under test).
SPEC_COLUMNS = ["step", "target_dV_over_V", "dV_over_V", "E_total", "E_bend", "E_stretch",
                "E_over_kappa", "E_before_c0_cycle", "pressure", "grad_norm", "iterations",
                "inertia", "min_distance", "wall_s"]
SPEC_ANALYSIS = ["shape", "n_dimples", "corners", "W"]

PARAMS = {"gamma": 271.0, "nu": 1 / 3, "kappa": 1.0}
PROTOCOL = {"dv": 0.019, "until": 0.3, "c0_cycle": True, "jiggle": 0.05, "seed": 7,
            "bending": "star", "minimizer": {"gtol": 1e-9, "max_iter": 200}}


def _mesh(n=30, seed=0):
    rng = np.random.default_rng(seed)
    X0 = rng.normal(size=(n, 3))
    X0 /= np.linalg.norm(X0, axis=1, keepdims=True)
    faces = rng.integers(0, n, size=(2 * n - 4, 3))
    return X0, faces


def _record(k):
    return {"target_dV_over_V": 0.019 * k, "dV_over_V": 0.019 * k + 1e-13,
            "E_total": 1.0 / 3.0 + k, "E_bend": np.float64(np.pi), "E_stretch": 1e-300 * k,
            "E_over_kappa": 1.0 / 3.0 + k, "E_before_c0_cycle": None, "pressure": -2.5e7,
            "grad_norm": 3e-11, "iterations": np.int64(12 + k), "inertia": 0,
            "min_distance": 0.123456789012345678, "wall_s": 0.5, "converged": True,
            "phase": "deflate"}


def _create(path, **kw):
    X0, faces = _mesh()
    args = dict(params=PARAMS, protocol=PROTOCOL, X0=X0, faces=faces)
    args.update(kw)
    return RunStore.create(path, **args)


def _cli(argv):
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = cli.main(argv)
    return code, out.getvalue(), err.getvalue()


# ----------------------------------------------------------------------------- round trips

def test_positions_records_arrays_and_mesh_round_trip_bitwise(tmp_path):
    rng = np.random.default_rng(1)
    X0, faces = _mesh()
    rest = {"abar_inv": rng.normal(size=(len(faces), 2, 2)), "rest_area": rng.random(len(faces))}
    written = []
    with RunStore.create(tmp_path / "run", params=PARAMS, protocol=PROTOCOL, X0=X0,
                         faces=faces, rest=rest) as store:
        for k in range(4):
            X = X0 * rng.lognormal(size=(len(X0), 1)) * 10.0 ** rng.integers(-300, 300)
            arrays = {"hinge_angles": rng.normal(size=57), "flags": rng.integers(0, 2, 9)}
            store.append_step(k, X, _record(k), arrays)
            written.append((X, arrays))
    store = RunStore.open(tmp_path / "run")
    assert store.steps == [0, 1, 2, 3] and store.last_step == 3
    assert store.X0.tobytes() == X0.tobytes() and np.array_equal(store.faces, faces)
    assert all(store.rest[name].tobytes() == rest[name].tobytes() for name in rest)
    for k, (X, arrays) in enumerate(written):
        assert store.positions(k).dtype == np.float64
        assert store.positions(k).tobytes() == X.tobytes()
        got = store.arrays(k)
        assert all(np.array_equal(got[n], a) and got[n].dtype == a.dtype for n, a in arrays.items())
        expected = json.loads(json.dumps({"step": k, **run_module._jsonable(_record(k), "r")}))
        assert store.record(k) == expected
        assert store.record(k)["E_stretch"] == 1e-300 * k  # float bits survive JSON
    assert store.params == PARAMS and store.protocol == json.loads(json.dumps(PROTOCOL))


def test_large_arrays_are_stored_compressed_and_read_back_bitwise(tmp_path):
    # a 160k-vertex run writes 3.8 MB of positions per step: large arrays are gzip-compressed
    # (one chunk per array), small ones plain; either way the same bits come back
    from shellbuckle.mesh import icosphere
    from shellbuckle.store.layout import COMPRESS_MIN_SIZE

    mesh = icosphere(16)
    X0, faces = mesh.X, mesh.faces
    assert X0.size >= COMPRESS_MIN_SIZE and faces.size >= COMPRESS_MIN_SIZE
    X = X0 * np.random.default_rng(2).lognormal(size=(len(X0), 1))
    with RunStore.create(tmp_path / "run", params=PARAMS, protocol=PROTOCOL, X0=X0,
                         faces=faces) as store:
        store.append_step(0, X, _record(0), {"small": np.arange(5.0)})
    store = RunStore.open(tmp_path / "run")
    assert store.positions(0).tobytes() == X.tobytes()
    assert store.X0.tobytes() == X0.tobytes() and np.array_equal(store.faces, faces)
    assert store.arrays(0)["small"].tobytes() == np.arange(5.0).tobytes()
    with h5py.File(tmp_path / "run" / "mesh.h5") as f:
        assert f["faces"].compression == "gzip" and f["X0"].compression == "gzip"
        assert f["faces"].chunks == f["faces"].shape
        # the faces of an icosphere are far from random integers: they shrink several-fold
        assert f["faces"].id.get_storage_size() < 0.5 * faces.astype(f["faces"].dtype).nbytes
    step_file = next((tmp_path / "run" / "steps").glob("*.h5"))
    with h5py.File(step_file) as f:
        assert f["X"].compression == "gzip" and f["arrays/small"].compression is None


def test_table_has_spec_columns_in_order_then_analysis_then_others(tmp_path):
    with _create(tmp_path / "run") as store:
        for k in range(3):
            store.append_step(k, store.X0, _record(k))
        store.update_analysis({1: {"W": 0, "shape": "capsule"}, 2: {"corners": 5}})
        store.update_analysis({2: {"shape": "polygonal", "n_dimples": 1, "rim_radius": 0.4}})
        table = store.table()
    assert list(table.columns[:14]) == SPEC_COLUMNS
    assert list(table.columns[14:18]) == SPEC_ANALYSIS
    assert set(table.columns[18:]) == {"converged", "phase", "rim_radius"}
    assert table["step"].tolist() == [0, 1, 2]
    assert table["iterations"].dtype == np.int64
    assert table.loc[2, "shape"] == "polygonal" and table.loc[2, "corners"] == 5
    assert pd.isna(table.loc[0, "shape"]) and table["E_before_c0_cycle"].isna().all()
    csv = pd.read_csv(tmp_path / "run" / "table.csv")  # the convenience copy agrees
    assert list(csv.columns) == list(table.columns)
    for column in ["dV_over_V", "E_total", "min_distance", "E_stretch"]:
        assert csv[column].to_numpy().tobytes() == table[column].to_numpy().tobytes()



def test_table_csv_reads_back_as_the_table(tmp_path):
    """Every cell of table.csv reads back (pandas) as the table's value: floats to the bit,
    integers, an integer column with a gap, booleans, missing values, infinities and text
    that needs quoting."""
    with _create(tmp_path / "run") as store:
        for k in range(4):
            record = _record(k) | {"pressure": [np.inf, -np.inf, np.nan, 5e-324][k],
                                   "message": ['a, "quoted" note', None, "plain", "x\ny"][k]}
            if k == 2:
                record["inertia"] = None
            store.append_step(k, store.X0, record)
        store.update_analysis({1: {"W": 3, "shape": "capsule"}})
        table = store.table()
    csv = pd.read_csv(tmp_path / "run" / "table.csv", keep_default_na=False,
                      na_values=[""])
    assert list(csv.columns) == list(table.columns)
    for column in table.columns:
        got, want = csv[column], table[column]
        if want.dtype.kind == "f" or column in ("inertia", "W", "n_dimples", "corners"):
            np.testing.assert_array_equal(got.to_numpy(dtype=float),
                                          want.to_numpy(dtype=float, na_value=np.nan))
        else:
            assert [None if pd.isna(v) else v for v in got] == \
                [None if pd.isna(v) else v for v in want], column
    assert table["inertia"].dtype == "Int64" and table["iterations"].dtype == np.int64
    assert csv["iterations"].dtype == np.int64  # integers are written as integers

def test_empty_run_table_has_spec_header(tmp_path):
    with _create(tmp_path / "run") as store:
        assert store.last_step is None and store.steps == []
        assert list(store.table().columns) == SPEC_COLUMNS and len(store.table()) == 0
    assert (tmp_path / "run" / "table.csv").read_text().strip() == ",".join(SPEC_COLUMNS)
    assert tuple(SPEC_COLUMNS) == TABLE_COLUMNS


# ----------------------------------------------------------------------------- crash safety

def test_exception_inside_atomic_replace_leaves_previous_state(tmp_path, monkeypatch):
    with _create(tmp_path / "run") as store:
        store.append_step(0, store.X0, _record(0))
        store.append_step(1, 0.9 * store.X0, _record(1))
        table_before = (tmp_path / "run" / "table.csv").read_bytes()

        def crash(src, dst):
            raise OSError("simulated crash during rename")
        monkeypatch.setattr(os, "replace", crash)
        with pytest.raises(OSError, match="simulated"):
            store.append_step(2, 0.8 * store.X0, _record(2))
        monkeypatch.undo()
        assert store.steps == [0, 1]
        assert (tmp_path / "run" / "table.csv").read_bytes() == table_before
        leftovers = [p.name for p in (tmp_path / "run").rglob(".tmp.*")]
        assert leftovers == []
        store.append_step(2, 0.8 * store.X0, _record(2))  # the run goes on
        assert store.steps == [0, 1, 2]
        assert store.positions(1).tobytes() == (0.9 * store.X0).tobytes()


def test_stale_temporaries_are_ignored_and_removed_by_the_next_writer(tmp_path):
    with _create(tmp_path / "run") as store:
        store.append_step(0, store.X0, _record(0))
    partial = tmp_path / "run" / "steps" / ".tmp.step_000001.h5.999.deadbeef"
    partial.write_bytes(b"\x89HDF\r\n half a file")  # what a kill mid-write leaves
    stale_meta = tmp_path / "run" / ".tmp.run.json.999.cafe0001"
    stale_meta.write_text("{")
    reader = RunStore.open(tmp_path / "run")
    assert reader.steps == [0] and len(reader.table()) == 1
    with _create(tmp_path / "run") as store:  # resuming writer
        assert not partial.exists() and not stale_meta.exists()
        store.append_step(1, store.X0, _record(1))
        assert store.steps == [0, 1]


WRITER_SCRIPT = textwrap.dedent("""
    import os, sys, time
    import numpy as np
    from shellbuckle.store import RunStore

    if len(sys.argv) > 2:  # freeze inside the write of step argv[2], data half written
        freeze_at, real_fsync = int(sys.argv[2]), os.fsync

        def fsync(fd):
            name = os.readlink(f"/proc/self/fd/{fd}")
            if f".tmp.step_{freeze_at:06d}.h5." in name:
                os.ftruncate(fd, os.fstat(fd).st_size // 2)
                print("frozen", flush=True)
                time.sleep(600)
            real_fsync(fd)
        os.fsync = fsync

    def positions(k, n):
        return np.random.default_rng(k).normal(size=(n, 3)) * (1.0 + k)

    n = 20000
    X0 = positions(0, n)
    faces = np.arange(3 * (n // 3)).reshape(-1, 3)
    store = RunStore.create(sys.argv[1], params={"gamma": 271.0}, protocol={"dv": 0.019},
                            X0=X0, faces=faces)
    k = 0 if store.last_step is None else store.last_step + 1
    print("ready", k, flush=True)
    while True:
        store.append_step(k, positions(k, n), {"dV_over_V": 0.019 * k, "E_total": k / 3})
        k += 1
""")


def _positions(k, n=20000):
    return np.random.default_rng(k).normal(size=(n, 3)) * (1.0 + k)


@pytest.mark.parametrize("kills", [3, pytest.param(30, marks=pytest.mark.slow)])
def test_sigkill_at_random_moments_never_loses_or_corrupts_a_step(tmp_path, kills):
    script = tmp_path / "writer.py"
    script.write_text(WRITER_SCRIPT)
    folder = tmp_path / "run"
    rng = random.Random(12345 + kills)
    before, killed_mid_write = 0, 0
    for _ in range(kills):
        proc = subprocess.Popen([sys.executable, str(script), str(folder)],
                                stdout=subprocess.PIPE, text=True)
        ready = proc.stdout.readline().split()
        assert ready[0] == "ready" and int(ready[1]) == before  # resumed after the last step
        time.sleep(rng.uniform(0.05, 0.4))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        proc.stdout.close()
        killed_mid_write += any((folder / "steps").glob(".tmp.*"))
        store = RunStore.open(folder)
        steps = store.steps
        assert steps == list(range(len(steps))) and len(steps) > before
        for k in steps:
            assert store.positions(k).tobytes() == _positions(k).tobytes()
            assert store.record(k) == {"step": k, "dV_over_V": 0.019 * k, "E_total": k / 3}
        assert not store.writer_active  # the kernel released the dead writer's lock
        assert store.status == "running"
        before = len(steps)
    assert len(store.table()) == before
    if kills >= 30:  # the kills did land inside step writes, leaving partial temporaries
        assert killed_mid_write > 0


def test_a_run_killed_outright_reads_interrupted_while_its_writer_lives_it_reads_running(
        tmp_path):
    # run.json of a killed run keeps "running" (nothing could write its status); whether a
    # process still writes it is what the writer lock tells
    script = tmp_path / "writer.py"
    script.write_text(WRITER_SCRIPT)
    folder = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, str(script), str(folder)],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().split() == ["ready", "0"]
        while RunStore.open(folder).last_step is None:
            time.sleep(0.01)
        assert RunStore.open(folder).current_status() == ("running", None)  # it is written
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        proc.stdout.close()
    text = (folder / "run.json").read_bytes()
    store = RunStore.open(folder)
    status, message = store.current_status()
    assert store.status == "running" and status == "interrupted"
    assert f"after step {store.last_step};" in message
    assert f"`shellbuckle resume {folder}` continues it" in message
    assert (folder / "run.json").read_bytes() == text  # asking writes nothing
    with RunStore.resume(folder) as writer:  # its own writer: running
        assert writer.current_status() == ("running", None)
        assert RunStore.open(folder).current_status() == ("running", None)


def test_a_run_that_ends_while_its_status_is_asked_reads_as_it_ended(tmp_path):
    folder = tmp_path / "run"
    writer = _create(folder)
    writer.append_step(0, writer.X0, _record(0))
    reader = RunStore.open(folder)  # its run.json said "running" when it was read
    writer.set_status("finished", "reached the target volume")
    writer.close()
    assert reader.status == "running"
    assert reader.current_status() == ("finished", "reached the target volume")


def test_a_status_that_cannot_be_probed_is_the_stored_one(tmp_path, monkeypatch):
    # a read-only copy of a run folder: the lock file cannot be opened for the probe
    from shellbuckle.store.atomic import FileLock

    folder = tmp_path / "run"
    with _create(folder) as store:
        store.append_step(0, store.X0, _record(0))

    def refused(self, patience=0.1):
        raise PermissionError(13, "Permission denied", str(self.path))

    monkeypatch.setattr(FileLock, "is_held_elsewhere", refused)
    assert RunStore.open(folder).current_status() == ("running", None)


def test_without_flock_a_running_run_reads_running(tmp_path, monkeypatch):
    # where locks are no-ops (Windows) a live writer cannot be told from a killed one: the
    # stored status, never the advice to resume (a second writer would not be refused)
    from shellbuckle.store import atomic

    folder = tmp_path / "run"
    with _create(folder) as store:
        store.append_step(0, store.X0, _record(0))
    assert RunStore.open(folder).current_status()[0] == "interrupted"
    monkeypatch.setattr(atomic, "fcntl", None)
    assert RunStore.open(folder).current_status() == ("running", None)


@pytest.mark.skipif(not Path("/proc/self/fd").exists(), reason="needs /proc")
def test_sigkill_inside_a_step_write_keeps_the_previous_steps_and_resumes(tmp_path):
    script = tmp_path / "writer.py"
    script.write_text(WRITER_SCRIPT)
    folder = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, str(script), str(folder), "4"],
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().split() == ["ready", "0"]
    assert proc.stdout.readline().strip() == "frozen"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    proc.stdout.close()
    partial = list((folder / "steps").glob(".tmp.step_000004.h5.*"))
    assert len(partial) == 1
    with pytest.raises(OSError):  # the half-written temporary is not a readable HDF5 file
        h5py.File(partial[0], "r").close()
    store = RunStore.open(folder)
    assert store.steps == [0, 1, 2, 3]
    assert all(store.positions(k).tobytes() == _positions(k).tobytes() for k in range(4))
    with RunStore.resume(folder) as resumed:
        assert not partial[0].exists()  # cleaned by the resuming writer
        resumed.append_step(4, _positions(4), {"dV_over_V": 0.019 * 4, "E_total": 4 / 3})
    assert RunStore.open(folder).positions(4).tobytes() == _positions(4).tobytes()


# ----------------------------------------------------------------------------- identity

def test_a_different_run_is_refused_and_the_same_run_is_resumed(tmp_path):
    folder = tmp_path / "run"
    with _create(folder) as store:
        store.append_step(0, store.X0, _record(0))
        run_id = store.run_id
    with pytest.raises(ValueError, match=r"holds a different run \(params\.gamma: stored 271\.0, "
                                         r"requested 743\.0\).*shellbuckle resume"):
        _create(folder, params={**PARAMS, "gamma": 743.0})
    with pytest.raises(ValueError, match=r"protocol\.minimizer\.gtol"):
        _create(folder, protocol={**PROTOCOL, "minimizer": {"gtol": 1e-8, "max_iter": 200}})
    X0, faces = _mesh(seed=5)
    with pytest.raises(ValueError, match=r"mesh_sha256"):
        _create(folder, X0=X0, faces=faces)
    # the same run, given with numpy/tuple types, is the same identity: reopened for resuming
    same = {**PARAMS, "gamma": np.float64(271)}
    with _create(folder, params=same, protocol={**PROTOCOL, "seed": np.int32(7)}) as store:
        assert store.run_id == run_id and store.steps == [0]
        assert len(store.meta["sessions"]) == 2
        store.append_step(1, store.X0, _record(1))
    assert RunStore.open(folder).steps == [0, 1]


def test_a_second_live_writer_is_refused(tmp_path):
    folder = tmp_path / "run"
    first = _create(folder)
    assert RunStore.open(folder).writer_active
    with pytest.raises(ValueError, match="another process is writing"):
        _create(folder)
    reader = RunStore.open(folder)
    with pytest.raises(ValueError, match="another process is writing"):
        reader.set_status("finished")
    first.append_step(0, first.X0, _record(0))
    assert reader.steps == [0]  # reading while a run is being written is fine
    first.close()
    with _create(folder) as again:
        again.set_status("finished", "reached the target volume")
    meta = json.loads((folder / "run.json").read_text())
    assert meta["status"] == "finished" and meta["message"] == "reached the target volume"


def test_refusals_of_bad_paths_and_bad_steps(tmp_path):
    (tmp_path / "afile").write_text("x")
    with pytest.raises(ValueError, match="is an existing file"):
        _create(tmp_path / "afile")
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="non-empty folder that is not a shellbuckle run"):
        _create(tmp_path / "busy")
    with pytest.raises(ValueError, match="not a shellbuckle run folder"):
        RunStore.resume(tmp_path / "busy")
    for bad, message in [(tmp_path / "missing", "does not exist"),
                         (tmp_path / "afile", "is a file"),
                         (tmp_path / "busy", "not a shellbuckle run folder")]:
        with pytest.raises(ValueError, match=message):
            RunStore.open(bad)
    store = _create(tmp_path / "run")
    with pytest.raises(ValueError, match="the next step is 0"):
        store.append_step(1, store.X0, {})
    store.append_step(0, store.X0, {})
    with pytest.raises(ValueError, match="already stored"):
        store.append_step(0, store.X0, {})
    store.append_step(0, 2 * store.X0, {"E_total": 1.0}, overwrite=True)
    assert store.positions(0).tobytes() == (2 * store.X0).tobytes()
    assert store.record(0) == {"step": 0, "E_total": 1.0}
    with pytest.raises(ValueError, match=r"must be a finite \(30, 3\) array"):
        store.append_step(1, store.X0[:-1], {})
    with pytest.raises(ValueError, match="finite"):
        store.append_step(1, np.full_like(store.X0, np.nan), {})
    with pytest.raises(ValueError, match="record of step 1.E_bend must be a number"):
        store.append_step(1, store.X0, {"E_bend": [1.0, 2.0]})
    with pytest.raises(ValueError, match="says step 5"):
        store.append_step(1, store.X0, {"step": 5})
    with pytest.raises(ValueError, match=r"step 7 is not in run .* \(finished steps 0..0\)"):
        store.positions(7)
    with pytest.raises(ValueError, match="reserved"):
        store.update_analysis({0: {"E_total": 3.0}})
    with pytest.raises(ValueError, match="status 'done' is not one of"):
        store.set_status("done")
    store.close()


def test_interrupted_creation_is_completed_and_a_hole_is_reported(tmp_path):
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "mesh.h5").write_bytes(b"half")  # killed before run.json appeared
    (folder / ".tmp.run.json.1.abcd0123").write_text("{")
    with _create(folder) as store:
        assert store.X0.tobytes() == _mesh()[0].tobytes()
        for k in range(3):
            store.append_step(k, store.X0, {})
    (folder / "steps" / "step_000001.h5").unlink()
    store = RunStore.open(folder)  # the hole is a damaged step; the others read
    assert store.steps == [0, 2]
    assert store.damaged == {1: "steps/step_000001.h5 is missing although later steps exist"}
    with pytest.raises(ValueError, match=r"step 1 of run .* is damaged .*--step 0 --out"):
        RunStore.resume(folder)


# ----------------------------------------------------------------------------- branches

def test_branch_starts_from_the_parent_step_and_resumes(tmp_path):
    with _create(tmp_path / "parent") as parent:
        for k in range(3):
            parent.append_step(k, (1 - 0.1 * k) * parent.X0, _record(k), {"a": np.arange(k)})
        inflate = {**PROTOCOL, "schedule": [0.02, 0.0]}
        child = parent.branch(tmp_path / "child", 2, protocol=inflate)
        assert child.steps == [0]
        assert child.positions(0).tobytes() == parent.positions(2).tobytes()
        assert child.X0.tobytes() == parent.X0.tobytes()
        assert child.record(0) == {**parent.record(2), "step": 0}
        assert child.parent["run_id"] == parent.run_id and child.parent["step"] == 2
        assert child.protocol["schedule"] == [0.02, 0.0] and child.params == parent.params
        child.append_step(1, parent.X0, _record(1))
        child.close()
        with parent.branch(tmp_path / "child", 2, protocol=inflate) as again:
            assert again.steps == [0, 1] and again.run_id == child.run_id
        with RunStore.resume(tmp_path / "child") as again:  # resume needs no identity
            again.append_step(2, parent.X0, _record(2))
            again.set_status("paused", "stopped after 1 new step")
        assert RunStore.open(tmp_path / "child").status == "paused"
        with pytest.raises(ValueError, match=r"parent\.step: stored 2, requested 1"):
            parent.branch(tmp_path / "child", 1, protocol=inflate)
        with pytest.raises(ValueError, match="holds a different run"):
            parent.branch(tmp_path / "parent", 1)


# ----------------------------------------------------------------------------- readers

def test_table_cli_prints_spec_header_and_refuses_bad_dir(tmp_path):
    with _create(tmp_path / "run") as store:
        for k in range(2):
            store.append_step(k, store.X0, _record(k))
        store.update_analysis({1: {"shape": "capsule", "n_dimples": 1}})
    code, out, err = _cli(["table", str(tmp_path / "run"), "--csv"])
    assert code == 0 and err == ""
    lines = out.splitlines()
    assert lines[0].split(",")[:16] == SPEC_COLUMNS + ["shape", "n_dimples"]
    assert len(lines) == 3
    parsed = pd.read_csv(io.StringIO(out))
    assert parsed["E_total"].tolist() == [1.0 / 3.0, 1.0 / 3.0 + 1]
    code, out, err = _cli(["table", str(tmp_path / "run"), "--all"])
    header = out.splitlines()[0]
    body = "\n".join(line for line in out.splitlines() if not line.startswith("#"))
    assert header.startswith("# gamma = ") and "energy convention helfrich" in header
    assert code == 0 and body.split()[:14] == SPEC_COLUMNS and "capsule" in body
    for bad in [tmp_path / "nowhere", tmp_path]:
        code, out, err = _cli(["table", str(bad)])
        assert code == 2 and out == "" and str(bad) in err and "Traceback" not in err


def test_documented_snippet_reads_a_run_without_shellbuckle(tmp_path):
    folder = tmp_path / "run"
    with _create(folder) as store:
        for k in range(3):
            store.append_step(k, (1 + k) * store.X0, _record(k))
    doc = run_module.__doc__
    snippet = textwrap.dedent(doc.split("pandas::\n")[1].split("\nJSON values")[0])
    program = "\n".join([
        f"DIR = {str(folder)!r}", snippet,
        "import sys, numpy as np",
        "assert not any(m.startswith('shellbuckle') for m in sys.modules)",
        "np.save(sys.argv[1], np.stack(X))",
        "print(json.dumps({'run': run, 'columns': list(table.columns),",
        "                  'E_total': table['E_total'].tolist(), 'faces': faces.tolist()}))"])
    out = subprocess.run([sys.executable, "-I", "-c", program, str(tmp_path / "X.npy")],
                         capture_output=True, text=True, check=True, cwd=tmp_path).stdout
    got = json.loads(out)
    X = np.load(tmp_path / "X.npy")
    assert X.tobytes() == np.stack([(1 + k) * _mesh()[0] for k in range(3)]).tobytes()
    assert got["faces"] == _mesh()[1].tolist()
    assert got["run"]["params"] == PARAMS and got["run"]["format"] == "shellbuckle-run"
    assert {"numpy", "scipy", "h5py", "python", "shellbuckle"} <= set(got["run"]["versions"])
    assert got["E_total"] == [_record(k)["E_total"] for k in range(3)]
    assert got["columns"][0] == "step"
    assert re.fullmatch(r"[0-9a-f]{32}", got["run"]["run_id"])


def test_versions_name_the_source_commit_when_run_from_a_git_checkout():
    # oracle: git's own answer for the package directory; the package version alone does not
    # tell two commits apart
    package = Path(run_module.__file__).resolve().parents[1]
    git = ["git", "-C", str(package)]
    run_module.source_commit.cache_clear()
    versions = run_module._versions()
    try:
        tracked = subprocess.run(git + ["ls-files", "--", "__init__.py"], capture_output=True,
                                 text=True, check=True).stdout.strip()
        head = subprocess.run(git + ["rev-parse", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        tracked = head = ""
    if not tracked:  # an installed copy: the commit its build recorded, if any
        built = package / "_build.json"
        expected = json.loads(built.read_text())["git"] if built.is_file() else None
        assert versions.get("shellbuckle_git") == expected
        return
    commit = versions["shellbuckle_git"]
    assert re.fullmatch(r"[0-9a-f]{12}(\+dirty)?", commit) and head.startswith(commit[:12])
    dirty = subprocess.run(git + ["status", "--porcelain", "--", "."], capture_output=True,
                           text=True, check=True).stdout.strip()
    assert commit.endswith("+dirty") == bool(dirty)


def test_an_installed_copy_names_the_commit_its_build_recorded(tmp_path):
    """Outside a git checkout (``pip install .`` copies the package without ``.git``) the
    commit is the one ``setup.py`` wrote into ``_build.json``; without that file, or with a
    damaged one, none."""
    from shellbuckle.store.meta import source_commit

    package = tmp_path / "shellbuckle"
    package.mkdir()
    (package / "__init__.py").write_text("")
    assert source_commit(package) is None
    (package / "_build.json").write_text('{"git": "0123456789ab+dirty"}\n')
    source_commit.cache_clear()
    assert source_commit(package) == "0123456789ab+dirty"
    (package / "_build.json").write_text("{not json")
    source_commit.cache_clear()
    assert source_commit(package) is None
    source_commit.cache_clear()


def test_the_build_records_the_commit_the_store_reads_from_the_checkout(monkeypatch):
    """``setup.py``'s commit (what ``pip install .`` writes into the package) and the run
    store's own reading of the checkout are the same string, ``+dirty`` included."""
    import runpy

    setuptools = pytest.importorskip("setuptools")  # not in every environment (Python >= 3.12)
    from shellbuckle.store.meta import source_commit

    setup_py = Path(run_module.__file__).resolve().parents[3] / "setup.py"
    package = Path(run_module.__file__).resolve().parents[1]
    source_commit.cache_clear()
    if not setup_py.is_file() or source_commit() is None or (package / "_build.json").exists():
        pytest.skip("not a git checkout of the source")
    monkeypatch.setattr(setuptools, "setup", lambda **kwargs: None)
    hook = runpy.run_path(str(setup_py))
    assert hook["_commit"]() == source_commit()


def test_asking_whether_a_lock_is_held_does_not_make_a_free_lock_look_held(tmp_path):
    # asking takes the lock for a moment (flock has no test): a non-blocking acquire that
    # meets such a probe from another process must not report the lock as held (a run's
    # writer or location lock refused while nobody held it)
    from shellbuckle.store.atomic import FileLock

    path = tmp_path / ".lock"
    path.touch()
    asking = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import time
        from shellbuckle.store.atomic import FileLock
        probe, end = FileLock({str(path)!r}), time.monotonic() + 4
        print("asking", flush=True)
        while time.monotonic() < end:
            probe.is_held_elsewhere()
        """)], stdout=subprocess.PIPE, text=True)
    try:
        assert asking.stdout.readline().strip() == "asking"
        refused, end = 0, time.monotonic() + 2
        while time.monotonic() < end:
            lock = FileLock(path)
            if lock.acquire():
                lock.release()
            else:
                refused += 1
    finally:
        asking.wait(timeout=60)
    assert refused == 0
    holder = FileLock(path)  # a real holder is seen, and keeps the lock from others
    assert holder.acquire() and FileLock(path).is_held_elsewhere()
    assert not FileLock(path).acquire()
    holder.release()
    assert not FileLock(path).is_held_elsewhere()


def test_an_analysis_entry_that_is_not_an_analysis_is_left_out_and_made_again(tmp_path, caplog):
    from shellbuckle.analysis import analyze_run
    from shellbuckle.mesh import icosphere
    from shellbuckle.params import ShellParameters
    from shellbuckle.run import deflate
    from shellbuckle.store.catalogue import analysis_complete

    from shellbuckle.run import resume

    params = ShellParameters.from_gamma(271)
    run = deflate(icosphere(3), params, until=0.1, out=tmp_path / "r", locate=False,
                  progress=False, threads=1, max_steps=2)
    analyze_run(run)
    store = RunStore.open(run.path)
    whole = store.analysis()
    data = json.loads((run.path / "analysis.json").read_text())
    data["1"] = [1]  # whole JSON, not the analysis of a step
    (run.path / "analysis.json").write_text(json.dumps(data))
    with caplog.at_level("WARNING"):
        assert sorted(store.analysis()) == [0, 2]
    assert caplog.text.count("the entries of steps 1 are not analyses") == 1
    assert len(store.table()) == 3 and not analysis_complete(store)  # read past it
    caplog.clear()
    with caplog.at_level("WARNING"):  # table.csv, written after every step, says nothing
        run = resume(run.path, locate=False, progress=False, threads=1)
    assert len(run.store.table()) == 6
    assert caplog.text.count("are not analyses") <= 1
    analyze_run(run)  # made again, the same classification
    store = RunStore.open(run.path)
    assert store.analysis()[1] == whole[1] and analysis_complete(store)
