"""The energy-term interface and the sum of terms.

Every term is a small frozen object with ``value(X) -> float``, ``gradient(X) -> (V, 3)`` and
``hessian(X) -> scipy.sparse.csr_matrix (3V, 3V)`` (vertex-major dofs, see
:mod:`shellbuckle.energies.assembly`). Hessians are the true second derivatives, never
projected: buckling *is* a negative eigenvalue. Terms compose by summing (``Sum``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import scipy.sparse as sp


@runtime_checkable
class Energy(Protocol):
    def value(self, X: np.ndarray) -> float: ...

    def gradient(self, X: np.ndarray) -> np.ndarray: ...

    def hessian(self, X: np.ndarray) -> sp.csr_matrix: ...


@dataclass(frozen=True)
class Sum:
    """Sum of energy terms, itself an energy term."""

    terms: tuple

    def __init__(self, terms):
        object.__setattr__(self, "terms", tuple(terms))

    def value(self, X: np.ndarray) -> float:
        return float(sum(t.value(X) for t in self.terms))

    def gradient(self, X: np.ndarray) -> np.ndarray:
        return sum(t.gradient(X) for t in self.terms)

    def hessian(self, X: np.ndarray) -> sp.csr_matrix:
        return sum(t.hessian(X) for t in self.terms).tocsr()
