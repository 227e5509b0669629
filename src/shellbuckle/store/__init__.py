"""Durable, self-describing run folders (see :mod:`shellbuckle.store.run`)."""

from .run import (ANALYSIS_COLUMNS, FORMAT_NAME, FORMAT_VERSION, STATUSES, TABLE_COLUMNS,
                  RunStore, array_sha256)

__all__ = ["RunStore", "TABLE_COLUMNS", "ANALYSIS_COLUMNS", "STATUSES", "FORMAT_NAME",
           "FORMAT_VERSION", "array_sha256"]
