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

from .assembly import ElementAssembler


def _skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[v]_x`` of ``v (..., 3)``, shape ``(..., 3, 3)``."""
    out = np.zeros(v.shape + (3,))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


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


@dataclass(frozen=True, eq=False)
class Area:
    """Total area ``sum_f |(x1 - x0) x (x2 - x0)| / 2`` with exact gradient and Hessian.

    ``faces (F, 3)`` int, ``n_vertices``. The gradient is undefined on a face of zero area;
    there it is taken as zero (the Hessian would be infinite and is not meaningful).
    """

    faces: np.ndarray
    n_vertices: int
    _assembler: ElementAssembler = field(init=False, repr=False)

    def __post_init__(self):
        faces = np.asarray(self.faces)
        if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
            raise ValueError(f"faces must be an integer (F, 3) array, got {faces.dtype} {faces.shape}")
        if faces.size and (faces.min() < 0 or faces.max() >= self.n_vertices):
            raise ValueError(f"face vertex indices must lie in [0, {self.n_vertices})")
        object.__setattr__(self, "faces", faces.astype(np.int64, copy=False))
        object.__setattr__(self, "_assembler", ElementAssembler(self.faces, self.n_vertices))

    def _corners(self, X):
        X = np.asarray(X, dtype=np.float64)
        if X.shape != (self.n_vertices, 3):
            raise ValueError(f"positions must have shape ({self.n_vertices}, 3), got {X.shape}")
        return X[self.faces]  # (F, 3 corners, 3)

    def value(self, X) -> float:
        x = self._corners(X)
        n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        return float(0.5 * np.sqrt(np.einsum("ij,ij->i", n, n)).sum())

    def gradient(self, X) -> np.ndarray:
        """Exact gradient ``(V, 3)``: 1/2 nhat x (x_c - x_b) at corner a."""
        x = self._corners(X)
        n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        norm = np.sqrt(np.einsum("ij,ij->i", n, n))
        nhat = np.divide(n, norm[:, None], out=np.zeros_like(n), where=norm[:, None] > 0)
        opposite = np.roll(x, -2, axis=1) - np.roll(x, -1, axis=1)  # x_c - x_b for corner a
        local = 0.5 * np.cross(nhat[:, None, :], opposite)
        return self._assembler.gradient(local)

    def hessian(self, X) -> sp.csr_matrix:
        """Exact Hessian, CSR ``(3V, 3V)``, vertex-major dofs."""
        x = self._corners(X)
        n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        norm = np.sqrt(np.einsum("ij,ij->i", n, n))
        nhat = n / norm[:, None]
        J = _skew(np.roll(x, -2, axis=1) - np.roll(x, -1, axis=1))  # (F, 3 corners, 3, 3)
        P = np.eye(3) - nhat[:, :, None] * nhat[:, None, :]
        # (f, a, c, b, d): J_a^T P J_b / (2|n|)
        H = np.einsum("faic,fij,fbjd->facbd", J, P, J, optimize=True) / (2.0 * norm)[:, None, None, None, None]
        K = 0.5 * _skew(nhat)
        for a in range(3):
            H[:, a, :, (a + 1) % 3, :] -= K
            H[:, a, :, (a + 2) % 3, :] += K
        return self._assembler.hessian(H.reshape(-1, 9, 9))
