"""Figures across runs: the paper's Figs. 4, 5 and 10 from run folders, with the paper's values.

- :func:`plot_W_vs_dV` (paper Fig. 4): W of the wrinkled steps vs dV/V, one curve per run,
  coloured by gamma, with the averaging window [0.53, 0.76] shaded;
- :func:`plot_W_vs_gamma` (paper Fig. 5): W averaged over the wrinkled steps with dV/V in
  [0.53, 0.76], pooled over the runs at each gamma, error bar = standard deviation; the
  experiments' 4-8 wrinkles as a band;
- :func:`plot_thresholds` (paper Fig. 10): primary buckling, loss of axisymmetry and wrinkles
  vs gamma in log-log, our fits (:func:`shellbuckle.analysis.collect.threshold_fits`), the
  paper's laws ``2.8 gamma^-0.55`` and ``850/gamma``, the theory's ``U_sphere = U_axisym``
  crossing and the classical threshold ``6 (1 - nu)/sqrt(gamma)``;
- :func:`plot_across_runs` (paths, out_dir, formats) writes the three of them.

Each figure function takes a :func:`~shellbuckle.analysis.collect.collect_runs` DataFrame and
returns the matplotlib Figure (Agg backend); every data artist carries a ``gid`` naming what it
shows (``primary``, ``fit_primary``, ``paper_secondary``, ``W_mean``, ``W_run:<name>``...).
The paper's values come from its reference JSON (:func:`~shellbuckle.analysis.collect.
load_reference`); without it the figures show ours alone (logged).
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import pandas as pd

from .. import theory
from ..analysis import collect as collect_mod
from ..analysis.fits import W_WINDOW, critical_gamma
from ..params import ShellParameters
from .render import place_legend

log = logging.getLogger(__name__)

DPI = 200
STYLE = {"font.size": 10, "axes.labelsize": 11, "legend.fontsize": 8, "xtick.labelsize": 9,
         "ytick.labelsize": 9, "axes.titlesize": 10}
FIGSIZE = (6.4, 4.6)
_MARKERS = {"primary": ("s", "k", "primary buckling"),
            "axisymmetry_loss": ("^", "k", "loss of axisymmetry"),
            "wrinkles": ("v", "0.55", "wrinkles")}


#: gamma_effective / gamma of each energy convention, as printed in a formula
_GAMMA_FACTOR = {"helfrich": "", "paper": "4", "evolver-modulus": "2"}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _nu(df) -> float:
    """The most common nu of the runs (as stored, not rounded); 1/3 without runs."""
    nu = df["nu"].dropna()
    if not len(nu):
        return 1.0 / 3.0
    rounded = nu.round(6)
    return float(nu[rounded == rounded.value_counts().idxmax()].iloc[0])


#: The part of viridis the gammas are drawn in: without its light yellow-green end, whose
#: contrast with white is below 2 (WCAG contrast ratio; viridis(0.72) has 2.3).
VIRIDIS_END = 0.72


def _gamma_colour(plt, t: float):
    """Colour of a gamma mapped to ``t`` in [0, 1]: viridis up to :data:`VIRIDIS_END`."""
    return plt.get_cmap("viridis")(VIRIDIS_END * float(t))


def fit_label(name: str, fit) -> str:
    """A fit's legend: the law with its errors and its degrees of freedom
    (:meth:`~shellbuckle.analysis.fits.PowerLawFit.describe`), or, without them, that it has
    no error estimate."""
    return f"fit {name}: {fit.describe()}"


def gamma_c_label(fit) -> str:
    """The legend of our gamma_c (the secondary law at dV/V = 1) with its error and the
    degrees of freedom of the fit it comes from, or without an error when the fit has none."""
    gc = critical_gamma(fit)
    if not (fit.has_error and math.isfinite(gc.err)):
        return rf"our $\gamma_c$ = {gc.value:.0f} (no error estimate: {fit.dof} dof)"
    return rf"our $\gamma_c$ = {gc.value:.0f} ± {gc.err:.0f} ({fit.dof} dof)"


def _no_data(ax, text):
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", color="0.4")


def plot_thresholds(df, fits=None, *, reference=None, path=None):
    """Fig. 10: the thresholds of the deflation runs vs gamma (one marker per run), our fits,
    the paper's laws and the theory. ``fits`` defaults to
    :func:`~shellbuckle.analysis.collect.threshold_fits` of ``df``."""
    plt = _pyplot()
    ref = collect_mod.load_reference(reference, required=False)
    runs = collect_mod.deflation_runs(df)
    fits = collect_mod.threshold_fits(df) if fits is None else fits
    nu = _nu(runs if len(runs) else df)
    convention = collect_mod.convention_of(runs if len(runs) else df)
    with plt.rc_context(STYLE):
        fig, ax = plt.subplots(figsize=(9.6, 4.8), constrained_layout=True)
        gammas = runs["gamma"].to_numpy(float)
        lo, hi = (271.0, 29160.0) if ref is None else ref["protocol"]["gamma_range"]
        if len(gammas):
            lo, hi = min(lo, gammas.min()), max(hi, gammas.max())
        grid = np.geomspace(lo / 1.3, hi * 1.3, 60)
        for name, (marker, color, label) in _MARKERS.items():
            y = runs[f"{name}_dV_over_V"].to_numpy(float)
            ok = np.isfinite(y)
            if not ok.any():
                continue
            width = runs.get(f"{name}_resolution")
            width = (np.full(len(y), np.nan) if width is None
                     else pd.to_numeric(width, errors="coerce").to_numpy(float))
            located = np.isfinite(width) & (width < 0.5 * np.nanmedian(runs["dv"].to_numpy(float)))
            how = ("located" if located[ok].all() else "read at the steps" if not located[ok].any()
                   else "some located; bars: the interval each lies in")
            bars = ax.errorbar(gammas[ok], y[ok],
                               yerr=np.where(np.isfinite(width[ok]), width[ok] / 2, 0),
                               fmt=marker, ms=6, color=color, capsize=2, elinewidth=0.8,
                               mfc=color if name != "axisymmetry_loss" else "none",
                               label=f"{label} (ours, {how})")
            bars.lines[0].set_gid(name)  # the markers; the bars: the interval each lies in
            for cap in bars.lines[1]:
                cap.set_gid(f"{name}_interval")
        for key, style, label in (("primary", "-", "primary"), ("secondary", "-", "secondary")):
            if key in fits:
                ax.plot(grid, fits[key](grid), style, color="C0" if key == "primary" else "C3",
                        lw=1.4, label=fit_label(label, fits[key]), gid=f"fit_{key}")
        if ref is not None:
            p, s = ref["results"]["primary_buckling_fit"], ref["results"]["secondary_buckling_fit"]
            paper = np.geomspace(*ref["protocol"]["gamma_range"], 60)
            ax.plot(paper, p["a"] * paper ** p["b"], "--", color="C0", lw=1.0,
                    label=rf"paper: $\Delta V/V = {p['a']:g}\,\gamma^{{{p['b']:g}}}$",
                    gid="paper_primary")
            sec = paper[s["a"] / paper <= 1.0]
            ax.plot(sec, s["a"] / sec, "--", color="C3", lw=1.0,
                    label=rf"paper: $\Delta V/V = {s['a']:g}/\gamma$, $\gamma_c$ = "
                          f"{s['gamma_c']:g}", gid="paper_secondary")
            ax.plot([s["gamma_c"]], [1.0], "*", ms=11, color="C3", mfc="none",
                    gid="paper_gamma_c")
        if "secondary" in fits:
            ax.plot([critical_gamma(fits["secondary"]).value], [1.0], "*", ms=11, color="C3",
                    gid="gamma_c", label=gamma_c_label(fits["secondary"]))
        crossing = []
        for g in grid:
            try:
                crossing.append(theory.crossing(ShellParameters.from_gamma(
                    g, nu=nu, energy_convention=convention)))
            except ValueError:
                crossing.append(math.nan)
        ax.plot(grid, crossing, ":", color="0.3", lw=1.2,
                label=r"theory: $U_{sphere} = U_{axisym}$", gid="theory_crossing")
        classical = [theory.classical_threshold(ShellParameters.from_gamma(
            g, nu=nu, energy_convention=convention)).dV_over_V for g in grid]
        ax.plot(grid, classical, "-.", color="0.6", lw=1.0,
                label=r"classical: $6(1-\nu)/\sqrt{%s\gamma}$" % _GAMMA_FACTOR[convention],
                gid="classical")
        ax.axhline(1.0, color="0.6", lw=0.8, gid="whole_volume")
        values = runs[[f"{n}_dV_over_V" for n in _MARKERS]].to_numpy(float)
        bottom = min(0.01, np.nanmin(values) / 1.5) if np.isfinite(values).any() else 0.01
        ax.set(xscale="log", yscale="log",
               xlabel=r"Föppl–von Kármán number $\gamma = AR^2/\kappa$", ylabel=r"threshold $\Delta V/V$", ylim=(bottom, 1.5))
        reading = "" if convention == "helfrich" else f", energy convention {convention}"
        ax.set_title(rf"Buckling thresholds vs $\gamma$ ($\nu$ = {nu:.3g}{reading}; "
                     "paper Fig. 10)")
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False, ncol=1)
    if path is not None:
        fig.savefig(path, dpi=DPI)
    return fig


def plot_W_vs_gamma(df, *, reference=None, path=None):
    """Fig. 5: W averaged over dV/V in [0.53, 0.76] vs gamma (pooled over the runs at each
    gamma, :func:`~shellbuckle.analysis.collect.wrinkles_by_gamma`; error bar = standard
    deviation), each run's average as a small dot, and the paper's experimental W range."""
    plt = _pyplot()
    ref = collect_mod.load_reference(reference, required=False)
    pooled = collect_mod.wrinkles_by_gamma(df)
    runs = collect_mod.deflation_runs(df)
    runs = runs[runs["W_steps"].fillna(0).astype(int).to_numpy() > 0]
    window = W_WINDOW if ref is None else tuple(ref["results"]["wrinkle_average_window"])
    with plt.rc_context(STYLE):
        fig, ax = plt.subplots(figsize=FIGSIZE, constrained_layout=True)
        if ref is not None:
            lo, hi = ref["results"]["experiments"]["wrinkles_observed"]
            ax.axhspan(lo, hi, color="C2", alpha=0.12, lw=0, gid="paper_experiments",
                       label=f"experiments (paper): W = {lo}–{hi}")
        if len(runs):
            ax.plot(runs["gamma"].to_numpy(float), runs["W_mean"].to_numpy(float), ".",
                    color="0.6", ms=5, label="one run", gid="W_runs")
        if len(pooled):
            container = ax.errorbar(pooled["gamma"].to_numpy(float),
                                    pooled["W_mean"].to_numpy(float),
                                    yerr=pooled["W_std"].to_numpy(float), fmt="o", color="k",
                                    capsize=3, ms=6, label="ours (mean ± std)")
            container.lines[0].set_gid("W_mean")
        else:
            every = collect_mod.deflation_runs(df)
            stops = every["stop_dV_over_V"].to_numpy(float) if len(every) else np.array([])
            why = (f": the runs end at ΔV/V ≤ {np.nanmax(stops):.3g}"
                   if len(stops) and np.nanmax(stops) < window[0] else "")
            _no_data(ax, f"no wrinkled step with ΔV/V in [{window[0]}, {window[1]}]{why}")
            if len(every):
                g = every["gamma"].to_numpy(float)
                ax.set_xlim(g.min() / 1.5, g.max() * 1.5)
        ax.set(xscale="log", xlabel=r"$\gamma = AR^2/\kappa$",
               ylabel=rf"$\langle W \rangle$, $\Delta V/V \in [{window[0]}, {window[1]}]$")
        ax.set_ylim(bottom=0)
        ax.set_title("Number of wrinkles vs γ (paper Fig. 5)")
        place_legend(ax, frameon=False)
    if path is not None:
        fig.savefig(path, dpi=DPI)
    return fig


def plot_W_vs_dV(df, tables=None, *, reference=None, path=None):
    """Fig. 4: W of the wrinkled steps vs dV/V, one curve per deflation run (``tables``:
    ``{path: analysed table}`` from :func:`~shellbuckle.analysis.collect.collect_runs`; read
    from the run folders when None), coloured by gamma; the W window shaded."""
    plt = _pyplot()
    from matplotlib.colors import LogNorm

    ref = collect_mod.load_reference(reference, required=False)
    runs = collect_mod.deflation_runs(df)
    window = W_WINDOW if ref is None else tuple(ref["results"]["wrinkle_average_window"])
    with plt.rc_context(STYLE):
        fig, ax = plt.subplots(figsize=FIGSIZE, constrained_layout=True)
        ax.axvspan(*window, color="0.85", lw=0, gid="W_window",
                   label=f"W window [{window[0]}, {window[1]}] (paper)")
        gammas = runs["gamma"].to_numpy(float)
        norm = LogNorm(gammas.min(), max(gammas.max(), gammas.min() * 1.001)) \
            if len(gammas) else None
        drawn = 0
        for _, row in runs.sort_values(["gamma", "seed"]).iterrows():
            table = None if tables is None else tables.get(row["path"])
            if table is None:
                from ..run import Run

                table, _ = collect_mod.analysed_table(Run.open(row["path"]))
            wrinkled = table[table["shape"].astype(str) == "wrinkled"]
            if wrinkled.empty:
                continue
            seed = "" if pd.isna(row["seed"]) else f", seed {row['seed']}"
            ax.plot(wrinkled["dV_over_V"].to_numpy(float), wrinkled["W"].to_numpy(float), "o-",
                    ms=4, lw=1.0, color=_gamma_colour(plt, norm(row["gamma"])),
                    label=rf"$\gamma$ = {row['gamma']:g}{seed}", gid=f"W_run:{row['name']}")
            drawn += 1
        if drawn == 0:
            _no_data(ax, "no wrinkled step in these runs")
        ax.set(xlabel=r"$\Delta V/V$", ylabel="number of wrinkles $W$", xlim=(0, 1))
        ax.set_ylim(0, ax.get_ylim()[1] + 1.0)
        ax.set_title("Wrinkles along the deflation (paper Fig. 4)")
        place_legend(ax, frameon=False, fontsize=7, ncol=2 if drawn > 8 else 1)
    if path is not None:
        fig.savefig(path, dpi=DPI)
    return fig


#: File stems of the figures written by :func:`plot_across_runs`.
FIGURES = ("fig04_W_vs_dV", "fig05_W_vs_gamma", "fig10_thresholds")


def across_figures(df, tables=None, *, reference=None, fits=None) -> dict:
    """The three figures of a collected DataFrame: ``{stem: Figure}`` (:data:`FIGURES`)."""
    ref = collect_mod.load_reference(reference, required=False)
    if fits is None:
        fits = collect_mod.threshold_fits(df)
    n_gamma = collect_mod.deflation_runs(df)["gamma"].round(6).nunique()
    if n_gamma < 2:
        log.info("power laws with a free exponent need deflation runs at 2 or more gamma "
                 "values; got %d: those fits are not drawn", n_gamma)
    return {"fig04_W_vs_dV": plot_W_vs_dV(df, tables, reference=ref),
            "fig05_W_vs_gamma": plot_W_vs_gamma(df, reference=ref),
            "fig10_thresholds": plot_thresholds(df, fits, reference=ref)}


def save_figures(figures: dict, out_dir, formats=("png", "pdf")) -> list[Path]:
    """Save ``{stem: Figure}`` as ``out_dir/<stem>.<format>`` (PNG at 200 dpi), close them."""
    plt = _pyplot()
    formats = tuple(formats)
    bad = [f for f in formats if f not in ("png", "pdf", "svg")]
    if bad or not formats:
        raise ValueError(f"formats must be among png, pdf, svg; got {list(formats)!r}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for stem, fig in figures.items():
        for fmt in formats:
            target = out_dir / f"{stem}.{fmt}"
            fig.savefig(target, dpi=DPI)
            written.append(target)
        plt.close(fig)
    return written


def plot_across_runs(paths, out_dir, formats=("png", "pdf"), *, reference=None) -> list[Path]:
    """Collect the runs in ``paths`` (run or sweep folders,
    :func:`~shellbuckle.analysis.collect.collect_runs`; nothing is recomputed or written in
    them) and write the paper's Figs. 4, 5 and 10 in ``out_dir`` in each of ``formats``.
    Works with one run (the fits that need two gammas are skipped, as the log says).
    Returns the written files."""
    tables: dict = {}
    df = collect_mod.collect_runs(paths, tables=tables)
    log.info("collected %d runs at %d gamma values", len(df), df["gamma"].round(6).nunique())
    return save_figures(across_figures(df, tables, reference=reference), out_dir, formats)
