"""The run object's own analysis and viewer: ``Run.classify(k)`` and ``Run.view(k)``.

Oracles: ``Run.classify`` is the classification ``shellbuckle classify DIR --step K`` prints and
:func:`shellbuckle.analysis.classify_run` returns, and equals the stored analysis columns where
these are current; ``Run.view`` holds the page ``shellbuckle view DIR --step K`` writes.
"""

import html
import json
import re
import shutil
import sys
import types

import numpy as np
import pytest

from shellbuckle.analysis import analyze_run, classify_run
from shellbuckle.cli import main
from shellbuckle.plots.viewer_page import in_notebook
from shellbuckle.run import Run
from shellbuckle.util import json_safe
from test_analysis_classify import deflated_271


@pytest.fixture
def run(tmp_path_factory, tmp_path):
    """A copy of the gamma = 271 deflation (642 vertices, sphere then capsule), so that what a
    test writes or checks is written stays its own."""
    shutil.copytree(deflated_271(tmp_path_factory).path, tmp_path / "g271")
    return Run.open(tmp_path / "g271")


def _files(path) -> dict:
    return {p.name: (p.stat().st_mtime_ns, p.stat().st_size) for p in path.rglob("*")}


def _page_data(text: str) -> dict:
    m = re.search(r'<script id="sb-data" type="application/json">(.*?)</script>', text, re.S)
    return json.loads(m.group(1))


# ------------------------------------------------------------------------------ classify
def test_classify_is_the_command_s_classification(run, capsys):
    steps = run.steps
    for k in (0, len(steps) // 2, -1):
        c = run.classify(k)
        capsys.readouterr()
        assert main(["classify", str(run.path), "--step", str(k), "--json"]) == 0
        printed = json.loads(capsys.readouterr().out)
        assert printed.pop("source") == f"{run.path} step {run.step(k)}"
        assert json_safe(c.as_dict()) == printed
        # and the run-level function on the same step
        assert json_safe(classify_run(run.path, steps=[run.step(k)])[run.step(k)].as_dict()) \
            == printed
    # the shell is a sphere at step 0 and has buckled into one dent at the end
    assert run.classify(0).shape == "sphere" and run.classify(0).dent_axis is None
    last = run.classify()
    assert last.n_dimples == 1 and np.linalg.norm(last.dent_axis) == pytest.approx(1.0)


def test_classify_writes_nothing_and_matches_the_stored_analysis(run):
    before = _files(run.path)
    computed = {k: run.classify(k) for k in run.steps}
    assert _files(run.path) == before
    analyze_run(run)
    stored = run.store.analysis()
    for k, c in computed.items():
        # the stored columns are the same numbers (non-finite stored as null)
        assert {name: stored[k][name] for name in c.columns()} == json_safe(c.columns())
    # with the analysis stored, the same classification
    assert json_safe(run.classify(-1).as_dict()) == json_safe(computed[run.steps[-1]].as_dict())


def test_classify_refuses_a_step_that_is_not_stored(run):
    with pytest.raises(ValueError, match="allowed steps"):
        run.classify(len(run.steps) + 3)
    with pytest.raises(ValueError, match="integer"):
        run.classify(1.5)


# ------------------------------------------------------------------------------ view
def test_view_outside_jupyter_writes_the_command_s_page(run, tmp_path, capsys):
    assert not in_notebook()  # pytest runs in no Jupyter kernel
    page = run.view(1, open_browser=False)
    assert page.path == run.path / "view.html" and page.path.is_file()
    text = page.path.read_text(encoding="utf-8")
    assert text == page.html
    assert run.steps[_page_data(text)["start"]] == 1
    # the page of `shellbuckle view DIR --step 1`, byte for byte
    out = tmp_path / "cli.html"
    assert main(["view", str(run.path), "--out", str(out), "--step", "1"]) == 0
    assert out.read_text(encoding="utf-8") == text
    # elsewhere, under another colouring
    other = run.view(-1, color="strain", path=tmp_path / "strain.html", open_browser=False)
    data = _page_data(other.path.read_text(encoding="utf-8"))
    assert data["color"] == "strain" and data["start"] == len(run.steps) - 1


def test_view_shows_the_page_inline(run):
    page = run.view(-1, inline=True)
    assert page.path is None and not (run.path / "view.html").exists()
    frame = page._repr_html_()
    m = re.fullmatch(r'<div[^>]*><iframe srcdoc="(.*?)" style="[^"]*height: 760px[^"]*" '
                     r'sandbox="allow-scripts"></iframe></div>', frame, re.S)
    assert m is not None
    assert html.unescape(m.group(1)) == page.html
    data = _page_data(page.html)
    assert data["steps"] == run.steps and data["n_vertices"] == len(run.store.X0)


def test_view_in_a_jupyter_kernel_is_inline(run, monkeypatch):
    # a Jupyter kernel: IPython's shell has a kernel
    shell = types.SimpleNamespace(kernel=object())
    monkeypatch.setitem(sys.modules, "IPython", types.SimpleNamespace(get_ipython=lambda: shell))
    assert in_notebook()
    page = run.view()
    assert page.path is None and not (run.path / "view.html").exists()
    assert "<iframe srcdoc=" in page._repr_html_()
    # a terminal IPython has no kernel: the page is written
    monkeypatch.setitem(sys.modules, "IPython",
                        types.SimpleNamespace(get_ipython=lambda: types.SimpleNamespace()))
    assert not in_notebook()
    assert run.view(open_browser=False).path == run.path / "view.html"


def test_view_opens_the_written_page_in_the_browser(run, monkeypatch):
    import webbrowser

    opened = []
    monkeypatch.setattr(webbrowser, "open", lambda url, *a, **k: opened.append(url) or True)
    page = run.view(0, inline=False)
    assert opened == [page.path.resolve().as_uri()]
    assert run.view(0, inline=False, open_browser=False).path.is_file() and len(opened) == 1


def test_view_refuses_bad_values(run, tmp_path):
    with pytest.raises(ValueError, match="curvature, strain, bending"):
        run.view(color="pressure", inline=True)
    with pytest.raises(ValueError, match="allowed steps"):
        run.view(99, inline=True)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        run.view(path=tmp_path / "missing" / "v.html", open_browser=False)
