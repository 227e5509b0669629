"""The progress bar of a run and the closing line of a step that logged fold warnings.

Oracles: how the run ended (its status and the steps stored: a run that ends early ends at
100 % with the total set to the steps done; a paused one shows the steps done out of the
schedule's), the classical buckling pressure p_c = 4 sqrt(kappa A)/R^2 = 4 sqrt(gamma) at
kappa = R = 1 (Quilliet et al. 2008, eq. 3; the unit of the run figure), and the step's
record (converged, inertia) for the closing line; within a step, the record's iterations (the
count the minimizers report, one per accepted step) and the energy falling at each of them.
"""

from __future__ import annotations

import logging
import math
import re
from pathlib import Path

import pytest

from shellbuckle import run as run_mod
from shellbuckle.analysis.classify import SHAPES
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.protocol import deflate as protocol_mod
from shellbuckle.protocol.deflate import folded_flat

GAMMA = 271.0


def _deflate(tmp_path, **kw):
    return run_mod.deflate(icosphere(2), ShellParameters.from_gamma(GAMMA), dv=0.05, until=0.3,
                           seed=1, out=tmp_path / "run", locate=False, threads=1,
                           progress=True, **kw)


def _last_bar(err: str) -> str:
    frames = [f for f in re.split(r"[\r\n]", err) if f.startswith("deflation:")]
    return frames[-1]


def _wrap_step(monkeypatch, after):
    """protocol.step followed by ``after(state, record) -> (state, record)``."""
    real = protocol_mod.step

    def step(ctx, state):
        return after(*real(ctx, state))

    monkeypatch.setattr(protocol_mod, "step", step)


def test_a_run_that_ends_before_its_schedule_ends_at_100_percent(tmp_path, monkeypatch,
                                                                 capsys):
    def contact_at_2(state, record):
        if state.step == 2:
            state = protocol_mod.state_after(2, state.X, record, "self-intersection (test)")
        return state, record

    _wrap_step(monkeypatch, contact_at_2)
    run = _deflate(tmp_path)
    assert run.status == "finished" and run.steps == [0, 1, 2]  # 2 of the schedule's 6
    bar = _last_bar(capsys.readouterr().err)
    assert "100%" in bar and "| 2/2 " in bar, bar
    # the postfix: dV/V, E/kappa, p/p_c of step 2 and its shape and W
    table = run.table.set_index("step")
    values = dict(re.findall(r"([\w/]+)=(\S+?)[,\]\s]", bar))
    assert float(values["dV/V"]) == pytest.approx(table.loc[2, "dV_over_V"], abs=5e-4)
    p_c = 4.0 * math.sqrt(GAMMA)
    assert float(values["p/p_c"]) == pytest.approx(table.loc[2, "pressure"] / p_c, abs=5e-4)
    assert values["shape"] in SHAPES and int(values["W"]) >= 0


def test_a_failed_run_ends_at_100_percent_a_paused_one_does_not(tmp_path, monkeypatch,
                                                                capsys):
    def fail_at_2(state, record):
        if state.step == 2:
            raise protocol_mod.LeftDomain(2, "a test")
        return state, record

    with monkeypatch.context() as m:
        _wrap_step(m, fail_at_2)
        with pytest.raises(protocol_mod.LeftDomain):
            _deflate(tmp_path)
    bar = _last_bar(capsys.readouterr().err)
    assert "100%" in bar and "| 1/1 " in bar, bar
    run = run_mod.resume(tmp_path / "run", progress=True, max_steps=2)
    assert run.status == "paused" and run.steps == [0, 1, 2, 3]
    bar = _last_bar(capsys.readouterr().err)
    assert "| 3/6 " in bar and "100%" not in bar, bar


def _flat_fold_message():
    mesh = icosphere(2)
    hinges = mesh.topology.hinges
    X = mesh.X.copy()
    X[hinges[0, 3]] = X[hinges[0, 2]]  # the two faces of hinge 0 on each other
    why = folded_flat(X, hinges)
    assert why is not None and "folded onto each other" in why
    return f"no convergence (abandoned: {why}; E = 170.7)"


@pytest.mark.parametrize("why", [_flat_fold_message(),
                                 "a fold of the mesh (only neighbouring faces intersect)"])
def test_a_step_with_fold_warnings_ends_with_one_line_on_its_minimum(tmp_path, monkeypatch,
                                                                      caplog, why):
    mesh = icosphere(2)
    real = protocol_mod.step

    def step(ctx, state):
        if state.step == 0:  # step 1 logs what the protocol logs when a fold stops it
            logging.getLogger("shellbuckle.protocol.deflate").warning(
                "step %d: %s after a jiggle of std %.3g; jiggling again with half of it",
                1, why, 0.01)
        return real(ctx, state)

    monkeypatch.setattr(protocol_mod, "step", step)
    with caplog.at_level(logging.WARNING, logger="shellbuckle"):
        run = run_mod.deflate(mesh, ShellParameters.from_gamma(GAMMA), dv=0.05, until=0.1,
                              seed=1, out=tmp_path / "run", locate=False, threads=1)
    closing = [r.getMessage() for r in caplog.records if r.name == "shellbuckle.run"]
    record = run.store.record(1)
    assert record["converged"] and record["inertia"] == 0  # a certified minimum at step 1
    assert closing == ["step 1 converged to a minimum (inertia 0); the fold was left behind"]


@pytest.mark.parametrize("record, words", [
    ({"converged": True, "inertia": 0}, "converged to a minimum (inertia 0)"),
    ({"converged": False, "inertia": 0}, "did not converge"),
    ({"converged": False, "inertia": None}, "did not converge"),
    ({"converged": True, "inertia": 2}, "saddle point, not a minimum (inertia 2"),
    ({"converged": True, "inertia": None}, "inertia was not computed"),
    ({"converged": True, "inertia": -1}, "inertia was not computed"),
])
def test_the_closing_line_follows_the_record(record, words):
    line = run_mod._fold_verdict(7, record)
    assert line.startswith("step 7 ") and words in line and "\n" not in line


# ------------------------------------------------------------------ within a step

def test_the_bar_counts_within_a_step_the_iterations_its_record_stores(tmp_path, monkeypatch,
                                                                       capsys):
    # every accepted step of every minimization of a step (relaxation, Newton, the c0 cycle's
    # two, the jiggles made again) reaches the bar once: the count equals the record's
    counted = []
    real_update = run_mod._Progress.update

    def update(self, X, record):
        counted.append((self.step, self.iterations, record["iterations"]))
        real_update(self, X, record)

    monkeypatch.setattr(run_mod._Progress, "update", update)
    monkeypatch.setattr(run_mod._Progress, "EVERY_S", 0.0)  # show every iteration
    monkeypatch.setattr(run_mod._Progress, "EVERY_S_LOG", 0.0)  # pytest's capture is no tty
    run = _deflate(tmp_path, temperature=0.01)
    assert [k for k, _, _ in counted] == run.steps[1:]
    assert all(ours == stored > 0 for _, ours, stored in counted), counted
    frames = [f for f in re.split(r"[\r\n]", capsys.readouterr().err) if " it, 0:" in f]
    assert frames and all(re.search(r"step [1-6]: \d+ it, 0:\d\d\]\s*$", f) for f in frames)
    # after the first step, beside what the last step ended with
    assert any(re.search(r"W=\d \| step [2-6]: ", f) for f in frames)


def test_a_listener_hears_each_accepted_step_and_its_energy_and_only_its_own_thread(tmp_path):
    import threading

    import numpy as np

    from shellbuckle.energies.total import ShellEnergy
    from shellbuckle.energies.volume import Volume
    from shellbuckle.solve.listen import listening
    from shellbuckle.solve.newton import newton

    mesh = icosphere(3)
    params = ShellParameters.from_gamma(GAMMA)
    energy = ShellEnergy.build(mesh, params, c0=2.0 / params.R)
    volume = Volume(mesh.faces, mesh.n_vertices)
    V = 0.9 * volume.value(mesh.X)
    start = mesh.X + 0.01 * np.random.default_rng(3).standard_normal(mesh.X.shape)

    def minimize():
        return newton(energy, volume, start, V, precondition_at=mesh.X)

    heard, results = [], {}
    thread = threading.Thread(target=lambda: results.update(other=minimize()))
    with listening(lambda E, r: heard.append(E)):
        thread.start()  # a thread of its own: its context has no listener
        result = minimize()
        thread.join()
    assert len(heard) == result.nit > 10
    assert heard[-1] == result.fun
    # each accepted step lowers the energy (to round-off near the minimum)
    assert all(b <= a + 1e-13 * abs(a) for a, b in zip(heard, heard[1:]))
    assert results["other"].nit == result.nit  # the same work, unheard: heard once

    import contextvars

    with listening(lambda E, r: heard.append(E)):  # a thread that inherits the context
        thread = threading.Thread(target=contextvars.copy_context().run, args=(minimize,))
        thread.start()
        thread.join()
    assert len(heard) == result.nit  # nothing more heard

    def broken(E, r):
        raise RuntimeError("display gone")

    with listening(broken):  # a listener that fails never changes the minimization
        again = minimize()
    assert np.array_equal(again.x, result.x) and again.nit == result.nit


@pytest.mark.parametrize("conjugate", [True, False])
def test_the_gradient_methods_report_each_step_they_count(conjugate):
    # to their usual end here: the energy stationary within round-off
    import numpy as np

    from shellbuckle.energies.total import ShellEnergy
    from shellbuckle.energies.volume import Volume
    from shellbuckle.solve.cg import conjugate_gradient
    from shellbuckle.solve.listen import listening

    mesh = icosphere(2)
    energy = ShellEnergy.build(mesh, ShellParameters.from_gamma(GAMMA), c0=2.0)
    volume = Volume(mesh.faces, mesh.n_vertices)
    start = mesh.X + 0.005 * np.random.default_rng(5).standard_normal(mesh.X.shape)
    heard = []
    with listening(lambda E, r: heard.append(E)):
        result = conjugate_gradient(energy, volume, start, 0.95 * volume.value(mesh.X),
                                    conjugate=conjugate, tol_grad=1e-14, atol_grad=0.0,
                                    max_iter=400)
    assert len(heard) == result.nit > 20 and heard[-1] == result.fun


def test_a_bar_written_to_a_log_refreshes_within_a_step_once_a_minute(monkeypatch):
    """Redrawn on a terminal every second; written frame after frame to a file or a pipe (a
    batch job's log) every minute, not 3600 frames an hour."""
    import io

    from tqdm import tqdm

    from shellbuckle.mesh import icosphere
    from shellbuckle.params import ShellParameters

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    for stream, every in ((io.StringIO(), run_mod._Progress.EVERY_S_LOG),
                          (Terminal(), run_mod._Progress.EVERY_S)):
        monkeypatch.setattr("tqdm.auto.tqdm", lambda *a, **k: tqdm(*a, file=stream, **k))
        progress = run_mod._Progress(5, 0, icosphere(2), ShellParameters.from_gamma(100, 1 / 3))
        try:
            assert run_mod.interactive(progress.bar) == isinstance(stream, Terminal)
            assert progress.every == every
            clock = [1000.0]
            monkeypatch.setattr(run_mod.time, "monotonic", lambda: clock[0])
            progress.begin(1)
            written = len(stream.getvalue())
            for _ in range(120):  # two minutes of iterations, one every second
                clock[0] += 1.0
                progress.accepted(1.0, 1e-3)
            frames = stream.getvalue()[written:].count(" it, ")
            assert frames == 120 // every
        finally:
            monkeypatch.undo()
            progress.close(False)
    assert run_mod._Progress.EVERY_S_LOG >= 60 * run_mod._Progress.EVERY_S
    # in a notebook tqdm.auto's bar is a subclass of the notebook's, defined in tqdm.auto, and
    # writes to the kernel's stream, which is no tty: both are seen as a notebook
    from types import SimpleNamespace

    notebook = type("tqdm_notebook", (), {"__module__": "tqdm.notebook"})
    assert run_mod.interactive(type("tqdm", (notebook,), {"__module__": "tqdm.auto"})())
    kernel = type("OutStream", (io.StringIO,), {"__module__": "ipykernel.iostream"})
    assert run_mod.interactive(SimpleNamespace(fp=kernel()))
    assert not run_mod.interactive(SimpleNamespace(fp=io.StringIO()))
    # a sweep's bar counts the steps made as often: every 5 s on a terminal, every minute in a log
    import shellbuckle.sweep as sweep_mod

    for stream, every in ((io.StringIO(), sweep_mod.STEPS_EVERY_S_LOG),
                          (Terminal(), sweep_mod.STEPS_EVERY_S)):
        bar = tqdm(total=1, file=stream)
        assert sweep_mod._Shown(bar, Path("."), []).every == every
        bar.close()
