"""The simulation figures of Quilliet et al. (EPJE 27, 13 (2008)) drawn from run folders.

Each function takes runs (:class:`shellbuckle.run.Run` objects or run folders) and returns a
:class:`~matplotlib.figure.Figure` (Agg canvas, no display needed) sized for a journal page:
3.4 in (one column) or 7.0 in (two columns) wide, fonts of 7-9 pt. :func:`save` writes it as
PNG (300 dpi) and PDF.

- :func:`fig3_potato_capsule`: the conformations reached without and with the zero-curvature
  cycle at one dV/V (paper: gamma = 743, dV/V = 0.171, a potato with 17 dimples and a capsule
  with 3.10 times lower energy);
- :func:`fig7_gallery`: one conformation per run at dV/V = 0.854 (or the nearest stored step);
- :func:`fig9_energy`: E/kappa against dV/V with U_sphere and U_axisym (paper §3), the primary
  buckling of each run and the crossing U_sphere = U_axisym;
- :func:`fig11_paths`: two conformations at the same gamma and dV/V reached by different paths
  (paper: gamma = 15163, dV/V = 0.645, energy ratio 1.42);
- :func:`run_gallery`: the conformations of one run every k steps.

What is drawn is the run data: energies are the table's ``E_over_kappa``, volumes its
``dV_over_V``, conformations the stored positions of the chosen step
(:func:`shellbuckle.plots.render.render`, view along the dent axis). The shape class, corners
and W are the table's analysis columns when the run was analysed
(:func:`shellbuckle.analysis.analyze_run`), else they are computed the same way on the fly
(without writing). Each rendering axis carries the :class:`Conformation` it shows
(``ax.conformation``) and the :class:`~shellbuckle.plots.render.Rendering` (``ax.rendering``);
each data curve has a ``gid`` (``"simulation:<run folder name>"``), so the figures can be checked
against the runs.

The paper's values come from the reference file ``quilliet2008.json``
(:func:`shellbuckle.analysis.collect.load_reference`, re-exported here); without it the
figures show ours alone (logged).
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .. import theory
from ..analysis.collect import load_reference
from .render import CURVATURE_LIMIT, render
from .run import check_units, energy_unit
from .theory import _STYLE

__all__ = ["Conformation", "FORMATS", "conformation", "fig3_potato_capsule", "fig7_gallery",
           "fig9_energy", "fig11_paths", "load_reference", "nearest_step", "run_gallery", "save"]

log = logging.getLogger(__name__)

#: Widths of a journal column and of a full page, inches.
COLUMN = 3.4
PAGE = 7.0
#: The paper's gallery volume (Fig. 7).
GALLERY_DV_OVER_V = 0.854
#: Panels per row of Fig. 7 at page width (1.4 in each).
GALLERY_COLUMNS = 5
FORMATS = ("png", "pdf", "svg")
#: Volumes closer than this are one volume for :func:`nearest_step` (the dV/V held along a
#: path in gamma or c0 differs from step to step by rounding, ~1e-15).
VOLUME_TIE = 1e-9


# ---------------------------------------------------------------------- inputs

def _paper(reference, key: str) -> dict | None:
    if reference is None:
        return None
    return reference.get("results", {}).get(key)


def _open(run):
    from ..store.view import Run

    return Run.of(run)


def _name(run) -> str:
    return Path(run.path).name


def _short(run) -> str:
    """A run as a legend names it: its seed and what sets it apart, not its folder name."""
    protocol = run.protocol
    parts = [f"seed {protocol.seed}"]
    if run.store.n_vertices != 3594:
        parts.append(f"{run.store.n_vertices} vertices")
    if run.params.energy_convention != "helfrich":
        parts.append(run.params.energy_convention)
    if not protocol.c0_cycle:
        parts.append("no $c_0$ cycle")
    return ", ".join(parts)


def nearest_step(run, dV_over_V: float) -> int:
    """The stored step of ``run`` whose ``dV_over_V`` is nearest to ``dV_over_V`` (the last on
    a tie within :data:`VOLUME_TIE`, so along a path in gamma or c0 at fixed volume it is the
    end of the path).
    ValueError if ``dV_over_V`` is not a number in [0, 1) or the run has no step."""
    value = float(dV_over_V)
    if not (math.isfinite(value) and 0.0 <= value < 1.0):
        raise ValueError(f"dV/V must be in [0, 1), got {dV_over_V!r}")
    table = _open(run).table
    if table.empty:
        raise ValueError(f"run {run} has no finished step")
    distance = np.abs(table["dV_over_V"].to_numpy(dtype=float) - value)
    # a tie up to rounding: the volume held along a path is measured anew at each step
    i = int(np.flatnonzero(distance <= distance.min() + VOLUME_TIE)[-1])
    return int(table["step"].iloc[i])


@dataclass(frozen=True, eq=False)
class Conformation:
    """One stored conformation and what the figures write about it.

    ``run`` (folder name), ``step``, ``dV_over_V``, ``E_over_kappa`` (table values), ``gamma``
    (in force at that step), ``X (V, 3)`` stored positions, ``faces``, the class ``shape``,
    ``n_dimples``, ``corners``, ``W`` (the table's analysis columns when present, else
    computed), ``axis`` (dent axis or ``None``), ``H (V,)`` (the analysis' smoothed mean
    curvature, in the run's units like ``X``) and ``R``, the run's length unit (its radius in
    the units of ``X``: 1 for a shell given by gamma, metres for a material), by which the
    panels show ``X/R`` and ``H R``.
    """

    run: str
    step: int
    dV_over_V: float
    E_over_kappa: float
    gamma: float
    X: np.ndarray
    faces: np.ndarray
    shape: str
    n_dimples: int
    corners: int
    W: int
    axis: np.ndarray | None
    H: np.ndarray
    R: float = 1.0

    @property
    def label(self) -> str:
        """The class in words: ``capsule``, ``17 dimples``, ``polygonal, 5 corners``,
        ``wrinkled, W = 7``, ..."""
        if self.shape == "dimples":
            return f"{self.n_dimples} dimples"
        if self.shape == "polygonal":
            return f"polygonal, {self.corners} corners"
        if self.shape == "wrinkled":
            return f"wrinkled, W = {self.W}"
        return self.shape


def _stored(row, name):
    value = row.get(name)
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return None
    try:
        if value != value:  # pandas NA / NaN
            return None
    except TypeError:
        return None
    return value


def conformation(run, step: int, analyzer=None) -> Conformation:
    """The :class:`Conformation` of ``step`` of ``run`` (a Run or a folder). ``analyzer``: a
    :class:`~shellbuckle.analysis.ShapeAnalyzer` of the run's faces to reuse."""
    from ..analysis import ShapeAnalyzer, classify_descriptors

    run = _open(run)
    table = run.table
    rows = table[table["step"] == int(step)]
    if rows.empty:
        raise ValueError(f"run {_name(run)} has no finished step {step} "
                         f"(steps {int(table['step'].min())}..{int(table['step'].max())})")
    row = rows.iloc[0].to_dict()
    X = run.positions(int(step))
    faces = run.faces
    analyzer = analyzer or ShapeAnalyzer(faces, n_vertices=len(X), contact=False)
    c = classify_descriptors(analyzer.describe(X))
    stored = {k: _stored(row, k) for k in ("shape", "n_dimples", "corners", "W")}
    return Conformation(
        run=_name(run), step=int(step), dV_over_V=float(row["dV_over_V"]),
        E_over_kappa=float(row["E_over_kappa"]), gamma=_gamma_at(run, int(step)), X=X,
        faces=faces, shape=str(stored["shape"] if stored["shape"] is not None else c.shape),
        n_dimples=int(stored["n_dimples"] if stored["n_dimples"] is not None else c.n_dimples),
        corners=int(stored["corners"] if stored["corners"] is not None else c.corners),
        W=int(stored["W"] if stored["W"] is not None else c.W),
        axis=None if c.dent_axis is None else np.asarray(c.dent_axis),
        H=c.descriptors.geometry.H_smooth, R=float(run.params.R))


def _gamma_at(run, step: int) -> float:
    """gamma in force at ``step`` (the step's own along a path in gamma)."""
    params_at = getattr(run, "params_at", None)
    return float((params_at(step) if params_at else run.params).gamma)


def _length(conf: Conformation, units: str) -> float:
    """The length unit a panel shows ``conf`` in, in the run's units: its R (reduced), or 1
    (``"si"``: a material run's positions are stored in m)."""
    return conf.R if units == "reduced" else 1.0


def _panel(fig, rect, conf: Conformation, radius: float, tilt: float, units: str = "reduced"):
    """A 3D panel of ``conf`` in R and 1/R (or m and 1/m), colour limits ``CURVATURE_LIMIT/R``
    (the same colours for the same shape in either unit)."""
    L = _length(conf, units)
    ax = fig.add_axes(rect, projection="3d")
    ax.rendering = render(ax, conf.X / L, conf.faces, axis=conf.axis, values=conf.H * L,
                          vlim=CURVATURE_LIMIT * L / conf.R, radius=radius, tilt=tilt)
    ax.conformation = conf
    return ax


def _radius(confs, units: str = "reduced") -> float:
    """The half-width shared by the panels: the largest shape's, in the unit shown."""
    return max(float(np.linalg.norm(c.X - c.X.mean(axis=0), axis=1).max()) / _length(c, units)
               for c in confs)


def _colorbar(fig, ax_rendering, rect, orientation="horizontal", units: str = "reduced"):
    cax = fig.add_axes(rect)
    bar = fig.colorbar(ax_rendering.rendering.mappable, cax=cax, orientation=orientation)
    unit = "1/R" if units == "reduced" else "1/m"
    bar.set_label(rf"mean curvature $H$ (${unit}$)", fontsize=7)
    cax.tick_params(labelsize=6)
    return bar


def _text_width(text: str, fontsize: float) -> float:
    """Width in inches of one line of ``text`` at ``fontsize`` points, as matplotlib draws it
    (mathtext between dollars)."""
    from matplotlib.backends.backend_agg import RendererAgg
    from matplotlib.font_manager import FontProperties

    math_text = text.count("$") >= 2 and text.count("$") % 2 == 0
    width, _, _ = RendererAgg(1, 1, 72).get_text_width_height_descent(
        text, FontProperties(size=fontsize), ismath=math_text)
    return width / 72.0


def _wrap(text: str, width: float, fontsize: float, min_fontsize: float = 6.0):
    """``(text, fontsize)`` of a caption that fits ``width`` inches: each line too wide is
    broken after its commas outside mathtext (greedily), and if a piece is still too wide the
    font shrinks by half points down to ``min_fontsize``."""
    lines = []
    for line in text.split("\n"):
        pieces, start = [], 0
        for i, char in enumerate(line):
            if line.startswith(", ", i) and line[:i].count("$") % 2 == 0:
                pieces.append(line[start:i + 1])
                start = i + 2
        pieces.append(line[start:])
        current = pieces[0]
        for piece in pieces[1:]:
            if _text_width(f"{current} {piece}", fontsize) <= width:
                current = f"{current} {piece}"
            else:
                lines.append(current)
                current = piece
        lines.append(current)
    while fontsize > min_fontsize and max(_text_width(ln, fontsize) for ln in lines) > width:
        fontsize -= 0.5
    return "\n".join(lines), fontsize


def _row_figure(confs, captions, width: float, title: str | None, footer: list[str],
                tilt: float, titles=None, ncols: int | None = None,
                units: str = "reduced") -> Figure:
    """Renderings in rows of ``ncols`` (default: one row) square panels, a caption under each,
    a colour bar and footer lines below, a title above. Layout in inches; every text is
    wrapped to its width (:func:`_wrap`: a caption to its panel, so neighbours never meet)."""
    n = len(confs)
    ncols = n if ncols is None else max(1, min(int(ncols), n))
    nrows = math.ceil(n / ncols)
    side = width / ncols
    fitted = [_wrap(c, side - 0.08, 7 if side >= 1.6 else 6.5) for c in captions]
    caption_h = 0.13 * max(c.count("\n") + 1 for c, _ in fitted)
    if title:
        title, title_size = _wrap(title, width - 0.1, 8.5)
    title_h = 0.25 + 0.15 * title.count("\n") if title else 0.0
    panel_title_h = 0.16 if titles else 0.0
    row_h = panel_title_h + side + caption_h
    bar_h = 0.55
    footer = [piece for line in footer for piece in _wrap(line, width - 0.08, 7)[0].split("\n")]
    footer_h = 0.14 * len(footer) + (0.05 if footer else 0.0)
    height = title_h + nrows * row_h + bar_h + footer_h
    fig = Figure(figsize=(width, height))
    radius = _radius(confs, units)
    axes = []
    for i, (conf, (caption, size)) in enumerate(zip(confs, fitted)):
        row, col = divmod(i, ncols)
        y0 = footer_h + bar_h + (nrows - 1 - row) * row_h + caption_h
        ax = _panel(fig, (col * side / width, y0 / height, side / width, side / height), conf,
                    radius, tilt, units)
        axes.append(ax)
        fig.text((col + 0.5) * side / width, (y0 - 0.03) / height, caption, ha="center",
                 va="top", fontsize=size, linespacing=1.25)
        if titles:
            fig.text((col + 0.5) * side / width, (y0 + side + 0.02) / height, titles[i],
                     ha="center", va="bottom", fontsize=8)
    _colorbar(fig, axes[0], (0.3, (footer_h + 0.38) / height, 0.4, 0.05 / height),
              units=units)
    for j, line in enumerate(footer):
        fig.text(0.02, (footer_h - 0.05 - 0.14 * j) / height, line, ha="left", va="top",
                 fontsize=7)
    if title:
        fig.text(0.5, 1.0 - 0.5 * title_h / height, title, ha="center", va="center",
                 fontsize=title_size)
    fig.panels = axes
    return fig


def _fmt(x: float) -> str:
    return f"{x:.4g}"


# ---------------------------------------------------------------------- Fig. 3

def fig3_potato_capsule(potato, capsule, *, at: float | None = None, reference=None,
                        tilt: float = 0.0) -> Figure:
    """Fig. 3: the conformation without the zero-curvature cycle (``potato`` run) beside the one
    with it (``capsule`` run), at the stored steps nearest to ``at`` (default: the paper's
    dV/V = 0.171, or the largest dV/V both runs reached if the reference is not found).

    Under each: the protocol, the class (dimples counted), E/kappa and the step's dV/V; below:
    the energy ratio E_potato/E_capsule and the paper's (17 dimples, ratio 3.10).
    """
    potato, capsule = _open(potato), _open(capsule)
    reference = load_reference(reference, required=False)
    paper = _paper(reference, "potato_vs_capsule")
    if at is None:
        at = paper["DeltaV_over_V"] if paper else min(
            float(potato.table["dV_over_V"].max()), float(capsule.table["dV_over_V"].max()))
    confs = [conformation(r, nearest_step(r, at)) for r in (potato, capsule)]
    for r, name in ((potato, "potato"), (capsule, "capsule")):
        if name == "potato" and r.protocol.c0_cycle:
            log.warning("the potato run %s used the zero-curvature cycle", _name(r))
        if name == "capsule" and not r.protocol.c0_cycle:
            log.warning("the capsule run %s did not use the zero-curvature cycle", _name(r))
    captions = [f"{'with' if r.protocol.c0_cycle else 'without'} $c_0$ cycle\n{c.label}\n"
                f"$E/\\kappa$ = {_fmt(c.E_over_kappa)}\n"
                f"$\\Delta V/V$ = {c.dV_over_V:.3f} (step {c.step})"
                for r, c in zip((potato, capsule), confs)]
    ratio = confs[0].E_over_kappa / confs[1].E_over_kappa
    footer = [f"ours: $E_\\mathrm{{potato}}/E_\\mathrm{{capsule}}$ = {ratio:.2f}, "
              f"{confs[0].label} vs {confs[1].label}"]
    if paper:
        footer += [f"paper ($\\gamma$ = {paper['gamma']:g}, $\\Delta V/V$ = "
                   f"{paper['DeltaV_over_V']:g}, {paper['vertices']} vertices):",
                   f"   {paper['potato_dimples']} dimples, ratio "
                   f"{paper['energy_ratio_potato_over_capsule']:.2f}"]
    gammas = {c.gamma for c in confs}
    title = (f"$\\gamma$ = {confs[0].gamma:g}" if len(gammas) == 1 else
             f"$\\gamma$ = {confs[0].gamma:g} vs {confs[1].gamma:g} (different!)")
    fig = _row_figure(confs, captions, COLUMN, title, footer, tilt)
    fig.energy_ratio = ratio
    return fig


# ---------------------------------------------------------------------- Fig. 7

def fig7_gallery(runs, *, at: float = GALLERY_DV_OVER_V, reference=None,
                 tilt: float = 0.0) -> Figure:
    """Fig. 7: one conformation per run at the stored step nearest to ``at`` (default 0.854),
    runs sorted by gamma, in rows of at most ``GALLERY_COLUMNS``, gamma as panel titles; under each: dV/V of the step, the class and W,
    and the paper's description of its gallery panel at the same gamma if it has one (up to its
    first comma or parenthesis)."""
    runs = sorted((_open(r) for r in runs), key=lambda r: r.params.gamma)
    if not runs:
        raise ValueError("fig7_gallery needs at least one run")
    paper = {float(p["gamma"]): re.split(r"[,(]", p["shape"])[0].strip()
             for p in (_paper(load_reference(reference, required=False),
                              f"gallery_at_DeltaV_over_V_{at:g}")
                       or [])}
    confs = [conformation(r, nearest_step(r, at)) for r in runs]
    captions = []
    for c in confs:
        lines = [f"$\\Delta V/V$ = {c.dV_over_V:.3f} (step {c.step})", c.label]
        if c.gamma in paper:
            lines.append(f"paper: {paper[c.gamma]}")
        captions.append("\n".join(lines))
    width = COLUMN if len(confs) <= 2 else PAGE
    fig = _row_figure(confs, captions, width, f"$\\Delta V/V \\approx$ {at:g}", [], tilt,
                      titles=[f"$\\gamma$ = {c.gamma:g}" for c in confs],
                      ncols=min(len(confs), GALLERY_COLUMNS))
    return fig


# ---------------------------------------------------------------------- Fig. 9

def fig9_energy(runs, *, theory_curves: bool = True, ax=None, units: str = "reduced") -> Figure:
    """Fig. 9: E/kappa (table column ``E_over_kappa``) against ``dV_over_V`` for each run, with
    U_sphere (eq. Usphere, small strain, as the paper's figure) and U_axisym (eq. Ucapsule) for
    each gamma, the primary buckling of each run (:func:`shellbuckle.analysis.events`; a filled
    triangle when the pressure drop confirms it, open otherwise) and the crossing
    U_sphere = U_axisym (vertical line). With one gamma the curves take the colours of
    :func:`shellbuckle.plots.theory.plot_theory` and the exact Green-Lagrange energy of the
    shrunk sphere is added; with several, each gamma has one colour (runs and theory) and the
    legend names the line styles once. ``units="si"`` (runs made from a material): energies in
    J, each run's E/kappa times its kappa, the theory of each gamma times the kappa of its
    first run."""
    from matplotlib.lines import Line2D

    from ..analysis import events

    runs = [_open(r) for r in ([runs] if not isinstance(runs, (list, tuple)) else runs)]
    if not runs:
        raise ValueError("fig9_energy needs at least one run")
    scales = [energy_unit(r.params, units)[0] for r in runs]  # checks the units first
    if ax is None:
        fig = Figure(figsize=(1.65 * COLUMN, 2.8))  # the legend to the right of the axes
        ax = fig.add_axes((0.095, 0.14, 0.55, 0.78))
    fig = ax.figure
    gammas = sorted({r.params.gamma for r in runs})
    single = len(gammas) == 1
    xmax = max(float(r.table["dV_over_V"].max()) for r in runs)
    xmax = min(max(xmax, 0.05) * 1.05, 0.999)
    ymax = max(float(r.table["E_over_kappa"].max()) * k for r, k in zip(runs, scales)) * 1.15
    if theory_curves:
        for g in gammas:
            params = next(r.params for r in runs if r.params.gamma == g)
            _theory(ax, params, xmax, None if single else f"C{gammas.index(g)}", single,
                    energy_unit(params, units)[0])
    for i, (run, scale) in enumerate(zip(runs, scales)):
        table = run.table
        color = f"C{gammas.index(run.params.gamma)}" if not single else f"C{i}"
        label = (f"$\\gamma$ = {run.params.gamma:g}, {_short(run)}" if not single else
                 f"simulation, {_short(run)}")
        ax.plot(table["dV_over_V"].to_numpy(float),
                table["E_over_kappa"].to_numpy(float) * scale, "o-", ms=2.5, lw=0.9,
                color=color, label=label, gid=f"simulation:{_name(run)}", zorder=4)
        for e in events(run, table):
            if e.name != "primary_buckling":
                continue
            y = float(table.loc[table["step"] == e.step, "E_over_kappa"].iloc[0]) * scale
            ax.plot([e.dV_over_V], [y], marker="v", ms=6, mec="black", zorder=6,
                    mfc=color if e.confirmed else "white", ls="none",
                    gid=f"primary:{_name(run)}",
                    label=(f"primary buckling, $\\Delta V/V$ = {e.dV_over_V:.3g}" if single
                           else None))
    handles, _ = ax.get_legend_handles_labels()
    if not single:
        handles += [Line2D([], [], color="0.3", **{k: v for k, v in _STYLE[key].items()
                                                     if k != "color"}, label=text)
                    for key, text in (("sphere", r"$U_\mathrm{sphere}$"),
                                      ("axisym", r"$U_\mathrm{axisym}$"),
                                      ("crossing", r"$U_\mathrm{sphere}=U_\mathrm{axisym}$"))]
        handles.append(Line2D([], [], marker="v", ms=6, mec="black", mfc="0.5", ls="none",
                              label="primary buckling"))
    ax.set_xlim(0.0, xmax)
    ax.set_ylim(0.0, ymax)
    ax.set_xlabel(r"relative volume loss $\Delta V/V$")
    ax.set_ylabel(energy_unit(runs[0].params, units)[1])
    ax.grid(True, alpha=0.25, lw=0.5)
    ax.tick_params(labelsize=7)
    # beside the axes, never over the data (the curves fill the upper left and right), each
    # label broken after its commas to the width left of the figure
    box = ax.get_position()
    room = fig.get_figwidth() * (1.0 - box.x1 - 0.02 * box.width) - 3.0 * 6 / 72 - 0.05
    labels = [_wrap(h.get_label(), max(room, 1.0), 6, min_fontsize=6)[0] for h in handles]
    ax.legend(handles=handles, labels=labels, loc="upper left", bbox_to_anchor=(1.02, 1.0),
              fontsize=6, frameon=False, handlelength=2.2, borderaxespad=0.0)
    if single:
        note = runs[0].params.convention_note.replace("gamma_eff", r"$\gamma_{eff}$")
        ax.set_title(f"$\\gamma$ = {gammas[0]:g}, $\\nu$ = {runs[0].params.nu:.3g}{note}",
                     fontsize=8)
    return fig


def _theory(ax, params, xmax: float, color, labelled: bool, scale: float = 1.0) -> None:
    """U_sphere (and its exact form when ``labelled``), U_axisym and their crossing, as E/kappa
    times ``scale``."""
    x = np.linspace(0.0, xmax, 400)
    unit = params.kappa / scale  # the energy drawn as 1

    def style(key):
        s = dict(_STYLE[key])
        if color is not None:
            s["color"] = color
        return s

    def label(text):
        return text if labelled else None

    ax.plot(x, theory.U_sphere(x, params) / unit, **style("sphere"),
            label=label(r"$U_\mathrm{sphere}$"), gid=f"U_sphere:{params.gamma:g}")
    if labelled:
        ax.plot(x, theory.U_sphere_exact(x, params) / unit, **style("sphere_exact"),
                label=r"$U_\mathrm{sphere}$, exact Green-Lagrange",
                gid=f"U_sphere_exact:{params.gamma:g}")
    ax.plot(x[1:], theory.U_axisym_of_dV(x[1:], params) / unit, **style("axisym"),
            label=label(r"$U_\mathrm{axisym}$"), gid=f"U_axisym:{params.gamma:g}")
    xc = theory.summary(params)["crossing_dV_over_V"]
    if xc is not None and xc < xmax:
        ax.axvline(xc, **style("crossing"), zorder=1, gid=f"crossing:{params.gamma:g}",
                   label=label(r"$U_\mathrm{sphere}=U_\mathrm{axisym}$ at "
                               rf"$\Delta V/V$ = {xc:.3g}"))


# ---------------------------------------------------------------------- Fig. 11

def fig11_paths(a, b, *, at: float | None = None, step_a: int | None = None,
                step_b: int | None = None, reference=None, tilt: float = 0.0) -> Figure:
    """Fig. 11: two conformations at the same gamma and dV/V reached by different paths.

    ``a`` and ``b`` are runs (they may be the same run, e.g. a re-inflation passing a volume
    twice, with ``step_a`` and ``step_b``). Steps: ``step_a``/``step_b`` if given, else the
    steps nearest to ``at``, else to the largest dV/V both runs reached. Under each: the path
    (run folder), class, W, E/kappa; below: the energy ratio of the higher to the lower energy
    and the paper's (gamma = 15163, dV/V = 0.645: 1.42, the W = 7 bowl from deflation over the
    conformation reached from a capsule at lower gamma). A difference in gamma or in dV/V
    larger than 1e-3 is stated in the title.
    """
    a, b = _open(a), _open(b)
    if at is None:
        at = min(float(a.table["dV_over_V"].max()), float(b.table["dV_over_V"].max()))
    ka = nearest_step(a, at) if step_a is None else int(step_a)
    kb = nearest_step(b, at) if step_b is None else int(step_b)
    confs = [conformation(a, ka), conformation(b, kb)]
    captions = [f"{tag}: {_how(run)}\n{c.label}\n"
                f"$E/\\kappa$ = {_fmt(c.E_over_kappa)}\n$\\Delta V/V$ = {c.dV_over_V:.3f}"
                for tag, c, run in zip("AB", confs, (a, b))]
    hi, lo = sorted(range(2), key=lambda i: -confs[i].E_over_kappa)
    ratio = confs[hi].E_over_kappa / confs[lo].E_over_kappa
    footer = [f"ours: $E_{'AB'[hi]}/E_{'AB'[lo]}$ = {ratio:.3f}"]
    paper = _paper(load_reference(reference, required=False), "soleil")
    paper_ratio = _soleil_ratio(paper)
    if paper_ratio is not None:
        footer += [f"paper ($\\gamma$ = {paper['gamma']:g}, $\\Delta V/V$ = "
                   f"{paper['DeltaV_over_V']:g}): ratio {paper_ratio:g},",
                   "   the W = 7 bowl over the path from a lower $\\gamma$"]
    title = f"$\\gamma$ = {confs[0].gamma:g}"
    if confs[0].gamma != confs[1].gamma:
        log.warning("fig11: the two conformations have different gamma (%g, %g)",
                    confs[0].gamma, confs[1].gamma)
        title = f"$\\gamma$ = {confs[0].gamma:g} vs {confs[1].gamma:g} (different!)"
    if abs(confs[0].dV_over_V - confs[1].dV_over_V) > 1e-3:
        log.warning("fig11: the two conformations have different dV/V (%.4f, %.4f)",
                    confs[0].dV_over_V, confs[1].dV_over_V)
        title += r", different $\Delta V/V$!"
    fig = _row_figure(confs, captions, COLUMN, title, footer, tilt)
    fig.energy_ratio = ratio
    return fig


def _how(run) -> str:
    """How a conformation was reached, in a few words (the run folder is in the data)."""
    control = run.protocol.control
    if control == "gamma":
        start = run.params_at(0).gamma
        return f"$\\gamma$ path from {start:g}, seed {run.protocol.seed}"
    if run.store.meta.get("parent"):
        return f"branch, seed {run.protocol.seed}"
    return f"deflation, seed {run.protocol.seed}"


def _soleil_ratio(paper: dict | None) -> float | None:
    """The paper's energy ratio of Fig. 11 (``energy_ratio`` or read from ``statement``:
    "... has 1.42 times lower energy ...")."""
    if not paper:
        return None
    if "energy_ratio" in paper:
        return float(paper["energy_ratio"])
    found = re.search(r"([0-9]+(?:\.[0-9]+)?) times lower energy", paper.get("statement", ""))
    return float(found.group(1)) if found else None


# ---------------------------------------------------------------------- per-run gallery

def run_gallery(run, *, every: int | None = None, steps=None, max_panels: int = 8,
                ncols: int = 4, tilt: float = 0.0, units: str = "reduced") -> Figure:
    """The conformations of one run (sphere -> capsule -> polygon -> wrinkled), one panel every
    ``every`` stored steps from the first, plus the last step (default ``every``: so that
    there are at most ``max_panels`` panels), or exactly ``steps``; all from the same view
    (along the dent axis) and scale, with dV/V, the class and W under each. ``units``:
    lengths and curvatures in R and 1/R, or (``"si"``, a run made from a material) m and
    1/m."""
    from ..analysis import ShapeAnalyzer

    run = _open(run)
    check_units(units, run.params)
    stored = list(run.steps)
    if not stored:
        raise ValueError(f"run {_name(run)} has no finished step")
    if steps is None:
        if every is None:
            every = max(1, math.ceil((len(stored) - 1) / max(max_panels - 1, 1)))
        if int(every) < 1:
            raise ValueError(f"every must be a positive number of steps, got {every}")
        steps = stored[::int(every)]
        if steps[-1] != stored[-1]:
            steps.append(stored[-1])
    analyzer = ShapeAnalyzer(run.faces, n_vertices=len(run.positions(stored[0])), contact=False)
    confs = [conformation(run, k, analyzer) for k in steps]
    n = len(confs)
    ncols = min(ncols, n)
    nrows = math.ceil(n / ncols)
    side = PAGE / ncols
    captions = [_wrap(f"step {c.step}, $\\Delta V/V$ = {c.dV_over_V:.3f}\n{c.label}",
                      side - 0.08, 7) for c in confs]
    caption_h = 0.06 + 0.12 * max(text.count("\n") + 1 for text, _ in captions)
    title_h, bar_h = 0.3, 0.55  # the colour bar, its ticks and its label below the panels
    height = title_h + nrows * (side + caption_h) + bar_h
    fig = Figure(figsize=(PAGE, height))
    radius = _radius(confs, units)
    axes = []
    for i, (c, (caption, size)) in enumerate(zip(confs, captions)):
        row, col = divmod(i, ncols)
        y0 = height - title_h - (row + 1) * side - row * caption_h
        ax = _panel(fig, (col * side / PAGE, y0 / height, side / PAGE, side / height), c,
                    radius, tilt, units)
        axes.append(ax)
        fig.text((col + 0.5) * side / PAGE, (y0 - 0.02) / height, caption, ha="center",
                 va="top", fontsize=size, linespacing=1.25)
    _colorbar(fig, axes[0], (0.35, 0.38 / height, 0.3, 0.05 / height), units=units)
    p = run.params
    fig.text(0.5, 1.0 - 0.5 * title_h / height,
             f"{_name(run)}: $\\gamma$ = {p.gamma:g}, $\\nu$ = {p.nu:.3g}, "
             f"{len(run.positions(stored[0]))} vertices", ha="center", va="center",
             fontsize=8.5)
    fig.panels = axes
    return fig


# ---------------------------------------------------------------------- output

def save(fig: Figure, out_stem, formats=("png", "pdf"), dpi: int = 300) -> list[Path]:
    """Write ``fig`` as ``out_stem.<format>`` for each format (``png`` at ``dpi``, ``pdf``,
    ``svg``); creates the folder. Returns the paths written."""
    formats = [formats] if isinstance(formats, str) else list(formats)
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise ValueError(f"figure formats must be among {FORMATS}, got {bad or formats}")
    out_stem = Path(out_stem)
    out_stem.parent.mkdir(parents=True, exist_ok=True)
    written = []
    for f in formats:
        path = out_stem.with_name(out_stem.name + "." + f)
        fig.savefig(path, dpi=dpi)
        written.append(path)
        log.info("figure written to %s", path)
    return written
