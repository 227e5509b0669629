"""Assembly of the reduced KKT matrix of Newton's method at fixed volume.

Newton's method keeps its iterates on the constraint surface and solves, for a tangent step
``dx``, the saddle-point system (Nocedal & Wright, *Numerical Optimization*, 2nd ed., §16.1;
Benzi, Golub & Liesen, Acta Numerica 14, 1 (2005))

    [[K + mu I, g], [g^T, 0]] [dx; dlam] = -[r; V - V_target],
    K = Hess E - lam Hess V,  g = grad V,

restricted to the free dofs (the pinned ones fix the rigid-motion gauge, :mod:`.gauge`).
:class:`KKTAssembler` builds its upper triangle as a CSR matrix whose pattern stays fixed while
the patterns of the Hessian terms do, so the linear solver reuses its symbolic analysis. As in
scikit-fem's ``COOData``, the map from every stored entry of every term to its slot in the
result is computed once per pattern (a sort of integer keys); an assembly is then one scatter
per term (compiled, :func:`~shellbuckle.energies.kernels.add_scaled_at`), without sparse sums,
transposes or sorting.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..energies.kernels import add_scaled_at


def _sorted_unique(a: np.ndarray) -> np.ndarray:
    """``np.unique(a)`` for integer keys, by a sort (the KKT pattern's keys come nearly sorted,
    row by row, where a sort is much faster than ``np.unique``'s hash table)."""
    a = np.sort(a)
    keep = np.empty(a.size, dtype=bool)
    keep[:1] = True
    np.not_equal(a[1:], a[:-1], out=keep[1:])
    return a[keep]


def _contains(sorted_keys: np.ndarray, keys: np.ndarray) -> bool:
    """Whether every one of ``keys`` is in ``sorted_keys`` (sorted, unique)."""
    if not keys.size:
        return True
    if not sorted_keys.size:
        return False
    at = np.minimum(np.searchsorted(sorted_keys, keys), sorted_keys.size - 1)
    return bool(np.array_equal(sorted_keys[at], keys))


class KKTAssembler:
    """Upper triangle of the reduced KKT matrix ``[[sum_t c_t M_t + mu I, g], [g^T, 0]]`` over
    the free dofs ``f``, from symmetric sparse terms ``M_t`` (the energy and volume Hessians).

    The result is a CSR matrix (sorted indices, int32) whose pattern is the union of the
    patterns seen so far: a term whose pattern lies within it keeps it, one with new entries
    widens it (the diagonal, the constraint column and the corner are always stored).
    """

    def __init__(self, free: np.ndarray, n_dofs: int):
        self.free = np.asarray(free)
        self.n = len(self.free)
        self.n_dofs = int(n_dofs)
        self.new_index = np.full(n_dofs, -1, dtype=np.int64)
        self.new_index[self.free] = np.arange(self.n)
        self._keys = None
        self._terms: list = []

    def _term_keys(self, M: sp.csr_matrix):
        """Positions of the kept (free, upper) entries of ``M`` and their pattern keys."""
        rows = np.repeat(np.arange(self.n_dofs), np.diff(M.indptr))
        a, b = self.new_index[rows], self.new_index[M.indices]
        keep = np.flatnonzero((a >= 0) & (a <= b))
        return keep, a[keep] * (self.n + 1) + b[keep]

    def _analyse(self, mats):
        n = self.n
        found = [self._term_keys(M) for M in mats]
        if self._keys is None or not all(_contains(self._keys, keys) for _, keys in found):
            ar = np.arange(n + 1, dtype=np.int64)
            fixed = [ar[:n] * (n + 1) + ar[:n], ar * (n + 1) + n]  # diagonal; g column, corner
            self._keys = _sorted_unique(np.concatenate(fixed + [keys for _, keys in found]))
            rows = self._keys // (n + 1)
            self._indices = (self._keys % (n + 1)).astype(np.int32)
            self._indptr = np.zeros(n + 2, dtype=np.int32)
            np.cumsum(np.bincount(rows, minlength=n + 1), out=self._indptr[1:])
            self._slot_diag = np.searchsorted(self._keys, ar[:n] * (n + 1) + ar[:n])
            self._slot_g = np.searchsorted(self._keys, ar[:n] * (n + 1) + n)
        self._terms = [(M.indptr.copy(), M.indices.copy(), keep,
                        np.searchsorted(self._keys, keys)) for M, (keep, keys) in zip(mats, found)]

    def _same_patterns(self, mats) -> bool:
        return len(mats) == len(self._terms) and all(
            len(M.indices) == len(t[1]) and np.array_equal(M.indptr, t[0])
            and np.array_equal(M.indices, t[1]) for M, t in zip(mats, self._terms))

    def build(self, terms, g: np.ndarray) -> np.ndarray:
        """Data array of the unshifted matrix. ``terms``: list of ``(M (3V, 3V) csr,
        coefficient)``; ``g (V, 3)`` the constraint gradient."""
        mats = [M if sp.issparse(M) and M.format == "csr" else sp.csr_matrix(M) for M, _ in terms]
        for M in mats:
            if not M.has_canonical_format:  # one slot per stored entry is assumed below
                M.sum_duplicates()
        if not self._same_patterns(mats):
            self._analyse(mats)
        data = np.zeros(len(self._keys))
        for M, (coef, (_, _, keep, slot)) in zip(mats, zip([c for _, c in terms], self._terms)):
            add_scaled_at(data, slot, np.ascontiguousarray(M.data, dtype=np.float64), keep,
                          float(coef))
        data[self._slot_g] = g.ravel()[self.free]
        return data

    def diagonal(self, data: np.ndarray) -> np.ndarray:
        """The diagonal of ``K_ff`` in a data array from :meth:`build`."""
        return data[self._slot_diag]

    def matrix(self, data: np.ndarray, mu: float = 0.0) -> sp.csr_matrix:
        """The upper-triangular CSR matrix of ``data`` with ``mu`` added to ``K_ff``'s diagonal."""
        if mu != 0.0:
            data = data.copy()
            data[self._slot_diag] += mu
        return sp.csr_matrix((data, self._indices, self._indptr), shape=(self.n + 1, self.n + 1))
