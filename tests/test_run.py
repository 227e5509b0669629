"""Durable runs: resume gives the uninterrupted result; bad input is refused before work."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest

from shellbuckle.cli import main
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.run import Run, continue_from, deflate, resume
from shellbuckle.solve.linear import _load_mkl

PARAMS = ShellParameters.from_gamma(271.0, nu=1 / 3)
OPTIONS = dict(dv=0.03, until=0.24, jiggle=0.02, seed=7)


def _compare(a: pd.DataFrame, b: pd.DataFrame):
    cols = [c for c in a.columns if c != "wall_s"]
    pd.testing.assert_frame_equal(a[cols].reset_index(drop=True), b[cols].reset_index(drop=True),
                                  check_exact=True)


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    return deflate(icosphere(4), PARAMS, out=tmp_path_factory.mktemp("full") / "run", **OPTIONS)


def test_resume_after_pause_gives_the_same_table(tmp_path, uninterrupted):
    out = tmp_path / "run"
    part = deflate(icosphere(4), PARAMS, out=out, max_steps=3, **OPTIONS)
    assert part.status == "paused" and part.steps == [0, 1, 2, 3]
    done = resume(out)
    assert done.status == "finished"
    _compare(done.table, uninterrupted.table)
    for k in done.steps:
        np.testing.assert_array_equal(done.positions(k), uninterrupted.positions(k))


_CHILD = """
import sys
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.run import deflate
deflate(icosphere(4), ShellParameters.from_gamma(271.0, nu=1/3), out=sys.argv[1],
        dv=0.03, until=0.24, jiggle=0.02, seed=7)
"""


def kill_9_after_steps(args: list, out, n_steps: int = 3, timeout: float = 120.0) -> None:
    """Run ``python -c args...`` writing a run into ``out`` and ``kill -9`` it once ``n_steps``
    step files exist (or after ``timeout`` s, or when it has ended)."""
    child = subprocess.Popen([sys.executable, "-c", *args])
    deadline = time.time() + timeout
    while time.time() < deadline and child.poll() is None:
        if len(list((out / "steps").glob("step_*.h5"))) >= n_steps:
            break
        time.sleep(0.02)
    os.kill(child.pid, signal.SIGKILL)
    child.wait()


def test_kill_9_then_resume_gives_the_same_table(tmp_path, uninterrupted):
    out = tmp_path / "run"
    kill_9_after_steps([_CHILD, str(out)], out)
    before = Run.open(out).steps
    assert before == list(range(len(before))) and len(before) >= 1
    done = resume(out)
    _compare(done.table, uninterrupted.table)


@pytest.mark.skipif(_load_mkl() is None, reason="single precision needs PARDISO (Intel MKL)")
def test_a_run_whose_certificates_turn_to_double_precision_resumes_exactly(tmp_path,
                                                                           monkeypatch):
    # Newton's method certifies the minima in single precision while it can; once a step
    # needs double precision (soft modes after buckling) the run stops trying single, and a
    # resumed run must make the same choice from the stored record (oracle: the uninterrupted
    # run, to the last bit). Certificates are refused here at dV/V = 0.12 only, as a shell
    # whose smallest eigenvalue falls below the certificate's shift would refuse them: a
    # resumed run that tried again later would certify in single precision, other bits
    import importlib

    from shellbuckle.energies.volume import Volume

    system = importlib.import_module("shellbuckle.solve.system")
    mesh = icosphere(4)
    V0 = Volume(mesh.faces, mesh.n_vertices).value(mesh.X)
    tries = []
    certify = system.KKTSystem.certify_single
    monkeypatch.setattr(system.KKTSystem, "certify_single", lambda nt: tries.append(
        nt.V_target) or (not 0.87 * V0 < nt.V_target < 0.89 * V0 and certify(nt)))
    full = deflate(mesh, PARAMS, out=tmp_path / "full", **OPTIONS)
    certificates = list(full.table["certificate"].iloc[1:])  # dV/V = 0.03, 0.06, ...
    assert certificates == ["single"] * 3 + ["double"] * (len(certificates) - 3)
    # tried in steps 1-4 only: not after the first step that needed double precision
    assert min(tries) == pytest.approx(0.88 * V0, rel=1e-12) and len(tries) >= 4
    out = tmp_path / "part"
    deflate(mesh, PARAMS, out=out, max_steps=5, **OPTIONS)
    _compare(resume(out).table, full.table)


@pytest.mark.skipif(_load_mkl() is None, reason="Intel MKL not installed")
def test_a_run_goes_on_in_the_pardiso_mode_it_was_made_in(tmp_path):
    # PARDISO's plain mode (one thread) and its reproducible mode (several) give other bits;
    # a run stores its mode and a resumed run uses it whatever threads it is given (oracle:
    # the uninterrupted run in the same mode, to the last bit)
    full = {}
    for threads in (1, 2):
        full[threads] = deflate(icosphere(4), PARAMS, out=tmp_path / f"full{threads}",
                                threads=threads, **OPTIONS)
    assert full[1].store.meta["extra"]["pardiso_mode"] == "plain"
    assert full[2].store.meta["extra"]["pardiso_mode"] == "reproducible"
    a, b = full[1].table, full[2].table
    assert not a["E_total"].equals(b["E_total"])  # the modes differ: the stored one matters
    # the same problem (after buckling the modes may reach other, nearly degenerate minima)
    np.testing.assert_allclose(a["E_total"], b["E_total"], rtol=1e-3)
    for made, resumed in ((1, 2), (2, 1)):
        out = tmp_path / f"part{made}"
        deflate(icosphere(4), PARAMS, out=out, threads=made, max_steps=3, **OPTIONS)
        _compare(resume(out, threads=resumed).table, full[made].table)


def test_a_run_with_an_unknown_pardiso_mode_is_refused_before_any_step(tmp_path):
    import json

    out = tmp_path / "run"
    deflate(icosphere(3), PARAMS, out=out, max_steps=1, dv=0.03, until=0.09, threads=1)
    meta = json.loads((out / "run.json").read_text())
    assert meta["extra"]["pardiso_mode"] == "plain"
    meta["extra"]["pardiso_mode"] = "fast"
    (out / "run.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="stores PARDISO mode 'fast'; expected 'plain' or "
                                         "'reproducible'"):
        resume(out)
    stored = Run.open(out)
    assert stored.steps == [0, 1]  # nothing lost
    assert stored.status == "failed"


def test_reinflation_branch_keeps_the_reference(tmp_path, uninterrupted):
    k = uninterrupted.steps[-1]
    back = continue_from(uninterrupted, k, tmp_path / "back", dv=-0.06, until=0.05)
    table = back.table
    assert table["target_dV_over_V"].iloc[1] == pytest.approx(table["dV_over_V"].iloc[0] - 0.06)
    assert (np.diff(table["dV_over_V"]) < 0).all()
    # energies are measured from the same stress-free sphere: step 0 repeats the parent's step k
    assert table["E_total"].iloc[0] == pytest.approx(uninterrupted.table["E_total"].iloc[k])


@pytest.mark.parametrize("argv, fragment", [
    (["deflate", "--gamma", "-1"], "gamma"),
    (["deflate", "--nu", "1.5"], "nu"),
    (["deflate", "--E", "1", "--sigma", "0.7", "--d", "0.1", "--R", "1"], "sigma"),
    (["deflate", "--dv", "0"], "dv"),
    (["deflate", "--until", "1.2"], "dV/V"),
    (["deflate", "--jiggle", "-1"], "jiggle"),
    (["deflate", "--vertices", "2"], "--vertices 2"),
    (["deflate", "--mesh", "/nonexistent/shell.fe"], "does not exist"),
    (["resume", "/nonexistent/run"], "run"),
])
def test_bad_input_exits_2_with_the_value_named(tmp_path, capsys, argv, fragment):
    code = main(argv + (["--out", str(tmp_path / "x")] if argv[0] == "deflate" else []))
    err = capsys.readouterr().err
    assert code == 2
    assert fragment in err and "Traceback" not in err
    assert not (tmp_path / "x").exists(), "nothing is written for refused input"


def test_a_different_run_is_never_written_into_an_existing_run(uninterrupted, capsys):
    before = uninterrupted.table
    code = main(["deflate", "--icosphere", "4", "--gamma", "743", "--out", str(uninterrupted.path)])
    assert code == 2 and "different run" in capsys.readouterr().err
    _compare(Run.open(uninterrupted.path).table, before)


def test_cli_continues_from_a_stored_step(uninterrupted, tmp_path, capsys):
    out = tmp_path / "back"
    code = main(["deflate", "--from", str(uninterrupted.path), "--step", "3", "--dv", "-0.03",
                 "--until", "0.0", "--out", str(out), "--quiet", "--no-plot"])
    assert code == 0
    table = Run.open(out).table
    np.testing.assert_array_equal(Run.open(out).positions(0), uninterrupted.positions(3))
    assert table["dV_over_V"].iloc[-1] == pytest.approx(0.0, abs=1e-12)
    assert main(["deflate", "--from", str(uninterrupted.path), "--step", "99", "--dv", "-0.03",
                 "--until", "0.0", "--out", str(tmp_path / "bad")]) == 2
    assert "allowed" in capsys.readouterr().err


def test_step_resolves_negative_indices_and_names_the_allowed_steps(uninterrupted):
    steps = uninterrupted.steps
    assert uninterrupted.step(-1) == steps[-1] and uninterrupted.step(-len(steps)) == 0
    assert uninterrupted.step(3) == 3 and isinstance(uninterrupted.step(np.int64(2)), int)
    for bad in (len(steps), -len(steps) - 1):
        with pytest.raises(ValueError, match=rf"allowed steps: 0\.\.{steps[-1]} \(or -1 \.\. "
                                             rf"-{len(steps)} counted from the last\)"):
            uninterrupted.step(bad)
    for bad in (1.0, True, "1"):
        with pytest.raises(ValueError, match="must be an integer"):
            uninterrupted.step(bad)
    np.testing.assert_array_equal(uninterrupted.positions(-1),
                                  uninterrupted.positions(steps[-1]))


def test_of_opens_a_folder_and_keeps_a_run(uninterrupted):
    assert Run.of(uninterrupted) is uninterrupted
    assert Run.of(uninterrupted.path).table.equals(uninterrupted.table)
    assert Run.of(str(uninterrupted.path)).steps == uninterrupted.steps
    with pytest.raises(ValueError, match="a Run or a run folder"):
        Run.of(3)
