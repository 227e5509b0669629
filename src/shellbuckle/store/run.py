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
                              arrays if any
    DIR/steps/step_000123.h5  one file per finished step: X (V, 3) float64 positions; the step
                              record as attributes (one per column, and all of it exactly as
                              JSON in the attribute record_json); group arrays/ with optional
                              extra arrays
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
import re
import subprocess
import sys
import uuid
from collections.abc import Mapping
from pathlib import Path

import h5py
import numpy as np
import pandas as pd

from ..util import now
from .atomic import FileLock, atomic_write_bytes, remove_temporaries, temporary_target

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
_STEP_RE = re.compile(r"^step_(\d+)\.h5$")


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


def _read_meta(path: Path) -> dict:
    """The contents of ``path/run.json``; ValueError with a clear message if no run is there."""
    if not path.exists():
        raise ValueError(f"{path} does not exist; expected a run folder (made by "
                         "`shellbuckle deflate --out DIR`)")
    if not path.is_dir():
        raise ValueError(f"{path} is a file, not a run folder")
    try:
        text = (path / RUN_JSON).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"{path} is not a shellbuckle run folder (it has no {RUN_JSON})") \
            from None
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path / RUN_JSON} is not valid JSON ({exc})") from None
    return check_format(meta, path / RUN_JSON, FORMAT_NAME, FORMAT_VERSION)


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

    def __init__(self, path: Path, meta: dict):
        self._path = Path(path)
        self._meta = meta
        self._writer = FileLock(self._path / WRITER_LOCK)
        self._mesh_cache = None
        self._record_cache: dict[int, tuple[tuple, dict]] = {}

    # ------------------------------------------------------------------ opening

    @classmethod
    def open(cls, path) -> "RunStore":
        """Open an existing run folder (ValueError naming the folder if it holds no run)."""
        path = Path(path)
        return cls(path, _read_meta(path))

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
        """
        store = cls.open(path)
        store._start_session()
        return store

    def _start_session(self) -> None:
        self._take_writer_lock()
        self._meta["sessions"].append(_session())
        self._meta.update(status="running", message=None, updated=now())
        self._write_meta()
        log.info("resuming run %s in %s after step %s", self.run_id, self._path, self.last_step)

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
            def read(f):
                rest = {name: f["rest"][name][()] for name in f["rest"]} if "rest" in f else {}
                return f["X0"][()], f["faces"][()], rest
            self._mesh_cache = _read_h5(self._path / MESH_H5, read)
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

    @property
    def steps(self) -> list[int]:
        """Finished steps, sorted; always ``0..last_step`` (ValueError if a file is missing)."""
        try:
            names = os.listdir(self._path / STEPS_DIR)
        except FileNotFoundError:
            return []
        steps = sorted(int(m.group(1)) for m in map(_STEP_RE.match, names) if m)
        if steps != list(range(len(steps))):
            missing = sorted(set(range(steps[-1] + 1)) - set(steps))
            raise ValueError(f"run {self._path} lacks the step files of steps {missing[:10]} "
                             "although later steps exist; the folder was altered by hand")
        return steps

    @property
    def last_step(self) -> int | None:
        """Index of the last finished step, or None before step 0 is stored."""
        steps = self.steps
        return steps[-1] if steps else None

    def _existing_step(self, k) -> Path:
        k = operator.index(k)
        path = self._step_path(k)
        if k < 0 or not path.exists():
            last = self.last_step
            held = "no finished step" if last is None else f"finished steps 0..{last}"
            raise ValueError(f"step {k} is not in run {self._path} ({held})")
        return path

    def positions(self, k: int) -> np.ndarray:
        """Vertex positions ``(V, 3)`` float64 of finished step ``k``."""
        return _read_h5(self._existing_step(k), lambda f: f["X"][()])

    def arrays(self, k: int) -> dict[str, np.ndarray]:
        """Extra arrays stored with step ``k`` (empty dict if none)."""
        def read(f):
            return {name: f["arrays"][name][()] for name in f["arrays"]} if "arrays" in f else {}
        return _read_h5(self._existing_step(k), read)

    def record(self, k: int) -> dict:
        """The step record of step ``k`` exactly as appended, with ``"step": k``."""
        return copy.deepcopy(self._stored_record(k))

    def _stored_record(self, k: int) -> dict:
        """:meth:`record` without the copy (read only), from the cache while the file is the
        one it was read from (same modification time, size and inode)."""
        path = self._existing_step(k)
        signature = _signature(path)
        cached = self._record_cache.get(k)
        if cached is None or cached[0] != signature:
            record = _read_h5(path, lambda f: json.loads(f.attrs["record_json"]))
            cached = self._record_cache[k] = (signature, record)
        return cached[1]

    def append_step(self, k: int, X, record: Mapping, arrays: Mapping | None = None, *,
                    overwrite: bool = False) -> None:
        """Store finished step ``k``: positions ``X (V, 3)``, a flat ``record``, extra arrays.

        ``k`` must be the next step (0 for an empty run); with ``overwrite=True`` the last
        stored step may be replaced instead. The record is a flat dict of numbers, strings,
        booleans or None (the SPEC §7 names for the table columns); a ``"step"`` entry must
        equal ``k``. The file appears atomically and ``table.csv`` is regenerated.
        """
        k = operator.index(k)
        steps = self.steps
        following = steps[-1] + 1 if steps else 0
        if k in steps and not overwrite:
            raise ValueError(f"step {k} is already stored in {self._path}; it is not "
                             "overwritten unless overwrite=True")
        if k != following and not (overwrite and steps and k == steps[-1]):
            allowed = f"{following}" + (f" (or {steps[-1]} with overwrite=True)" if steps else "")
            raise ValueError(f"step {k} cannot be stored in {self._path}: the next step is "
                             f"{allowed}")
        X = np.ascontiguousarray(X, dtype=np.float64)
        if X.shape != (self.n_vertices, 3) or not np.isfinite(X).all():
            raise ValueError(f"positions of step {k} must be a finite ({self.n_vertices}, 3) "
                             f"array, got shape {X.shape}")
        record = _scalar_dict(record, f"record of step {k}", reserved=("record_json",))
        if record.setdefault("step", k) != k:
            raise ValueError(f"record of step {k} says step {record['step']!r}")
        record = {"step": k, **{key: v for key, v in record.items() if key != "step"}}
        arrays = _check_arrays(arrays)

        def write(f):
            f.create_dataset("X", data=X)
            for key, value in record.items():
                if value is not None:
                    f.attrs[key] = _attribute_value(value)
            f.attrs["record_json"] = json.dumps(record)
            if arrays:
                group = f.create_group("arrays")
                for name, arr in arrays.items():
                    group.create_dataset(name, data=arr)

        self._take_writer_lock()
        path = self._step_path(k)
        atomic_write_bytes(path, _h5_bytes(write))
        # what record() would read back from the file just written
        self._record_cache[k] = (_signature(path), json.loads(json.dumps(record)))
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
        rows = [{**self._stored_record(k), **analysis.get(k, {})} for k in self.steps]
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
        def write(f):
            f.create_dataset("X0", data=X0)
            f.create_dataset("faces", data=faces)
            if rest:
                group = f.create_group("rest")
                for name, arr in rest.items():
                    group.create_dataset(name, data=arr)
        atomic_write_bytes(self._path / MESH_H5, _h5_bytes(write))
        self._mesh_cache = (X0.copy(), faces.copy(), {k: v.copy() for k, v in rest.items()})
