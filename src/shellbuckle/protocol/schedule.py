"""Volume schedules: the sequence of target relative volume changes dV/V, one per step.

``dV/V = (V0 - V) / V0`` where ``V0`` is the volume of the initial (stress-free) mesh, so
deflation increases dV/V and re-inflation decreases it. The paper's protocol uses steps of
``dv = 0.0190`` (Quilliet et al. 2008, §4.1).
"""

from __future__ import annotations

import math

import numpy as np

PAPER_DV = 0.0190
"""Volume step of the paper, as a fraction of the initial volume V0."""

MAX_DV_OVER_V = 0.99
"""Largest target dV/V accepted: the enclosed volume must stay positive."""


def linear_schedule(dv: float = PAPER_DV, until: float = 0.95, start: float = 0.0) -> np.ndarray:
    """Targets ``start + dv, start + 2 dv, ...`` up to ``until`` (included when it falls on a step).

    ``dv < 0`` with ``until < start`` gives a re-inflation schedule.
    """
    dv, until, start = _real("dv", dv), _real("until", until), _real("start", start)
    if dv == 0:
        raise ValueError("dv (volume step / V0) must be non-zero, got 0")
    if abs(dv) > 0.5:
        raise ValueError(f"dv (volume step / V0) must be in [-0.5, 0.5] \\ {{0}}, got {dv!r}")
    if (until - start) * dv <= 0:
        direction = "larger" if dv > 0 else "smaller"
        raise ValueError(f"until = {until!r} must be {direction} than the start dV/V = {start!r} "
                         f"for dv = {dv!r}")
    if not -1.0 < until < MAX_DV_OVER_V:
        raise ValueError(f"until = {until!r}: allowed: a dV/V in (-1, {MAX_DV_OVER_V}) "
                         "(dV/V = 1 - V/V0)")
    n = steps_between(start, until, dv)
    if n == 0:
        raise ValueError(f"until = {until!r} is less than one step dv = {dv!r} from the start "
                         f"dV/V = {start!r}: no target in between")
    return check_schedule(start + dv * np.arange(1, n + 1))


def steps_between(start: float, until: float, dv: float) -> int:
    """The number of whole steps ``dv`` from ``start`` towards ``until`` (the targets of
    :func:`linear_schedule`); 0 when ``until`` is less than one step away."""
    return max(0, int(math.floor((until - start) / dv + 1e-9)))


def geometric_schedule(start: float, end: float, increments: int) -> np.ndarray:
    """``increments`` values from ``start`` to ``end`` in equal ratios (``start`` excluded,
    ``end`` included exactly): ``start (end/start)^(k/n)``, k = 1..n. For a positive parameter
    spanning decades, such as gamma; ``increments = 0`` gives an empty schedule."""
    start, end = _real("start", start), _real("end", end)
    n = _increments(increments)
    if start <= 0 or end <= 0:
        raise ValueError(f"a geometric schedule needs positive values, got start = {start!r}, "
                         f"end = {end!r} (gamma = A R^2/kappa must be > 0)")
    values = start * (end / start) ** (np.arange(1, n + 1) / max(n, 1))
    if n:
        values[-1] = end
    return values


def linear_values(start: float, end: float, increments: int) -> np.ndarray:
    """``increments`` equally spaced values from ``start`` (excluded) to ``end`` (included
    exactly), e.g. a path in the spontaneous curvature c0; 0 increments: empty."""
    start, end = _real("start", start), _real("end", end)
    n = _increments(increments)
    values = start + (end - start) * np.arange(1, n + 1) / max(n, 1)
    if n:
        values[-1] = end
    return values


def _increments(n) -> int:
    try:
        ok = not isinstance(n, bool) and float(n).is_integer() and n >= 0
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"increments must be an integer >= 0, got {n!r}")
    return int(n)


def check_schedule(targets) -> np.ndarray:
    """Validate a list of target dV/V values; each must be finite and below ``MAX_DV_OVER_V``."""
    targets = np.atleast_1d(np.asarray(targets, dtype=float))
    if targets.ndim != 1 or len(targets) == 0:
        raise ValueError("a volume schedule must be a non-empty list of target dV/V values")
    bad = ~np.isfinite(targets) | (targets >= MAX_DV_OVER_V) | (targets <= -1.0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"target dV/V number {k + 1} is {targets[k]!r}; each target must lie in "
                         f"(-1, {MAX_DV_OVER_V}) (dV/V = 1 - V/V0)")
    return targets


def _real(name, value) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return value
