"""Every figure the package draws passes a visual check.

Each figure is rendered from small real runs (gamma = 2333 and 271, 642 vertices, 5 steps) or
small synthetic tables, drawn on the Agg canvas, and checked in display coordinates:

- its size is the documented one (and so is the PNG it writes);
- no legend covers drawn data: no vertex of a line, and no point every 2 px along a drawn
  segment, error bar or scattered marker of its axes lies inside the legend's box;
- titles, axis labels, tick labels in view, legend texts and figure texts lie inside the
  figure (none is cut);
- no text overlaps another of the same axes or of another axes, no figure text overlaps
  another or a panel (for a 3D panel, the drawn surface);
- every line contrasts with its axes' background: WCAG contrast ratio >= 2, the colour seen
  through its alpha (for markers alone, the face or the edge);
- no text says "(±?)"; fit legends state their degrees of freedom.

The checks are written here, independently of :func:`shellbuckle.plots.render.drawn_points`
and :func:`~shellbuckle.plots.render.place_legend`. In SI units the values drawn are the
reduced run's times the paper's units, computed here from (E, sigma, d, R).
"""

import io
import itertools
import math

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PathCollection
from matplotlib.figure import Figure
from matplotlib.text import Text
from matplotlib.transforms import Bbox

from shellbuckle.analysis.classify import classify
from shellbuckle.analysis.fits import fit_power_law
from shellbuckle.mesh import icosphere
from shellbuckle.mesh.mesh import Mesh
from shellbuckle.params import ShellParameters, d_over_R
from shellbuckle.plots import across, paper
from shellbuckle.plots.animation import animation_frame
from shellbuckle.plots.pv import family, plot_pv
from shellbuckle.plots.render import place_legend, render_figure
from shellbuckle.plots.run import plot_deflation, plot_run, view_axis
from shellbuckle.plots.theory import plot_theory
from shellbuckle.run import Run, continue_from, continue_in_parameter, deflate
from shellbuckle.studies import refinement

from test_analysis_shapes import inverted_cap

#: Lowest WCAG contrast ratio of a line against its background (white on white is 1).
MIN_CONTRAST = 2.0
#: The material of the SI run: a shell of radius 0.1 mm with gamma = 2333, nu = 1/3.
E, SIGMA, R = 2e6, 0.5, 1e-4
D = d_over_R(2333.0, 1.0 / 3.0) * R


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Deflations to dV/V = 0.3 in 5 steps on a 642-vertex icosphere (~1.3 s each): gamma =
    2333 with and without the c0 cycle and its re-inflation branch, gamma = 271 and its path
    in gamma to 2333 at dV/V = 0.18, and the gamma = 2333 shell as a material of radius
    0.1 mm."""
    base = tmp_path_factory.mktemp("visual")
    mesh = icosphere(8)
    options = dict(dv=0.06, until=0.3, seed=1, threads=1, locate=False)
    params = ShellParameters.from_gamma(2333.0, nu=1.0 / 3.0)
    out = {"a": deflate(mesh, params, out=base / "g2333", **options)}
    out["back"] = continue_from(out["a"], 5, base / "g2333_back", dv=-0.06, until=0.12,
                                threads=1, locate=False)
    out["plain"] = deflate(mesh, params, out=base / "g2333_plain", c0_cycle=False, **options)
    out["g271"] = deflate(mesh, ShellParameters.from_gamma(271.0, nu=1.0 / 3.0),
                          out=base / "g271", **options)
    out["path"] = continue_in_parameter(out["g271"], 3, base / "g271_path", gamma=2333.0,
                                        increments=2, threads=1, locate=False)
    material = ShellParameters.from_material(E=E, sigma=SIGMA, d=D, R=R)
    out["material"] = deflate(Mesh.from_arrays(mesh.X * R, mesh.faces), material,
                              out=base / "material", **options)
    return {k: Run.open(v.path) for k, v in out.items()}


def collected(gammas, seeds=1):
    """A :func:`~shellbuckle.analysis.collect.collect_runs` table and analysed tables of
    deflations at ``gammas`` with the paper's laws for thresholds (primary 2.8 gamma^-0.55,
    secondary 850/gamma) and 4-8 wrinkles, ``seeds`` runs each."""
    rows, tables = [], {}
    for g, s in itertools.product(gammas, range(seeds)):
        name = f"g{g:g}_s{s}"
        dv = np.round(np.arange(0.0, 0.9, 0.019), 3)
        primary, secondary = 2.8 * g ** -0.55 * (1 + 0.05 * s), 850.0 / g * (1 + 0.03 * s)
        shape = np.where(dv < primary, "sphere", np.where(dv < secondary, "capsule",
                                                          "wrinkled"))
        W = np.where(shape == "wrinkled", 4 + round(math.log(g)) % 4 + np.arange(len(dv)) % 2,
                     0)
        tables[name] = pd.DataFrame({"dV_over_V": dv, "shape": shape, "W": W})
        window = (shape == "wrinkled") & (dv >= 0.53) & (dv <= 0.76)
        rows.append({
            "path": name, "name": name, "parent": None, "gamma": float(g), "nu": 1 / 3,
            "energy_convention": "helfrich", "seed": s, "c0_cycle": True, "control": "volume",
            "dv": 0.019, "n_steps": len(dv), "stop_dV_over_V": float(dv[-1]),
            "primary_dV_over_V": primary,
            "axisymmetry_loss_dV_over_V": secondary if secondary < 0.9 else math.nan,
            "wrinkles_dV_over_V": 1.1 * secondary if 1.1 * secondary < 0.9 else math.nan,
            "W_mean": W[window].mean() if window.any() else math.nan,
            "W_std": W[window].std() if window.any() else math.nan,
            "W_steps": int(window.sum()), "converged_fraction": 1.0})
    return pd.DataFrame(rows), tables


MANY = (271, 600, 933, 2333, 6000, 15163, 29160)


def _empty_W():
    df, tables = collected([300])
    return df.assign(W_steps=0), {k: t.assign(shape="capsule") for k, t in tables.items()}


def refinement_table() -> pd.DataFrame:
    """A refinement report's table (:data:`shellbuckle.studies.refinement.COLUMNS`): every
    quantity, two groups, three meshes, values q0 (1 + 2 h^2) extrapolated to q0."""
    rows = []
    labels = refinement.quantities() | refinement.carried_columns()
    for convention, gamma in (("paper", 15163.0), ("helfrich", 2333.0)):
        for i, (quantity, label) in enumerate(labels.items()):
            q0 = (1.0 + 0.1 * i) * (2.0 if convention == "paper" else 1.0)
            for n in refinement.VERTICES:
                h = float(refinement.mean_edge(n))
                mean = q0 * (1.0 + 2.0 * h ** 2)
                rows.append({
                    "energy_convention": convention, "gamma": gamma, "nu": 1.0 / 3.0,
                    "imperfection": "shape 0.1 d", "quantity": quantity, "label": label,
                    "n_vertices": n, "h": h, "mean": mean, "std": 0.01 * mean, "n_seeds": 2,
                    "seeds": "0 1", "compared_mean": mean, "extrapolated": q0, "order": 2.0,
                    "method": "Richardson", "extrapolation_seeds": "0 1",
                    "paper_mesh_value": q0, "paper_mesh_error": 0.0,
                    "paper_mesh_relative_error": 0.0})
    return pd.DataFrame(rows, columns=list(refinement.COLUMNS))


#: name -> (builder of the figure from the runs, size in inches; a None height: any).
FIGURES = {
    "run": (lambda r: plot_deflation(r["a"]), (13.5, 5.0)),
    "run_si": (lambda r: plot_deflation(r["material"], units="si"), (13.5, 5.0)),
    "pv": (lambda r: plot_pv(family(r["a"])), (5.0, 3.8)),
    "pv_si": (lambda r: plot_pv([r["material"]], units="si"), (5.0, 3.8)),
    "fig3": (lambda r: paper.fig3_potato_capsule(r["plain"], r["a"], at=0.18),
             (paper.COLUMN, None)),
    "fig4": (lambda r: across.plot_W_vs_dV(*collected(MANY, seeds=2)), across.FIGSIZE),
    "fig4_no_wrinkles": (lambda r: across.plot_W_vs_dV(*_empty_W()), across.FIGSIZE),
    "fig5": (lambda r: across.plot_W_vs_gamma(collected(MANY, seeds=2)[0]), across.FIGSIZE),
    "fig5_no_wrinkles": (lambda r: across.plot_W_vs_gamma(_empty_W()[0]), across.FIGSIZE),
    "fig7": (lambda r: paper.fig7_gallery([r["a"], r["plain"], r["g271"]], at=0.3),
             (paper.PAGE, None)),
    "fig9": (lambda r: paper.fig9_energy([r["a"]]), (1.65 * paper.COLUMN, 2.8)),
    "fig9_runs": (lambda r: paper.fig9_energy([r["a"], r["plain"], r["g271"]]),
                  (1.65 * paper.COLUMN, 2.8)),
    "fig9_si": (lambda r: paper.fig9_energy([r["material"]], units="si"),
                (1.65 * paper.COLUMN, 2.8)),
    "fig10_two_gammas": (lambda r: across.plot_thresholds(collected([300, 3000])[0]),
                         (9.6, 4.8)),
    "fig10": (lambda r: across.plot_thresholds(collected(MANY, seeds=2)[0]), (9.6, 4.8)),
    "fig11_gamma_path": (lambda r: paper.fig11_paths(r["a"], r["path"], at=0.18),
                         (paper.COLUMN, None)),
    "fig11_branch": (lambda r: paper.fig11_paths(r["a"], r["back"], at=0.18),
                     (paper.COLUMN, None)),
    "gallery": (lambda r: paper.run_gallery(r["a"]), (paper.PAGE, None)),
    "gallery_si": (lambda r: paper.run_gallery(r["material"], units="si"), (paper.PAGE, None)),
    "theory": (lambda r: plot_theory(ShellParameters.from_gamma(2333.0)), (11.0, 5.4)),
    "rendering": (lambda r: render_figure(r["a"].positions(5), r["a"].faces, title="step 5"),
                  (3.4, None)),
    "animation_frame": (lambda r: animation_frame(r["a"]), (4.0, 4.5)),
    "refinement": (lambda r: refinement.figure(refinement_table()), (12.8, None)),
}


# ---------------------------------------------------------------------- the checks

def _draw(fig):
    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    fig.canvas.draw()
    return fig.canvas.get_renderer()


def _luminance(rgb) -> float:
    c = np.asarray(rgb, float)
    c = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return float(c @ [0.2126, 0.7152, 0.0722])


def contrast(color, background) -> float:
    """WCAG 2 contrast ratio of ``color`` (RGBA; its alpha blended on ``background``)."""
    rgba = np.asarray(matplotlib.colors.to_rgba(color), float)
    bg = np.asarray(matplotlib.colors.to_rgb(background), float)
    seen = rgba[3] * rgba[:3] + (1.0 - rgba[3]) * bg
    lo, hi = sorted((_luminance(seen), _luminance(bg)))
    return (hi + 0.05) / (lo + 0.05)


def _line_contrast(line, background) -> float:
    alpha = line.get_alpha()
    if line.get_linestyle() not in ("None", "", " "):
        colors = [line.get_color()]
    else:
        colors = [c for c in (line.get_markerfacecolor(), line.get_markeredgecolor())
                  if not (isinstance(c, str) and c.lower() == "none")]
    return max(contrast(matplotlib.colors.to_rgba(c, alpha), background) for c in colors)


def _dense(P, step=2.0):
    out = [P]
    for a, b in zip(P[:-1], P[1:]):
        if np.isfinite(a).all() and np.isfinite(b).all():
            t = np.linspace(0.0, 1.0, max(int(np.linalg.norm(b - a) / step), 1) + 1)[1:, None]
            out.append(a + t * (b - a))
    return np.concatenate(out)


def data_pixels(ax) -> np.ndarray:
    """Display coordinates of the data ``ax`` draws, inside its box (module docstring)."""
    pts = [np.zeros((0, 2))]
    for line in ax.get_lines():
        P = line.get_transform().transform(np.asarray(line.get_xydata(), float))
        if line.get_linestyle() not in ("None", "", " ") and len(P) > 1:
            P = _dense(P)
        pts.append(P[np.isfinite(P).all(axis=1)])
    for c in ax.collections:
        if isinstance(c, LineCollection):
            pts += [_dense(c.get_transform().transform(np.asarray(s, float)))
                    for s in c.get_segments()]
        elif isinstance(c, PathCollection):
            pts.append(c.get_offset_transform().transform(np.asarray(c.get_offsets(), float)))
    P = np.concatenate(pts)
    b = ax.get_window_extent()
    return P[(P[:, 0] >= b.x0) & (P[:, 0] <= b.x1) & (P[:, 1] >= b.y0) & (P[:, 1] <= b.y1)]


def _tick_labels(ax):
    out = []
    for axis in (ax.xaxis, ax.yaxis):
        lo, hi = sorted(axis.get_view_interval())
        eps = 1e-9 * (hi - lo)
        for tick in axis.get_major_ticks() + axis.get_minor_ticks():
            if tick.get_loc() is not None and lo - eps <= tick.get_loc() <= hi + eps:
                out += [t for t in (tick.label1, tick.label2) if t.get_visible()]
    return out


def _shown(texts):
    return [t for t in texts if t.get_visible() and t.get_text().strip()]


def _axes_texts(ax):
    return _shown([ax.title, ax._left_title, ax._right_title, ax.xaxis.label,
                   ax.yaxis.label, *ax.texts])


def _figure_texts(fig):
    texts = list(fig.texts)
    if fig._suptitle is not None and fig._suptitle not in texts:
        texts.append(fig._suptitle)
    return _shown(texts)


def _picture(ax):
    """What a 3D panel draws: the box of its projected polygons."""
    V = [p.vertices for c in ax.collections for p in c.get_paths()]
    if not V:
        return ax.get_window_extent()
    P = ax.transData.transform(np.concatenate(V))
    return Bbox([P.min(axis=0), P.max(axis=0)])


def visual_problems(fig) -> list[str]:
    """Every failed check of ``fig`` (module docstring), in words."""
    renderer = _draw(fig)
    width, height = fig.canvas.get_width_height()
    inside = Bbox([[-1.0, -1.0], [width + 1.0, height + 1.0]])
    flat = [ax for ax in fig.axes if ax.name != "3d"]
    problems = []
    legends = [(ax.get_legend(), [ax]) for ax in flat if ax.get_legend() is not None]
    legends += [(legend, flat) for legend in fig.legends]
    for legend, axes in legends:
        box = legend.get_window_extent(renderer)
        for ax in axes:
            P = data_pixels(ax)
            covered = ((P[:, 0] > box.x0) & (P[:, 0] < box.x1) & (P[:, 1] > box.y0)
                       & (P[:, 1] < box.y1))
            if covered.any():
                problems.append(f"a legend covers {covered.sum()} data points of "
                                f"{ax.get_title() or ax.get_ylabel()!r}")
    texts = _figure_texts(fig) + [t for leg in fig.legends for t in leg.get_texts()]
    for ax in fig.axes:
        texts += _axes_texts(ax)
        if ax.axison and ax.name != "3d":
            texts += _tick_labels(ax)
        if ax.get_legend() is not None:
            texts += list(ax.get_legend().get_texts())
    for t in texts:
        box = t.get_window_extent(renderer)
        if not (inside.contains(box.x0, box.y0) and inside.contains(box.x1, box.y1)):
            problems.append(f"text {t.get_text()!r} is cut: {box.bounds} outside the figure")
    groups = [[(t.get_text(), t.get_window_extent(renderer)) for t in _axes_texts(ax)]
              + ([("legend", ax.get_legend().get_window_extent(renderer))]
                 if ax.get_legend() is not None else [])
              for ax in fig.axes]
    top = [(t.get_text(), t.get_window_extent(renderer)) for t in _figure_texts(fig)]
    top += [("figure legend", leg.get_window_extent(renderer)) for leg in fig.legends]
    for group in [*groups, top]:
        for (a, box_a), (b, box_b) in itertools.combinations(group, 2):
            if box_a.overlaps(box_b):
                problems.append(f"texts {a!r} and {b!r} overlap")
    for group_a, group_b in itertools.combinations(groups, 2):  # of two panels
        for (a, box_a), (b, box_b) in itertools.product(group_a, group_b):
            if box_a.overlaps(box_b):
                problems.append(f"texts {a!r} and {b!r} of two panels overlap")
    for a, box_a in top:
        for ax in fig.axes:
            if box_a.overlaps(_picture(ax) if ax.name == "3d" else ax.get_window_extent()):
                problems.append(f"figure text {a!r} overlaps the axes {ax.get_label()!r}")
    for ax in flat:
        background = ax.get_facecolor()[:3]
        for line in ax.get_lines():
            ratio = _line_contrast(line, background)
            if ratio < MIN_CONTRAST:
                problems.append(f"line {line.get_label()!r} has contrast {ratio:.2f}")
    problems += [f"text {t.get_text()!r} prints an unknown error"
                 for t in fig.findobj(Text) if "±?" in t.get_text()]
    return problems


# ---------------------------------------------------------------------- every figure

@pytest.mark.parametrize("name", list(FIGURES))
def test_every_figure_has_its_size_and_passes_the_visual_checks(runs, name):
    build, (width, height) = FIGURES[name]
    fig = build(runs)
    w, h = fig.get_size_inches()
    assert w == pytest.approx(width, abs=1e-9)
    if height is not None:
        assert h == pytest.approx(height, abs=1e-9)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=40)
    header = buffer.getvalue()[16:24]  # the PNG's width and height, pixels
    size = np.array([int.from_bytes(header[:4], "big"), int.from_bytes(header[4:], "big")])
    assert np.abs(size - np.array([w, h]) * 40).max() < 1.0
    assert visual_problems(fig) == []
    plt.close("all")


def test_the_checks_see_what_they_check():
    """The checks fail where they should: a legend on the data, a cut title, a pale line,
    two texts at one place."""
    fig = Figure(figsize=(4.0, 3.0))
    ax = fig.add_axes((0.15, 0.15, 0.8, 0.75))
    x = np.linspace(0.0, 1.0, 50)
    ax.plot(x, x, label="data")
    ax.plot(x, 1 - x, color="#fff59d", label="pale")
    ax.legend(loc="center")
    ax.set_title("a title far too long to fit inside a figure of only four inches wide")
    ax.text(0.1, 0.9, "one")
    ax.text(0.1, 0.9, "two")
    beside = fig.add_axes((0.5, 0.15, 0.4, 0.5))  # its title on the first panel's data
    beside.set_title("three")
    ax.text(0.7, 0.67, "four", transform=fig.transFigure, ha="center")
    problems = " | ".join(visual_problems(fig))
    for expected in ("legend covers", "is cut", "contrast", "'one' and 'two' overlap",
                     "'four' and 'three' of two panels overlap"):
        assert expected in problems


# ---------------------------------------------------------------------- legend placement

def test_a_legend_goes_to_the_free_corner_or_beside_the_axes():
    x = np.linspace(0.0, 1.0, 200)
    fig = Figure(figsize=(5.0, 4.0), constrained_layout=True)
    ax = fig.add_subplot()
    ax.plot(x, x, label="diagonal")            # leaves the upper left and lower right free
    ax.plot(x, 0.9 + 0.0 * x, label="a high line crossing the upper left")  # not the first
    legend = place_legend(ax)
    assert legend._loc == matplotlib.legend.Legend.codes["lower right"]
    assert visual_problems(fig) == []
    # data everywhere (loc="best" would cover some): beside the axes, inside the figure
    fig = Figure(figsize=(5.0, 4.0), constrained_layout=True)
    ax = fig.add_subplot()
    for level in np.linspace(0.0, 1.0, 21):
        ax.plot(x, level + 0.0 * x, color="C0", label="level" if level == 0 else None)
    legend = place_legend(ax)
    renderer = _draw(fig)
    assert legend.get_window_extent(renderer).x0 > ax.get_window_extent().x1
    assert visual_problems(fig) == []


# ---------------------------------------------------------------------- fits

def test_fit_legends_state_their_degrees_of_freedom():
    two = across.plot_thresholds(collected([300, 3000])[0])
    labels = {line.get_gid(): line.get_label() for line in two.axes[0].get_lines()}
    # two gammas: the free power law goes through both primary points, no error to give
    assert "0 dof" in labels["fit_primary"] and "no error estimate" in labels["fit_primary"]
    # 850/gamma through the two secondary points (loss of axisymmetry and wrinkles at
    # gamma = 3000; at 300 both would need more than the whole volume): one parameter
    assert "2 points, 1 dof" in labels["fit_secondary"]
    assert "(1 dof)" in labels["gamma_c"] and "±" in labels["gamma_c"]
    many = across.plot_thresholds(collected(MANY, seeds=1)[0])
    labels = {line.get_gid(): line.get_label() for line in many.axes[0].get_lines()}
    assert f"{len(MANY)} points, {len(MANY) - 2} dof" in labels["fit_primary"]
    for fig in (two, many):
        assert not [t for t in fig.findobj(Text) if "?" in t.get_text()]


def test_a_fit_says_what_its_error_rests_on():
    free = fit_power_law([300.0, 3000.0], [0.12, 0.034])
    assert free.dof == 0 and "no error estimate" in free.describe()
    assert "0 dof" in free.describe() and "?" not in free.describe()
    three = fit_power_law([300.0, 1000.0, 3000.0], [0.12, 0.06, 0.034])
    assert three.dof == 1 and three.describe().endswith("3 points, 1 dof")
    fixed = fit_power_law([300.0, 3000.0], [3.0, 0.3], exponent=-1.0)
    assert fixed.dof == 1 and "exponent fixed" in fixed.describe()
    weighted = fit_power_law([300.0, 3000.0], [0.12, 0.034], sigma=[0.01, 0.003])
    assert weighted.dof == 0 and "seeds' scatter" in weighted.describe()


# ---------------------------------------------------------------------- units

def _line(fig, gid, ax_index):
    return next(ln for ln in fig.axes[ax_index].get_lines() if ln.get_gid() == gid)


def test_si_figures_draw_the_reduced_values_times_the_papers_units(runs):
    """The material run is the gamma = 2333 shell of radius R. Its SI figures draw its
    E/kappa times kappa = E d^3/(12 (1 - sigma^2)) in J and its pressure in Pa, with
    p_c = 4 sqrt(kappa A)/R^2, A = (1 + 2 sigma)/(1 + sigma)^2 E d; these are the reduced
    run's E/kappa times kappa and p R^3/kappa times kappa/R^3 (scale invariance, to the
    minimizer's tolerance)."""
    kappa = E * D ** 3 / (12.0 * (1.0 - SIGMA ** 2))
    A = (1.0 + 2.0 * SIGMA) / (1.0 + SIGMA) ** 2 * E * D
    p_c = 4.0 * math.sqrt(kappa * A) / R ** 2
    own, reduced = runs["material"].table, runs["a"].table
    si = plot_deflation(runs["material"], units="si")
    energy = _line(si, "simulation", 0).get_ydata()
    pressure = _line(si, "simulation", 1).get_ydata()
    np.testing.assert_allclose(energy, own["E_over_kappa"] * kappa, rtol=1e-12)
    np.testing.assert_array_equal(pressure, own["pressure"])
    np.testing.assert_allclose(energy, reduced["E_over_kappa"] * kappa, rtol=1e-4)
    np.testing.assert_allclose(pressure, reduced["pressure"] * kappa / R ** 3, rtol=1e-4,
                               atol=1e-9 * kappa / R ** 3)
    assert _line(si, "p_c", 1).get_ydata()[0] == pytest.approx(p_c, rel=1e-12)
    assert "(J)" in si.axes[0].get_ylabel() and "(Pa)" in si.axes[1].get_ylabel()
    assert any("1/m" in ax.get_ylabel() for ax in si.axes)       # the colour bar
    assert f"R$ = {R:.3g} m" in si.axes[2].get_title()
    # the same run in reduced units: E/kappa and p/p_c
    same = plot_deflation(runs["material"])
    np.testing.assert_allclose(_line(same, "simulation", 0).get_ydata(), own["E_over_kappa"],
                               rtol=1e-12)
    np.testing.assert_allclose(_line(same, "simulation", 1).get_ydata(),
                               own["pressure"] / p_c, rtol=1e-12)
    pv = plot_pv([runs["material"]], units="si")
    np.testing.assert_array_equal(_line(pv, "pv:material", 0).get_ydata(), own["pressure"])
    fig9 = paper.fig9_energy([runs["material"]], units="si")
    np.testing.assert_allclose(_line(fig9, "simulation:material", 0).get_ydata(),
                               own["E_over_kappa"] * kappa, rtol=1e-12)
    plt.close("all")


def test_one_pressure_unit_across_the_figures(runs):
    """The run figure and the p-V figure draw the same pressures, p/p_c, with one axis
    label; Fig. 9 and the paper's figures draw no pressure."""
    run = runs["a"]
    p_c = 4.0 * math.sqrt(run.params.kappa * run.params.A) / run.params.R ** 2
    expected = run.table["pressure"].to_numpy(float) / p_c
    figure = plot_deflation(run)
    pv = plot_pv([run])
    drawn = _line(figure, "simulation", 1)
    np.testing.assert_allclose(drawn.get_ydata(), expected, rtol=1e-12)
    np.testing.assert_allclose(_line(pv, "pv:g2333", 0).get_ydata(), expected, rtol=1e-12)
    assert figure.axes[1].get_ylabel() == pv.axes[0].get_ylabel()
    assert "p/p_c" in pv.axes[0].get_ylabel() and "classical buckling" in pv.axes[0].get_ylabel()
    assert not any("pressure" in ax.get_ylabel() for ax in paper.fig9_energy([run]).axes)
    plt.close("all")


def test_si_needs_a_material_and_is_refused_before_any_work(runs, monkeypatch):
    import shellbuckle.plots.run as run_figure

    def fail(*args, **kwargs):
        raise AssertionError("work started")

    monkeypatch.setattr(run_figure, "view_axis", fail)
    with pytest.raises(ValueError, match="material"):
        plot_deflation(runs["a"], units="si")
    with pytest.raises(ValueError, match="units must be one of reduced, si"):
        plot_deflation(runs["a"], units="cgs")
    with pytest.raises(ValueError, match="material"):
        plot_pv([runs["a"]], units="si")
    with pytest.raises(ValueError, match="material"):
        paper.fig9_energy([runs["a"]], units="si")
    with pytest.raises(ValueError, match="material"):
        paper.run_gallery(runs["a"], units="si")


# ---------------------------------------------------------------------- the 3D panel

@pytest.mark.parametrize("alpha_deg", [45.0, 88.0])
def test_the_run_figure_looks_into_the_dent_of_a_deep_bowl(alpha_deg):
    """The camera of the run figure's 3D panel is on the side the classifier's dent axis
    points to (their dot product is positive), also for a bowl so deep that its inverted
    vertices lie past the centre."""
    sphere = icosphere(10)
    u = np.array([0.3, -0.5, 0.81])
    u /= np.linalg.norm(u)
    X = inverted_cap(sphere.X, math.radians(alpha_deg), axis=u)
    dent_axis = np.asarray(classify(X, sphere.faces).dent_axis)
    assert dent_axis @ u > 0.9  # the oracle: a cap inverted about u has its dent along +u
    table = pd.DataFrame({"step": [0, 1], "dV_over_V": [0.0, 0.3], "E_over_kappa": [0.0, 50.0],
                          "pressure": [0.0, 10.0]})
    fig = plot_run(table, ShellParameters.from_gamma(2333.0), X, sphere.faces,
                   axis=view_axis(X, sphere.faces))
    panel = next(ax for ax in fig.axes if hasattr(ax, "rendering"))
    camera = panel.rendering.frame[2]  # from the shape towards the camera
    assert camera @ dent_axis > 0.3
    plt.close("all")


def test_the_stored_run_figure_looks_into_its_dent(runs):
    run = runs["a"]
    X = run.positions(run.steps[-1])
    dent_axis = classify(X, run.faces).dent_axis
    assert dent_axis is not None
    panel = next(ax for ax in plot_deflation(run).axes if hasattr(ax, "rendering"))
    assert panel.rendering.frame[2] @ np.asarray(dent_axis) > 0.3
    plt.close("all")
