"""Damaged run folders: the good steps stay readable, the damaged ones are named, and a resume
heals a damaged last step or explains a damaged middle one.

Oracles: the same small run read before the fault (its table and positions, bit for bit), and
the determinism of the protocol given the seed and the step index (a resumed run equals the
uninterrupted one bit for bit, tests/test_run.py), so a step computed again after it was set
aside equals the step it replaces in every column but its wall time.
"""

from __future__ import annotations

import io
import json
import logging
import re
import shutil
from contextlib import redirect_stderr, redirect_stdout

import h5py
import numpy as np
import pandas as pd
import pytest

from shellbuckle import cli
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.run import Run, deflate, resume
from shellbuckle.store import RunStore

PARAMS = ShellParameters.from_gamma(271.0, nu=1 / 3)
OPTIONS = dict(dv=0.03, until=0.18, jiggle=0.02, seed=7, threads=1)  # steps 0..6
MIDDLE, LAST = 3, 6


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """A finished small run (162 vertices, steps 0..6), its table and positions."""
    run = deflate(icosphere(4), PARAMS, out=tmp_path_factory.mktemp("ref") / "run", **OPTIONS)
    assert run.status == "finished" and run.steps == list(range(LAST + 1))
    return run.path, run.table, {k: run.positions(k) for k in run.steps}


@pytest.fixture
def folder(tmp_path, reference):
    """A fresh copy of the reference run to damage."""
    return shutil.copytree(reference[0], tmp_path / "run")


def _step(folder, k):
    return folder / "steps" / f"step_{k:06d}.h5"


def _same_rows(table, expected, ignore=()):
    cols = [c for c in expected.columns if c not in ignore]
    pd.testing.assert_frame_equal(table[cols].reset_index(drop=True),
                                  expected[cols].reset_index(drop=True), check_exact=True)


# ----------------------------------------------------------------------------- step faults

def _truncate(path):
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _empty(path):
    path.write_bytes(b"")


def _junk(path):
    path.write_bytes(np.random.default_rng(0).bytes(path.stat().st_size))


def _flip_positions(path):
    # a few bytes inside X's raw data: the file still opens, only the checksum can tell
    with h5py.File(path, "r") as f:
        offset = f["X"].id.get_offset()
    data = bytearray(path.read_bytes())
    data[offset + 100: offset + 104] = bytes(b ^ 0x5A for b in data[offset + 100: offset + 104])
    path.write_bytes(bytes(data))


def _break_record(path):
    with h5py.File(path, "a") as f:
        f.attrs["record_json"] = '{"step": 3, "E_total": '


def _remove(path):
    path.unlink()


def _of_another_run(path):
    # the file as another run on the same mesh writes it: only the run it names differs
    with h5py.File(path, "a") as f:
        f.attrs["run_id"] = "0123456789abcdef" * 2


STEP_FAULTS = {
    "truncated": (_truncate, r"cannot be read as HDF5, truncated or overwritten"),
    "empty": (_empty, r"is empty \(0 bytes\)"),
    "junk": (_junk, r"is not an HDF5 file"),
    "corrupted positions": (_flip_positions, r"checksum mismatch in the positions X"),
    "broken record": (_break_record, r"record \(attribute record_json\) is not valid JSON"),
    "missing file": (_remove, r"is missing although later steps exist"),
    "another run's step": (_of_another_run, r"is a step of another run \(run id "
                           r"0123456789ab\.\.\., this run's is [0-9a-f]{12}\.\.\.\)"),
}


@pytest.mark.parametrize("k, fault", [(k, f) for k in (MIDDLE, LAST) for f in STEP_FAULTS
                                      if (k, f) != (LAST, "missing file")])  # a shorter run
def test_a_damaged_step_is_named_and_the_good_steps_read_as_before(folder, reference, fault, k,
                                                                   caplog):
    damage, reason = STEP_FAULTS[fault]
    _, table, positions = reference
    damage(_step(folder, k))
    with caplog.at_level(logging.WARNING, logger="shellbuckle.store"):
        run = Run.open(folder)
        good = [j for j in range(LAST + 1) if j != k]
        assert run.steps == good
    assert list(run.damaged) == [k]
    assert f"step_{k:06d}.h5" in run.damaged[k]
    assert re.search(reason, run.damaged[k]), run.damaged[k]
    assert f"step {k}: steps/step_{k:06d}.h5" in caplog.text  # one warning names it
    _same_rows(run.table, table[table["step"] != k])
    for j in good:
        assert run.positions(j).tobytes() == positions[j].tobytes()
    with pytest.raises(ValueError, match=rf"step {k} .*is damaged: steps/step_{k:06d}\.h5"):
        run.positions(k)
    with pytest.raises(ValueError, match=rf"step {k} .*is damaged"):
        run.step(k)
    assert run.step(-1) == good[-1]


@pytest.mark.parametrize("fault", [f for f in STEP_FAULTS if f != "missing file"])
def test_resume_sets_a_damaged_last_step_aside_and_computes_it_again(folder, reference, fault):
    damage, _ = STEP_FAULTS[fault]
    _, table, positions = reference
    damage(_step(folder, LAST))
    damaged_bytes = _step(folder, LAST).read_bytes()
    done = resume(folder)
    assert done.status == "finished" and done.damaged == {}
    assert done.steps == list(range(LAST + 1))
    _same_rows(done.table, table, ignore=("wall_s",))  # bit for bit, the wall time aside
    for k in done.steps:
        assert done.positions(k).tobytes() == positions[k].tobytes()
    aside = folder / "steps" / f"step_{LAST:06d}.h5.damaged-1"
    assert aside.read_bytes() == damaged_bytes  # set aside, never deleted
    assert json.loads((folder / "run.json").read_text())["sessions"][-1]["set_aside"] == \
        [aside.name]
    assert pd.read_csv(folder / "table.csv")["step"].tolist() == list(range(LAST + 1))


def test_two_damaged_last_steps_are_both_set_aside(folder, reference):
    _, table, _ = reference
    _truncate(_step(folder, LAST - 1))
    _empty(_step(folder, LAST))
    _empty(folder / "steps" / f"step_{LAST:06d}.h5.damaged-1")  # an earlier one is kept
    done = resume(folder)
    _same_rows(done.table, table, ignore=("wall_s",))
    assert (folder / "steps" / f"step_{LAST - 1:06d}.h5.damaged-1").exists()
    assert (folder / "steps" / f"step_{LAST:06d}.h5.damaged-2").exists()


@pytest.mark.parametrize("fault", STEP_FAULTS)
def test_resume_stops_at_a_damaged_middle_step_and_says_where_to_continue(folder, fault):
    damage, _ = STEP_FAULTS[fault]
    damage(_step(folder, MIDDLE))
    before = sorted(p.name for p in (folder / "steps").iterdir())
    meta_before = (folder / "run.json").read_bytes()
    with pytest.raises(ValueError) as info:
        resume(folder)
    message = str(info.value)
    assert f"step {MIDDLE} of run {folder} is damaged (steps/step_{MIDDLE:06d}.h5" in message
    k = MIDDLE - 1
    assert f"`shellbuckle continue {folder} --step {k} --out NEW_DIR`" in message
    assert f"`shellbuckle deflate --from {folder} --step {k} --out NEW_DIR`" in message
    assert sorted(p.name for p in (folder / "steps").iterdir()) == before  # nothing written
    assert (folder / "run.json").read_bytes() == meta_before
    assert not RunStore.open(folder).writer_active  # the lock was let go


def test_the_cli_refuses_a_damaged_middle_step_with_exit_2(folder):
    _junk(_step(folder, MIDDLE))
    code, _, err = _cli(["resume", str(folder), "--quiet", "--no-plot"])
    assert code == 2 and "Traceback" not in err
    assert f"--step {MIDDLE - 1}" in err


def test_table_cli_prints_the_good_steps_of_a_damaged_run(folder, reference):
    _flip_positions(_step(folder, MIDDLE))
    code, out, _ = _cli(["table", str(folder), "--csv"])
    assert code == 0
    assert pd.read_csv(io.StringIO(out))["step"].tolist() == [0, 1, 2, 4, 5, 6]


def test_a_step_file_without_checksums_reads_unchecked(folder, reference, caplog):
    # files written before the checksums: no check possible, said in the debug log only
    with h5py.File(_step(folder, MIDDLE), "a") as f:
        del f.attrs["sha256"]
    with caplog.at_level(logging.DEBUG, logger="shellbuckle.store"):
        run = Run.open(folder)
        assert run.damaged == {} and run.steps == list(range(LAST + 1))
        assert run.positions(MIDDLE).tobytes() == reference[2][MIDDLE].tobytes()
    assert {r.levelno for r in caplog.records if "no checksums" in r.getMessage()} == \
        {logging.DEBUG}


@pytest.fixture(scope="module")
def same_mesh_other_gamma(tmp_path_factory):
    """A run on the reference's mesh with its options but another gamma: its step files and
    its run.json fit the reference folder by shape and mesh, and are another shell's."""
    run = deflate(icosphere(4), ShellParameters.from_gamma(400.0, nu=1 / 3),
                  out=tmp_path_factory.mktemp("other") / "run", **OPTIONS)
    assert run.status == "finished" and run.steps == list(range(LAST + 1))
    return run.path


def test_a_step_copied_from_a_run_on_the_same_mesh_is_not_read_as_this_runs(
        folder, reference, same_mesh_other_gamma):
    """The copied file is whole and of the right shape, so only the run id it carries tells:
    it is named, left out, and a resume computes this run's own step again."""
    _, table, positions = reference
    copied = same_mesh_other_gamma / "steps" / f"step_{LAST:06d}.h5"
    assert RunStore.open(same_mesh_other_gamma).positions(LAST).tobytes() != \
        positions[LAST].tobytes()
    shutil.copyfile(copied, _step(folder, LAST))
    run = Run.open(folder)
    assert run.steps == list(range(LAST)) and "is a step of another run" in run.damaged[LAST]
    done = resume(folder)
    assert done.damaged == {}
    _same_rows(done.table, table, ignore=("wall_s",))
    assert done.positions(LAST).tobytes() == positions[LAST].tobytes()


def test_a_step_file_that_names_no_run_is_read_as_before(folder, reference):
    # files written before step files named their run
    for k in range(LAST + 1):
        with h5py.File(_step(folder, k), "a") as f:
            del f.attrs["run_id"]
    run = Run.open(folder)
    assert run.damaged == {} and run.steps == list(range(LAST + 1))
    assert run.positions(LAST).tobytes() == reference[2][LAST].tobytes()


# ----------------------------------------------------------------------------- run.json faults

def test_missing_run_json_fields_are_named_and_the_copy_in_mesh_h5_restores_them(folder,
                                                                                  reference):
    _, table, positions = reference
    meta = json.loads((folder / "run.json").read_text())
    del meta["params"], meta["status"]
    meta["mesh"].pop("sha256")
    (folder / "run.json").write_text(json.dumps(meta))
    for call in (Run.open, resume):
        with pytest.raises(ValueError, match=r"lacks the field\(s\) it needs: params \(missing"
                                             r"\), status \(missing\), mesh.sha256 \(missing\)"
                                             r".*move run.json aside"):
            call(folder)
    code, _, err = _cli(["table", str(folder)])
    assert code == 2 and "params (missing)" in err
    (folder / "run.json").rename(folder / "run.json.bad")  # what the message says to do
    run = Run.open(folder)
    _same_rows(run.table, table)
    for k in run.steps:
        assert run.positions(k).tobytes() == positions[k].tobytes()
    assert run.params == PARAMS
    done = resume(folder)
    assert done.status == "finished"
    _same_rows(done.table, table)


def test_a_missing_run_json_is_rebuilt_from_mesh_h5(folder, reference):
    _, table, positions = reference
    original = json.loads((folder / "run.json").read_text())
    (folder / "run.json").unlink()
    run = Run.open(folder)  # read: rebuilt in memory
    assert not (folder / "run.json").exists()
    assert run.status == "interrupted" and "rebuilt" in run.store.meta["message"]
    _same_rows(run.table, table)
    for k in run.steps:
        assert run.positions(k).tobytes() == positions[k].tobytes()
    done = resume(folder)  # the last step is the end of the schedule: finished at once
    assert done.status == "finished"
    _same_rows(done.table, table)
    rebuilt = json.loads((folder / "run.json").read_text())
    for key in ("run_id", "created", "params", "protocol", "mesh", "parent", "extra"):
        assert rebuilt[key] == original[key]


def test_a_run_json_lost_before_the_last_step_resumes_to_the_same_table(folder, reference):
    _, table, _ = reference
    (folder / "run.json").unlink()
    for k in (LAST - 1, LAST):
        _step(folder, k).unlink()
    done = resume(folder)
    assert done.status == "finished"
    _same_rows(done.table, table, ignore=("wall_s",))


def test_a_run_killed_before_run_json_existed_resumes_or_runs_again_in_place(tmp_path,
                                                                              reference):
    _, table, _ = reference
    for how in ("resume", "deflate"):
        out = tmp_path / how
        shutil.copytree(reference[0], out)
        (out / "run.json").unlink()
        (out / "table.csv").unlink()
        shutil.rmtree(out / "steps")  # created after mesh.h5, before run.json
        done = resume(out) if how == "resume" else deflate(icosphere(4), PARAMS, out=out,
                                                          **OPTIONS)
        assert done.status == "finished"
        _same_rows(done.table, table, ignore=("wall_s",))


def test_a_lost_run_json_of_an_older_run_says_what_to_do(folder):
    with h5py.File(folder / "mesh.h5", "a") as f:  # mesh.h5 of a run made before the copy
        del f.attrs["run_json"]
    (folder / "run.json").unlink()
    for call in (Run.open, resume):
        with pytest.raises(ValueError, match=r"has step files but no run.json.*cannot be "
                                             r"recovered.*Restore run.json from a backup"):
            call(folder)
    with pytest.raises(ValueError, match="cannot be recovered"):
        deflate(icosphere(4), PARAMS, out=folder, **OPTIONS)


def test_a_missing_steps_folder_is_explained_and_an_empty_one_computes_the_run_again(
        folder, reference):
    _, table, _ = reference
    shutil.rmtree(folder / "steps")
    for call in (Run.open, resume):
        with pytest.raises(ValueError, match=r"has no steps/ folder: the files of its finished "
                                             r"steps .* were moved or deleted.*create an empty "
                                             r"folder"):
            call(folder)
    code, _, err = _cli(["table", str(folder)])
    assert code == 2 and "no steps/ folder" in err
    (folder / "steps").mkdir()  # what the message says to do
    done = resume(folder)
    _same_rows(done.table, table, ignore=("wall_s",))


def _cli(argv):
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = cli.main(argv)
    return code, out.getvalue(), err.getvalue()


def test_a_branch_whose_step_0_is_damaged_is_made_again_from_its_parent(tmp_path):
    # a branch's step 0 is its parent's step: a resume cannot compute it, the branch can
    rng = np.random.default_rng(0)
    X0 = rng.normal(size=(30, 3))
    faces = rng.integers(0, 30, size=(56, 3))
    with RunStore.create(tmp_path / "parent", params={"gamma": 1.0}, protocol={"dv": 0.1},
                         X0=X0, faces=faces) as parent:
        for k in range(3):
            parent.append_step(k, (1 - 0.1 * k) * X0, {"E_total": float(k)})
        parent.branch(tmp_path / "child", 2).close()
    _junk(_step(tmp_path / "child", 0))
    with pytest.raises(ValueError, match=r"step 0 of run .*child is damaged; it is the step "
                                         r"it starts from, step 2 of .*parent.*shellbuckle "
                                         r"continue .*parent --step 2 --out .*child"):
        RunStore.resume(tmp_path / "child")
    with RunStore.open(tmp_path / "parent").branch(tmp_path / "child", 2) as child:
        assert child.steps == [0] and child.damaged == {}
        assert child.positions(0).tobytes() == ((1 - 0.2) * X0).tobytes()
    assert (tmp_path / "child" / "steps" / "step_000000.h5.damaged-1").exists()


def test_a_sweep_catalogue_row_names_the_damaged_steps(tmp_path, folder):
    from shellbuckle.store.catalogue import run_row

    shutil.copytree(folder, tmp_path / "sweep" / "g271")
    _truncate(_step(tmp_path / "sweep" / "g271", MIDDLE))
    row = run_row(tmp_path / "sweep", "g271", {})
    assert row["status"] == "finished" and row["steps"] == LAST
    assert row["message"].startswith("end of the schedule")  # the stop reason still reads
    assert f"damaged step(s) left out: step {MIDDLE}: steps/step_{MIDDLE:06d}.h5" in \
        row["message"]


# ------------------------------------------------------------ a description that is not the run's

def _other_mesh_description(folder, tmp_path):
    other = deflate(icosphere(3), PARAMS, out=tmp_path / "other", **OPTIONS)
    shutil.copyfile(other.path / "run.json", folder / "run.json")


def _changed_reference(folder, tmp_path):
    with h5py.File(folder / "mesh.h5", "r+") as f:
        f["X0"][0, 0] *= 1.01


def _set_protocol(value):
    def damage(folder, tmp_path):
        meta = json.loads((folder / "run.json").read_text())
        meta["protocol"] = value(meta["protocol"])
        (folder / "run.json").write_text(json.dumps(meta))
    return damage


@pytest.mark.parametrize("damage, said", [
    (lambda folder, tmp_path: _truncate(folder / "mesh.h5"), "cannot be read as HDF5"),
    (lambda folder, tmp_path: (folder / "mesh.h5").unlink(), "mesh.h5 is missing"),
    (_other_mesh_description, "does not match the mesh run.json describes"),
    (_changed_reference, "does not match the mesh run.json describes"),
    (_set_protocol(lambda p: p | {"schedule": "x"}), "protocol cannot be read"),
    (_set_protocol(lambda p: {}), "protocol cannot be read"),
], ids=["mesh truncated", "mesh missing", "another mesh's run.json", "reference changed",
        "schedule not numbers", "no protocol"])
def test_resume_refuses_a_run_it_cannot_read_before_writing_anything(folder, tmp_path, damage,
                                                                      said):
    """The description and the mesh are checked before the store records a session: a
    refusal leaves run.json, the status and every step file as they were (no step is set
    aside for a mesh that is not the run's)."""
    damage(folder, tmp_path)
    before = {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    code, _, err = _cli(["resume", str(folder), "--quiet", "--no-plot", "--no-locate"])
    assert code == 2 and "Traceback" not in err and said in err, err
    assert len(err.strip().splitlines()) == 1
    after = {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    assert after == before


def test_a_run_json_of_another_run_on_the_same_mesh_is_refused(folder, tmp_path,
                                                               same_mesh_other_gamma):
    """Its mesh SHA-256 is this folder's, so only the run id of the copy in mesh.h5 tells it
    is another shell's: resume refuses it before writing anything (it would have computed
    the damaged-looking steps again with the other gamma), and so do the readers."""
    shutil.copyfile(same_mesh_other_gamma / "run.json", folder / "run.json")
    before = {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    for argv in (["resume", str(folder), "--quiet", "--no-plot", "--no-locate"],
                 ["export", str(folder), "--step", "-1", "--format", "vtk", "--out",
                  str(tmp_path / "x.vtk")], ["table", str(folder)]):
        code, _, err = _cli(argv)
        assert code == 2 and "Traceback" not in err, err
        assert "run.json is another run's" in err and "mixes two runs" in err, err
        assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.vtk").exists()
    assert {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*")
            if p.is_file()} == before
    with pytest.raises(ValueError, match="mixes two runs"):  # not "every step is damaged"
        Run.open(folder).steps
    (folder / "run.json").rename(folder / "run.json.bad")  # what the message says to do
    assert Run.open(folder).params.gamma == pytest.approx(271.0)


def test_a_mesh_found_good_is_read_once_and_checked_again_when_it_changes(folder, tmp_path,
                                                                        monkeypatch):
    from shellbuckle.store import run as store_run

    RunStore.open(folder).check_mesh()
    reads = []
    real = store_run._read_h5
    monkeypatch.setattr(store_run, "_read_h5", lambda *a: reads.append(a) or real(*a))
    RunStore.open(folder).check_mesh()  # another store of the same folder, the file as it was
    assert reads == []
    _changed_reference(folder, tmp_path)
    with pytest.raises(ValueError, match="does not match the mesh run.json describes"):
        RunStore.open(folder).check_mesh()
    assert len(reads) == 1


def test_a_changed_reference_mesh_is_refused_by_every_reader(folder, tmp_path):
    """A reference shape changed in place is another shell: no new run starts from it, its
    steps are not exported, drawn or located on it, and running its command again does not
    reopen it (exit 2 and every file as it was)."""
    _changed_reference(folder, tmp_path)
    before = {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    for argv in (["continue", str(folder), "--until", "0.3", "--out", str(tmp_path / "c"),
                  "--quiet", "--no-plot"],
                 ["export", str(folder), "--step", "-1", "--format", "vtk", "--out",
                  str(tmp_path / "x.vtk")],
                 ["plot", str(folder), "--out", str(tmp_path / "c")],
                 ["locate", str(folder)],
                 ["deflate", "--icosphere", "4", "--gamma", "271", "--dv", "0.03", "--until",
                  "0.18", "--jiggle", "0.02", "--seed", "7", "--threads", "1", "--out",
                  str(folder), "--quiet", "--no-plot"]):  # the same run again
        code, _, err = _cli(argv)
        assert code == 2 and "does not match the mesh run.json describes" in err, err
        assert len(err.strip().splitlines()) == 1
        assert not (tmp_path / "c").exists() and not (tmp_path / "x.vtk").exists()
    assert {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*")
            if p.is_file()} == before


def test_a_refusal_names_the_folder_once_and_keeps_the_rest_of_its_message(tmp_path,
                                                                          monkeypatch):
    """A folder named `e`: the message keeps every letter e and the paths of its advice."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "e").mkdir()
    (tmp_path / "e" / "run.json").write_text("{bad")
    code, _, err = _cli(["table", "e"])
    assert code == 2 and err.count("DIR e: ") == 1
    assert "e/run.json is not valid JSON (Expecting property name" in err


def _edit_run_json(edit):
    def damage(folder):
        meta = json.loads((folder / "run.json").read_text())
        edit(meta)
        (folder / "run.json").write_text(json.dumps(meta))
    return damage


def _run_json_a_folder(folder):
    (folder / "run.json").unlink()
    (folder / "run.json").mkdir()


@pytest.mark.parametrize("damage, said", [
    (_edit_run_json(lambda m: m.__setitem__("format_version", "2")), "not an integer"),
    (_run_json_a_folder, "run.json is a folder"),
    (lambda folder: (folder / "run.json").write_bytes(b'{"format": "\xff"}'), "utf-8"),
    (_edit_run_json(lambda m: m["params"].__setitem__("gamma", "abc")),
     "cannot be read"),
], ids=["format_version text", "a folder", "not UTF-8", "gamma text"])
@pytest.mark.parametrize("argv", [["table"], ["analyze"], ["resume", "--no-plot", "--no-locate"],
                                  ["export", "--step", "-1", "--format", "vtk", "--out", "x.vtk"],
                                  ["plot", "--out", "figs"], ["view", "--out", "x.html"]],
                         ids=lambda argv: argv[0])
def test_a_damaged_run_json_is_refused_in_one_line_naming_it(folder, tmp_path, monkeypatch,
                                                             damage, said, argv):
    monkeypatch.chdir(tmp_path)
    damage(folder)
    before = {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    code, _, err = _cli([argv[0], str(folder), *argv[1:]])
    if code == 0:  # analyze reads the stored shapes only: the parameters are not needed
        assert argv[0] == "analyze" and said == "cannot be read"
        return
    # a damaged folder is refused as input, before any work
    assert code == 2 and said in err and "run.json" in err, err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "x.vtk").exists()
    assert not (tmp_path / "figs").exists() and not (tmp_path / "x.html").exists()
    assert {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*")
            if p.is_file()} == before


def test_resuming_a_finished_run_keeps_its_message_and_steps(folder, reference):
    before = json.loads((folder / "run.json").read_text())
    run = resume(folder)
    after = json.loads((folder / "run.json").read_text())
    assert before["status"] == after["status"] == "finished"
    assert after["message"] == before["message"] and "(dV/V = " in after["message"]
    _same_rows(run.table, reference[1], ignore=("wall_s",))
