"""The documented examples run and their own checks (assertions inside them) hold."""

import runpy
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _run_notebook(monkeypatch, out, quick: bool):
    monkeypatch.setenv("SHELLBUCKLE_EXAMPLE_OUT", str(out))
    monkeypatch.setenv("SHELLBUCKLE_EXAMPLE_QUICK", "1" if quick else "0")
    return runpy.run_path(str(EXAMPLES / "notebook.py"), run_name="__main__")


def _check(namespace, out):
    from shellbuckle.mesh.io import read_mesh
    from shellbuckle.run import Run

    run = namespace["run"]
    table = Run.open(run.path).table
    # the analysis columns were stored, one class per step, and step 0 is the sphere
    assert table["shape"].notna().all() and table["shape"].iloc[0] == "sphere"
    for name in ("deflation.png", "theory.png", "view.html", "last.vtu", "last.fe"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    # the VTU holds the positions of the exported step
    mesh = read_mesh(out / "last.vtu")
    assert abs(mesh.X - run.positions(-1)).max() < 1e-12
    # the gamma path ends at the target gamma at the volume of its start step
    path = namespace["path"].table
    assert path["gamma"].iloc[-1] == 7465
    assert (abs(path["dV_over_V"] - path["dV_over_V"].iloc[0]) < 1e-12).all()


def test_notebook_quick(tmp_path, monkeypatch):
    _check(_run_notebook(monkeypatch, tmp_path, quick=True), tmp_path)


@pytest.mark.slow
def test_notebook_full(tmp_path, monkeypatch):
    _check(_run_notebook(monkeypatch, tmp_path, quick=False), tmp_path)
