"""Richardson extrapolation in the mean edge h of a sequence of meshes: the value at h -> 0,
the order fitted from three meshes or assumed from two, and when a sequence is not
converged."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

#: Order of the discretization error assumed when it cannot be fitted (two meshes): the
#: bending and stretching energies of the discrete shell converge as h^2 on smooth shapes.
ASSUMED_ORDER = 2.0
#: Fitted orders below MIN_ORDER mean the sequence is not in its asymptotic regime (above
#: MAX_ORDER: converged, or not, by VANISHING). The discrete energies converge as h^2 and a
#: located threshold at least as h; an order below 1/2 means increments that barely shrink (by
#: less than 1.41 when h halves), and the extrapolation would reach beyond the finest value by
#: more than 2.4 times the last increment (1 / (2^p - 1)): a guess, not a limit.
MIN_ORDER = 0.5
MAX_ORDER = 20.0
#: Increments that shrink faster than at MAX_ORDER are converged where the last is at most
#: this fraction of the one before (meshes of nearly one size fit high orders to any sequence).
VANISHING = 1e-3


@dataclasses.dataclass(frozen=True)
class Extrapolation:
    """``q(h) = value + c h^order`` through the finest meshes; ``method`` says how the order
    was had: ``fitted`` (three meshes, monotone), ``assumed`` (:data:`ASSUMED_ORDER`, two
    meshes), ``equal`` (the two finest give the same value, to the resolution of a located
    threshold), ``not converged`` (value NaN: three that are not monotone, or a fitted order
    below :data:`MIN_ORDER`, or above :data:`MAX_ORDER` with a last increment that does not
    vanish), ``gap`` (value NaN: a mesh finer than one with the value lacks it),
    ``no value`` or ``one mesh`` (value NaN: the quantity is had on no mesh, or on one),
    ``to the finest`` (value NaN: an angle measured to the finest mesh, or a state carried to
    it, nothing to extrapolate), ``not located`` (value NaN: a threshold known on some mesh to
    its volume step only, which no extrapolation can sharpen), ``count`` (value NaN: a count,
    W, reported per mesh and not extrapolated), ``converged`` (the increments shrink faster
    than at order :data:`MAX_ORDER`: the finest value is the limit)."""

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
        if self.method == "not located":
            return "not located on every mesh (known to the volume step only)"
        if self.method == "count":
            return "a count: not extrapolated"
        if self.method == "converged":
            return f"converged (the increments vanish faster than at order {MAX_ORDER:g})"
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
#: A threshold that some mesh's run has not located (its value is a volume step's end).
NOT_LOCATED = Extrapolation(math.nan, math.nan, math.nan, "not located")
#: A count (W): the mean of integers over steps and seeds, not a smooth function of h.
COUNT = Extrapolation(math.nan, math.nan, math.nan, "count")


def _order(h, q) -> float | None:
    """The p with (q1 - q2)/(q2 - q3) = (h1^p - h2^p)/(h2^p - h3^p), h1 > h2 > h3, or None
    when none lies in [MIN_ORDER, MAX_ORDER]; ``math.inf`` when the increments shrink faster
    than at MAX_ORDER and the last is at most :data:`VANISHING` times the one before. The
    right side grows monotonically with p."""
    from scipy.optimize import brentq

    (h1, h2, h3), (q1, q2, q3) = h, q
    target = math.log((q1 - q2) / (q2 - q3))

    def gap(p):
        return math.log((h1 ** p - h2 ** p) / (h2 ** p - h3 ** p)) - target

    low, high = MIN_ORDER, MAX_ORDER
    if gap(high) < 0:  # faster than MAX_ORDER: converged only if the last increment vanishes
        return math.inf if abs(q3 - q2) <= VANISHING * abs(q2 - q1) else None
    if gap(low) > 0:
        return None
    return float(brentq(gap, low, high, xtol=1e-14, rtol=1e-14))


def richardson(h, q, *, assumed_order: float = ASSUMED_ORDER,
               resolution: float = 0.0) -> Extrapolation:
    """Richardson extrapolation of ``q`` (values) at mesh sizes ``h`` to h -> 0.

    Two finest values within ``resolution`` of each other (a located threshold is known to its
    bisection's bracket) are ``equal``: the limit is the finest value, to that resolution.

    NaN values of the coarsest meshes are left out and the finest meshes used: with three or
    more, the three finest fit ``q = q0 + c h^p`` exactly when the sequence is monotone (else:
    not converged; a fitted order above :data:`MAX_ORDER` and a last increment at most
    :data:`VANISHING` times the one before: converged at the finest value); with two, the
    order is ``assumed_order``:
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
        if p == math.inf:
            return Extrapolation(float(q[-1]), math.inf, 0.0, "converged")
        method = "fitted"
    else:
        p, method = float(assumed_order), "assumed"
    c = (q[-2] - q[-1]) / (h[-2] ** p - h[-1] ** p)
    return Extrapolation(float(q[-1] - c * h[-1] ** p), p, float(c), method)
