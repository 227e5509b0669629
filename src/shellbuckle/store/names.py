"""The names of the files a run folder and a sweep folder keep (:mod:`.layout`,
:mod:`.located`, :mod:`.catalogue`), and :func:`store_file`: whether a path is one of them.

A light module (no HDF5, no pandas), so that a command refuses to write over a store's file
before it loads anything.
"""

from __future__ import annotations

from pathlib import Path

RUN_JSON, MESH_H5, STEPS_DIR = "run.json", "mesh.h5", "steps"
TABLE_CSV, ANALYSIS_JSON = "table.csv", "analysis.json"
WRITER_LOCK, ANALYSIS_LOCK = ".lock", ".analysis.lock"
LOCATED_JSON, LOCATED_LOCK = "located.json", ".located.lock"
SWEEP_JSON, CATALOGUE_CSV, LOGS_DIR = "sweep.json", "catalogue.csv", "logs"

#: The files and folders a run folder keeps (a folder holding ``run.json``).
RUN_FILES = (RUN_JSON, MESH_H5, STEPS_DIR, TABLE_CSV, ANALYSIS_JSON, WRITER_LOCK,
             ANALYSIS_LOCK, LOCATED_JSON, LOCATED_LOCK)
#: Those of a sweep folder (a folder holding ``sweep.json``).
SWEEP_FILES = (SWEEP_JSON, CATALOGUE_CSV, LOGS_DIR)


def store_file(path) -> tuple[Path, str, str] | None:
    """Whether ``path`` is a file a run or sweep folder keeps, or lies inside one of its
    folders (a run's ``steps/``, a sweep's ``logs/``): ``(folder, entry, kind)`` with the
    folder, the store's entry on the way to ``path`` and ``"run"`` or ``"sweep"``; None for a
    path a command may write. The folder is recognized by its description (``run.json``,
    ``sweep.json``)."""
    path = Path(path).absolute()
    for depth, folder in enumerate(path.parents):
        if depth > 1:
            return None
        entry = path.parts[len(folder.parts)]  # the child of ``folder`` on the way to ``path``
        if (folder / RUN_JSON).exists() and entry in RUN_FILES:
            return folder, entry, "run"
        if (folder / SWEEP_JSON).exists() and entry in SWEEP_FILES:
            return folder, entry, "sweep"
    return None
