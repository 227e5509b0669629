"""Figures of one run: energy and pressure along the path with the theory, and 3D views.

All figures use matplotlib's Agg backend (no display needed) and are saved as PNG, or PDF when
the path ends in ``.pdf``.

Units (``units=``): ``"reduced"`` (default) draws energies as E/kappa, pressures as p/p_c
(the classical buckling pressure ``p_c = 4 sqrt(f kappa A)/R^2``, the unit of every figure
that shows a pressure, :func:`pressure_unit`), lengths in R and curvatures in 1/R; ``"si"``,
for a run made from a material (:meth:`~shellbuckle.params.ShellParameters.from_material`,
E in Pa, d and R in m), draws energies in J, pressures in Pa, lengths in m and curvatures in
1/m (:func:`shellbuckle.params.unit_scale`: kappa, kappa/R^3, R).
"""

from __future__ import annotations

import numpy as np

from .. import theory
from ..params import UNIT_SYSTEMS, unit_scale
from .render import DEFAULT_VIEW, place_legend, render

#: The run figure's 3D panel: the camera's angle from the dent axis, degrees
#: (:func:`shellbuckle.plots.render.render`'s ``tilt``; negative: below the axis, so the
#: opening of the bowl is in the upper half of the picture, a three-quarter view into it).
VIEW_TILT = -55.0


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def check_units(units: str, params) -> str:
    """``units`` if the figures of a run with ``params`` can be drawn in it: one of
    :data:`~shellbuckle.params.UNIT_SYSTEMS`, and ``"si"`` only for a shell made from a
    material. ``ValueError`` naming the reason otherwise."""
    if units not in UNIT_SYSTEMS:
        raise ValueError(f"units must be one of {', '.join(UNIT_SYSTEMS)}, got {units!r}")
    if units == "si" and not params.is_material:
        raise ValueError("units 'si' need a run made from a material (E, sigma, d, R); this "
                         f"shell is given by gamma = {params.gamma:g} alone, in units of "
                         "kappa and R")
    return units


def energy_unit(params, units: str = "reduced") -> tuple[float, str]:
    """``(scale, axis label)`` of the energies drawn: E/kappa times ``scale`` (1, or kappa in
    J for ``"si"``)."""
    if check_units(units, params) == "si":
        return unit_scale(params, "energy"), r"elastic energy $E$ (J)"
    return 1.0, r"elastic energy $E/\kappa$"


def pressure_unit(params, units: str = "reduced") -> tuple[float, str]:
    """``(p_unit, axis label)``: the figures draw ``pressure / p_unit``, a pressure in the
    run's units (as stored). Reduced: ``p_unit`` is the classical buckling pressure
    ``p_c = 4 sqrt(f kappa A)/R^2`` (:func:`shellbuckle.theory.classical_pressure`), the one
    pressure unit of the run figure, the p-V figure and the progress bar; ``"si"``: 1 (the
    stored pressure of a material run is in Pa)."""
    if check_units(units, params) == "si":
        return 1.0, r"pressure $p$ (Pa)"
    return (theory.classical_pressure(params),
            rf"pressure $p/p_c$,  $p_c = 4\sqrt{{{_factor(params)}\kappa A}}/R^2$ "
            "(classical buckling)")


def _factor(params) -> str:
    """The bending factor f of ``p_c = 4 sqrt(f kappa A)/R^2`` as the formulas show it: its
    value, or nothing where it is 1 (the ``helfrich`` convention)."""
    return "" if params.bending_factor == 1 else f"{params.bending_factor:g}"


def p_c_label(params, units: str = "reduced") -> str:
    """The legend of the classical threshold's line: its formula and value, in the
    table's unit kappa/R^3 (reduced) or in Pa."""
    p_c = theory.classical_pressure(params)
    f = _factor(params)
    if check_units(units, params) == "si":
        return rf"classical $p_c=4\sqrt{{{f}\kappa A}}/R^2$ = {p_c:.3g} Pa"
    return (rf"classical $p_c=4\sqrt{{{f}\kappa A}}/R^2$ = "
            rf"{p_c / unit_scale(params, 'pressure'):.3g} $\kappa/R^3$")


def view_axis(X, faces):
    """The direction to look from at a conformation: out of its dent (the classifier's
    ``dent_axis``), or None without a dent. In a deep bowl the negative-curvature vertices lie
    past the centre, so their mean position would look at the back of the shell. Computed from
    the descriptors (the rim's axis, else the largest dent's), as the classifier does, without
    importing it: the classifier opens runs, and :meth:`shellbuckle.run.Run.plot` draws this."""
    from ..analysis.descriptors import ShapeAnalyzer

    X = np.asarray(X, dtype=np.float64)
    d = ShapeAnalyzer(faces, n_vertices=len(X)).describe(X)
    axis = d.rim.axis if d.rim is not None else (d.dents[0].axis if d.dents else None)
    return None if axis is None else np.asarray(axis, float)


def _energy_panel(ax, table, params, grid, xmax, units):
    """E (E/kappa, or J) of the table and of the theory's shrunk sphere and inverted cap."""
    scale, label = energy_unit(params, units)
    kappa = params.kappa
    ax.plot(grid, theory.U_sphere_exact(grid, params) / kappa * scale, "--", color="0.4",
            label=r"$U_{sphere}$ (exact, uniform shrink)", gid="U_sphere_exact")
    ax.plot(grid[1:], theory.U_axisym_of_dV(grid[1:], params) / kappa * scale, ":",
            color="C3", label=r"$U_{axisym}$ (inverted cap)", gid="U_axisym")
    E = np.asarray(table["E_over_kappa"], float) * scale
    x = np.asarray(table["dV_over_V"], float)
    ax.plot(x, E, "o-", ms=3, color="C0", label="simulation", gid="simulation")
    for column, style, color, text in (("E_bend", "-", "C2", "bending"),
                                       ("E_stretch", "-", "C1", "stretching")):
        if column in table:
            part = np.asarray(table[column], float) / kappa * scale
            ax.plot(x, part, style, lw=1.0, color=color, label=f"{text} part", gid=column)
    ax.set(xlabel=r"$\Delta V/V$", ylabel=label, xlim=(0, xmax),
           ylim=(0, 1.15 * max(float(np.nanmax(E)), scale)))


def _pressure_panel(ax, table, params, grid, xmax, units):
    """The pressure (p/p_c, or Pa) of the table, of the shrunk sphere and p_c."""
    p_unit, label = pressure_unit(params, units)
    p_c = theory.classical_pressure(params) / p_unit
    ax.plot(grid, theory.pressure_sphere_exact(grid, params) / p_unit, "--", color="0.4",
            label="uniformly shrunk sphere", gid="pressure_sphere")
    ax.axhline(p_c, color="C3", lw=0.8, label=p_c_label(params, units), gid="p_c")
    p = np.asarray(table["pressure"], float) / p_unit
    ax.plot(np.asarray(table["dV_over_V"], float), p, "o-", ms=3, color="C0",
            label="simulation", gid="simulation")
    ax.set(xlabel=r"$\Delta V/V$", ylabel=label, xlim=(0, xmax))
    ax.yaxis.label.set_size(8)
    ax.set_ylim(min(0.0, float(np.nanmin(p)) * 1.1), max(1.3 * p_c, 1.1 * float(np.nanmax(p))))


def _shape_panel(ax, X, faces, curvature, axis, units, params):
    """The conformation seen from out of its dent (``axis``; the default view without one),
    in R and 1/R (reduced) or m and 1/m, coloured by ``curvature`` when given."""
    length = unit_scale(params, "length") if units == "reduced" else 1.0
    X = np.asarray(X, float) / length
    rendering = render(ax, X, faces, color_by="none" if curvature is None else "mean_curvature",
                       values=None if curvature is None else np.asarray(curvature) * length,
                       view="dent" if axis is not None else DEFAULT_VIEW, axis=axis,
                       tilt=VIEW_TILT if axis is not None else 0.0)
    if rendering.mappable is not None:
        unit = "1/R" if units == "reduced" else "1/m"
        ax.figure.colorbar(rendering.mappable, ax=ax, shrink=0.6, pad=0.02,
                           label=rf"mean curvature $H$ ({unit})")
    ax.rendering = rendering
    return rendering


#: Colours of the shape classes in the run figure's strip.
SHAPE_COLORS = {"sphere": "0.82", "dimples": "C1", "capsule": "C0", "polygonal": "C2",
                "wrinkled": "C3", "other": "0.45"}
#: Markers and names of the located events marked in the run figure.
EVENT_MARKS = {"primary_buckling": ("v", "primary buckling"),
               "axisymmetry_loss": ("s", "loss of axisymmetry"),
               "wrinkles": ("D", "wrinkles")}


def _shape_strip(ax, table, xmax):
    """The class of every step (a band from the previous step's dV/V to its own, coloured by
    :data:`SHAPE_COLORS`) and W where it changes on wrinkled steps."""
    x = np.asarray(table["dV_over_V"], float)
    shapes = [str(v) for v in table["shape"]]
    W = np.asarray(table["W"], float) if "W" in table else np.zeros(len(x))
    seen = []
    for i in range(1, len(x)):
        color = SHAPE_COLORS.get(shapes[i], SHAPE_COLORS["other"])
        label = shapes[i] if shapes[i] not in seen else None
        if label:
            seen.append(label)
        ax.axvspan(x[i - 1], x[i], color=color, lw=0, label=label, gid=f"shape_{i}")
    last_x = -1.0
    for i in range(1, len(x)):
        new_count = W[i] != W[i - 1] or shapes[i - 1] != "wrinkled"
        if shapes[i] == "wrinkled" and W[i] > 0 and new_count and x[i] - last_x > 0.06 * xmax:
            ax.text(0.5 * (x[i - 1] + x[i]), 0.5, f"W={int(W[i])}", ha="center", va="center",
                    fontsize=7, color="white", gid=f"W_{i}")
            last_x = x[i]
    ax.set(xlim=(0, xmax), ylim=(0, 1), yticks=[])
    ax.set_ylabel("shape", rotation=0, ha="right", va="center", fontsize=8)
    if seen:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.55), ncol=len(seen), fontsize=7,
                  frameon=False, handlelength=1.2, columnspacing=1.0)


def _complete_events(located: dict):
    """``(name, marker, text, point)`` of every completely located event, in the order of
    :data:`EVENT_MARKS`."""
    for name, (marker, text) in EVENT_MARKS.items():
        point = located.get(name)
        if point and point.get("complete", True):
            yield name, marker, text, point


def mark_jumps(ax, located: dict, value, *, label=None, ms: float = 6) -> None:
    """Each located event (:mod:`shellbuckle.locate`) at its volume: the two ends of its
    bracket (the last state of the old branch and the first of the new one) at the heights
    ``value(side)`` (``side``: the point's ``"old"`` or ``"new"`` values), joined by a segment
    (the jump, if any); ``label(text, dV_over_V)`` gives the legend entry (None: none)."""
    for name, marker, text, point in _complete_events(located):
        x = float(point["dV_over_V"])
        ax.plot([x, x], [value(point["old"]), value(point["new"])], "-", color="0.2", lw=1.0,
                marker=marker, ms=ms, mfc="white", mec="0.1",
                label=None if label is None else label(text, x), gid=f"located_{name}",
                zorder=4)


def _mark_located(ax_e, ax_p, ax_strip, located: dict, params, units: str) -> None:
    """The located events in the energy and pressure panels (:func:`mark_jumps`), named in
    the pressure panel's legend, and a tick in the shape strip."""
    e_scale, _ = energy_unit(params, units)
    p_unit, _ = pressure_unit(params, units)
    mark_jumps(ax_e, located, lambda side: float(side["E_over_kappa"]) * e_scale)
    mark_jumps(ax_p, located, lambda side: float(side["pressure"]) / p_unit,
               label=lambda text, x: f"{text}, located at {x:.4f}")
    if ax_strip is not None:
        for name, marker, _, point in _complete_events(located):
            ax_strip.plot([float(point["dV_over_V"])], [0.9], marker=marker, ms=5, color="0.1",
                          mfc="white", gid=f"located_{name}_strip", zorder=4)


def plot_run(table, params, X, faces, curvature=None, *, path=None, title=None, axis=None,
             units: str = "reduced", located: dict | None = None):
    """Three panels: the elastic energy vs dV/V with its bending and stretching parts,
    U_sphere and U_axisym; the pressure vs dV/V with the shrunk-sphere pressure and the
    classical threshold p_c; the last conformation in 3D, coloured by ``curvature``
    (per-vertex mean curvature H, or None). Under the first two, when the table has the
    analysis column ``shape``, a strip of the class of every step with W (the fourth axes);
    ``located``: the located events (:func:`shellbuckle.locate.located`), marked by vertical
    lines in the energy and pressure panels and in the strip.

    ``table`` is a run's per-step DataFrame (columns ``step``, ``dV_over_V``,
    ``E_over_kappa``, ``pressure``, as stored); ``params`` a
    :class:`~shellbuckle.params.ShellParameters`; ``axis``: the direction the 3D view looks
    from (:func:`view_axis`; None: the default view). ``units``: ``"reduced"`` (E/kappa, p/p_c,
    1/R) or ``"si"`` (J, Pa, m, 1/m; a run made from a material) — module docstring. The
    legends are placed off the data (:func:`~shellbuckle.plots.render.place_legend`) once
    every panel is drawn. The 3D axis carries the ``Rendering`` (``fig.axes[2].rendering``).
    """
    check_units(units, params)
    plt = _pyplot()
    strip = "shape" in table and table["shape"].notna().all() and len(table) > 1
    fig = plt.figure(figsize=(13.5, 5.0 if strip else 4.2), constrained_layout=True)
    grid_spec = fig.add_gridspec(2, 3, height_ratios=(1.0, 0.09 if strip else 1e-6))
    ax_e = fig.add_subplot(grid_spec[0, 0])
    ax_p = fig.add_subplot(grid_spec[0, 1])
    ax_s = fig.add_subplot(grid_spec[:, 2], projection="3d")
    x = np.asarray(table["dV_over_V"], float)
    xmax = max(float(np.nanmax(x)) if len(x) else 0.0, 0.05) * 1.05
    grid = np.linspace(0.0, min(xmax, 0.999), 400)
    _energy_panel(ax_e, table, params, grid, xmax, units)
    _pressure_panel(ax_p, table, params, grid, xmax, units)
    _shape_panel(ax_s, X, faces, curvature, axis, units, params)
    if strip:
        ax_strip = fig.add_subplot(grid_spec[1, 0:2])
        _shape_strip(ax_strip, table, xmax)
    if located:
        _mark_located(ax_e, ax_p, ax_strip if strip else None, located, params, units)
    last = table.iloc[-1]
    size = f", $R$ = {params.R:.3g} m" if units == "si" else ""
    ax_s.set_title(rf"step {int(last['step'])}, $\Delta V/V$ = {float(last['dV_over_V']):.3f}"
                   + size, fontsize=9)
    fig.suptitle(title or rf"$\gamma$ = {params.gamma:g}, $\nu$ = {params.nu:.3g}"
                 + params.convention_note.replace("gamma_eff", r"$\gamma_{eff}$"), fontsize=11)
    for ax in (ax_e, ax_p):  # last: every curve and marker of the panel is drawn by now
        place_legend(ax, frameon=False, fontsize=8)
    if path is not None:
        fig.savefig(path, dpi=150)
        plt.close(fig)
    return fig


def plot_deflation(run, path=None, step: int = -1, *, units: str = "reduced"):
    """The run figure (:func:`plot_run`) of a stored :class:`~shellbuckle.run.Run`, with the
    conformation of ``step`` (default: the last) coloured by Jülicher's mean curvature, seen
    from out of its dent (:func:`view_axis`), in ``units`` (``"reduced"`` or ``"si"``; checked
    before any work), the strip of shapes (the stored analysis, or the steps classified
    without writing) and the located events stored with the run."""
    from ..analysis.classify import table_with_shapes
    from ..energies.bending import Bending
    from ..mesh.topology import Topology
    from ..store.located import read_located

    check_units(units, run.params)
    X = run.positions(step)
    faces = run.faces
    H = Bending.from_mesh(Topology.from_faces(faces, len(X))).mean_curvature(X)
    table = table_with_shapes(run, run.table)
    table = table[table["step"] <= run.step(step)]
    located = {name: p for name, p in read_located(run.path).items()
               if p.get("step", 1 << 30) <= run.step(step)}
    return plot_run(table, run.params, X, faces, H, path=path, axis=view_axis(X, faces),
                    units=units, located=located)
