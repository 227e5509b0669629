"""Located transitions of a run: ``located.json`` in the run folder.

A refinement of the run, not part of its protocol: the volume at which each buckling event
happens, found by bisection between two stored steps (:mod:`shellbuckle.locate`). The table
and the steps are never changed by it. The file maps an event name to its located point::

    {"version": 2,
     "events": {"primary_buckling": {"step": 3, "tol": 1e-4, "lo": ..., "hi": ...,
                                     "dV_over_V": ..., "uncertainty": ..., "old": {...},
                                     "new": {...}, "evaluations": [...], ...}, ...}}

Version 2: every evaluation of the bisection starts from the stored step before the event.
A version-1 file (whose bisection advanced its start, so that a barrier crossing closed on a
point of its own grid) is ignored with a warning and replaced when the run is located again.

It is replaced atomically under its own lock, one event at a time, so an interrupted location
keeps the events already located. One process at a time locates a run's events: it holds
``.locating.lock`` while it does (:func:`locating`), and another waits for it. A file that
cannot be read is reported and treated as absent (the location can be made again: it is
derived from the stored steps).
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
from collections.abc import Mapping
from pathlib import Path

from ..util import json_safe
from .atomic import FileLock, atomic_write_bytes, locked_update
from .names import LOCATED_JSON, LOCATED_LOCK, LOCATING_LOCK  # noqa: F401

log = logging.getLogger(__name__)

LOCATED_VERSION = 2
#: Default tolerance of a located event, in dV/V (the final bracket's width).
LOCATE_TOL = 1e-4


def read_located(folder, *, warn: bool = True) -> dict[str, dict]:
    """The located events of the run in ``folder``, ``{name: point}`` (empty if none, or if
    the file is damaged or of an older version; an entry that is not a located point, a JSON
    object with the fields every point has (:func:`_is_point`), is left out: a warning says so
    unless ``warn`` is False)."""
    path = Path(folder) / LOCATED_JSON
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return {}
    try:
        data = json.loads(text)
        if data.get("version") == 1:
            raise ValueError("located by a bisection that advanced its start (version 1), "
                             "whose barrier crossings are not the protocol's thresholds")
        if data.get("version") != LOCATED_VERSION or not isinstance(data.get("events"), dict):
            raise ValueError(f"version {data.get('version')!r}, expected {LOCATED_VERSION}")
        events = dict(data["events"])
    except (json.JSONDecodeError, UnicodeDecodeError, AttributeError, ValueError) as exc:
        if not warn:
            return {}
        log.warning("%s cannot be read (%s): the located events are ignored; "
                    "`shellbuckle locate %s` locates them again", path, exc, Path(folder))
        return {}
    damaged = sorted(name for name, point in events.items() if not _is_point(point))
    if damaged and warn:
        log.warning("%s: the entries %s are not located points: they are ignored; "
                    "`shellbuckle locate %s` locates them again", path, ", ".join(damaged),
                    Path(folder))
    return {name: point for name, point in events.items() if name not in damaged}


#: The fields every located point has, with numbers: the events, the catalogue and the
#: tables read them (:func:`shellbuckle.locate._locate_event` writes them all).
POINT_NUMBERS = ("dV_over_V", "uncertainty", "lo", "hi")


def _is_point(point) -> bool:
    """Whether ``point`` has the form of a located point: a JSON object with an integer
    ``step``, finite numbers :data:`POINT_NUMBERS` and a ``mechanism``."""
    def number(v):
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

    return (isinstance(point, dict) and isinstance(point.get("step"), int)
            and not isinstance(point.get("step"), bool)
            and all(number(point.get(k)) for k in POINT_NUMBERS)
            and isinstance(point.get("mechanism"), str))


def write_located(folder, events: Mapping[str, Mapping]) -> None:
    """Add or replace the located points ``{name: point}`` of the run in ``folder`` (a damaged
    or older file is replaced without a warning: the points it held are made again)."""
    folder = Path(folder)
    with locked_update(folder, LOCATED_JSON, LOCATED_LOCK):
        merged = read_located(folder, warn=False) | {name: dict(point)
                                                     for name, point in events.items()}
        text = json.dumps(json_safe({"version": LOCATED_VERSION, "events": merged}), indent=1,
                          allow_nan=False)
        atomic_write_bytes(folder / LOCATED_JSON, text.encode("utf-8"))


@contextlib.contextmanager
def locating(folder):
    """Hold the run's location lock while the block locates its events, waiting (with a
    warning) while another process holds it: a second sweep on the same folder, or
    ``shellbuckle locate``, started while a location runs, then finds the events located
    instead of making the same bisections at the same time."""
    lock = FileLock(Path(folder) / LOCATING_LOCK)
    if not lock.acquire():
        log.warning("another process is locating the events of %s (it holds %s); waiting for "
                    "it", folder, Path(folder) / LOCATING_LOCK)
        lock.acquire(blocking=True)
    try:
        yield
    finally:
        lock.release()
