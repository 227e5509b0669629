"""The names of the files a run folder and a sweep folder keep (:mod:`.layout`,
:mod:`.located`, :mod:`.catalogue`), and :func:`store_file`: whether a path is one of them.

A light module (no HDF5, no pandas), so that a command refuses to write over a store's file
before it loads anything.
"""

from __future__ import annotations

import os
from pathlib import Path

RUN_JSON, MESH_H5, STEPS_DIR = "run.json", "mesh.h5", "steps"
TABLE_CSV, ANALYSIS_JSON = "table.csv", "analysis.json"
WRITER_LOCK, ANALYSIS_LOCK = ".lock", ".analysis.lock"
LOCATED_JSON, LOCATED_LOCK = "located.json", ".located.lock"
#: Held while a process locates the run's events (:func:`shellbuckle.locate.locate`).
LOCATING_LOCK = ".locating.lock"
SWEEP_JSON, CATALOGUE_CSV, LOGS_DIR = "sweep.json", "catalogue.csv", "logs"

#: The files and folders a run folder keeps (a folder holding ``run.json``).
RUN_FILES = (RUN_JSON, MESH_H5, STEPS_DIR, TABLE_CSV, ANALYSIS_JSON, WRITER_LOCK,
             ANALYSIS_LOCK, LOCATED_JSON, LOCATED_LOCK, LOCATING_LOCK)
#: Those of a sweep folder (a folder holding ``sweep.json``).
SWEEP_FILES = (SWEEP_JSON, CATALOGUE_CSV, LOGS_DIR)


def store_file(path) -> tuple[Path, str, str] | None:
    """Whether ``path`` is a file a run or sweep folder keeps, or lies inside one of its
    folders (a run's ``steps/``, a sweep's ``logs/``): ``(folder, entry, kind)`` with the
    folder, the store's entry on the way to ``path`` and ``"run"`` or ``"sweep"``; None for a
    path a command may write. The folder is recognized by its description (``run.json``,
    ``sweep.json``)."""
    path = Path(os.path.realpath(path))  # through symbolic links and ".." (a loop: as is)
    for depth, folder in enumerate(path.parents):
        if depth > 1:
            return None
        entry = path.parts[len(folder.parts)]  # the child of ``folder`` on the way to ``path``
        if (folder / RUN_JSON).exists() and entry in RUN_FILES:
            return folder, entry, "run"
        if (folder / SWEEP_JSON).exists() and entry in SWEEP_FILES:
            return folder, entry, "sweep"
    return None


def refuse_store_file(path, also=(), *, option: str | None = None) -> None:
    """ValueError if ``path``, or a file written beside it (``also``), is a file of a run or
    sweep folder's store or lies inside its ``steps/`` or ``logs/`` (:func:`store_file`);
    ``option``: the command-line option that gave ``path``, which heads the message."""
    path = Path(path)
    for target in (path, *also):
        found = store_file(target)
        if found is None:
            continue
        folder, entry, kind = found
        beside = "" if Path(target) == path else f" (it writes {Path(target).name} beside it)"
        if Path(os.path.realpath(target)).name == entry:
            what = f"{entry} belongs to the {kind} in {folder}"
        else:
            what = f"{Path(target).name} would be inside {entry}/ of the {kind} in {folder}"
        head = f"{option} {path}" if option else f"{str(path)!r}"
        raise ValueError(f"{head}: {what}{beside}, which only the {kind}'s store writes; "
                         "write elsewhere")
