"""Across runs: one table of many run folders, the threshold power laws, the paper's numbers.

- :func:`collect_runs` (paths) -> pandas DataFrame, one row per run folder (run folders, sweep
  folders with a ``sweep.json``, or folders holding run folders), read from the stores: the
  parameters and protocol, status, stop, the buckling thresholds of
  :func:`shellbuckle.analysis.events` and the W average of
  :func:`shellbuckle.analysis.fits.wrinkle_average`. Steps without stored analysis are
  classified on the fly (nothing is written unless ``store_analysis=True``); no simulation is
  ever re-run.
- :func:`threshold_points` / :func:`threshold_fits`: per-gamma averages of the thresholds and
  the power laws of the paper's Fig. 10 fitted to them.
- :func:`wrinkles_by_gamma`: W pooled over the runs at each gamma (the paper's Fig. 5).
- :func:`load_reference`: the paper's numbers (``reference/quilliet2008.json``).
"""

from __future__ import annotations

import json
import logging
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

from ..store.catalogue import typed_columns
from .fits import W_WINDOW, fit_power_law, wrinkle_average

log = logging.getLogger(__name__)

#: Columns of :func:`collect_runs`, in order.
COLUMNS = ("path", "name", "parent", "gamma", "nu", "energy_convention", "seed", "n_vertices",
           "mesh", "jiggle",
           "temperature", "smooth_jiggle", "smooth_degree", "shape_imperfection", "shape_degree",
           "c0_cycle", "method", "bending", "control", "dv", "until", "status",
           "message", "n_steps", "stop_dV_over_V", "stop_reason", "primary_dV_over_V",
           "primary_confirmed", "axisymmetry_loss_dV_over_V", "wrinkles_dV_over_V",
           "primary_resolution", "axisymmetry_loss_resolution", "wrinkles_resolution",
           "located", "primary_located", "axisymmetry_loss_located", "wrinkles_located",
           "W_mean", "W_std", "W_steps", "final_shape", "analysis",
           "converged_fraction", "wall_s")
#: Runs whose minimizations converged at fewer steps than this are quenches, not deflations.
MIN_CONVERGED_FRACTION = 0.5
#: The thresholds of Fig. 10 (column ``<name>_dV_over_V``).
THRESHOLDS = ("primary", "axisymmetry_loss", "wrinkles")
#: Environment variable naming the reference JSON (else it is searched, :func:`load_reference`).
REFERENCE_ENV = "SHELLBUCKLE_REFERENCE"
REFERENCE_NAME = "quilliet2008.json"


# --------------------------------------------------------------------------- finding runs

def _missing_runs(path: Path, missing: list[str], total: int) -> None:
    """Say which runs of the sweep ``path`` have no run folder: a warning naming those the
    catalogue lists with a status (they had started: their folder was moved, deleted or
    replaced) or whose name is a file, an info line for the others (pending, or failed before
    starting)."""
    import csv

    from ..store.catalogue import CATALOGUE_CSV

    statuses = {}
    try:
        with open(path / CATALOGUE_CSV, newline="", encoding="utf-8") as f:
            statuses = {row.get("name"): row.get("status") for row in csv.DictReader(f)}
    except (OSError, UnicodeDecodeError, csv.Error):
        pass
    # (a failed run may have failed before its folder was made: not counted as lost)
    lost = [n for n in missing if (path / n).is_file() or statuses.get(n) in
            ("finished", "paused", "interrupted", "running")]
    if lost:
        log.warning("%s: %d run(s) of the sweep have no readable run folder although they had "
                    "started (moved, deleted or damaged), left out: %s", path, len(lost),
                    ", ".join(lost))
    if len(lost) < len(missing):
        log.info("%s: %d of %d runs of the sweep have no run folder yet (pending or failed "
                 "before starting); skipped", path, len(missing) - len(lost), total)


def _run_folders(path: Path, warn: bool = True) -> list[Path]:
    """The run folders a path stands for: itself, the runs of a sweep, or the run and sweep
    folders directly inside it (ValueError if none). ``warn``: name the runs of a sweep that
    have no run folder."""
    from ..store.catalogue import SWEEP_JSON, read_sweep_file
    from ..store.run import RUN_JSON

    if not path.exists():
        raise ValueError(f"{str(path)!r} does not exist (expected a run folder or a sweep folder)")
    if not path.is_dir():
        raise ValueError(f"{str(path)!r} is a file; expected a run folder (with {RUN_JSON}) or a "
                         f"sweep folder (with {SWEEP_JSON})")
    if (path / RUN_JSON).exists():
        return [path]
    if (path / SWEEP_JSON).exists():
        names = list(read_sweep_file(path)["runs"])
        found = [path / n for n in names if (path / n / RUN_JSON).exists()]
        if len(found) < len(names) and warn:
            _missing_runs(path, [n for n in names if not (path / n / RUN_JSON).exists()],
                          len(names))
        return found
    found = []
    for sub in sorted(p for p in path.iterdir() if p.is_dir()):
        if (sub / RUN_JSON).exists():
            found.append(sub)
        elif (sub / SWEEP_JSON).exists():
            found += _run_folders(sub, warn)
    if not found:
        raise ValueError(f"{str(path)!r} is neither a run folder (no {RUN_JSON}) nor a sweep "
                         f"folder (no {SWEEP_JSON}) nor a folder of run folders")
    return found


def check_folder(option: str, path) -> None:
    """ValueError naming ``option`` and ``path`` unless ``path`` is a run folder, a sweep
    folder or a folder of them (what :func:`run_folders` reads)."""
    try:
        _run_folders(Path(path), warn=False)
    except ValueError as exc:
        message = str(exc)
        quoted = f"{str(path)!r} "
        message = message[len(quoted):] if message.startswith(quoted) else message
        raise ValueError(f"{option} {path}: {message}") from None


def run_folders(paths) -> list[Path]:
    """Every run folder named by ``paths`` (one path or a list), each once, in order."""
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    paths = list(paths)
    if not paths:
        raise ValueError("no run folder given")
    out, seen = [], set()
    for p in paths:
        for folder in _run_folders(Path(p)):
            key = folder.resolve()
            if key not in seen:
                seen.add(key)
                out.append(folder)
    return out


# --------------------------------------------------------------------------- one run

def analysed_table(run, *, store: bool = False) -> tuple[pd.DataFrame, str]:
    """The run's table with the analysis columns for every step, and where they came from
    (``"stored"``, ``"computed"``: classified now, or ``"stored now"`` with ``store=True``,
    which writes them with :func:`shellbuckle.analysis.analyze_run`). A step analysed by
    another version of the classifier counts as not analysed."""
    from .classify import analyze_run, classify_run, is_current

    table = run.table
    if table.empty:
        return table, "none"
    stored = run.store.analysis()
    # absent, or stored by another version of the classifier: classified again
    missing = [int(k) for k in table["step"] if not is_current(stored.get(int(k)))]
    if not missing:
        return table, "stored"
    if store:
        return analyze_run(run, steps=missing), "stored now"
    results = classify_run(run, steps=missing)
    table = table.copy()
    first = next(iter(results.values()))
    for name in first.columns():
        if name not in table.columns:
            table[name] = None
        table[name] = table[name].astype(object)
    for k, c in results.items():
        row = table.index[table["step"] == k]
        for name, value in c.columns().items():
            table.loc[row, name] = value
    for name in ("n_dimples", "corners", "W", "rim_mode", "concave_arcs"):
        if name in table.columns:
            table[name] = pd.to_numeric(table[name]).astype("Int64")
    return table, "computed"


def mesh_kind(faces: np.ndarray, n_vertices: int) -> str:
    """``icosphere(n)`` when the triangulation is a subdivided icosahedron (``10 n^2 + 2``
    vertices, 12 of valence 5 and the others of valence 6), else ``random``."""
    valence = np.bincount(np.asarray(faces).ravel(), minlength=n_vertices)
    n = round(math.sqrt(max(n_vertices - 2, 0) / 10.0))
    if 10 * n * n + 2 == n_vertices and (valence == 5).sum() == 12 \
            and (valence == 6).sum() == n_vertices - 12:
        return f"icosphere({n})"
    return "random"


def _schedule_numbers(protocol: dict) -> tuple[float, float]:
    schedule = np.asarray(protocol.get("schedule", []) or [], dtype=float)
    if protocol.get("control", "volume") != "volume" or len(schedule) == 0:
        return math.nan, math.nan
    steps = np.diff(np.concatenate([[0.0], schedule]))
    return float(np.median(np.abs(steps))), float(schedule[-1])


def collect_run(folder, *, store_analysis: bool = False,
                located: bool = True) -> tuple[dict, pd.DataFrame]:
    """The :func:`collect_runs` row of one run folder, and its analysed table."""
    from ..run import Run
    from ..store.catalogue import stop_reason
    from .events import events

    run = Run.open(folder)
    meta = run.store.meta
    params, protocol = meta.get("params", {}), meta.get("protocol", {})
    table, source = analysed_table(run, store=store_analysis)
    dv, until = _schedule_numbers(protocol)
    status, message = run.store.current_status()  # a run killed outright: interrupted
    parent = meta.get("parent")
    row = dict.fromkeys(COLUMNS)
    row.update(path=str(Path(folder).resolve()), name=Path(folder).resolve().name,
               parent=None if not parent else str(parent.get("path", parent)),
               gamma=params.get("gamma"), nu=params.get("nu"),
               energy_convention=params.get("energy_convention", "helfrich"),
               seed=protocol.get("seed"),
               n_vertices=run.store.n_vertices, mesh=mesh_kind(run.faces, run.store.n_vertices),
               jiggle=protocol.get("jiggle"), temperature=protocol.get("temperature"),
               smooth_jiggle=protocol.get("smooth_jiggle"),
               smooth_degree=protocol.get("smooth_degree"),
               shape_imperfection=protocol.get("shape_imperfection"),
               shape_degree=protocol.get("shape_degree"),
               c0_cycle=protocol.get("c0_cycle"), method=protocol.get("method"),
               bending=protocol.get("bending"), control=protocol.get("control", "volume"),
               dv=dv, until=until, status=status, message=message,
               stop_reason=stop_reason(status, message),
               analysis=source, W_steps=0)
    if table.empty:
        return row, table
    if protocol.get("control") == "gamma" and "gamma" in table:  # a path: the gamma reached
        row["gamma"] = float(table["gamma"].iloc[-1])
    if "converged" in table:  # steps whose minimizations converged (a quench: none)
        row["converged_fraction"] = float(table["converged"].fillna(True).astype(bool).mean())
    row.update(n_steps=int(table["step"].iloc[-1]),
               stop_dV_over_V=float(table["dV_over_V"].iloc[-1]),
               final_shape=str(table["shape"].iloc[-1]),
               wall_s=float(np.nansum(table["wall_s"].to_numpy(dtype=float))))
    found = {}
    for e in events(run, table=table, located=located):
        found.setdefault(e.name, e)
    if "primary_buckling" in found:
        row.update(primary_dV_over_V=found["primary_buckling"].dV_over_V,
                   primary_confirmed=found["primary_buckling"].confirmed,
                   primary_resolution=found["primary_buckling"].resolution)
    for name in ("axisymmetry_loss", "wrinkles"):
        if name in found:
            row[f"{name}_dV_over_V"] = found[name].dV_over_V
            row[f"{name}_resolution"] = found[name].resolution
    thresholds = [e for e in found.values() if e.name != "inertia_change"]
    row["located"] = bool(thresholds) and all(e.located for e in thresholds)
    for name in ("primary_buckling", "axisymmetry_loss", "wrinkles"):
        row[f"{name.removesuffix('_buckling')}_located"] = name in found and found[name].located
    avg = wrinkle_average(table, W_WINDOW)
    row.update(W_mean=avg.mean, W_std=avg.std, W_steps=avg.n)
    return row, table


_FLOATS = ("gamma", "nu", "jiggle", "temperature", "smooth_jiggle", "shape_imperfection", "dv",
           "until", "stop_dV_over_V",
           "primary_dV_over_V", "axisymmetry_loss_dV_over_V", "wrinkles_dV_over_V",
           "primary_resolution", "axisymmetry_loss_resolution", "wrinkles_resolution",
           "W_mean", "W_std", "converged_fraction", "wall_s")
_INTS = ("seed", "n_vertices", "n_steps", "W_steps", "smooth_degree", "shape_degree")
_BOOLS = ("c0_cycle", "primary_confirmed", "located", "primary_located",
          "axisymmetry_loss_located", "wrinkles_located")


def _typed(frame: pd.DataFrame) -> pd.DataFrame:
    return typed_columns(frame, ints=_INTS, floats=_FLOATS, bools=_BOOLS)


def collect_runs(paths, *, store_analysis: bool = False, tables: dict | None = None,
                 progress: bool = False, located: bool = True) -> pd.DataFrame:
    """One row per run folder (columns :data:`COLUMNS`).

    ``paths``: run folders, sweep folders (the runs of their ``sweep.json`` that have a
    folder), or folders whose sub-folders are runs or sweeps; each run appears once. Per row: ``path``
    (absolute), ``name``, ``parent`` (the run it branches from), the parameters ``gamma``,
    ``nu`` and protocol fields ``seed``, ``jiggle``, ``temperature``, ``smooth_jiggle`` and
    ``smooth_degree`` (the smooth imperfection; missing for Surface Evolver's jiggle),
    ``shape_imperfection`` and ``shape_degree`` (the shell's own imperfection; missing for a
    spherical shell),
    ``c0_cycle``,
    ``method``, ``bending``, ``control``, ``dv`` (volume step, the median of the schedule's
    increments), ``until`` (last target); ``n_vertices``, ``mesh`` (:func:`mesh_kind`);
    ``status``, ``message``, ``n_steps`` (last finished step), ``stop_dV_over_V`` (dV/V of the
    last step), ``stop_reason`` (``self-intersection``, ``end of schedule`` or None); the
    thresholds ``primary_dV_over_V`` (with ``primary_confirmed``),
    ``axisymmetry_loss_dV_over_V``, ``wrinkles_dV_over_V`` (NaN where the event did not
    happen; the located values where the run has them, :mod:`shellbuckle.locate`, unless
    ``located`` is False), each with its ``<name>_resolution`` (the width in dV/V of the
    interval it lies in: the volume step, or the located bracket) and ``<name>_located``
    (``primary_located``, ...: located by bisection; False where the event did not happen),
    and ``located`` (every threshold of the run located); ``W_mean``, ``W_std``, ``W_steps`` over the wrinkled steps with dV/V in
    [0.53, 0.76]; ``final_shape``; ``analysis`` (``stored``, ``computed``, ``stored now``);
    ``wall_s`` (sum of the step wall times).

    ``tables``: a dict that receives ``{path: analysed table}`` (to plot without reading the
    runs again). ValueError for a path that is not a run or sweep folder.
    """
    folders = run_folders(paths)
    iterator = folders
    if progress:
        from tqdm.auto import tqdm

        iterator = tqdm(folders, unit="run", desc="collect", dynamic_ncols=True)
    rows = []
    for folder in iterator:
        row, table = collect_run(folder, store_analysis=store_analysis, located=located)
        rows.append(row)
        if tables is not None:
            tables[row["path"]] = table
    return _typed(pd.DataFrame(rows, columns=list(COLUMNS)))


# --------------------------------------------------------------------------- aggregation

def deflation_runs(df: pd.DataFrame) -> pd.DataFrame:
    """The runs that follow the paper's deflation protocol: volume control, the
    zero-curvature cycle on, not branched from another run, at least one step, and
    minimizations converged at :data:`MIN_CONVERGED_FRACTION` of the steps or more (a quenched
    run, e.g. the Fig. 3 pair, converges at none and has no equilibrium thresholds; a rare
    step that stopped at the iteration limit does not disqualify a run)."""
    keep = (df["control"].fillna("volume") == "volume") & df["parent"].isna()
    if "converged_fraction" in df:
        keep &= df["converged_fraction"].fillna(1.0).to_numpy(float) >= MIN_CONVERGED_FRACTION
    keep &= df["c0_cycle"].fillna(True).astype(bool)
    keep &= df["n_steps"].fillna(0).astype(int) > 0
    return df[keep.to_numpy()]


def convention_of(df: pd.DataFrame) -> str:
    """The most common energy convention of the runs (helfrich without runs or column)."""
    if "energy_convention" not in df or not df["energy_convention"].notna().any():
        return "helfrich"
    return str(df["energy_convention"].fillna("helfrich").value_counts().idxmax())


def _one_nu(df: pd.DataFrame, nu) -> pd.DataFrame:
    """The runs at one nu and one energy convention (the most common ones, with a warning when
    several are present): a fit across conventions would mix different shells."""
    if "energy_convention" in df and len(df):
        conventions = df["energy_convention"].fillna("helfrich")
        if conventions.nunique() > 1:
            chosen = convention_of(df)
            log.warning("runs under several energy conventions (%s): using those under %s only",
                        ", ".join(sorted(conventions.unique())), chosen)
            df = df[(conventions == chosen).to_numpy()]
    if nu is not None:
        return df[np.isclose(df["nu"].to_numpy(float), float(nu), rtol=1e-6)]
    values = df["nu"].round(6)
    if values.nunique() > 1:
        chosen = values.value_counts().idxmax()
        log.warning("runs at several nu (%s): fitting those at nu = %g only (pass nu=...)",
                    ", ".join(f"{v:g}" for v in sorted(values.unique())), chosen)
        return df[(values == chosen).to_numpy()]
    return df


def _gamma_key(gamma: pd.Series) -> pd.Series:
    return gamma.map(lambda g: float(f"{g:.6g}"))


def threshold_points(df: pd.DataFrame, name: str, *, nu=None) -> pd.DataFrame:
    """Per-gamma statistics of the threshold ``name`` (one of :data:`THRESHOLDS`) over the
    deflation runs (:func:`deflation_runs`) where it happened: columns ``gamma``, ``mean``,
    ``std`` (sample standard deviation over runs, NaN for one run), ``n`` (runs), ``dv``
    (median volume step), ``resolution`` (median width of the intervals the thresholds lie
    in: the volume step, or the bracket of a located threshold) and ``sigma``:
    ``max(std, resolution/sqrt(12))``, the scatter floored at that resolution (uniform within
    the interval)."""
    if name not in THRESHOLDS:
        raise ValueError(f"threshold must be one of {', '.join(THRESHOLDS)}, got {name!r}")
    runs = _one_nu(deflation_runs(df), nu)
    column = f"{name}_dV_over_V"
    runs = runs[np.isfinite(runs[column].to_numpy(float))]
    rows = []
    for gamma, group in runs.groupby(_gamma_key(runs["gamma"]), sort=True):
        values = group[column].to_numpy(float)
        std = float(values.std(ddof=1)) if len(values) > 1 else math.nan
        dv = float(np.nanmedian(group["dv"].to_numpy(float))) if group["dv"].notna().any() \
            else math.nan
        resolution = dv
        widths = group.get(f"{name}_resolution")
        if widths is not None and widths.notna().any():
            resolution = float(np.nanmedian(widths.to_numpy(float)))
        floor = resolution / math.sqrt(12.0) if math.isfinite(resolution) else 0.0
        rows.append({"gamma": float(gamma), "mean": float(values.mean()), "std": std,
                     "n": len(values), "dv": dv, "resolution": resolution,
                     "sigma": max(std, floor) if math.isfinite(std) else math.nan})
    return pd.DataFrame(rows, columns=["gamma", "mean", "std", "n", "dv", "resolution",
                                       "sigma"])


def _sigma(points: pd.DataFrame):
    """The per-point sigma when every gamma has several runs (and a positive sigma)."""
    s = points["sigma"].to_numpy(float)
    if len(s) and (points["n"] >= 2).all() and np.isfinite(s).all() and (s > 0).all():
        return s
    return None


def threshold_fits(df: pd.DataFrame, *, nu=None, bootstrap: int = 0) -> dict:
    """Power laws of the thresholds vs gamma (the paper's Fig. 10), fitted to the per-gamma
    means of :func:`threshold_points`.

    Keys (present only when the runs allow the fit; the log says why one is missing):
    ``primary`` (free exponent; paper 2.8 gamma^-0.55), ``primary_theory`` (exponent fixed at
    the theory's -3/5), ``secondary`` (exponent fixed at -1 on the loss-of-axisymmetry and
    wrinkle points together; paper 850/gamma), ``secondary_free`` (same points, free exponent),
    ``axisymmetry_loss`` and ``wrinkles`` (exponent -1, each alone). The means are weighted by
    their ``sigma`` when every gamma has several runs, else fitted unweighted (errors from the
    residual scatter). A free exponent needs two gammas, a fixed one one gamma.
    """
    points = {n: threshold_points(df, n, nu=nu) for n in THRESHOLDS}
    fits = {}

    def attempt(key, pts, exponent):
        need = 1 if exponent is not None else 2
        if len(pts) < need:
            log.info("fit %s skipped: it needs thresholds at %d gamma value(s), the runs give "
                     "%d", key, need, len(pts))
            return
        fits[key] = fit_power_law(pts["gamma"], pts["mean"], sigma=_sigma(pts),
                                  exponent=exponent, bootstrap=bootstrap)

    attempt("primary", points["primary"], None)
    attempt("primary_theory", points["primary"], -0.6)
    secondary = pd.concat([points["axisymmetry_loss"], points["wrinkles"]], ignore_index=True)
    attempt("secondary", secondary, -1.0)
    if secondary["gamma"].nunique() >= 2:
        attempt("secondary_free", secondary, None)
    else:
        log.info("fit secondary_free skipped: it needs secondary thresholds at 2 gamma values, "
                 "the runs give %d", secondary["gamma"].nunique())
    attempt("axisymmetry_loss", points["axisymmetry_loss"], -1.0)
    attempt("wrinkles", points["wrinkles"], -1.0)
    return fits


def wrinkles_by_gamma(df: pd.DataFrame, *, nu=None) -> pd.DataFrame:
    """W pooled over the deflation runs at each gamma: columns ``gamma``, ``W_mean``,
    ``W_std`` (population standard deviation of all the pooled steps, as in the paper's
    Fig. 5 error bars), ``W_steps`` and ``runs`` (runs contributing steps). Exact pooling of
    the per-run means ``m_i``, stds ``s_i`` and counts ``n_i``:
    ``M = sum n_i m_i / N``, ``S^2 = sum n_i (s_i^2 + m_i^2) / N - M^2``."""
    runs = _one_nu(deflation_runs(df), nu)
    runs = runs[runs["W_steps"].fillna(0).astype(int).to_numpy() > 0]
    rows = []
    for gamma, group in runs.groupby(_gamma_key(runs["gamma"]), sort=True):
        n = group["W_steps"].to_numpy(float)
        m = group["W_mean"].to_numpy(float)
        s = group["W_std"].to_numpy(float)
        N = n.sum()
        M = float((n * m).sum() / N)
        var = float((n * (s ** 2 + m ** 2)).sum() / N - M ** 2)
        rows.append({"gamma": float(gamma), "W_mean": M, "W_std": math.sqrt(max(var, 0.0)),
                     "W_steps": int(N), "runs": len(group)})
    return pd.DataFrame(rows, columns=["gamma", "W_mean", "W_std", "W_steps", "runs"])


# --------------------------------------------------------------------------- the paper

def reference_path(path=None) -> Path:
    """Where the paper's numbers are: ``path`` if given, else ``$SHELLBUCKLE_REFERENCE``, else
    the copy shipped with the package (``shellbuckle/data/quilliet2008.json``, the numbers of
    Quilliet et al. 2008 as the reproduction compares them). ValueError if a given file does
    not exist."""
    if path is not None:
        p = Path(path)
        if not p.is_file():
            raise ValueError(f"reference file {str(p)!r} does not exist")
        return p
    env = os.environ.get(REFERENCE_ENV)
    if env:
        return reference_path(env)
    shipped = Path(__file__).resolve().parents[1] / "data" / REFERENCE_NAME
    if shipped.is_file():
        return shipped
    raise ValueError(f"the paper's reference numbers ({REFERENCE_NAME}) are missing from the "
                     f"installed package; give the file with --reference FILE or "
                     f"${REFERENCE_ENV}")


def load_reference(path=None, *, required: bool = True) -> dict | None:
    """The paper's numbers as a dict: ``path`` itself when it is one (a reference already
    read), else the file :func:`reference_path` finds. ValueError if a given file is not the
    reference, or if none is found and ``required``; without ``required`` a missing default
    is logged and None returned (the figures then show our values only)."""
    if isinstance(path, dict):
        return path
    try:
        p = reference_path(path)
    except ValueError as exc:
        if required or path is not None:
            raise
        log.warning("%s; the paper's values are not drawn", exc)
        return None
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{p} is not valid JSON ({exc})") from None
    if not isinstance(data, dict) or "results" not in data:
        raise ValueError(f"{p} does not hold the paper's reference numbers (no 'results')")
    return data
