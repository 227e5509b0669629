"""The protocol's context for a stored run: the linear solver in the mode the run was made in.

A run stores the PARDISO mode of its factorizations (``SOLVER_MODE`` in its run.json: the
plain mode on one thread, or the reproducible mode, bitwise the same on any number of
threads; :mod:`shellbuckle.solve.pardiso`). Whatever computes more of a stored run (a resume,
the location of its buckling events) sets the protocol up here, in that mode, so that it
computes exactly what the run's own steps computed.
"""

from __future__ import annotations

import logging

from ..store.layout import SOLVER_MODE
from . import deflate as protocol_mod

log = logging.getLogger(__name__)

MODES = ("plain", "reproducible")


def stored_mode(store) -> str:
    """The PARDISO mode stored with the run (``"reproducible"`` for runs stored before the
    mode was)."""
    mode = store.meta.get("extra", {}).get(SOLVER_MODE, "reproducible")
    if mode not in MODES:
        raise ValueError(f"{store.path} stores PARDISO mode {mode!r}; expected 'plain' or "
                         f"'reproducible'")
    return mode


def init_stored(store, mesh, params, protocol, threads: int | None):
    """``protocol_mod.init`` for the run in ``store`` (its rest state, its PARDISO mode; a
    run made in the plain mode goes on on one thread, whatever ``threads`` asks)."""
    mode = stored_mode(store)
    if mode == "plain" and threads is not None and threads > 1:
        log.info("run %s was made in PARDISO's plain mode on one thread: it goes on on one "
                 "thread (%d asked) to give the same bits", store.path, threads)
    return protocol_mod.init(mesh, params, protocol, form_factors=store.rest.get("form_factors"),
                             threads=1 if mode == "plain" else threads,
                             reproducible=mode == "reproducible")


def stored_context(run, threads: int | None = None):
    """The protocol's context (:func:`.deflate.init`) of a stored run (a
    :class:`~shellbuckle.store.view.Run`): its reference mesh, parameters, protocol, rest state
    and PARDISO mode (:func:`init_stored`)."""
    from ..mesh.mesh import Mesh
    from ..params import ShellParameters
    from .spec import Protocol

    store = run.store
    mesh = Mesh.from_arrays(store.X0, store.faces)
    ctx, _ = init_stored(store, mesh, ShellParameters.from_dict(store.params),
                         Protocol.from_dict(store.protocol), threads)
    return ctx
