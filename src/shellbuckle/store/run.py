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
                              array_sha256((name, array))}; attribute run_id, the run it
                              was written for
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
  as HDF5, its record parses and names its step, its positions have the run's shape, it names
  this run and its content matches its checksums (step files written before the checksums
  were introduced are read unchecked) — and a damaged one is left out of
  :attr:`RunStore.steps` and the table and listed with what is wrong in
  :attr:`RunStore.damaged`; the good steps stay readable. Resuming
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

This module is the :class:`RunStore` and the folder-level logic (creating, reopening, resuming,
branching, locking, scanning the steps). The parts it builds on: the folder's names and
constants (:mod:`~shellbuckle.store.layout`), the values of run.json
(:mod:`~shellbuckle.store.meta`), the step file format with its checksums and damage reports
(:mod:`~shellbuckle.store.steps`), run.json rebuilt or refused and damaged steps set aside
(:mod:`~shellbuckle.store.repair`), and the per-step table (:mod:`~shellbuckle.store.table`).
"""


from __future__ import annotations

import copy
import json
import logging
import operator
import os
import platform
import sys
import uuid
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..util import now
from .atomic import (FileLock, atomic_write_bytes, fsync_folder, locked_update, locks_work,
                     remove_temporaries, temporary_target)
# the store's names are all importable from here: the public ones and the helpers that other
# modules and the tests use
from .layout import (_INTEGER_COLUMNS, _WRITER_FILES, ANALYSIS_COLUMNS,  # noqa: F401
                     ANALYSIS_JSON, ANALYSIS_LOCK, CHECKSUM_ATTR, DESCRIPTION_ATTR, FORMAT_NAME,
                     FORMAT_VERSION, MESH_H5, REQUIRED_FIELDS, REQUIRED_MESH_FIELDS, RUN_ID_ATTR,
                     RUN_JSON,
                     STATUSES, STEPS_DIR, TABLE_COLUMNS, TABLE_CSV, WRITER_LOCK, _h5_bytes,
                     _has_step_files, _ranges, _read_h5, _read_mesh_arrays, _span, _step_indices,
                     check_format, step_file, write_array)
from .meta import (_differences, _identity, _json_dict, _jsonable, _scalar_dict,  # noqa: F401
                   _session, _short, _versions, source_commit)
from .names import store_file
from .repair import (_check_fields, _how_to_replace_run_json, _read_meta,  # noqa: F401
                     _rebuilt_meta, _redo_branch, _stored_description, damaged_to_set_aside,
                     set_aside_step)
from .steps import (_HDF5_SIGNATURE, _WARNED, DamagedStep, _attribute_value,  # noqa: F401
                    _check_arrays, _check_name, _signature, _text_attribute, array_sha256,
                    damage_summary, mesh_sha256, read_step_file, step_checksums,
                    step_file_bytes)
from .table import _csv_cell, _integer_like, table_columns, table_csv, table_frame  # noqa: F401

if TYPE_CHECKING:  # pandas is imported when a table is asked for
    import pandas

log = logging.getLogger(__name__)


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


#: The mesh files found to be their run's: (folder, mesh.h5's signature, the SHA-256 and run id
#: run.json gives), for :meth:`RunStore.check_mesh`.
_MESHES_CHECKED: set[tuple] = set()


def _description_owner(f) -> str | None:
    """The run id of the copy of run.json an open mesh.h5 holds (None if it holds no
    readable copy)."""
    try:
        text = _text_attribute(f, DESCRIPTION_ATTR)
        owner = json.loads(text).get("run_id") if isinstance(text, str) else None
    except (ValueError, AttributeError):  # not UTF-8, not JSON, not an object
        owner = None
    return owner if isinstance(owner, str) else None


def _read_mesh_and_owner(f) -> tuple:
    """The mesh arrays of an open mesh.h5 and the run id of the copy of run.json it holds."""
    return (*_read_mesh_arrays(f), _description_owner(f))


def _interrupted_creation(path: Path) -> bool:
    """True if ``path`` is empty or holds only what an interrupted ``create`` leaves behind."""
    for entry in os.scandir(path):
        if entry.name in (MESH_H5, WRITER_LOCK, ANALYSIS_LOCK) or temporary_target(entry.name):
            continue
        if entry.name == STEPS_DIR and entry.is_dir() and not os.listdir(entry.path):
            continue
        return False
    return True


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
        self._owner_checked = False
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
                     "sha256": mesh_sha256(X0, faces, rest)},
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
        found = store_file(path)
        if found is not None:  # e.g. inside another run's steps/
            raise ValueError(f"{path} is inside {found[1]}/ of the {found[2]} in {found[0]}, "
                             f"which only that {found[2]}'s store writes; choose another "
                             "folder for the run")
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
        store.check_mesh()  # readable and this run's, before anything is written
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
        store.check_mesh()  # readable and this run's, before anything is written
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
        names = []
        for k in damaged_to_set_aside(self._path, stored, damaged):
            names.append(set_aside_step(self._path, k, damaged[k]))
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

    def current_status(self) -> tuple[str, str | None]:
        """``(status, message)`` as they stand now: run.json's, except that a run whose
        run.json says "running" while no process holds its writer lock was stopped outright
        (SIGKILL, out of memory, a machine that went down; nothing could write its status)
        and is reported ``"interrupted"``, with a message saying so and how to continue.

        The lock is probed once, without waiting (a reader probing it at that moment makes
        the run count as live), then run.json is read again, so that a run which ended
        between the two reads is reported as it ended. Where the lock cannot be probed (a
        read-only copy of the folder, a system without ``flock``) the stored status is
        reported. A lock of a network file system that other machines' locks do not reach is
        free here while a process there writes the run: the message says so."""
        status, message = self._meta["status"], self._meta.get("message")
        if status != "running" or self._writer.held or not locks_work():
            return status, message
        try:
            if self._writer.is_held_elsewhere(patience=0.0):
                return status, message
            meta = json.loads((self._path / RUN_JSON).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return status, message
        if not isinstance(meta, dict) or meta.get("status") not in STATUSES:
            return status, message
        if meta["status"] != "running":
            return meta["status"], meta.get("message")
        after = f" after step {self.last_step}" if self.last_step is not None else ""
        return "interrupted", (
            f"run.json says running, but no process holds its writer lock: it was stopped "
            f"outright (killed, out of memory, or its machine went down){after}; `shellbuckle "
            f"resume {self._path}` continues it (unless a process on another machine writes "
            f"it through a file system whose locks do not reach this one)")

    # ------------------------------------------------------------------ mesh

    def _mesh(self):
        """The mesh arrays of mesh.h5, read once, checked against run.json's SHA-256 of them
        and against the run id of the copy of run.json it holds (ValueError: the mesh file is
        damaged, or run.json is another run's)."""
        if self._mesh_cache is None:
            X0, faces, rest, owner = _read_h5(self._path / MESH_H5, _read_mesh_and_owner)
            if mesh_sha256(X0, faces, rest) != self._meta["mesh"]["sha256"]:
                raise ValueError(
                    f"{self._path / MESH_H5} does not match the mesh {RUN_JSON} describes "
                    f"(SHA-256): the mesh file was changed or damaged, or {RUN_JSON} is "
                    f"another run's; restore the folder from a backup (a {RUN_JSON} removed "
                    f"is rebuilt from the copy in {MESH_H5})")
            self._refuse_owner(owner)
            self._mesh_cache = X0, faces, rest
        return self._mesh_cache

    def _refuse_owner(self, owner: str | None) -> None:
        """ValueError if mesh.h5's copy of run.json names another run than run.json."""
        if owner is not None and owner != self.run_id:
            raise ValueError(
                f"{self._path / RUN_JSON} is another run's (run id {self.run_id[:12]}...) than "
                f"{MESH_H5} (written for run {owner[:12]}...): the folder mixes two runs; "
                f"restore {RUN_JSON} from a backup, or move it aside (`mv "
                f"{self._path / RUN_JSON} {self._path / RUN_JSON}.bad`) and the run opens from "
                f"the copy in {MESH_H5}")
        self._owner_checked = True

    def check_owner(self) -> None:
        """ValueError if ``run.json`` is another run's than the one ``mesh.h5`` was written for
        (their run ids): the folder mixes two runs. Reads only the copy of run.json that
        mesh.h5 holds; a mesh.h5 that is missing or unreadable tells nothing here
        (:meth:`check_mesh` names it). Checked before the steps are first scanned, so that no
        reader takes this run's step files for another run's."""
        if self._owner_checked or self._mesh_cache is not None:
            return
        try:
            owner = _read_h5(self._path / MESH_H5, _description_owner)
        except ValueError:
            return
        self._refuse_owner(owner)

    def check_mesh(self) -> None:
        """ValueError unless mesh.h5 is readable and is the mesh run.json describes (its
        SHA-256 and run id). A verdict is kept for the process while neither file changes
        (modification time, size, inode), so a sweep that checks its runs at the start and
        again for its catalogue reads each mesh once."""
        if self._mesh_cache is not None:
            return
        try:
            key = (str(self._path.resolve()), _signature(self._path / MESH_H5),
                   self._meta["mesh"]["sha256"], self.run_id)
        except (FileNotFoundError, OSError):
            key = None
        if key is not None and key in _MESHES_CHECKED:
            return
        self._mesh()
        if key is not None:
            _MESHES_CHECKED.add(key)

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
        return step_file(self._path, k)

    def _scan(self, warn: bool = True) -> tuple[list[int], dict[int, str]]:
        """The stored steps ``0..K`` (K the highest step file) and the damaged ones among them,
        ``{k: what is wrong}`` (a missing file below K is damaged too).

        Each file is checked once (:func:`read_step_file`) and its verdict kept with its
        signature (modification time, size, inode); only the last file can be replaced
        (``overwrite=True``, a resume that set it aside), so only its signature is taken again
        on a later scan. ``warn``: log a warning when the damaged steps differ from the last
        ones warned about.
        """
        self.check_owner()
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
            record = read_step_file(path, k, self.n_vertices, run_id=self.run_id)[0]
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
            _, X, arrays, _ = read_step_file(path, k, self.n_vertices, parts=parts,
                                             run_id=self.run_id)
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
                              reserved=("record_json", CHECKSUM_ATTR, RUN_ID_ATTR))
        if record.setdefault("step", k) != k:
            raise ValueError(f"record of step {k} says step {record['step']!r}")
        record = {"step": k, **{key: v for key, v in record.items() if key != "step"}}
        arrays = _check_arrays(arrays)
        record_json = json.dumps(record)
        self._take_writer_lock()
        path = self._step_path(k)
        atomic_write_bytes(path, step_file_bytes(X, record, record_json, arrays, self.run_id))
        # what record() would read back from the file just written
        self._step_cache[k] = (_signature(path), json.loads(record_json), None)
        self._write_table()

    # ------------------------------------------------------------------ table and analysis

    def analysis(self, *, warn: bool = True) -> dict[int, dict]:
        """Analysis results per step, as stored in ``analysis.json`` (empty if none; an entry
        that is not a JSON object is left out, with a warning unless ``warn`` is False, and
        analysed again where asked; a file that is not a JSON object of steps: ValueError)."""
        try:
            text = (self._path / ANALYSIS_JSON).read_text(encoding="utf-8")
        except FileNotFoundError:
            return {}
        try:
            entries = {int(k): v for k, v in json.loads(text).items()}
        except (json.JSONDecodeError, AttributeError, ValueError) as exc:
            raise ValueError(f"{self._path / ANALYSIS_JSON} is damaged ({exc})") from None
        damaged = sorted(k for k, v in entries.items() if not isinstance(v, dict))
        if damaged and warn:  # derived from the steps: analysed again where asked
            log.warning("%s: the entries of steps %s are not analyses (JSON objects): they are "
                        "ignored; `shellbuckle analyze %s` makes them again",
                        self._path / ANALYSIS_JSON, ", ".join(map(str, damaged)), self._path)
        return {k: v for k, v in entries.items() if k not in damaged}

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
        with locked_update(self._path, ANALYSIS_JSON, ANALYSIS_LOCK):
            merged = self.analysis(warn=False)  # the entries left out are replaced
            for k, values in updates.items():
                merged.setdefault(k, {}).update(values)
            text = json.dumps({str(k): merged[k] for k in sorted(merged)}, indent=1)
            atomic_write_bytes(self._path / ANALYSIS_JSON, text.encode("utf-8"))
        if self._writer.held:
            self._write_table()
        elif self._writer.acquire():  # no live writer: refresh table.csv ourselves
            try:
                self._write_table()
            finally:
                self._writer.release()

    def _rows(self, warn: bool = True) -> tuple[list[dict], list[str]]:
        """The table's rows (record and analysis of every step, as stored) and its columns,
        in the order :meth:`table` documents. The rows share the cached records: read only.
        ``warn``: as :meth:`analysis` (table.csv is written after every step: no warning
        there, or a long run would repeat it at every step)."""
        analysis = self.analysis(warn=warn)
        stored, damaged = self._scan()
        rows = [{**self._step_cache[k][1], **analysis.get(k, {})}
                for k in stored if k not in damaged]
        return rows, table_columns(rows)

    def table(self) -> pandas.DataFrame:
        """The per-step table as a DataFrame, one row per finished step.

        Columns: SPEC §7 names in order (``step`` ... ``wall_s``, always present, NaN where a
        step did not record them), then the analysis columns ``shape``, ``n_dimples``,
        ``corners``, ``W`` if any step has them, then any other recorded or analysis names in
        order of appearance. Integer-valued columns such as ``iterations`` are int64, or the
        nullable ``Int64`` where some steps lack them.
        """
        return table_frame(*self._rows())

    def _write_table(self) -> None:
        """``table.csv`` from the stored records, with the csv module rather than through
        :meth:`table` (pandas takes ~7 ms a step for what this writes in well under one);
        ``pandas.read_csv`` reads it back to the table's values."""
        atomic_write_bytes(self._path / TABLE_CSV, table_csv(*self._rows(warn=False)))

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
            write_array(f, "X0", X0)
            write_array(f, "faces", faces)
            if rest:
                group = f.create_group("rest")
                for name, arr in rest.items():
                    write_array(group, name, arr)
            f.attrs[DESCRIPTION_ATTR] = description  # run.json as created, to rebuild it
        atomic_write_bytes(self._path / MESH_H5, _h5_bytes(write))
        self._mesh_cache = (X0.copy(), faces.copy(), {k: v.copy() for k, v in rest.items()})
