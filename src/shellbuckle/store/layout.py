"""The layout of a run folder (format ``shellbuckle-run``, described in
:mod:`shellbuckle.store.run`): the format's name and version, the names of its files, locks and
HDF5 attributes, the table's columns and the fields run.json must have; the check of a
description's format, the step files' names and indices, and reading or building a whole HDF5
file of the folder.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import h5py
import numpy as np

FORMAT_NAME = "shellbuckle-run"
FORMAT_VERSION = 1

#: Per-step table columns of SPEC §7, in this order, always present (NaN where not recorded).
TABLE_COLUMNS = ("step", "target_dV_over_V", "dV_over_V", "E_total", "E_bend", "E_stretch",
                 "E_over_kappa", "E_before_c0_cycle", "pressure", "grad_norm", "iterations",
                 "inertia", "min_distance", "wall_s")
#: Analysis columns of SPEC §7, placed after TABLE_COLUMNS when any step has them.
ANALYSIS_COLUMNS = ("shape", "n_dimples", "corners", "W")
STATUSES = ("running", "paused", "finished", "failed", "interrupted")

from .names import (ANALYSIS_JSON, ANALYSIS_LOCK, MESH_H5, RUN_JSON, STEPS_DIR,  # noqa: F401
                    TABLE_CSV, WRITER_LOCK)
#: Key of PARDISO's mode in a run's ``meta["extra"]``: ``"plain"`` or ``"reproducible"``
#: (:mod:`shellbuckle.solve.linear`); a run stored without it was made in the reproducible mode.
SOLVER_MODE = "pardiso_mode"
_WRITER_FILES = {RUN_JSON, MESH_H5, TABLE_CSV}
_INTEGER_COLUMNS = {"step", "iterations", "inertia", "n_dimples", "corners", "W"}
#: Attribute of a step file holding the checksums of its content (JSON), and of mesh.h5
#: holding a copy of run.json as created.
CHECKSUM_ATTR, DESCRIPTION_ATTR = "sha256", "run_json"
#: The attribute of a step file naming the run it was written for (its run id).
RUN_ID_ATTR = "run_id"
#: Fields every run.json has (all written since format version 1), and those of its "mesh".
REQUIRED_FIELDS = {"run_id": str, "params": dict, "protocol": dict, "mesh": dict,
                   "status": str, "sessions": list}
REQUIRED_MESH_FIELDS = {"n_vertices": int, "sha256": str}


def check_format(data, file: Path, name: str, version: int) -> dict:
    """``data``, read from ``file``, if it describes format ``name`` in a version up to
    ``version`` (ValueError otherwise); the check of ``run.json`` and ``sweep.json``."""
    if not isinstance(data, dict) or data.get("format") != name:
        raise ValueError(f"{file} is not a {name} description")
    found = data.get("format_version", 0)
    if isinstance(found, bool) or not isinstance(found, int):
        raise ValueError(f"{file} has a format_version {found!r} that is not an integer; "
                         "the file is damaged")
    if found > version:
        raise ValueError(f"{file.parent} was written in {name} format version "
                         f"{data['format_version']}; this shellbuckle reads up to version "
                         f"{version}, please upgrade")
    return data


def step_file(path: Path, k: int) -> Path:
    """The file of step ``k`` in the run folder ``path``: ``steps/step_000123.h5``."""
    return path / STEPS_DIR / f"step_{k:06d}.h5"


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


def _span(steps) -> str:
    """``0..5`` for contiguous step indices (``0..0`` for one), else :func:`_ranges`."""
    steps = list(steps)
    if steps and steps == list(range(steps[0], steps[-1] + 1)):
        return f"{steps[0]}..{steps[-1]}"
    return _ranges(steps)


COMPRESS_MIN_SIZE = 4096
"""Arrays of at least this many elements are stored compressed (gzip level 4 after a byte
shuffle, one chunk per array: every step is its own file, so a chunk is a step's array);
smaller ones are stored plain, where compression would only add its headers."""


def write_array(group, name: str, arr) -> None:
    """Store ``arr`` as the dataset ``name`` of the HDF5 ``group``, compressed when large
    (:data:`COMPRESS_MIN_SIZE`); the values read back are the same bits either way."""
    arr = np.asarray(arr)
    if arr.size >= COMPRESS_MIN_SIZE and arr.dtype.kind in "fiub":
        group.create_dataset(name, data=arr, chunks=arr.shape, compression="gzip",
                             compression_opts=4, shuffle=True)
    else:
        group.create_dataset(name, data=arr)


def _h5_bytes(write) -> bytes:
    """The bytes of a complete HDF5 file built in memory by ``write(h5py.File)``."""
    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as f:
        write(f)
    return buffer.getvalue()


def _read_h5(path: Path, read):
    try:
        with h5py.File(path, "r", locking=False) as f:
            return read(f)
    except FileNotFoundError:
        raise ValueError(f"{path} is missing; the run folder is damaged") from None
    except OSError as exc:
        raise ValueError(f"{path} cannot be read as HDF5 ({exc}); the run folder is "
                         "damaged") from None
    except KeyError as exc:
        raise ValueError(f"{path} lacks the dataset {exc}; the run folder is damaged") from None


def _read_mesh_arrays(f) -> tuple:
    rest = {name: f["rest"][name][()] for name in f["rest"]} if "rest" in f else {}
    return f["X0"][()], f["faces"][()], rest
