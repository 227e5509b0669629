"""Durable, self-describing run folders (see :mod:`shellbuckle.store.run`).

The names below are read from :mod:`.run` when first asked for, so that a light module of the
package (:mod:`.located`, whose tolerance the command line shows) loads without HDF5.
"""

__all__ = ["RunStore", "DamagedStep", "TABLE_COLUMNS", "ANALYSIS_COLUMNS", "STATUSES",
           "FORMAT_NAME", "FORMAT_VERSION", "array_sha256", "step_checksums"]


def __getattr__(name: str):
    if name in __all__:
        from . import run

        return getattr(run, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
