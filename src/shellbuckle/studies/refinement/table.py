"""The refinement table: per group, quantity and mesh, the mean over seeds, and the
extrapolation over the seeds that every mesh has."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .extrapolation import COUNT, NOT_LOCATED, TO_FINEST, richardson
from .runs import (CARRIED_W, COUNTS, ENERGY_AT, LOCATED, PAPER_VERTICES, RESOLUTIONS,
                   angle_column, axis_column, carried_columns, mean_edge, quantities)

if TYPE_CHECKING:  # pandas is imported where a table is made: not to build the command line
    import pandas as pd


GROUP = ["energy_convention", "gamma", "nu", "imperfection"]
COLUMNS = (*GROUP, "quantity", "label", "n_vertices", "h", "mean", "std", "n_seeds", "seeds",
           "compared_mean", "extrapolated", "order", "method", "extrapolation_seeds",
           "paper_mesh_value", "paper_mesh_error", "paper_mesh_relative_error")
OWN_SEEDS = "each mesh's own"  # extrapolation_seeds where no seed has a value on every mesh


def _spread(values: np.ndarray) -> tuple[float, float, int]:
    values = values[np.isfinite(values)]
    if not len(values):
        return math.nan, math.nan, 0
    std = float(values.std(ddof=1)) if len(values) > 1 else math.nan
    return float(values.mean()), std, len(values)


def _seeds_with(group: pd.DataFrame, quantity: str, n: int) -> list:
    """The seeds of ``group`` with a finite ``quantity`` on the mesh of ``n`` vertices."""
    rows = group[group["n_vertices"] == n]
    return sorted(rows.loc[np.isfinite(rows[quantity].to_numpy(dtype=float)), "seed"].tolist())


def _compared_seeds(group: pd.DataFrame, having: dict) -> list | None:
    """The seeds with the quantity on every mesh that has it for any seed (``having``: mesh
    size -> :func:`_seeds_with`; where no mesh has it, the seeds of ``group`` with a run on
    every mesh), sorted; ``None`` where no seed has (each mesh then stands for its own
    seeds)."""
    valued = [set(seeds) for seeds in having.values() if seeds] or [
        set(group.loc[group["n_vertices"] == n, "seed"]) for n in having]
    common = set.intersection(*valued) if valued else set()
    return sorted(common) if common else None


def _with_angles(group: pd.DataFrame, energy_at_values) -> pd.DataFrame:
    """``group`` with ``dent_angle_at_<a>``: per run, the angle in degrees between its dent
    axis at dV/V = a and that of the finest mesh's run of the same seed (NaN where either has
    none); the same shell dents at the same material point on every mesh."""
    group = group.copy()
    finest = group["n_vertices"].max()
    for a in energy_at_values:
        column = axis_column(a)
        reference = {row["seed"]: row[column] for _, row in group.iterrows()
                     if row["n_vertices"] == finest} if column in group else {}
        angles = []
        for _, row in group.iterrows():
            mine = row[column] if column in group else None
            theirs = reference.get(row["seed"])
            if row["n_vertices"] == finest and isinstance(mine, tuple):
                angles.append(0.0)  # the reference itself
                continue
            if mine is None or theirs is None or not isinstance(mine, tuple) \
                    or not isinstance(theirs, tuple):
                angles.append(math.nan)
                continue
            cos = float(np.clip(np.dot(mine, theirs), -1.0, 1.0))
            angles.append(math.degrees(math.acos(cos)))
        group[angle_column(a)] = angles
    return group


def _resolution(group: pd.DataFrame, quantity: str, sizes) -> float:
    """The coarsest resolution (bracket width) of a located threshold on the meshes ``sizes``
    (0 for the other quantities)."""
    column = RESOLUTIONS.get(quantity)
    if column is None or column not in group:
        return 0.0
    widths = group.loc[group["n_vertices"].isin(sizes), column].to_numpy(dtype=float)
    widths = widths[np.isfinite(widths)]
    return float(widths.max()) if len(widths) else 0.0


def _all_located(group: pd.DataFrame, quantity: str) -> bool:
    """Whether every run of ``group`` with a value of the threshold ``quantity`` located it
    (True for the quantities that are no located threshold, and for tables collected before
    the flags were)."""
    flag = LOCATED.get(quantity)
    if flag is None or flag not in group:
        return True
    valued = np.isfinite(group[quantity].to_numpy(dtype=float))
    return bool(group.loc[valued, flag].astype(bool).all())


def _extrapolation(chosen: pd.DataFrame, quantity: str, sizes, compared: dict):
    """How ``quantity``'s means over ``chosen`` go to h -> 0 (:func:`richardson`), unless it
    is measured to the finest mesh, a count, or a threshold not located on every mesh."""
    if quantity.startswith(("dent_angle_at_", "carried_")):
        return TO_FINEST
    if quantity in COUNTS:
        return COUNT
    if not _all_located(chosen, quantity):
        return NOT_LOCATED
    resolution = _resolution(chosen, quantity, [n for n in sizes
                                                if math.isfinite(compared[n][0])][-2:])
    return richardson(mean_edge(sizes), [compared[n][0] for n in sizes], resolution=resolution)


def _refuse_repeated_runs(runs: pd.DataFrame) -> None:
    """ValueError where one group has two runs of one seed on one mesh (a run made again in
    another folder, or a sweep extended with another protocol): the table would count them as
    two seeds."""
    key = [*GROUP, "n_vertices", "seed"]
    repeated = runs[runs.duplicated(key, keep=False)]
    if not repeated.empty:
        _, rows = next(iter(repeated.groupby(key, sort=True, dropna=False)))
        first, paths = rows.iloc[0], rows["path"]
        raise ValueError(f"two or more runs of seed {first['seed']} on {first['n_vertices']} "
                         f"vertices ({first['energy_convention']}, gamma = "
                         f"{first['gamma']:g}, {first['imperfection']}): "
                         f"{', '.join(map(str, paths))}; give the folders of one study (each "
                         "shell once per mesh and seed)")


def refinement_table(runs: pd.DataFrame, energy_at_values=ENERGY_AT) -> pd.DataFrame:
    """The refinement table (:data:`COLUMNS`) of :func:`collect`'s runs: per group
    (convention, gamma, nu, imperfection), quantity and mesh size N, the mean over seeds, its
    sample std, how many seeds have it and which (``seeds``); per group and quantity the
    extrapolation (:func:`richardson`) and the paper's mesh's error ``q(3594) - q0``
    (absolute, and relative to ``|q0|``), both from the means over the seeds that have the
    quantity on every mesh (``compared_mean``, over ``extrapolation_seeds``,
    :func:`_compared_seeds`; :data:`OWN_SEEDS`, each mesh's mean over its own seeds, where no
    seed has), so that a seed run on some meshes only does not pass for a change with the
    mesh. W (:data:`~.runs.COUNTS`) is not extrapolated, nor a threshold that a run has not
    located. ValueError where a group has two runs of one seed on one mesh."""
    import pandas as pd

    rows = []
    if runs.empty:
        return pd.DataFrame(rows, columns=list(COLUMNS))
    _refuse_repeated_runs(runs)
    for key, group in runs.groupby(GROUP, sort=True):
        sizes = sorted(group["n_vertices"].astype(int).unique())
        group = _with_angles(group, energy_at_values)
        extra = {}  # the carried states' rows, at the volume fraction they were carried at
        for column in group.columns:
            if column.startswith(CARRIED_W):
                extra |= carried_columns(float(column.removeprefix(CARRIED_W)))
        for quantity, label in (quantities(energy_at_values) | extra).items():
            stats = {n: _spread(group.loc[group["n_vertices"] == n, quantity]
                                .to_numpy(dtype=float)) for n in sizes}
            having = {n: _seeds_with(group, quantity, n) for n in sizes}
            seeds = _compared_seeds(group, having)
            chosen = group if seeds is None else group[group["seed"].isin(seeds)]
            compared = {n: _spread(chosen.loc[chosen["n_vertices"] == n, quantity]
                                   .to_numpy(dtype=float)) for n in sizes}
            fit = _extrapolation(chosen, quantity, sizes, compared)
            paper = compared.get(PAPER_VERTICES, (math.nan,))[0]
            error = paper - fit.value
            relative = error / abs(fit.value) if fit.value else math.nan
            for n in sizes:
                rows.append(dict(zip(GROUP, key)) | {
                    "quantity": quantity, "label": label, "n_vertices": n,
                    "h": float(mean_edge(n)), "mean": stats[n][0], "std": stats[n][1],
                    "n_seeds": stats[n][2],
                    "seeds": " ".join(map(str, having[n])),
                    "compared_mean": compared[n][0], "extrapolated": fit.value,
                    "order": fit.order,
                    "method": fit.describe(), "extrapolation_seeds": OWN_SEEDS
                    if seeds is None else " ".join(map(str, seeds)), "paper_mesh_value": paper,
                    "paper_mesh_error": error, "paper_mesh_relative_error": relative})
    return pd.DataFrame(rows, columns=list(COLUMNS))
