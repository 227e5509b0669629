"""Enclosed volume of a closed oriented surface, the quantity held fixed by the constraint.

V = (1/6) sum_f x0 . (x1 x x2) over faces ``(x0, x1, x2)`` with outward orientation
(divergence theorem). It is invariant under translations and rotations.

The volume is cubic in the positions and linear in each vertex, which the kernels use:

- value and gradient are one compiled loop over the faces (:func:`.kernels.volume`);
- the Hessian has no diagonal blocks and its entries are linear in ``X``: its CSR data is one
  product ``B @ X.ravel()`` with a sparse matrix ``B`` built once per mesh;
- along a straight line the volume is an exact cubic in the step length
  (:meth:`Volume.along`), so the constraint can be restored along a direction by solving a
  cubic instead of iterating (see :func:`shellbuckle.solve.linesearch.restore_volume`;
  :meth:`Volume.restore` is that restoration as one compiled loop).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from . import kernels
from .assembly import ElementAssembler


@dataclass(frozen=True, eq=False)
class Volume:
    """Enclosed volume; ``gradient`` is the constraint normal used by the solvers."""

    faces: np.ndarray
    n_vertices: int
    _assembler: ElementAssembler = field(init=False, repr=False)
    _corner: np.ndarray = field(init=False, repr=False)
    _hessian_map: sp.csr_matrix = field(init=False, repr=False)

    def __post_init__(self):
        faces = np.asarray(self.faces, dtype=np.int64)
        assembler = ElementAssembler(faces, self.n_vertices)
        object.__setattr__(self, "_assembler", assembler)
        object.__setattr__(self, "_corner", np.ascontiguousarray(faces.T))
        object.__setattr__(self, "_hessian_map", self._build_hessian_map(faces, assembler))

    def _compiled(self, X, gradient: bool):
        """``(value, gradient or (0, 3))`` from :func:`.kernels.volume`."""
        value, G = kernels.volume(kernels.positions(X, self.n_vertices), self._corner, gradient)
        return float(value), G

    def value(self, X: np.ndarray) -> float:
        return self._compiled(X, False)[0]

    def gradient(self, X: np.ndarray) -> np.ndarray:
        return self._compiled(X, True)[1]

    def value_and_gradient(self, X: np.ndarray) -> tuple[float, np.ndarray]:
        return self._compiled(X, True)

    def along(self, X: np.ndarray, D: np.ndarray) -> np.ndarray:
        """Coefficients ``c`` of the exact cubic ``V(X + t D) = c0 + c1 t + c2 t^2 + c3 t^3``."""
        n = self.n_vertices
        return kernels.volume_along(kernels.positions(X, n), kernels.positions(D, n), self._corner)

    def restore(self, X: np.ndarray, V_target: float,
                rtol: float = 1e-15) -> tuple[np.ndarray, float]:
        """A copy of ``X`` moved along the volume gradient to ``V_target``, and the relative
        error left (:func:`shellbuckle.solve.linesearch.restore_volume`; one compiled call)."""
        X, err = kernels.restore_volume(kernels.positions(X, self.n_vertices), self._corner,
                                        float(V_target), float(rtol))
        return X, float(err)

    def hessian(self, X: np.ndarray) -> sp.csr_matrix:
        data = self._hessian_map @ np.asarray(X, dtype=np.float64).ravel()
        a = self._assembler
        return sp.csr_matrix((data, a.indices, a.indptr), shape=(a.n_dofs, a.n_dofs))

    @staticmethod
    def _build_hessian_map(faces: np.ndarray, assembler: ElementAssembler) -> sp.csr_matrix:
        """``B`` with ``Hessian data = B @ X.ravel()``: the block of a face's vertex pair
        ``(p, q)`` is ``-[x_r]_x / 6`` if ``q`` follows ``p`` in the face, ``+[x_r]_x / 6`` if it
        precedes it (``r`` the third vertex, ``[v]_x`` the cross-product matrix); diagonal
        blocks vanish."""
        skew = [(0, 1, 2, -1.0), (0, 2, 1, 1.0), (1, 0, 2, 1.0), (1, 2, 0, -1.0),
                (2, 0, 1, -1.0), (2, 1, 0, 1.0)]  # ([v]_x)[i, j] = sign v[k]
        slots = assembler.slot.reshape(len(faces), 9, 9)
        rows, cols, vals = [], [], []
        for p in range(3):
            for q in range(3):
                if p == q:
                    continue
                r = 3 - p - q
                sign = -1.0 if q == (p + 1) % 3 else 1.0
                for i, j, k, s in skew:
                    rows.append(slots[:, 3 * p + i, 3 * q + j])
                    cols.append(3 * faces[:, r] + k)
                    vals.append(np.full(len(faces), sign * s / 6.0))
        B = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(assembler.nnz, assembler.n_dofs))
        B.sum_duplicates()
        return B
