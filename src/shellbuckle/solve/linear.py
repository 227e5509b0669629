"""Sparse symmetric-indefinite factorizations with inertia, for the Newton method.

Every solver has the same three methods:

- ``factor(A, upper=False)``: ``A`` a real symmetric sparse matrix in full storage (both
  triangles, any scipy format), or, with ``upper=True``, its upper triangle as a CSR matrix
  with sorted indices (what :class:`~.newton.KKTAssembler` builds; PARDISO then uses the
  arrays as they are). The symbolic analysis (fill-reducing ordering, elimination tree) is
  reused when the sparsity pattern of ``A`` (with its explicit zeros) equals the previous one,
  so a fixed-pattern Hessian costs one numeric factorization per call.
- ``solve(b)``: ``x`` with ``A x = b``.
- ``inertia()``: ``(n_pos, n_neg, n_zero)`` of ``A`` from the signs of the pivots ``D`` of
  ``P A P^T = L D L^T`` (Sylvester's law of inertia), or ``None`` when the factorization does
  not give it.

``factor`` raises :class:`SingularFactorError` when a pivot is zero or not finite.

Backends
--------
``make_solver()`` (the default everywhere) picks PARDISO when Intel MKL can be loaded and
QDLDL otherwise ("auto"); name a backend to force it.

``QDLDLSolver`` (always available, a package dependency): QDLDL's up-looking ``L D L^T`` with 1x1 pivots and an AMD ordering
(Stellato et al., OSQP, Math. Prog. Comp. 12, 637 (2020); Amestoy, Davis & Duff, SIAM J.
Matrix Anal. Appl. 17, 886 (1996)). There is no numerical pivoting, so the ordering must not
meet a zero pivot: the Newton method removes the rigid-motion null space before factoring.

``PardisoSolver`` (optional, needs Intel MKL, e.g. the ``mkl`` wheel): PARDISO's supernodal
``L D L^T`` for symmetric indefinite matrices (``mtype = -2``) with Bunch–Kaufman pivoting
inside supernodes, METIS nested-dissection ordering and pivot perturbation ``1e-8``; it
reports the inertia itself (Schenk & Gärtner, Future Gener. Comput. Syst. 20, 475 (2004)).
Scaling and weighted matching are off (``iparm[10] = iparm[12] = 0``: they matter for
unsymmetric or badly scaled pivots, not here, and cost time). Iterative refinement is left to
PARDISO's default (``iparm[7] = 0``): two steps only when a pivot was perturbed, none
otherwise, which makes a solve about three times cheaper; the KKT solves of the Newton method
then have relative residuals of about ``1e-11``. ``PardisoSolver(precision="single")``
factors in single precision (``iparm[27] = 1``: about 1.7 times faster, 55 ms against 92 ms
on the matrix below) and refines every solve with ``refinement`` (2) double-precision
residual steps; it is an option, not the default, because the inertia of a matrix with
eigenvalues within ~1e-7 of its scale (the soft post-buckling modes are ~1e-6) is then less
certain. A double-precision solver factors a matrix in single precision when asked with
``factor(A, approximate=True)`` (a second PARDISO handle with its own symbolic analysis,
``refinement = 0``; ``single_precision`` is then true): the Newton method does so for the
shifted, positive definite preconditioner of its relaxation and for its Newton steps far from
a minimum (:mod:`.newton`), whose solves are corrected by L-BFGS, and for a certificate of a
minimum with a margin (:mod:`.newton`, "Single-precision certificates"); QDLDL and SuperLU
ignore the flag. The approximate factorizations pivot on the diagonal only (``iparm[20] = 0``,
1x1 pivots inside the supernodes instead of Bunch–Kaufman's 1x1 and 2x2: 36-40 against 40-44 ms
on the matrix below, the same residuals); one in which PARDISO had to perturb a pivot
(``iparm[13] > 0``) is made again with Bunch–Kaufman pivots, and so is one asked with
``stable_pivots=True`` (Newton's single-precision certificates did so until their margin was
measured with 1x1 pivots too, :mod:`.newton`). PARDISO reads
``iparm[20]`` in its solves too (a 1x1 factorization solved as a Bunch–Kaufman one gives
garbage, residuals 5-1400 times the right-hand side), so each held factorization keeps its own.
PARDISO keeps the last two
numeric factorizations of a pattern in each precision (``maxfct = 2``): ``held()`` names the
one in use and ``activate(handle)`` solves with an earlier one again while it is held, so
that a minimization can start from a factorization made two minimizations earlier (the
protocol's zero-spontaneous-curvature cycle, :mod:`.newton`, "Warm start"); the other
backends have neither method. PARDISO is one to two orders of magnitude faster than QDLDL on
shell Hessians of a few thousand vertices (BLAS-3 supernodes): the KKT matrix of the
3594-vertex mesh (10.8k rows, 0.64M entries) has 3.0M entries in ``L`` and its numeric
factorization takes about 1.3 GFlop. The constraint's row and column of a KKT matrix reach
every other row: such dense rows (AMD's rule, more than ``10 sqrt(n)`` entries) are left out
of the graph METIS orders and eliminated last, which halves PARDISO's analysis of that
matrix (METIS with the dense row took about two thirds of it) and saves 0.6 % of the
factorization's flops. A solver keeps the last few orderings by pattern (a digest of the
index arrays; ``orderings``, shared with its single-precision twin) and gives them to any later
analysis of the same pattern (``iparm[4] = 1``), so that a run pays for one once for its two
precisions; a solver made with another's ``orderings`` reuses them too. The factors are
bitwise those of the first analysis.

PARDISO runs in one of two modes (``reproducible``). On several threads it runs in its
conditional-numerical-reproducibility mode (``iparm[33] = 1``), so its results are bitwise the
same on any number of threads (checked with 1, 2, 3, 4 and 8 threads on that matrix) and the
thread count is a matter of speed only. On one thread it runs in its plain mode
(``iparm[33] = 0``), which is deterministic there and lays out the factors so that solves are
faster: on the matrix above, one thread, a single-precision 1x1 factorization solves in 1.6-1.7
against 2.3-2.5 ms, a double-precision one in 2.5-2.8 against 2.8-3.2 ms
(``bench_newton_parts.py``), and a whole run of the comparison's protocol takes 6-10 % less time.
The two modes give different bits (single-precision solves differ by about ``1e-6``
relative), so the mode is part of what reproduces a run: the run stores it and a resumed run
uses it (:func:`shellbuckle.run.deflate`), whatever the threads it is given.
``PardisoSolver(n_threads, reproducible=None)``: ``n_threads`` default :func:`default_threads`
(the cores this process may use, or ``MKL_NUM_THREADS`` / ``OMP_NUM_THREADS`` when set, as in
the sweep's workers); ``reproducible`` defaults to ``n_threads > 1``, and the plain mode needs
one thread (its results on several may depend on their number). The count is set
thread-locally around each call (``mkl_set_num_threads_local``), so that a global limit on MKL's
BLAS threads (see :func:`shellbuckle.protocol.deflate.step`) does not apply to PARDISO. On the
matrix above two threads factor in 48-56 ms instead of 90 ms.

``SuperLUSolver``: SciPy's ``splu`` in symmetric mode with diagonal pivoting only
(``diag_pivot_thresh=0``) and a minimum-degree ordering of ``A + A^T``; then
``L U = P A P^T`` and ``diag(U) = D``. If SuperLU had to take an off-diagonal pivot
(an exactly zero diagonal), the inertia is not available and ``inertia()`` returns ``None``.
"""

from __future__ import annotations

import functools
import hashlib
import inspect

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .recent import Recent


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
    """The MKL runtime library (``libmkl_rt``) through ctypes, or ``None``."""
    import ctypes
    import ctypes.util
    import glob
    import os
    import sys

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


def _pattern_key(upper) -> tuple:
    """A key of the sparsity pattern of a CSR matrix (its shape and a digest of its index
    arrays), for :attr:`PardisoSolver.orderings`."""
    digest = hashlib.blake2b(np.ascontiguousarray(upper.indptr).view(np.uint8), digest_size=16)
    digest.update(np.ascontiguousarray(upper.indices).view(np.uint8))
    return upper.shape, upper.nnz, digest.hexdigest()


class PardisoSolver:
    """MKL PARDISO symmetric-indefinite ``L D L^T`` (``mtype = -2``) through ctypes."""

    name = "pardiso"
    single_precision = True  # factor(..., approximate=True) is in single precision
    _MTYPE = -2
    _SLOTS = 2

    def __init__(self, n_threads: int | None = None, precision: str = "double",
                 refinement: int = 2, diagonal_pivoting: bool = False,
                 reproducible: bool | None = None, orderings: Recent | None = None):
        import ctypes

        if precision not in ("double", "single"):
            raise ValueError(f"precision must be 'double' or 'single', got {precision!r}")

        self._ct = ctypes
        self._mkl = _load_mkl()
        if self._mkl is None:
            raise ValueError("the 'pardiso' linear solver needs Intel MKL (pip install mkl); "
                             "use 'qdldl' or 'superlu' instead")
        self._pardiso = self._mkl.pardiso
        self._pardiso.restype = None
        self._set_local_threads = self._mkl.MKL_Set_Num_Threads_Local
        self._set_local_threads.restype = ctypes.c_int
        self.n_threads = default_threads() if n_threads is None else check_threads(n_threads)
        self.reproducible = check_mode(reproducible, self.n_threads)
        self._pt = np.zeros(64, dtype=np.int64)
        self._iparm = np.zeros(64, dtype=np.int32)
        # 33: conditional numerical reproducibility (the same bits on any number of threads) in
        # the reproducible mode, 0 in the plain mode (one thread, faster solves)
        self._iparm[[0, 1, 7, 9, 10, 12, 20, 33, 34]] = [1, 2, 0, 8, 0, 0, 1,
                                                         int(self.reproducible), 1]
        self.precision, self.refinement = precision, int(refinement)
        # 1x1 pivots only (iparm[20] = 0), Bunch-Kaufman where a pivot had to be perturbed
        self.diagonal_pivoting = bool(diagonal_pivoting)
        self._iparm[27] = 1 if precision == "single" else 0
        self._pattern = None
        self._n = 0
        self.n_symbolic = 0
        self.n_numeric = 0
        self._approximate = None  # single-precision twin for factor(..., approximate=True)
        # pattern key (_pattern_key) -> PARDISO's perm of METIS's ordering of it, shared with
        # the twin: the orderings of the patterns this solver has analysed
        self.orderings = Recent(8) if orderings is None else orderings
        self._active = self
        # two numeric factorizations of one pattern (PARDISO's maxfct = 2, mnum = slot + 1):
        # each factorization overwrites the older one, so the previous one can still be used
        self._slot = 0  # the factorization solve() uses
        self._serial = [0] * self._SLOTS  # number of the factorization held in each slot (0: none)
        self._slot_data = [None] * self._SLOTS  # its values (read again by refinement)
        self._slot_signs = [None] * self._SLOTS  # its inertia
        self._slot_matrix = [None] * self._SLOTS  # single precision: (upper, diagonal), refined
        self._slot_pivots = [1] * self._SLOTS  # its iparm[20]: 1 Bunch-Kaufman, 0 diagonal

    def _call(self, phase: int, data, b=None, x=None, slot: int = 0, perm=None) -> int:
        ct = self._ct
        i32 = ct.c_int32
        err = i32(0)
        nrhs = 1
        if b is None:
            b = np.zeros(self._n)
            x = np.zeros(self._n)
        previous = self._set_local_threads(i32(self.n_threads))
        try:
            self._pardiso(self._pt.ctypes.data_as(ct.c_void_p), ct.byref(i32(self._SLOTS)),
                          ct.byref(i32(slot + 1)), ct.byref(i32(self._MTYPE)),
                          ct.byref(i32(phase)),
                          ct.byref(i32(self._n)), data.ctypes.data_as(ct.c_void_p),
                          self._pattern.indptr.ctypes.data_as(ct.c_void_p),
                          self._pattern.indices.ctypes.data_as(ct.c_void_p),
                          ct.c_void_p() if perm is None else perm.ctypes.data_as(ct.c_void_p),
                          ct.byref(i32(nrhs)),
                          self._iparm.ctypes.data_as(ct.c_void_p), ct.byref(i32(0)),
                          b.ctypes.data_as(ct.c_void_p), x.ctypes.data_as(ct.c_void_p),
                          ct.byref(err))
        finally:
            self._set_local_threads(i32(previous))
        return err.value

    def _release(self):
        if self._pattern is not None:
            self._call(-1, np.zeros(1))
            self._pattern = None
        self._serial = [0] * self._SLOTS

    def __del__(self):
        try:
            self._release()
        except Exception:  # interpreter shutdown: the library may already be gone
            pass

    def factor(self, A, upper: bool = False, approximate: bool = False,
               stable_pivots: bool = False) -> None:
        """Factor ``A`` (only its upper triangle is read; ``upper``: ``A`` is that triangle as
        sorted CSR). ``approximate``: in single precision without refinement and with 1x1
        pivots, for a double solver (see the module docstring); the following solves and
        inertia are its. ``stable_pivots``: Bunch–Kaufman pivots in any case."""
        if approximate and self.precision == "double":
            if self._approximate is None:
                self._approximate = PardisoSolver(self.n_threads, "single", refinement=0,
                                                  diagonal_pivoting=True,
                                                  reproducible=self.reproducible,
                                                  orderings=self.orderings)
            self._active = self._approximate
            self._approximate.factor(A, upper, stable_pivots=stable_pivots)
            return
        self._active = self
        if upper and sp.issparse(A) and A.format == "csr" and A.has_sorted_indices:
            upper = A
        else:
            upper = sp.triu(A, format="csr")
            upper.sort_indices()
        if upper.indptr.dtype != np.int32 or upper.indices.dtype != np.int32:
            upper = sp.csr_matrix((upper.data, upper.indices.astype(np.int32),
                                   upper.indptr.astype(np.int32)), shape=upper.shape)
        data = np.ascontiguousarray(upper.data, dtype=np.float64)
        refine = None
        if self.precision == "single":
            refine = (upper, upper.diagonal())  # the matrix, for the refinement
            data = data.astype(np.float32)
        if not _same_pattern(upper, self._pattern):
            self._release()
            self._pattern, self._n = upper, upper.shape[0]
            err = self._analyse(data)
            if err:
                self._pattern = None
                raise SingularFactorError(f"PARDISO analysis failed (error {err})")
            self.n_symbolic += 1
        slot = (self._slot + 1) % self._SLOTS  # overwrite the older factorization
        self._slot, self._serial[slot], self._slot_data[slot] = slot, 0, data
        self._slot_matrix[slot] = refine
        err = self._numeric(data, slot, self.diagonal_pivoting and not stable_pivots)
        if err:
            raise SingularFactorError(f"PARDISO factorization failed (error {err})")
        n_pos, n_neg = int(self._iparm[21]), int(self._iparm[22])
        signs = self._slot_signs[slot] = (n_pos, n_neg, self._n - n_pos - n_neg)
        if signs[2]:
            raise SingularFactorError(f"{signs[2]} zero pivot(s) in the PARDISO factorization")
        self._serial[slot] = self.n_numeric  # held only once it succeeded

    def _numeric(self, data, slot: int, diagonal: bool) -> int:
        """PARDISO's numeric factorization (phase 22) into ``slot``, with 1x1 pivots if
        ``diagonal`` (made again with Bunch–Kaufman pivots if a pivot had to be perturbed,
        ``iparm[13]``); PARDISO's error code."""
        pivots = self._slot_pivots[slot] = self._iparm[20] = 0 if diagonal else 1
        err = self._call(22, data, slot=slot)
        self.n_numeric += 1
        if pivots == 0 and not err and self._iparm[13] > 0:
            self._slot_pivots[slot] = self._iparm[20] = 1
            err = self._call(22, data, slot=slot)
            self.n_numeric += 1
        return err

    def _analyse(self, data) -> int:
        """PARDISO's analysis (phase 11) of ``self._pattern``, with the fill-reducing ordering
        of an earlier analysis of the same pattern if :attr:`orderings` holds one (METIS is
        then skipped), else :meth:`_ordering`'s, which is kept there."""
        key = _pattern_key(self._pattern)
        perm = self.orderings.get(key)
        if perm is None:
            perm = self._ordering(data)
            if perm is None:  # no dense row: METIS's ordering of the whole, from this analysis
                perm = np.zeros(self._n, dtype=np.int32)
                err = self._analyse_ordering(data, perm, given=False)
                if not err:
                    self.orderings.put(key, perm)
                return err
            self.orderings.put(key, perm)
        return self._analyse_ordering(data, perm.copy(), given=True)

    def _analyse_ordering(self, data, perm: np.ndarray, given: bool) -> int:
        """Phase 11 with the ordering ``perm`` (``given``, ``iparm[4] = 1``), or with METIS's,
        returned in ``perm`` (``iparm[4] = 2``); PARDISO's error code."""
        self._iparm[4] = 1 if given else 2
        try:
            return self._call(11, data, perm=perm)
        finally:
            self._iparm[4] = 0

    def _ordering(self, data):
        """The elimination order of ``self._pattern`` for a matrix with dense rows (a KKT
        matrix's constraint row and column, which reach every other row): METIS's ordering
        of the rest, then the dense rows, as PARDISO's ``perm`` (int32, the rows in the order
        they are eliminated); ``None`` without dense rows. A row is dense when it has more
        than ``max(16, 10 sqrt(n))`` entries in the full symmetric pattern (AMD's rule,
        Amestoy, Davis & Duff 1996). METIS is then given a graph of bounded degree: on the
        paper's mesh (10.8k rows) it orders it in about a third of the time it takes with
        the dense row, and the factorization takes 0.6 % fewer flops."""
        upper, n = self._pattern, self._n
        degree = np.diff(upper.indptr) + np.bincount(upper.indices, minlength=n)
        dense = degree > max(16.0, 10.0 * np.sqrt(n))
        if not dense.any() or dense.all():
            return None
        kept = np.flatnonzero(~dense)
        rest = upper[kept][:, kept]
        rest.sort_indices()
        rest = sp.csr_matrix((rest.data.astype(data.dtype), rest.indices.astype(np.int32),
                              rest.indptr.astype(np.int32)), shape=rest.shape)
        self._pattern, self._n = rest, rest.shape[0]
        perm = np.zeros(self._n, dtype=np.int32)
        try:
            err = self._analyse_ordering(rest.data, perm, given=False)
            self._call(-1, rest.data[:1])  # release that analysis
        finally:
            self._pattern, self._n = upper, n
        if err:
            return None
        return np.concatenate([kept[perm], np.flatnonzero(dense)]).astype(np.int32)

    def held(self):
        """A handle of the factorization that :meth:`solve` uses now, for :meth:`activate`:
        ``(precision, slot, serial)``, the precision being that of the factorization
        (``"single"`` for an ``approximate`` one); ``None`` if none is held."""
        active = self._active
        if not active._serial[active._slot]:
            return None
        return (active.precision, active._slot, active._serial[active._slot])

    def activate(self, handle) -> bool:
        """Solve with the factorization of ``handle`` (from :meth:`held`) again, if it is
        still held: PARDISO keeps the last two factorizations of a pattern in each precision
        (the ``approximate`` ones in their own handle). Whether it was."""
        if handle is None:
            return False
        precision, slot, serial = handle
        solver = self if precision == self.precision else self._approximate
        if solver is None or not serial or solver._serial[slot] != serial:
            return False
        self._active, solver._slot = solver, slot
        return True

    @property
    def _signs(self):
        """Inertia of the factorization :meth:`solve` uses (``None`` if none is held)."""
        return self._slot_signs[self._slot] if self._serial[self._slot] else None

    def _solve_factor(self, b: np.ndarray) -> np.ndarray:
        dtype = np.float32 if self.precision == "single" else np.float64
        b = np.array(b, dtype=dtype)
        x = np.zeros_like(b)
        self._iparm[20] = self._slot_pivots[self._slot]  # as the factorization was made
        err = self._call(33, self._slot_data[self._slot], b, x, slot=self._slot)
        if err:
            raise SingularFactorError(f"PARDISO solve failed (error {err})")
        return x.astype(np.float64)

    def solve(self, b: np.ndarray) -> np.ndarray:
        if self._active is not self:
            return self._active.solve(b)
        b = np.asarray(b, dtype=np.float64)
        x = self._solve_factor(b)
        if self.precision == "single":  # iterative refinement with double residuals
            U, diagonal = self._slot_matrix[self._slot]
            for _ in range(self.refinement):
                x += self._solve_factor(b - (U @ x + U.T @ x - diagonal * x))
        return x

    def inertia(self) -> tuple[int, int, int]:
        return self._active._signs


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


_BACKENDS = {"qdldl": QDLDLSolver, "superlu": SuperLUSolver, "pardiso": PardisoSolver}


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
        if solver not in _BACKENDS:
            raise ValueError(f"unknown linear solver {solver!r}; choose 'auto' or one of "
                             f"{sorted(_BACKENDS)}")
        if threads is not None:
            threads = check_threads(threads)
        if solver == "pardiso":
            return PardisoSolver(threads, reproducible=reproducible)
        return _BACKENDS[solver]()
    missing = [m for m in ("factor", "solve", "inertia") if not callable(getattr(solver, m, None))]
    if missing:
        raise ValueError(f"linear solver {solver!r} lacks method(s) {missing}")
    return solver
