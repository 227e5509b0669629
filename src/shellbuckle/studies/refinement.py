"""The mesh-refinement study: do the buckling thresholds, W and the energies converge as the
mesh is refined, and how far is the paper's mesh (3594 vertices) from the limit?

One sweep (:mod:`shellbuckle.sweep`) of deflations of the same shells on every mesh over
energy conventions x gamma x mesh sizes N x seeds: by default shells with a shape imperfection
of :data:`SHAPE_IN_D` of their effective thickness up to the classical buckling band
(:func:`~shellbuckle.protocol.imperfection.critical_shape_degree`) and no jiggle, so that
every mesh dents at the same material point; or spherical shells kicked by the smooth
imperfection (:mod:`shellbuckle.protocol.imperfection`, the same field on every mesh). Then, per
(convention, gamma, imperfection) and mesh size N:

- the primary threshold, the loss of axisymmetry and the wrinkle onset (dV/V, located by
  bisection where the runs have them, :mod:`shellbuckle.locate`), ``W_mean`` (wrinkles over the
  wrinkled steps with dV/V in [0.53, 0.76], i.e. near 0.645) as
  :func:`shellbuckle.analysis.collect.collect_runs` gives them;
- ``E/kappa`` at fixed dV/V (:data:`ENERGY_AT`), :func:`energy_at`: linear interpolation of the
  stored total energy between the two stored steps around that dV/V; the rim's largest
  harmonic at the same dV/V (:func:`rim_amplitude_at`), how far the dent is from
  axisymmetric, for shells whose dent is born non-axisymmetric; the dent axis's angle to the
  finest mesh's;

- with :func:`carry` (``shellbuckle refine --carry``), the step of each coarser mesh nearest
  dV/V = :data:`CARRY_AT` carried to the finest mesh of its seed and relaxed there
  (:func:`shellbuckle.studies.transfer.compare`): its wrinkle count there and its energy
  relative to the finest mesh's own step, i.e. whether a coarse mesh's W is a state of the
  shell or of its mesh; kept in ``carried.json`` in the study folder;

each averaged over seeds (mean, sample standard deviation with ``n - 1``, NaN for one seed),
and per quantity a value extrapolated to h -> 0 in the mean edge ``h = sqrt(8 pi / (sqrt(3)
(N - 2))) R`` (:func:`richardson`), with the discretization error of the paper's mesh relative
to it. :func:`run_study` runs the sweep and writes ``refinement.md``, ``refinement.csv`` and
``refinement.png`` (:func:`write_report`); :func:`report` rebuilds them from the runs.

Reference for the protocol: Quilliet et al., Eur. Phys. J. E 27, 13 (2008), §4.1.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
from pathlib import Path

from typing import TYPE_CHECKING

import numpy as np

from ..util import interrupt_of

if TYPE_CHECKING:  # pandas is imported where a table is made: not to build the command line
    import pandas as pd

log = logging.getLogger(__name__)

#: The issue's three gamma labels and its two readings of the bending energy.
GAMMAS = (2333.0, 15163.0, 29160.0)
CONVENTIONS = ("paper", "helfrich")
#: Mesh sizes of the study; the paper's randomized sphere is the first.
PAPER_VERTICES = 3594
VERTICES = (PAPER_VERTICES, 10_000, 40_000)
#: dV/V at which E/kappa is compared across meshes (before, around and after buckling).
ENERGY_AT = (0.1, 0.3, 0.5)
#: Order of the discretization error assumed when it cannot be fitted (two meshes): the
#: bending and stretching energies of the discrete shell converge as h^2 on smooth shapes.
ASSUMED_ORDER = 2.0
#: Fitted orders outside [MIN_ORDER, MAX_ORDER] mean the sequence is not in its asymptotic
#: regime. The discrete energies converge as h^2 and a located threshold at least as h; an order
#: below 1/2 means increments that barely shrink (by less than 1.41 when h halves), and the
#: extrapolation would reach beyond the finest value by more than 2.4 times the last increment
#: (1 / (2^p - 1)): a guess, not a limit.
MIN_ORDER = 0.5
MAX_ORDER = 20.0
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
CSV, MARKDOWN, FIGURE = "refinement.csv", "refinement.md", "refinement.png"
#: Default shape imperfection of the study, in units of each shell's effective thickness: it
#: lowered the buckling pressure to half the classical one at gamma = 2333
#: (docs/mesh-convergence.md) and sets where the shell dents, the same material point on
#: every mesh.
SHAPE_IN_D = 0.1
#: The volume fraction near which :func:`carry` carries each coarse mesh's step to the finest
#: mesh: the middle of the W window [0.53, 0.76].
CARRY_AT = 0.645
CARRIED_JSON = "carried.json"
CARRIED_VERSION = 1


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
    from ..protocol.imperfection import reference_directions

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
    from ..analysis.events import events, located_point

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
            from ..params import ShellParameters

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
    ``primary_branch_end_resolution``, ``E_over_kappa_at_<a>``,
    ``rim_amplitude_at_<a>`` (:func:`rim_amplitude_at`) and
    ``dent_axis_at_<a>`` (:func:`dent_axis_at`, a tuple or None) for each ``a`` of
    ``energy_at_values``."""
    import pandas as pd

    from ..analysis.collect import collect_runs
    from ..store.located import read_located
    from ..store.run import RunStore

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


# --------------------------------------------------------------------------- extrapolation

@dataclasses.dataclass(frozen=True)
class Extrapolation:
    """``q(h) = value + c h^order`` through the finest meshes; ``method`` says how the order
    was had: ``fitted`` (three meshes, monotone), ``assumed`` (:data:`ASSUMED_ORDER`, two
    meshes), ``equal`` (the two finest give the same value, to the resolution of a located
    threshold), ``not converged`` (value NaN:
    three that are not monotone, or a fitted order outside [:data:`MIN_ORDER`,
    :data:`MAX_ORDER`]), ``gap`` (value NaN: a mesh finer than one with the value lacks it),
    ``no value`` or ``one mesh`` (value NaN: the quantity is had on no mesh, or on one),
    ``to the finest`` (value NaN: an angle measured to the finest mesh, or a state carried to
    it, nothing to extrapolate)."""

    value: float
    order: float
    c: float
    method: str
    resolution: float = 0.0  # ``equal``: the resolution within which the two are equal

    def curve(self, h) -> np.ndarray:
        return self.value + self.c * np.asarray(h, dtype=float) ** self.order

    def describe(self) -> str:
        if self.method == "fitted":
            return f"order {self.order:.2f} fitted (3 meshes)"
        if self.method == "assumed":
            return f"order {self.order:g} assumed (2 meshes)"
        if self.method == "equal":
            if self.resolution > 0:
                return (f"two finest meshes equal within {self.resolution:.2g} (the "
                        "location's bracket)")
            return "two finest meshes equal"
        if self.method == "no value":
            return "no value on any mesh"
        if self.method == "one mesh":
            return "value on one mesh only"
        if self.method == "gap":
            return "not converged (no value on a finer mesh)"
        if self.method == "to the finest":
            return "measured to the finest mesh"
        return "not converged"


NOT_CONVERGED = Extrapolation(math.nan, math.nan, math.nan, "not converged")
#: No mesh has the value (the event did not happen, or dV/V was not reached), or only one.
NO_VALUE = Extrapolation(math.nan, math.nan, math.nan, "no value")
ONE_MESH = Extrapolation(math.nan, math.nan, math.nan, "one mesh")
#: A finer mesh lacks the value that a coarser one has (the event did not happen there, or the
#: run stopped before that dV/V): the sequence says nothing about the limit.
GAP = Extrapolation(math.nan, math.nan, math.nan, "gap")
#: An angle measured to the finest mesh's dent axis: zero there by definition.
TO_FINEST = Extrapolation(math.nan, math.nan, math.nan, "to the finest")


def _order(h, q) -> float | None:
    """The p with (q1 - q2)/(q2 - q3) = (h1^p - h2^p)/(h2^p - h3^p), h1 > h2 > h3, or None
    when none lies in [MIN_ORDER, MAX_ORDER]. The right side grows monotonically with p."""
    from scipy.optimize import brentq

    (h1, h2, h3), (q1, q2, q3) = h, q
    target = math.log((q1 - q2) / (q2 - q3))

    def gap(p):
        return math.log((h1 ** p - h2 ** p) / (h2 ** p - h3 ** p)) - target

    low, high = MIN_ORDER, MAX_ORDER
    if gap(low) > 0 or gap(high) < 0:
        return None
    return float(brentq(gap, low, high, xtol=1e-14, rtol=1e-14))


def richardson(h, q, *, assumed_order: float = ASSUMED_ORDER,
               resolution: float = 0.0) -> Extrapolation:
    """Richardson extrapolation of ``q`` (values) at mesh sizes ``h`` to h -> 0.

    Two finest values within ``resolution`` of each other (a located threshold is known to its
    bisection's bracket) are ``equal``: the limit is the finest value, to that resolution.

    NaN values of the coarsest meshes are left out and the finest meshes used: with three or
    more, the three finest fit ``q = q0 + c h^p`` exactly when the sequence is monotone (else:
    not converged); with two, the order is ``assumed_order``:
    ``q0 = q2 + (q2 - q1) h2^p / (h1^p - h2^p)``. When two or more meshes have a value, a NaN
    on a mesh finer than the coarsest of them (an event seen on 3594 and 40000 vertices but not
    on 10000) gives :data:`GAP`. Meshes of unknown size are left out."""
    h, q = np.asarray(h, dtype=float), np.asarray(q, dtype=float)
    known = np.isfinite(h)
    h, q = h[known], q[known]
    order = np.argsort(-h, kind="stable")
    h, q = h[order], q[order]
    valued = np.flatnonzero(np.isfinite(q))
    gap = len(valued) > 1 and not np.isfinite(q[valued[0]:]).all()
    h, q = h[valued], q[valued]
    if len(h) < 2 or len(np.unique(h)) < len(h):
        return NO_VALUE if not len(h) else ONE_MESH if len(h) == 1 else NOT_CONVERGED
    if gap:
        return GAP
    if abs(q[-1] - q[-2]) <= resolution:  # equal values whatever the resolution
        return Extrapolation(float(q[-1]), math.nan, 0.0, "equal",
                             resolution if q[-1] != q[-2] else 0.0)
    if len(h) >= 3:
        h, q = h[-3:], q[-3:]
        d1, d2 = q[1] - q[0], q[2] - q[1]
        if d1 * d2 <= 0:
            return NOT_CONVERGED
        p = _order(h, q)
        if p is None:
            return NOT_CONVERGED
        method = "fitted"
    else:
        p, method = float(assumed_order), "assumed"
    c = (q[-2] - q[-1]) / (h[-2] ** p - h[-1] ** p)
    return Extrapolation(float(q[-1] - c * h[-1] ** p), p, float(c), method)


# --------------------------------------------------------------------------- the table

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


def _compared_seeds(group: pd.DataFrame, quantity: str, sizes) -> list | None:
    """The seeds of ``group`` with a finite ``quantity`` on every mesh of ``sizes`` that has
    one for any seed (with a run on every mesh where none has), sorted; ``None`` where no seed
    has (each mesh then stands for its own seeds)."""
    values = group[["seed", "n_vertices", quantity]]
    values = values[np.isfinite(values[quantity].to_numpy(dtype=float))]
    valued = [n for n in sizes if (values["n_vertices"] == n).any()]
    if not valued:
        values, valued = group, sizes
    common = None
    for n in valued:
        mine = set(values.loc[values["n_vertices"] == n, "seed"].tolist())
        common = mine if common is None else common & mine
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


def refinement_table(runs: pd.DataFrame, energy_at_values=ENERGY_AT) -> pd.DataFrame:
    """The refinement table (:data:`COLUMNS`) of :func:`collect`'s runs: per group
    (convention, gamma, nu, imperfection), quantity and mesh size N, the mean over seeds, its
    sample std, how many seeds have it and which (``seeds``); per group and quantity the
    extrapolation (:func:`richardson`) and the paper's mesh's error ``q(3594) - q0``
    (absolute, and relative to ``|q0|``), both from the means over the seeds that have the
    quantity on every mesh (``compared_mean``, over ``extrapolation_seeds``,
    :func:`_compared_seeds`; :data:`OWN_SEEDS`, each mesh's mean over its own seeds, where no
    seed has), so that a seed run on some meshes only does not pass for a change with the
    mesh."""
    import pandas as pd

    rows = []
    if runs.empty:
        return pd.DataFrame(rows, columns=list(COLUMNS))
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
            seeds = _compared_seeds(group, quantity, sizes)
            chosen = group if seeds is None else group[group["seed"].isin(seeds)]
            compared = {n: _spread(chosen.loc[chosen["n_vertices"] == n, quantity]
                                   .to_numpy(dtype=float)) for n in sizes}
            resolution = _resolution(chosen, quantity, [n for n in sizes
                                                        if math.isfinite(compared[n][0])][-2:])
            fit = TO_FINEST if quantity.startswith(("dent_angle_at_", "carried_")) else richardson(
                mean_edge(sizes), [compared[n][0] for n in sizes], resolution=resolution)
            paper = compared.get(PAPER_VERTICES, (math.nan,))[0]
            error = paper - fit.value
            relative = error / abs(fit.value) if fit.value else math.nan
            for n in sizes:
                rows.append(dict(zip(GROUP, key)) | {
                    "quantity": quantity, "label": label, "n_vertices": n,
                    "h": float(mean_edge(n)), "mean": stats[n][0], "std": stats[n][1],
                    "n_seeds": stats[n][2],
                    "seeds": " ".join(map(str, _seeds_with(group, quantity, n))),
                    "compared_mean": compared[n][0], "extrapolated": fit.value,
                    "order": fit.order,
                    "method": fit.describe(), "extrapolation_seeds": OWN_SEEDS
                    if seeds is None else " ".join(map(str, seeds)), "paper_mesh_value": paper,
                    "paper_mesh_error": error, "paper_mesh_relative_error": relative})
    return pd.DataFrame(rows, columns=list(COLUMNS))


# --------------------------------------------------------------------------- the study

def study_spec(gammas=GAMMAS, conventions=CONVENTIONS, vertices=VERTICES, seeds=(0,), *,
               smooth_jiggle: float | None = None, smooth_degree: int | None = None,
               shape_imperfection: float | None = None,
               shape_imperfection_d: float | None = None, shape_degree=None,
               until: float = 0.95):
    """The study's :class:`~shellbuckle.sweep.SweepSpec`: the paper's protocol (dv = 0.019,
    the c0 cycle, Newton) on shells with a shape imperfection, by default
    :data:`SHAPE_IN_D` of each shell's effective thickness up to its
    :func:`~shellbuckle.protocol.imperfection.critical_shape_degree` (``shape_imperfection``
    gives it in units of R instead, ``shape_degree`` a degree; an amplitude 0 means spherical
    shells), with the smooth imperfection (jiggle) of rms ``smooth_jiggle`` R up to degree
    ``smooth_degree`` (default :data:`~shellbuckle.protocol.imperfection.DEFAULT_DEGREE`);
    the default jiggle is none on imperfect shells (the shape breaks the symmetry, the same
    way on every mesh) and :func:`paper_equivalent_amplitude` on spherical ones."""
    from ..protocol.imperfection import CRITICAL, DEFAULT_DEGREE
    from ..sweep import SweepSpec

    if shape_imperfection is not None and shape_imperfection_d is not None:
        raise ValueError("give either shape_imperfection (units of R) or shape_imperfection_d "
                         "(units of d), not both")
    if shape_imperfection is None and shape_imperfection_d is None:
        shape_imperfection_d = SHAPE_IN_D
    spherical = shape_imperfection == 0 or shape_imperfection_d == 0
    if spherical:  # the runs of a study without shape imperfection
        if shape_degree is not None:
            raise ValueError(f"shape_degree = {shape_degree}: needs a shape imperfection (its "
                             "amplitude is 0: spherical shells)")
        shape = {}
    else:
        shape = {"shape_degree": CRITICAL if shape_degree is None else shape_degree}
        if shape_imperfection is not None:
            shape["shape_imperfection"] = shape_imperfection
        else:
            shape["shape_imperfection_d"] = shape_imperfection_d
    if smooth_jiggle is None and not spherical:  # the shape breaks the symmetry: no jiggle
        if smooth_degree is not None:
            raise ValueError(f"smooth_degree = {smooth_degree}: needs smooth_jiggle (imperfect "
                             "shells have no jiggle by default)")
        smooth_jiggle, degree = 0.0, None
    else:  # an explicit jiggle keeps its degree (and the run names of earlier studies)
        degree = DEFAULT_DEGREE if smooth_degree is None else smooth_degree
        if smooth_jiggle is None:
            smooth_jiggle = round(paper_equivalent_amplitude(degree), 5)
    return SweepSpec(gamma=list(gammas), energy_convention=list(conventions),
                     vertices=list(vertices), seeds=list(seeds), until=until,
                     smooth_jiggle=smooth_jiggle, smooth_degree=degree, **shape)


def run_study(out, gammas=GAMMAS, conventions=CONVENTIONS, vertices=VERTICES, seeds=(0,), *,
              smooth_jiggle: float | None = None, smooth_degree: int | None = None,
              shape_imperfection: float | None = None,
              shape_imperfection_d: float | None = None, shape_degree=None,
              until: float = 0.95, workers: int | None = None, scheduler=None,
              progress: bool = True, energy_at_values=ENERGY_AT,
              carry_states: bool = False) -> pd.DataFrame:
    """Run (or resume) the study's sweep in ``out`` (:func:`study_spec`, runs that are
    finished are skipped), with ``carry_states`` carry each coarse mesh's state near
    :data:`CARRY_AT` to the finest mesh (:func:`carry`, on ``workers`` local processes, by
    default one per core), then write its report
    (:func:`write_report`) from the runs of this spec; returns the refinement table."""
    from ..sweep import default_workers, run_sweep

    spec = study_spec(gammas, conventions, vertices, seeds, smooth_jiggle=smooth_jiggle,
                      smooth_degree=smooth_degree, shape_imperfection=shape_imperfection,
                      shape_imperfection_d=shape_imperfection_d, shape_degree=shape_degree,
                      until=until)
    run_sweep(spec, out, scheduler=scheduler, workers=workers, progress=progress)
    folders = [f for f in (Path(out) / p["name"] for p in spec.points()) if f.exists()]
    if carry_states:
        carry(out, folders, workers=workers or default_workers(), progress=progress)
    return report(out, folders, energy_at_values=energy_at_values)


def report(out, paths=None, *, energy_at_values=ENERGY_AT) -> pd.DataFrame:
    """Build the refinement table of the finished runs in ``paths`` (default: every run of the
    sweep folder ``out``) and write it in ``out`` (:func:`write_report`); returns it."""
    import pandas as pd

    paths = [out] if paths is None else list(paths)
    runs = collect(paths, energy_at_values) if paths else pd.DataFrame(
        columns=[*GROUP, "n_vertices", *quantities(energy_at_values)])
    runs = with_carried(runs, read_carried(out), out)
    table = refinement_table(runs, energy_at_values)
    write_report(table, out, n_runs=len(runs))
    return table


# --------------------------------------------------------------------------- carried states

def _name(path, out) -> str:
    """How a run is named in :data:`CARRIED_JSON`: its folder relative to the study folder
    ``out`` when it lies in it, else its absolute path."""
    path, out = Path(path).resolve(), Path(out).resolve()
    return str(path.relative_to(out)) if path.is_relative_to(out) else str(path)


def _carry_key(source: str, step: int, target: str, at: float) -> str:
    return f"{source} {step} -> {target} at {at:g}"


def read_carried(out, *, strict: bool = False) -> dict:
    """The carried states kept in the study folder ``out`` (:data:`CARRIED_JSON`): ``{key:
    entry}``, empty if there are none. A file that cannot be read, or of another version, is
    a ``RuntimeError`` naming it with ``strict`` (:func:`carry` does not write over it), else
    a warning and no entries (the report goes on without them)."""
    import json

    path = Path(out) / CARRIED_JSON
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(data, dict) or not isinstance(data.get("carried"), dict):
            raise ValueError("not a record of carried states")
        if data.get("version") != CARRIED_VERSION:
            raise ValueError(f"version {data.get('version')!r}, this version reads "
                             f"{CARRIED_VERSION}")
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        why = f"{path}: {exc}"
        if strict:
            raise RuntimeError(f"{why}; move it away to carry the states again") from None
        log.warning("%s: the carried states are left out of the report", why)
        return {}
    return dict(data["carried"])


def _write_carried(out, carried: dict) -> None:
    import json

    from ..store.atomic import atomic_write_bytes
    from ..util import json_safe

    text = json.dumps(json_safe({"version": CARRIED_VERSION, "carried": carried}), indent=1)
    Path(out).mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(Path(out) / CARRIED_JSON, (text + "\n").encode())


def _finest_runs(runs: pd.DataFrame) -> dict:
    """Per group and seed, the path of the run on the group's finest mesh (over all seeds;
    a seed without a finished run there has none)."""
    finest = {}
    for key, group in runs.groupby(GROUP, sort=True):
        top = group[group["n_vertices"] == group["n_vertices"].max()]
        for seed, rows in top.groupby("seed"):
            if len(rows) == 1:
                finest[(*key, seed)] = str(rows["path"].iloc[0])
    return finest


def carry_pairs(runs: pd.DataFrame, at: float = CARRY_AT) -> list[tuple]:
    """The (source folder, step, finest folder) of :func:`carry`: per group and seed, each
    coarser mesh's run, its stored step nearest dV/V = ``at`` (within half a step: a run that
    ended before has none), and the run of the same seed on the group's finest mesh, which
    holds a step at that step's dV/V (pairs without one are left out)."""
    from ..store.run import RunStore
    from .transfer import own_step

    pairs = []
    finest = _finest_runs(runs)
    for _, row in runs.iterrows():
        target = finest.get((*(row[c] for c in GROUP), row["seed"]))
        if target is None or str(row["path"]) == target:
            continue
        table = RunStore.open(row["path"]).table()
        k = step_near(table, at)
        if k is None or k == 0:  # the reference sphere is not carried
            continue
        dv = float(table.loc[table["step"] == k, "dV_over_V"].iloc[0])
        if own_step(target, dv) is not None:
            pairs.append((str(row["path"]), k, target))
    return pairs


def _carried_entry(source: str, k: int, target: str, threads: int | None) -> dict:
    """What :data:`CARRIED_JSON` keeps of one carried state (without its names): the
    comparison's numbers, or ``failed`` with the reason where the relaxation failed (an
    interrupt is raised, not kept)."""
    from .transfer import compare

    try:
        c = compare(source, k, target, threads=threads)
    except Exception as exc:  # a failed relaxation is kept as such, the others go on
        if interrupt_of(exc) is not None:
            raise
        return {"failed": f"{type(exc).__name__}: {exc}", "certified": False}
    return {"dV_over_V": c.dV_over_V, "shape": c.carried.shape, "W": c.carried.W,
            "E_over_kappa": c.carried.E_over_kappa, "source_W": c.source.W,
            "own_shape": c.own.shape, "own_W": c.own.W, "own_E_over_kappa": c.own.E_over_kappa,
            "relative": c.relative, "certified": c.certified}


def _carried_in_processes(pairs, threads, workers):
    """``(pair, entry)`` of :func:`_carried_entry` for each pair as a worker process ends it
    (``min(workers, len(pairs))`` fresh processes, each BLAS and PARDISO on ``threads``, which
    ignore SIGINT: an interrupt reaches this process, which stops them, as it does whenever the
    caller stops iterating); RuntimeError where a worker dies (killed, out of memory) before
    its states are done."""
    import multiprocessing
    import queue

    context = multiprocessing.get_context("spawn")
    tasks, results = context.Queue(), context.Queue()
    n = min(workers, len(pairs))
    for i, pair in enumerate(pairs):
        tasks.put((i, (*pair, threads)))
    for _ in range(n):
        tasks.put(None)  # one end mark per worker
    processes = [context.Process(target=_carry_worker, args=(tasks, results), daemon=True)
                 for _ in range(n)]
    for process in processes:
        process.start()
    try:
        for _ in pairs:
            while True:
                try:
                    i, entry = results.get(timeout=1.0)
                    break
                except queue.Empty:
                    dead = [p.exitcode for p in processes if p.exitcode not in (None, 0)]
                    if dead:
                        raise RuntimeError(
                            f"a process carrying states to the finest mesh died (exit code "
                            f"{dead[0]}: killed, or out of memory?); the states carried so far "
                            "are kept: run again, with fewer workers") from None
            yield pairs[i], entry
    finally:
        for process in processes:
            if process.is_alive():
                process.terminate()
        for process in processes:
            process.join()
        tasks.cancel_join_thread()  # states not started are dropped, not waited for at exit


def _carry_worker(tasks, results) -> None:
    """A worker process of :func:`_carried_in_processes`: carries the states it is given until
    the end mark."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles it and stops the workers
    while (task := tasks.get()) is not None:
        i, args = task
        results.put((i, _carried_entry(*args)))


def carry(out, paths=None, *, at: float = CARRY_AT, threads: int | None = 1,
          workers: int | None = 1, progress: bool = False) -> dict:
    """Carry, per group and seed, each coarser mesh's step nearest dV/V = ``at`` to the finest
    mesh (:func:`carry_pairs`, :func:`shellbuckle.studies.transfer.compare`) and keep what it
    gives in ``out``/:data:`CARRIED_JSON`, each pair written as soon as it is done (a pair
    already kept is not computed again): the carried state's class and W on the finest mesh,
    its energy and that of the finest mesh's own step, their relative difference, whether it
    relaxed to a certified minimum; a relaxation that fails (it left the physical domain) is
    kept as ``failed`` with its reason, reported as no value, and tried again by the next
    call. ``paths``: the runs (default every run of the sweep folder ``out``); ``workers``:
    processes relaxing pairs at once (each on ``threads``; the same numbers as one at a time,
    this process writing the file). Returns every kept entry."""
    carried = read_carried(out, strict=True)
    paths = [out] if paths is None else list(paths)
    if not paths:
        return carried
    pairs = [p for p in carry_pairs(collect(paths, ()), at)  # not kept, or kept as failed
             if "failed" in carried.get(_carry_key(_name(p[0], out), p[1], _name(p[2], out),
                                                   at), {"failed": ""})]
    bar = None
    if progress and pairs:
        from tqdm import tqdm

        bar = tqdm(total=len(pairs), desc="carrying to the finest mesh", unit="state")
    done = (_carried_in_processes(pairs, threads, workers) if (workers or 1) > 1
            and len(pairs) > 1 else ((p, _carried_entry(*p, threads)) for p in pairs))
    with contextlib.closing(done):  # the workers stop with this loop, however it ends
        for (source, k, target), entry in done:
            names = {"source": _name(source, out), "step": k, "target": _name(target, out),
                     "at": at}
            key = _carry_key(names["source"], k, names["target"], at)
            if "failed" in entry:
                log.warning("carrying %s failed: %s", key, entry["failed"])
            carried[key] = names | entry
            _write_carried(out, carried)
            if bar is not None:
                bar.update()
    if bar is not None:
        bar.close()
    return carried


def with_carried(runs: pd.DataFrame, carried: dict, out, at: float = CARRY_AT) -> pd.DataFrame:
    """``runs`` with the columns of :func:`carried_columns` from the entries of ``carried``
    (:func:`read_carried` of the study folder ``out``) carried at ``at`` from a run of
    ``runs`` to the run of its seed on its group's finest mesh: a coarse run, the W of its
    state carried there and the relative energy in percent (no value where the carried
    state is no certified minimum); the finest run, its own W and 0. Without such entries,
    ``runs`` unchanged."""
    if not carried or runs.empty:
        return runs
    w_col, e_col = carried_columns(at)
    row_of = {_name(p, out): i for i, p in enumerate(runs["path"])}
    finest = {_name(p, out) for p in _finest_runs(runs).values()}
    W, dE = np.full(len(runs), np.nan), np.full(len(runs), np.nan)
    for entry in carried.values():
        source, target = entry.get("source"), entry.get("target")
        if (entry.get("at") != at or "failed" in entry or target not in finest
                or source not in row_of or source == target):
            continue
        i, j = row_of[source], row_of[target]
        if entry.get("certified"):
            relative = entry.get("relative")
            W[i] = entry["W"]
            dE[i] = math.nan if relative is None else 100.0 * float(relative)
        W[j], dE[j] = entry["own_W"], 0.0
    if np.isnan(W).all():
        return runs
    runs = runs.copy()
    runs[w_col], runs[e_col] = W, dE
    return runs


# --------------------------------------------------------------------------- the report

def _cell(mean: float, std: float, n: int) -> str:
    if not math.isfinite(mean):
        return "–"
    text = f"{mean:.4g}"
    if math.isfinite(std):
        text += f" ± {std:.2g}"
    return text + (f" ({n} seeds)" if n > 1 else "")


def _error(row) -> str:
    error, relative = row["paper_mesh_error"], row["paper_mesh_relative_error"]
    if not math.isfinite(error):
        return "–"
    return f"{error:+.3g}" + (f" ({100 * relative:+.2g} %)" if math.isfinite(relative) else "")


def markdown(table: pd.DataFrame, *, n_runs: int | None = None) -> str:
    """The table as a physicist reads it: per convention and gamma, one line per quantity with
    its value on every mesh (the paper's first), the value extrapolated to h -> 0, how, and
    the paper's mesh's error relative to it."""
    lines = ["# Mesh refinement", "",
             ("Mean over seeds ± sample standard deviation; h is the mean edge "
             "sqrt(8 pi/(sqrt(3)(N - 2))) R. Extrapolated: Richardson in h (the order fitted "
             "from the three finest meshes when they are monotone, else the order 2 assumed "
             "from two meshes, else not converged). Error of the paper's mesh: "
             f"q(N = {PAPER_VERTICES}) - q(h -> 0), and relative to |q(h -> 0)|. E/kappa and "
             "the rim harmonic (the largest harmonic m >= 2 of the dent's rim over the rim's "
             "radius: 0 for an axisymmetric dent) are interpolated linearly in dV/V between "
             "the two stored steps around the given dV/V."), ""]
    if n_runs is not None:
        lines += [f"Finished runs: {n_runs}.", ""]
    if table.empty:
        return "\n".join(lines + ["No finished run yet.", ""])
    for key, group in table.groupby(GROUP, sort=True):
        convention, gamma, nu, imperfection = key
        sizes = sorted(group["n_vertices"].unique())
        finest = sizes[-1]
        heads = [f"N = {n} (h = {mean_edge(n):.3g} R)" + (", paper" if n == PAPER_VERTICES
                                                             else ", finest" if n == finest
                                                             else "") for n in sizes]
        seeds = {n: sorted(set().union(*map(_seed_list, group.loc[group["n_vertices"] == n,
                                                                   "seeds"])), key=int)
                 for n in sizes}
        mixed = len({tuple(v) for v in seeds.values()}) > 1
        lines += [f"## {convention}, gamma = {gamma:g}, nu = {nu:.3g}, {imperfection}", "",
                  f"Classical threshold of the perfect sphere (thin-shell theory, to compare "
                  f"with the {'imperfect shell' if imperfection.startswith('shape') else 'sphere'}"
                  f" branch's end): dV/V = {_classical(convention, gamma, nu):.4g}.", "",
                  "| quantity | " + " | ".join(heads) + " | h -> 0 | extrapolation | "
                  "error of the paper's mesh |",
                  "|---" * (len(sizes) + 4) + "|"]
        for quantity, rows in group.groupby("quantity", sort=False):
            rows = rows.set_index("n_vertices")
            first = rows.iloc[0]
            cells = [_cell(rows.loc[n, "mean"], rows.loc[n, "std"], rows.loc[n, "n_seeds"])
                     for n in sizes]
            value = first["extrapolated"]
            label = first["label"]
            if quantity in BRANCH_END and imperfection.startswith("shape"):
                label = IMPERFECT_BRANCH_END
            method = first["method"]
            used = first["extrapolation_seeds"]
            if math.isfinite(value) and (used == OWN_SEEDS or set(_seed_list(used))
                                         != set().union(*map(_seed_list, rows["seeds"]))):
                method += ", " + _seeds_used(used)
            lines.append(f"| {label} | " + " | ".join(cells) + " | "
                         + (f"{value:.4g}" if math.isfinite(value) else "–") + " | "
                         + f"{method} | {_error(first)} |")
        lines.append("")
        if mixed:
            lines += ["Seeds differ between the meshes (" + "; ".join(
                f"N = {n}: {_seeds_used(' '.join(k))}" for n, k in seeds.items()) + "): each "
                "column is the mean over its own seeds; h -> 0 and the error of the paper's "
                "mesh compare the seeds named beside the extrapolation (those with the quantity "
                "on every mesh; where none has it, each mesh's own).", ""]
        born = _born_polygonal(group, sizes)
        if born:
            lines += [f"On N = {', '.join(map(str, born))} the loss of axisymmetry is the "
                      "primary buckling itself: the dent is not axisymmetric from its birth "
                      "(an imperfection with non-axisymmetric modes at the dent's scale shapes "
                      "its rim).", ""]
    return "\n".join(lines)


def _seed_list(seeds) -> list[str]:
    """The seeds of a ``seeds`` or ``extrapolation_seeds`` cell: space-separated (a number, or
    NaN for none, where a table was read back from its CSV file)."""
    if isinstance(seeds, str):
        return [] if seeds == OWN_SEEDS else seeds.split()
    if isinstance(seeds, (int, float, np.integer, np.floating)) and math.isfinite(seeds):
        return [str(int(seeds))]
    return []


def _seeds_used(seeds) -> str:
    """How the markdown names a row's ``extrapolation_seeds``."""
    names = _seed_list(seeds)
    if not names:
        return "each mesh's own seeds (none is on every mesh)"
    return ("seed " if len(names) == 1 else "seeds ") + ", ".join(names)


def _born_polygonal(group: pd.DataFrame, sizes) -> list[int]:
    """The mesh sizes of a group whose loss of axisymmetry equals its primary buckling (every
    seed's mean)."""
    by = {q: rows.set_index("n_vertices")["mean"] for q, rows in group.groupby("quantity")}
    primary, loss = by.get("primary_dV_over_V"), by.get("axisymmetry_loss_dV_over_V")
    if primary is None or loss is None:
        return []
    return [int(n) for n in sizes if math.isfinite(primary.get(n, math.nan))
            and primary.get(n) == loss.get(n)]


def _classical(convention: str, gamma: float, nu: float) -> float:
    """dV/V of the classical threshold (:func:`shellbuckle.theory.classical_threshold`)."""
    from .. import theory
    from ..params import ShellParameters

    params = ShellParameters.from_gamma(float(gamma), nu=float(nu),
                                        energy_convention=convention)
    return float(theory.classical_threshold(params).dV_over_V_exact)


def figure(table: pd.DataFrame):
    """Each quantity against h (seed means with their spread) per convention and gamma, with
    its extrapolation: the curve q0 + c h^p over the meshes it used and q0 at h = 0 (where
    it compared fewer seeds than a mesh has, their means as open circles)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    names = list(dict.fromkeys(table["quantity"])) or ["primary_dV_over_V"]
    ncols = min(4, len(names))
    nrows = math.ceil(len(names) / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.2 * ncols, 2.8 * nrows + 0.6),
                             squeeze=False, layout="constrained")
    groups = list(table.groupby(GROUP, sort=True)) if not table.empty else []
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.8, max(len(groups), 1)))
    for ax, name in zip(axes.flat, names):
        for colour, (key, group) in zip(colours, groups):
            rows = group[group["quantity"] == name].sort_values("h")
            if rows.empty:
                continue
            label = f"{key[0]}, gamma = {key[1]:g}"
            ax.errorbar(rows["h"], rows["mean"], yerr=rows["std"].fillna(0.0), marker="o",
                        ms=4, lw=1, color=colour, label=label, capsize=2)
            first = rows.iloc[0]
            if not np.allclose(rows["compared_mean"], rows["mean"], rtol=0, atol=0,
                               equal_nan=True):  # the means the extrapolation compared
                ax.plot(rows["h"], rows["compared_mean"], ls="none", marker="o", ms=6,
                        mfc="none", color=colour)
            if math.isfinite(first["extrapolated"]):
                order = first["order"] if math.isfinite(first["order"]) else 0.0
                used = rows.dropna(subset=["compared_mean"])["h"].to_numpy()[:3]
                h = np.linspace(0.0, used.max(), 50)
                c = _c(rows, first["extrapolated"], order)
                ax.plot(h, first["extrapolated"] + c * h ** order, ls="--", lw=0.8,
                        color=colour)
                ax.plot([0.0], [first["extrapolated"]], marker="*", ms=8, color=colour)
            if name in BRANCH_END:  # beside it: the thin-shell classical threshold
                ax.plot([0.0], [_classical(*key[:3])], marker="D", ms=5, mfc="none",
                        color=colour)
        if not np.isfinite(table.loc[table["quantity"] == name, "mean"]
                           .to_numpy(dtype=float)).any():
            ax.text(0.5, 0.5, "no value on any mesh", ha="center", va="center",
                    transform=ax.transAxes, fontsize=8, color="0.3")
            ax.set_yticks([])
        ax.set_xlim(0.0, 1.05 * float(table["h"].max()) if not table.empty else 1.0)
        ax.set_xlabel("mean edge h / R")
        ax.set_title(str(table.loc[table["quantity"] == name, "label"].iloc[0])
                     if name in set(table["quantity"]) else name, fontsize=9)
        ax.axvline(float(mean_edge(PAPER_VERTICES)), color="0.5", lw=0.6, ls=":")
    for ax in list(axes.flat)[len(names):]:
        ax.set_visible(False)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=min(3, len(labels)),
                   fontsize=8)
    fig.suptitle("Mesh refinement: values against the mean edge h (dotted: the paper's mesh; "
                 "star: h -> 0; open circles: the means over the seeds it compares; open "
                 "diamond: the classical threshold)", fontsize=9)
    return fig


def _c(rows: pd.DataFrame, value: float, order: float) -> float:
    """The coefficient c of q0 + c h^p through the finest mesh of ``rows`` (its mean over the
    seeds the extrapolation compared)."""
    finest = rows.dropna(subset=["compared_mean"]).iloc[0]
    return 0.0 if order == 0.0 else (finest["compared_mean"] - value) / finest["h"] ** order


def write_report(table: pd.DataFrame, out, *, n_runs: int | None = None) -> list[Path]:
    """Write ``refinement.csv``, ``refinement.md`` and ``refinement.png`` in ``out``."""
    import matplotlib.pyplot as plt

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / CSV, out / MARKDOWN, out / FIGURE]
    table.to_csv(paths[0], index=False, lineterminator="\n")
    paths[1].write_text(markdown(table, n_runs=n_runs), encoding="utf-8")
    fig = figure(table)
    fig.savefig(paths[2], dpi=150)
    plt.close(fig)
    return paths
