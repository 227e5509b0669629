"""Total area of a triangulated surface, and per-face areas and unit normals.

For a face ``(x0, x1, x2)`` (counter-clockwise seen from outside) the area vector is
``n = (x1 - x0) x (x2 - x0)``, the area ``|n| / 2`` and the outward unit normal ``n / |n|``.
The total area ``sum_f |n_f| / 2`` is invariant under rigid motions and scales as ``s^2``.

Derivatives (exact). For corner ``a`` with the next corners ``b = a+1``, ``c = a+2`` (mod 3),
``dn = J_a dx_a`` with ``J_a = [x_c - x_b]_x`` (cross-product matrix), so

    d area / dx_a = 1/2 nhat x (x_c - x_b),
    d^2 area / dx_a dx_b = 1/(2|n|) J_a^T (I - nhat nhat^T) J_b + 1/2 K_ab,

with ``K_ab = -[nhat]_x`` if ``b = a+1``, ``+[nhat]_x`` if ``b = a-1`` and 0 if ``a = b`` (the
second derivative of the bilinear ``n`` projected on ``nhat``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from . import kernels
from .stretching import FaceAssembler


def face_area_vectors(X: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area vectors ``n = (x1 - x0) x (x2 - x0)`` (twice the area times the unit normal), ``(F, 3)``."""
    x0 = X[faces[:, 0]]
    return np.cross(X[faces[:, 1]] - x0, X[faces[:, 2]] - x0)


def face_areas_normals(X: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-face areas ``(F,)`` and unit normals ``(F, 3)`` (outward for outward-oriented faces).

    A face of zero area gets a zero normal rather than NaN.
    """
    n = face_area_vectors(np.asarray(X, dtype=np.float64), np.asarray(faces))
    norm = np.sqrt(np.einsum("ij,ij->i", n, n))
    unit = np.divide(n, norm[:, None], out=np.zeros_like(n), where=norm[:, None] > 0)
    return 0.5 * norm, unit


def _cross_cm(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of component-major vectors ``(3, ...)``."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@dataclass(frozen=True, eq=False)
class Area:
    """Total area ``sum_f |(x1 - x0) x (x2 - x0)| / 2`` with exact gradient and Hessian.

    ``faces (F, 3)`` int, ``n_vertices``. Kernels work on ``s = x1 - x0``, ``t = x2 - x0``:
    ``d area/ds = 1/2 t x nhat``, ``d area/dt = 1/2 nhat x s``; the off-diagonal vertex block
    of corners ``(a, a+1)`` is ``[(e.e') I - e' e^T - m m'^T] / (2|n|) - [nhat]_x / 2`` with
    ``e = x_{a+2} - x_{a+1}``, ``e' = x_a - x_{a+2}``, ``m = nhat x e``, ``m' = nhat x e'``
    (from ``[e]_x^T P [e']_x`` with ``P = I - nhat nhat^T``); diagonal blocks follow from
    translation invariance. A face of zero area has no defined gradient: it contributes zero.
    """

    faces: np.ndarray
    n_vertices: int
    _sorted_faces: np.ndarray = field(init=False, repr=False)
    _assembler: FaceAssembler = field(init=False, repr=False)

    def __post_init__(self):
        faces = np.asarray(self.faces)
        if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
            raise ValueError(f"faces must be an integer (F, 3) array, got {faces.dtype} {faces.shape}")
        if faces.size and (faces.min() < 0 or faces.max() >= self.n_vertices):
            raise ValueError(f"face vertex indices must lie in [0, {self.n_vertices})")
        faces = faces.astype(np.int64, copy=False)
        # kernels run over faces sorted by smallest vertex (memory locality); the sum is the same
        sorted_faces = faces[np.argsort(faces.min(axis=1), kind="stable")] if faces.size else faces
        object.__setattr__(self, "faces", faces)
        object.__setattr__(self, "_sorted_faces", sorted_faces)
        object.__setattr__(self, "_assembler", FaceAssembler(sorted_faces, self.n_vertices))

    def _edges(self, X):
        """``s = x1 - x0``, ``t = x2 - x0`` component-major ``(3, F)`` and ``n = s x t``."""
        Xt = np.ascontiguousarray(kernels.positions(X, self.n_vertices).T)
        faces = self._sorted_faces
        x0 = np.take(Xt, faces[:, 0], axis=1)
        s = np.take(Xt, faces[:, 1], axis=1) - x0
        t = np.take(Xt, faces[:, 2], axis=1) - x0
        return s, t, _cross_cm(s, t)

    def value(self, X) -> float:
        n = self._edges(X)[2]
        return float(0.5 * np.sqrt(np.einsum("ij,ij->j", n, n)).sum())

    def value_and_gradient(self, X) -> tuple[float, np.ndarray]:
        s, t, n = self._edges(X)
        norm = np.sqrt(np.einsum("ij,ij->j", n, n))
        nhat = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
        g = 0.5 * np.concatenate([_cross_cm(t, nhat), _cross_cm(nhat, s)], axis=1)
        return float(0.5 * norm.sum()), self._assembler.gradient_from_edges(g)

    def gradient(self, X) -> np.ndarray:
        """Exact gradient ``(V, 3)``."""
        return self.value_and_gradient(X)[1]

    def hessian(self, X) -> sp.csr_matrix:
        """Exact Hessian, CSR ``(3V, 3V)``, vertex-major dofs."""
        s, t, n = self._edges(X)
        norm = np.sqrt(np.einsum("ij,ij->j", n, n))
        nhat = n / norm
        # block b couples corners (a, a') = (b+1, b+2): e = x_b - x_{b+2}, e' = x_{b+1} - x_b
        r = t - s
        e = np.stack([-t, s, r], axis=1)  # (3 comp, 3 blocks, F)
        e2 = np.stack([s, r, -t], axis=1)
        m, m2 = _cross_cm(nhat[:, None], e), _cross_cm(nhat[:, None], e2)
        inv = 0.5 / norm
        blocks = e2[:, None] * e[None, :]  # (3 c, 3 d, 3 b, F)
        blocks += m[:, None] * m2[None, :]
        blocks *= -inv
        dot = np.einsum("ibf,ibf->bf", e, e2)
        dot *= inv
        for c in range(3):
            blocks[c, c] += dot
        half = 0.5 * nhat  # - [nhat]_x / 2
        for c, d, sign in ((0, 1, 1), (0, 2, -1), (1, 2, 1)):
            k = 3 - c - d
            blocks[c, d] += sign * half[k]
            blocks[d, c] -= sign * half[k]
        return self._assembler.hessian_from_blocks(blocks)
