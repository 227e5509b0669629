"""Sparse symmetric-indefinite factorizations with inertia, for Newton's method.

Every solver has the same three methods:

- ``factor(A, upper=False)``: ``A`` a real symmetric sparse matrix in full storage (both
  triangles, any scipy format), or, with ``upper=True``, its upper triangle as a CSR matrix
  with sorted indices (what :class:`~.kkt.KKTAssembler` builds). The symbolic analysis
  (fill-reducing ordering, elimination tree) is reused when the sparsity pattern of ``A``
  (with its explicit zeros) equals the previous one, so a fixed-pattern Hessian costs one
  numeric factorization per call.
- ``solve(b)``: ``x`` with ``A x = b``.
- ``inertia()``: ``(n_pos, n_neg, n_zero)`` of ``A`` from the signs of the pivots ``D`` of
  ``P A P^T = L D L^T`` (Sylvester's law of inertia), or ``None`` when the factorization does
  not give it.

``factor`` raises :class:`SingularFactorError` when a pivot is zero or not finite. A solver may
also take ``factor(A, upper, approximate=True)``: an approximate factorization (single
precision) for a preconditioner, a step far from a minimum or a certificate with a margin
(:mod:`.system`); ``single_precision`` says whether it really is one. A solver that keeps
several factorizations names the one in use with ``held()`` and solves with an earlier one
again with ``activate(handle)`` (:mod:`.workspace`).

Backends
--------
:func:`make_solver` (the default everywhere) picks PARDISO when Intel MKL can be loaded and
QDLDL otherwise ("auto"); name a backend to force it.

``QDLDLSolver`` (always available, a package dependency): QDLDL's up-looking ``L D L^T`` with
1x1 pivots and an AMD ordering (Stellato et al., OSQP, Math. Prog. Comp. 12, 637 (2020);
Amestoy, Davis & Duff, SIAM J. Matrix Anal. Appl. 17, 886 (1996)). There is no numerical
pivoting, so the ordering must not meet a zero pivot: Newton's method removes the rigid-motion
null space before factoring (:mod:`.gauge`).

``PardisoSolver`` (optional, needs Intel MKL): PARDISO's supernodal ``L D L^T`` with
Bunch–Kaufman pivoting, in double and single precision, two held factorizations per precision
and two threading modes (:mod:`.pardiso`).

``SuperLUSolver``: SciPy's ``splu`` in symmetric mode with diagonal pivoting only
(``diag_pivot_thresh=0``) and a minimum-degree ordering of ``A + A^T`` (Demmel et al., SIAM
J. Matrix Anal. Appl. 20, 720 (1999)); then ``L U = P A P^T`` and ``diag(U) = D``. If SuperLU
had to take an off-diagonal pivot (an exactly zero diagonal), the inertia is not available and
``inertia()`` returns ``None``.

:class:`CountingSolver` wraps any of them and counts its factorizations and solves.
"""

from __future__ import annotations

import functools
import inspect

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


class SingularFactorError(ArithmeticError):
    """The matrix has a zero (or non-finite) pivot in the chosen elimination order."""


def _count_signs(d: np.ndarray) -> tuple[int, int, int]:
    if not np.isfinite(d).all():
        raise SingularFactorError("factorization produced a non-finite pivot")
    return int((d > 0).sum()), int((d < 0).sum()), int((d == 0).sum())


def _same_buffer(x: np.ndarray, y: np.ndarray) -> bool:
    return x is y or (x.shape == y.shape and x.dtype == y.dtype and x.strides == y.strides
                      and x.ctypes.data == y.ctypes.data)


def _same_pattern(a, b) -> bool:
    if a is None or b is None or a.shape != b.shape or a.nnz != b.nnz:
        return False
    if _same_buffer(a.indptr, b.indptr) and _same_buffer(a.indices, b.indices):
        return True  # a fixed-pattern assembler's arrays (``b``, kept by the solver, is alive)
    return np.array_equal(a.indptr, b.indptr) and np.array_equal(a.indices, b.indices)


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

    def factor(self, A, upper: bool = False, approximate: bool = False) -> None:
        # CSC upper triangle; triu and tocsc keep explicit zeros, so the pattern is stable
        upper = sp.csc_matrix(A) if upper else sp.triu(A, format="csc")
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

    def factor(self, A, upper: bool = False, approximate: bool = False) -> None:
        if upper:
            A = A + sp.triu(A, k=1).T
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


def default_threads() -> int:
    """Threads for PARDISO by default: ``MKL_NUM_THREADS`` or ``OMP_NUM_THREADS`` when set to a
    positive integer, else the number of cores this process may run on."""
    import os

    for var in ("MKL_NUM_THREADS", "OMP_NUM_THREADS"):
        value = os.environ.get(var, "").strip()
        if value.isdigit() and int(value) > 0:
            return int(value)
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def check_mode(reproducible, threads: int) -> bool:
    """PARDISO's mode for ``threads`` threads: ``reproducible`` as a bool, ``threads > 1`` for
    ``None``; a ``ValueError`` for the plain mode on several threads or a value not a bool."""
    if reproducible is None:
        return threads > 1
    if not isinstance(reproducible, (bool, np.bool_)):
        raise ValueError(f"reproducible must be True, False or None, got {reproducible!r}")
    if not reproducible and threads > 1:
        raise ValueError(f"PARDISO's plain mode (reproducible=False) runs on one thread, got "
                         f"{threads} threads; use reproducible=True or one thread")
    return bool(reproducible)


def check_threads(threads) -> int:
    """``threads`` as a positive int, or a ``ValueError`` naming the bad value."""
    if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
        raise ValueError(f"threads must be an integer >= 1, got {threads!r}")
    return int(threads)


@functools.lru_cache(maxsize=None)
def _load_mkl():
    """The MKL runtime library (``libmkl_rt``) through ctypes, or ``None``.

    Looked for in ``$SHELLBUCKLE_MKL_RT`` (a path or library name), then by
    ``ctypes.util.find_library("mkl_rt")``, then in the ``lib`` (``Library/bin`` on Windows)
    folder of the Python prefix. ``SHELLBUCKLE_NO_MKL=1`` (any value but empty or ``0``) gives
    ``None`` even where MKL is installed, so that ``"auto"`` picks QDLDL as on a machine without
    MKL (e.g. ARM) and PARDISO is unavailable. The result is cached for the process: set either
    variable before the first call (in practice, before the first solve).
    """
    import ctypes
    import ctypes.util
    import glob
    import os
    import sys

    if os.environ.get("SHELLBUCKLE_NO_MKL", "").strip() not in ("", "0"):
        return None
    names = [os.environ.get("SHELLBUCKLE_MKL_RT"), ctypes.util.find_library("mkl_rt")]
    for prefix in {sys.prefix, sys.base_prefix}:
        names += sorted(glob.glob(os.path.join(prefix, "lib", "libmkl_rt.so*")), key=len)
        names += sorted(glob.glob(os.path.join(prefix, "Library", "bin", "mkl_rt*.dll")), key=len)
    for name in names:
        if name:
            try:
                return ctypes.CDLL(name)
            except OSError:
                continue
    return None


def accepts(function, name: str) -> bool:
    """Whether ``function`` has a parameter ``name``."""
    try:
        return name in inspect.signature(function).parameters
    except (TypeError, ValueError):
        return False


class CountingSolver:
    """A linear solver that counts its work and passes every call on to ``inner``:
    ``counts["double"]`` factorizations, ``counts["single"]`` approximate ones
    (``factor(..., approximate=True)``) and ``counts["solve"]`` solves. For measuring what a
    minimization costs (benchmarks, tests)."""

    def __init__(self, inner):
        self.inner = make_solver(inner)
        self.counts = dict(double=0, single=0, solve=0)

    @property
    def n_factor(self) -> int:
        """Factorizations of either kind so far."""
        return self.counts["double"] + self.counts["single"]

    @property
    def single_precision(self) -> bool:
        """Whether ``inner`` factors the approximate matrices in single precision."""
        return bool(getattr(self.inner, "single_precision", False))

    def factor(self, A, upper: bool = False, approximate: bool = False) -> None:
        self.counts["single" if approximate else "double"] += 1
        self.inner.factor(A, upper=upper, approximate=approximate)

    def solve(self, b: np.ndarray) -> np.ndarray:
        self.counts["solve"] += 1
        return self.inner.solve(b)

    def inertia(self):
        return self.inner.inertia()

    def held(self):
        held = getattr(self.inner, "held", None)
        return None if held is None else held()

    def activate(self, handle) -> bool:
        activate = getattr(self.inner, "activate", None)
        return activate is not None and activate(handle)


BACKENDS = ("pardiso", "qdldl", "superlu")


def make_solver(solver=None, threads: int | None = None, reproducible: bool | None = None):
    """A linear solver from ``None`` or ``"auto"`` (PARDISO if Intel MKL loads, else QDLDL),
    a backend name (``"qdldl"``, ``"superlu"``, ``"pardiso"``), or a solver object.
    ``threads``: PARDISO's threads (default :func:`default_threads`), ``reproducible`` its mode
    (default: on several threads; see the module docstring); QDLDL and SuperLU run on one.

    A solver object is anything with ``factor``, ``solve`` and ``inertia`` methods as
    described in the module docstring; it is returned unchanged.
    """
    if solver is None or solver == "auto":
        solver = "pardiso" if _load_mkl() is not None else "qdldl"
    if isinstance(solver, str):
        if solver not in BACKENDS:
            raise ValueError(f"unknown linear solver {solver!r}; choose 'auto' or one of "
                             f"{list(BACKENDS)}")
        if threads is not None:
            threads = check_threads(threads)
        if solver == "pardiso":
            from .pardiso import PardisoSolver  # it builds on this module

            return PardisoSolver(threads, reproducible=reproducible)
        return QDLDLSolver() if solver == "qdldl" else SuperLUSolver()
    missing = [m for m in ("factor", "solve", "inertia") if not callable(getattr(solver, m, None))]
    if missing:
        raise ValueError(f"linear solver {solver!r} lacks method(s) {missing}")
    return solver
