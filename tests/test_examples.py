"""The documented examples run and their own checks (assertions inside them) hold; the
notebook ``examples/tour.ipynb`` runs top to bottom in a Jupyter kernel and makes what it says."""

import html
import json
import re
import runpy
from pathlib import Path

import numpy as np
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


# ------------------------------------------------------------------------------ tour.ipynb
def _execute(notebook: Path, folder: Path):
    """Run every cell of ``notebook`` in a fresh ``python3`` kernel (ipykernel's) with
    ``folder`` as its working directory; CellExecutionError names a failing cell."""
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(notebook, as_version=4)
    NotebookClient(nb, timeout=240, kernel_name="python3",
                   resources={"metadata": {"path": str(folder)}}).execute()
    return nb


def _is_image(path: Path) -> bool:
    import matplotlib.image

    if not path.read_bytes().startswith(b"\x89PNG\r\n\x1a\n"):
        return False
    pixels = matplotlib.image.imread(path)
    return pixels.shape[0] > 100 and pixels.shape[1] > 100 and float(pixels.std()) > 0.01


def test_tour_notebook_is_stored_without_outputs():
    nb = json.loads((EXAMPLES / "tour.ipynb").read_text(encoding="utf-8"))
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    assert code and all(c["outputs"] == [] and c["execution_count"] is None for c in code)
    assert nb["metadata"]["kernelspec"]["name"] == "python3"


def test_tour_notebook_runs_and_makes_what_it_says(tmp_path):  # about 20 s
    from shellbuckle import theory
    from shellbuckle.analysis import events
    from shellbuckle.run import Run

    nb = _execute(EXAMPLES / "tour.ipynb", tmp_path)
    run = Run.open(tmp_path / "runs" / "g2333")
    params, table = run.params, run.table
    # the deflation: gamma = 2333, steps of 0.019 up to 0.3, every one finished
    assert run.status == "finished" and params.gamma == 2333
    n = int(np.floor(0.3 / 0.019 + 1e-9))
    assert run.steps == list(range(n + 1))
    np.testing.assert_allclose(table["dV_over_V"], 0.019 * np.arange(n + 1), atol=1e-9)
    # before buckling the energy rises with dV/V and is the shrunk sphere's stretching energy
    primary = next(e for e in events(run) if e.name == "primary_buckling")
    before = table[table["step"] < primary.step]
    assert len(before) >= 2 and (np.diff(before["E_total"]) > 0).all()
    np.testing.assert_allclose(before["E_stretch"][1:],
                               theory.U_sphere_exact(before["dV_over_V"][1:], params), rtol=0.01)
    # it buckles past the energetic crossing and before the classical threshold (paper Fig. 9)
    assert theory.crossing(params) < primary.dV_over_V < \
        theory.classical_threshold(params).dV_over_V_exact
    # the classification the notebook shows: a sphere, then one dent
    assert run.classify(0).shape == "sphere" and run.classify(-1).n_dimples == 1
    # the figures, as images
    for name in ("deflation.png", "pv.png"):
        assert _is_image(tmp_path / name), name
    # the re-inflation branch: a child of the run, its volume loss shrinking
    back = Run.open(tmp_path / "runs" / "g2333-back")
    assert Path(back.store.parent["path"]).resolve() == run.path.resolve()
    assert (np.diff(back.table["dV_over_V"]) < 0).all()
    # the viewer, inline: the page of every step, opening at the primary buckling
    frames = [o["data"]["text/html"] for c in nb.cells if c.cell_type == "code"
              for o in c.outputs if "<iframe srcdoc=" in o.get("data", {}).get("text/html", "")]
    assert len(frames) == 1
    page = html.unescape(re.search(r'srcdoc="(.*?)"', frames[0], re.S).group(1))
    data = json.loads(re.search(r'<script id="sb-data" type="application/json">(.*?)</script>',
                                page, re.S).group(1))
    assert data["steps"] == run.steps and data["steps"][data["start"]] == primary.step
    assert not (run.path / "view.html").exists()  # inline: nothing written
