"""The paper's reproduction report: our numbers next to every number of Quilliet et al. (2008).

:func:`write_report` writes the report of :mod:`shellbuckle.studies.report` with one row per
entry of the paper's reference JSON (``shellbuckle/data/quilliet2008.json``,
:func:`~shellbuckle.analysis.collect.load_reference`; every key, flattened as
``results.primary_buckling_fit.a``): the paper's value, ours, the difference and a verdict, or
why the runs cannot reach it (:func:`comparison_rows`), and a section on the two captions of
the paper whose gamma and d/R contradict its own formula
(:func:`shellbuckle.params.check_caption`). This module knows the reference's keys; the
machinery (rows, verdicts, fits, figures, provenance, Markdown and HTML) is general.
"""

from __future__ import annotations

import logging
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ...analysis import collect as collect_mod
from ...analysis.collect import load_reference
from ...analysis.fits import W_WINDOW, critical_gamma
from ...params import check_caption, d_over_R
from ..report import (FORMATS, GAMMA_RTOL, REL_AGREEMENT, Comparison, Context, Row, as_text,
                      compare, flatten, fmt_number, info, readings, render_html,
                      render_markdown, set_of, unreachable)
from ..report import build_document as _build_document
from ..report import write_report as _write_report

__all__ = ["FORMATS", "GAMMA_RTOL", "PAPER_STOP", "REL_AGREEMENT", "TITLE", "Context", "Row",
           "build_document", "caption_blocks", "compare", "comparison_rows", "flatten",
           "fmt_number", "info", "onset", "render_html", "render_markdown", "unreachable",
           "write_report"]

log = logging.getLogger(__name__)

TITLE = "Reproduction report: Quilliet et al., EPJE 27, 13 (2008)"
#: The paper's self-contact stop, "inner volumes of the order 7-11 % of V0" (§4.1).
PAPER_STOP = (0.89, 0.93)


# --------------------------------------------------------------------------- comparisons

def _conventions(ctx, key, value):
    ours = {"gamma": "A R^2 / kappa (shellbuckle.params)",
            "nu": f"2D Poisson ratio; runs at nu = "
                  f"{', '.join(sorted({fmt_number(v) for v in ctx.df['nu'].dropna()}))}",
            "gamma_from_d_over_R": "gamma = 12 (1 - 2 nu^2/(1-nu)) (R/d)^2 "
                                   "(shellbuckle.params.gamma_from_d_over_R)",
            "spontaneous_curvature": "c = c1 + c2, c0 = 2/R on the stress-free sphere; energy "
                                     "convention(s) of the runs: " + readings(ctx.df)}
    name = key.split(".")[-1]
    return info(key, value, ours.get(name, "same definitions"), "same convention")


def _protocol(ctx, key, value):
    runs = ctx.deflation if len(ctx.deflation) else ctx.df
    name = key.split(".")[-1]
    if name == "volume_step_over_V0":
        steps = set_of(runs["dv"].round(6))
        if not steps:
            return unreachable(key, value, "no run with a volume schedule")
        if len(steps) == 1:
            return compare(key, value, steps[0], what="volume step")
        return info(key, value, steps, "several volume steps among the runs")
    if name == "vertices":
        n = set_of(int(v) for v in runs["n_vertices"].dropna())
        if len(n) == 1:
            return compare(key, value, n[0], exact=True)
        return info(key, value, n, "several mesh sizes among the runs")
    if name == "mesh":
        kinds = set_of(runs["mesh"])
        same = kinds == ["random"]
        return info(key, value, kinds, "same kind (randomized)" if same else
                    "different: not only randomized meshes", not same)
    if name == "minimization":
        ours = (f"methods {set_of(runs['method'])}, c0 cycle {set_of(runs['c0_cycle'])}, "
                f"jiggle {set_of(runs['jiggle'])}, temperature {set_of(runs['temperature'])}")
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
    from ... import theory
    from ...params import ShellParameters

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


def caption_blocks(ctx: Context) -> list[tuple]:
    """The section on the paper's captions: each printed gamma and d/R against
    gamma = 8 (R/d)^2 (nu = 1/3), and a note on each inconsistent one."""
    cap_rows, notes = [], []
    for entry in ctx.ref.get("gamma_to_d_over_R_in_captions", []):
        formula = d_over_R(entry["gamma"], 1.0 / 3.0)
        ok = check_caption(entry["gamma"], entry["d_over_R"])
        cap_rows.append([fmt_number(entry["gamma"]), as_text(entry["d_over_R"]),
                         f"{formula:.4f}", "yes" if ok else "no"])
        if not ok:
            notes.append(f"gamma = {entry['gamma']} is printed with d/R = {entry['d_over_R']}, "
                         f"but gamma = 12 (1 - 2 nu^2/(1 - nu)) (R/d)^2 = 8 (R/d)^2 at nu = 1/3 "
                         f"gives d/R = {formula:.4f}; the caption is inconsistent with the "
                         f"paper's own formula.")
    blocks = [("h", 2, "The paper's captions: gamma vs d/R"),
              ("table", ["gamma", "d/R printed", "d/R from gamma = 8 (R/d)^2", "consistent"],
               cap_rows)]
    return blocks + ([("list", notes)] if notes else [])


#: The paper's report: its title, one row per reference entry, the captions' section.
COMPARISON = Comparison(title=TITLE, rows=comparison_rows, sections=caption_blocks,
                        label="paper")


def build_document(df, tables, reference, fits=None, figures=None) -> list[tuple]:
    """The paper's report as blocks (:func:`shellbuckle.studies.report.build_document`)."""
    return _build_document(df, tables, reference, COMPARISON, fits, figures)


def write_report(paths, out, fmt: str = "md", *, reference=None, figures: bool = True) -> Path:
    """Write the reproduction report of the runs in ``paths`` to ``out`` (``fmt`` ``md`` or
    ``html``; :mod:`shellbuckle.studies.report`). ``reference``: the paper's JSON (a dict or a
    path; :func:`~shellbuckle.analysis.collect.load_reference`, the package's copy, when
    None). With ``figures`` the paper's Figs. 4, 5, 10 are drawn: as PNG files in
    ``<out stem>_figures/`` linked from a Markdown report, embedded in the HTML one. Returns
    ``out``."""
    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    return _write_report(paths, out, fmt, reference=load_reference(reference),
                         comparison=COMPARISON, figures=figures)
