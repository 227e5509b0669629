"""The paper's simulation figures draw exactly the run data: plotted arrays equal the table
columns, renderings show the stored positions of the chosen steps, labels the analysis."""

import math
import re

import numpy as np
import pytest
from matplotlib.text import Text

from shellbuckle import theory
from shellbuckle.analysis import ShapeAnalyzer, analyze_run, classify, events
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.plots import paper
from shellbuckle.run import Run, deflate

GAMMA = 743.0
#: A reference file with invented values: the figures must print what the file says.
REFERENCE = {"results": {
    "potato_vs_capsule": {"gamma": 743, "nu": 0.3333, "DeltaV_over_V": 0.12, "vertices": 3594,
                          "potato_dimples": 23, "energy_ratio_potato_over_capsule": 9.87},
    "soleil": {"gamma": 15163, "DeltaV_over_V": 0.645,
               "statement": "a conformation reached otherwise has 2.71 times lower energy"},
    "gallery_at_DeltaV_over_V_0.854": [{"gamma": 743, "shape": "a test capsule (panel z)"}],
}}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two tiny real deflations (162 vertices, 4 steps, buckled at the end): with and
    without the zero-curvature cycle; the first analysed (table columns), the second not."""
    base = tmp_path_factory.mktemp("paper_runs")
    params = ShellParameters.from_gamma(GAMMA, nu=1.0 / 3.0)
    cycle = deflate(icosphere(4), params, dv=0.06, until=0.18, out=base / "cycle", seed=0)
    plain = deflate(icosphere(4), params, dv=0.06, until=0.18, out=base / "plain", seed=0,
                    c0_cycle=False)
    analyze_run(cycle)
    return Run.open(cycle.path), Run.open(plain.path)


def _line(fig, gid):
    found = [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_gid() == gid]
    assert len(found) == 1, gid
    return found[0]


def _texts(fig):
    return " ".join(t.get_text() for t in fig.findobj(Text))


def _check_panel(ax, run, step):
    """The panel shows the stored positions of ``step`` and labels them from the run."""
    conf, rendering = ax.conformation, ax.rendering
    X = run.positions(step)
    row = run.table.set_index("step").loc[step]
    assert conf.step == step and conf.run == run.path.name
    np.testing.assert_array_equal(conf.X, X)
    np.testing.assert_allclose(rendering.centre, X.mean(axis=0), rtol=0, atol=1e-14)
    assert conf.dV_over_V == row["dV_over_V"] and conf.E_over_kappa == row["E_over_kappa"]
    H = ShapeAnalyzer(run.faces, n_vertices=len(X)).geometry(X).H_smooth
    np.testing.assert_allclose(rendering.face_values, H[run.faces].mean(axis=1), atol=1e-12)
    c = classify(X, run.faces)
    if "shape" in run.table.columns and isinstance(row["shape"], str):
        assert (conf.shape, conf.W, conf.n_dimples) == (row["shape"], row["W"], row["n_dimples"])
    assert (conf.shape, conf.W, conf.n_dimples) == (c.shape, c.W, c.n_dimples)


def _readable(fig):
    assert fig.get_figwidth() <= paper.PAGE + 1e-9
    sizes = [t.get_fontsize() for t in fig.findobj(Text) if t.get_text().strip()]
    assert min(sizes) >= 6.0


def test_fig9_draws_the_table_and_the_theory(runs):
    cycle, plain = runs
    fig = paper.fig9_energy([cycle])
    table = cycle.table
    line = _line(fig, f"simulation:{cycle.path.name}")
    np.testing.assert_array_equal(line.get_xdata(), table["dV_over_V"].to_numpy(float))
    np.testing.assert_array_equal(line.get_ydata(), table["E_over_kappa"].to_numpy(float))
    # U_sphere against eq. Usphere written out: 4 pi R^2 A / (9 (1 - nu)) (dV/V)^2, kappa = 1
    p = cycle.params
    u = _line(fig, f"U_sphere:{p.gamma:g}")
    x = np.asarray(u.get_xdata())
    np.testing.assert_allclose(u.get_ydata(), 4 * math.pi * p.A / (9 * (1 - p.nu)) * x ** 2,
                               rtol=1e-12)
    axi = _line(fig, f"U_axisym:{p.gamma:g}")
    np.testing.assert_allclose(axi.get_ydata(),
                               theory.U_axisym_of_dV(np.asarray(axi.get_xdata()), p), rtol=1e-12)
    # the crossing line is where the two energies are equal
    xc = _line(fig, f"crossing:{p.gamma:g}").get_xdata()[0]
    assert theory.U_sphere(xc, p) == pytest.approx(float(theory.U_axisym_of_dV(xc, p)),
                                                   rel=1e-8)
    # the primary buckling marker is the analysis' event, at the table's energy
    primary = [e for e in events(cycle) if e.name == "primary_buckling"]
    mark = _line(fig, f"primary:{cycle.path.name}")
    assert len(primary) == 1
    assert mark.get_xdata()[0] == primary[0].dV_over_V
    assert mark.get_ydata()[0] == table.set_index("step").loc[primary[0].step, "E_over_kappa"]
    _readable(fig)


def test_fig9_with_several_runs_draws_each(runs):
    fig = paper.fig9_energy(list(runs))
    for run in runs:
        line = _line(fig, f"simulation:{run.path.name}")
        np.testing.assert_array_equal(line.get_ydata(), run.table["E_over_kappa"].to_numpy())


def test_run_gallery_shows_every_kth_step_and_the_last(runs):
    cycle, plain = runs
    fig = paper.run_gallery(plain, every=2)
    steps = plain.steps
    expected = steps[::2] + ([steps[-1]] if steps[-1] not in steps[::2] else [])
    assert [ax.conformation.step for ax in fig.panels] == expected
    for ax in fig.panels:
        _check_panel(ax, plain, ax.conformation.step)
    assert len({ax.rendering.radius for ax in fig.panels}) == 1  # one scale for all panels
    _readable(fig)
    default = paper.run_gallery(cycle, max_panels=3)
    assert len(default.panels) <= 3
    assert default.panels[0].conformation.step == steps[0]
    assert default.panels[-1].conformation.step == steps[-1]
    with pytest.raises(ValueError, match="every"):
        paper.run_gallery(cycle, every=0)


def test_fig7_shows_the_steps_nearest_to_the_volume(runs):
    cycle, plain = runs
    at = 0.1
    fig = paper.fig7_gallery([plain, cycle], at=at, reference=REFERENCE)
    for ax, run in zip(fig.panels, (plain, cycle)):  # sorted by gamma, stable (same gamma)
        dv = run.table["dV_over_V"].to_numpy()
        step = int(run.table["step"].iloc[int(np.argmin(np.abs(dv - at)))])
        _check_panel(ax, run, step)
    assert "\\gamma$ = 743" in _texts(fig)
    fig = paper.fig7_gallery([cycle], reference=REFERENCE)  # the paper's 0.854: nearest step
    assert fig.panels[0].conformation.step == cycle.steps[-1]
    assert "paper: a test capsule" in _texts(fig)


def test_fig3_ratio_and_the_papers_values_from_the_reference(runs):
    cycle, plain = runs
    fig = paper.fig3_potato_capsule(plain, cycle, reference=REFERENCE)
    at = REFERENCE["results"]["potato_vs_capsule"]["DeltaV_over_V"]
    steps = [paper.nearest_step(r, at) for r in (plain, cycle)]
    for ax, run, step in zip(fig.panels, (plain, cycle), steps):
        _check_panel(ax, run, step)
    e = [r.table.set_index("step").loc[k, "E_over_kappa"] for r, k in zip((plain, cycle), steps)]
    assert fig.energy_ratio == e[0] / e[1]
    text = _texts(fig)
    assert f"= {e[0] / e[1]:.2f}" in text
    assert "23 dimples, ratio 9.87" in text
    assert "without $c_0$ cycle" in text and "with $c_0$ cycle" in text
    _readable(fig)


def test_fig11_two_steps_of_one_run_and_the_papers_ratio(runs):
    cycle, _ = runs
    a, b = cycle.steps[-2], cycle.steps[-1]
    fig = paper.fig11_paths(cycle, cycle, step_a=a, step_b=b, reference=REFERENCE)
    _check_panel(fig.panels[0], cycle, a)
    _check_panel(fig.panels[1], cycle, b)
    e = cycle.table.set_index("step")["E_over_kappa"]
    assert fig.energy_ratio == max(e[a], e[b]) / min(e[a], e[b])
    text = _texts(fig)
    assert "ratio 2.71" in text
    assert "different $\\Delta V/V$" in text  # two different volumes are said to differ


def test_fig11_of_two_runs_at_one_volume(runs):
    cycle, plain = runs
    fig = paper.fig11_paths(plain, cycle, reference={})
    at = min(plain.table["dV_over_V"].max(), cycle.table["dV_over_V"].max())
    assert [ax.conformation.step for ax in fig.panels] == [paper.nearest_step(r, at)
                                                           for r in (plain, cycle)]
    assert "different" not in _texts(fig)
    assert "paper" not in _texts(fig)  # no reference values given: ours only


def test_save_writes_valid_png_and_pdf(runs, tmp_path):
    fig = paper.fig9_energy(runs[0])
    written = paper.save(fig, tmp_path / "sub" / "fig9")
    assert [p.name for p in written] == ["fig9.png", "fig9.pdf"]
    png, pdf = written
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    assert pdf.read_bytes()[:5] == b"%PDF-" and pdf.read_bytes().rstrip()[-5:] == b"%%EOF"
    # 300 dpi at the figure's size (PNG header: width, height big-endian at bytes 16-24)
    header = png.read_bytes()[16:24]
    width = int.from_bytes(header[:4], "big")
    assert width == round(fig.get_figwidth() * 300)
    with pytest.raises(ValueError, match="formats"):
        paper.save(fig, tmp_path / "x", formats=("png", "bmp"))


@pytest.mark.parametrize("bad", [1.2, -0.1, float("nan"), 1.0])
def test_nearest_step_refuses_volumes_outside_0_1(runs, bad):
    with pytest.raises(ValueError, match=re.escape(repr(bad)) if bad == bad else "nan"):
        paper.nearest_step(runs[0], bad)


def test_nearest_step_is_the_closest_stored_volume(runs):
    run = runs[0]
    dv = run.table["dV_over_V"].to_numpy()
    for target in np.linspace(0.0, 0.99, 23):
        k = paper.nearest_step(run, target)
        # the nearest, up to a tie within VOLUME_TIE (then the last of the tied steps)
        distance = np.abs(dv - target)
        assert abs(dv[run.steps.index(k)] - target) <= distance.min() + paper.VOLUME_TIE
        assert k == run.steps[np.flatnonzero(distance <= distance.min() + paper.VOLUME_TIE)[-1]]


def test_fig7_of_many_runs_wraps_into_rows_of_equal_panels(runs):
    fig = paper.fig7_gallery(list(runs) * 3, at=0.1, reference={})
    boxes = [ax.get_position() for ax in fig.panels]
    assert len(boxes) == 6
    ncols = paper.GALLERY_COLUMNS
    assert len({round(b.y0, 9) for b in boxes[:ncols]}) == 1  # first row
    assert boxes[ncols].y0 < boxes[0].y0 - boxes[0].height  # second row, below the first
    assert len({round(b.width * fig.get_figwidth(), 9) for b in boxes}) == 1
    assert fig.get_figwidth() == paper.PAGE
    _readable(fig)
