"""The secant pairs of an L-BFGS method and its two-loop recursion, compiled (Numba).

``H r`` for the inverse-Hessian approximation built from the last ``m`` pairs
``(s_i, y_i)`` (``rho_i = 1 / s_i . y_i``) on top of an initial inverse Hessian ``H0``
(Nocedal & Wright, *Numerical Optimization*, 2nd ed., Algorithm 7.4): the first loop runs
from the newest pair to the oldest (``a_i = rho_i s_i . q``, ``q -= a_i y_i``), ``H0`` is
applied to ``q``, and the second loop runs back (``z += (a_i - rho_i y_i . z) s_i``).

Newton's method (:mod:`.newton`, :mod:`.relax`) uses a factorization of the KKT matrix as
``H0``; the loops around it are 4 m passes over vectors of ``3V`` numbers. The pairs live in
preallocated rows and the loops update in place, without a temporary per pass. Sums run in
index order: reproducible bits.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _first_loop(S, Y, rho, order, q, a):
    """Newest to oldest (``order`` lists the rows oldest first): ``a_i = rho_i s_i . q``,
    ``q -= a_i y_i``, in place; ``a`` in ``order``'s order."""
    n = q.shape[0]
    for idx in range(order.shape[0] - 1, -1, -1):
        i = order[idx]
        acc = 0.0
        for k in range(n):
            acc += S[i, k] * q[k]
        ai = rho[i] * acc
        a[idx] = ai
        for k in range(n):
            q[k] -= ai * Y[i, k]


@njit(cache=True, nogil=True)
def _second_loop(S, Y, rho, order, a, z):
    """Oldest to newest: ``z += (a_i - rho_i y_i . z) s_i``, in place."""
    n = z.shape[0]
    for idx in range(order.shape[0]):
        i = order[idx]
        acc = 0.0
        for k in range(n):
            acc += Y[i, k] * z[k]
        c = a[idx] - rho[i] * acc
        for k in range(n):
            z[k] += c * S[i, k]


class SecantPairs:
    """The last ``memory`` secant pairs of an L-BFGS method over ``n`` unknowns.

    :meth:`add` keeps a pair only if its curvature ``s . y`` is positive (relative to
    ``|s| |y|``, 1e-12), dropping the oldest one when full; :meth:`apply` is the two-loop
    recursion around a given ``H0``."""

    def __init__(self, n: int, memory: int):
        self.memory = max(int(memory), 0)
        self.S = np.empty((self.memory, n))
        self.Y = np.empty((self.memory, n))
        self.rho = np.empty(self.memory)
        self._order: list[int] = []  # rows, oldest first

    def __len__(self) -> int:
        return len(self._order)

    def clear(self) -> None:
        self._order.clear()

    def add(self, s: np.ndarray, y: np.ndarray) -> None:
        s, y = s.ravel(), y.ravel()
        sy = float(s @ y)
        if self.memory == 0 or not sy > 1e-12 * np.linalg.norm(s) * np.linalg.norm(y):
            return
        if len(self._order) == self.memory:
            row = self._order.pop(0)
        else:
            row = next(i for i in range(self.memory) if i not in self._order)
        self.S[row], self.Y[row], self.rho[row] = s, y, 1.0 / sy
        self._order.append(row)

    def apply(self, r: np.ndarray, H0) -> np.ndarray:
        """``H r`` (a new flat array) with ``H0(q) -> z`` the initial inverse Hessian applied
        to a flat vector (it may return ``q`` itself, changed in place)."""
        q = np.array(r, dtype=np.float64).ravel()
        if not self._order:
            return H0(q)
        order = np.array(self._order, dtype=np.int64)
        a = np.empty(len(order))
        _first_loop(self.S, self.Y, self.rho, order, q, a)
        z = np.ascontiguousarray(H0(q), dtype=np.float64)
        _second_loop(self.S, self.Y, self.rho, order, a, z)
        return z
