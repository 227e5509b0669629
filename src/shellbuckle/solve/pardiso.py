"""PARDISO's symmetric-indefinite ``L D L^T`` through ctypes (:class:`PardisoSolver`).

Method: PARDISO's supernodal ``L D L^T`` for symmetric indefinite matrices (``mtype = -2``)
with Bunch–Kaufman pivoting inside supernodes (Bunch & Kaufman, Math. Comp. 31, 163 (1977))
and pivot perturbation ``1e-8``; it reports the inertia itself (Schenk & Gärtner, Future
Gener. Comput. Syst. 20, 475 (2004)). The interface is that of :mod:`.linear`.

- Ordering: METIS nested dissection (Karypis & Kumar, SIAM J. Sci. Comput. 20, 359 (1998)).
  The constraint's row and column of a KKT matrix reach every other row: rows with more than
  ``max(16, 10 sqrt(n))`` entries (the dense-row rule of AMD, Amestoy, Davis & Duff, SIAM J.
  Matrix Anal. Appl. 17, 886 (1996)) are left out of the graph METIS orders and eliminated
  last (:meth:`PardisoSolver._ordering`). A solver keeps the orderings of the patterns it has
  analysed (``orderings``, by a digest of the index arrays, shared with its single-precision
  twin, or given by the caller) and passes them to any later analysis of the same pattern
  (``iparm[4] = 1``); the factors are bitwise those of the first analysis.
- Options: scaling and weighted matching off (``iparm[10] = iparm[12] = 0``; they matter for
  unsymmetric or badly scaled pivots); iterative refinement left to PARDISO's default
  (``iparm[7] = 0``: two steps only where a pivot was perturbed).
- Precision: ``PardisoSolver(precision="single")`` factors in single precision
  (``iparm[27] = 1``) and refines every solve with ``refinement`` double-precision residual
  steps. A double-precision solver factors in single precision when asked with
  ``factor(A, approximate=True)``: a second PARDISO handle (its twin) with its own symbolic
  analysis, no refinement, and 1x1 pivots on the diagonal only (``iparm[20] = 0``); one in which
  PARDISO had to perturb a pivot (``iparm[13] > 0``), or asked with ``stable_pivots=True``, is
  made again with Bunch–Kaufman pivots. PARDISO reads ``iparm[20]`` in its solves too (a 1x1
  factorization solved as a Bunch–Kaufman one gives garbage), so each held factorization keeps
  its own.
- Held factorizations: PARDISO keeps the last two numeric factorizations of a pattern in each
  precision (``maxfct = 2``); :meth:`PardisoSolver.held` names the one in use and
  :meth:`PardisoSolver.activate` solves with an earlier one again while it is held (warm
  starts, :mod:`.workspace`).
- Modes (``reproducible``): on several threads PARDISO runs in its conditional numerical
  reproducibility mode (``iparm[33] = 1``), whose results are bitwise the same on any number of
  threads; on one thread in its plain mode (``iparm[33] = 0``), deterministic there, whose
  factors solve faster. The two modes give different bits, so the mode is part of what
  reproduces a run (:func:`shellbuckle.run.deflate` stores it). ``n_threads`` defaults to
  :func:`~.linear.default_threads`, ``reproducible`` to ``n_threads > 1``; the plain mode needs
  one thread. The count is set thread-locally around each call (``mkl_set_num_threads_local``),
  so a global limit on MKL's BLAS threads does not apply to PARDISO.
"""

from __future__ import annotations

import hashlib

import numpy as np
import scipy.sparse as sp

from .linear import (SingularFactorError, _load_mkl, _same_pattern, check_mode, check_threads,
                     default_threads)
from .recent import Recent


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
        Amestoy, Davis & Duff 1996). METIS is then given a graph of bounded degree."""
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
