"""The step file format: one HDF5 file per finished step, written whole and checked whenever
it is read.

A step file holds the positions ``X (V, 3)`` float64, the step record as attributes (one per
column, and all of it as JSON in ``record_json``), optional extra arrays in the group
``arrays/``, in the attribute ``sha256`` the SHA-256 checksums of that content
(:func:`step_checksums`) and in the attribute ``run_id`` the id of the run it was written for.
:func:`read_step_file` verifies a file (HDF5 signature and structure, the run it belongs to,
the record naming its step, the positions' shape, dtype and finiteness, the checksums) and
raises :class:`DamagedStep` saying what is wrong; :func:`damage_summary` puts the damaged
steps of a run and what to do about them in one line.
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Mapping
from pathlib import Path

import h5py
import numpy as np

from .layout import CHECKSUM_ATTR, RUN_ID_ATTR, _h5_bytes, _ranges, write_array

#: The run store's logger: its messages keep the name they are shown with
#: (``shellbuckle.store.run``), whichever module of the store writes them.
log = logging.getLogger("shellbuckle.store.run")

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def array_sha256(*named_arrays) -> str:
    """SHA-256 over ``(name, array)`` pairs: name, little-endian dtype, shape and raw bytes."""
    h = hashlib.sha256()
    for name, arr in named_arrays:
        a = np.ascontiguousarray(arr)
        a = a.astype(a.dtype.newbyteorder("<"), copy=False)
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def mesh_sha256(X0, faces, rest: Mapping) -> str:
    """The SHA-256 of a run's mesh (``run.json``'s ``mesh.sha256``): the reference positions,
    the faces and the rest-state arrays by name (:func:`array_sha256`)."""
    return array_sha256(("X0", X0), ("faces", faces), *sorted(rest.items()))


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


def _text_attribute(f, name: str):
    try:
        value = f.attrs[name]
    except KeyError:
        return None
    return value.decode("utf-8") if isinstance(value, bytes) else value


def read_step_file(path: Path, k: int, n_vertices: int | None = None, *,
                   parts: str = "all", run_id: str | None = None):
    """``(record, X, arrays, checked)`` of the step file ``path`` of step ``k``, verified:
    it opens as HDF5, its record parses as a dict naming step ``k``, ``X`` is a finite
    ``(n_vertices, 3)`` float64 array, and the content matches its checksums (``checked`` is
    False for a file written before the checksums, which cannot be checked).
    :class:`DamagedStep` naming the file and what is wrong otherwise.

    ``parts``: ``"all"``; or ``"X"`` or ``"arrays"`` to read and check only the positions or
    only the extra arrays (the other values are then None). ``run_id``: the run the file must
    belong to; a file written for another run (copied from another run's folder) is damaged.
    A file written before step files named their run is read whatever its run.
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
            owner = _text_attribute(f, RUN_ID_ATTR)
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
    if run_id is not None and owner is not None and owner != run_id:
        raise DamagedStep(f"{name} is a step of another run (run id {str(owner)[:12]}..., this "
                          f"run's is {run_id[:12]}...): it was copied from another run's "
                          "folder")
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


def _attribute_value(value):
    """A JSON scalar as an HDF5 attribute value (None is only kept in ``record_json``)."""
    return value if not isinstance(value, str) else np.array(value, dtype=h5py.string_dtype())


def step_file_bytes(X: np.ndarray, record: dict, record_json: str,
                    arrays: Mapping[str, np.ndarray], run_id: str | None = None) -> bytes:
    """The bytes of the step file holding positions ``X``, the step ``record`` (one attribute
    per non-None value, and all of it as ``record_json``), the extra ``arrays`` in the group
    ``arrays/``, the checksums of all of it (:func:`step_checksums`) and, if given, the id of
    the run it belongs to (attribute ``run_id``)."""

    def write(f):
        write_array(f, "X", X)
        for key, value in record.items():
            if value is not None:
                f.attrs[key] = _attribute_value(value)
        f.attrs["record_json"] = record_json
        if arrays:
            group = f.create_group("arrays")
            for name, arr in arrays.items():
                write_array(group, name, arr)
        f.attrs[CHECKSUM_ATTR] = json.dumps(step_checksums(X, record_json, arrays))
        if run_id is not None:
            f.attrs[RUN_ID_ATTR] = run_id

    return _h5_bytes(write)


def _signature(path: Path) -> tuple[int, int, int]:
    """Modification time, size and inode of a file: they change when it is replaced."""
    stat = path.stat()
    return stat.st_mtime_ns, stat.st_size, stat.st_ino


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
