"""The catalogue of a sweep: one row per run, regenerated from the run folders.

Layout of a sweep folder ``OUT`` (format ``shellbuckle-sweep``, version 1)::

    OUT/sweep.json             the sweep: format + version, every spec run in this folder (in
                               order), and ``runs``: {name: point} with the parameters of each
                               run (gamma, nu, seed, mesh, n_vertices, icosphere, dv, until,
                               c0_cycle, jiggle, bending, method, energy_convention, tol,
                               stop_at_contact)
    OUT/<name>/                one run folder per point (:mod:`shellbuckle.store.run`), named
                               from its parameters, e.g. ``g2333_nu0.333_v3594_s0``
    OUT/logs/<name>.json       the sweep's attempts at that run: start and end time, wall
                               time, host, pid, worker, outcome and message
    OUT/logs/<name>.traceback.txt   the traceback of the last failed attempt, if any
    OUT/catalogue.csv          the catalogue (columns below), replaced atomically

The run folders are the truth: status, steps, final dV/V, stop reason and thresholds of every
row are read from its run folder each time the catalogue is regenerated (:meth:`Catalogue.load`,
:meth:`Catalogue.write`), so the catalogue cannot disagree with them. ``logs/`` adds only what
a run folder cannot hold: the failure of a run that never got a folder (an invalid option for
that grid point), a worker that died, and the sweep's wall time per run.

Columns (:data:`COLUMNS`):

- ``name``, ``path`` (relative to ``OUT``), the parameters (from ``run.json`` where the run
  exists, else from ``sweep.json``): ``gamma``, ``nu``, ``seed``, ``mesh`` (``random`` or
  ``icosphere``), ``n_vertices``, ``icosphere`` (level), ``dv``, ``until``, ``c0_cycle``,
  ``jiggle``, ``temperature``, ``smooth_jiggle``, ``smooth_degree`` (the smooth imperfection),
  ``shape_imperfection``, ``shape_degree`` (the shell's own, in units of R; empty where
  unset), ``shape_imperfection_d`` (the amplitude in units of d the sweep gave, if it did),
  ``bending``, ``method``, ``energy_convention``;
- ``status``: the run's status (running, paused, finished, failed, interrupted; a run whose
  run.json says running while no process writes it was stopped outright and is listed as
  interrupted, :meth:`~shellbuckle.store.run.RunStore.current_status`), ``pending``
  for a run not started, ``failed`` for a run whose last attempt failed before its folder was
  written or whose worker died; ``message`` (the run's, and, where the last attempt's
  analysis or location of a finished run failed and that failure stands, the failure's);
  ``stop_reason`` (``self-intersection`` or
  ``end of schedule`` for a finished run);
- ``steps`` (last finished volume step; step 0 is the sphere), ``final_dV_over_V``;
- ``pressure_drop_dV_over_V``: dV/V at the first step whose pressure (the Lagrange multiplier of
  the volume constraint) falls below ``(1 - PRESSURE_DROP)`` times the previous step's, the
  snap-through of primary buckling seen from the table alone;
- ``primary_dV_over_V``, ``primary_source``: the primary buckling threshold, from the analysis
  events (:func:`shellbuckle.analysis.events`) when the run's steps are analysed
  (``primary_source = "analysis"``), else the pressure drop (``"pressure"``); ``primary_confirmed``;
- ``axisymmetry_loss_dV_over_V``, ``wrinkles_dV_over_V``: the paper's secondary thresholds
  (analysis events; empty without analysis);
- ``W_mean``, ``W_std``, ``W_steps``: number of wrinkles averaged over the analysed steps with
  dV/V in [0.53, 0.76] whose shape is ``wrinkled`` (the paper's Fig. 11 average; population
  standard deviation), and how many steps entered the average;
- ``final_shape``: the analysed shape of the last step;
- ``wall_s``: sum of the per-step wall times stored in the run (minimization and measurement
  over all sessions); ``task_wall_s``: total wall time of the sweep's attempts at the run
  (mesh building, setup, steps, writing, analysis) and ``task_cpu_s`` the CPU time of the
  worker process during them (well below ``task_wall_s``: the worker shared its core with other
  work), ``attempts``; ``traceback`` (relative path
  of the traceback file when the last attempt failed).
"""

from __future__ import annotations

import json
import logging
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

from ..util import now
from .atomic import atomic_write_bytes, set_aside
from .run import ANALYSIS_JSON, MESH_H5, RUN_JSON, STEPS_DIR, RunStore, check_format

log = logging.getLogger(__name__)

FORMAT_NAME = "shellbuckle-sweep"
FORMAT_VERSION = 1
from .names import CATALOGUE_CSV, LOCATED_JSON, LOGS_DIR, SWEEP_JSON  # noqa: E402, F401

#: Relative pressure drop between consecutive steps taken as the primary snap-through when the
#: analysis is not available (the same criterion confirms primary buckling in the analysis).
PRESSURE_DROP = 0.2
#: dV/V range over which W is averaged (Quilliet et al. 2008, Fig. 11).
W_RANGE = (0.53, 0.76)

PARAMETER_COLUMNS = ("gamma", "nu", "seed", "mesh", "n_vertices", "icosphere", "dv", "until",
                     "c0_cycle", "jiggle", "temperature", "smooth_jiggle", "smooth_degree",
                     "shape_imperfection", "shape_imperfection_d", "shape_degree", "bending",
                     "method",
                     "energy_convention")
RESULT_COLUMNS = ("status", "message", "stop_reason", "steps", "final_dV_over_V",
                  "pressure_drop_dV_over_V", "primary_dV_over_V", "primary_source",
                  "primary_confirmed", "axisymmetry_loss_dV_over_V", "wrinkles_dV_over_V",
                  "W_mean", "W_std", "W_steps", "final_shape")
TIME_COLUMNS = ("wall_s", "task_wall_s", "task_cpu_s", "attempts")
COLUMNS = ("name", *PARAMETER_COLUMNS, *RESULT_COLUMNS, *TIME_COLUMNS, "traceback", "path")
#: Columns that depend on the machine and on interruptions, not on the runs' results.
TIMING_COLUMNS = TIME_COLUMNS


def _write_json(path: Path, value) -> None:
    atomic_write_bytes(path, json.dumps(value, indent=1, allow_nan=True).encode("utf-8"))


def _read_json(path: Path):
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path} is not valid JSON ({exc})") from None
    except IsADirectoryError:
        raise ValueError(f"{path} is a folder; expected a JSON file") from None
    except PermissionError:
        raise ValueError(f"{path} cannot be read (permission denied)") from None


# --------------------------------------------------------------------------- sweep.json

def read_sweep_file(out_dir) -> dict:
    """The contents of ``OUT/sweep.json`` (ValueError if ``out_dir`` holds no sweep)."""
    out_dir = Path(out_dir)
    data = _read_json(out_dir / SWEEP_JSON)
    if data is None:
        raise ValueError(f"{out_dir} is not a shellbuckle sweep folder (it has no {SWEEP_JSON}; "
                         "made by `shellbuckle sweep --out DIR`)")
    data = check_format(data, out_dir / SWEEP_JSON, FORMAT_NAME, FORMAT_VERSION)
    runs, specs = data.get("runs"), data.get("specs")
    if not isinstance(runs, dict) or not all(isinstance(p, dict) for p in runs.values()) \
            or not isinstance(specs, list):
        raise ValueError(f"{out_dir / SWEEP_JSON} is damaged: it needs 'runs' (each run's "
                         "parameters by name) and 'specs' (a list)")
    return data


def check_sweep_folder(out_dir, runs: dict[str, dict]) -> dict | None:
    """The sweep ``out_dir`` holds (``None`` for a new or empty folder), after the refusals
    of :func:`write_sweep_file` (ValueError): a file, a non-empty folder that is no sweep, a
    run name of ``runs`` that stands for other parameters there. Writes nothing."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"{out_dir} is an existing file; a sweep needs a folder")
    if not (out_dir / SWEEP_JSON).exists():
        if out_dir.exists() and any(os.scandir(out_dir)):
            raise ValueError(f"{out_dir} is a non-empty folder that is not a shellbuckle sweep; "
                             "choose a new or empty folder with --out")
        return None
    data = read_sweep_file(out_dir)
    for name in sorted(set(data["runs"]) | set(runs)):
        if (out_dir / name).exists() and not (out_dir / name).is_dir():
            raise ValueError(f"{out_dir} has a file {name} where the sweep keeps that run's "
                             "folder; move it away (or restore the run folder)")
    runs = json.loads(json.dumps(runs))
    for name, point in runs.items():
        held = data["runs"].get(name)
        if held is not None and held != point:
            diff = sorted(k for k in set(held) | set(point) if held.get(k) != point.get(k))
            shown = ", ".join(f"{k}: stored {held.get(k)!r}, requested {point.get(k)!r}"
                              for k in diff)
            raise ValueError(f"{out_dir} already has a run {name!r} with other parameters "
                             f"({shown}); use another --out folder")
    return data


def write_sweep_file(out_dir, spec: dict, runs: dict[str, dict]) -> dict:
    """Record a sweep in ``OUT/sweep.json``; returns the merged contents.

    ``spec`` is the sweep's description (JSON), ``runs`` its points by run name. A folder that
    already holds a sweep keeps its runs and gains the new ones, so a sweep can be extended
    (more gammas, more seeds) in the same folder; a name that already stands for other
    parameters is refused (ValueError naming it), as is a non-empty folder that is no sweep
    (:func:`check_sweep_folder`).
    """
    out_dir = Path(out_dir)
    data = check_sweep_folder(out_dir, runs)
    runs = json.loads(json.dumps(runs))
    spec = json.loads(json.dumps(spec))
    if data is not None:
        if spec not in data["specs"]:
            data["specs"].append(spec)
        data["runs"].update(runs)
        data["updated"] = now()
    else:
        out_dir.mkdir(parents=True, exist_ok=True)
        data = {"format": FORMAT_NAME, "format_version": FORMAT_VERSION, "created": now(),
                "updated": now(), "specs": [spec], "runs": runs}
    _write_json(out_dir / SWEEP_JSON, data)
    return data


# --------------------------------------------------------------------------- attempt logs

def attempts_path(out_dir, name: str) -> Path:
    return Path(out_dir) / LOGS_DIR / f"{name}.json"


def traceback_path(out_dir, name: str) -> Path:
    return Path(out_dir) / LOGS_DIR / f"{name}.traceback.txt"


def _damaged_attempts(path: Path) -> tuple[list[dict], str | None]:
    """The attempts recorded in ``path`` and, if the file is damaged (not JSON, or not a
    list of attempt objects), what is wrong with it (the attempts then ``[]``)."""
    try:
        data = _read_json(path)
    except ValueError as exc:
        return [], str(exc)
    if data is None:
        return [], None
    attempts = data.get("attempts", []) if isinstance(data, dict) else None
    if not isinstance(attempts, list) or not all(isinstance(a, dict) for a in attempts):
        return [], f"{path} does not hold a list of attempts"
    return list(attempts), None


def read_attempts(out_dir, name: str) -> list[dict]:
    """The sweep's attempts at run ``name``, oldest first (empty list if none). A damaged log
    (it is written atomically: damaged from outside) counts as none, with a warning; the next
    attempt sets it aside (:func:`record_attempt`). The run's results do not depend on it."""
    attempts, damaged = _damaged_attempts(attempts_path(out_dir, name))
    if damaged:
        log.warning("%s; its attempts are not counted (the next attempt at run %s sets the "
                    "file aside)", damaged, name)
    return attempts


def record_attempt(out_dir, name: str, attempt: dict, *, replace_last: bool = False,
                   traceback: str | None = None, earlier=None) -> None:
    """Append ``attempt`` to ``logs/<name>.json`` (or replace the last one), atomically (a
    damaged log is first set aside as ``<name>.json.damaged-<n>``).

    ``traceback`` (text) is written to ``logs/<name>.traceback.txt``. ``earlier``: a function
    the attempts already logged are passed through first (to end those whose process was
    killed). One task works on a run at a time, so the read-modify-write needs no lock.
    """
    path = attempts_path(out_dir, name)
    path.parent.mkdir(parents=True, exist_ok=True)
    attempts, damaged = _damaged_attempts(path)
    if damaged:  # kept beside, never deleted, as a damaged step is
        log.warning("%s; set aside as %s, and a new log begun", damaged, set_aside(path).name)
    if earlier is not None:
        attempts = [earlier(a) for a in attempts]
    if replace_last and attempts:
        attempts[-1] = attempt
    else:
        attempts.append(attempt)
    _write_json(path, {"run": name, "attempts": attempts})
    if traceback is not None:
        atomic_write_bytes(traceback_path(out_dir, name), traceback.encode("utf-8"))


# --------------------------------------------------------------------------- one row

def analysis_complete(store: RunStore) -> bool:
    """True if every finished step of the run has its stored classification, made by the
    current classifier (:data:`shellbuckle.analysis.classify.ANALYSIS_VERSION`)."""
    from ..analysis.classify import is_current

    analysis = store.analysis()
    steps = store.steps
    return bool(steps) and all(is_current(analysis.get(k)) for k in steps)


def pressure_drop_dV_over_V(table: pd.DataFrame, drop: float = PRESSURE_DROP) -> float:
    """dV/V at the first step ``k`` with ``p_k < (1 - drop) p_(k-1)`` and ``p_(k-1) > 0``.

    Under volume control the pressure rises along the spherical branch and falls at the
    snap-through to the buckled branch (Quilliet et al. 2008, Fig. 9). NaN if it never drops.
    """
    p = table["pressure"].to_numpy(dtype=float)
    dv = table["dV_over_V"].to_numpy(dtype=float)
    prev, cur = p[:-1], p[1:]
    with np.errstate(invalid="ignore"):
        hit = np.flatnonzero((prev > 0) & (cur < (1.0 - drop) * prev))
    return float(dv[hit[0] + 1]) if len(hit) else math.nan


def stop_reason(status: str, message: str | None) -> str | None:
    """``self-intersection`` or ``end of schedule`` for a finished run, else None."""
    if status != "finished" or not message:
        return None
    if message.startswith("self-intersection"):
        return "self-intersection"
    if message.startswith("end of the schedule"):
        return "end of schedule"
    return message


def _analysis_columns(store: RunStore, table: pd.DataFrame) -> dict:
    """Thresholds, W average and last shape from the stored analysis; {} if not analysed
    (or analysed by another version of the classifier).

    Completeness is judged on ``table`` itself (one snapshot), not on a second read of the
    folder, which the worker may be writing meanwhile.
    """
    if "shape" not in table.columns or table["shape"].isna().any():
        return {}
    versions = table["analysis_version"] if "analysis_version" in table else None
    from ..analysis.classify import ANALYSIS_VERSION

    if versions is None or (versions != ANALYSIS_VERSION).any():
        return {}  # stored by another version of the classifier: stale
    try:
        from ..analysis import events
    except ImportError:  # pragma: no cover - analysis module absent
        return {}
    found = {}
    for e in events(store.path, table=table):
        found.setdefault(e.name, e)
    out = {"final_shape": str(table["shape"].iloc[-1])}
    primary = found.get("primary_buckling")
    if primary is not None:
        out.update(primary_dV_over_V=primary.dV_over_V, primary_source="analysis",
                   primary_confirmed=primary.confirmed)
    else:  # the analysis saw no buckling: the pressure drop stays in its own column
        out.update(primary_dV_over_V=math.nan, primary_source="analysis")
    for name in ("axisymmetry_loss", "wrinkles"):
        if name in found:
            out[f"{name}_dV_over_V"] = found[name].dV_over_V
    dv = table["dV_over_V"].to_numpy(dtype=float)
    chosen = (dv >= W_RANGE[0]) & (dv <= W_RANGE[1]) & (table["shape"].astype(str) == "wrinkled")
    W = table.loc[chosen.to_numpy(), "W"].to_numpy(dtype=float)
    out["W_steps"] = int(len(W))
    if len(W):
        out.update(W_mean=float(W.mean()), W_std=float(W.std()))
    return out


def _parameters(point: dict, meta: dict | None) -> dict:
    row = {k: point.get(k) for k in PARAMETER_COLUMNS}
    if meta is not None:  # the run folder is the truth where it exists
        params, protocol = meta.get("params", {}), meta.get("protocol", {})
        row.update(gamma=params.get("gamma"), nu=params.get("nu"),
                   energy_convention=params.get("energy_convention", "helfrich"))
        for key in ("seed", "c0_cycle", "jiggle", "temperature", "smooth_jiggle",
                    "smooth_degree", "shape_imperfection", "shape_degree", "bending", "method"):
            if key in protocol:
                row[key] = protocol[key]
        row["n_vertices"] = meta.get("mesh", {}).get("n_vertices", row["n_vertices"])
    return row


#: The outcomes of an attempt whose run finished but whose analysis or location then failed.
AFTER_RUN_FAILURES = ("analysis failed", "location failed")


def failure_stands(store: RunStore, last: dict) -> bool:
    """Whether the last attempt on a finished run failed in its analysis or location
    (``analysis failed``, ``location failed``) and that failure still stands: its steps are
    not all analysed, or its events not all located (:func:`shellbuckle.locate.pending`). A
    failure mended since (``shellbuckle analyze`` or ``locate``, outside the sweep) no longer
    stands."""
    outcome = last.get("outcome")
    if outcome not in AFTER_RUN_FAILURES or not last.get("message"):
        return False
    if outcome == "analysis failed":
        return not analysis_complete(store)
    from ..locate import pending

    try:
        return bool(pending(store.path))
    except Exception:  # what the location failed on, still there
        return True


def run_row(out_dir, name: str, point: dict) -> dict:
    """The catalogue row of run ``name`` (module docstring), read from its run folder."""
    out_dir = Path(out_dir)
    folder = out_dir / name
    attempts = read_attempts(out_dir, name)
    last = attempts[-1] if attempts else {}
    row = {c: None for c in COLUMNS}
    row.update(name=name, path=name, attempts=len(attempts),
               task_wall_s=float(sum(a.get("wall_s") or 0.0 for a in attempts)),
               task_cpu_s=float(sum(a.get("cpu_s") or 0.0 for a in attempts)))
    if last.get("outcome") in ("failed", *AFTER_RUN_FAILURES) and \
            traceback_path(out_dir, name).exists():
        row["traceback"] = str(Path(LOGS_DIR) / traceback_path(out_dir, name).name)
    meta = None
    if (folder / RUN_JSON).exists():
        try:
            store = RunStore.open(folder)
            meta = store.meta
            store.check_mesh()
            table = store.table()
        except ValueError as exc:
            row.update(_parameters(point, meta), status="failed", message=str(exc))
            return row
        status, message = store.current_status()  # a run killed outright: interrupted
        row.update(_parameters(point, meta), status=status, message=message)
        damaged = store.damaged  # left out of the table: say so where the sweep looks
        if damaged:
            note = ("damaged step(s) left out: "
                    + "; ".join(f"step {k}: {why}" for k, why in sorted(damaged.items())))
            row["message"] = f"{row['message']}; {note}" if row["message"] else note
        if last.get("outcome") == "failed" and meta["status"] not in ("finished", "failed"):
            # the worker died (or the task failed outside deflate) after the folder was made
            row.update(status="failed", message=last.get("message"))
        row["stop_reason"] = stop_reason(row["status"], row["message"])
        if failure_stands(store, last):
            # the run stands; what failed after it is said where the sweep looks
            row["message"] = "; ".join(m for m in (row["message"], last["message"]) if m)
        elif last.get("outcome") in AFTER_RUN_FAILURES:
            row["traceback"] = None  # mended since, outside the sweep
        if not table.empty:
            row.update(steps=int(table["step"].iloc[-1]),
                       final_dV_over_V=float(table["dV_over_V"].iloc[-1]),
                       wall_s=float(np.nansum(table["wall_s"].to_numpy(dtype=float))))
            drop = pressure_drop_dV_over_V(table)
            row.update(pressure_drop_dV_over_V=drop, primary_dV_over_V=drop,
                       primary_source="pressure")
            row.update(_analysis_columns(store, table))
        return row
    row.update(_parameters(point, None))
    if last.get("outcome") == "failed":
        row.update(status="failed", message=last.get("message"))
    else:
        row.update(status="pending", message=None)
    return row


def _signature(out_dir: Path, name: str):
    """What changes whenever a row can change: mtimes and sizes of the files it is read from."""
    folder = out_dir / name
    parts = []
    for path in (folder / RUN_JSON, folder / MESH_H5, folder / ANALYSIS_JSON,
                 folder / LOCATED_JSON, attempts_path(out_dir, name),
                 traceback_path(out_dir, name)):
        try:
            st = path.stat()
            parts.append((st.st_mtime_ns, st.st_size, st.st_ino))
        except FileNotFoundError:
            parts.append(None)
    try:
        steps = os.listdir(folder / STEPS_DIR)
        parts.append(len(steps))
    except FileNotFoundError:
        parts.append(None)
    return tuple(parts)


# --------------------------------------------------------------------------- the catalogue

class Catalogue:
    """The catalogue of the sweep folder ``out_dir`` (module docstring).

    ``Catalogue.load(out_dir)`` regenerates and returns it as a DataFrame;
    ``Catalogue(out_dir).write()`` also replaces ``catalogue.csv``. An object keeps the rows
    of runs whose files have not changed since it last read them, so a sweep refreshing the
    catalogue after every finished run reads only the runs that moved.
    """

    def __init__(self, out_dir):
        self.out_dir = Path(out_dir)
        self._rows: dict[str, tuple[tuple, dict]] = {}

    @classmethod
    def load(cls, out_dir) -> pd.DataFrame:
        """The catalogue regenerated from the run folders (nothing is written)."""
        return cls(out_dir).frame()

    def frame(self) -> pd.DataFrame:
        """One row per run of ``sweep.json``, in the order of ``sweep.json``."""
        runs = read_sweep_file(self.out_dir)["runs"]
        rows = []
        for name, point in runs.items():
            signature = _signature(self.out_dir, name)
            cached = self._rows.get(name)
            if cached is None or cached[0] != signature or cached[1]["status"] == "running":
                # (a live run is asked again: its process may have died since)
                cached = self._rows[name] = (signature, run_row(self.out_dir, name, point))
            rows.append(cached[1])
        return _typed(pd.DataFrame(rows, columns=list(COLUMNS)))

    def write(self) -> pd.DataFrame:
        """Regenerate the catalogue, replace ``catalogue.csv`` atomically, return it."""
        frame = self.frame()
        text = frame.to_csv(index=False, lineterminator="\n")
        atomic_write_bytes(self.out_dir / CATALOGUE_CSV, text.encode("utf-8"))
        return frame


_INT_COLUMNS = ("seed", "n_vertices", "icosphere", "steps", "W_steps", "attempts")
_FLOAT_COLUMNS = ("gamma", "nu", "dv", "until", "jiggle", "temperature", "final_dV_over_V",
                  "pressure_drop_dV_over_V", "primary_dV_over_V", "axisymmetry_loss_dV_over_V",
                  "wrinkles_dV_over_V", "W_mean", "W_std", "wall_s", "task_wall_s", "task_cpu_s")
_BOOL_COLUMNS = ("c0_cycle", "primary_confirmed")


def typed_columns(frame: pd.DataFrame, *, ints=(), floats=(), bools=()) -> pd.DataFrame:
    """Cast columns in place: ``floats`` to float64 (NaN where missing), ``ints`` and ``bools``
    to pandas' nullable ``Int64`` and ``boolean`` (``<NA>`` where None or NaN)."""
    for c in floats:
        frame[c] = pd.to_numeric(frame[c], errors="coerce").astype(np.float64)
    for c in ints:
        frame[c] = pd.array([None if v is None or v != v else int(v) for v in frame[c]],
                            dtype="Int64")
    for c in bools:
        frame[c] = pd.array([None if v is None or v != v else bool(v) for v in frame[c]],
                            dtype="boolean")
    return frame


def _typed(frame: pd.DataFrame) -> pd.DataFrame:
    typed_columns(frame, ints=_INT_COLUMNS, floats=_FLOAT_COLUMNS, bools=_BOOL_COLUMNS)
    for c in COLUMNS:
        if c not in _INT_COLUMNS + _FLOAT_COLUMNS + _BOOL_COLUMNS:
            frame[c] = frame[c].astype(object).where(frame[c].notna(), None)
    return frame
