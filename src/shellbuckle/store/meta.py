"""What run.json holds, as plain JSON: parameters, protocols, step records and analysis
results converted to JSON values (numpy scalars and arrays included, anything else refused by
name), the package and dependency versions and git commit of a session, the identity that
tells two runs apart, and a readable list of where two descriptions differ.
"""

from __future__ import annotations

import functools
import json
import math
import os
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path

import h5py
import numpy as np

from ..util import now


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


def _identity(meta: dict) -> dict:
    """What makes two runs the same run: parameters, protocol, mesh hash and parent."""
    parent = meta.get("parent")
    if parent is not None:
        parent = {key: parent[key] for key in ("run_id", "step", "positions_sha256")}
    return {"params": meta["params"], "protocol": meta["protocol"],
            "mesh_sha256": meta["mesh"]["sha256"], "parent": parent}


def _pandas_version() -> str:
    """pandas' version without importing it (0.25 s) when a run has not needed it yet."""
    if "pandas" in sys.modules:
        return sys.modules["pandas"].__version__
    from importlib.metadata import version

    return version("pandas")


def _versions() -> dict:
    # the modules' own version attributes: importlib.metadata scans the installed
    # distributions (about 5 ms a call, twice per run)
    import scipy

    from .. import __version__

    versions = {"python": sys.version.split()[0], "numpy": np.__version__,
                "h5py": h5py.__version__, "hdf5": h5py.version.hdf5_version,
                "pandas": _pandas_version(), "shellbuckle": __version__,
                "scipy": scipy.__version__}
    commit = source_commit()
    if commit:
        versions["shellbuckle_git"] = commit
    return versions


@functools.lru_cache(maxsize=None)
def source_commit(package: Path | None = None) -> str | None:
    """The git commit of shellbuckle's source (``package``: its folder, by default this
    one's): when it runs from a git checkout (an editable install), that checkout's commit,
    with ``+dirty`` if the package's files differ from it; when it was installed from a
    checkout (``pip install .``), the commit the build recorded in ``_build.json`` (see
    ``setup.py``); None otherwise (an install from an archive without git).

    The package version does not tell two commits apart, and after buckling a run's
    trajectory depends on the code down to round-off, so the commit is what reproduces a run."""
    package = Path(__file__).resolve().parents[1] if package is None else Path(package)
    git = ["git", "--no-optional-locks", "-C", str(package)]
    try:
        tracked = subprocess.run(git + ["ls-files", "--", "__init__.py"], capture_output=True,
                                 text=True, timeout=10, check=True).stdout.strip()
        if tracked:
            commit = subprocess.run(git + ["rev-parse", "--short=12", "HEAD"],
                                    capture_output=True, text=True, timeout=10,
                                    check=True).stdout.strip()
            dirty = subprocess.run(git + ["status", "--porcelain", "--", "."],
                                   capture_output=True, text=True, timeout=10,
                                   check=True).stdout.strip()
            return f"{commit}+dirty" if dirty else commit or None
    except (OSError, subprocess.SubprocessError):
        pass
    return _built_commit(package)


def _built_commit(package: Path) -> str | None:
    """The commit ``setup.py`` recorded in ``package/_build.json`` at build time, if any."""
    try:
        commit = json.loads((package / "_build.json").read_text(encoding="utf-8")).get("git")
    except (OSError, ValueError, AttributeError):
        return None
    return commit if isinstance(commit, str) and commit else None


def _session() -> dict:
    return {"started": now(), "command_line": list(sys.argv), "versions": _versions()}
