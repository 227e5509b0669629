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


def block_layout(bptr: np.ndarray, bcol: np.ndarray):
    """The CSR layout over ``3 V`` dofs (vertex-major) of a pattern of 3x3 vertex blocks:
    block row ``a`` holds blocks ``bptr[a]:bptr[a + 1]`` with columns ``bcol`` (increasing),
    and each of its three dof rows holds entry ``d`` of every block in turn, so entry
    ``(c, d)`` of block ``k`` of row ``a`` lies at ``first[k] + c stride[a] + d``. Returns
    ``(first, stride, indices (int32), indptr (int32))``."""
    per_row = np.diff(bptr)
    brow = np.repeat(np.arange(len(per_row)), per_row)
    stride = 3 * per_row
    first = 9 * bptr[brow] + 3 * (np.arange(len(bcol)) - bptr[brow])
    indices = np.empty(9 * len(bcol), dtype=np.int32)
    for c in range(3):
        for d in range(3):
            indices[first + c * stride[brow] + d] = 3 * bcol + d
    indptr = np.append((9 * bptr[:-1, None] + 3 * np.arange(3) * per_row[:, None]).ravel(),
                       len(indices)).astype(np.int32)
    return first, stride, indices, indptr


class ElementAssembler:
    """Assembly of element quantities over ``elements (n_el, k)`` vertex indices."""

    def __init__(self, elements: np.ndarray, n_vertices: int):
        elements = np.asarray(elements, dtype=np.int64)
        V = self.n_vertices = int(n_vertices)
        self.n_dofs = 3 * V
        n_el, k = elements.shape
        self.dofs = (3 * elements[:, :, None] + np.arange(3)).reshape(n_el, 3 * k)
        # the pattern by vertex blocks (a, b), sorted (9 times fewer keys than by dofs)
        block_keys = (np.repeat(elements, k, axis=1) * V + np.tile(elements, (1, k))).ravel()
        blocks, block_of = np.unique(block_keys, return_inverse=True)
        bptr = np.zeros(V + 1, dtype=np.int64)
        np.cumsum(np.bincount(blocks // V, minlength=V), out=bptr[1:])
        first, stride, self.indices, self.indptr = block_layout(bptr, blocks % V)
        self.nnz = len(self.indices)
        # local entry (3 i + c, 3 j + d) of an element: first[block (i, j)] + c stride[v_i] + d
        c = np.arange(3)
        self.slot = (first[block_of.reshape(n_el, k, 1, k, 1)]
                     + c[:, None, None] * stride[elements][:, :, None, None, None]
                     + c).reshape(-1)

    def gradient(self, local: np.ndarray) -> np.ndarray:
        """Sum local gradients ``(n_el, k, 3)`` into a ``(V, 3)`` array."""
        g = np.bincount(self.dofs.ravel(), weights=local.ravel(), minlength=self.n_dofs)
        return g.reshape(self.n_vertices, 3)

    def hessian(self, local: np.ndarray) -> sp.csr_matrix:
        """Sum local Hessians ``(n_el, 3k, 3k)`` into a ``(3V, 3V)`` CSR matrix."""
        data = np.bincount(self.slot, weights=local.ravel(), minlength=self.nnz)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n_dofs, self.n_dofs))
