"""What a minimization tells a listener while it runs: one call per accepted step.

A step of the protocol on a fine mesh is minutes of minimization, so a progress display needs
word from inside it. Newton's method (:mod:`.newton`), its relaxation (:mod:`.relax`), the
gradient methods (:mod:`.cg`) and the minimization at a given pressure (:mod:`.pressure`,
which reports its enthalpy) call :func:`accepted` after every accepted step. The listener
installed with :func:`listening` in the calling thread's context receives ``(E, r_norm)``: the
energy reached and the projected gradient's norm (at the step's end for Newton's method, at
its start for the others, which do not evaluate it at the end). Without a listener a call
costs one context-variable lookup. The listener must be quick (a display throttles itself); if
it raises, the error is logged and the listener removed for the rest of its block, so that a
display never stops a minimization.
"""

from __future__ import annotations

import logging
import threading
from contextlib import contextmanager
from contextvars import ContextVar

log = logging.getLogger(__name__)

#: ``[listener, thread id]`` of the innermost :func:`listening` block, or None.
_LISTENER: ContextVar = ContextVar("shellbuckle_minimization_listener", default=None)


@contextmanager
def listening(listener):
    """Call ``listener(E, r_norm)`` after every accepted step of the minimizations made in
    this block, by this thread only (also where new threads inherit the context); a nested
    block replaces it for its extent."""
    token = _LISTENER.set([listener, threading.get_ident()])
    try:
        yield
    finally:
        _LISTENER.reset(token)


def accepted(E: float, r_norm: float) -> None:
    """Tell the listener of this block, if any, that a step was accepted."""
    entry = _LISTENER.get()
    if entry is None or entry[0] is None or entry[1] != threading.get_ident():
        return
    try:
        entry[0](E, r_norm)
    except Exception as exc:  # noqa: BLE001 - a display never stops a minimization
        log.warning("a progress display failed and is switched off: %s: %s",
                    type(exc).__name__, exc)
        entry[0] = None  # for the rest of the block
