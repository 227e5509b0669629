"""The per-step table of a run: its columns in order (SPEC §7 step columns, then the analysis
columns present, then any other names in order of appearance), the DataFrame with
integer-valued columns as integers, and the text of ``table.csv`` written with the csv module,
which ``pandas.read_csv`` reads back to the table's values.

No placeholder values: a value that was not computed is missing (``<NA>`` in the DataFrame,
an empty cell in ``table.csv``). Runs stored before this rule wrote ``inertia = -1`` where the
inertia was not computed (step 0, minimizers without a factorization); it is read as missing
(:data:`PLACEHOLDERS`). The values are stored in the run's own units (those of its ``kappa``
and ``R``: SI for a shell made from a material given in SI); :func:`table_in_units` gives
them in reduced units or SI (:data:`COLUMN_DIMENSIONS`, :func:`shellbuckle.params.unit_scale`).
"""

from __future__ import annotations

import csv
import io
import math
from typing import TYPE_CHECKING

import numpy as np

from ..params import UNIT_SYSTEMS, unit_scale
from .layout import _INTEGER_COLUMNS, ANALYSIS_COLUMNS, TABLE_COLUMNS

if TYPE_CHECKING:  # pandas is imported when a table is asked for
    import pandas as pd

#: Values that stand for "not computed" in runs stored before missing values were stored as
#: missing (the inertia of step 0 was -1): column -> predicate. They are read as missing.
PLACEHOLDERS = {"inertia": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool)
                and v < 0}

#: The physical dimension of every column that has one (:data:`shellbuckle.params.UNITS`); the
#: other columns are numbers without dimension (dV_over_V, E_over_kappa, gamma, counts, the
#: relative amplitude of the rim, the asphericity) or wall times in seconds.
COLUMN_DIMENSIONS = {
    "E_total": "energy", "E_bend": "energy", "E_stretch": "energy",
    "E_before_c0_cycle": "energy", "pressure": "pressure", "target_pressure": "pressure",
    "grad_norm": "force", "min_distance": "length", "jiggle_sigma": "length", "c0": "curvature",
    "dent_depth": "length", "dent_sagitta": "length", "rim_radius": "length",
    "crest_radius": "length", "contact_distance": "length",
}


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
    rows = _without_placeholders(rows)
    import pandas as pd  # imported when a table is asked for: a run's steps do not need it

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
    for row in _without_placeholders(rows):
        writer.writerow([_csv_cell(row.get(column), column in _INTEGER_COLUMNS)
                         for column in columns])
    return out.getvalue().encode("utf-8")


def table_in_units(table: pd.DataFrame, params, units: str = "reduced") -> pd.DataFrame:
    """``table`` (values in the run's units, as stored) with its dimensional columns
    (:data:`COLUMN_DIMENSIONS`) in ``units``: ``"reduced"`` divides them by their reduced unit
    (energies by kappa, pressures by kappa/R^3, lengths by R; exact when kappa = R = 1),
    ``"si"`` keeps them as stored, which for a shell made from a material
    (:meth:`~shellbuckle.params.ShellParameters.from_material`, E in Pa, d and R in m) are J,
    Pa and m; ``ValueError`` for a shell given by gamma alone. Column names are unchanged.
    """
    if units not in UNIT_SYSTEMS:
        raise ValueError(f"units must be one of {', '.join(UNIT_SYSTEMS)}, got {units!r}")
    if units == "si":
        if not params.is_material:
            raise ValueError("the run has no material: SI units need a run made from E, "
                             "sigma, d and R (ShellParameters.from_material)")
        return table
    import pandas as pd

    out = table.copy()
    for column, dimension in COLUMN_DIMENSIONS.items():
        if column in out.columns:
            out[column] = pd.to_numeric(out[column]) / unit_scale(params, dimension)
    return out


def _without_placeholders(rows: list[dict]) -> list[dict]:
    """``rows`` with the :data:`PLACEHOLDERS` values as None (new dicts only where needed)."""
    return [{**row, **{c: None for c, is_placeholder in PLACEHOLDERS.items()
                       if is_placeholder(row.get(c))}}
            if any(is_placeholder(row.get(c)) for c, is_placeholder in PLACEHOLDERS.items())
            else row for row in rows]


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
