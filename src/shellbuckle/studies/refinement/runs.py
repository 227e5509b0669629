"""The refinement study's defaults and what it reads from one run: thresholds, W, energies
and rim harmonics at fixed dV/V, the dent's material axis, the end of the sphere branch
(:func:`collect`), and the mesh's mean edge."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pandas is imported where a table is made: not to build the command line
    import pandas as pd

#: The issue's three gamma labels and its two readings of the bending energy.
GAMMAS = (2333.0, 15163.0, 29160.0)
CONVENTIONS = ("paper", "helfrich")
#: Mesh sizes of the study; the paper's randomized sphere is the first.
PAPER_VERTICES = 3594
VERTICES = (PAPER_VERTICES, 10_000, 40_000)
#: dV/V at which E/kappa is compared across meshes (before, around and after buckling).
ENERGY_AT = (0.1, 0.3, 0.5)
#: Surface Evolver's jiggle at the paper's temperature 0.05: std 0.028 R per coordinate.
PAPER_JIGGLE_SIGMA = 0.028
#: The thresholds as collect_runs names them, with their labels.
THRESHOLDS = {"primary_dV_over_V": "primary buckling dV/V",
              "axisymmetry_loss_dV_over_V": "loss of axisymmetry dV/V",
              "wrinkles_dV_over_V": "wrinkle onset dV/V",
              "W_mean": "W near dV/V = 0.645"}
#: Where the sphere branch ends when followed without any jiggle (the located primary
#: buckling's ``old_branch``, :func:`shellbuckle.locate._old_branch`): the discrete shell's own
#: instability, to compare with the thin-shell classical threshold
#: (:func:`shellbuckle.theory.classical_threshold`). For a shell with a shape imperfection it
#: is the end of the imperfect shell's own branch (:data:`IMPERFECT_BRANCH_END`).
BRANCH_END = {"primary_branch_end_dV_over_V": "sphere branch's end without jiggle dV/V"}
#: The located thresholds' resolutions (width of the bisection's bracket, collect_runs).
RESOLUTIONS = {"primary_dV_over_V": "primary_resolution",
               "axisymmetry_loss_dV_over_V": "axisymmetry_loss_resolution",
               "wrinkles_dV_over_V": "wrinkles_resolution",
               "primary_branch_end_dV_over_V": "primary_branch_end_resolution"}
IMPERFECT_BRANCH_END = "imperfect shell's branch end without jiggle dV/V"
#: The located thresholds' flags (collect): True where the run's event was located by
#: bisection, False where it is known to its volume step only.
LOCATED = {"primary_dV_over_V": "primary_located",
           "axisymmetry_loss_dV_over_V": "axisymmetry_loss_located",
           "wrinkles_dV_over_V": "wrinkles_located",
           "primary_branch_end_dV_over_V": "primary_located"}
#: Quantities that count (wrinkles): their means over steps and seeds are reported per mesh
#: and never extrapolated.
COUNTS = ("W_mean",)
#: Default shape imperfection of the study, in units of each shell's effective thickness: it
#: lowered the buckling pressure to half the classical one at gamma = 2333
#: (docs/mesh-convergence.md) and sets where the shell dents, the same material point on
#: every mesh.
SHAPE_IN_D = 0.1
#: The volume fraction near which :func:`carry` carries each coarse mesh's step to the finest
#: mesh: the middle of the W window [0.53, 0.76].
CARRY_AT = 0.645


def energy_column(at: float) -> str:
    return f"E_over_kappa_at_{at:g}"


def axis_column(at: float) -> str:
    return f"dent_axis_at_{at:g}"


def angle_column(at: float) -> str:
    return f"dent_angle_at_{at:g}"


def rim_column(at: float) -> str:
    return f"rim_amplitude_at_{at:g}"


CARRIED_W = "carried_W_at_"


def carried_columns(at: float = CARRY_AT) -> dict[str, str]:
    """Columns of the carried states (:func:`carry`) -> labels."""
    return {f"{CARRIED_W}{at:g}": f"W of the state carried to the finest mesh, dV/V = {at:g}",
            f"carried_dE_at_{at:g}": f"its E/kappa over the finest mesh's own - 1, dV/V = "
                                     f"{at:g} (%)"}


def quantities(energy_at=ENERGY_AT) -> dict[str, str]:
    """Column name -> label of every quantity of the table, in order."""
    return (THRESHOLDS | BRANCH_END
            | {energy_column(a): f"E/kappa at dV/V = {a:g}" for a in energy_at}
            | {rim_column(a): f"rim harmonic / rim radius at dV/V = {a:g}" for a in energy_at}
            | {angle_column(a): f"dent axis to finest mesh, dV/V = {a:g} (deg)"
               for a in energy_at})


def mean_edge(n_vertices) -> np.ndarray:
    """Mean edge / R of a closed near-equilateral triangulation of the sphere with
    ``n_vertices``: its 2 (N - 2) faces cover 4 pi R^2, so h^2 = 8 pi / (sqrt(3) (N - 2))."""
    n = np.asarray(n_vertices, dtype=float)
    return np.sqrt(8.0 * math.pi / (math.sqrt(3.0) * (n - 2.0)))


def paper_equivalent_amplitude(degree: int, n_vertices: int = PAPER_VERTICES,
                               sigma: float = PAPER_JIGGLE_SIGMA) -> float:
    """The rms (units of R) of the part of the paper's jiggle that lies in the degrees 2..L.

    White noise of std ``sigma`` at the ``n_vertices`` vertices of a near-uniform mesh spreads
    its variance evenly over about N harmonics; the ``(L + 1)^2 - 4`` of degrees 2..L hold
    ``sigma^2 ((L + 1)^2 - 4) / N`` of it. For L = 20 on the paper's mesh: 0.0098 R. The
    default amplitude of the study: the paper's shells felt this imperfection at the scales a
    refined mesh keeps; the rest of the paper's jiggle is the mesh-scale noise, which changes
    with the mesh."""
    return sigma * math.sqrt(((degree + 1) ** 2 - 4) / n_vertices)


# --------------------------------------------------------------------------- one run

def energy_at(table: pd.DataFrame, kappa: float, at: float) -> float:
    """``E_total / kappa`` at dV/V = ``at``: linear interpolation in dV/V between the two
    stored steps around it (the stored value at a stored step); NaN outside the dV/V the run
    reached. Across a snap-through between the two steps the value is on the chord, not on
    either branch (the table's step is the resolution)."""
    return _interpolate(table, "E_total", at) / kappa


def rim_amplitude_at(table: pd.DataFrame, at: float) -> float:
    """The rim's largest harmonic (modes m >= 2, relative to the rim's radius; the table's
    ``rim_amplitude``, :mod:`shellbuckle.analysis.wrinkles`) at dV/V = ``at``, interpolated as
    :func:`energy_at`; NaN where either step has not exactly one dent (``n_dimples``: the
    sphere, or several dents, whose table keeps the largest one's rim) or outside the run. It
    measures how far the dent is from axisymmetric: for a shell with a shape imperfection,
    born non-axisymmetric, a converged number where the loss of axisymmetry is no
    threshold."""
    if "rim_amplitude" not in table or "n_dimples" not in table:
        return math.nan
    # a step with several dents keeps its largest dent's rim: not the one dent's harmonic
    one_dent = table["n_dimples"].to_numpy(dtype=float) == 1
    rim = np.where(one_dent, table["rim_amplitude"].to_numpy(dtype=float), math.nan)
    return _interpolate(table.assign(rim_amplitude=rim), "rim_amplitude", at)


def _interpolate(table: pd.DataFrame, column: str, at: float) -> float:
    """``column`` at dV/V = ``at``: the stored value at a stored step, else linear in dV/V
    between the two stored steps around it (NaN if either is NaN, outside the run, or where
    the run's table has no such column: a run not analysed). Steps without a finite dV/V
    are left out."""
    if column not in table:
        return math.nan
    dv = table["dV_over_V"].to_numpy(dtype=float)
    q = table[column].to_numpy(dtype=float)
    finite = np.isfinite(dv)
    dv, q = dv[finite], q[finite]
    order = np.argsort(dv, kind="stable")
    dv, q = dv[order], q[order]
    if not len(dv) or not dv[0] <= at <= dv[-1]:
        return math.nan
    exact = np.flatnonzero(dv == at)  # (np.interp gives NaN there beside a NaN step)
    if len(exact):
        return float(q[exact[0]])
    i = int(np.searchsorted(dv, at))  # dv[i - 1] < at < dv[i]
    t = (at - dv[i - 1]) / (dv[i] - dv[i - 1])
    return float((1.0 - t) * q[i - 1] + t * q[i])


def material_dent_axis(X0: np.ndarray, X: np.ndarray) -> np.ndarray:
    """The unit vector to the dent in the material: the material points of the vertices
    (:func:`~shellbuckle.protocol.imperfection.reference_directions` of the reference sphere
    ``X0``) weighted by the squared depth of each below the median distance from the origin in
    ``X``. A material direction, so it compares across meshes of the same sphere (and is blind
    to rigid rotations of ``X``'s frame that keep the origin)."""
    from ...protocol.imperfection import reference_directions

    radius = np.linalg.norm(X, axis=1)
    w = np.maximum(np.median(radius) - radius, 0.0) ** 2
    c = (w[:, None] * reference_directions(X0)).sum(axis=0)
    norm = float(np.linalg.norm(c))
    return c / norm if norm > 0 else np.full(3, np.nan)


def step_near(table: pd.DataFrame, at: float) -> int | None:
    """The step of a run's ``table`` nearest dV/V = ``at``, if within half a step of its
    schedule (the widest spacing of its finite dV/V; every mesh of a study has the same
    steps); else None (a run that ended before, or that has fewer than two steps)."""
    dv = table["dV_over_V"].to_numpy(dtype=float)
    finite = np.flatnonzero(np.isfinite(dv))
    if len(finite) < 2:
        return None
    dv = dv[finite]
    i = int(np.argmin(np.abs(dv - at)))
    if abs(dv[i] - at) > 0.5 * float(np.max(np.diff(np.sort(dv)))):
        return None
    return int(table["step"].iloc[finite[i]])


def dent_axis_at(store, table: pd.DataFrame, at: float) -> tuple | None:
    """:func:`material_dent_axis` at the stored step nearest to dV/V = ``at``
    (:func:`step_near`), where that step is classified as dented (not ``sphere``); ``None``
    otherwise."""
    k = step_near(table, at)
    if k is None:
        return None
    if "shape" in table.columns and str(table.loc[table["step"] == k, "shape"].iloc[0]) in (
            "sphere", "nan", "None"):
        return None
    axis = material_dent_axis(store.X0, store.positions(k))
    return tuple(float(v) for v in axis) if np.isfinite(axis).all() else None


def _primary_point(path, table, points: dict) -> dict | None:
    """The located primary buckling of the run at ``path`` if it belongs to the run's primary
    buckling event, as the thresholds require
    (:func:`shellbuckle.analysis.events.located_point`)."""
    from ...analysis.events import events, located_point

    primary = next((e for e in events(path, table=table, located=False)
                    if e.name == "primary_buckling"), None)
    return None if primary is None else located_point(primary, points)


def _branch_bracket(point: dict | None) -> tuple[float, float] | None:
    """``(end_lo, end_hi)`` of the old branch's end of a located point, or None."""
    branch = (point or {}).get("old_branch") or {}
    if branch.get("end_lo") is None or branch.get("end_hi") is None:
        return None
    return float(branch["end_lo"]), float(branch["end_hi"])


def branch_end(point: dict | None) -> float:
    """The middle of the bracket of the old branch's end of a located point (NaN without
    one: not located, located before the branch was followed, a continuous event, or a branch
    that goes on past the step)."""
    bracket = _branch_bracket(point)
    return math.nan if bracket is None else 0.5 * (bracket[0] + bracket[1])


def branch_end_resolution(point: dict | None) -> float:
    """The width of that bracket (NaN without one)."""
    bracket = _branch_bracket(point)
    return math.nan if bracket is None else bracket[1] - bracket[0]


def _imperfection(protocol: dict, params: dict | None = None) -> str:
    """A run's imperfections in words: the shape (in units of R, and of the effective
    thickness where ``params`` give one) and the jiggle."""
    if protocol.get("smooth_jiggle") == 0:
        kick = "no jiggle"
    elif protocol.get("smooth_jiggle") is not None:
        kick = f"smooth {protocol['smooth_jiggle']:.3g} R, L <= {protocol.get('smooth_degree')}"
    elif protocol.get("jiggle") is not None:
        kick = f"jiggle {protocol['jiggle']:g} edge"
    else:
        kick = f"jiggle T = {protocol.get('temperature'):g}"
    if protocol.get("shape_imperfection"):
        in_d = ""
        try:
            from ...params import ShellParameters

            d = ShellParameters.from_dict(params).d_over_R_effective if params else math.nan
            in_d = f" ({protocol['shape_imperfection'] / d:.3g} d)" if d > 0 else ""
        except (ValueError, TypeError, KeyError):
            pass  # no thickness (nu >= 1/2): units of R only
        kick = (f"shape {protocol['shape_imperfection']:.3g} R{in_d}, L <= "
                f"{protocol.get('shape_degree')}; {kick}")
    return kick


def collect(paths, energy_at_values=ENERGY_AT) -> pd.DataFrame:
    """One row per finished run of ``paths`` (run or sweep folders): the columns of
    :func:`~shellbuckle.analysis.collect.collect_runs`, ``imperfection`` (its description),
    ``primary_branch_end_dV_over_V`` (:data:`BRANCH_END`; NaN where the run's primary buckling
    was located before the branch was followed, or is no jump) and its bracket's width
    ``primary_branch_end_resolution`` (and, from ``collect_runs``, per threshold
    ``<name>_located``, :data:`LOCATED`: located by bisection, or known to its volume step
    only), ``E_over_kappa_at_<a>``,
    ``rim_amplitude_at_<a>`` (:func:`rim_amplitude_at`) and
    ``dent_axis_at_<a>`` (:func:`dent_axis_at`, a tuple or None) for each ``a`` of
    ``energy_at_values``."""
    import pandas as pd

    from ...analysis.collect import collect_runs
    from ...store.located import read_located
    from ...store.run import RunStore

    tables: dict = {}
    runs = collect_runs(paths, tables=tables)
    runs = runs[runs["status"] == "finished"].reset_index(drop=True)
    imperfections, energies, ends, end_widths = [], {a: [] for a in energy_at_values}, [], []
    axes = {a: [] for a in energy_at_values}
    rims = {a: [] for a in energy_at_values}
    for path in runs["path"]:
        store = RunStore.open(path)
        meta = store.meta
        imperfections.append(_imperfection(meta.get("protocol", {}), meta.get("params")))
        point = _primary_point(path, tables[path], read_located(path))
        ends.append(branch_end(point))
        end_widths.append(branch_end_resolution(point))
        kappa = float(meta["params"]["kappa"])
        for a in energy_at_values:
            energies[a].append(energy_at(tables[path], kappa, a))
            rims[a].append(rim_amplitude_at(tables[path], a))
            axes[a].append(dent_axis_at(store, tables[path], a))
    runs["imperfection"] = imperfections
    runs[next(iter(BRANCH_END))] = np.array(ends, dtype=float)
    runs["primary_branch_end_resolution"] = np.array(end_widths, dtype=float)
    for a in energy_at_values:
        runs[energy_column(a)] = energies[a]
        runs[rim_column(a)] = rims[a]
        runs[axis_column(a)] = pd.Series(axes[a], index=runs.index, dtype=object)
    return runs
