"""Bad input to the Python API: refused with a ValueError or TypeError naming the argument,
before any folder or file is made, and never written over a run's own files.

Oracles: the folder and its files, byte for byte, before and after each refusal; what the run
reads afterwards.
"""

from __future__ import annotations

import logging
import shutil

import numpy as np
import pytest

from shellbuckle.analysis import classify, classify_run
from shellbuckle.export import export_series
from shellbuckle.mesh import icosphere
from shellbuckle.mesh.mesh import Mesh
from shellbuckle.params import ShellParameters
from shellbuckle.plots.animation import animate_run
from shellbuckle.plots.viewer import write_html
from shellbuckle.run import Run, continue_from, continue_in_parameter, deflate, resume
from shellbuckle.studies.transfer import transfer

PARAMS = ShellParameters.from_gamma(271.0, nu=1 / 3)
QUICK = dict(until=0.08, threads=1, locate=False)  # steps 0..4 on 92 vertices


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    run = deflate(icosphere(3), PARAMS, out=tmp_path_factory.mktemp("api") / "run", **QUICK)
    assert run.status == "finished" and len(run.steps) >= 4
    return run.path


@pytest.fixture
def run_dir(tmp_path, finished):
    return shutil.copytree(finished, tmp_path / "run")


def _files(folder):
    return {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


# ------------------------------------------------------------------ writers and a run's files

@pytest.mark.parametrize("write", [
    lambda run, target: write_html(run, target),
    lambda run, target: Run.open(run).view(path=target, inline=False, open_browser=False),
    lambda run, target: __import__("shellbuckle.report", fromlist=["write_report"])
    .write_report([run], target, figures=False),
], ids=["write_html", "Run.view", "write_report"])
@pytest.mark.parametrize("target", ["run.json", "steps/step_000001.h5", "table.csv"])
def test_no_writer_replaces_a_file_of_the_run(run_dir, write, target):
    before = _files(run_dir)
    with pytest.raises(ValueError, match="belongs to the run|inside steps/ of the run"):
        write(run_dir, run_dir / target)
    assert _files(run_dir) == before
    assert Run.open(run_dir).damaged == {}


def test_an_animation_is_not_written_inside_the_runs_steps(run_dir):
    before = _files(run_dir)
    with pytest.raises(ValueError, match="inside steps/ of the run"):
        animate_run(run_dir, run_dir / "steps" / "a.gif")
    assert _files(run_dir) == before


def test_a_continued_run_is_not_made_inside_its_parents_steps(run_dir):
    before = _files(run_dir)
    with pytest.raises(ValueError, match="inside steps/ of the run"):
        continue_from(run_dir, 2, run_dir / "steps" / "back", dv=-0.019, until=0.0)
    assert _files(run_dir) == before and not (run_dir / "steps" / "back").exists()


# ------------------------------------------------------------------ deflate: before any folder

def _material():
    return ShellParameters.from_material(E=1e8, sigma=0.5, d=2e-9, R=2e-8)


@pytest.mark.parametrize("args, error, said", [
    (lambda: (icosphere(3), _material()), ValueError,
     r"mesh radius 0\.9799\d* .* is not the shell's R = 2e-08"),
    (lambda: (Mesh.from_arrays(icosphere(3).X, icosphere(3).faces[:, ::-1]), PARAMS),
     ValueError, "non-positive volume .* faces must point outward"),
    (lambda: (icosphere(3), 271.0), TypeError, "params must be a ShellParameters"),
    (lambda: ((icosphere(3).X, icosphere(3).faces), PARAMS), TypeError, "mesh must be a Mesh"),
], ids=["unit mesh, SI shell", "inward faces", "params a number", "mesh a tuple"])
def test_deflate_refuses_a_mesh_that_is_not_the_shell_before_any_folder(tmp_path, args, error,
                                                                        said):
    mesh, params = args()
    with pytest.raises(error, match=said):
        deflate(mesh, params, out=tmp_path / "r", **QUICK)
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("R", [1.0, 2e-8])
def test_the_api_and_the_command_line_draw_the_c0_limit_at_one_place(R):
    from shellbuckle.commands._checks import check_c0
    from shellbuckle.mesh import random_sphere
    from shellbuckle.resolution import c0_limit
    from shellbuckle.run import check_shell_options

    mesh = random_sphere(500, seed=3)
    mesh = mesh.with_positions(mesh.X * R)
    params = ShellParameters(gamma=1000.0, R=R) if R == 1.0 else \
        ShellParameters.from_material(E=1e8, sigma=1 / 3, d=2e-9, R=R)
    limit = c0_limit(500, R)
    edges = mesh.X[mesh.topology.edges]  # the rule's edge is the mesh's own, to a few percent
    own = np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1).mean()
    assert limit == pytest.approx(2.0 / own, rel=0.05)
    for c0 in (0.0, 2.0 / R, limit * (1 - 1e-9), -limit * (1 - 1e-9), limit * (1 + 1e-9),
               -limit * (1 + 1e-9), 10 * limit):
        verdicts = []
        for check in (lambda: check_c0("--c0", str(c0), c0, 500, R),
                      lambda: check_shell_options(mesh, params, c0=c0)):
            try:
                check()
                verdicts.append(True)
            except ValueError:
                verdicts.append(False)
        assert verdicts[0] == verdicts[1] == (abs(c0) <= limit), (c0, limit, verdicts)


@pytest.mark.parametrize("options, error, said", [
    (dict(form_factors=[[1.0, 2.0, 3.0]]), ValueError, "form_factors must have shape"),
    (dict(c0=1e4), ValueError, r"c0 = 10000.0: allowed \|c0\| <= "),
    (dict(pressures=[1e6]), ValueError, "pressure 1000000.0: allowed overpressures"),
    (dict(max_steps=-1), ValueError, "max_steps = -1"),
    (dict(max_steps="2"), TypeError, "max_steps must be an integer"),
    (dict(locate=True, locate_tol=-1.0), ValueError, "location tolerance must be in"),
], ids=["form factors", "c0", "pressure", "max_steps < 0", "max_steps text", "locate_tol"])
def test_deflate_refuses_bad_options_before_any_folder(tmp_path, options, error, said):
    kwargs = QUICK | options
    with pytest.raises(error, match=said):
        deflate(icosphere(3), PARAMS, out=tmp_path / "r", **kwargs)
    assert not (tmp_path / "r").exists()


def test_the_default_mesh_is_built_at_the_shells_radius(tmp_path):
    """deflate without a mesh at a material's R: the paper's randomized sphere of that radius
    (it was built of radius 1, a shell 5e7 times too large), whose first step is the same
    shell's in reduced units."""
    material = _material()
    run = deflate(None, material, out=tmp_path / "m", max_steps=0, threads=1, locate=False)
    reduced = deflate(None, ShellParameters.from_gamma(material.gamma, nu=material.nu),
                      out=tmp_path / "g", max_steps=0, threads=1, locate=False)
    np.testing.assert_allclose(run.store.X0, reduced.store.X0 * material.R, rtol=1e-14)
    np.testing.assert_allclose(run.table["E_over_kappa"], reduced.table["E_over_kappa"],
                               rtol=1e-9)


def test_an_unresolved_mesh_is_warned_about(tmp_path, caplog):
    with caplog.at_level(logging.WARNING, logger="shellbuckle.run"):
        deflate(icosphere(3), ShellParameters.from_gamma(15163.0), out=tmp_path / "r",
                max_steps=0, threads=1, locate=False)
    assert "does not resolve the elastic length" in caplog.text and "184 vertices" in caplog.text


# ------------------------------------------------------------------ continued runs, resume

@pytest.mark.parametrize("call", [
    lambda parent, out: continue_from(parent, 2, out, dv=-0.019, until=0.0, temprature=0.5),
    lambda parent, out: continue_in_parameter(parent, 2, out, gamma=300.0, increments=1,
                                              c0_cylce=False),
    lambda parent, out: continue_from(parent, 2, out, dv=-0.019, until=0.0, control="c0"),
    lambda parent, out: continue_from(parent, 2, out, schedule=[0.01], until=0.5),
], ids=["continue_from typo", "continue_in_parameter typo", "a field the function sets",
        "schedule and until"])
def test_a_continued_run_refuses_an_unknown_option_by_name(run_dir, tmp_path, call):
    with pytest.raises((TypeError, ValueError), match="unknown option|not both"):
        call(run_dir, tmp_path / "c")
    assert not (tmp_path / "c").exists()


def test_continue_from_takes_max_steps_and_threads(run_dir, tmp_path):
    run = continue_from(run_dir, 2, tmp_path / "c", dv=-0.019, until=0.0, max_steps=1,
                        threads=1)
    assert run.status == "paused" and run.steps == [0, 1]


def test_a_bad_max_steps_leaves_a_paused_run_paused(tmp_path):
    run = deflate(icosphere(3), PARAMS, out=tmp_path / "r", max_steps=1, **QUICK)
    assert run.status == "paused"
    before = _files(run.path)
    with pytest.raises(TypeError, match="max_steps must be an integer"):
        resume(run.path, max_steps="a")
    with pytest.raises(ValueError, match="location tolerance"):
        resume(run.path, locate_tol=0.0)
    assert _files(run.path) == before and Run.open(run.path).status == "paused"


# ------------------------------------------------------------------ export, analysis, animation

@pytest.mark.parametrize("steps, said", [([1, 1], "each step once"), ([3, 1], "increasing"),
                                         ([-1, 3], "each step once"), (3, "a list of step")])
def test_a_series_needs_each_step_once_in_order_and_writes_nothing_otherwise(run_dir, tmp_path,
                                                                          steps, said):
    with pytest.raises((ValueError, TypeError), match=said):
        export_series(run_dir, tmp_path / "s.xdmf", steps=steps)
    assert list(tmp_path.glob("s.*")) == []


def test_a_series_into_a_folder_is_refused_before_writing(run_dir, tmp_path):
    (tmp_path / "s.xdmf").mkdir()
    with pytest.raises(ValueError, match="is a folder"):
        export_series(run_dir, tmp_path / "s.xdmf")
    assert not (tmp_path / "s.h5").exists()


def test_classify_refuses_inward_faces_and_fractional_steps(run_dir):
    run = Run.open(run_dir)
    X, faces = run.positions(-1), run.faces
    assert classify(X, faces).shape in ("sphere", "capsule", "bowl", "dimples", "other")
    with pytest.raises(ValueError, match="non-positive volume"):
        classify(X, faces[:, ::-1])
    with pytest.raises(ValueError, match="steps must be integers"):
        classify_run(run, steps=[1.7])
    with pytest.raises(ValueError, match="not a finished step"):
        classify_run(run, steps=[99])


@pytest.mark.parametrize("options, said", [
    (dict(fps=0), "fps = 0: allowed: an integer from 1 to 60"),
    (dict(dpi=0), "dpi = 0"), (dict(steps=[]), "steps is empty"),
    (dict(size=float("nan")), "size = nan"),
], ids=["fps 0", "dpi 0", "no steps", "size nan"])
def test_an_animation_refuses_bad_options_before_writing(run_dir, tmp_path, options, said):
    with pytest.raises(ValueError, match=said):
        animate_run(run_dir, tmp_path / "a.gif", **options)
    assert not (tmp_path / "a.gif").exists()


@pytest.mark.parametrize("name, values", [
    ("fps", (0, 1, 5, 60, 61)), ("dpi", (49, 50, 300, 1200, 1201)),
])
def test_an_animation_takes_the_values_the_command_line_takes(run_dir, tmp_path, name, values):
    from shellbuckle.commands._checks import RANGES
    from shellbuckle.commands.animate import FPS

    cli = FPS if name == "fps" else RANGES["dpi"]
    for value in values:
        # no steps: a value the API takes goes on to the steps and is refused there
        with pytest.raises(ValueError) as refused:
            animate_run(run_dir, tmp_path / "a.gif", steps=[], **{name: value})
        api_takes = "steps is empty" in str(refused.value)
        assert api_takes == (cli.problem(value) is None), (name, value, str(refused.value))


def test_transfer_refuses_zero_threads(run_dir):
    with pytest.raises(ValueError, match="threads must be an integer >= 1, got 0"):
        transfer(run_dir, -1, run_dir, threads=0)


@pytest.mark.parametrize("options, error, said", [
    (dict(c0="2"), TypeError, "c0 must be a number, got str '2'"),
    (dict(tol="1e-9"), TypeError, "tol must be a number"),
    (dict(seed=True), TypeError, "seed must be an integer, got bool True"),
    (dict(c0_cycle="no"), TypeError, "c0_cycle must be True or False"),
    (dict(until=0.01), ValueError, "until = 0.01 is less than one step dv = 0.019"),
    (dict(until=5.0), ValueError, r"until = 5.0: allowed: a dV/V in \(-1, 0.99\)"),
    (dict(schedule=[0.02, 0.04]), ValueError, "give either schedule or dv and until"),
    (dict(pressures=[1.0], dv=0.01, until=None), ValueError, "give either pressures or dv"),
], ids=["c0 text", "tol text", "seed bool", "flag text", "until within a step", "until > 1",
        "schedule and until", "pressures and dv"])
def test_protocol_options_of_the_wrong_kind_are_named(tmp_path, options, error, said):
    with pytest.raises(error, match=said):
        deflate(icosphere(3), PARAMS, out=tmp_path / "r", threads=1, locate=False,
                **({"until": 0.08} | options))
    assert not (tmp_path / "r").exists()
