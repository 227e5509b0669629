"""What is wrong with a path given as a run folder, found without loading the run store's
readers (h5py): a command refuses a missing folder or a file before any heavy import."""

from __future__ import annotations

from pathlib import Path


def folder_problem(path) -> str | None:
    """Why ``path`` cannot be a run folder (it does not exist, or it is a file), or None."""
    path = Path(path)
    if not path.exists():
        return "does not exist; expected a run folder (made by `shellbuckle deflate --out DIR`)"
    if not path.is_dir():
        return "is a file, not a run folder"
    return None
