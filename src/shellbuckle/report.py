"""The reproduction report: our numbers next to every number of the paper that the runs reach.

``write_report(paths, out, fmt="md")`` collects the runs (run or sweep folders,
:func:`shellbuckle.analysis.collect.collect_runs`; nothing is recomputed), fits the thresholds
(:func:`~shellbuckle.analysis.collect.threshold_fits`) and writes a Markdown or a single-file
HTML report with:

1. one row per entry of the paper's reference JSON (``reference/quilliet2008.json``, every
   key, flattened as ``results.primary_buckling_fit.a``): the paper's value, ours, the
   difference (absolute and relative) and a plain verdict, or why the runs cannot reach it;
2. the disagreements, stated one by one;
3. the two captions of the paper whose gamma and d/R contradict its own formula
   (:func:`shellbuckle.params.check_caption`);
4. our fits and the per-gamma thresholds and W;
5. the figures (:mod:`shellbuckle.plots.across`: linked PNG files beside a Markdown report,
   embedded as base64 in the HTML one);
6. the provenance of every run: parameters, protocol, seed, mesh, versions (``run.json``).

Numbers are printed with 4 significant digits (:func:`fmt_number`). A numerical agreement
means the difference is within twice our 1-sigma error when we have one, else within
:data:`REL_AGREEMENT`.
"""

from __future__ import annotations

import base64
import html
import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .analysis import collect as collect_mod
from .analysis.fits import W_WINDOW, critical_gamma
from .params import check_caption, d_over_R

log = logging.getLogger(__name__)

FORMATS = ("md", "html")
#: Without an error estimate, a relative difference below this counts as agreement.
REL_AGREEMENT = 0.05
#: Relative tolerance on gamma when looking for runs at one of the paper's gammas.
GAMMA_RTOL = 0.01
#: The paper's self-contact stop, "inner volumes of the order 7-11 % of V0" (§4.1).
PAPER_STOP = (0.89, 0.93)


def fmt_number(x) -> str:
    """A number as printed in the report: 4 significant digits; ``n/a`` for None/NaN."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    if isinstance(x, (bool, np.bool_)):
        return str(bool(x)).lower()
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    return f"{float(x):.4g}"


@dataclass
class Row:
    """One comparison: reference ``key``, ``paper`` and ``ours`` (as text), ``diff`` and
    ``rel`` (text, empty when not numeric), ``verdict`` and whether it is a ``disagreement``."""

    key: str
    paper: str
    ours: str
    diff: str = ""
    rel: str = ""
    verdict: str = ""
    disagreement: bool = False


def flatten(value, prefix: str = "") -> dict:
    """``{"a.b[0].c": leaf}`` for every leaf of a JSON value (lists of numbers stay leaves)."""
    out = {}
    if isinstance(value, dict):
        for k, v in value.items():
            out.update(flatten(v, f"{prefix}.{k}" if prefix else k))
    elif isinstance(value, list) and any(isinstance(v, (dict, list)) for v in value):
        for i, v in enumerate(value):
            out.update(flatten(v, f"{prefix}[{i}]"))
    else:
        out[prefix] = value
    return out


def _text(value) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(_text(v) for v in value) + "]"
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        return fmt_number(value)
    return str(value)


def compare(key, paper, ours, err=None, *, what: str = "", exact: bool = False) -> Row:
    """A numerical comparison row: ours - paper, relative to |paper|, and a verdict (agrees
    within 2 sigma of ``err``, or within :data:`REL_AGREEMENT`, or ``exact`` equality)."""
    if ours is None or (isinstance(ours, float) and not math.isfinite(ours)):
        return Row(key, _text(paper), "not reachable", verdict=f"not reachable: {what}")
    ours_f, paper_f = float(ours), float(paper)
    diff = ours_f - paper_f
    rel = diff / abs(paper_f) if paper_f != 0 else math.nan
    shown = fmt_number(ours) + (f" ± {fmt_number(err)}" if err is not None and math.isfinite(err)
                                and err > 0 else "")
    if exact:
        ok = diff == 0
        verdict = "same" if ok else f"different: ours {fmt_number(ours)}, paper {_text(paper)}"
    elif err is not None and math.isfinite(err) and err > 0:
        k = abs(diff) / err
        ok = k <= 2.0
        verdict = (f"agrees ({k:.1f} sigma)" if ok else
                   f"differs: ours is {abs(100 * rel):.0f} % {'higher' if diff > 0 else 'lower'}"
                   f" ({k:.1f} sigma)")
    else:
        ok = abs(rel) <= REL_AGREEMENT if math.isfinite(rel) else diff == 0
        verdict = (f"agrees (within {100 * REL_AGREEMENT:.0f} %, no error estimate)" if ok else
                   f"differs: ours is {abs(100 * rel):.0f} % "
                   f"{'higher' if diff > 0 else 'lower'} (no error estimate)")
    return Row(key, _text(paper), shown, fmt_number(diff),
               "" if not math.isfinite(rel) else f"{100 * rel:+.1f} %", verdict, not ok)


def info(key, paper, ours, verdict, disagreement: bool = False) -> Row:
    """A row for a statement or a non-numerical entry."""
    return Row(key, _text(paper), _text(ours), verdict=verdict, disagreement=disagreement)


def unreachable(key, paper, why: str) -> Row:
    return Row(key, _text(paper), "not reachable", verdict=f"not reachable with these runs: {why}")


# --------------------------------------------------------------------------- context

class Context:
    """Everything the comparisons need: the runs, their tables, the fits."""

    def __init__(self, df: pd.DataFrame, tables: dict, reference: dict, fits: dict):
        self.df, self.tables, self.ref, self.fits = df, tables, reference, fits
        self.deflation = collect_mod.deflation_runs(df)

    def at_gamma(self, gamma, frame=None) -> pd.DataFrame:
        frame = self.df if frame is None else frame
        g = frame["gamma"].to_numpy(float)
        return frame[np.isclose(g, float(gamma), rtol=GAMMA_RTOL)]

    def table(self, row) -> pd.DataFrame | None:
        table = self.tables.get(row["path"])
        if table is None and isinstance(row.get("path"), str) and Path(row["path"]).exists():
            from .run import Run

            table, _ = collect_mod.analysed_table(Run.open(row["path"]))
            self.tables[row["path"]] = table
        return table

    def step_near(self, row, dV_over_V: float):
        """The step of a run closest to ``dV_over_V`` if within one volume step, else None."""
        table = self.table(row)
        if table is None or table.empty:
            return None
        dv = table["dV_over_V"].to_numpy(float)
        i = int(np.argmin(np.abs(dv - dV_over_V)))
        step = row["dv"] if math.isfinite(row["dv"]) else np.median(np.abs(np.diff(dv)))
        return table.iloc[i] if abs(dv[i] - dV_over_V) <= max(step, 1e-9) else None


# --------------------------------------------------------------------------- comparisons

def _conventions(ctx, key, value):
    ours = {"gamma": "A R^2 / kappa (shellbuckle.params)",
            "nu": f"2D Poisson ratio; runs at nu = "
                  f"{', '.join(sorted({fmt_number(v) for v in ctx.df['nu'].dropna()}))}",
            "gamma_from_d_over_R": "gamma = 12 (1 - 2 nu^2/(1-nu)) (R/d)^2 "
                                   "(shellbuckle.params.gamma_from_d_over_R)",
            "spontaneous_curvature": "c = c1 + c2, c0 = 2/R on the stress-free sphere; energy "
                                     "convention(s) of the runs: " + _readings(ctx.df)}
    name = key.split(".")[-1]
    return info(key, value, ours.get(name, "same definitions"), "same convention")


def _readings(df) -> str:
    """The energy conventions of the runs with their bending energy and gamma factor."""
    from .params import bending_factor, convention_formula

    names = (df["energy_convention"].fillna("helfrich") if "energy_convention" in df
             else pd.Series(["helfrich"] * len(df)))
    out = []
    for name, n in names.value_counts().items():
        f = bending_factor(name)
        scale = "" if f == 1 else f", the standard shell at {1 / f:g} gamma"
        out.append(f"{name} ({convention_formula(name)}{scale}): {n} run(s)")
    return "; ".join(out) if out else "none"


def _set_of(values) -> list:
    """Sorted distinct values (numpy scalars as Python ones), missing values left out."""
    values = [v.item() if isinstance(v, np.generic) else v for v in values]
    return sorted({v for v in values if v is not None and v is not pd.NA
                   and not (isinstance(v, float) and math.isnan(v))}, key=str)


def _protocol(ctx, key, value):
    runs = ctx.deflation if len(ctx.deflation) else ctx.df
    name = key.split(".")[-1]
    if name == "volume_step_over_V0":
        steps = _set_of(runs["dv"].round(6))
        if not steps:
            return unreachable(key, value, "no run with a volume schedule")
        if len(steps) == 1:
            return compare(key, value, steps[0], what="volume step")
        return info(key, value, steps, "several volume steps among the runs")
    if name == "vertices":
        n = _set_of(int(v) for v in runs["n_vertices"].dropna())
        if len(n) == 1:
            return compare(key, value, n[0], exact=True)
        return info(key, value, n, "several mesh sizes among the runs")
    if name == "mesh":
        kinds = _set_of(runs["mesh"])
        same = kinds == ["random"]
        return info(key, value, kinds, "same kind (randomized)" if same else
                    "different: not only randomized meshes", not same)
    if name == "minimization":
        ours = (f"methods {_set_of(runs['method'])}, c0 cycle {_set_of(runs['c0_cycle'])}, "
                f"jiggle {_set_of(runs['jiggle'])}, temperature {_set_of(runs['temperature'])}")
        return info(key, value, ours, "protocol as run (see provenance)")
    if name == "gamma_range":
        g = runs["gamma"].dropna()
        if g.empty:
            return unreachable(key, value, "no run")
        covers = g.min() <= value[0] * (1 + GAMMA_RTOL) and g.max() >= value[1] * (1 - GAMMA_RTOL)
        return info(key, value, [float(g.min()), float(g.max())],
                    "covers the paper's range" if covers else
                    "narrower than the paper's range (numbers below cover only our range)")
    if name == "stop":
        stopped = ctx.df[ctx.df["stop_reason"] == "self-intersection"]
        if stopped.empty:
            return unreachable(key, value, "no run stopped at self-intersection")
        lo, hi = float(stopped["stop_dV_over_V"].min()), float(stopped["stop_dV_over_V"].max())
        inside = lo >= PAPER_STOP[0] - 0.02 and hi <= PAPER_STOP[1] + 0.02
        return info(key, value, f"self-intersection at dV/V = {fmt_number(lo)}-{fmt_number(hi)}"
                    f" ({len(stopped)} runs)", "agrees (within one volume step)" if inside else
                    f"differs: the paper stops at dV/V = {PAPER_STOP[0]}-{PAPER_STOP[1]}",
                    not inside)
    return info(key, value, "", "not compared")


def _caption(ctx, key, value, entry):
    name = key.rsplit(".", 1)[-1]
    formula = d_over_R(entry["gamma"], 1.0 / 3.0)
    consistent = check_caption(entry["gamma"], entry["d_over_R"])
    if name == "gamma":
        return info(key, value, "", "caption value (see the captions section)")
    if name == "d_over_R":
        row = compare(key, value, formula, what="")
        row.disagreement = False  # the paper against its own formula: see the captions section
        row.verdict = ("caption consistent with gamma = 8 (R/d)^2" if consistent else
                       f"caption inconsistent: gamma = {entry['gamma']} gives d/R = "
                       f"{formula:.4f}")
        return row
    if name == "consistent":
        return info(key, value, consistent, "same finding" if consistent == value else
                    "different finding", consistent != value)
    if name == "formula_gives":
        return compare(key, value, formula, what="")
    return info(key, value, "", "not compared")


def _compare_fit(key, value, fit, attr: str, why: str):
    """The row comparing the paper's ``value`` with ``fit.<attr>`` and its error."""
    if fit is None:
        return compare(key, value, None, None, what=why)
    return compare(key, value, getattr(fit, attr), getattr(fit, f"{attr}_err"), what=why)


def _fit_rows(ctx, key, value):
    name = key.split(".")[-1]
    group = key.split(".")[1]
    if name == "form":
        return info(key, value, value, "same form")
    if group == "primary_buckling_fit":
        fit = ctx.fits.get("primary")
        why = "the primary fit needs runs that buckled at 2 or more gamma values"
        if name == "a":
            return _compare_fit(key, value, fit, "prefactor", why)
        if name == "b":
            return _compare_fit(key, value, fit, "exponent", why)
        if name == "theory_exponent":
            row = _compare_fit(key, value, fit, "exponent", why)
            row.ours = "fitted exponent " + row.ours if fit is not None else row.ours
            return row
    fit = ctx.fits.get("secondary")
    why = "no run with a secondary threshold (loss of axisymmetry or wrinkles)"
    if name == "a":
        return _compare_fit(key, value, fit, "prefactor", why)
    if name == "gamma_c":
        gc = None if fit is None else critical_gamma(fit)
        return compare(key, value, None if gc is None else gc.value,
                       None if gc is None else gc.err, what=why)
    return info(key, value, "", "not compared")


def onset(ctx) -> tuple[float | None, float | None]:
    """(largest gamma whose deflation runs all stayed capsules until self-contact, smallest
    gamma with a wrinkles event)."""
    runs = ctx.deflation
    capsule = None
    for gamma, group in runs.groupby(runs["gamma"].round(6)):
        contact = (group["stop_reason"] == "self-intersection").all()
        none = group[["axisymmetry_loss_dV_over_V", "wrinkles_dV_over_V"]].isna().all().all()
        if contact and none and np.isfinite(group["primary_dV_over_V"]).all():
            capsule = float(gamma) if capsule is None else max(capsule, float(gamma))
    wr = runs[np.isfinite(runs["wrinkles_dV_over_V"].to_numpy(float))]
    return capsule, (float(wr["gamma"].min()) if len(wr) else None)


def _results(ctx, key, value):
    parts = key.split(".")
    top = parts[1].split("[")[0]
    name = parts[-1]
    if top in ("primary_buckling_fit", "secondary_buckling_fit"):
        return _fit_rows(ctx, key, value)
    if top == "secondary_buckling_onset":
        numbers = [float(x) for x in re.findall(r"gamma = (\d+(?:\.\d+)?)", str(value))]
        capsule, wrinkled = onset(ctx)
        ours = (f"capsule only up to gamma = {fmt_number(capsule)}; wrinkles from gamma = "
                f"{fmt_number(wrinkled)}")
        if capsule is None and wrinkled is None:
            return unreachable(key, value, "no run stayed a capsule until self-contact and none "
                               "wrinkled")
        verdicts, bad = [], False
        if capsule is not None and numbers:
            verdicts.append(f"capsule-only limit {fmt_number(capsule)} vs {fmt_number(numbers[0])}")
            bad |= wrinkled is not None and wrinkled <= capsule
        if wrinkled is not None and len(numbers) > 1:
            verdicts.append(f"wrinkles onset {fmt_number(wrinkled)} vs {fmt_number(numbers[1])}")
            bad |= wrinkled < numbers[0]
        return info(key, value, ours, "; ".join(verdicts) + (" (ours is bracketed only by the "
                    "gammas that were run)"), bad)
    if top == "energy_vs_volume_figure":
        return _energy(ctx, key, value, name)
    if top == "wrinkle_count_vs_gamma":
        pooled = collect_mod.wrinkles_by_gamma(ctx.df)
        if pooled.empty:
            return unreachable(key, value, "no wrinkled step with dV/V in the W window")
        text = ", ".join(f"{fmt_number(g)}: {fmt_number(m)} ± {fmt_number(s)}" for g, m, s in
                         pooled[["gamma", "W_mean", "W_std"]].itertuples(index=False))
        inc = bool(np.all(np.diff(pooled["W_mean"].to_numpy()) >= 0)) if len(pooled) > 1 else None
        verdict = ("W increases with gamma, as in the paper" if inc else
                   "W does not increase monotonically with gamma" if inc is False else
                   "one gamma only: the trend is not reachable")
        return info(key, value, f"<W> by gamma: {text}", verdict, inc is False)
    if top == "wrinkle_average_window":
        return info(key, value, list(W_WINDOW), "same window" if list(W_WINDOW) == list(value)
                    else "different window", list(W_WINDOW) != list(value))
    if top == "wrinkle_count_vs_volume":
        return _W_vs_volume(ctx, key, value)
    if top == "potato_vs_capsule":
        return _potato(ctx, key, value, name)
    if top == "gallery_at_DeltaV_over_V_0":
        return _gallery(ctx, key, value)
    if top in ("reinflation", "reinflation_low_W"):
        return _reinflation(ctx, key, value, top, name)
    if top == "soleil":
        return _soleil(ctx, key, value, name)
    if top == "experiments":
        return _experiments(ctx, key, value, name)
    return info(key, value, "", "not compared")


def _energy(ctx, key, value, name):
    from . import theory
    from .params import ShellParameters

    g0 = ctx.ref["results"]["energy_vs_volume_figure"]["gamma"]
    runs = ctx.at_gamma(g0, ctx.deflation)
    if name == "gamma":
        return info(key, value, f"{len(runs)} run(s) at this gamma", "")
    if name == "nu":
        return compare(key, value, float(runs["nu"].iloc[0]) if len(runs) else None,
                       what=f"no run at gamma = {g0}")
    if runs.empty:
        return unreachable(key, value, f"no deflation run at gamma = {g0}")
    before, after, late = [], [], []
    for _, row in runs.iterrows():
        table = ctx.table(row)
        p = ShellParameters.from_gamma(float(row["gamma"]), nu=float(row["nu"]))
        x = table["dV_over_V"].to_numpy(float)
        E = table["E_over_kappa"].to_numpy(float) * p.kappa
        shape = table["shape"].astype(str).to_numpy()
        pre = (shape == "sphere") & (x > 0)
        cap = shape == "capsule"
        before += list(E[pre] / theory.U_sphere(x[pre], p) - 1)
        after += list(E[cap] / theory.U_axisym_of_dV(x[cap], p) - 1)
        if math.isfinite(row["primary_dV_over_V"]):
            late.append(row["primary_dV_over_V"] > theory.crossing(p))
    ours = (f"median |E/U_sphere - 1| before buckling = {fmt_number(np.median(np.abs(before)))}"
            if before else "no spherical step") + "; " + \
           (f"median |E/U_axisym - 1| on capsule steps = {fmt_number(np.median(np.abs(after)))}"
            if after else "no capsule step") + "; " + \
           (f"buckling past the crossing in {sum(late)}/{len(late)} runs" if late else
            "no primary buckling")
    ok = bool(late) and all(late)
    return info(key, value, ours, "hysteresis as in the paper" if ok else
                "no hysteresis past the crossing in every run", not ok)


def _W_vs_volume(ctx, key, value):
    slopes = []
    for _, row in ctx.deflation.iterrows():
        table = ctx.table(row)
        if table is None or "shape" not in table:
            continue
        w = table[table["shape"].astype(str) == "wrinkled"]
        if len(w) >= 3 and np.ptp(w["dV_over_V"].to_numpy(float)) > 0:
            slopes.append((row["gamma"], np.polyfit(w["dV_over_V"].to_numpy(float),
                                                    w["W"].to_numpy(float), 1)[0]))
    if not slopes:
        return unreachable(key, value, "no run with 3 or more wrinkled steps")
    text = ", ".join(f"gamma {fmt_number(g)}: {fmt_number(s)}" for g, s in slopes)
    positive = sum(s > 0 for _, s in slopes)
    return info(key, value, f"slope dW/d(dV/V): {text}",
                f"W increases with dV/V in {positive}/{len(slopes)} runs",
                positive < len(slopes) / 2)


def _potato(ctx, key, value, name):
    entry = ctx.ref["results"]["potato_vs_capsule"]
    runs = ctx.at_gamma(entry["gamma"])
    runs = runs[(runs["control"].fillna("volume") == "volume") & runs["parent"].isna()]
    without = runs[runs["c0_cycle"].fillna(True).astype(bool).to_numpy() == False]  # noqa: E712
    with_cycle = runs[runs["c0_cycle"].fillna(True).astype(bool).to_numpy()]
    why = (f"needs deflation runs at gamma = {entry['gamma']} with and without the c0 cycle "
           f"(have {len(with_cycle)} with, {len(without)} without)")
    if name in ("gamma", "nu", "vertices", "DeltaV_over_V", "statement"):
        if without.empty or with_cycle.empty:
            return unreachable(key, value, why)
        ours = {"gamma": float(without["gamma"].iloc[0]), "nu": float(without["nu"].iloc[0]),
                "vertices": int(without["n_vertices"].iloc[0]),
                "DeltaV_over_V": entry["DeltaV_over_V"]}
        if name == "statement":
            return info(key, value, "see potato_dimples and energy_ratio_potato_over_capsule", "")
        return compare(key, value, ours[name], exact=name == "vertices")
    if without.empty or with_cycle.empty:
        return unreachable(key, value, why)
    # compare like with like: a capsule run made with the potato run's minimizer and mesh
    # (the quenched pair of reproduce-paper) before any other run with the cycle
    same = ((with_cycle["method"] == without["method"].iloc[0])
            & (with_cycle["n_vertices"] == without["n_vertices"].iloc[0])).to_numpy()
    with_cycle = pd.concat([with_cycle[same], with_cycle[~same]])
    a = ctx.step_near(without.iloc[0], entry["DeltaV_over_V"])
    b = ctx.step_near(with_cycle.iloc[0], entry["DeltaV_over_V"])
    if a is None or b is None:
        return unreachable(key, value, f"the runs do not reach dV/V = {entry['DeltaV_over_V']}")
    if name == "potato_dimples":
        return compare(key, value, int(a["n_dimples"]) if pd.notna(a["n_dimples"]) else None,
                       what="no analysis", exact=True)
    if name == "energy_ratio_potato_over_capsule":
        return compare(key, value, float(a["E_total"]) / float(b["E_total"]),
                       what="energies missing")
    return info(key, value, "", "not compared")


def _gallery(ctx, key, value):
    m = re.search(r"\[(\d+)\]", key)
    entry = ctx.ref["results"]["gallery_at_DeltaV_over_V_0.854"][int(m.group(1))]
    runs = ctx.at_gamma(entry["gamma"], ctx.deflation)
    if key.endswith(".gamma"):
        return info(key, value, f"{len(runs)} run(s) at this gamma", "")
    shapes = [s for s in (ctx.step_near(r, 0.854) for _, r in runs.iterrows()) if s is not None]
    if not shapes:
        return unreachable(key, value, f"no deflation run at gamma = {entry['gamma']} reaching "
                           "dV/V = 0.854")
    ours = [f"{s['shape']}" + (f" W = {int(s['W'])}" if s["shape"] == "wrinkled" else "")
            for s in shapes]
    expected = "wrinkled" if "wrinkled" in str(value) else "capsule"
    ok = all(s["shape"] == expected for s in shapes)
    return info(key, value, ours, f"same class ({expected})" if ok else
                f"different class: the paper shows a {expected} shape", not ok)


def _reinflation_runs(ctx) -> pd.DataFrame:
    keep = []
    for _, row in ctx.df.iterrows():
        table = ctx.table(row)
        dv = table["dV_over_V"].to_numpy(float) if table is not None else np.array([])
        keep.append(len(dv) > 1 and dv[-1] < dv[0])
    return ctx.df[np.array(keep, dtype=bool)] if len(ctx.df) else ctx.df


def _reinflation(ctx, key, value, top, name):
    runs = _reinflation_runs(ctx)
    if runs.empty:
        return unreachable(key, value, "no re-inflation run (a run whose volume increases, e.g. "
                           "`shellbuckle deflate --from DIR --step K`)")
    summaries = []
    for _, row in runs.iterrows():
        t = ctx.table(row)
        last = t.iloc[-1]
        summaries.append(f"gamma {fmt_number(row['gamma'])}: dV/V "
                         f"{fmt_number(t['dV_over_V'].iloc[0])} -> {fmt_number(last['dV_over_V'])}, {last['shape']}"
                         f" ({int(last['corners']) if pd.notna(last['corners']) else 0} corners,"
                         f" W = {int(last['W']) if pd.notna(last['W']) else 0})")
    return info(key, value, "; ".join(summaries), "compare by eye (shape statement)")


def _soleil(ctx, key, value, name):
    entry = ctx.ref["results"]["soleil"]
    runs = ctx.at_gamma(entry["gamma"])
    plain, path = runs[runs["parent"].isna()], runs[runs["parent"].notna()]
    why = (f"needs a deflation run and a run reached along another path (a branch) at gamma = "
           f"{entry['gamma']}, both at dV/V = {entry['DeltaV_over_V']}")
    if name in ("gamma", "nu", "DeltaV_over_V", "statement"):
        if plain.empty or path.empty:
            return unreachable(key, value, why)
        return info(key, value, f"{len(plain)} deflation and {len(path)} branched run(s)", "")
    if plain.empty or path.empty:
        return unreachable(key, value, why)
    # a path in gamma first (the paper's route), compared at its end, where gamma is reached
    path = pd.concat([path[path["control"] == "gamma"], path[path["control"] != "gamma"]])
    a = ctx.step_near(plain.iloc[0], entry["DeltaV_over_V"])
    b = ctx.step_near(path.iloc[0], entry["DeltaV_over_V"])
    table = ctx.table(path.iloc[0])
    if path["control"].iloc[0] == "gamma" and table is not None and not table.empty:
        b = table.iloc[-1] if abs(table["dV_over_V"].iloc[-1] - entry["DeltaV_over_V"]) <= \
            max(float(plain["dv"].iloc[0]), 1e-9) else None
    if a is None or b is None:
        return unreachable(key, value, why)
    return compare(key, value, float(a["E_total"]) / float(b["E_total"]))


def _experiments(ctx, key, value, name):
    runs = ctx.deflation
    if name == "d_over_R_thin_shells":
        return info(key, value, "", "experimental (not a simulation result)")
    if name == "wrinkles_observed":
        Ws = []
        for _, row in runs.iterrows():
            t = ctx.table(row)
            if t is not None and "shape" in t:
                Ws += list(t.loc[t["shape"].astype(str) == "wrinkled", "W"].astype(int))
        if not Ws:
            return unreachable(key, value, "no wrinkled step")
        lo, hi = min(Ws), max(Ws)
        inside = lo >= value[0] and hi <= value[1]
        return info(key, value, [lo, hi], "within the observed range" if inside else
                    "outside the observed range", not inside)
    wr = runs[np.isfinite(runs["wrinkles_dV_over_V"].to_numpy(float))]
    if wr.empty:
        return unreachable(key, value, "no run with wrinkles")
    d = [d_over_R(float(g), float(n)) for g, n in zip(wr["gamma"], wr["nu"])]
    return info(key, value, [min(d), max(d)], "d/R of our wrinkled runs")


def comparison_rows(ctx: Context) -> list[Row]:
    """One row per flattened key of the reference, in the order of the file."""
    rows = []
    captions = ctx.ref.get("gamma_to_d_over_R_in_captions", [])
    for key, value in flatten(ctx.ref).items():
        top = key.split(".")[0].split("[")[0]
        try:
            if top == "source":
                from importlib import metadata

                rows.append(info(key, value, f"shellbuckle {metadata.version('shellbuckle')}",
                                 "the paper is the reference"))
            elif top == "conventions":
                rows.append(_conventions(ctx, key, value))
            elif top == "protocol":
                rows.append(_protocol(ctx, key, value))
            elif top == "gamma_to_d_over_R_in_captions":
                i = int(re.search(r"\[(\d+)\]", key).group(1))
                rows.append(_caption(ctx, key, value, captions[i]))
            elif top == "results":
                rows.append(_results(ctx, key, value))
            else:
                rows.append(info(key, value, "", "not compared (entry unknown to this report)"))
        except (KeyError, IndexError, TypeError, ValueError) as exc:
            log.warning("reference entry %s not compared: %s", key, exc)
            rows.append(info(key, value, "", f"not compared: {type(exc).__name__}: {exc}"))
    return rows


# --------------------------------------------------------------------------- document

def _per_gamma(ctx) -> tuple[list[str], list[list[str]]]:
    header = ["gamma", "nu", "runs", "primary dV/V", "loss of axisymmetry", "wrinkles",
              "<W> (0.53-0.76)"]
    W = collect_mod.wrinkles_by_gamma(ctx.df).set_index("gamma")
    rows = []
    runs = ctx.deflation
    for gamma, group in runs.groupby(runs["gamma"].round(6)):
        cells = [fmt_number(float(gamma)), fmt_number(float(group["nu"].iloc[0])),
                 str(len(group))]
        for col in ("primary_dV_over_V", "axisymmetry_loss_dV_over_V", "wrinkles_dV_over_V"):
            v = group[col].to_numpy(float)
            v = v[np.isfinite(v)]
            cells.append("none" if not len(v) else fmt_number(v.mean()) + (
                f" ± {fmt_number(v.std(ddof=1))} ({len(v)})" if len(v) > 1 else ""))
        g = float(f"{float(gamma):.6g}")
        cells.append(f"{fmt_number(W.loc[g, 'W_mean'])} ± {fmt_number(W.loc[g, 'W_std'])}"
                     if g in W.index else "none")
        rows.append(cells)
    return header, rows


def _provenance(df) -> tuple[list[str], list[list[str]]]:
    from .store.run import RunStore

    header = ["run", "gamma", "nu", "energy convention", "seed", "mesh", "protocol", "status",
              "versions", "created"]
    rows = []
    for _, row in df.iterrows():
        meta = RunStore.open(row["path"]).meta
        p, m, v = meta.get("protocol", {}), meta.get("mesh", {}), meta.get("versions", {})
        protocol = (f"dv {fmt_number(row['dv'])} to {fmt_number(row['until'])}, "
                    f"c0 cycle {p.get('c0_cycle')}, jiggle {p.get('jiggle')}, "
                    f"temperature {p.get('temperature')}, {p.get('method')}, "
                    f"{p.get('bending')}, tol {p.get('tol')}, control {p.get('control', 'volume')}")
        if meta.get("parent"):
            protocol += f"; branched from {Path(meta['parent'].get('path', '')).name} step " \
                        f"{meta['parent'].get('step')}"
        shown = dict(v)
        if v.get("shellbuckle") and v.get("shellbuckle_git"):
            shown["shellbuckle"] = f"{v['shellbuckle']} (git {v['shellbuckle_git']})"
        versions = ", ".join(f"{k} {shown[k]}" for k in ("shellbuckle", "python", "numpy", "scipy")
                             if shown.get(k))
        convention = meta.get("params", {}).get("energy_convention", "helfrich")
        rows.append([row["name"], fmt_number(row["gamma"]), fmt_number(row["nu"]), convention,
                     fmt_number(row["seed"]) if pd.notna(row["seed"]) else "n/a",
                     f"{row['mesh']}, {m.get('n_vertices')} vertices, sha256 "
                     f"{str(m.get('sha256', ''))[:12]}",
                     protocol, f"{row['status']}: {meta.get('message') or ''}", versions,
                     str(meta.get("created", ""))])
    return header, rows


def build_document(df, tables, reference, fits=None, figures=None) -> list[tuple]:
    """The report as blocks: ``("h", level, text)``, ``("p", text)``, ``("list", items)``,
    ``("table", header, rows)``, ``("img", name, src)``."""
    fits = collect_mod.threshold_fits(df) if fits is None else fits
    ctx = Context(df, tables, reference, fits)
    rows = comparison_rows(ctx)
    blocks: list[tuple] = [("h", 1, "Reproduction report: Quilliet et al., EPJE 27, 13 (2008)")]
    n_gamma = ctx.deflation["gamma"].round(6).nunique()
    blocks.append(("p", f"{len(df)} run(s), {len(ctx.deflation)} following the paper's "
                        f"deflation protocol, at {n_gamma} gamma value(s). Energy convention "
                        f"(which bending energy kappa multiplies): {_readings(df)}. Reference: "
                        f"{reference.get('source', '')}. Numbers have 4 significant digits; an "
                        f"agreement is a difference within 2 sigma of our error, or within "
                        f"{100 * REL_AGREEMENT:.0f} % without an error estimate."))
    blocks.append(("h", 2, "Every reference number"))
    blocks.append(("table", ["reference key", "paper", "ours", "ours - paper", "relative",
                             "verdict"],
                   [[r.key, r.paper, r.ours, r.diff, r.rel, r.verdict] for r in rows]))
    blocks.append(("h", 2, "Disagreements"))
    bad = [f"{r.key}: paper {r.paper}, ours {r.ours} - {r.verdict}" for r in rows
           if r.disagreement]
    blocks.append(("list", bad) if bad else ("p", "None among the reachable numbers."))
    missing = [r.key for r in rows if r.verdict.startswith("not reachable")]
    if missing:
        blocks.append(("p", f"Not reachable with these runs ({len(missing)}): "
                            + ", ".join(missing) + "."))
    blocks.append(("h", 2, "The paper's captions: gamma vs d/R"))
    cap_rows, notes = [], []
    for entry in reference.get("gamma_to_d_over_R_in_captions", []):
        formula = d_over_R(entry["gamma"], 1.0 / 3.0)
        ok = check_caption(entry["gamma"], entry["d_over_R"])
        cap_rows.append([fmt_number(entry["gamma"]), _text(entry["d_over_R"]),
                         f"{formula:.4f}", "yes" if ok else "no"])
        if not ok:
            notes.append(f"gamma = {entry['gamma']} is printed with d/R = {entry['d_over_R']}, "
                         f"but gamma = 12 (1 - 2 nu^2/(1 - nu)) (R/d)^2 = 8 (R/d)^2 at nu = 1/3 "
                         f"gives d/R = {formula:.4f}; the caption is inconsistent with the "
                         f"paper's own formula.")
    blocks.append(("table", ["gamma", "d/R printed", "d/R from gamma = 8 (R/d)^2",
                             "consistent"], cap_rows))
    if notes:
        blocks.append(("list", notes))
    blocks.append(("h", 2, "Our fits"))
    fit_rows = []
    for key, fit in fits.items():
        fit_rows.append([key, str(fit), fmt_number(fit.prefactor), fmt_number(fit.prefactor_err),
                         fmt_number(fit.exponent), fmt_number(fit.exponent_err), str(fit.n),
                         "sigma of the seeds" if fit.weighted else "residual scatter"])
    if "secondary" in fits:
        gc = critical_gamma(fits["secondary"])
        fit_rows.append(["gamma_c (secondary law at dV/V = 1)", "", fmt_number(gc.value),
                         fmt_number(gc.err), "", "", "", ""])
    blocks.append(("table", ["fit", "law", "a", "a error", "b", "b error", "points",
                             "errors from"], fit_rows) if fit_rows else
                  ("p", "No fit: the runs give no threshold at enough gamma values."))
    header, per = _per_gamma(ctx)
    blocks.append(("h", 2, "Thresholds and W per gamma"))
    blocks.append(("table", header, per) if per else ("p", "No deflation run."))
    if figures:
        blocks.append(("h", 2, "Figures"))
        for name, src in figures.items():
            blocks.append(("img", name, src))
    blocks.append(("h", 2, "Provenance of the runs"))
    header, prov = _provenance(df)
    blocks.append(("table", header, prov))
    return blocks


def _md_cell(text) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def render_markdown(blocks) -> str:
    out = []
    for b in blocks:
        if b[0] == "h":
            out.append("#" * b[1] + " " + b[2])
        elif b[0] == "p":
            out.append(b[1])
        elif b[0] == "list":
            out.append("\n".join(f"- {item}" for item in b[1]))
        elif b[0] == "table":
            lines = ["| " + " | ".join(_md_cell(h) for h in b[1]) + " |",
                     "|" + "---|" * len(b[1])]
            lines += ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in b[2]]
            out.append("\n".join(lines))
        elif b[0] == "img":
            out.append(f"![{b[1]}]({b[2]})")
    return "\n\n".join(out) + "\n"


_CSS = ("body{font-family:sans-serif;max-width:1200px;margin:2em auto;line-height:1.4}"
        "table{border-collapse:collapse;font-size:0.85em;margin:1em 0}"
        "td,th{border:1px solid #ccc;padding:3px 6px;vertical-align:top}th{background:#eee}"
        "img{max-width:100%}")


def render_html(blocks) -> str:
    e = html.escape
    out = ["<!DOCTYPE html>", "<html><head><meta charset='utf-8'>",
           f"<title>{e(blocks[0][2])}</title><style>{_CSS}</style></head><body>"]
    for b in blocks:
        if b[0] == "h":
            out.append(f"<h{b[1]}>{e(b[2])}</h{b[1]}>")
        elif b[0] == "p":
            out.append(f"<p>{e(b[1])}</p>")
        elif b[0] == "list":
            out.append("<ul>" + "".join(f"<li>{e(str(i))}</li>" for i in b[1]) + "</ul>")
        elif b[0] == "table":
            out.append("<table><tr>" + "".join(f"<th>{e(str(h))}</th>" for h in b[1]) + "</tr>")
            out += ["<tr>" + "".join(f"<td>{e(str(c))}</td>" for c in row) + "</tr>"
                    for row in b[2]]
            out.append("</table>")
        elif b[0] == "img":
            out.append(f"<figure><img alt='{e(b[1])}' src='{b[2]}'>"
                       f"<figcaption>{e(b[1])}</figcaption></figure>")
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def write_report(paths, out, fmt: str = "md", *, reference=None, figures: bool = True) -> Path:
    """Write the reproduction report of the runs in ``paths`` to ``out`` (``fmt`` ``md`` or
    ``html``; module docstring). ``reference``: the paper's JSON (a dict or a path; found by
    :func:`~shellbuckle.analysis.collect.load_reference` when None). With ``figures`` the
    paper's Figs. 4, 5, 10 are drawn: as PNG files in ``<out stem>_figures/`` linked from a
    Markdown report, embedded in the HTML one. Returns ``out``."""
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    ref = reference if isinstance(reference, dict) else collect_mod.load_reference(reference)
    tables: dict = {}
    df = collect_mod.collect_runs(paths, tables=tables)
    fits = collect_mod.threshold_fits(df)
    out = Path(out)
    if out.exists() and out.is_dir():
        raise ValueError(f"--out {str(out)!r} is a folder; give a file name")
    out.parent.mkdir(parents=True, exist_ok=True)
    srcs = None
    if figures:
        from .plots.across import across_figures, save_figures

        fig_dir = out.parent / f"{out.stem}_figures"
        written = save_figures(across_figures(df, tables, reference=ref, fits=fits), fig_dir,
                               ("png",))
        if fmt == "html":
            srcs = {p.stem: "data:image/png;base64," + base64.b64encode(p.read_bytes()).decode()
                    for p in written}
            for p in written:
                p.unlink()
            if not any(fig_dir.iterdir()):
                fig_dir.rmdir()
        else:
            srcs = {p.stem: f"{fig_dir.name}/{p.name}" for p in written}
    blocks = build_document(df, tables, ref, fits, srcs)
    text = render_html(blocks) if fmt == "html" else render_markdown(blocks)
    out.write_text(text, encoding="utf-8")
    log.info("report of %d runs written to %s", len(df), out)
    return out
