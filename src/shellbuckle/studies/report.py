"""A report that puts runs' numbers next to a reference's: the machinery of a study's report.

A study (e.g. :mod:`shellbuckle.studies.quilliet2008`) gives a :class:`Comparison`: its title,
one :class:`Row` per entry of its reference file (:func:`compare` for numbers, :func:`info`
for statements, :func:`unreachable` for what the runs cannot reach) and sections of its own.
:func:`write_report` collects the runs (run or sweep folders,
:func:`shellbuckle.analysis.collect.collect_runs`; nothing is recomputed), fits the thresholds
(:func:`~shellbuckle.analysis.collect.threshold_fits`) and writes a Markdown or a single-file
HTML report with:

1. one row per reference entry: the reference's value, ours, the difference (absolute and
   relative) and a plain verdict, or why the runs cannot reach it;
2. the disagreements, stated one by one;
3. the study's own sections;
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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from ..analysis import collect as collect_mod
from ..analysis.fits import critical_gamma

log = logging.getLogger(__name__)

FORMATS = ("md", "html")
#: Without an error estimate, a relative difference below this counts as agreement.
REL_AGREEMENT = 0.05
#: Relative tolerance on gamma when looking for runs at one of the reference's gammas.
GAMMA_RTOL = 0.01


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


def as_text(value) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(as_text(v) for v in value) + "]"
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        return fmt_number(value)
    return str(value)


def compare(key, paper, ours, err=None, *, what: str = "", exact: bool = False) -> Row:
    """A numerical comparison row: ours - paper, relative to |paper|, and a verdict (agrees
    within 2 sigma of ``err``, or within :data:`REL_AGREEMENT`, or ``exact`` equality)."""
    if ours is None or (isinstance(ours, float) and not math.isfinite(ours)):
        return Row(key, as_text(paper), "not reachable", verdict=f"not reachable: {what}")
    ours_f, paper_f = float(ours), float(paper)
    diff = ours_f - paper_f
    rel = diff / abs(paper_f) if paper_f != 0 else math.nan
    shown = fmt_number(ours) + (f" ± {fmt_number(err)}" if err is not None and math.isfinite(err)
                                and err > 0 else "")
    if exact:
        ok = diff == 0
        verdict = "same" if ok else f"different: ours {fmt_number(ours)}, paper {as_text(paper)}"
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
    return Row(key, as_text(paper), shown, fmt_number(diff),
               "" if not math.isfinite(rel) else f"{100 * rel:+.1f} %", verdict, not ok)


def info(key, paper, ours, verdict, disagreement: bool = False) -> Row:
    """A row for a statement or a non-numerical entry."""
    return Row(key, as_text(paper), as_text(ours), verdict=verdict, disagreement=disagreement)


def unreachable(key, paper, why: str) -> Row:
    return Row(key, as_text(paper), "not reachable", verdict=f"not reachable with these runs: {why}")


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
            from ..run import Run

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


def readings(df) -> str:
    """The energy conventions of the runs with their bending energy and gamma factor."""
    from ..params import bending_factor, convention_formula

    names = (df["energy_convention"].fillna("helfrich") if "energy_convention" in df
             else pd.Series(["helfrich"] * len(df)))
    out = []
    for name, n in names.value_counts().items():
        f = bending_factor(name)
        scale = "" if f == 1 else f", the standard shell at {1 / f:g} gamma"
        out.append(f"{name} ({convention_formula(name)}{scale}): {n} run(s)")
    return "; ".join(out) if out else "none"


def set_of(values) -> list:
    """Sorted distinct values (numpy scalars as Python ones), missing values left out."""
    values = [v.item() if isinstance(v, np.generic) else v for v in values]
    return sorted({v for v in values if v is not None and v is not pd.NA
                   and not (isinstance(v, float) and math.isnan(v))}, key=str)


# --------------------------------------------------------------------------- document

def per_gamma(ctx) -> tuple[list[str], list[list[str]]]:
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


def provenance(df) -> tuple[list[str], list[list[str]]]:
    from ..store.run import RunStore

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


@dataclass(frozen=True)
class Comparison:
    """What a study puts in its report: the ``title``; ``rows(ctx)``, one :class:`Row` per
    entry of its reference, in order; ``sections(ctx)``, blocks of its own after the
    disagreements (see :func:`build_document`); ``label``, how the rows name the reference's
    values (its column, "ours - label", the disagreements)."""

    title: str
    rows: Callable[[Context], list]
    sections: Callable[[Context], list] = field(default=lambda ctx: [])
    label: str = "reference"


def _fit_blocks(fits: dict) -> list[tuple]:
    """Our fits: one row per power law, and gamma_c of the secondary law."""
    fit_rows = []
    for key, fit in fits.items():
        fit_rows.append([key, str(fit), fmt_number(fit.prefactor), fmt_number(fit.prefactor_err),
                         fmt_number(fit.exponent), fmt_number(fit.exponent_err), str(fit.n),
                         "sigma of the seeds" if fit.weighted else "residual scatter"])
    if "secondary" in fits:
        gc = critical_gamma(fits["secondary"])
        fit_rows.append(["gamma_c (secondary law at dV/V = 1)", "", fmt_number(gc.value),
                         fmt_number(gc.err), "", "", "", ""])
    return [("h", 2, "Our fits"),
            ("table", ["fit", "law", "a", "a error", "b", "b error", "points", "errors from"],
             fit_rows) if fit_rows else
            ("p", "No fit: the runs give no threshold at enough gamma values.")]


def _comparison_blocks(rows: list, label: str) -> list[tuple]:
    """Every reference entry, the disagreements, and what the runs cannot reach."""
    blocks: list[tuple] = [
        ("h", 2, "Every reference number"),
        ("table", ["reference key", label, "ours", f"ours - {label}", "relative", "verdict"],
         [[r.key, r.paper, r.ours, r.diff, r.rel, r.verdict] for r in rows]),
        ("h", 2, "Disagreements")]
    bad = [f"{r.key}: {label} {r.paper}, ours {r.ours} - {r.verdict}" for r in rows
           if r.disagreement]
    blocks.append(("list", bad) if bad else ("p", "None among the reachable numbers."))
    missing = [r.key for r in rows if r.verdict.startswith("not reachable")]
    if missing:
        blocks.append(("p", f"Not reachable with these runs ({len(missing)}): "
                            + ", ".join(missing) + "."))
    return blocks


def build_document(df, tables, reference: dict, comparison: Comparison, fits=None,
                   figures=None) -> list[tuple]:
    """The report as blocks: ``("h", level, text)``, ``("p", text)``, ``("list", items)``,
    ``("table", header, rows)``, ``("img", name, src)``."""
    fits = collect_mod.threshold_fits(df) if fits is None else fits
    ctx = Context(df, tables, reference, fits)
    n_gamma = ctx.deflation["gamma"].round(6).nunique()
    blocks: list[tuple] = [("h", 1, comparison.title), (
        "p", f"{len(df)} run(s), {len(ctx.deflation)} following the paper's "
             f"deflation protocol, at {n_gamma} gamma value(s). Energy convention "
             f"(which bending energy kappa multiplies): {readings(df)}. Reference: "
             f"{reference.get('source', '')}. Numbers have 4 significant digits; an "
             f"agreement is a difference within 2 sigma of our error, or within "
             f"{100 * REL_AGREEMENT:.0f} % without an error estimate.")]
    blocks += _comparison_blocks(comparison.rows(ctx), comparison.label)
    blocks += comparison.sections(ctx)
    blocks += _fit_blocks(fits)
    header, per = per_gamma(ctx)
    blocks.append(("h", 2, "Thresholds and W per gamma"))
    blocks.append(("table", header, per) if per else ("p", "No deflation run."))
    if figures:
        blocks.append(("h", 2, "Figures"))
        for name, src in figures.items():
            blocks.append(("img", name, src))
    blocks.append(("h", 2, "Provenance of the runs"))
    header, prov = provenance(df)
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


def write_report(paths, out, fmt: str = "md", *, reference: dict, comparison: Comparison,
                 figures: bool = True) -> Path:
    """Write the report of the runs in ``paths`` against ``reference`` (a dict) with the
    study's ``comparison`` to ``out`` (``fmt`` ``md`` or ``html``; module docstring). With
    ``figures`` Figs. 4, 5 and 10 of :mod:`shellbuckle.plots.across` are drawn: as PNG files
    in ``<out stem>_figures/`` linked from a Markdown report, embedded in the HTML one.
    Returns ``out``."""
    from ..store.names import refuse_store_file

    if fmt not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    refuse_store_file(out)  # before any run is read
    tables: dict = {}
    df = collect_mod.collect_runs(paths, tables=tables)
    fits = collect_mod.threshold_fits(df)
    out = Path(out)
    if out.exists() and out.is_dir():
        raise ValueError(f"--out {str(out)!r} is a folder; give a file name")
    out.parent.mkdir(parents=True, exist_ok=True)
    srcs = _figures(df, tables, reference, fits, out, fmt) if figures else None
    blocks = build_document(df, tables, reference, comparison, fits, srcs)
    text = render_html(blocks) if fmt == "html" else render_markdown(blocks)
    out.write_text(text, encoding="utf-8")
    log.info("report of %d runs written to %s", len(df), out)
    return out


def _figures(df, tables, reference, fits, out: Path, fmt: str) -> dict:
    """Figs. 4, 5 and 10 as ``{name: src}``: PNG files beside a Markdown report, data URLs
    in an HTML one."""
    from ..plots.across import across_figures, save_figures

    fig_dir = out.parent / f"{out.stem}_figures"
    written = save_figures(across_figures(df, tables, reference=reference, fits=fits), fig_dir,
                           ("png",))
    if fmt != "html":
        return {p.stem: f"{fig_dir.name}/{p.name}" for p in written}
    srcs = {p.stem: "data:image/png;base64," + base64.b64encode(p.read_bytes()).decode()
            for p in written}
    for p in written:
        p.unlink()
    if not any(fig_dir.iterdir()):
        fig_dir.rmdir()
    return srcs
