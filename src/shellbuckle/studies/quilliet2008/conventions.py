"""Which energy did the paper simulate? Its study under each energy convention, scored.

The paper's eq. (1), ``1/2 kappa (c - c0)^2`` with ``c0 = 1/R``, can be read three ways
(:mod:`shellbuckle.params`): ``helfrich`` (c = c1 + c2, the standard thin plate), ``paper``
(c = H: a quarter of it, the standard shell at 4 gamma) and ``evolver-modulus`` (Surface
Evolver's modulus kappa: half of it, 2 gamma). :func:`compare_conventions` runs the paper's
whole study (:func:`shellbuckle.studies.quilliet2008.reproduce.reproduce_paper`) under each reading, in
``OUT/<convention>/``, then measures every number of the paper's reference file under each
reading, with the scatter of the seeds, and scores the readings.

The score was fixed before the runs (:data:`CRITERIA`): one point for each reference value
that a reading reproduces,

- a fitted number (the thresholds' power laws) agrees when ``|ours - paper| <= 2 sigma``,
  ``sigma = max(standard deviation of the per-seed fits, error of the fit to all seeds)``;
- a count (W) agrees within ``max(2 sigma_seeds, 2)``: the paper says W "fluctuates by one,
  or even two, units" between runs;
- a ratio of energies with no stated spread (Figs. 3 and 11) agrees within 20 % (Fig. 3, a
  quench whose depressions depend on its budget) or 10 % (Fig. 11), the number of the potato's
  depressions within 20 %;
- a gamma bracket (where capsules stop, where wrinkles start) agrees when ours, the median of
  the seeds, falls where the paper's statements put it (capsules up to 583 and at 743 until
  0.646; wrinkles from 933): capsule-only limit in {583, 743}, wrinkle onset in {743, 933};
- the Fig. 9 statement ("very well fitted" by U_axisym) agrees when the median of
  ``|E/U_axisym - 1|`` over the buckled steps with dV/V in [0.05, 0.35] at gamma = 2916 is at
  most 0.15, U_axisym being the paper's printed eq. Ucapsule at the printed gamma (the curve
  the paper drew; the reading's own U_axisym is reported beside it);
- a shape statement (Fig. 7 gallery at dV/V = 0.854, the re-inflation's 4-fold state,
  hysteresis past the crossing) agrees when most seeds show it; self-contact agrees when the
  median stop of all runs lies in the paper's 0.89-0.93 widened by one volume step; "W
  increases with gamma" when the slope of the runs' W against log10 gamma exceeds twice its
  standard error; "a weak tendency of W to increase with dV/V" when the median slope over the
  wrinkled runs is positive.

The reading with the most points is the verdict; a lead of one point or less is reported as
undecided. Every reading's values are reported whatever the score.
"""

from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ...util import json_safe

log = logging.getLogger(__name__)

CONVENTIONS = ("helfrich", "paper", "evolver-modulus")
COMPARISON_JSON = "conventions.json"
COMPARISON_MD = "conventions.md"
FIGURE = "conventions_thresholds"

FIG9_WINDOW = (0.05, 0.35)
FIG9_TOLERANCE = 0.15
W_SPREAD = 2.0
RATIO_TOLERANCE = {"fig3_ratio": 0.20, "fig3_dimples": 0.20, "fig11_ratio": 0.10}
CAPSULE_LIMIT_OK = (583.0, 743.0)
WRINKLE_ONSET_OK = (743.0, 933.0)
GALLERY = {271.0: "capsule", 2333.0: "wrinkled", 20995.0: "wrinkled"}
GALLERY_DV = 0.854
W_BOWL = (15163.0, 0.645, 7.0)

CRITERIA = {
    "primary_a": "2.8 (primary fit prefactor): within 2 sigma",
    "primary_b": "-0.55 (primary fit exponent): within 2 sigma",
    "secondary_a": "850 (secondary fit a/gamma, = gamma_c): within 2 sigma",
    "capsule_limit": "capsules only up to gamma = 583 (743 a capsule at 0.646): median of the "
                     "seeds in {583, 743}",
    "wrinkle_onset": "wrinkles from gamma = 933: median of the seeds in {743, 933}",
    "W_bowl": "W = 7 at gamma = 15163, dV/V = 0.645 (Fig. 11): within max(2 sigma, 2)",
    "W_vs_gamma": "W increases with gamma (Fig. 5, [0.53, 0.76]): slope vs log10 gamma > 2 SE",
    "W_vs_volume": "weak tendency of W to increase with dV/V (Fig. 4): median slope > 0",
    "fig9": "energy very well fitted by U_axisym after buckling (Fig. 9, gamma = 2916): median "
            "abs(E/U_axisym - 1) over dV/V in [0.05, 0.35] <= 0.15",
    "hysteresis": "buckling past the U_sphere = U_axisym crossing (gamma = 2916): most seeds",
    "fig3_dimples": "17 depressions in the potato (Fig. 3, quench): within 20 %",
    "fig3_ratio": "E_potato / E_capsule = 3.10 (Fig. 3): within 20 %",
    "fig11_ratio": "E_bowl / E_path = 1.42 (Fig. 11): within 10 %",
    "reinflation": "re-inflation 0.474 -> 0.209 ends in a 4-fold state (Fig. 8; 3 and 4 "
                   "wrinkles): 4 corners or W in {3, 4} in most seeds",
    "self_contact": "self-contact at dV/V = 0.89-0.93: median stop in [0.871, 0.949]",
    "gallery_271": "Fig. 7 at dV/V = 0.854, gamma = 271: a capsule in most seeds",
    "gallery_2333": "Fig. 7 at dV/V = 0.854, gamma = 2333: a wrinkled bowl in most seeds",
    "gallery_20995": "Fig. 7 at dV/V = 0.854, gamma = 20995: a wrinkled bowl in most seeds",
}
"""Every scored reference value and its agreement rule (the module docstring says why)."""


@dataclass
class Metric:
    """One reference value measured under one reading."""

    key: str
    paper: object
    value: object = None
    scatter: float = math.nan
    seeds: list = field(default_factory=list)
    agrees: bool | None = None
    note: str = ""

    def to_dict(self) -> dict:
        return {"key": self.key, "paper": self.paper, "value": json_safe(self.value),
                "scatter": json_safe(self.scatter), "seeds": json_safe(self.seeds),
                "agrees": self.agrees, "note": self.note, "rule": CRITERIA[self.key]}


# --------------------------------------------------------------------------- measurements

def _std(values) -> float:
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], float)
    return float(v.std(ddof=1)) if len(v) > 1 else math.nan


def _within(value, paper, tolerance) -> bool | None:
    if value is None or not np.isfinite(value) or not np.isfinite(tolerance):
        return None
    return bool(abs(value - paper) <= tolerance)


def _near(gamma_series, gamma, rtol=0.01):
    return np.isclose(gamma_series.to_numpy(float), gamma, rtol=rtol)


def _seed_fits(runs: pd.DataFrame) -> dict:
    """The primary and secondary fits of one seed's runs, weighted as the fit to all seeds
    is: each threshold by its resolution/sqrt(12), the volume step or the located bracket
    (one run per gamma has no scatter)."""
    from ...analysis.collect import threshold_points
    from ...analysis.fits import fit_power_law

    points = {n: threshold_points(runs, n) for n in ("primary", "axisymmetry_loss", "wrinkles")}
    secondary = pd.concat([points["axisymmetry_loss"], points["wrinkles"]], ignore_index=True)
    fits = {}
    for key, pts, exponent in (("primary", points["primary"], None),
                               ("secondary", secondary, -1.0)):
        if len(pts) >= (1 if exponent is not None else 2):
            floor = pts["resolution"].to_numpy(float) / math.sqrt(12.0)
            fits[key] = fit_power_law(pts["gamma"], pts["mean"], sigma=floor,
                                      exponent=exponent)
    return fits


def _fits(runs: pd.DataFrame, seeds) -> tuple[dict, dict]:
    from ...analysis.collect import threshold_fits

    pooled = threshold_fits(runs)
    per_seed = {s: _seed_fits(runs[runs["seed"] == s]) for s in seeds}
    return pooled, per_seed


def _fit_metric(key, paper, pooled, per_seed, name, attr) -> Metric:
    fit = pooled.get(name)
    values = [getattr(f[name], attr) if name in f else math.nan for f in per_seed.values()]
    if fit is None:
        return Metric(key, paper, seeds=values, note="no fit: too few thresholds")
    value = getattr(fit, attr)
    err = getattr(fit, f"{attr}_err")
    finite = [x for x in (_std(values), err) if math.isfinite(x)]
    sigma = max(finite) if finite else math.nan
    return Metric(key, paper, value, sigma, values, _within(value, paper, 2 * sigma),
                  f"fit to all seeds {fit}; per-seed std {_std(values):.3g}")


def _bracket(runs: pd.DataFrame, seeds) -> tuple[list, list]:
    """Per seed: the largest gamma up to which every run stays a capsule (no secondary
    threshold before the run's end), and the smallest gamma with a wrinkles event."""
    limits, onsets = [], []
    for s in seeds:
        mine = runs[runs["seed"] == s].sort_values("gamma")
        limit = None
        for _, row in mine.iterrows():
            secondary = np.isfinite([row["axisymmetry_loss_dV_over_V"],
                                     row["wrinkles_dV_over_V"]]).any()
            if secondary:
                break
            limit = float(row["gamma"])
        limits.append(limit)
        wr = mine[np.isfinite(mine["wrinkles_dV_over_V"].to_numpy(float))]
        onsets.append(float(wr["gamma"].min()) if len(wr) else None)
    return limits, onsets


def _median_label(values):
    v = sorted(x for x in values if x is not None)
    return v[(len(v) - 1) // 2] if v else None


def _row_near(table, dV_over_V, dv):
    if table is None or table.empty:
        return None
    x = table["dV_over_V"].to_numpy(float)
    i = int(np.argmin(np.abs(x - dV_over_V)))
    return table.iloc[i] if abs(x[i] - dV_over_V) <= 0.5 * dv + 1e-9 else None


def _W_bowl(runs, tables, seeds, dv) -> Metric:
    gamma, at, paper = W_BOWL
    values = []
    for s in seeds:
        mine = runs[(runs["seed"] == s) & _near(runs["gamma"], gamma)]
        row = _row_near(tables.get(mine["path"].iloc[0]), at, dv) if len(mine) else None
        values.append(math.nan if row is None or pd.isna(row["W"]) else float(row["W"]))
    value = float(np.nanmean(values)) if np.isfinite(values).any() else math.nan
    tol = max(2 * _std(values), W_SPREAD) if np.isfinite(_std(values)) else W_SPREAD
    note = "W at the stored step nearest 0.645 per seed (NaN: the run stopped before)"
    return Metric("W_bowl", paper, value, _std(values), values, _within(value, paper, tol), note)


def _W_vs_gamma(runs) -> Metric:
    wr = runs[runs["W_steps"].fillna(0).astype(int).to_numpy() > 0]
    by_gamma = wr.groupby(wr["gamma"].round(6))["W_mean"].agg(["mean", "std", "count"])
    text = ", ".join(f"{g:g}: {m:.2f}" for g, m in by_gamma["mean"].items())
    if wr["gamma"].round(6).nunique() < 2:
        return Metric("W_vs_gamma", "increases", None, seeds=[], note=f"<W> by gamma: {text}")
    x = np.log10(wr["gamma"].to_numpy(float))
    y = wr["W_mean"].to_numpy(float)
    A = np.vstack([x, np.ones_like(x)]).T
    coef, res, *_ = np.linalg.lstsq(A, y, rcond=None)
    dof = max(len(x) - 2, 1)
    s2 = float(np.sum((y - A @ coef) ** 2) / dof)
    cov = s2 * np.linalg.inv(A.T @ A)
    slope, se = float(coef[0]), float(math.sqrt(max(cov[0, 0], 0.0)))
    agrees = bool(slope > 2 * se) if se > 0 else bool(slope > 0)
    return Metric("W_vs_gamma", "increases", slope, se, list(by_gamma["mean"]), agrees,
                  f"slope of W per decade of gamma ± SE; <W> by gamma: {text}")


def _W_vs_volume(runs, tables) -> Metric:
    slopes = []
    for _, row in runs.iterrows():
        t = tables.get(row["path"])
        if t is None or t.empty or "shape" not in t:
            continue
        w = t[t["shape"].astype(str) == "wrinkled"]
        if len(w) >= 3 and w["dV_over_V"].nunique() >= 2:
            slopes.append(float(np.polyfit(w["dV_over_V"].to_numpy(float),
                                           w["W"].to_numpy(float), 1)[0]))
    if not slopes:
        return Metric("W_vs_volume", "weak increase", None, note="no run with 3 wrinkled steps")
    value = float(np.median(slopes))
    positive = sum(s > 1e-9 for s in slopes)
    return Metric("W_vs_volume", "weak increase", value, _std(slopes), slopes, value > 1e-9,
                  f"median dW/d(dV/V) over {len(slopes)} wrinkled runs; {positive} positive")


def _fig9(runs, tables, seeds, nu) -> tuple[Metric, Metric]:
    from ... import theory
    from ...params import ShellParameters

    printed = ShellParameters.from_gamma(2916.0, nu=nu)  # the curve the paper drew
    devs, own_devs, hyst = [], [], []
    convention = None
    for s in seeds:
        mine = runs[(runs["seed"] == s) & _near(runs["gamma"], 2916.0)]
        if not len(mine):
            continue
        row = mine.iloc[0]
        convention = row.get("energy_convention", "helfrich")
        own = ShellParameters.from_gamma(float(row["gamma"]), nu=float(row["nu"]),
                                         energy_convention=convention)
        t = tables.get(row["path"])
        primary = float(row["primary_dV_over_V"])
        hyst.append(bool(np.isfinite(primary) and primary > theory.crossing(printed)))
        if t is None or t.empty or not np.isfinite(primary):
            devs.append(math.nan)
            own_devs.append(math.nan)
            continue
        x = t["dV_over_V"].to_numpy(float)
        keep = (x >= FIG9_WINDOW[0]) & (x <= FIG9_WINDOW[1]) & (x >= primary - 1e-9)
        if not keep.any():
            devs.append(math.nan)
            own_devs.append(math.nan)
            continue
        E = t["E_over_kappa"].to_numpy(float)[keep]
        devs.append(float(np.median(np.abs(E / (theory.U_axisym_of_dV(x[keep], printed)
                                               / printed.kappa) - 1.0))))
        own_devs.append(float(np.median(np.abs(E / (theory.U_axisym_of_dV(x[keep], own)
                                                   / own.kappa) - 1.0))))
    value = float(np.nanmean(devs)) if np.isfinite(devs).any() else math.nan
    note = ("median |E/U_axisym - 1| per seed, U_axisym as printed at gamma = 2916; from this "
            f"reading's own U_axisym ({convention}): "
            + ", ".join(f"{d:.3f}" for d in own_devs))
    fig9 = Metric("fig9", "very well fitted", value, _std(devs), devs,
                  None if not np.isfinite(value) else bool(value <= FIG9_TOLERANCE), note)
    hysteresis = Metric("hysteresis", "past the crossing", sum(hyst), math.nan, hyst,
                        bool(sum(hyst) > len(hyst) / 2) if hyst else None,
                        f"seeds buckling past the crossing dV/V = {theory.crossing(printed):.4f}")
    return fig9, hysteresis


def _special(summary: dict, name: str) -> list:
    return [x for x in (summary.get("seeds_of_special_runs") or {}).get(name) or [] if x]


def _ratio_metric(key, paper, values, note) -> Metric:
    values = [float(v) for v in values]
    value = float(np.mean(values)) if values else math.nan
    tol = RATIO_TOLERANCE[key] * paper
    if np.isfinite(_std(values)):
        tol = max(tol, 2 * _std(values))
    return Metric(key, paper, value, _std(values), values, _within(value, paper, tol), note)


def _reinflation(summary) -> Metric:
    results = _special(summary, "reinflation")
    ok = [int(r["to"]["corners"]) == 4 or int(r["to"]["W"]) in (3, 4) for r in results]
    states = [f"gamma {r['gamma']:g}: {r['from']['shape']} (W {r['from']['W']}) -> "
              f"{r['to']['shape']} ({r['to']['corners']} corners, W {r['to']['W']})"
              for r in results]
    return Metric("reinflation", "4-fold", sum(ok), math.nan, ok,
                  bool(sum(ok) > len(ok) / 2) if ok else None, "; ".join(states))


def _self_contact(runs, dv) -> Metric:
    stops = runs.loc[runs["stop_reason"] == "self-intersection", "stop_dV_over_V"]
    stops = stops.to_numpy(float)
    if not len(stops):
        return Metric("self_contact", [0.89, 0.93], None, note="no run reached self-contact")
    value = float(np.median(stops))
    lo, hi = 0.89 - dv, 0.93 + dv
    return Metric("self_contact", [0.89, 0.93], value, _std(stops), list(stops),
                  bool(lo <= value <= hi),
                  f"median of {len(stops)} runs; range {stops.min():.3f}-{stops.max():.3f}")


def _gallery(runs, tables, seeds, dv) -> list[Metric]:
    out = []
    for gamma, shape in GALLERY.items():
        found, judged = [], 0
        for s in seeds:
            mine = runs[(runs["seed"] == s) & _near(runs["gamma"], gamma)]
            if not len(mine):
                continue
            row = _row_near(tables.get(mine["path"].iloc[0]), GALLERY_DV, dv)
            if row is None:
                stop = float(mine["stop_dV_over_V"].iloc[0])
                reason = mine["stop_reason"].iloc[0]
                # a run that touched itself before 0.854 is a finding; a shorter schedule is not
                judged += reason == "self-intersection"
                found.append(f"not reached ({reason} at {stop:.3f})")
            else:
                judged += 1
                found.append(str(row["shape"]) + (f" W {int(row['W'])}" if str(row["shape"])
                                                  == "wrinkled" else ""))
        hits = sum(f.split()[0] == shape for f in found)
        out.append(Metric(f"gallery_{gamma:g}", shape, hits, math.nan, found,
                          bool(hits > judged / 2) if judged else None,
                          f"{hits} of {len(found)} seeds"))
    return out


def measure(folder, *, reference: dict | None = None) -> dict:
    """Every scored value (:data:`CRITERIA`) of the study in ``folder`` (one
    :func:`~shellbuckle.studies.quilliet2008.reproduce.reproduce_paper` output):
    ``{"convention", "metrics": {key: Metric}, "score", "scored"}``."""
    from ...analysis.collect import collect_runs, convention_of, deflation_runs

    folder = Path(folder)
    summary = json.loads((folder / "reproduction.json").read_text(encoding="utf-8"))
    tables: dict = {}
    df = collect_runs([folder / "sweep"], tables=tables)
    runs = deflation_runs(df)
    seeds = sorted(int(s) for s in runs["seed"].dropna().unique())
    dv = float(np.nanmedian(runs["dv"].to_numpy(float)))
    nu = float(np.nanmedian(runs["nu"].to_numpy(float)))
    pooled, per_seed = _fits(runs, seeds)
    metrics = [
        _fit_metric("primary_a", 2.8, pooled, per_seed, "primary", "prefactor"),
        _fit_metric("primary_b", -0.55, pooled, per_seed, "primary", "exponent"),
        _fit_metric("secondary_a", 850.0, pooled, per_seed, "secondary", "prefactor"),
    ]
    limits, onsets = _bracket(runs, seeds)
    limit, onset = _median_label(limits), _median_label(onsets)
    metrics.append(Metric("capsule_limit", 583.0, limit, math.nan, limits,
                          None if limit is None else limit in CAPSULE_LIMIT_OK,
                          "largest gamma up to which every run stays a capsule, per seed"))
    metrics.append(Metric("wrinkle_onset", 933.0, onset, math.nan, onsets,
                          None if onset is None else onset in WRINKLE_ONSET_OK,
                          "smallest gamma with wrinkles, per seed"))
    metrics += [_W_bowl(runs, tables, seeds, dv), _W_vs_gamma(runs), _W_vs_volume(runs, tables)]
    metrics += list(_fig9(runs, tables, seeds, nu))
    fig3 = _special(summary, "fig3")
    metrics.append(_ratio_metric("fig3_dimples", 17.0, [r["b"]["n_dimples"] for r in fig3],
                                 "depressions of the quenched potato, per seed"))
    metrics.append(_ratio_metric("fig3_ratio", 3.10, [r["ratio"] for r in fig3],
                                 "E_potato / E_capsule of the quenched pair, per seed"))
    fig11 = _special(summary, "fig11")
    metrics.append(_ratio_metric(
        "fig11_ratio", 1.42, [r["ratio"] for r in fig11],
        "E_bowl / E_path per seed; path end W: "
        + ", ".join(str(r["a"].get("W")) for r in fig11) + "; bowl W: "
        + ", ".join(str(r["b"].get("W")) for r in fig11)))
    metrics.append(_reinflation(summary))
    metrics.append(_self_contact(runs, dv))
    metrics += _gallery(runs, tables, seeds, dv)
    by_key = {m.key: m for m in metrics}
    assert set(by_key) == set(CRITERIA), set(CRITERIA) ^ set(by_key)
    scored = [m for m in metrics if m.agrees is not None]
    return {"convention": convention_of(runs), "folder": str(folder), "seeds": seeds,
            "metrics": by_key, "score": sum(m.agrees for m in scored), "scored": len(scored),
            "wall_s": summary.get("wall_s", {}).get("total"), "run_s": _run_time(folder),
            "fits": {k: str(v) for k, v in pooled.items()}}


def _run_time(folder: Path) -> float:
    """Single-core seconds spent in the minimizations of every run stored under ``folder``
    (the sum of the runs' ``wall_s`` columns), whichever invocations made them."""
    total = 0.0
    for table in folder.rglob("table.csv"):
        total += float(pd.read_csv(table, usecols=["wall_s"])["wall_s"].sum())
    return total


def verdict(results: dict) -> str:
    """The reading with the most points, or why none is picked."""
    ranked = sorted(results.values(), key=lambda r: -r["score"])
    best = ranked[0]
    line = ", ".join(f"{r['convention']} {r['score']}/{r['scored']}" for r in ranked)
    if len(ranked) > 1 and best["score"] - ranked[1]["score"] <= 1:
        return (f"undecided: {line} (a lead of one point or less does not pick a reading)")
    if best["score"] < best["scored"] / 2:
        return (f"{best['convention']} scores best ({line}) but reproduces fewer than half of "
                "the paper's values: no reading reproduces the paper")
    return f"{best['convention']} reproduces the paper best: {line}"


# --------------------------------------------------------------------------- outputs

def _fmt(value) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, float):
        return "n/a" if not math.isfinite(value) else f"{value:.4g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_fmt(v) for v in value) + "]"
    return str(value)


def _cell(m: Metric) -> str:
    mark = {True: "✓", False: "✗", None: "–"}[m.agrees]
    value = _fmt(m.value)
    if isinstance(m.scatter, float) and math.isfinite(m.scatter):
        value += f" ± {m.scatter:.2g}"
    seeds = _fmt(m.seeds) if m.seeds else ""
    return f"{mark} {value}" + (f" (seeds {seeds})" if seeds else "")


def markdown(results: dict) -> str:
    """The comparison table (one row per scored value, one column per reading)."""
    names = [c for c in CONVENTIONS if c in results]
    lines = ["| reference value (agreement rule) | " + " | ".join(names) + " |",
             "|---" * (len(names) + 1) + "|"]
    for key, rule in CRITERIA.items():
        cells = [_cell(results[c]["metrics"][key]) for c in names]
        lines.append(f"| {rule} | " + " | ".join(cells) + " |")
    lines.append("| **score** | " + " | ".join(
        f"**{results[c]['score']} / {results[c]['scored']}**" for c in names) + " |")
    lines.append("| wall time of the last invocation | " + " | ".join(
        _fmt((results[c]["wall_s"] or math.nan) / 60.0) + " min" for c in names) + " |")
    lines.append("| single-core run time of all runs | " + " | ".join(
        _fmt(results[c].get("run_s", math.nan) / 60.0) + " min" for c in names) + " |")
    notes = [f"- {c}, {key}: {results[c]['metrics'][key].note}"
             for c in names for key in CRITERIA if results[c]["metrics"][key].note]
    return "\n".join(lines + ["", f"Verdict: {verdict(results)}", "", "Notes:", *notes]) + "\n"


def plot_thresholds(results: dict, path=None):
    """Thresholds against gamma under each reading (mean and std of the seeds), with the
    paper's laws 2.8 gamma^-0.55 and 850/gamma."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from ...analysis.collect import collect_runs, deflation_runs

    names = [c for c in CONVENTIONS if c in results]
    fig, axes = plt.subplots(1, len(names), figsize=(4.2 * len(names), 3.9), sharey=True,
                             constrained_layout=True, squeeze=False)
    grid = np.geomspace(200, 40000, 80)
    for ax, name in zip(axes[0], names):
        runs = deflation_runs(collect_runs([Path(results[name]["folder"]) / "sweep"]))
        for column, marker, color, label in (
                ("primary_dV_over_V", "s", "k", "primary"),
                ("axisymmetry_loss_dV_over_V", "^", "C3", "loss of axisymmetry"),
                ("wrinkles_dV_over_V", "v", "C1", "wrinkles")):
            g = runs.groupby(runs["gamma"].round(6))[column].agg(["mean", "std", "count"])
            g = g[g["count"] > 0]
            ax.errorbar(g.index, g["mean"], yerr=g["std"].fillna(0.0), fmt=marker, color=color,
                        mfc="none" if column != "primary_dV_over_V" else color, ms=5,
                        capsize=2, label=label)
        ax.plot(grid, 2.8 * grid ** -0.55, "--", color="k", lw=1,
                label=r"paper $2.8\,\gamma^{-0.55}$")
        sec = grid[850 / grid <= 1]
        ax.plot(sec, 850 / sec, "--", color="C3", lw=1, label=r"paper $850/\gamma$")
        ax.set(xscale="log", yscale="log", ylim=(0.008, 1.2), xlabel=r"$\gamma$ (as labelled)",
               title=f"{name}: {results[name]['score']}/{results[name]['scored']} values")
    axes[0][0].set_ylabel(r"threshold $\Delta V/V$")
    axes[0][-1].legend(fontsize=7, loc="lower left", frameon=False)
    if path is not None:
        fig.savefig(path, dpi=150)
        plt.close(fig)
    return fig


def best_readings(results: dict) -> tuple:
    """``("helfrich", best)``: the standard reading and the best-scoring other one (the
    sensitivity table's two readings)."""
    others = sorted((r for n, r in results.items() if n != "helfrich"),
                    key=lambda r: -r["score"])
    return ("helfrich",) + ((others[0]["convention"],) if others else ())


def compare_conventions(out, study=None, *, conventions=CONVENTIONS, workers=None,
                        scheduler=None, progress: bool = True, formats=("png", "pdf"),
                        run: bool = True, sensitivity_seeds: int | None = None) -> dict:
    """Run the paper's study under each of ``conventions`` in ``OUT/<convention>/`` (resumable:
    finished runs are kept) and write the scored comparison: ``OUT/conventions.md`` (the
    table and the verdict), ``OUT/conventions.json`` (every value, per seed) and
    ``OUT/conventions_thresholds.png`` (thresholds under each reading). ``study`` sets the
    scale (default: the paper's, three seeds, the special runs for every seed); its
    ``energy_convention`` is replaced. ``run=False`` only measures existing folders.
    ``sensitivity_seeds``: also the sensitivity table (:func:`sensitivity`) under helfrich
    and the best other reading, with that many seeds."""
    import dataclasses

    from ...params import check_convention
    from .reproduce import Study, reproduce_paper

    conventions = tuple(check_convention(c) for c in conventions)
    study = study or Study()
    study = dataclasses.replace(study, special_seeds=study.seeds)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    for name in conventions:
        if run:
            reproduce_paper(out / name, dataclasses.replace(study, energy_convention=name),
                            workers=workers, scheduler=scheduler, progress=progress,
                            formats=formats)
        elif not (out / name / "reproduction.json").exists():
            raise ValueError(f"{out / name} holds no study (no reproduction.json): run it first")
    results = {name: measure(out / name) for name in conventions}
    text = markdown(results)
    if sensitivity_seeds:
        readings = best_readings(results)
        sensitivity(out, readings, seeds=sensitivity_seeds, workers=workers,
                    scheduler=scheduler, progress=progress, run=run)
        text += ("\nSensitivity (gamma = 2333 and 15163; readings "
                 f"{', '.join(readings)}):\n\n" + (out / SENSITIVITY_MD).read_text("utf-8"))
    (out / COMPARISON_MD).write_text(text, encoding="utf-8")
    data = {"criteria": CRITERIA, "verdict": verdict(results),
            "readings": {n: {**{k: v for k, v in r.items() if k != "metrics"},
                             "metrics": {k: m.to_dict() for k, m in r["metrics"].items()}}
                         for n, r in results.items()},
            "wall_s": time.perf_counter() - t0}
    (out / COMPARISON_JSON).write_text(json.dumps(json_safe(data), indent=1), encoding="utf-8")
    plot_thresholds(results, out / f"{FIGURE}.png")
    log.info("conventions compared in %s: %s", out, data["verdict"])
    return data


# --------------------------------------------------------------------------- sensitivity

SENSITIVITY_GAMMAS = (2333.0, 15163.0)
SENSITIVITY_MD, SENSITIVITY_CSV = "sensitivity.md", "sensitivity.csv"
QUENCH_ITERATIONS = 300
"""Conjugate-gradient iterations per minimization of the quench variant: the budget of the
Fig. 3 pair on the paper's mesh (:func:`shellbuckle.studies.quilliet2008.reproduce.potato_quench`)."""
VARIANTS = {
    "base (T 0.05, Newton, juelicher, 3594)": {},
    "jiggle T 0.01": {"temperature": (0.01,)},
    "jiggle T 0.2": {"temperature": (0.2,)},
    f"quench (CG, {QUENCH_ITERATIONS} iterations)": {"method": ("cg",),
                                                     "max_iter": QUENCH_ITERATIONS},
    "bending evolver": {"bending": ("evolver",)},
    "mesh 10242": {"vertices": (10242,)},
}
"""The other suspects, one change each from the paper's protocol as we run it."""


def _variant_of(row) -> str:
    if row["n_vertices"] != 3594:
        return f"mesh {int(row['n_vertices'])}"
    if row["method"] == "cg":
        return f"quench (CG, {QUENCH_ITERATIONS} iterations)"
    if row["bending"] == "evolver":
        return "bending evolver"
    t = row["temperature"]
    if isinstance(t, float) and math.isfinite(t) and abs(t - 0.05) > 1e-12:
        return f"jiggle T {t:g}"
    return "base (T 0.05, Newton, juelicher, 3594)"


def sensitivity_specs(conventions, seeds: int, *, gammas=SENSITIVITY_GAMMAS,
                      with_base: bool = False) -> list:
    """The sweeps of the sensitivity table: each variant of :data:`VARIANTS` at ``gammas``
    under each of ``conventions``, seeds 0..seeds-1 (the base too when ``with_base``)."""
    from ...sweep import SweepSpec

    common = dict(gamma=tuple(gammas), seeds=tuple(range(seeds)), vertices=(3594,),
                  energy_convention=tuple(conventions))
    return [SweepSpec(**(common | change)) for change in VARIANTS.values()
            if change or with_base]


SENSITIVITY_COLUMNS = {
    "primary_dV_over_V": "primary buckling",
    "axisymmetry_loss_dV_over_V": "loss of axisymmetry",
    "wrinkles_dV_over_V": "wrinkles",
    "W_mean": "<W> in [0.53, 0.76]",
    "stop_dV_over_V": "stop",
}
"""The columns of the sensitivity table: thresholds (dV/V), the mean wrinkle count, the end."""


def sensitivity_table(frames) -> pd.DataFrame:
    """One row per (variant, reading, gamma): the thresholds and W over the seeds
    (``collect_runs`` rows of the variants and of the base study; finished runs only)."""
    df = pd.concat(frames, ignore_index=True)
    df = df[df["gamma"].round(0).isin([round(g) for g in SENSITIVITY_GAMMAS])
            & (df["status"] == "finished")]
    df = df.assign(variant=df.apply(_variant_of, axis=1))
    rows = []
    for (variant, convention, gamma), g in df.groupby(["variant", "energy_convention",
                                                       df["gamma"].round(0)]):
        row = {"variant": variant, "energy_convention": convention, "gamma": float(gamma),
               "runs": len(g)}
        for column in SENSITIVITY_COLUMNS:
            v = g[column].to_numpy(float)
            row[f"{column}_n"] = int(np.isfinite(v).sum())
            row[f"{column}_mean"] = float(np.nanmean(v)) if np.isfinite(v).any() else math.nan
            row[f"{column}_std"] = _std(v)
        rows.append(row)
    order = {name: i for i, name in enumerate(VARIANTS)}
    table = pd.DataFrame(rows)
    return table.sort_values(["energy_convention", "gamma", "variant"],
                             key=lambda c: c.map(order) if c.name == "variant" else c)


def sensitivity_markdown(table: pd.DataFrame) -> str:
    def cell(r, column):
        n, m, s = r[f"{column}_n"], r[f"{column}_mean"], r[f"{column}_std"]
        if n == 0:
            return f"none (0/{r['runs']})"
        if math.isfinite(s) and s <= 1e-9 * max(abs(m), 1.0):
            s = 0.0  # equal values up to round-off
        text = f"{m:.3g}" + (f" ± {s:.2g}" if math.isfinite(s) else "")
        return text + (f" ({n}/{r['runs']})" if n < r["runs"] else "")

    lines = ["| reading | gamma | variant | runs | " + " | ".join(SENSITIVITY_COLUMNS.values())
             + " |", "|---" * (4 + len(SENSITIVITY_COLUMNS)) + "|"]
    for _, r in table.iterrows():
        lines.append(f"| {r['energy_convention']} | {r['gamma']:g} | {r['variant']} | "
                     f"{r['runs']} | " + " | ".join(cell(r, c) for c in SENSITIVITY_COLUMNS)
                     + " |")
    return "\n".join(lines) + "\n"


def sensitivity(out, conventions, *, seeds: int = 2, workers=None, scheduler=None,
                progress: bool = True, run: bool = True) -> pd.DataFrame:
    """The sensitivity table at gamma = 2333 and 15163 under each of ``conventions``: the
    secondary thresholds and W against the jiggle temperature, the minimization (converged or
    a fixed CG quench), the bending discretization and the mesh, one change at a time, in
    ``OUT/sensitivity/`` (resumable); the base is taken from ``OUT/<convention>/sweep`` when
    the study is there, else run too. Writes ``OUT/sensitivity.md`` and ``.csv``."""
    from ...analysis.collect import collect_runs
    from ...sweep import run_sweep, sweep_client

    out = Path(out)
    folder = out / "sensitivity"
    bases = [out / c / "sweep" for c in conventions if (out / c / "sweep").is_dir()]
    with_base = len(bases) < len(conventions)
    if run:
        with sweep_client(scheduler, workers, [folder]) as client:
            for spec in sensitivity_specs(conventions, seeds, with_base=with_base):
                run_sweep(spec, folder, scheduler=client, progress=progress)
    frames = [collect_runs([folder])] if folder.is_dir() else []
    frames += [collect_runs([b]) for b in bases]
    table = sensitivity_table(frames)
    table = table[table["energy_convention"].isin(conventions)]
    table.to_csv(out / SENSITIVITY_CSV, index=False)
    (out / SENSITIVITY_MD).write_text(sensitivity_markdown(table), encoding="utf-8")
    return table
