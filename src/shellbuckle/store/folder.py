"""What is wrong with a path given as a run folder, found without loading the run store's
readers (h5py): a command refuses a missing folder or a file before any heavy import."""

from __future__ import annotations

from pathlib import Path


def check_run_folder(path) -> None:
    """ValueError, starting with ``path``, where ``path`` cannot be a run folder: it does not
    exist, or it is a file."""
    if not Path(path).exists():
        raise ValueError(f"{path} does not exist; expected a run folder (made by "
                         "`shellbuckle deflate --out DIR`)")
    if not Path(path).is_dir():
        raise ValueError(f"{path} is a file, not a run folder")
