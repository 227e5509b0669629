"""Scatter per-element gradients and Hessians into global arrays with a fixed sparsity pattern.

Degrees of freedom are vertex-major: the coordinate ``c`` of vertex ``v`` is dof ``3 v + c``,
so a position array ``X (V, 3)`` flattens to ``X.ravel()``. An element with ``k`` vertices
has local dofs ``3 a + c`` for local vertex ``a`` and coordinate ``c``; its local gradient is
``(k, 3)`` and its local Hessian ``(3k, 3k)``.

The CSR pattern and the map from every local Hessian entry to its slot in the CSR data array
are computed once (scikit-fem's COO -> CSR idea); each assembly is then one ``np.bincount``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


class ElementAssembler:
    """Assembly of element quantities over ``elements (n_el, k)`` vertex indices."""

    def __init__(self, elements: np.ndarray, n_vertices: int):
        elements = np.asarray(elements, dtype=np.int64)
        self.n_vertices = int(n_vertices)
        self.n_dofs = 3 * self.n_vertices
        n_el, k = elements.shape
        self.dofs = (3 * elements[:, :, None] + np.arange(3)).reshape(n_el, 3 * k)
        rows = np.broadcast_to(self.dofs[:, :, None], (n_el, 3 * k, 3 * k)).ravel()
        cols = np.broadcast_to(self.dofs[:, None, :], (n_el, 3 * k, 3 * k)).ravel()
        key = rows * self.n_dofs + cols
        unique, self.slot = np.unique(key, return_inverse=True)
        self.slot = self.slot.ravel()
        self.nnz = len(unique)
        self.indices = (unique % self.n_dofs).astype(np.int32)
        self.indptr = np.zeros(self.n_dofs + 1, dtype=np.int32)
        np.cumsum(np.bincount(unique // self.n_dofs, minlength=self.n_dofs), out=self.indptr[1:])

    def gradient(self, local: np.ndarray) -> np.ndarray:
        """Sum local gradients ``(n_el, k, 3)`` into a ``(V, 3)`` array."""
        g = np.bincount(self.dofs.ravel(), weights=local.ravel(), minlength=self.n_dofs)
        return g.reshape(self.n_vertices, 3)

    def hessian(self, local: np.ndarray) -> sp.csr_matrix:
        """Sum local Hessians ``(n_el, 3k, 3k)`` into a ``(3V, 3V)`` CSR matrix."""
        data = np.bincount(self.slot, weights=local.ravel(), minlength=self.nnz)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n_dofs, self.n_dofs))
