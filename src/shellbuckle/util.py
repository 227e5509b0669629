"""Small helpers shared by the store, the sweep, the studies and the command line.

Nothing here knows about shells: a timestamp, plain JSON values and the interrupt behind an
exception. The module imports only
the standard library, so any module of the package may use it.
"""

from __future__ import annotations

import datetime as _dt
import math


def now() -> str:
    """The current UTC time as ISO 8601 to the second, e.g. ``2026-12-04T19:42:29+00:00``
    (the timestamps of ``run.json``, ``sweep.json`` and a sweep's attempts)."""
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def plain(value, *, strict: bool = False):
    """``value`` as plain JSON values: dict keys as strings, tuples as lists, NumPy scalars as
    Python ones (``np.bool_`` as ``bool``). With ``strict``, non-finite floats become None
    (strict JSON); otherwise they are kept (``json.dumps`` writes them as ``NaN``)."""
    if isinstance(value, dict):
        return {str(k): plain(v, strict=strict) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v, strict=strict) for v in value]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)) \
            and getattr(value, "ndim", 0) == 0:
        value = value.item()
    if strict and isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def json_safe(value):
    """``value`` ready for strict JSON: :func:`plain` with non-finite floats replaced by None."""
    return plain(value, strict=True)


def interrupt_of(exc: BaseException) -> KeyboardInterrupt | None:
    """The interrupt (a ``KeyboardInterrupt``, or a subclass such as the CLI's SIGTERM) behind
    ``exc``, or None: ``exc`` itself, or one in its chain of causes and contexts. An interrupt
    that arrives inside a compiled call (a Numba kernel, a linear solver) surfaces as another
    exception, e.g. ``SystemError: ... returned a result with an exception set``, whose
    context is the interrupt."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None
