"""Sparse symmetric-indefinite factorizations with inertia, for the Newton method.

Every solver has the same three methods:

- ``factor(A)``: ``A`` a real symmetric sparse matrix in full storage (both triangles, any
  scipy format). The symbolic analysis (fill-reducing ordering, elimination tree) is reused
  when the sparsity pattern of ``A`` (with its explicit zeros) equals the previous one, so a
  fixed-pattern Hessian costs one numeric factorization per call.
- ``solve(b)``: ``x`` with ``A x = b``.
- ``inertia()``: ``(n_pos, n_neg, n_zero)`` of ``A`` from the signs of the pivots ``D`` of
  ``P A P^T = L D L^T`` (Sylvester's law of inertia), or ``None`` when the factorization does
  not give it.

``factor`` raises :class:`SingularFactorError` when a pivot is zero or not finite.

Backends
--------
``QDLDLSolver`` (default): QDLDL's up-looking ``L D L^T`` with 1x1 pivots and an AMD ordering
(Stellato et al., OSQP, Math. Prog. Comp. 12, 637 (2020); Amestoy, Davis & Duff, SIAM J.
Matrix Anal. Appl. 17, 886 (1996)). There is no numerical pivoting, so the ordering must not
meet a zero pivot: the Newton method removes the rigid-motion null space before factoring.

``SuperLUSolver``: SciPy's ``splu`` in symmetric mode with diagonal pivoting only
(``diag_pivot_thresh=0``) and a minimum-degree ordering of ``A + A^T``; then
``L U = P A P^T`` and ``diag(U) = D``. If SuperLU had to take an off-diagonal pivot
(an exactly zero diagonal), the inertia is not available and ``inertia()`` returns ``None``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


class SingularFactorError(ArithmeticError):
    """The matrix has a zero (or non-finite) pivot in the chosen elimination order."""


def _count_signs(d: np.ndarray) -> tuple[int, int, int]:
    if not np.isfinite(d).all():
        raise SingularFactorError("factorization produced a non-finite pivot")
    return int((d > 0).sum()), int((d < 0).sum()), int((d == 0).sum())


def _same_pattern(a, b) -> bool:
    return (a is not None and b is not None and a.shape == b.shape and a.nnz == b.nnz
            and np.array_equal(a.indptr, b.indptr) and np.array_equal(a.indices, b.indices))


class QDLDLSolver:
    """``L D L^T`` by QDLDL with AMD ordering; symbolic analysis reused for a fixed pattern."""

    name = "qdldl"

    def __init__(self):
        import qdldl  # the package dependency; imported here so the module loads without it

        self._qdldl = qdldl
        self._solver = None
        self._pattern = None
        self._signs = None
        self.n_symbolic = 0
        self.n_numeric = 0

    def factor(self, A) -> None:
        upper = sp.triu(A, format="csc")  # keeps explicit zeros, so the pattern is stable
        self._signs = None
        try:
            if _same_pattern(upper, self._pattern):
                self._solver.update(upper, upper=True)
            else:
                self._solver = None
                self._solver = self._qdldl.Solver(upper, upper=True)
                self._pattern = upper
                self.n_symbolic += 1
        except RuntimeError as exc:  # QDLDL reports a zero pivot as an exception
            self._solver = None
            self._pattern = None
            raise SingularFactorError(str(exc)) from exc
        self.n_numeric += 1
        d = self._solver.factors()[1]
        self._signs = _count_signs(d)
        if self._signs[2]:
            raise SingularFactorError(f"{self._signs[2]} zero pivot(s) in the LDL^T factorization")

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._solver.solve(np.ascontiguousarray(b, dtype=np.float64))

    def inertia(self) -> tuple[int, int, int]:
        return self._signs


class SuperLUSolver:
    """SciPy SuperLU in symmetric mode (diagonal pivots), as a fallback backend."""

    name = "superlu"

    def __init__(self, permc_spec: str = "MMD_AT_PLUS_A"):
        self.permc_spec = permc_spec
        self._lu = None
        self._signs = None
        self.n_symbolic = 0
        self.n_numeric = 0

    def factor(self, A) -> None:
        A = sp.csc_matrix(A)
        self._signs = None
        try:
            self._lu = spla.splu(A, permc_spec=self.permc_spec, diag_pivot_thresh=0.0,
                                 options=dict(SymmetricMode=True))
        except RuntimeError as exc:  # "Factor is exactly singular"
            self._lu = None
            raise SingularFactorError(str(exc)) from exc
        self.n_symbolic += 1
        self.n_numeric += 1
        if np.array_equal(self._lu.perm_r, self._lu.perm_c):
            self._signs = _count_signs(self._lu.U.diagonal())
            if self._signs[2]:
                raise SingularFactorError(f"{self._signs[2]} zero pivot(s) in the LU factorization")

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(np.asarray(b, dtype=np.float64))

    def inertia(self) -> tuple[int, int, int] | None:
        return self._signs


_BACKENDS = {"qdldl": QDLDLSolver, "superlu": SuperLUSolver}


def make_solver(solver=None):
    """A linear solver from ``None`` (the default, QDLDL), a backend name, or a solver object.

    A solver object is anything with ``factor``, ``solve`` and ``inertia`` methods as
    described in the module docstring; it is returned unchanged.
    """
    if solver is None:
        solver = "qdldl"
    if isinstance(solver, str):
        if solver not in _BACKENDS:
            raise ValueError(f"unknown linear solver {solver!r}; choose one of {sorted(_BACKENDS)}")
        return _BACKENDS[solver]()
    missing = [m for m in ("factor", "solve", "inertia") if not callable(getattr(solver, m, None))]
    if missing:
        raise ValueError(f"linear solver {solver!r} lacks method(s) {missing}")
    return solver
