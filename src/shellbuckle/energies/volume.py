"""Enclosed volume of a closed oriented surface, the quantity held fixed by the constraint.

V = (1/6) sum_f x0 . (x1 x x2) over faces ``(x0, x1, x2)`` with outward orientation
(divergence theorem). It is invariant under translations and rotations.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .assembly import ElementAssembler


def _skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[v]_x`` of ``v (..., 3)``, shape ``(..., 3, 3)``."""
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1),
                     np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


@dataclass(frozen=True, eq=False)
class Volume:
    """Enclosed volume; ``gradient`` is the constraint normal used by the solvers."""

    faces: np.ndarray
    n_vertices: int
    _assembler: ElementAssembler = field(init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "_assembler", ElementAssembler(self.faces, self.n_vertices))

    def value(self, X: np.ndarray) -> float:
        x0, x1, x2 = (X[self.faces[:, k]] for k in range(3))
        return float(np.einsum("ij,ij->", x0, np.cross(x1, x2)) / 6.0)

    def gradient(self, X: np.ndarray) -> np.ndarray:
        x0, x1, x2 = (X[self.faces[:, k]] for k in range(3))
        local = np.stack([np.cross(x1, x2), np.cross(x2, x0), np.cross(x0, x1)], axis=1) / 6.0
        return self._assembler.gradient(local)

    def hessian(self, X: np.ndarray) -> sp.csr_matrix:
        x = X[self.faces]  # (F, 3, 3)
        local = np.zeros((len(self.faces), 3, 3, 3, 3))
        for a in range(3):
            b, c = (a + 1) % 3, (a + 2) % 3
            # d/dx_b (x_b x x_c) = -[x_c]_x ; d/dx_c (x_b x x_c) = [x_b]_x
            local[:, a, :, b, :] = -_skew(x[:, c]) / 6.0
            local[:, a, :, c, :] = _skew(x[:, b]) / 6.0
        return self._assembler.hessian(local.reshape(-1, 9, 9))
