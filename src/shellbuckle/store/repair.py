"""Opening a run folder whose description is missing or broken, and what to do about damage.

:func:`_read_meta` reads run.json; when it is missing, the description is rebuilt from the copy
kept in the attribute ``run_json`` of mesh.h5 and checked against the SHA-256 of the mesh
arrays. A run.json that is not JSON or lacks the fields every run has, a run without its
``steps/`` folder, and a description that cannot be rebuilt are refused with a message saying
what to do (move run.json aside, restore it from a backup, recreate the folder, run the
command again). Before a resume writes, damaged last steps are renamed
``step_K.h5.damaged-<n>`` to be computed again; a damaged step followed by good ones is
refused with the step a new run can continue from.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from pathlib import Path

import h5py

from ..util import now
from .atomic import set_aside
from .folder import check_run_folder
from .layout import (DESCRIPTION_ATTR, FORMAT_NAME, FORMAT_VERSION, MESH_H5, REQUIRED_FIELDS,
                     REQUIRED_MESH_FIELDS, RUN_JSON, STEPS_DIR, _has_step_files, _ranges,
                     _read_h5, _read_mesh_arrays, check_format, step_file)
from .steps import mesh_sha256

#: The run store's logger: its messages keep the name they are shown with
#: (``shellbuckle.store.run``), whichever module of the store writes them.
log = logging.getLogger("shellbuckle.store.run")


def _read_meta(path: Path) -> tuple[dict, bool]:
    """The contents of ``path/run.json`` and False, or the description rebuilt from
    ``mesh.h5`` and True when run.json is missing; ValueError with a clear message (what to do)
    if no run can be read there."""
    check_run_folder(path)
    try:
        text = (path / RUN_JSON).read_text(encoding="utf-8")
    except FileNotFoundError:
        return _rebuilt_meta(path), True
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path / RUN_JSON} is not valid JSON ({exc}); "
                         + _how_to_replace_run_json(path)) from None
    except IsADirectoryError:
        raise ValueError(f"{path / RUN_JSON} is a folder, not the run's description; "
                         + _how_to_replace_run_json(path)) from None
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
    if mesh_sha256(X0, faces, rest) \
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


def _redo_branch(store) -> str:
    """How to make the step 0 of the branch ``store`` again."""
    parent = store.parent
    return (f"Run the command that made this run again (`shellbuckle continue "
            f"{parent['path']} --step {parent['step']} --out {store.path}` with the same "
            "options): it writes step 0 from the parent and goes on")


def damaged_to_set_aside(path: Path, stored, damaged: Mapping[int, str]) -> list[int]:
    """The damaged last steps of the run in ``path``, sorted, for a resume to set aside and
    compute again. ValueError if a damaged (or missing) step has good steps after it: naming
    it and the last good step before it, from which a new run can continue."""
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
                   f"run from it: `shellbuckle continue {path} --step {k} --out "
                   f"NEW_DIR` (the same as `shellbuckle deflate --from {path} --step "
                   f"{k} --out NEW_DIR`)")
        else:
            how = ("No good step comes before it: compute the run again in a new folder "
                   "with its options (`shellbuckle deflate ... --out NEW_DIR`)")
        raise ValueError(
            f"step {first} of run {path} is damaged ({damaged[first]}){also}; "
            f"steps after it exist, so the run cannot go on from its last step. {how}. "
            "The good steps stay readable.")
    return sorted(trailing)


def set_aside_step(path: Path, k: int, what: str) -> str:
    """Rename the damaged step file ``k`` of the run in ``path`` to ``step_K.h5.damaged-<n>``
    (the first ``n`` not taken; never deleted) and return the new name; ``what`` is what is
    wrong with it, for the log."""
    target = set_aside(step_file(path, k))
    log.warning("run %s: set aside the damaged step %d (%s) as %s/%s; it is computed "
                "again", path, k, what, STEPS_DIR, target.name)
    return target.name
