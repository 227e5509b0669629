"""Durable run store: one self-describing folder per run that never loses a finished step.

Layout of a run folder ``DIR`` (format ``shellbuckle-run``, version 1)::

    DIR/run.json              what the run is: format + version, run id, creation time,
                              parameters, protocol, mesh size and hash, package and
                              dependency versions, platform, command line of every session,
                              status (running / paused / finished / failed / interrupted)
                              + message,
                              parent run and step for a branch (a path in gamma or c0:
                              protocol control "gamma"/"c0", the schedule of values and
                              fixed_dV_over_V, the volume held)
    DIR/mesh.h5               reference mesh, written once: X0 (V, 3) float64 initial
                              positions, faces (F, 3) int64, group rest/ with the rest-state
                              arrays if any; attribute run_json, a copy of run.json as created
                              (from which a lost run.json is rebuilt)
    DIR/steps/step_000123.h5  one file per finished step: X (V, 3) float64 positions; the step
                              record as attributes (one per column, and all of it exactly as
                              JSON in the attribute record_json); group arrays/ with optional
                              extra arrays; attribute sha256, the checksums of its content as
                              JSON: {"X": array_sha256(("X", X)), "record_json": SHA-256 of
                              the attribute's UTF-8 bytes, "arrays/<name>":
                              array_sha256((name, array))}
    DIR/steps/step_000123.h5.damaged-1
                              a damaged last step set aside by a resume (never deleted)
    DIR/analysis.json         analysis columns per step (shape, n_dimples, corners, W, ...)
                              {"<step>": {column: value}}, written by the analysis
    DIR/table.csv             the per-step table (SPEC §7 header), regenerated after every
                              step; a convenience copy, the step files are the truth

Guarantees and how they are kept:

- *A finished step is never lost or corrupted.* Every file is written whole to a temporary in
  the same folder, fsynced, then renamed over its name with ``os.replace`` and the folder is
  fsynced (:mod:`shellbuckle.store.atomic`). A kill at any moment (Ctrl-C, ``kill -9``, power
  cut) leaves the old complete file or the new complete one; step files are only ever added,
  in order, so the steps present are always ``0..k``. Stale temporaries are ignored by readers
  and removed by the next writer.
- *A damaged step is named, never read as good.* A step file can still be damaged after it was
  written (a disk fault, a copy cut short, a hand edit): empty, truncated, junk, a broken
  record, positions whose bytes changed. Every step file is checked when it is read — it opens
  as HDF5, its record parses and names its step, its positions have the run's shape and its
  content matches its checksums (step files written before the checksums were introduced are
  read unchecked) — and a damaged one is left out of :attr:`RunStore.steps` and the table and
  listed with what is wrong in :attr:`RunStore.damaged`; the good steps stay readable. Resuming
  sets damaged last steps aside (``step_....h5.damaged-<n>``) and computes them again; a
  damaged step followed by good ones stops the resume with the step to continue from.
- *A lost run.json is rebuilt* from the copy in ``mesh.h5`` (the status and later sessions are
  lost; resuming writes run.json again). A run.json that lacks fields, and a run without its
  ``steps/`` folder, are refused with a message saying what to do.
- *One writer per run.* Writing takes an exclusive ``flock`` on ``DIR/.lock`` for as long as
  the store is open for writing; the kernel releases it when the process dies, so ``shellbuckle
  resume DIR`` after a crash just works, while a second live writer is refused. Analysis writes
  use their own lock (``DIR/.analysis.lock``) so a run can be analysed while it is computing.
- *A folder never receives a different run.* :meth:`RunStore.create` compares the identity
  (parameters, protocol, SHA-256 of the mesh arrays, parent for a branch) with what the folder
  holds: the same run is reopened for resuming, a different one is refused with the
  differences, and a non-empty folder that is no run is refused.
- *Readable without shellbuckle*, with json, h5py and (for the table) pandas::

    import glob, json, os, h5py, pandas as pd
    run = json.load(open(os.path.join(DIR, "run.json")))     # parameters, protocol, versions
    with h5py.File(os.path.join(DIR, "mesh.h5"), "r") as f:
        X0, faces = f["X0"][()], f["faces"][()]               # (V, 3) float64, (F, 3) int64
    X, records = [], []
    for name in sorted(glob.glob(os.path.join(DIR, "steps", "step_*.h5"))):
        with h5py.File(name, "r") as f:
            X.append(f["X"][()])                               # positions of that step
            records.append(json.loads(f.attrs["record_json"]))
    table = pd.DataFrame(records)                # or pd.read_csv(os.path.join(DIR, "table.csv"))

JSON values may contain ``NaN`` (Python's json reads and writes it). Step 0 is the initial
state: the stress-free sphere for a new run, the parent's step for a branch.
"""

from __future__ import annotations

import copy
import csv
import functools
import hashlib
import io
import json
import logging
import math
import operator
import os
import platform
import subprocess
import sys
import uuid
from collections.abc import Mapping
from pathlib import Path

import h5py
import numpy as np
import pandas as pd

from ..util import now
from .atomic import (FileLock, atomic_write_bytes, fsync_folder, remove_temporaries,
                     temporary_target)

log = logging.getLogger(__name__)

FORMAT_NAME = "shellbuckle-run"
FORMAT_VERSION = 1

#: Per-step table columns of SPEC §7, in this order, always present (NaN where not recorded).
TABLE_COLUMNS = ("step", "target_dV_over_V", "dV_over_V", "E_total", "E_bend", "E_stretch",
                 "E_over_kappa", "E_before_c0_cycle", "pressure", "grad_norm", "iterations",
                 "inertia", "min_distance", "wall_s")
#: Analysis columns of SPEC §7, placed after TABLE_COLUMNS when any step has them.
ANALYSIS_COLUMNS = ("shape", "n_dimples", "corners", "W")
STATUSES = ("running", "paused", "finished", "failed", "interrupted")

RUN_JSON, MESH_H5, STEPS_DIR = "run.json", "mesh.h5", "steps"
TABLE_CSV, ANALYSIS_JSON = "table.csv", "analysis.json"
WRITER_LOCK, ANALYSIS_LOCK = ".lock", ".analysis.lock"
_WRITER_FILES = {RUN_JSON, MESH_H5, TABLE_CSV}
_INTEGER_COLUMNS = {"step", "iterations", "inertia", "n_dimples", "corners", "W"}
#: Attribute of a step file holding the checksums of its content (JSON), and of mesh.h5
#: holding a copy of run.json as created.
CHECKSUM_ATTR, DESCRIPTION_ATTR = "sha256", "run_json"
#: Fields every run.json has (all written since format version 1), and those of its "mesh".
REQUIRED_FIELDS = {"run_id": str, "params": dict, "protocol": dict, "mesh": dict,
                   "status": str, "sessions": list}
REQUIRED_MESH_FIELDS = {"n_vertices": int, "sha256": str}
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


# --------------------------------------------------------------------------- JSON values

def _jsonable(value, where: str):
    """``value`` as plain JSON types (numpy scalars/arrays converted); ValueError otherwise."""
    if isinstance(value, Mapping):
        out = {}
        for key, item in value.items():
            if not isinstance(key, str):
                raise ValueError(f"{where}: key {key!r} must be a string")
            out[key] = _jsonable(item, f"{where}.{key}")
        return out
    if isinstance(value, (list, tuple)):
        return [_jsonable(item, f"{where}[{i}]") for i, item in enumerate(value)]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist(), where)
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise ValueError(f"{where} = {value!r} cannot be stored (allowed: numbers, strings, "
                     "booleans, None, and lists or dicts of these)")


def _json_dict(value, where: str) -> dict:
    if not isinstance(value, Mapping):
        raise ValueError(f"{where} must be a dict, got {type(value).__name__}")
    return json.loads(json.dumps(_jsonable(value, where)))  # tuples -> lists, canonical


def _scalar_dict(values, where: str, reserved=()) -> dict:
    """A flat dict of JSON scalars (a step record or analysis results)."""
    out = _json_dict(values, where)
    for key, item in out.items():
        if isinstance(item, (list, dict)):
            raise ValueError(f"{where}.{key} must be a number, string, boolean or None, got "
                             f"{type(item).__name__}; store arrays with arrays=...")
        if key in reserved:
            raise ValueError(f"{where}.{key}: the name {key!r} is reserved")
    return out


def _differences(stored, wanted, where: str = "") -> list[str]:
    """Human-readable list of the paths where two JSON values differ (ints equal floats)."""
    if isinstance(stored, dict) and isinstance(wanted, dict):
        out = []
        for key in sorted(set(stored) | set(wanted), key=str):
            sub = f"{where}.{key}" if where else str(key)
            if key not in stored:
                out.append(f"{sub}: not stored, requested {wanted[key]!r}")
            elif key not in wanted:
                out.append(f"{sub}: stored {stored[key]!r}, not requested")
            else:
                out.extend(_differences(stored[key], wanted[key], sub))
        return out
    same = stored == wanted or (isinstance(stored, float) and isinstance(wanted, float)
                                and math.isnan(stored) and math.isnan(wanted))
    return [] if same else [f"{where}: stored {_short(stored)}, requested {_short(wanted)}"]


def _short(value, limit: int = 6) -> str:
    """``repr`` of a value; a long list by its first two values, its last and its length
    (a schedule of 50 volumes is not printed whole in an error message)."""
    if isinstance(value, (list, tuple)) and len(value) > limit:
        return f"[{value[0]!r}, {value[1]!r}, ..., {value[-1]!r}] ({len(value)} values)"
    return repr(value)


def _versions() -> dict:
    # the modules' own version attributes: importlib.metadata scans the installed
    # distributions (about 5 ms a call, twice per run)
    import scipy

    from .. import __version__

    versions = {"python": sys.version.split()[0], "numpy": np.__version__,
                "h5py": h5py.__version__, "hdf5": h5py.version.hdf5_version,
                "pandas": pd.__version__, "shellbuckle": __version__,
                "scipy": scipy.__version__}
    commit = source_commit()
    if commit:
        versions["shellbuckle_git"] = commit
    return versions


@functools.lru_cache(maxsize=None)
def source_commit() -> str | None:
    """The git commit of shellbuckle's source when it runs from a git checkout (an editable
    install), with ``+dirty`` if the package's files differ from it; None otherwise.

    The package version does not tell two commits apart, and after buckling a run's
    trajectory depends on the code down to round-off, so the commit is what reproduces a run."""
    package = Path(__file__).resolve().parents[1]
    git = ["git", "-C", str(package)]
    try:
        tracked = subprocess.run(git + ["ls-files", "--", "__init__.py"], capture_output=True,
                                 text=True, timeout=10, check=True).stdout.strip()
        if not tracked:
            return None
        commit = subprocess.run(git + ["rev-parse", "--short=12", "HEAD"], capture_output=True,
                                text=True, timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(git + ["status", "--porcelain", "--", "."], capture_output=True,
                               text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return f"{commit}+dirty" if dirty else commit or None


def _session() -> dict:
    return {"started": now(), "command_line": list(sys.argv), "versions": _versions()}


# --------------------------------------------------------------------------- arrays

def array_sha256(*named_arrays) -> str:
    """SHA-256 over ``(name, array)`` pairs: name, little-endian dtype, shape and raw bytes."""
    h = hashlib.sha256()
    for name, arr in named_arrays:
        a = np.ascontiguousarray(arr)
        a = a.astype(a.dtype.newbyteorder("<"), copy=False)
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _check_mesh(X0, faces, rest):
    X0 = np.ascontiguousarray(X0, dtype=np.float64)
    if X0.ndim != 2 or X0.shape[1] != 3 or len(X0) == 0 or not np.isfinite(X0).all():
        raise ValueError(f"X0 must be a finite (V, 3) array of positions, got shape {X0.shape}")
    faces_in = np.asarray(faces)
    if faces_in.ndim != 2 or faces_in.shape[1] != 3 or not np.issubdtype(faces_in.dtype,
                                                                         np.integer):
        raise ValueError(f"faces must be an integer (F, 3) array, got {faces_in.dtype} "
                         f"{faces_in.shape}")
    faces = np.ascontiguousarray(faces_in, dtype=np.int64)
    if faces.size and (faces.min() < 0 or faces.max() >= len(X0)):
        raise ValueError(f"faces index vertices outside 0..{len(X0) - 1}")
    rest = {} if rest is None else dict(rest)
    for name in rest:
        _check_name(name, "rest")
        rest[name] = np.ascontiguousarray(rest[name])
    return X0, faces, rest


def _check_name(name, where: str) -> None:
    if not isinstance(name, str) or not name or "/" in name or name.startswith("."):
        raise ValueError(f"{where} array name {name!r} must be a non-empty string without '/'")


def _check_arrays(arrays) -> dict:
    out = {}
    for name, arr in (arrays or {}).items():
        _check_name(name, "step")
        arr = np.asarray(arr)
        if arr.dtype == object:
            raise ValueError(f"step array {name!r} must be numeric, got dtype object")
        out[name] = np.ascontiguousarray(arr)
    return out


def step_checksums(X, record_json: str, arrays: Mapping | None = None) -> dict[str, str]:
    """The checksums a step file stores in its attribute ``sha256`` (as JSON): the positions
    ``"X"`` and each extra array ``"arrays/<name>"`` by :func:`array_sha256`, the record by
    the SHA-256 of ``record_json``'s UTF-8 bytes."""
    sums = {"X": array_sha256(("X", X)),
            "record_json": hashlib.sha256(record_json.encode("utf-8")).hexdigest()}
    for name in sorted(arrays or {}):
        sums[f"arrays/{name}"] = array_sha256((name, arrays[name]))
    return sums


class DamagedStep(ValueError):
    """A step file that cannot be trusted; the message says which file and what is wrong."""


def _text_attribute(f, name: str):
    try:
        value = f.attrs[name]
    except KeyError:
        return None
    return value.decode("utf-8") if isinstance(value, bytes) else value


def read_step_file(path: Path, k: int, n_vertices: int | None = None, *,
                   parts: str = "all"):
    """``(record, X, arrays, checked)`` of the step file ``path`` of step ``k``, verified:
    it opens as HDF5, its record parses as a dict naming step ``k``, ``X`` is a finite
    ``(n_vertices, 3)`` float64 array, and the content matches its checksums (``checked`` is
    False for a file written before the checksums, which cannot be checked).
    :class:`DamagedStep` naming the file and what is wrong otherwise.

    ``parts``: ``"all"``; or ``"X"`` or ``"arrays"`` to read and check only the positions or
    only the extra arrays (the other values are then None).
    """
    name = f"{path.parent.name}/{path.name}"
    try:
        size = path.stat().st_size
    except FileNotFoundError:
        raise DamagedStep(f"{name} is missing although later steps exist") from None
    if size == 0:
        raise DamagedStep(f"{name} is empty (0 bytes)")
    text = X = arrays = None
    try:
        with h5py.File(path, "r", locking=False) as f:
            sums = _text_attribute(f, CHECKSUM_ATTR)
            if parts == "all":
                text = _text_attribute(f, "record_json")
            if parts in ("all", "X"):
                try:
                    X = f["X"][()]
                except KeyError:
                    X = None
            if parts in ("all", "arrays"):
                group = f.get("arrays")
                arrays = {key: group[key][()] for key in group} if group is not None else {}
    except (OSError, KeyError, ValueError, RuntimeError, TypeError, AttributeError,
            UnicodeDecodeError) as exc:
        with open(path, "rb") as fh:
            head = fh.read(len(_HDF5_SIGNATURE))
        if head != _HDF5_SIGNATURE:
            raise DamagedStep(f"{name} is not an HDF5 file ({size} bytes starting with "
                              f"{head!r})") from None
        raise DamagedStep(f"{name} cannot be read as HDF5, truncated or overwritten "
                          f"({size} bytes; {exc})") from None
    record = None
    if parts == "all":
        if not isinstance(text, str):
            raise DamagedStep(f"{name} has no step record (attribute record_json)")
        try:
            record = json.loads(text)
        except json.JSONDecodeError as exc:
            raise DamagedStep(f"{name}: its record (attribute record_json) is not valid JSON "
                              f"({exc})") from None
        if not isinstance(record, dict) or record.get("step") != k:
            said = record.get("step") if isinstance(record, dict) else type(record).__name__
            raise DamagedStep(f"{name}: its record (attribute record_json) is not the record "
                              f"of step {k} (it says {said!r})")
    if parts in ("all", "X"):
        if not isinstance(X, np.ndarray):
            raise DamagedStep(f"{name} has no positions (dataset X)")
        expected = (n_vertices, 3) if n_vertices is not None else (len(X), 3)
        if X.shape != expected or X.dtype != np.float64 or not np.isfinite(X).all():
            raise DamagedStep(f"{name}: its positions X are {X.dtype} {X.shape}, expected "
                              f"finite float64 {expected}")
    if sums is None:
        log.debug("%s has no checksums (written before step checksums existed); its content "
                  "cannot be checked", path)
        return record, X, arrays, False
    try:
        stored = json.loads(sums)
    except json.JSONDecodeError:
        stored = None
    if not isinstance(stored, dict):
        raise DamagedStep(f"{name}: its checksums (attribute {CHECKSUM_ATTR}) are unreadable")
    computed = {}
    if X is not None:
        computed["X"] = array_sha256(("X", X))
    if text is not None:
        computed["record_json"] = hashlib.sha256(text.encode("utf-8")).hexdigest()
    for key in sorted(arrays or {}):
        computed[f"arrays/{key}"] = array_sha256((key, arrays[key]))
    expected_parts = {p for p in stored if parts == "all" or p == parts
                      or (parts == "arrays" and p.startswith("arrays/"))}
    for part in sorted(expected_parts | set(computed), key=lambda p: (p != "X", p)):
        what = "the positions X" if part == "X" else (
            "the record (attribute record_json)" if part == "record_json" else part)
        if part not in computed:
            raise DamagedStep(f"{name}: {what}, recorded in its checksums, is missing")
        if part not in stored:
            raise DamagedStep(f"{name}: {what} has no checksum (added after writing)")
        if stored[part] != computed[part]:
            raise DamagedStep(f"{name}: checksum mismatch in {what} (SHA-256 stored "
                              f"{str(stored[part])[:12]}..., the content gives "
                              f"{computed[part][:12]}...): the file changed after it was "
                              "written")
    return record, X, arrays, True


def _h5_bytes(write) -> bytes:
    """The bytes of a complete HDF5 file built in memory by ``write(h5py.File)``."""
    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as f:
        write(f)
    return buffer.getvalue()


def _attribute_value(value):
    """A JSON scalar as an HDF5 attribute value (None is only kept in ``record_json``)."""
    return value if not isinstance(value, str) else np.array(value, dtype=h5py.string_dtype())


def _read_h5(path: Path, read):
    try:
        with h5py.File(path, "r", locking=False) as f:
            return read(f)
    except FileNotFoundError:
        raise ValueError(f"{path} is missing; the run folder is damaged") from None
    except OSError as exc:
        raise ValueError(f"{path} cannot be read as HDF5 ({exc}); the run folder is "
                         "damaged") from None


def _read_meta(path: Path) -> tuple[dict, bool]:
    """The contents of ``path/run.json`` and False, or the description rebuilt from
    ``mesh.h5`` and True when run.json is missing; ValueError with a clear message (what to do)
    if no run can be read there."""
    if not path.exists():
        raise ValueError(f"{path} does not exist; expected a run folder (made by "
                         "`shellbuckle deflate --out DIR`)")
    if not path.is_dir():
        raise ValueError(f"{path} is a file, not a run folder")
    try:
        text = (path / RUN_JSON).read_text(encoding="utf-8")
    except FileNotFoundError:
        return _rebuilt_meta(path), True
    try:
        meta = json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path / RUN_JSON} is not valid JSON ({exc}); "
                         + _how_to_replace_run_json(path)) from None
    meta = check_format(meta, path / RUN_JSON, FORMAT_NAME, FORMAT_VERSION)
    _check_fields(meta, path)
    if not (path / STEPS_DIR).is_dir():
        parent = meta.get("parent")
        again = (f"run again the command that made it (`shellbuckle continue {parent['path']} "
                 f"--step {parent['step']} --out {path}` with the same options)"
                 if isinstance(parent, dict) and {"path", "step"} <= set(parent)
                 else f"run `shellbuckle resume {path}`")
        raise ValueError(
            f"{path} has no {STEPS_DIR}/ folder: the files of its finished steps "
            f"({STEPS_DIR}/step_NNNNNN.h5) were moved or deleted. Put the folder back from a "
            f"backup; or, to compute the run again from its start, create an empty folder "
            f"{path / STEPS_DIR} and {again}")
    return meta, False


def _check_fields(meta: dict, path: Path) -> None:
    """ValueError naming the fields of run.json that are missing or of the wrong type."""
    problems = []
    for name, kind in REQUIRED_FIELDS.items():
        if name not in meta:
            problems.append(f"{name} (missing)")
        elif not isinstance(meta[name], kind):
            problems.append(f"{name} (a {type(meta[name]).__name__}, expected a "
                            f"{kind.__name__})")
    if isinstance(meta.get("mesh"), dict):
        for name, kind in REQUIRED_MESH_FIELDS.items():
            value = meta["mesh"].get(name)
            if value is None:
                problems.append(f"mesh.{name} (missing)")
            elif not isinstance(value, kind) or isinstance(value, bool):
                problems.append(f"mesh.{name} (a {type(value).__name__}, expected a "
                                f"{kind.__name__})")
    if problems:
        raise ValueError(f"{path / RUN_JSON} lacks the field(s) it needs: "
                         f"{', '.join(problems)}; " + _how_to_replace_run_json(path))


def _how_to_replace_run_json(path: Path) -> str:
    """What to do about an unusable run.json: rebuild it from the copy in mesh.h5 if there
    is one, else restore it from a backup."""
    if _stored_description(path) is not None:
        return (f"mesh.h5 holds a copy of the run's description: move run.json aside "
                f"(`mv {path / RUN_JSON} {path / RUN_JSON}.bad`) and the run opens from the "
                f"copy; `shellbuckle resume {path}` then writes a new run.json")
    return (f"restore {RUN_JSON} from a backup: the run's parameters and protocol are stored "
            "nowhere else in the folder")


def _stored_description(path: Path) -> str | None:
    """The copy of run.json kept in ``path/mesh.h5`` (None if absent or unreadable)."""
    try:
        with h5py.File(path / MESH_H5, "r", locking=False) as f:
            text = f.attrs.get(DESCRIPTION_ATTR)
    except (OSError, KeyError, ValueError, RuntimeError):
        return None
    if isinstance(text, bytes):
        text = text.decode("utf-8", "replace")
    return text if isinstance(text, str) else None


def _rebuilt_meta(path: Path) -> dict:
    """The description of the run in ``path`` whose run.json is missing, from the copy in
    mesh.h5, checked against the mesh arrays; ValueError saying what to do otherwise."""
    has_steps = _has_step_files(path)
    if not (path / MESH_H5).exists() and not has_steps:
        raise ValueError(f"{path} is not a shellbuckle run folder (it has no {RUN_JSON})")
    text = _stored_description(path)
    if text is None:
        if not has_steps:
            raise ValueError(
                f"{path} holds a run whose creation was interrupted before {RUN_JSON} was "
                "written (it has no finished step); start it again with the same "
                f"`shellbuckle deflate ... --out {path}` (the folder is reused)")
        raise ValueError(
            f"{path} has step files but no {RUN_JSON}, and its {MESH_H5} holds no copy of the "
            "run's description (it was written by an older shellbuckle), so the parameters "
            f"and protocol cannot be recovered from the folder. Restore {RUN_JSON} from a "
            f"backup; the steps themselves stay readable with h5py ({STEPS_DIR}/step_*.h5: "
            "positions X, record in the attribute record_json); or compute the run again in "
            "a new folder with its original options (`shellbuckle deflate ... --out NEW_DIR`)")
    try:
        meta = check_format(json.loads(text), path / MESH_H5, FORMAT_NAME, FORMAT_VERSION)
    except json.JSONDecodeError as exc:
        raise ValueError(f"the copy of {RUN_JSON} in {path / MESH_H5} is not valid JSON "
                         f"({exc}); restore {RUN_JSON} from a backup") from None
    _check_fields(meta, path)
    X0, faces, rest = _read_h5(path / MESH_H5, _read_mesh_arrays)
    if array_sha256(("X0", X0), ("faces", faces), *sorted(rest.items())) \
            != meta["mesh"]["sha256"]:
        raise ValueError(f"{path / MESH_H5} does not match the SHA-256 of its own description: "
                         f"the mesh is damaged and {RUN_JSON} is missing; restore them from a "
                         "backup")
    meta.update(status="interrupted", updated=now(),
                message=f"{RUN_JSON} was missing and was rebuilt from {MESH_H5}: the run's "
                        "status and the sessions after the first one were lost; `shellbuckle "
                        f"resume {path}` continues the run (and writes {RUN_JSON} again)")
    log.warning("%s has no %s; rebuilt it from the copy in %s (the status and the sessions "
                "after the first one are lost); `shellbuckle resume %s` writes it again",
                path, RUN_JSON, MESH_H5, path)
    return meta


def _step_indices(names):
    """The step indices of the step file names among ``names`` (``step_000012.h5`` -> 12)."""
    for name in names:
        digits = name[5:-3]
        if name.startswith("step_") and name.endswith(".h5") and digits.isascii() \
                and digits.isdigit():
            yield int(digits)


def _has_step_files(path: Path) -> bool:
    try:
        return any(_step_indices(os.listdir(path / STEPS_DIR)))
    except (FileNotFoundError, NotADirectoryError):
        return False


def _ranges(steps) -> str:
    """``0..3, 5, 7..9`` for sorted step indices."""
    parts, start = [], None
    steps = list(steps)
    for i, k in enumerate(steps):
        if start is None:
            start = k
        if i + 1 == len(steps) or steps[i + 1] != k + 1:
            parts.append(str(k) if k == start else f"{start}..{k}")
            start = None
    return ", ".join(parts)


#: The damaged steps last warned about, by run folder: one warning per process and damage.
_WARNED: dict[str, dict[int, str]] = {}


def damage_summary(path, stored, damaged: Mapping[int, str]) -> str:
    """One line on the damaged steps of the run in ``path``: which, what is wrong with each,
    and what to do (a resume computes damaged last steps again; past a damaged step in the
    middle, a new run continues from the last good step before it)."""
    ks = sorted(damaged)
    which = (f"step {ks[0]} is" if len(ks) == 1 else f"steps {_ranges(ks)} are")
    what = "; ".join(f"step {k}: {damaged[k]}" for k in ks)
    trailing = ks == list(range(stored[-1] - len(ks) + 1, stored[-1] + 1))
    if trailing:
        todo = f"`shellbuckle resume {path}` computes {'it' if len(ks) == 1 else 'them'} again"
    else:
        before = [k for k in stored if k < ks[0] and k not in damaged]
        todo = ("a resume cannot go past a damaged step" + (
            f"; `shellbuckle continue {path} --step {before[-1]} --out NEW_DIR` goes on from "
            "the last good step before it" if before else ""))
    return f"run {path}: {which} damaged and left out, the other steps read ({what}); {todo}"


def _span(steps) -> str:
    """``0..5`` for contiguous step indices (``0..0`` for one), else :func:`_ranges`."""
    steps = list(steps)
    if steps and steps == list(range(steps[0], steps[-1] + 1)):
        return f"{steps[0]}..{steps[-1]}"
    return _ranges(steps)


def _redo_branch(store) -> str:
    """How to make the step 0 of the branch ``store`` again."""
    parent = store.parent
    return (f"Run the command that made this run again (`shellbuckle continue "
            f"{parent['path']} --step {parent['step']} --out {store.path}` with the same "
            "options): it writes step 0 from the parent and goes on")


def _read_mesh_arrays(f) -> tuple:
    rest = {name: f["rest"][name][()] for name in f["rest"]} if "rest" in f else {}
    return f["X0"][()], f["faces"][()], rest


def check_format(data, file: Path, name: str, version: int) -> dict:
    """``data``, read from ``file``, if it describes format ``name`` in a version up to
    ``version`` (ValueError otherwise); the check of ``run.json`` and ``sweep.json``."""
    if not isinstance(data, dict) or data.get("format") != name:
        raise ValueError(f"{file} is not a {name} description")
    if data.get("format_version", 0) > version:
        raise ValueError(f"{file.parent} was written in {name} format version "
                         f"{data['format_version']}; this shellbuckle reads up to version "
                         f"{version}, please upgrade")
    return data


def _interrupted_creation(path: Path) -> bool:
    """True if ``path`` is empty or holds only what an interrupted ``create`` leaves behind."""
    for entry in os.scandir(path):
        if entry.name in (MESH_H5, WRITER_LOCK, ANALYSIS_LOCK) or temporary_target(entry.name):
            continue
        if entry.name == STEPS_DIR and entry.is_dir() and not os.listdir(entry.path):
            continue
        return False
    return True


def _identity(meta: dict) -> dict:
    """What makes two runs the same run: parameters, protocol, mesh hash and parent."""
    parent = meta.get("parent")
    if parent is not None:
        parent = {key: parent[key] for key in ("run_id", "step", "positions_sha256")}
    return {"params": meta["params"], "protocol": meta["protocol"],
            "mesh_sha256": meta["mesh"]["sha256"], "parent": parent}


def _integer_like(column: pd.Series) -> bool:
    values = column.dropna()
    if values.empty:
        return False
    try:
        numbers = values.to_numpy(dtype=float)
    except (TypeError, ValueError):
        return False
    return bool(np.all(np.isfinite(numbers)) and np.all(numbers == np.round(numbers))
                and values.map(lambda v: not isinstance(v, bool)).all())


def _signature(path: Path) -> tuple[int, int, int]:
    """Modification time, size and inode of a file: they change when it is replaced."""
    stat = path.stat()
    return stat.st_mtime_ns, stat.st_size, stat.st_ino


def _csv_cell(value, integer: bool) -> str:
    """One cell of ``table.csv``: empty for None and NaN, the shortest repr of a float (an
    integer-valued one as an integer in an integer column), ``True``/``False``, else ``str``."""
    if value is None:
        return ""
    if isinstance(value, float):
        if math.isnan(value):
            return ""
        return str(int(value)) if integer and value.is_integer() else repr(value)
    return str(value)


class RunStore:
    """A run folder (see the module docstring): :meth:`create`, :meth:`open`, :meth:`resume`,
    :meth:`branch`.

    A store opened with :meth:`open` reads; its first write (``append_step``, ``set_status``)
    takes the writer lock. :meth:`create`, :meth:`resume` and :meth:`branch` return a store
    that already holds it. Use it as a
    context manager, or call :meth:`close`, to release the lock.
    """

    def __init__(self, path: Path, meta: dict, *, rebuilt: bool = False):
        self._path = Path(path)
        self._meta = meta
        self._rebuilt = rebuilt  # meta rebuilt from mesh.h5: run.json is to be written again
        self._writer = FileLock(self._path / WRITER_LOCK)
        self._mesh_cache = None
        # per step: (file signature, record or None, what is wrong or None), as checked
        self._step_cache: dict[int, tuple[tuple, dict | None, str | None]] = {}
        self._scan_cache: tuple | None = None  # (key, stored steps, damaged)

    # ------------------------------------------------------------------ opening

    @classmethod
    def open(cls, path) -> "RunStore":
        """Open an existing run folder (ValueError naming the folder if it holds no run).

        A missing run.json is rebuilt (in memory) from the copy in mesh.h5; a run.json that
        lacks fields, and a run without its ``steps/`` folder, give a ValueError saying what
        to do.
        """
        path = Path(path)
        meta, rebuilt = _read_meta(path)
        return cls(path, meta, rebuilt=rebuilt)

    @classmethod
    def create(cls, path, *, params: Mapping, protocol: Mapping, X0, faces,
               rest: Mapping | None = None, extra_meta: Mapping | None = None) -> "RunStore":
        """Create the run folder ``path``, or reopen it for resuming if it holds this same run.

        ``params``, ``protocol`` and ``extra_meta`` are JSON-able dicts (numpy scalars and
        arrays are converted); ``X0 (V, 3)`` and ``faces (F, 3)`` are the reference mesh and
        ``rest`` optional rest-state arrays by name. The identity of a run is ``params``,
        ``protocol`` and the SHA-256 of the mesh arrays; ``extra_meta`` is kept from the
        first creation. Refuses (ValueError) a file, a non-empty folder that is not a run, a
        folder holding a different run, and a run another live process is writing.
        """
        return cls._create(Path(path), params=params, protocol=protocol, X0=X0, faces=faces,
                           rest=rest, extra_meta=extra_meta, parent=None)

    @classmethod
    def _create(cls, path: Path, *, params, protocol, X0, faces, rest, extra_meta, parent):
        X0, faces, rest = _check_mesh(X0, faces, rest)
        meta = {
            "format": FORMAT_NAME, "format_version": FORMAT_VERSION,
            "run_id": uuid.uuid4().hex, "created": now(),
            "params": _json_dict(params, "params"), "protocol": _json_dict(protocol, "protocol"),
            "mesh": {"n_vertices": len(X0), "n_faces": len(faces), "rest_arrays": sorted(rest),
                     "sha256": array_sha256(("X0", X0), ("faces", faces), *sorted(rest.items()))},
            "parent": parent, "versions": _versions(),
            "platform": {"system": platform.system(), "release": platform.release(),
                         "machine": platform.machine(), "python": platform.python_implementation()},
            "command_line": list(sys.argv), "sessions": [_session()],
            "status": "running", "message": None, "updated": now(),
            "extra": _json_dict(extra_meta or {}, "extra_meta"),
        }
        if path.exists() and not path.is_dir():
            raise ValueError(f"{path} is an existing file; a run needs a folder (choose "
                             "another --out)")
        if (path / RUN_JSON).exists():
            return cls._reopen(path, meta)
        if path.exists() and not _interrupted_creation(path):
            if (path / MESH_H5).exists() or _has_step_files(path):
                return cls._reopen(path, meta)  # run.json lost: rebuilt, or why not
            raise ValueError(f"{path} is a non-empty folder that is not a shellbuckle run; "
                             "choose a new or empty folder with --out")
        path.mkdir(parents=True, exist_ok=True)
        store = cls(path, meta)
        store._take_writer_lock()
        if (path / RUN_JSON).exists():  # another process created it meanwhile
            store.close()
            return cls._reopen(path, meta)
        store._write_mesh(X0, faces, rest)
        (path / STEPS_DIR).mkdir(exist_ok=True)
        store._write_meta()  # run.json last: its presence marks a complete run folder
        store._write_table()
        log.info("created run %s in %s", meta["run_id"], path)
        return store

    @classmethod
    def _reopen(cls, path: Path, wanted: dict) -> "RunStore":
        store = cls.open(path)
        differences = _differences(_identity(store._meta), _identity(wanted))
        if differences:
            shown = "; ".join(differences[:6]) + ("; ..." if len(differences) > 6 else "")
            raise ValueError(f"{path} holds a different run ({shown}); choose another folder "
                             f"with --out, or continue the stored run with `shellbuckle "
                             f"resume {path}`")
        store._start_session()
        return store

    @classmethod
    def resume(cls, path) -> "RunStore":
        """Reopen the run in ``path`` for writing, whatever it is (a branch too).

        Takes the writer lock (ValueError if a live process holds it), removes stale
        temporaries, records a new session and sets the status to "running"; the caller
        continues after :attr:`last_step` with :attr:`params` and :attr:`protocol`.

        Damaged last steps are set aside (``step_K.h5.damaged-<n>``, never deleted) for the
        caller to compute again; a damaged step with good steps after it is a ValueError
        naming it and the step to continue from (:attr:`damaged`). A run.json rebuilt from
        mesh.h5 is written again.
        """
        store = cls.open(path)
        if store.parent is not None and 0 not in store.steps:
            # a branch's step 0 is its parent's step, which only `branch` writes
            raise ValueError(f"step 0 of run {store.path} is "
                             f"{'damaged' if 0 in store.damaged else 'not stored'}; it is "
                             f"the step it starts from, step {store.parent['step']} of "
                             f"{store.parent['path']}. " + _redo_branch(store))
        store._start_session()
        return store

    def _start_session(self) -> None:
        self._take_writer_lock()
        try:
            set_aside = self._set_aside_damaged()
        except BaseException:
            self.close()
            raise
        if self._rebuilt:
            (self._path / STEPS_DIR).mkdir(exist_ok=True)
            self._rebuilt = False
        session = _session()
        if set_aside:
            session["set_aside"] = set_aside
        self._meta["sessions"].append(session)
        self._meta.update(status="running", message=None, updated=now())
        self._write_meta()
        if set_aside:
            self._write_table()
        log.info("resuming run %s in %s after step %s", self.run_id, self._path, self.last_step)

    def _set_aside_damaged(self) -> list[str]:
        """Before writing: rename the damaged last steps ``step_K.h5`` to
        ``step_K.h5.damaged-<n>`` (computed again by the resumed run); the new names, in
        ``steps/``. ValueError if a damaged (or missing) step has good steps after it: naming
        it and the last good step before it, from which a new run can continue."""
        stored, damaged = self._scan(warn=False)
        if not damaged:
            return []
        trailing = []
        for k in reversed(stored):
            if k not in damaged:
                break
            trailing.append(k)
        middle = sorted(set(damaged) - set(trailing))
        if middle:
            first = middle[0]
            before = [k for k in stored if k < first and k not in damaged]
            others = [k for k in sorted(damaged) if k != first]
            also = (f"; damaged too: step(s) {_ranges(others)}" if others else "")
            if before:
                k = before[-1]
                how = (f"To go on from step {k}, the last good step before it, start a new "
                       f"run from it: `shellbuckle continue {self._path} --step {k} --out "
                       f"NEW_DIR` (the same as `shellbuckle deflate --from {self._path} --step "
                       f"{k} --out NEW_DIR`)")
            else:
                how = ("No good step comes before it: compute the run again in a new folder "
                       "with its options (`shellbuckle deflate ... --out NEW_DIR`)")
            raise ValueError(
                f"step {first} of run {self._path} is damaged ({damaged[first]}){also}; "
                f"steps after it exist, so the run cannot go on from its last step. {how}. "
                "The good steps stay readable.")
        names = []
        for k in sorted(trailing):
            path = self._step_path(k)
            n = 1
            while path.with_name(f"{path.name}.damaged-{n}").exists():
                n += 1
            target = path.with_name(f"{path.name}.damaged-{n}")
            os.replace(path, target)
            names.append(target.name)
            log.warning("run %s: set aside the damaged step %d (%s) as %s/%s; it is computed "
                        "again", self._path, k, damaged[k], STEPS_DIR, target.name)
            self._step_cache.pop(k, None)
        fsync_folder(self._path / STEPS_DIR)
        self._scan_cache = None
        return names

    def branch(self, new_path, from_step: int, *, params: Mapping | None = None,
               protocol: Mapping | None = None, extra_meta: Mapping | None = None,
               record: Mapping | None = None) -> "RunStore":
        """A new run in ``new_path`` whose step 0 is step ``from_step`` of this run.

        The reference mesh and rest state are this run's (energies stay measured from the same
        stress-free sphere); ``params``/``protocol`` default to this run's (pass a new protocol
        for a re-inflation, a volume schedule or a parameter path). ``run.json`` records the
        parent folder, run id, step and positions hash; calling ``branch`` again with the same
        arguments reopens the branch for resuming. Step 0's record is the parent step's,
        updated with ``record`` (e.g. the ``gamma`` column of a parameter path).
        """
        from_step = operator.index(from_step)
        X = self.positions(from_step)
        parent = {"path": str(self._path.resolve()), "run_id": self.run_id, "step": from_step,
                  "positions_sha256": array_sha256(("X", X))}
        child = type(self)._create(
            Path(new_path), params=self.params if params is None else params,
            protocol=self.protocol if protocol is None else protocol, X0=self.X0,
            faces=self.faces, rest=self.rest, extra_meta=extra_meta, parent=parent)
        if not child.steps:
            first = self.record(from_step) | dict(record or {})
            first.pop("step", None)
            child.append_step(0, X, first, self.arrays(from_step))
        return child

    def close(self) -> None:
        """Release the writer lock (the store stays readable)."""
        self._writer.release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        return (f"RunStore({str(self._path)!r}, status={self.status!r}, "
                f"last_step={self.last_step})")

    # ------------------------------------------------------------------ description

    @property
    def path(self) -> Path:
        return self._path

    @property
    def meta(self) -> dict:
        """A copy of ``run.json`` as loaded or last written by this object."""
        return copy.deepcopy(self._meta)

    @property
    def run_id(self) -> str:
        return self._meta["run_id"]

    @property
    def params(self) -> dict:
        return copy.deepcopy(self._meta["params"])

    @property
    def protocol(self) -> dict:
        return copy.deepcopy(self._meta["protocol"])

    @property
    def parent(self) -> dict | None:
        """``{"path", "run_id", "step", "positions_sha256"}`` for a branch, else None."""
        return copy.deepcopy(self._meta.get("parent"))

    @property
    def status(self) -> str:
        return self._meta["status"]

    @property
    def writer_active(self) -> bool:
        """True if another live process (or store object) holds this run's writer lock.

        A run whose status says "running" while no writer is active was killed; resume it.
        """
        return self._writer.is_held_elsewhere()

    # ------------------------------------------------------------------ mesh

    def _mesh(self):
        if self._mesh_cache is None:
            self._mesh_cache = _read_h5(self._path / MESH_H5, _read_mesh_arrays)
        return self._mesh_cache

    @property
    def X0(self) -> np.ndarray:
        """Reference (initial, stress-free) positions, ``(V, 3)`` float64."""
        return self._mesh()[0].copy()

    @property
    def faces(self) -> np.ndarray:
        """Triangles ``(F, 3)`` int64, outward orientation as given at creation."""
        return self._mesh()[1].copy()

    @property
    def rest(self) -> dict[str, np.ndarray]:
        """Rest-state arrays given at creation, by name (empty if none)."""
        return {name: arr.copy() for name, arr in self._mesh()[2].items()}

    @property
    def n_vertices(self) -> int:
        return int(self._meta["mesh"]["n_vertices"])

    # ------------------------------------------------------------------ steps

    def _step_path(self, k: int) -> Path:
        return self._path / STEPS_DIR / f"step_{k:06d}.h5"

    def _scan(self, warn: bool = True) -> tuple[list[int], dict[int, str]]:
        """The stored steps ``0..K`` (K the highest step file) and the damaged ones among them,
        ``{k: what is wrong}`` (a missing file below K is damaged too).

        Each file is checked once (:func:`read_step_file`) and its verdict kept with its
        signature (modification time, size, inode); only the last file can be replaced
        (``overwrite=True``, a resume that set it aside), so only its signature is taken again
        on a later scan. ``warn``: log a warning when the damaged steps differ from the last
        ones warned about.
        """
        try:
            names = os.listdir(self._path / STEPS_DIR)
        except FileNotFoundError:
            names = []
        found = sorted(_step_indices(names))
        last_signature = None
        if found:
            try:
                last_signature = _signature(self._step_path(found[-1]))
            except FileNotFoundError:  # removed meanwhile: scan again
                return self._scan(warn)
        key = (tuple(found), last_signature)
        if self._scan_cache is not None and self._scan_cache[0] == key:
            stored, damaged = self._scan_cache[1], self._scan_cache[2]
        else:
            present = set(found)
            stored = list(range(found[-1] + 1)) if found else []
            damaged = {}
            for k in stored:
                if k not in present:
                    damaged[k] = f"{STEPS_DIR}/{self._step_path(k).name} is missing although " \
                                 "later steps exist"
                    continue
                entry = self._checked(k, last_signature if k == found[-1] else None)
                if entry[2] is not None:
                    damaged[k] = entry[2]
            self._scan_cache = (key, stored, damaged)
        if warn and damaged and _WARNED.get(str(self._path)) != damaged:
            _WARNED[str(self._path)] = dict(damaged)
            log.warning("%s", damage_summary(self._path, stored, damaged))
        return list(stored), dict(damaged)

    def _checked(self, k: int, signature=None) -> tuple[tuple, dict | None, str | None]:
        """``(signature, record, None)`` for a good step file, ``(signature, None, what is
        wrong)`` for a damaged one; from the cache when it holds step ``k`` and, if the file's
        ``signature`` is given, the cached verdict is of that same file."""
        cached = self._step_cache.get(k)
        if cached is not None and (signature is None or cached[0] == signature):
            return cached
        path = self._step_path(k)
        try:
            signature = _signature(path) if signature is None else signature
        except FileNotFoundError:
            signature = None
        try:
            record = read_step_file(path, k, self.n_vertices)[0]
            entry = (signature, record, None)
        except DamagedStep as exc:
            entry = (signature, None, str(exc))
        self._step_cache[k] = entry
        return entry

    @property
    def steps(self) -> list[int]:
        """Finished steps whose files are whole, sorted: ``0..last`` less the damaged ones
        (:attr:`damaged`), which are left out rather than failing the whole run."""
        stored, damaged = self._scan()
        return [k for k in stored if k not in damaged]

    @property
    def damaged(self) -> dict[int, str]:
        """Damaged steps, ``{step: what is wrong}`` naming the file: empty, truncated, not
        HDF5, a broken record, positions of the wrong shape, content that does not match its
        checksums, or a file missing below the last step. Empty for a whole run."""
        return self._scan()[1]

    @property
    def last_step(self) -> int | None:
        """Index of the last good finished step, or None before step 0 is stored."""
        steps = self.steps
        return steps[-1] if steps else None

    def _existing_step(self, k) -> Path:
        """The file of step ``k``; ValueError if it is not stored or known to be damaged."""
        k = operator.index(k)
        path = self._step_path(k)
        cached = self._step_cache.get(k)
        if k >= 0 and path.exists() and (cached is None or cached[2] is None):
            return path
        self._not_readable(k)

    def _not_readable(self, k: int):
        """Raise the ValueError saying why step ``k`` cannot be read."""
        stored, damaged = self._scan()
        if k in damaged:
            raise DamagedStep(f"step {k} of run {self._path} is damaged: {damaged[k]}")
        good = [j for j in stored if j not in damaged]
        held = f"finished steps {_span(good)}" if good else "no finished step"
        if damaged:
            held += f"; damaged: {_ranges(sorted(damaged))}"
        raise ValueError(f"step {k} is not in run {self._path} ({held})")

    def _read_step(self, k, parts: str):
        """The positions (``parts="X"``) or the extra arrays (``"arrays"``) of step ``k``,
        checked against the file's checksums now (a change of its bytes since the last scan
        shows here)."""
        path = self._existing_step(k)
        k = operator.index(k)
        try:
            signature = _signature(path)
            _, X, arrays, _ = read_step_file(path, k, self.n_vertices, parts=parts)
        except FileNotFoundError:
            self._not_readable(k)
        except DamagedStep as exc:
            self._step_cache[k] = (signature, None, str(exc))
            self._scan_cache = None
            raise DamagedStep(f"step {k} of run {self._path} is damaged: {exc}") from None
        return X if parts == "X" else arrays

    def positions(self, k: int) -> np.ndarray:
        """Vertex positions ``(V, 3)`` float64 of finished step ``k`` (checked against the
        file's checksums; ValueError naming the file if it is damaged)."""
        return self._read_step(k, "X")

    def arrays(self, k: int) -> dict[str, np.ndarray]:
        """Extra arrays stored with step ``k`` (empty dict if none)."""
        return self._read_step(k, "arrays")

    def record(self, k: int) -> dict:
        """The step record of step ``k`` exactly as appended, with ``"step": k``."""
        return copy.deepcopy(self._stored_record(k))

    def _stored_record(self, k: int) -> dict:
        """:meth:`record` without the copy (read only), from the cache while the file is the
        one it was checked in (same modification time, size and inode)."""
        path = self._existing_step(k)
        try:
            entry = self._checked(operator.index(k), _signature(path))
        except FileNotFoundError:
            self._not_readable(k)
        if entry[2] is not None:
            self._scan_cache = None
            self._not_readable(k)
        return entry[1]

    def append_step(self, k: int, X, record: Mapping, arrays: Mapping | None = None, *,
                    overwrite: bool = False) -> None:
        """Store finished step ``k``: positions ``X (V, 3)``, a flat ``record``, extra arrays.

        ``k`` must be the next step (0 for an empty run); with ``overwrite=True`` the last
        stored step may be replaced instead. The record is a flat dict of numbers, strings,
        booleans or None (the SPEC §7 names for the table columns); a ``"step"`` entry must
        equal ``k``. The file appears atomically and ``table.csv`` is regenerated.
        """
        k = operator.index(k)
        steps, damaged = self._scan()
        following = steps[-1] + 1 if steps else 0
        if k in steps and not overwrite:
            raise ValueError(f"step {k} is already stored in {self._path}; it is not "
                             "overwritten unless overwrite=True")
        if k != following and not (overwrite and steps and k == steps[-1]):
            allowed = f"{following}" + (f" (or {steps[-1]} with overwrite=True)" if steps else "")
            raise ValueError(f"step {k} cannot be stored in {self._path}: the next step is "
                             f"{allowed}")
        blocking = sorted(j for j in damaged if not (overwrite and j == k))
        if blocking:
            raise ValueError(f"run {self._path} has damaged step(s) {_ranges(blocking)} "
                             f"({damaged[blocking[0]]}); no step is added after a damaged one. "
                             f"`shellbuckle resume {self._path}` sets damaged last steps aside "
                             "and computes them again")
        X = np.ascontiguousarray(X, dtype=np.float64)
        if X.shape != (self.n_vertices, 3) or not np.isfinite(X).all():
            raise ValueError(f"positions of step {k} must be a finite ({self.n_vertices}, 3) "
                             f"array, got shape {X.shape}")
        record = _scalar_dict(record, f"record of step {k}",
                              reserved=("record_json", CHECKSUM_ATTR))
        if record.setdefault("step", k) != k:
            raise ValueError(f"record of step {k} says step {record['step']!r}")
        record = {"step": k, **{key: v for key, v in record.items() if key != "step"}}
        arrays = _check_arrays(arrays)
        record_json = json.dumps(record)

        def write(f):
            f.create_dataset("X", data=X)
            for key, value in record.items():
                if value is not None:
                    f.attrs[key] = _attribute_value(value)
            f.attrs["record_json"] = record_json
            if arrays:
                group = f.create_group("arrays")
                for name, arr in arrays.items():
                    group.create_dataset(name, data=arr)
            f.attrs[CHECKSUM_ATTR] = json.dumps(step_checksums(X, record_json, arrays))

        self._take_writer_lock()
        path = self._step_path(k)
        atomic_write_bytes(path, _h5_bytes(write))
        # what record() would read back from the file just written
        self._step_cache[k] = (_signature(path), json.loads(record_json), None)
        self._write_table()

    # ------------------------------------------------------------------ table and analysis

    def analysis(self) -> dict[int, dict]:
        """Analysis results per step, as stored in ``analysis.json`` (empty if none)."""
        try:
            text = (self._path / ANALYSIS_JSON).read_text(encoding="utf-8")
        except FileNotFoundError:
            return {}
        try:
            return {int(k): v for k, v in json.loads(text).items()}
        except (json.JSONDecodeError, AttributeError, ValueError) as exc:
            raise ValueError(f"{self._path / ANALYSIS_JSON} is damaged ({exc})") from None

    def update_analysis(self, results: Mapping[int, Mapping]) -> None:
        """Add or refresh analysis columns: ``{step: {"shape": ..., "W": ..., ...}}``.

        Values are flat scalars; the names of the physics columns (SPEC §7 step table) are
        refused. ``analysis.json`` is replaced atomically under its own lock, so this works
        while the run is still being computed.
        """
        steps = set(self.steps)
        updates = {}
        for k, values in results.items():
            k = operator.index(k)
            if k not in steps:
                self._existing_step(k)  # raises with the list of finished steps
            updates[k] = _scalar_dict(values, f"analysis of step {k}", reserved=TABLE_COLUMNS)
        lock = FileLock(self._path / ANALYSIS_LOCK)
        lock.acquire(blocking=True)
        try:
            remove_temporaries(self._path, {ANALYSIS_JSON})
            merged = self.analysis()
            for k, values in updates.items():
                merged.setdefault(k, {}).update(values)
            text = json.dumps({str(k): merged[k] for k in sorted(merged)}, indent=1)
            atomic_write_bytes(self._path / ANALYSIS_JSON, text.encode("utf-8"))
        finally:
            lock.release()
        if self._writer.held:
            self._write_table()
        elif self._writer.acquire():  # no live writer: refresh table.csv ourselves
            try:
                self._write_table()
            finally:
                self._writer.release()

    def _rows(self) -> tuple[list[dict], list[str]]:
        """The table's rows (record and analysis of every step, as stored) and its columns,
        in the order :meth:`table` documents. The rows share the cached records: read only."""
        analysis = self.analysis()
        stored, damaged = self._scan()
        rows = [{**self._step_cache[k][1], **analysis.get(k, {})}
                for k in stored if k not in damaged]
        present = list(dict.fromkeys(key for row in rows for key in row))
        columns = list(TABLE_COLUMNS) + [c for c in ANALYSIS_COLUMNS if c in present]
        columns += [c for c in present if c not in columns]
        return rows, columns

    def table(self) -> pd.DataFrame:
        """The per-step table as a DataFrame, one row per finished step.

        Columns: SPEC §7 names in order (``step`` ... ``wall_s``, always present, NaN where a
        step did not record them), then the analysis columns ``shape``, ``n_dimples``,
        ``corners``, ``W`` if any step has them, then any other recorded or analysis names in
        order of appearance. Integer-valued columns such as ``iterations`` are int64, or the
        nullable ``Int64`` where some steps lack them.
        """
        rows, columns = self._rows()
        table = pd.DataFrame(rows, columns=columns)  # new dicts of scalars: no copy needed
        for column in columns:
            if column in _INTEGER_COLUMNS and _integer_like(table[column]):
                has_na = table[column].isna().any()
                table[column] = table[column].astype("Int64" if has_na else np.int64)
            elif column in TABLE_COLUMNS and table[column].isna().all():
                table[column] = table[column].astype(np.float64)
        return table

    def _write_table(self) -> None:
        """``table.csv`` from the stored records, with the csv module rather than through
        :meth:`table` (pandas takes ~7 ms a step for what this writes in well under one);
        ``pandas.read_csv`` reads it back to the table's values."""
        rows, columns = self._rows()
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_csv_cell(row.get(column), column in _INTEGER_COLUMNS)
                             for column in columns])
        atomic_write_bytes(self._path / TABLE_CSV, out.getvalue().encode("utf-8"))

    # ------------------------------------------------------------------ status and writing

    def set_status(self, status: str, message: str | None = None) -> None:
        """Record the run's status and a message.

        Statuses: running, paused (stopped on purpose, resumable), finished, failed,
        interrupted (Ctrl-C). A run killed outright keeps "running" with no live writer
        (see :attr:`writer_active`).
        """
        if status not in STATUSES:
            raise ValueError(f"status {status!r} is not one of {', '.join(STATUSES)}")
        if message is not None and not isinstance(message, str):
            raise ValueError(f"status message must be a string, got {type(message).__name__}")
        self._take_writer_lock()
        self._meta.update(status=status, message=message, updated=now())
        self._write_meta()
        self._write_table()

    def _take_writer_lock(self) -> None:
        if self._writer.held:
            return
        if not self._writer.acquire():
            raise ValueError(f"another process is writing run {self._path} (it holds "
                             f"{self._path / WRITER_LOCK}); wait for it to finish or stop it")
        removed = remove_temporaries(self._path, _WRITER_FILES)
        removed += remove_temporaries(self._path / STEPS_DIR)
        if removed:
            log.info("removed %d stale temporary file(s) in %s", len(removed), self._path)

    def _write_meta(self) -> None:
        text = json.dumps(self._meta, indent=1, allow_nan=True)
        atomic_write_bytes(self._path / RUN_JSON, text.encode("utf-8"))

    def _write_mesh(self, X0, faces, rest) -> None:
        description = json.dumps(self._meta, indent=1, allow_nan=True)

        def write(f):
            f.create_dataset("X0", data=X0)
            f.create_dataset("faces", data=faces)
            if rest:
                group = f.create_group("rest")
                for name, arr in rest.items():
                    group.create_dataset(name, data=arr)
            f.attrs[DESCRIPTION_ATTR] = description  # run.json as created, to rebuild it
        atomic_write_bytes(self._path / MESH_H5, _h5_bytes(write))
        self._mesh_cache = (X0.copy(), faces.copy(), {k: v.copy() for k, v in rest.items()})
