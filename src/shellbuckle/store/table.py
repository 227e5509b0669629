"""The per-step table of a run: its columns in order (SPEC §7 step columns, then the analysis
columns present, then any other names in order of appearance), the DataFrame with
integer-valued columns as integers, and the text of ``table.csv`` written with the csv module,
which ``pandas.read_csv`` reads back to the table's values.
"""

from __future__ import annotations

import csv
import io
import math

import numpy as np
import pandas as pd

from .layout import _INTEGER_COLUMNS, ANALYSIS_COLUMNS, TABLE_COLUMNS


def table_columns(rows: list[dict]) -> list[str]:
    """The table's columns for ``rows`` (one dict per step), in the order of
    :meth:`RunStore.table <shellbuckle.store.run.RunStore.table>`."""
    present = list(dict.fromkeys(key for row in rows for key in row))
    columns = list(TABLE_COLUMNS) + [c for c in ANALYSIS_COLUMNS if c in present]
    columns += [c for c in present if c not in columns]
    return columns


def table_frame(rows: list[dict], columns: list[str]) -> pd.DataFrame:
    """The table of ``rows`` as a DataFrame: integer-valued integer columns as int64 (the
    nullable ``Int64`` where some rows lack them), empty SPEC §7 columns as float64."""
    table = pd.DataFrame(rows, columns=columns)  # new dicts of scalars: no copy needed
    for column in columns:
        if column in _INTEGER_COLUMNS and _integer_like(table[column]):
            has_na = table[column].isna().any()
            table[column] = table[column].astype("Int64" if has_na else np.int64)
        elif column in TABLE_COLUMNS and table[column].isna().all():
            table[column] = table[column].astype(np.float64)
    return table


def table_csv(rows: list[dict], columns: list[str]) -> bytes:
    """The bytes of ``table.csv``: a header of ``columns``, then one line per row
    (:func:`_csv_cell`), UTF-8."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_csv_cell(row.get(column), column in _INTEGER_COLUMNS)
                         for column in columns])
    return out.getvalue().encode("utf-8")


def _integer_like(column: pd.Series) -> bool:
    values = column.dropna()
    if values.empty:
        return False
    try:
        numbers = values.to_numpy(dtype=float)
    except (TypeError, ValueError):
        return False
    return bool(np.all(np.isfinite(numbers)) and np.all(numbers == np.round(numbers))
                and values.map(lambda v: not isinstance(v, bool)).all())


def _csv_cell(value, integer: bool) -> str:
    """One cell of ``table.csv``: empty for None and NaN, the shortest repr of a float (an
    integer-valued one as an integer in an integer column), ``True``/``False``, else ``str``."""
    if value is None:
        return ""
    if isinstance(value, float):
        if math.isnan(value):
            return ""
        return str(int(value)) if integer and value.is_integer() else repr(value)
    return str(value)
