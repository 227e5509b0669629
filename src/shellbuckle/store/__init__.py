"""Durable, self-describing run folders (see :mod:`shellbuckle.store.run`)."""

from .run import (ANALYSIS_COLUMNS, FORMAT_NAME, FORMAT_VERSION, STATUSES, TABLE_COLUMNS,
                  DamagedStep, RunStore, array_sha256, step_checksums)

__all__ = ["RunStore", "DamagedStep", "TABLE_COLUMNS", "ANALYSIS_COLUMNS", "STATUSES",
           "FORMAT_NAME", "FORMAT_VERSION", "array_sha256", "step_checksums"]
