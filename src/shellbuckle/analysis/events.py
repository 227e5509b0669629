"""Buckling events along a deflation run, found from its table and conformations.

Quilliet et al. (EPJE 27, 13 (2008), §4.4, Fig. 10) read three thresholds off their runs by
eye; here they are found from the per-step classification (:mod:`.classify`) and the recorded
pressure, energies and Hessian inertia:

``primary_buckling``
    the first step whose shape is not ``sphere`` (sphere -> one dent, or dimples). It is
    *confirmed* when the pressure (the Lagrange multiplier of the volume constraint) lies at
    that step at least ``PRESSURE_DROP`` below the sphere branch's at its volume: the previous
    step's pressure carried along the uniformly shrunk sphere's curve
    (:func:`shellbuckle.theory.pressure_sphere_exact`), ``p_(k-1) p_s(V_k)/p_s(V_(k-1))``, or
    at the first step, whose predecessor is the unloaded sphere, ``p_s(V_k)`` itself (the
    branch's pressure rises with the volume lost: a step-to-step drop of the pressure alone
    misses a buckling a step after a long step); without pressures, when the stretching
    energy drops while the bending energy jumps (the snap-through of Fig. 9).
``axisymmetry_loss``
    the paper's first secondary threshold, polygonization of the rim: the first step after
    primary buckling from which the shape is ``polygonal`` or ``wrinkled`` for
    ``PERSISTENCE`` consecutive steps (or until the last step).
``wrinkles``
    the paper's second secondary threshold, a rim concave between its apices: the first step
    from which the shape is ``wrinkled`` for ``PERSISTENCE`` consecutive steps.
``inertia_change``
    every step where the number of negative eigenvalues of the constrained Hessian at the
    accepted state (column ``inertia``, missing where not computed) differs from the previous
    step's.

A run that starts buckled (a branch continued from a step of another run, e.g. a
re-inflation) has no primary buckling of its own, and a secondary event only where its shape
changes after its first step.

Each event gives the step and its ``dV_over_V`` (the relative volume change reached at that
step, so the threshold lies between the previous step's value and this one: its
``resolution`` is that step). Where the run's threshold events were located by bisection
(:mod:`shellbuckle.locate`, stored in ``located.json``), ``dV_over_V`` is the located value
(the middle of the final bracket), ``resolution`` the bracket's width and ``located`` True.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .classify import table_with_shapes

#: Relative pressure drop at a step that confirms a snap-through (primary buckling).
PRESSURE_DROP = 0.2
#: A secondary threshold is the first step from which its class holds this many steps in a row.
PERSISTENCE = 2

EVENT_NAMES = ("primary_buckling", "axisymmetry_loss", "wrinkles", "inertia_change")


@dataclass(frozen=True)
class Event:
    """One event: ``name`` (one of :data:`EVENT_NAMES`), ``step``, ``dV_over_V`` at that step
    (or located), ``confirmed`` (primary buckling: whether pressure/energies agree with the
    shape; None for the others), a one-line ``description``, the ``resolution`` (width in dV/V
    of the interval in which the event lies) and whether it was ``located`` by bisection."""

    name: str
    step: int
    dV_over_V: float
    confirmed: bool | None
    description: str
    resolution: float = math.nan
    located: bool = False


def _first_persistent(flags: np.ndarray, start: int, persistence: int) -> int | None:
    """First index ``i >= start`` with ``flags[i : i + persistence]`` all true (shorter at the
    end of the array)."""
    n = len(flags)
    for i in range(start, n):
        if flags[i:min(n, i + persistence)].all():
            return i
    return None


def _primary_confirmation(table, i: int, sphere=None, unit: float = 1.0) -> tuple[bool, str]:
    """Whether the first buckled step ``i`` (> 0) shows the pressure drop of a buckling, and
    why.
    ``sphere(k)``: the uniformly shrunk sphere's pressure at the volume of row ``k`` (None:
    not known). The step's pressure is compared with the sphere branch's at its volume: the
    previous step's pressure carried along the branch, ``p_(k-1) sphere(k)/sphere(k-1)``, or
    at the first step (the step before is the unloaded sphere) ``sphere(k)`` itself; without
    ``sphere``, with ``p_(k-1)``. Pressures are said in units of ``unit`` (the run's
    kappa/R^3 in its units)."""
    prev, cur = table.iloc[i - 1], table.iloc[i]
    p0, p1 = float(prev.get("pressure", math.nan)), float(cur.get("pressure", math.nan))
    if math.isfinite(p1) and sphere is not None:
        s0, s1 = sphere(i - 1), sphere(i)
        expected = math.nan
        if math.isfinite(p0) and p0 > 0 and math.isfinite(s0) and s0 > 0:
            expected, start = p0 * s1 / s0, f"pressure {p0 / unit:.4g} -> {p1 / unit:.4g}"
        elif p0 == 0:  # the unloaded sphere before it
            expected, start = s1, f"pressure {p1 / unit:.4g}"
        if math.isfinite(expected) and expected > 0:
            drop = 1.0 - p1 / expected
            return drop >= PRESSURE_DROP, (f"{start}, {100 * drop:.0f} % below the sphere "
                                           f"branch's {expected / unit:.4g} at this volume")
    if math.isfinite(p0) and math.isfinite(p1) and p0 > 0:
        drop = 1.0 - p1 / p0
        return drop >= PRESSURE_DROP, (f"pressure {p0 / unit:.4g} -> {p1 / unit:.4g} "
                                       f"({100 * drop:.0f} % drop)")
    s0, s1 = float(prev.get("E_stretch", math.nan)), float(cur.get("E_stretch", math.nan))
    b0, b1 = float(prev.get("E_bend", math.nan)), float(cur.get("E_bend", math.nan))
    if all(map(math.isfinite, (s0, s1, b0, b1))):
        ok = s1 < s0 and b1 > b0
        return ok, f"E_stretch {s0:.4g} -> {s1:.4g}, E_bend {b0:.4g} -> {b1:.4g}"
    return False, "no pressure or energies to confirm"


def _sphere_pressure(run, dV_over_V: float, k: int) -> float:
    """The uniformly shrunk sphere's pressure at ``dV_over_V`` with the parameters and the
    spontaneous curvature of step ``k``, stretching and bending parts
    (:func:`~shellbuckle.theory.pressure_sphere_exact`,
    :func:`~shellbuckle.theory.pressure_sphere_bending`); NaN outside 0 < dV/V < 1 or for
    parameters it does not know."""
    from ..theory import pressure_sphere_bending, pressure_sphere_exact

    if not 0.0 < dV_over_V < 1.0:
        return math.nan
    try:
        params = run.params_at(int(k))
        return float(pressure_sphere_exact(dV_over_V, params)
                     + pressure_sphere_bending(dV_over_V, params, run.c0_at(int(k))))
    except (ValueError, KeyError, TypeError):
        return math.nan


def events(run_or_path, table=None, *, located: bool = True) -> list[Event]:
    """Buckling events of a run (module docstring), in order of step.

    ``run_or_path``: a :class:`shellbuckle.run.Run` or a run folder. Uses the stored analysis
    columns when every step has them, and classifies the missing steps otherwise (without
    writing; :func:`shellbuckle.analysis.analyze_run` stores them). ``table`` may be given to
    avoid re-reading it. ``located``: use the located thresholds stored with the run (those
    at the same step as found here); False gives the values read at the steps.
    """
    from ..store.view import Run

    run = Run.of(run_or_path)
    table = table_with_shapes(run, table).reset_index(drop=True)
    if table.empty:
        return []
    shape = table["shape"].astype(str).to_numpy()
    dv = table["dV_over_V"].to_numpy(dtype=float)
    step = table["step"].to_numpy(dtype=int)
    out: list[Event] = []
    buckled = shape != "sphere"
    if buckled.any():
        i = int(np.argmax(buckled))
        from ..params import unit_scale

        if i > 0:  # a run that starts buckled (a branch) has no primary buckling of its own
            ok, why = _primary_confirmation(
                table, i, lambda k: _sphere_pressure(run, dv[k], step[k]),
                unit_scale(run.params, "pressure"))
            out.append(Event("primary_buckling", int(step[i]), float(dv[i]), ok,
                             f"{shape[i - 1]} -> {shape[i]}; {why}"))
        lost = np.isin(shape, ("polygonal", "wrinkled"))
        j = _first_persistent(lost, i, PERSISTENCE)
        if j is not None and j > 0:
            corners = int(table["corners"].iloc[j]) if "corners" in table else 0
            out.append(Event("axisymmetry_loss", int(step[j]), float(dv[j]), None,
                             f"{shape[j - 1]} -> {shape[j]} with "
                             f"{corners} corners"))
        j = _first_persistent(shape == "wrinkled", i, PERSISTENCE)
        if j is not None and j > 0:
            W = int(table["W"].iloc[j]) if "W" in table else 0
            out.append(Event("wrinkles", int(step[j]), float(dv[j]), None,
                             f"{shape[j - 1]} -> wrinkled with W = {W}"))
    if "inertia" in table.columns:
        inertia = table["inertia"].to_numpy(dtype=float)
        for k in range(1, len(table)):
            a, b = inertia[k - 1], inertia[k]
            if a >= 0 and b >= 0 and a != b:
                out.append(Event("inertia_change", int(step[k]), float(dv[k]), None,
                                 f"negative Hessian eigenvalues {int(a)} -> {int(b)}"))
    out = [_resolved(e, dv, step) for e in out]
    if located:
        out = _with_located(out, run)
    out.sort(key=lambda e: (e.step, EVENT_NAMES.index(e.name)))
    return out


def _resolved(event: Event, dv: np.ndarray, step: np.ndarray) -> Event:
    """``event`` with its resolution: the volume step that ends at its step."""
    i = int(np.searchsorted(step, event.step))
    before = dv[i - 1] if i > 0 else 0.0
    return dataclasses.replace(event, resolution=float(abs(dv[i] - before)))


def located_point(event: Event, points: dict) -> dict | None:
    """The located point of ``event`` among a run's located ``points``
    (:func:`shellbuckle.store.located.read_located`): the one of its name, if it was located at
    the event's step and its location is complete; else None."""
    point = points.get(event.name)
    if point and point.get("step") == event.step and point.get("complete", False):
        return point
    return None


def _with_located(found: list[Event], run) -> list[Event]:
    from ..store.located import read_located

    points = read_located(run.path)
    out = []
    for e in found:
        point = located_point(e, points)
        if point:
            e = dataclasses.replace(
                e, dV_over_V=float(point["dV_over_V"]), resolution=float(point["hi"] - point["lo"]),
                located=True, description=f"{e.description}; located at dV/V = "
                f"{point['dV_over_V']:.5f} ± {point['uncertainty']:.1e} ({point['mechanism']})")
        out.append(e)
    return out


def thresholds(run_or_path, table=None, *, located: bool = True) -> dict:
    """``{"primary_buckling": dV/V, "axisymmetry_loss": dV/V, "wrinkles": dV/V}`` of a run, NaN
    for an event that did not happen (the inputs of the paper's Fig. 10); located values where
    the run has them, unless ``located`` is False."""
    found = {e.name: e.dV_over_V for e in events(run_or_path, table, located=located)
             if e.name != "inertia_change"}
    return {name: found.get(name, math.nan) for name in EVENT_NAMES[:3]}
