"""The command line as one registry: one module per command, options declared once with the
library's defaults, one way to continue from a stored step, and the exit-code contract."""

import argparse
import importlib
import inspect
import pkgutil

import pandas as pd
import pytest

import shellbuckle
from shellbuckle import cli, commands
from shellbuckle.cli import main
from shellbuckle.commands._options import NU_HELP, protocol_defaults
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.protocol.deflate import Protocol
from shellbuckle.run import MAIN_JOB_GAMMA, Run, deflate
from shellbuckle.sweep import SweepSpec


def subparsers() -> dict:
    parser = cli.build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def option(parser, flag):
    return next(a for a in parser._actions if flag in a.option_strings)


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    return deflate(icosphere(3), ShellParameters.from_gamma(271.0, nu=1 / 3), dv=0.03,
                   until=0.12, seed=7, out=tmp_path_factory.mktemp("small") / "run")


# --------------------------------------------------------------------------- the registry

def test_version(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"shellbuckle {shellbuckle.__version__}"


def test_every_command_is_one_module_found_by_discovery():
    names = [i.name for i in pkgutil.iter_modules(commands.__path__)
             if not i.name.startswith("_")]
    found = {}
    for name in names:
        module = importlib.import_module(f"shellbuckle.commands.{name}")
        sub = argparse.ArgumentParser().add_subparsers()
        module.register(sub)
        assert len(sub.choices) == 1, name
        found.update(sub.choices)
    assert set(found) == set(subparsers())
    assert not [n for n, _ in inspect.getmembers(cli) if n.startswith("_register")]


@pytest.mark.parametrize("error, code, words", [
    (ValueError("--x 3 is not allowed"), 2, ["error", "--x 3 is not allowed"]),
    (FileNotFoundError("no such folder"), 2, ["error", "no such folder"]),
    (KeyboardInterrupt(), 130, ["interrupted"]),
    (RuntimeError("boom"), 1, ["failed: RuntimeError: boom"]),
])
def test_exit_codes(monkeypatch, capsys, error, code, words):
    from shellbuckle.commands import table

    def fail(args):
        raise error

    monkeypatch.setattr(table, "_cmd", fail)
    assert main(["table", "anywhere"]) == code
    err = capsys.readouterr().err
    assert err.startswith("shellbuckle table: ") and "Traceback" not in err
    for word in words:
        assert word in err


# --------------------------------------------------------------------------- one set of defaults

def test_one_default_gamma_and_one_nu_help():
    parsers = subparsers()
    assert option(parsers["theory"], "--gamma").default == MAIN_JOB_GAMMA
    for name in ("deflate", "theory", "sweep"):
        gamma, nu = option(parsers[name], "--gamma"), option(parsers[name], "--nu")
        assert f"default {MAIN_JOB_GAMMA:g}" in gamma.help, name
        assert NU_HELP in nu.help, name


def test_protocol_defaults_are_the_librarys():
    d = protocol_defaults()
    paper = Protocol.paper()
    assert (d["dv"], d["until"]) == (paper.schedule[0], 0.95)
    assert {k: d[k] for k in ("seed", "c0_cycle", "bending", "method", "max_iter", "temperature")
            } == {k: getattr(paper, k) for k in ("seed", "c0_cycle", "bending", "method",
                                                 "max_iter", "temperature")}
    spec = SweepSpec()
    for name in ("dv", "until", "temperature", "bending", "method", "c0_cycle"):
        assert getattr(spec, name) == (d[name],), name
    assert spec.seeds == (d["seed"],) and spec.max_iter == d["max_iter"]
    help_text = option(subparsers()["deflate"], "--dv").help
    assert f"default {d['dv']:g}" in help_text


def _capture_sweep(monkeypatch):
    from shellbuckle import sweep

    specs = []

    def run_sweep(spec, out, **kwargs):
        specs.append(spec)
        return pd.DataFrame({"status": ["finished"], "name": ["x"], "message": [""]})

    monkeypatch.setattr(sweep, "run_sweep", run_sweep)
    return specs


def test_sweep_takes_the_main_jobs_gamma_unless_given(monkeypatch, tmp_path, capsys):
    specs = _capture_sweep(monkeypatch)
    assert main(["sweep", "--out", str(tmp_path / "a"), "--quiet"]) == 0
    assert main(["sweep", "--gamma", "271,2333", "--out", str(tmp_path / "b")]) == 0
    config = tmp_path / "s.toml"
    config.write_text("[protocol]\nuntil = 0.3\n")
    assert main(["sweep", "--config", str(config), "--out", str(tmp_path / "c")]) == 0
    config.write_text("gamma = [743]\n")
    assert main(["sweep", "--config", str(config), "--out", str(tmp_path / "d")]) == 0
    assert [s.gamma for s in specs] == [(MAIN_JOB_GAMMA,), (271.0, 2333.0), (MAIN_JOB_GAMMA,),
                                        (743.0,)]
    assert specs[2].until == (0.3,)


# --------------------------------------------------------------------------- continue

def test_continue_in_volume_is_deflate_from(small_run, tmp_path, capsys):
    argv = ["--step", "2", "--dv", "-0.03", "--until", "0.0", "--no-plot", "--quiet"]
    assert main(["continue", str(small_run.path), *argv, "--out", str(tmp_path / "a")]) == 0
    assert main(["deflate", "--from", str(small_run.path), *argv,
                 "--out", str(tmp_path / "b")]) == 0
    a, b = Run.open(tmp_path / "a"), Run.open(tmp_path / "b")
    columns = [c for c in a.table.columns if c != "wall_s"]
    pd.testing.assert_frame_equal(a.table[columns], b.table[columns], check_exact=True)
    assert a.table["dV_over_V"].iloc[-1] == pytest.approx(0.0, abs=1e-12)
    assert a.protocol.seed == small_run.protocol.seed == 7   # kept, not reset
    assert "run folder:" in capsys.readouterr().out


def test_continue_without_a_path_deflates_on_with_the_protocols_steps(small_run, tmp_path):
    out = tmp_path / "on"
    assert main(["continue", str(small_run.path), "--step", "-2", "--until", "0.15",
                 "--no-plot", "--quiet", "--out", str(out)]) == 0
    table = Run.open(out).table
    assert table["target_dV_over_V"].iloc[1:].diff().dropna().round(12).eq(
        round(protocol_defaults()["dv"], 12)).all()


@pytest.mark.parametrize("argv, fragment", [
    (["--gamma", "500", "--increments", "2", "--until", "0.3"], "--until makes a volume path"),
    (["--gamma", "500", "--increments", "2", "--dv", "0.01"], "--then-deflate-to"),
    (["--dv", "0.01", "--increments", "2"], "--increments goes with a path"),
    (["--until", "0.3", "--then-deflate-to", "0.5"], "--then-deflate-to goes with"),
    (["--step", "99"], "--step 99: step 99 is not a finished step"),
    (["--gamma", "500", "--c0", "1"], "not allowed with argument"),
])
def test_continue_refuses_a_mixed_path(small_run, tmp_path, capsys, argv, fragment):
    with pytest.raises(SystemExit) if "allowed with" in fragment else _nothing():
        code = main(["continue", str(small_run.path), *argv, "--out", str(tmp_path / "x")])
        assert code == 2
    assert fragment in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


@pytest.mark.parametrize("flag, value", [("--gamma", "300"), ("--bending", "evolver"),
                                         ("--c0", "1.0"), ("--vertices", "200")])
def test_deflate_from_refuses_a_new_shell(small_run, tmp_path, capsys, flag, value):
    assert main(["deflate", "--from", str(small_run.path), flag, value,
                 "--out", str(tmp_path / "x")]) == 2
    assert f"{flag} {value}: cannot be combined with --from" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("quiet", [["--quiet"], []])
def test_a_deflation_without_figure_or_location_does_not_load_the_table_libraries(tmp_path,
                                                                                  quiet):
    # what a short run pays before its first step and after its last: the run is made and
    # reported from its records, without pandas, matplotlib or the locator; its progress bar
    # (each step's shape) without pandas either
    import subprocess
    import sys

    code = ("import sys; from shellbuckle.cli import main; "
            "code = main(['deflate', '--vertices', '200', '--gamma', '100', '--until', '0.019', "
            f"'--no-plot', '--no-locate', *{quiet!r}, '--threads', '1', "
            f"'--out', {str(tmp_path / 'r')!r}]); "
            "print(sorted(m for m in ('pandas', 'matplotlib', 'shellbuckle.locate') "
            "if m in sys.modules)); sys.exit(code)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=300)
    assert "steps: 1, dV/V = 0.0190" in out.stdout
    assert out.stdout.strip().splitlines()[-1] == "[]"


@pytest.mark.parametrize("argv", [
    ["deflate", "--gamma", "-1"],
    ["deflate", "--temperature", "0.1", "--jiggle", "0.2"],
    ["deflate", "--gamma", "1e6", "--vertices", "500"],
    ["deflate", "--shape-imperfection-d", "9"],
    ["deflate", "--help"],
    ["refine", "--shape-degree", "critic", "--out", "x"],
    ["transfer", "no_such_run", "x"],
    ["table", "no_such_run"],
])
def test_refusals_and_help_do_not_load_the_energies_or_the_solvers(argv, tmp_path):
    # bad input is refused, and the help printed, from the options' descriptions alone
    # (protocol.spec, energies.kinds): no compiled kernels, no sparse algebra, no run store
    import subprocess
    import sys

    heavy = ("numba", "scipy", "h5py", "pandas", "shellbuckle.run", "shellbuckle.energies.total",
             "shellbuckle.protocol.deflate")
    code = ("import sys; from shellbuckle.cli import main\n"
            f"try:\n    code = main({argv!r})\nexcept SystemExit as exc:\n    code = exc.code\n"
            f"print(sorted(m for m in {heavy!r} if m in sys.modules)); sys.exit(code)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, cwd=tmp_path)
    assert out.returncode == (0 if "--help" in argv else 2), out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"
    assert not (tmp_path / "x").exists() and not (tmp_path / "runs").exists()
    if "--help" not in argv:
        assert out.stderr.count("\n") == 1 and argv[1] in out.stderr


# --------------------------------------------------------------------------- exit codes

@pytest.mark.parametrize("command, module, name, argv", [
    ("classify", "shellbuckle.analysis", "classify", ["RUN"]),
    ("export", "shellbuckle.export", "export_step", ["RUN", "--step", "1", "--format", "vtu",
                                                     "--out", "OUT/s.vtu"]),
    ("export", "shellbuckle.export", "export_series", ["RUN", "--format", "xdmf",
                                                       "--out", "OUT/s.xdmf"]),
    ("animate", "shellbuckle.plots.animation", "animate_run", ["RUN", "--out", "OUT/a.gif"]),
    ("plot", "shellbuckle.plots.run", "plot_deflation", ["RUN", "--out", "OUT"]),
])
def test_a_value_error_of_the_work_exits_1_and_bad_input_2(small_run, tmp_path, capsys,
                                                            monkeypatch, command, module, name,
                                                            argv):
    # bad input is refused (exit 2) before any work; a ValueError raised by the work itself
    # (a singular matrix, a shape it cannot handle) is a failure of accepted input (exit 1)
    def fails(*args, **kwargs):
        raise ValueError("the work failed here")

    monkeypatch.setattr(importlib.import_module(module), name, fails)
    typed = [str(small_run.path) if a == "RUN" else a.replace("OUT", str(tmp_path / "out"))
             for a in argv]
    (tmp_path / "out").mkdir()
    assert main([command, *typed]) == 1
    err = capsys.readouterr().err.strip()
    assert "the work failed here" in err and len(err.splitlines()) == 1
    assert main([command, str(tmp_path / "no such run"), *typed[1:]]) == 2


def test_an_export_suffix_that_does_not_match_its_format_is_bad_input(small_run, tmp_path,
                                                                     capsys):
    out = tmp_path / "s.ply"
    assert main(["export", str(small_run.path), "--step", "1", "--format", "vtu",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert f"--out {out}" in err and ".vtu" in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_a_reader_that_closes_the_pipe_ends_a_command_quietly(monkeypatch, capsys):
    """`shellbuckle analyze DIR | head`: when the reader of standard output goes away the
    command stops with 141 (128 + SIGPIPE), as Unix tools do, and says nothing on stderr (it
    printed "failed: BrokenPipeError"); a broken pipe elsewhere stays a failure (exit 1)."""
    import io
    import os
    import signal
    import sys

    import shellbuckle.commands.table as table

    def lots(args):
        for _ in range(10_000):
            print("x" * 100)
        return 0

    # a long output, and a short one still in the buffer when the command returns
    for command in (lots, lambda args: print("one short line")):
        read, write = os.pipe()
        os.close(read)  # the reader is gone: writing raises BrokenPipeError (SIGPIPE ignored)
        stdout = io.TextIOWrapper(io.FileIO(write, "w"), line_buffering=False)
        monkeypatch.setattr(table, "_cmd", command)
        monkeypatch.setattr(sys, "stdout", stdout)
        code = main(["table", "somewhere"])
        monkeypatch.undo()
        assert code == 128 + signal.SIGPIPE
        assert capsys.readouterr().err == ""
        stdout.close()

    def broken_elsewhere(args):
        raise BrokenPipeError("a worker's connection")

    monkeypatch.setattr(table, "_cmd", broken_elsewhere)
    assert main(["table", "somewhere"]) == 1
    assert "failed: BrokenPipeError" in capsys.readouterr().err
