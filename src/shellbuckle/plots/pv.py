"""The pressure-volume figure of a run and its branches: p/p_c against dV/V.

A run's branches are the runs started from one of its steps by ``shellbuckle continue`` or
``shellbuckle deflate --from`` (:func:`shellbuckle.run.continue_from`), whose ``run.json``
names the parent folder (``parent.path``); :func:`family` finds them, and their own branches,
among the folders beside the run. Each run is one line of markers in the order of its steps,
with arrows along it showing the direction of the path: deflation (dV/V growing) or
re-inflation (dV/V shrinking); a deflation and a re-inflation through the same volumes that
do not retrace each other show the hysteresis of the buckling. The pressure is in units of
the classical buckling pressure ``p_c = 4 sqrt(f kappa A)/R^2``
(:func:`shellbuckle.theory.classical_threshold`; ``f`` the energy convention's factor), as in
the run figure (:func:`shellbuckle.plots.run.pressure_unit`), or in Pa with ``units="si"``
for a run made from a material, with the uniformly shrunk sphere's pressure for reference.

This module works on :class:`~shellbuckle.run.Run` objects and opens the branches it finds
with the class of the run it is given, so the Run itself can draw the figure
(:meth:`shellbuckle.run.Run.pv`) without an import circle.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from .. import theory
from ..store.located import read_located
from .render import place_legend
from .run import check_units, mark_jumps, p_c_label, pressure_unit

__all__ = ["family", "plot_pv"]


log = logging.getLogger(__name__)


def _parent_path(run) -> Path | None:
    """The folder of ``run``'s parent (None for a run that is no branch); ValueError if its
    ``run.json`` names a parent without a path."""
    parent = run.store.parent
    if not parent:
        return None
    path = parent.get("path") if isinstance(parent, dict) else None
    if not isinstance(path, str):
        raise ValueError(f"{Path(run.path) / 'run.json'} names a parent without its path")
    return Path(path).resolve()


def family(run, search=None) -> list:
    """``run`` and its branches (and theirs), in the order found: the run folders in
    ``search`` (default: the folder holding ``run``) whose ``run.json`` names ``run`` or one of
    its branches as parent. Folders that are not runs are skipped, and run folders that cannot
    be read are skipped with a warning naming them (a damaged neighbour does not stop the
    figure of ``run``)."""
    opener = type(run)
    root = Path(run.path).resolve()
    search = root.parent if search is None else Path(search)
    candidates = []
    for folder in sorted(p for p in search.iterdir() if (p / "run.json").is_file()):
        if folder.resolve() == root:
            continue
        try:
            other = opener.open(folder)
            candidates.append((other, _parent_path(other)))
        except (ValueError, OSError) as exc:
            log.warning("%s is left out of the branches of %s: %s", folder, run.path, exc)
    members, known = [run], {root}
    grew = True
    while grew:
        grew = False
        for other, parent in candidates:
            path = Path(other.path).resolve()
            if path not in known and parent in known:
                members.append(other)
                known.add(path)
                grew = True
    return members


def _direction(x) -> str:
    change = float(x[-1] - x[0]) if len(x) > 1 else 0.0
    return "deflation" if change > 0 else "re-inflation" if change < 0 else "fixed volume"


def _arrows(ax, x, y, color, n_arrows: int = 6) -> None:
    """Arrowheads at the middle of about ``n_arrows`` segments, pointing along the path."""
    n = len(x) - 1
    if n < 1:
        return
    for i in sorted(set(np.linspace(0, n - 1, min(n, n_arrows)).round().astype(int))):
        if x[i] == x[i + 1] and y[i] == y[i + 1]:
            continue
        mid = (0.5 * (x[i] + x[i + 1]), 0.5 * (y[i] + y[i + 1]))
        ax.annotate("", xy=mid, xytext=(x[i], y[i]),
                    arrowprops=dict(arrowstyle="-|>", color=color, lw=1.0,
                                    mutation_scale=11, shrinkA=0, shrinkB=0))


def _curve_label(run, x, *, first: bool) -> str:
    """The legend entry of a run's curve: its folder, with its seed, or for a branch the step
    of its parent it starts from, and the direction of its path; the first also says what the
    arrowheads along the curves mean."""
    parent = run.store.parent
    name = Path(run.path).name
    if isinstance(parent, dict) and parent.get("step") is not None:
        of = f" of {Path(parent['path']).name}" if isinstance(parent.get("path"), str) else ""
        who = f"{name}, from step {parent['step']}{of}"
    else:
        who = f"{name}, seed {run.protocol.seed}"
    arrows = ", arrowheads along the path" if first else ""
    return f"{who}: {_direction(x)}{arrows}"


def plot_pv(runs, path=None, *, theory_curve: bool = True, units: str = "reduced"):
    """The figure: ``runs`` (a Run or a list of Runs; :func:`family` gives a run's family)
    as p/p_c against dV/V (``units="si"``: p in Pa, for runs made from a material), each with
    arrows in the direction of its path and labelled with its folder and seed, or for a branch
    the parent's step it starts from, and its direction, and
    its located events (both ends of each bracket, joined, with their volumes); the
    first run's parameters set ``p_c`` and the title. The legend is placed off the data
    (:func:`~shellbuckle.plots.render.place_legend`). Saved to ``path`` (PNG, or PDF by the
    suffix) when given; returns the :class:`~matplotlib.figure.Figure`."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    runs = [runs] if hasattr(runs, "table") else list(runs)
    if not runs:
        raise ValueError("plot_pv needs at least one run")
    for run in runs:
        check_units(units, run.params)
    params = runs[0].params
    p_unit, label = pressure_unit(params, units)
    fig = Figure(figsize=(5.0, 3.8), constrained_layout=True)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    xmax, ymin, ymax = 0.05, 0.0, 0.0
    for i, run in enumerate(runs):
        table = run.table
        x = np.asarray(table["dV_over_V"], float)
        y = np.asarray(table["pressure"], float) / p_unit
        if not len(x):
            continue
        color = f"C{i % 10}"
        ax.plot(x, y, "o-", ms=3, lw=1.0, color=color, gid=f"pv:{Path(run.path).name}",
                label=_curve_label(run, x, first=i == 0))
        _arrows(ax, x, y, color)
        mark_jumps(ax, read_located(run.path), lambda side: float(side["pressure"]) / p_unit,
                   label=(lambda text, x: f"{text}, located at {x:.4f}") if i == 0 else None,
                   ms=5)
        xmax = max(xmax, float(np.nanmax(x)))
        ymin, ymax = min(ymin, float(np.nanmin(y))), max(ymax, float(np.nanmax(y)))
    xmax *= 1.05
    p_c = theory.classical_pressure(params) / p_unit
    if theory_curve:
        grid = np.linspace(0.0, min(xmax, 0.999), 300)
        ax.plot(grid, theory.pressure_sphere_exact(grid, params) / p_unit, "--", color="0.5",
                lw=0.8, label="uniformly shrunk sphere", gid="pressure_sphere")
    ax.axhline(p_c, color="0.3", lw=0.6,
               ls=":", gid="p_c")  # p_c: defined by the axis label (reduced) or the title
    # the runs' pressures and p_c set the range; the shrunk sphere's curve leaves it upwards
    span = max(ymax, p_c) - min(ymin, 0.0)
    ax.set(xlabel=r"$\Delta V/V$", xlim=(0.0, xmax), ylabel=label,
           ylim=(min(ymin, 0.0) - 0.05 * span, max(ymax, p_c) + 0.25 * span))
    ax.yaxis.label.set_size(8)
    ax.set_title(rf"$\gamma$ = {params.gamma:g}, $\nu$ = {params.nu:.3g}"
                 + params.convention_note.replace("gamma_eff", r"$\gamma_{eff}$")
                 + ("" if units == "reduced" else "; dotted: " + p_c_label(params, units)),
                 fontsize=9)
    place_legend(ax, frameon=False, fontsize=7)
    if path is not None:
        fig.savefig(path, dpi=200)
    return fig
