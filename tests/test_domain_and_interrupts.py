"""Trust at the edges: a run that leaves the physical domain fails (never "finished"), and
Ctrl-C or SIGTERM always ends a run as "interrupted", wherever it arrives.

Oracles: the run's status and message in run.json, the exit code of ``shellbuckle``, the stored
steps (none past the step that left the domain), and the table of an uninterrupted run, which
a resumed run repeats bit for bit (all columns but ``wall_s``).
"""

import json
import re
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest

from shellbuckle.cli import main
from shellbuckle.energies.total import ShellEnergy
from shellbuckle.mesh.random_sphere import random_sphere
from shellbuckle.params import ShellParameters
from shellbuckle.protocol import deflate as protocol_mod
from shellbuckle.protocol.deflate import LeftDomain, domain_exit, inverted_faces
from shellbuckle.run import Run, deflate, interrupt_of

pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")  # overflow on purpose

PARAMS = ShellParameters.from_gamma(2333.0, nu=1 / 3)


def _status(out) -> tuple[str, str]:
    meta = json.loads((out / "run.json").read_text())
    return meta["status"], meta["message"] or ""


def _nan_energy_from(monkeypatch, k: int) -> None:
    """The shell's energy is NaN from step ``k`` on (steps before it are untouched)."""
    active = {"on": False}
    step, value, value_and_gradient = (protocol_mod.step, ShellEnergy.value,
                                       ShellEnergy.value_and_gradient)

    def patched_step(ctx, state):
        active["on"] = state.step + 1 >= k
        return step(ctx, state)

    def patched_value(self, X):
        return float("nan") if active["on"] else value(self, X)

    def patched_value_and_gradient(self, X):
        E, g = value_and_gradient(self, X)
        return (float("nan") if active["on"] else E), g

    monkeypatch.setattr(protocol_mod, "step", patched_step)
    monkeypatch.setattr(ShellEnergy, "value", patched_value)
    monkeypatch.setattr(ShellEnergy, "value_and_gradient", patched_value_and_gradient)


# (name, deflate options, gamma, step at which the run leaves the domain, words of the reason)
DOMAIN_CASES = [
    ("inside-out pressure", dict(pressures=[1e4, 2e4], max_iter=20), 15163.0, 1,
     "turned inside out"),
    # the Hessian overflows at once: the minimizer stops there (or the volume runs away)
    ("huge negative pressure", dict(pressures=[-1e300], max_iter=20), 2333.0, 1,
     "(exceeds 8 V0|non-finite gradient norm)"),
    ("gamma 1e300", dict(until=0.1), 1e300, 1, "non-finite gradient norm"),
    ("NaN energy at step 2", dict(until=0.1, nan_from=2), 2333.0, 2, "non-finite energy"),
]


@pytest.mark.parametrize("name, options, gamma, k, reason", DOMAIN_CASES,
                         ids=[case[0] for case in DOMAIN_CASES])
def test_a_run_that_leaves_the_physical_domain_fails_there(tmp_path, monkeypatch, name,
                                                           options, gamma, k, reason):
    options = dict(options)
    if "nan_from" in options:
        _nan_energy_from(monkeypatch, options.pop("nan_from"))
    if "pressures" in options:
        # the API refuses pressures above p_c or below -gamma before any folder
        # (tests/test_api_input.py); past that check the domain guard still ends the run
        import shellbuckle.run as run_module

        monkeypatch.setattr(run_module, "check_shell_options", lambda *a, **k: None)
    out = tmp_path / "run"
    with pytest.raises(LeftDomain, match=f"step {k} left the physical domain: .*{reason}"):
        deflate(random_sphere(200, seed=0), ShellParameters.from_gamma(gamma, nu=1 / 3),
                out=out, threads=1, **options)
    status, message = _status(out)
    assert status == "failed"
    assert "LeftDomain" in message and re.search(reason, message)
    run = Run.open(out)
    assert run.steps == list(range(k))  # the step that left the domain is not stored
    assert run.table["converged"].astype(bool).all()


def test_the_cli_reports_a_domain_exit_as_a_failure(tmp_path, monkeypatch, capsys):
    _nan_energy_from(monkeypatch, 2)
    out = tmp_path / "run"
    code = main(["deflate", "--vertices", "200", "--gamma", "2333", "--until", "0.1",
                 "--threads", "1", "--quiet", "--no-plot", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 1
    assert "failed: LeftDomain: step 2 left the physical domain: non-finite energy" in err
    assert _status(out)[0] == "failed"
    assert Run.open(out).steps == [0, 1]


def test_valid_states_are_inside_the_domain(tmp_path):
    run = deflate(random_sphere(200, seed=0), PARAMS, until=0.1, out=tmp_path / "run",
                  threads=1)
    ctx, _ = protocol_mod.init(random_sphere(200, seed=0), PARAMS,
                               protocol_mod.Protocol.from_dict(run.protocol.to_dict()), threads=1)
    for k in run.steps:
        assert domain_exit(ctx, run.positions(k)) is None


def test_a_flipped_triangle_and_an_inverted_sphere_are_outside():
    mesh = random_sphere(200, seed=0)
    ctx, _ = protocol_mod.init(mesh, PARAMS, protocol_mod.Protocol.paper(until=0.1), threads=1)
    assert len(inverted_faces(mesh.X, mesh.topology)) == 0
    assert "turned inside out" in domain_exit(ctx, -mesh.X)
    # a triangle folded over one of its edges: its third vertex moved through the edge's
    # midpoint; on some faces the neighbours keep their orientation, and that face is flipped
    folds = []
    for f, (a, b, c) in enumerate(mesh.topology.faces[:20]):
        X = mesh.X.copy()
        X[c] = X[a] + X[b] - X[c]
        if list(inverted_faces(X, mesh.topology)) == [f]:
            folds.append(X)
    assert folds
    assert "1 inverted face(s)" in domain_exit(ctx, folds[0])
    assert "non-finite vertex positions" in domain_exit(ctx, np.full_like(mesh.X, np.nan))


def test_an_interrupt_inside_a_compiled_call_ends_as_interrupted(tmp_path, monkeypatch,
                                                                 capsys):
    # a KeyboardInterrupt raised inside a Numba kernel surfaces as a SystemError whose context
    # is the interrupt
    step = protocol_mod.step

    def interrupted_step(ctx, state):
        if state.step + 1 == 2:
            try:
                raise KeyboardInterrupt
            except KeyboardInterrupt:
                raise SystemError("CPUDispatcher(<function juelicher>) returned a result with "
                                  "an exception set")
        return step(ctx, state)

    monkeypatch.setattr(protocol_mod, "step", interrupted_step)
    out = tmp_path / "run"
    code = main(["deflate", "--vertices", "200", "--gamma", "2333", "--until", "0.1",
                 "--threads", "1", "--quiet", "--no-plot", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 130 and "interrupted" in err and "failed" not in err
    message = f"interrupted after step 1; `shellbuckle resume {out}` continues it"
    assert _status(out) == ("interrupted", message)
    assert interrupt_of(ValueError("plain")) is None


# -- signals sent to `shellbuckle deflate` in a subprocess -------------------------------------

CLI_RUN = ["deflate", "--vertices", "500", "--gamma", "2333", "--seed", "3", "--threads", "1",
           "--quiet", "--no-plot"]
LONG = ["--until", "0.95"]  # 50 steps of ~0.1-0.3 s: the signal always arrives during the work
SHORT = ["--until", "0.076"]
MAX_DELAY = 1.5
"""Seconds after the run folder appears within which the signal arrives (the start of the run,
step 0 and the first steps: Numba kernels, factorizations, stores)."""


def _command() -> list:
    found = shutil.which("shellbuckle")
    return [found] if found else [sys.executable, "-m", "shellbuckle.cli"]


def _compare(a: pd.DataFrame, b: pd.DataFrame):
    cols = [c for c in a.columns if c != "wall_s"]
    pd.testing.assert_frame_equal(a[cols].reset_index(drop=True), b[cols].reset_index(drop=True),
                                  check_exact=True)


@pytest.fixture(scope="module")
def warm(tmp_path_factory):
    """An uninterrupted short run through the CLI, in this process: it compiles (or loads)
    the Numba kernels into their on-disk cache, which every subprocess then reuses, and it is
    the table a resumed run must repeat."""
    out = tmp_path_factory.mktemp("warm") / "run"
    assert main(CLI_RUN + SHORT + ["--out", str(out)]) == 0
    return Run.open(out)


def _signal_run(out, signum: int, delay: float, schedule=LONG, after_step: int | None = None):
    """Start ``shellbuckle deflate`` into ``out``, send ``signum`` ``delay`` seconds after its
    run folder appears (or, with ``after_step``, after that step is stored: a point within the
    steps however fast the machine); returns (exit code, stderr)."""
    child = subprocess.Popen(
        _command() + CLI_RUN + schedule + ["--out", str(out)], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
        # a child of a shell in the background may inherit SIGINT ignored
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # noqa: PLW1509
    deadline = time.monotonic() + 120
    waited = out / ("run.json" if after_step is None else f"steps/step_{after_step:06d}.h5")
    while not waited.exists():
        assert child.poll() is None, child.communicate()
        assert time.monotonic() < deadline, f"{waited} never appeared"
        time.sleep(0.005)
    time.sleep(delay)
    child.send_signal(signum)
    _, err = child.communicate(timeout=120)
    return child.returncode, err


def _assert_interrupted(out, code, err, expected_code):
    assert code == expected_code, err
    assert "interrupted" in err and "failed" not in err, err
    status, message = _status(out)
    assert status == "interrupted", message
    assert "failed" not in message


SIGINT_TRIALS = 20
FAST_TRIALS = 3
"""SIGINT trials in the default test run (each ~4 s, mostly Python's start); the rest are
marked slow."""


@pytest.mark.parametrize("trial", [
    pytest.param(i, marks=() if i < FAST_TRIALS else pytest.mark.slow)
    for i in range(SIGINT_TRIALS)])
def test_sigint_at_a_random_moment_ends_as_interrupted(tmp_path, warm, trial):
    delay = np.random.default_rng([2024, trial]).uniform(0.0, MAX_DELAY)
    out = tmp_path / "run"
    code, err = _signal_run(out, signal.SIGINT, delay)
    _assert_interrupted(out, code, err, 130)


@pytest.mark.parametrize("trial", [
    pytest.param(0), pytest.param(1, marks=pytest.mark.slow),
    pytest.param(2, marks=pytest.mark.slow), pytest.param(3, marks=pytest.mark.slow)])
def test_sigterm_at_a_random_moment_ends_as_interrupted(tmp_path, warm, trial):
    delay = np.random.default_rng([143, trial]).uniform(0.0, MAX_DELAY)
    out = tmp_path / "run"
    code, err = _signal_run(out, signal.SIGTERM, delay)
    _assert_interrupted(out, code, err, 143)
    assert "SIGTERM" in _status(out)[1]


def test_a_run_interrupted_by_sigterm_resumes_to_the_uninterrupted_table(tmp_path, warm):
    out = tmp_path / "run"
    code, err = _signal_run(out, signal.SIGTERM, 0.0, schedule=SHORT, after_step=1)
    _assert_interrupted(out, code, err, 143)
    assert main(["resume", str(out), "--threads", "1", "--quiet", "--no-plot"]) == 0
    done = Run.open(out)
    assert done.status == "finished"
    _compare(done.table, warm.table)
    for k in done.steps:
        np.testing.assert_array_equal(done.positions(k), warm.positions(k))
