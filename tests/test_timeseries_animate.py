"""A run as one piece: the XDMF time series and the VTU field data (shellbuckle.export), the
animation (shellbuckle animate), the pressure-volume figure (shellbuckle.plots.pv) and the Run's
convenience methods. Tiny runs: icosphere(3), 92 vertices, a few steps."""

import xml.etree.ElementTree as ET

import meshio
from pathlib import Path

import numpy as np
import pytest

from shellbuckle import ShellParameters
from shellbuckle.cli import main
from shellbuckle.export import export_series, export_step, run_metadata
from shellbuckle.mesh import icosphere
from shellbuckle.run import continue_from, deflate
from shellbuckle.theory import classical_threshold

GAMMA = 271.0
NU = 1.0 / 3.0


@pytest.fixture(scope="module")
def family(tmp_path_factory):
    """A deflation to dV/V = 0.08 and a re-inflation branch from its last step back to 0.02."""
    base = tmp_path_factory.mktemp("family")
    run = deflate(icosphere(3), ShellParameters.from_gamma(GAMMA, nu=NU),
                  schedule=[0.02, 0.04, 0.06, 0.08], out=base / "down")
    back = continue_from(run, -1, base / "up", schedule=[0.05, 0.02])
    return run, back


@pytest.fixture(scope="module")
def run(family):
    return family[0]


# ------------------------------------------------------------------------------ XDMF
def _informations(element) -> dict:
    return {i.get("Name"): i.get("Value") for i in element.findall("Information")}


def test_xdmf_reads_back_every_step_exactly_with_meshio(run, tmp_path):
    path = export_series(run, tmp_path / "series.xdmf")
    assert path.is_file() and path.with_suffix(".h5").is_file()
    table = run.table
    with meshio.xdmf.TimeSeriesReader(path) as reader:
        points, cells = reader.read_points_cells()
        assert reader.num_steps == len(run.steps)
        np.testing.assert_array_equal(points, run.positions(run.steps[0]))
        np.testing.assert_array_equal(cells[0].data, run.faces)
        for k, step in enumerate(run.steps):
            t, point_data, cell_data = reader.read_data(k)
            assert t == step  # the time is the step number
            X = run.positions(step)
            np.testing.assert_array_equal(point_data["X"], X)
            np.testing.assert_array_equal(point_data["displacement"], X - run.positions(0))
            assert point_data["H"].shape == (len(X),)
            assert cell_data["stretching_energy_density"][0].shape == (len(run.faces),)
    # the per-step values are the table's, exactly (repr of a float round-trips)
    grids = ET.parse(path).getroot().find("Domain/Grid").findall("Grid")
    assert len(grids) == len(run.steps)
    for grid, step in zip(grids, run.steps):
        info = _informations(grid)
        row = table[table["step"] == step].iloc[0]
        assert int(info["step"]) == step
        for column in ("dV_over_V", "pressure", "E_over_kappa", "E_bend", "E_stretch"):
            assert float(info[column]) == row[column]
        # ParaView moves the geometry: each grid's Geometry is its own step's positions
        assert grid.find("Geometry/DataItem").text.endswith(f"/steps/{step:06d}/X")


def test_xdmf_carries_the_run_parameters(run, tmp_path):
    path = export_series(run, tmp_path / "series")  # the extension is added
    assert path.suffix == ".xdmf"
    info = _informations(ET.parse(path).getroot().find("Domain"))
    params = run.params
    assert float(info["gamma"]) == params.gamma and float(info["nu"]) == params.nu
    assert info["energy_convention"] == params.energy_convention
    assert float(info["p_c"]) == classical_threshold(params).pressure
    import h5py

    with h5py.File(path.with_suffix(".h5")) as h5:
        assert h5.attrs["gamma"] == params.gamma
        assert h5.attrs["energy_convention"] == params.energy_convention
        last = run.steps[-1]
        assert h5[f"steps/{last:06d}"].attrs["dV_over_V"] == run.table["dV_over_V"].iloc[-1]


def test_vtu_of_one_step_carries_field_data(run, tmp_path):
    step = run.steps[-1]
    mesh = meshio.read(export_step(run, step, tmp_path / "last.vtu"))
    row = run.table.iloc[-1]
    assert mesh.field_data["step"][0] == step
    for column in ("dV_over_V", "pressure", "E_over_kappa"):
        assert mesh.field_data[column][0] == row[column]
    assert mesh.field_data["gamma"][0] == GAMMA and mesh.field_data["nu"][0] == NU
    assert mesh.field_data["bending_factor"][0] == run.params.bending_factor
    assert mesh.field_data["pressure_over_p_c"][0] == pytest.approx(
        row["pressure"] / run_metadata(run)["p_c"], rel=1e-15)


def test_cli_export_xdmf(run, tmp_path, capsys):
    out = tmp_path / "cli.xdmf"
    assert main(["export", str(run.path), "--format", "xdmf", "--out", str(out)]) == 0
    assert out.is_file() and out.with_suffix(".h5").is_file()
    assert f"{len(run.steps)} steps" in capsys.readouterr().out


@pytest.mark.parametrize("argv, fragment", [
    (["--format", "xdmf", "--step", "1"], "--step 1: not used with --format xdmf"),
    (["--format", "vtu"], "--step is required"),
    (["--format", "xdmf", "--out", "{tmp}/x.vtu"], "--out"),
])
def test_cli_export_xdmf_refuses(run, tmp_path, capsys, argv, fragment):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(["export", str(run.path)] + argv) == 2
    assert fragment in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


# ------------------------------------------------------------------------------ animation
def _frames(path) -> int:
    from PIL import Image

    with Image.open(path) as image:
        return image.n_frames


def test_gif_has_one_frame_per_stored_step(run, tmp_path, capsys):
    out = tmp_path / "run.gif"
    assert main(["animate", str(run.path), "--out", str(out), "--fps", "8", "--dpi", "50"]) == 0
    assert _frames(out) == len(run.steps)
    assert f"({len(run.steps)} frames, 8 per second)" in capsys.readouterr().out


def test_gif_of_every_other_step_keeps_the_last(run, tmp_path):
    from shellbuckle.plots.animation import animate_run, frame_steps

    shown = frame_steps(run.steps, 2)
    assert shown[0] == run.steps[0] and shown[-1] == run.steps[-1]
    assert shown == sorted(set(run.steps[::2]) | {run.steps[-1]})
    path = animate_run(run, tmp_path / "every2.gif", every=2, dpi=50)
    assert _frames(path) == len(shown)
    assert _frames(animate_run(run, tmp_path / "two.gif", steps=[0, -1], dpi=50)) == 2


@pytest.mark.parametrize("argv, fragment", [
    (["--fps", "0"], "--fps 0: allowed: an integer in [1, 60]"),
    (["--fps", "61"], "--fps 61: allowed: an integer in [1, 60]"),
    (["--fps", "2.5"], "--fps 2.5: not an integer"),
    (["--out", "{tmp}/a.avi"], "--out"),
    (["--out", "{tmp}/no/a.gif"], "does not exist"),
    (["--every", "0"], "--every 0"),
])
def test_animate_refuses_bad_input_before_any_work(run, tmp_path, capsys, argv, fragment):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(["animate", str(run.path)] + argv) == 2
    assert fragment in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_mp4_without_ffmpeg_exits_2_suggesting_gif(run, tmp_path, capsys, monkeypatch):
    import shellbuckle.plots.animation as animation

    monkeypatch.setattr(animation, "mp4_available", lambda: False)
    assert main(["animate", str(run.path), "--out", str(tmp_path / "a.mp4")]) == 2
    err = capsys.readouterr().err
    assert "ffmpeg" in err and ".gif" in err
    assert not list(tmp_path.iterdir())


# ------------------------------------------------------------------------------ p-V, Run methods
def test_a_damaged_neighbour_is_left_out_of_the_family_with_a_warning(family, tmp_path, caplog):
    """Searched in a folder holding a copy of the branch, a copy whose run.json names a parent
    without a path and a copy whose run.json is not JSON: the family is the run and the
    branch, and each damaged neighbour is named in a warning."""
    import json
    import shutil

    from shellbuckle.plots.pv import family as find_family

    run, back = family
    here = tmp_path / "runs"
    branch = shutil.copytree(back.path, here / "branch")  # its parent: the run itself
    no_path = shutil.copytree(back.path, here / "no_path")
    meta = json.loads((no_path / "run.json").read_text())
    meta["parent"] = {"step": 1}
    (no_path / "run.json").write_text(json.dumps(meta))
    garbage = shutil.copytree(back.path, here / "garbage")
    (garbage / "run.json").write_text("{not json")
    with caplog.at_level("WARNING", logger="shellbuckle.plots.pv"):
        members = find_family(run, search=here)
    assert [Path(m.path) for m in members] == [Path(run.path), branch]
    assert "no_path" in caplog.text and "garbage" in caplog.text


def test_family_finds_the_branch_and_pv_draws_both_paths(family, tmp_path):
    from shellbuckle.plots.pv import family as find_family

    run, back = family
    members = find_family(run)
    assert [m.path for m in members] == [run.path, back.path]
    assert [m.path for m in find_family(back)] == [back.path]  # a branch's family: itself
    fig = run.pv(tmp_path / "pv.png")
    assert (tmp_path / "pv.png").stat().st_size > 0
    ax = fig.axes[0]
    p_c = classical_threshold(run.params).pressure
    lines = [line for line in ax.lines if line.get_marker() == "o"]
    assert len(lines) == 2
    for line, member in zip(lines, members):
        np.testing.assert_array_equal(line.get_xdata(), member.table["dV_over_V"])
        np.testing.assert_allclose(line.get_ydata(), member.table["pressure"] / p_c, rtol=1e-15)
    assert "p/p_c" in ax.get_ylabel()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("deflation" in t for t in labels) and any("re-inflation" in t for t in labels)
    # the run by its seed, the branch by the parent's step it starts from
    assert (f"{Path(run.path).name}, seed {run.protocol.seed}: deflation, arrowheads along "
            "the path") in labels
    assert any(f"from step {back.store.parent['step']} of {Path(run.path).name}: re-inflation"
               in t for t in labels), labels
    # the arrows point the way each path goes: right on the deflation, left on the way back
    arrows = [a for a in ax.texts if getattr(a, "arrow_patch", None) is not None]
    signs = {np.sign(a.xy[0] - a.xyann[0]) for a in arrows}
    assert signs == {1.0, -1.0}
    assert len(run.pv(branches=False).axes[0].get_legend().get_texts()) == 2  # run + theory


def test_run_plot_is_the_deflate_figure_and_its_view_axis_is_the_classifiers(run, tmp_path):
    from shellbuckle.analysis.classify import classify
    from shellbuckle.plots.run import view_axis

    run.plot(tmp_path / "run.png")
    assert (tmp_path / "run.png").stat().st_size > 0
    for step in run.steps:
        X = run.positions(step)
        expected = classify(X, run.faces).dent_axis
        got = view_axis(X, run.faces)
        assert (got is None) == (expected is None)
        if expected is not None:
            np.testing.assert_array_equal(got, np.asarray(expected))
