"""``shellbuckle classify`` and ``shellbuckle analyze`` on files and run folders."""

import json

import numpy as np
import pytest

from shellbuckle.cli import main
from shellbuckle.mesh import Mesh, write_mesh
from shellbuckle.store import RunStore

from test_analysis_classify import wrinkle_profile
from test_analysis_shapes import inverted_cap, mesh, modulated_cap

AXIS = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])


@pytest.fixture(scope="module")
def wrinkled6():
    m = mesh("random")
    return Mesh.from_arrays(modulated_cap(m.X, np.radians(45), wrinkle_profile(6), AXIS, 0.3),
                            m.faces)


@pytest.mark.parametrize("ext", [".ply", ".vtk", ".obj", ".fe"])
def test_classify_a_mesh_file(tmp_path, capsys, wrinkled6, ext):
    path = write_mesh(tmp_path / f"shape{ext}", wrinkled6)
    assert main(["classify", str(path)]) == 0
    out = capsys.readouterr().out
    assert "wrinkled" in out and "W           6" in out and "corners     6" in out
    assert main(["classify", str(path), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert (result["shape"], result["W"], result["n_dimples"]) == ("wrinkled", 6, 1)
    assert np.dot(result["dent_axis"], AXIS) > 0.99


@pytest.fixture
def two_step_run(tmp_path):
    m = mesh("icosphere")
    path = tmp_path / "run"
    with RunStore.create(path, params={"gamma": 1.0}, protocol={}, X0=m.X, faces=m.faces) as s:
        s.append_step(0, m.X, {"dV_over_V": 0.0, "pressure": 10.0, "inertia": 0})
        s.append_step(1, inverted_cap(m.X, np.radians(60)), {"dV_over_V": 0.3, "pressure": 2.0,
                                                              "inertia": 0})
    return path


def test_classify_a_run_step(capsys, two_step_run):
    assert main(["classify", str(two_step_run), "--step", "0", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["shape"] == "sphere"
    assert main(["classify", str(two_step_run), "--json"]) == 0  # default: the last step
    result = json.loads(capsys.readouterr().out)
    assert result["shape"] == "capsule"
    assert result["dent_depth"] == pytest.approx(2 * (1 - np.cos(np.radians(60))), abs=0.01)
    assert result["dent_axis"] == pytest.approx([0, 0, 1], abs=0.01)


def test_analyze_fills_the_columns_and_prints_the_events(capsys, two_step_run):
    assert main(["analyze", str(two_step_run), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "primary_buckling" in out and "step    1" in out and "[confirmed]" in out
    stored = json.loads((two_step_run / "analysis.json").read_text())
    assert stored["0"]["shape"] == "sphere" and stored["1"]["shape"] == "capsule"
    assert main(["analyze", str(two_step_run), "--quiet", "--json"]) == 0
    found = json.loads(capsys.readouterr().out)["events"]
    assert [(e["name"], e["step"]) for e in found] == [("primary_buckling", 1)]


@pytest.mark.parametrize("argv, fragment", [
    (["classify", "no_such_file.ply"], "does not exist"),
    (["classify", "shape.xyz"], "unsupported mesh file extension"),
    (["analyze", "no_such_dir"], "does not exist"),
])
def test_bad_input_exits_2(tmp_path, monkeypatch, capsys, argv, fragment):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "shape.xyz").write_text("1 2 3\n")
    assert main(argv) == 2
    assert fragment in capsys.readouterr().err


def test_step_options_are_checked(capsys, two_step_run, tmp_path, wrinkled6):
    assert main(["classify", str(two_step_run), "--step", "7"]) == 2
    assert "--step 7" in capsys.readouterr().err
    path = write_mesh(tmp_path / "s.ply", wrinkled6)
    assert main(["classify", str(path), "--step", "1"]) == 2
    assert "run folder" in capsys.readouterr().err
