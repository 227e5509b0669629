"""The interactive viewer page (shellbuckle.plots.viewer) and ``shellbuckle view``."""

import base64
import html
import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from shellbuckle import ShellParameters
from shellbuckle.cli import main
from shellbuckle.export import RunFields
from shellbuckle.mesh import icosphere
from shellbuckle.plots.viewer import COLORS, html_page, show, write_html
from shellbuckle.run import Run, deflate
from shellbuckle.store import RunStore

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")
                 if shutil.which(n)), None)
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="no Chromium found (chromium, chromium-browser or google-chrome on "
                             "PATH); on Debian/Ubuntu: apt-get install -y chromium")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A small deflation that buckles: gamma = 271, icosphere(4), past the primary buckling."""
    out = tmp_path_factory.mktemp("view") / "run"
    return deflate(icosphere(4), ShellParameters.from_gamma(271.0), schedule=[0.1, 0.2, 0.24],
                   out=out)


@pytest.fixture(scope="module")
def page(run, tmp_path_factory):
    return write_html(run, tmp_path_factory.mktemp("page") / "view.html")


def _data(text: str) -> dict:
    m = re.search(r'<script id="sb-data" type="application/json">(.*?)</script>', text, re.S)
    return json.loads(m.group(1))


def _decode(b64: str, dtype) -> np.ndarray:
    return np.frombuffer(base64.b64decode(b64), dtype=dtype)


# ------------------------------------------------------------------------------ the page's data
def test_page_is_self_contained(page):
    text = page.read_text(encoding="utf-8")
    # the only URL is the SVG namespace name, which is never fetched
    urls = set(re.findall(r"(?:https?:)?//[\w.-]+\.\w+[^\s\"')]*", text))
    assert urls <= {"http://www.w3.org/2000/svg"}, urls
    for fetching in ("<link", " src=", "fetch(", "XMLHttpRequest", "import(", "@import"):
        assert fetching not in text


def test_embedded_positions_faces_and_table_match_the_run(run, page):
    data = _data(page.read_text(encoding="utf-8"))
    steps = run.steps
    assert data["steps"] == steps
    V, F = data["n_vertices"], data["n_faces"]
    faces = _decode(data["faces"], "<u2").reshape(F, 3)
    np.testing.assert_array_equal(faces, run.faces)
    q = _decode(data["positions"], "<u2").reshape(len(steps), V, 3).astype(float)
    lo, hi = np.array(data["box"][:3]), np.array(data["box"][3:])
    P = lo + q * (hi - lo) / 65535
    for i, k in enumerate(steps):
        # uint16 quantization on the bounding box: error at most half a level
        assert np.abs(P[i] - run.positions(k)).max() <= 0.5 * (hi - lo).max() / 65535 * (1 + 1e-9)
    table = data["table"]
    cols = table["columns"]
    for name in ("step", "dV_over_V", "E_total", "E_bend", "E_stretch", "pressure"):
        assert name in cols
        got = [r[cols.index(name)] for r in table["rows"]]
        np.testing.assert_array_equal(got, run.table[name].to_numpy())


def test_colour_indices_encode_the_fields(run, page):
    data = _data(page.read_text(encoding="utf-8"))
    fields = RunFields.of(run)
    S = len(run.steps)
    expected = {
        "curvature": np.stack([fields.mean_curvature(run.positions(k)) for k in run.steps]),
        "strain": np.stack([fields.stretching_density(run.positions(k)) for k in run.steps]),
    }
    expected["bending"] = fields.bending_density(None, expected["curvature"])
    for name in COLORS:
        f = data["fields"][name]
        index = _decode(f["data"], "u1").reshape(S, -1).astype(float)
        assert index.shape == expected[name].shape
        assert len(_decode(f["lut"], "u1")) == 256 * 3
        lo, hi = f["lo"], f["hi"]
        value = np.clip(expected[name], lo, hi)
        assert np.abs(lo + index / 255 * (hi - lo) - value).max() <= 0.5 * (hi - lo) / 255 * (1 + 1e-9)
    # the curvature scale is centred on H = 0 (blue where the surface is inverted)
    assert data["fields"]["curvature"]["lo"] == -data["fields"]["curvature"]["hi"]
    # the buckled steps have an inverted cap: negative mean curvature somewhere
    assert expected["curvature"][-1].min() < 0 < expected["curvature"][0].min()


def test_page_size_for_the_papers_mesh(tmp_path):
    """3612 vertices (icosphere(19), like the paper's 3594) x 50 steps: a few MB."""
    mesh = icosphere(19)
    X0 = mesh.X
    store = RunStore.create(tmp_path / "big", params=ShellParameters.from_gamma(2333.0).to_dict(),
                            protocol={"schedule": list(np.arange(1, 50) * 0.019)},
                            X0=X0, faces=mesh.faces)
    rng = np.random.default_rng(1)
    for k in range(50):
        h = 1.0 - 0.03 * k  # mirror the cap z > h (an inverted dent), plus a little noise
        X = X0.copy()
        X[:, 2] = np.where(X[:, 2] > h, 2 * h - X[:, 2], X[:, 2])
        X += 1e-3 * rng.standard_normal(X.shape)
        store.append_step(k, X, {"target_dV_over_V": 0.019 * k, "dV_over_V": 0.019 * k,
                                 "E_total": float(k), "E_bend": 0.5 * k, "E_stretch": 0.5 * k,
                                 "pressure": 1.0})
    store.close()
    path = write_html(Run.open(tmp_path / "big"), tmp_path / "big.html")
    size = path.stat().st_size
    assert size < 3.5e6, size


def test_bad_colour_is_refused(run, tmp_path):
    with pytest.raises(ValueError, match="curvature, strain, bending"):
        write_html(run, tmp_path / "x.html", color="pressure")


def test_show_returns_an_iframe_holding_the_page(run):
    pytest.importorskip("IPython")
    from IPython.display import HTML

    shown = show(run, color="strain")
    assert isinstance(shown, HTML)
    m = re.fullmatch(r'<div[^>]*><iframe srcdoc="(.*?)" style=[^>]*></iframe></div>', shown.data,
                     re.S)
    assert m is not None
    assert html.unescape(m.group(1)) == html_page(run, color="strain")


def test_cli_view(run, tmp_path, capsys):
    out = tmp_path / "v.html"
    assert main(["view", str(run.path), "--out", str(out), "--color", "bending"]) == 0
    assert _data(out.read_text(encoding="utf-8"))["color"] == "bending"
    assert main(["view", str(run.path)]) == 0
    assert (run.path / "view.html").is_file()
    capsys.readouterr()
    assert main(["view", str(run.path), "--color", "rainbow"]) == 2
    assert "curvature, strain, bending" in capsys.readouterr().err
    assert main(["view", str(tmp_path / "missing")]) == 2


def test_page_opens_at_the_step_asked(run, tmp_path, capsys):
    steps = run.steps
    # by default the last step; a step number or a negative index counted from the last
    assert steps[_data(html_page(run))["start"]] == steps[-1]
    assert steps[_data(html_page(run, step=1))["start"]] == 1
    assert steps[_data(html_page(run, step=-2))["start"]] == steps[-2]
    with pytest.raises(ValueError, match="allowed steps"):
        html_page(run, step=len(steps) + 5)
    out = tmp_path / "v.html"
    assert main(["view", str(run.path), "--out", str(out), "--step", "0"]) == 0
    assert steps[_data(out.read_text(encoding="utf-8"))["start"]] == 0
    capsys.readouterr()
    assert main(["view", str(run.path), "--out", str(out), "--step", "99"]) == 2
    assert "--step 99" in capsys.readouterr().err


# ------------------------------------------------------------------------------ headless Chromium
def _chromium(tmp_path, url, *extra):
    profile = tmp_path / "profile"
    profile.mkdir(exist_ok=True)
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           "--no-first-run", f"--user-data-dir={profile}", "--hide-scrollbars",
           "--window-size=1200,800", "--virtual-time-budget=5000", *extra, url]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120,
                          stdin=subprocess.DEVNULL)


def _root_attributes(dom: str) -> dict:
    m = re.search(r"<html([^>]*)>", dom)
    assert m is not None, dom[:500]
    return dict(re.findall(r'([\w-]+)="([^"]*)"', m.group(1)))


@needs_chromium
@pytest.mark.parametrize("renderer", ["auto", "canvas2d"])
def test_page_renders_in_headless_chromium(page, run, tmp_path, renderer):
    asked = run.steps[1]  # the page opens at the last step unless the address asks another
    query = f"?step={asked}&color=strain" + ("&renderer=canvas2d" if renderer == "canvas2d" else "")
    out = _chromium(tmp_path, page.as_uri() + query, "--dump-dom")
    attrs = _root_attributes(out.stdout)
    assert "data-error" not in attrs, attrs["data-error"]
    assert int(attrs.get("data-rendered", 0)) >= 1, out.stderr[-2000:]
    assert attrs["data-renderer"] in (("canvas2d",) if renderer == "canvas2d" else ("webgl", "canvas2d"))
    assert attrs["data-step"] == str(asked)
    n_faces = len(run.faces)
    drawn = int(attrs["data-triangles"])  # canvas-2D draws the faces turned to the viewer
    assert (drawn == n_faces) if attrs["data-renderer"] == "webgl" else (0.3 * n_faces < drawn < n_faces)
    dom = out.stdout
    current = re.findall(r'<tr class="current"><td>(\d+)</td>', dom)
    assert current == [str(asked)]
    assert "stretching energy density" in dom
    # one curve per series, through every step
    curves = re.findall(r'<path d="([^"]+)" class="curve"', dom)
    assert len(curves) == 4
    assert all(c.count("L") == len(run.steps) - 1 for c in curves)


@needs_chromium
def test_screenshot_shows_the_surface(page, tmp_path):
    Image = pytest.importorskip("PIL.Image")
    png = tmp_path / "shot.png"
    _chromium(tmp_path, page.as_uri() + "?renderer=canvas2d", f"--screenshot={png}")
    assert png.is_file()
    img = np.asarray(Image.open(png).convert("RGB")).astype(int)
    assert img.shape[:2] == (800, 1200)
    # the 3D view fills the left part of the page below the header; its centre is the shell
    centre = img[250:450, 270:470].reshape(-1, 3)
    background = np.array([0xf6, 0xf7, 0xfa])
    covered = np.abs(centre - background).sum(axis=1) > 30
    assert covered.mean() > 0.95
    assert len(np.unique(centre, axis=0)) > 20  # shaded and coloured, not a flat fill
