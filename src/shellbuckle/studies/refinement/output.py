"""The study's report files: ``refinement.md`` (:func:`markdown`), ``refinement.png``
(:func:`figure`) and ``refinement.csv`` (:func:`write_report`)."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .runs import BRANCH_END, IMPERFECT_BRANCH_END, PAPER_VERTICES, mean_edge
from .table import GROUP, OWN_SEEDS

if TYPE_CHECKING:  # pandas is imported where a table is made: not to build the command line
    import pandas as pd

CSV, MARKDOWN, FIGURE = "refinement.csv", "refinement.md", "refinement.png"


def _cell(mean: float, std: float, n: int) -> str:
    if not math.isfinite(mean):
        return "–"
    text = f"{mean:.4g}"
    if math.isfinite(std):
        text += f" ± {std:.2g}"
    return text + (f" ({n} seeds)" if n > 1 else "")


def _error(row) -> str:
    error, relative = row["paper_mesh_error"], row["paper_mesh_relative_error"]
    if not math.isfinite(error):
        return "–"
    return f"{error:+.3g}" + (f" ({100 * relative:+.2g} %)" if math.isfinite(relative) else "")


def markdown(table: pd.DataFrame, *, n_runs: int | None = None) -> str:
    """The table as a physicist reads it: per convention and gamma, one line per quantity with
    its value on every mesh (the paper's first), the value extrapolated to h -> 0, how, and
    the paper's mesh's error relative to it."""
    lines = ["# Mesh refinement", "",
             ("Mean over seeds ± sample standard deviation; h is the mean edge "
             "sqrt(8 pi/(sqrt(3)(N - 2))) R. Extrapolated: Richardson in h, from the meshes "
             "with a value (the order fitted from the three finest when they are monotone, "
             "else not converged; with two meshes the order 2 assumed; the finest value where "
             "the two finest are equal within a located threshold's bracket; none where a "
             "mesh between two with a value has none, for a threshold a run has not located, "
             "and for W, a count). Error of the paper's mesh: "
             f"q(N = {PAPER_VERTICES}) - q(h -> 0), and relative to |q(h -> 0)|. E/kappa and "
             "the rim harmonic (the largest harmonic m >= 2 of the dent's rim over the rim's "
             "radius: 0 for an axisymmetric dent) are interpolated linearly in dV/V between "
             "the two stored steps around the given dV/V."), ""]
    if n_runs is not None:
        lines += [f"Finished runs: {n_runs}.", ""]
    if table.empty:
        return "\n".join(lines + ["No finished run yet.", ""])
    for key, group in table.groupby(GROUP, sort=True):
        convention, gamma, nu, imperfection = key
        sizes = sorted(group["n_vertices"].unique())
        finest = sizes[-1]
        heads = [f"N = {n} (h = {mean_edge(n):.3g} R)" + (", paper" if n == PAPER_VERTICES
                                                             else ", finest" if n == finest
                                                             else "") for n in sizes]
        seeds = {n: sorted(set().union(*map(_seed_list, group.loc[group["n_vertices"] == n,
                                                                   "seeds"])), key=int)
                 for n in sizes}
        mixed = len({tuple(v) for v in seeds.values()}) > 1
        lines += [f"## {convention}, gamma = {gamma:g}, nu = {nu:.3g}, {imperfection}", "",
                  f"Classical threshold of the perfect sphere (thin-shell theory, to compare "
                  f"with the {'imperfect shell' if imperfection.startswith('shape') else 'sphere'}"
                  f" branch's end): dV/V = {_classical(convention, gamma, nu):.4g}.", "",
                  "| quantity | " + " | ".join(heads) + " | h -> 0 | extrapolation | "
                  "error of the paper's mesh |",
                  "|---" * (len(sizes) + 4) + "|"]
        for quantity, rows in group.groupby("quantity", sort=False):
            rows = rows.set_index("n_vertices")
            first = rows.iloc[0]
            cells = [_cell(rows.loc[n, "mean"], rows.loc[n, "std"], rows.loc[n, "n_seeds"])
                     for n in sizes]
            value = first["extrapolated"]
            label = first["label"]
            if quantity in BRANCH_END and imperfection.startswith("shape"):
                label = IMPERFECT_BRANCH_END
            method = first["method"]
            used = first["extrapolation_seeds"]
            if math.isfinite(value) and (used == OWN_SEEDS or set(_seed_list(used))
                                         != set().union(*map(_seed_list, rows["seeds"]))):
                method += ", " + _seeds_used(used)
            lines.append(f"| {label} | " + " | ".join(cells) + " | "
                         + (f"{value:.4g}" if math.isfinite(value) else "–") + " | "
                         + f"{method} | {_error(first)} |")
        lines.append("")
        if mixed:
            lines += ["Seeds differ between the meshes (" + "; ".join(
                f"N = {n}: {_seeds_used(' '.join(k))}" for n, k in seeds.items()) + "): each "
                "column is the mean over its own seeds; h -> 0 and the error of the paper's "
                "mesh compare the seeds named beside the extrapolation (those with the quantity "
                "on every mesh; where none has it, each mesh's own).", ""]
        born = _born_polygonal(group, sizes)
        if born:
            lines += [f"On N = {', '.join(map(str, born))} the loss of axisymmetry is the "
                      "primary buckling itself: the dent is not axisymmetric from its birth "
                      "(an imperfection with non-axisymmetric modes at the dent's scale shapes "
                      "its rim).", ""]
    return "\n".join(lines)


def _seed_list(seeds) -> list[str]:
    """The seeds of a ``seeds`` or ``extrapolation_seeds`` cell: space-separated (a number, or
    NaN for none, where a table was read back from its CSV file)."""
    if isinstance(seeds, str):
        return [] if seeds == OWN_SEEDS else seeds.split()
    if isinstance(seeds, (int, float, np.integer, np.floating)) and math.isfinite(seeds):
        return [str(int(seeds))]
    return []


def _seeds_used(seeds) -> str:
    """How the markdown names a row's ``extrapolation_seeds``."""
    names = _seed_list(seeds)
    if not names:
        return "each mesh's own seeds (none is on every mesh)"
    return ("seed " if len(names) == 1 else "seeds ") + ", ".join(names)


def _born_polygonal(group: pd.DataFrame, sizes) -> list[int]:
    """The mesh sizes of a group whose loss of axisymmetry equals its primary buckling (every
    seed's mean)."""
    by = {q: rows.set_index("n_vertices")["mean"] for q, rows in group.groupby("quantity")}
    primary, loss = by.get("primary_dV_over_V"), by.get("axisymmetry_loss_dV_over_V")
    if primary is None or loss is None:
        return []
    return [int(n) for n in sizes if math.isfinite(primary.get(n, math.nan))
            and primary.get(n) == loss.get(n)]


def _classical(convention: str, gamma: float, nu: float) -> float:
    """dV/V of the classical threshold (:func:`shellbuckle.theory.classical_threshold`)."""
    from ... import theory
    from ...params import ShellParameters

    params = ShellParameters.from_gamma(float(gamma), nu=float(nu),
                                        energy_convention=convention)
    return float(theory.classical_threshold(params).dV_over_V_exact)


#: Characters of a panel's title on one line (a 3.2-inch panel at 9 points).
TITLE_WIDTH = 40


def figure(table: pd.DataFrame):
    """Each quantity against h (seed means with their spread) per convention and gamma, with
    its extrapolation: the curve q0 + c h^p over the meshes it used and q0 at h = 0 (where
    it compared fewer seeds than a mesh has, their means as open circles)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    names = list(dict.fromkeys(table["quantity"])) or ["primary_dV_over_V"]
    ncols = min(4, len(names))
    nrows = math.ceil(len(names) / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.2 * ncols, 2.8 * nrows + 0.6),
                             squeeze=False, layout="constrained")
    groups = list(table.groupby(GROUP, sort=True)) if not table.empty else []
    # viridis up to 0.7: its lightest colour still contrasts with white (WCAG ratio 2.35)
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.7, max(len(groups), 1)))
    for ax, name in zip(axes.flat, names):
        for colour, (key, group) in zip(colours, groups):
            rows = group[group["quantity"] == name].sort_values("h")
            if rows.empty:
                continue
            label = f"{key[0]}, gamma = {key[1]:g}" + (
                f", nu = {key[2]:g}" if table["nu"].nunique() > 1 else "") + (
                f", {key[3]}" if table["imperfection"].nunique() > 1 else "")
            ax.errorbar(rows["h"], rows["mean"], yerr=rows["std"].fillna(0.0), marker="o",
                        ms=4, lw=1, color=colour, label=label, capsize=2)
            first = rows.iloc[0]
            if not rows["compared_mean"].equals(rows["mean"]):  # the means it compared
                ax.plot(rows["h"], rows["compared_mean"], ls="none", marker="o", ms=6,
                        mfc="none", color=colour)
            if math.isfinite(first["extrapolated"]):
                order = first["order"] if math.isfinite(first["order"]) else 0.0
                used = rows.dropna(subset=["compared_mean"])["h"].to_numpy()[:3]
                h = np.linspace(0.0, used.max(), 50)
                c = _c(rows, first["extrapolated"], order)
                ax.plot(h, first["extrapolated"] + c * h ** order, ls="--", lw=0.8,
                        color=colour)
                ax.plot([0.0], [first["extrapolated"]], marker="*", ms=8, color=colour)
            if name in BRANCH_END:  # beside it: the thin-shell classical threshold
                ax.plot([0.0], [_classical(*key[:3])], marker="D", ms=5, mfc="none",
                        color=colour)
        if not np.isfinite(table.loc[table["quantity"] == name, "mean"]
                           .to_numpy(dtype=float)).any():
            ax.text(0.5, 0.5, "no value on any mesh", ha="center", va="center",
                    transform=ax.transAxes, fontsize=8, color="0.3")
            ax.set_yticks([])
        ax.set_xlim(0.0, 1.05 * float(table["h"].max()) if not table.empty else 1.0)
        ax.set_xlabel("mean edge h / R")
        title = (str(table.loc[table["quantity"] == name, "label"].iloc[0])
                 if name in set(table["quantity"]) else name)
        ax.set_title(textwrap.fill(title, TITLE_WIDTH), fontsize=9)
        ax.axvline(float(mean_edge(PAPER_VERTICES)), color="0.5", lw=0.6, ls=":")
    for ax in list(axes.flat)[len(names):]:
        ax.set_visible(False)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=min(3, len(labels)),
                   fontsize=8)
    fig.suptitle(textwrap.fill(
        "Mesh refinement: values against the mean edge h (dotted: the paper's mesh; star: "
        "h -> 0; open circles: the means over the seeds it compares; open diamond: the "
        "classical threshold)", int(TITLE_WIDTH * 1.15 * ncols)), fontsize=9)
    return fig


def _c(rows: pd.DataFrame, value: float, order: float) -> float:
    """The coefficient c of q0 + c h^p through the finest mesh of ``rows`` (its mean over the
    seeds the extrapolation compared)."""
    finest = rows.dropna(subset=["compared_mean"]).iloc[0]
    return 0.0 if order == 0.0 else (finest["compared_mean"] - value) / finest["h"] ** order


def write_report(table: pd.DataFrame, out, *, n_runs: int | None = None) -> list[Path]:
    """Write ``refinement.csv``, ``refinement.md`` and ``refinement.png`` in ``out``."""
    import matplotlib.pyplot as plt

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / CSV, out / MARKDOWN, out / FIGURE]
    table.to_csv(paths[0], index=False, lineterminator="\n")
    paths[1].write_text(markdown(table, n_runs=n_runs), encoding="utf-8")
    fig = figure(table)
    fig.savefig(paths[2], dpi=150)
    plt.close(fig)
    return paths
