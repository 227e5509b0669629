import os

import numpy as np
import pytest
import scipy.sparse as sp

from shellbuckle.solve.linear import (QDLDLSolver, SingularFactorError, SuperLUSolver, _load_mkl,
                                      check_threads, default_threads, make_solver)
from shellbuckle.solve.pardiso import PardisoSolver

BACKENDS = [QDLDLSolver, SuperLUSolver,
            pytest.param(PardisoSolver, marks=pytest.mark.skipif(_load_mkl() is None,
                                                                 reason="Intel MKL not installed"))]


def _random_symmetric(n, seed, density=0.15):
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=density, random_state=seed)
    return (A + A.T + sp.diags(2.0 * rng.standard_normal(n))).tocsc()


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("seed", range(4))
def test_inertia_and_solution_match_dense_linear_algebra(backend, seed):
    A = _random_symmetric(40, seed)
    eig = np.linalg.eigvalsh(A.toarray())
    solver = backend()
    solver.factor(A)
    assert solver.inertia() == ((eig > 0).sum(), (eig < 0).sum(), 0)
    b = np.random.default_rng(seed).standard_normal(40)
    np.testing.assert_allclose(A @ solver.solve(b), b, atol=1e-10 * np.abs(b).max())


@pytest.mark.parametrize("backend", BACKENDS)
def test_kkt_inertia_is_tangent_inertia_plus_constraints(backend):
    # Sylvester / Gould: inertia([[K, G], [G^T, 0]]) = inertia(Z^T K Z) + (m, m, 0)
    rng = np.random.default_rng(5)
    n, m = 30, 2
    K = _random_symmetric(n, 7).toarray()
    G = rng.standard_normal((n, m))
    Z = np.linalg.svd(G.T)[2][m:].T  # orthonormal basis of null(G^T)
    tangent = np.linalg.eigvalsh(Z.T @ K @ Z)
    kkt = sp.csc_matrix(np.block([[K, G], [G.T, np.zeros((m, m))]]))
    solver = backend()
    solver.factor(kkt)
    n_pos, n_neg, n_zero = solver.inertia()
    assert n_neg == (tangent < 0).sum() + m and n_pos == (tangent > 0).sum() + m and n_zero == 0


@pytest.mark.parametrize("backend", BACKENDS)
def test_symbolic_analysis_is_reused_for_an_unchanged_pattern(backend):
    A = _random_symmetric(50, 11) + 10 * sp.eye(50)
    B = A.copy()
    B.data = B.data * np.linspace(0.5, 1.5, B.nnz)
    B = (B + B.T) / 2  # same pattern, new values
    solver = backend()
    solver.factor(A.tocsc())
    solver.factor(B.tocsc())
    b = np.ones(50)
    np.testing.assert_allclose(B @ solver.solve(b), b, atol=1e-10)
    if backend is not SuperLUSolver:
        assert solver.n_symbolic == 1 and solver.n_numeric == 2


@pytest.mark.parametrize("backend", [QDLDLSolver, SuperLUSolver])
def test_singular_matrix_raises(backend):
    singular = sp.csc_matrix(np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 2.0]]))
    with pytest.raises(SingularFactorError):
        backend().factor(singular)


def test_make_solver():
    auto = PardisoSolver if _load_mkl() is not None else QDLDLSolver
    assert isinstance(make_solver(None), auto) and isinstance(make_solver("auto"), auto)
    assert isinstance(make_solver("qdldl"), QDLDLSolver)
    assert isinstance(make_solver("superlu"), SuperLUSolver)
    s = SuperLUSolver()
    assert make_solver(s) is s
    with pytest.raises(ValueError, match="unknown linear solver 'umfpack'"):
        make_solver("umfpack")
    with pytest.raises(ValueError, match="lacks method"):
        make_solver(object())


_NO_MKL_CHILD = """
import json
import numpy as np
import scipy.sparse as sp
from shellbuckle.solve.linear import _load_mkl, make_solver

# a KKT-like system: a sparse indefinite block K (a shifted 1D Laplacian) bordered by two
# dense constraint columns G, with the zero block of the multipliers
n, m = 60, 2
rng = np.random.default_rng(0)
K = sp.diags([-1.0, 2.2, -1.0], [-1, 0, 1], shape=(n, n)) - 0.5 * sp.identity(n)
G = sp.csr_matrix(rng.standard_normal((n, m)))
A = sp.bmat([[K, G], [G.T, None]], format="csc")
b = rng.standard_normal(n + m)
solver = make_solver()
solver.factor(A)
x = solver.solve(b)
try:
    make_solver("pardiso")
    pardiso = "available"
except ValueError as exc:
    pardiso = str(exc)
eig = np.linalg.eigvalsh(A.toarray())
print(json.dumps(dict(
    mkl=_load_mkl() is not None, name=type(solver).__name__, pardiso=pardiso,
    residual=float(np.linalg.norm(A @ x - b) / np.linalg.norm(b)),
    inertia=list(map(int, solver.inertia())),
    dense_inertia=[int((eig > 0).sum()), int((eig < 0).sum()), 0])))
"""


def test_without_mkl_the_default_solver_is_a_fallback_that_solves_a_kkt_system():
    # SHELLBUCKLE_NO_MKL=1 takes the path of a machine without MKL (e.g. ARM), so the
    # fallback stays exercised where MKL is installed. A fresh process, since _load_mkl
    # caches its answer. Oracles: the residual and the dense eigenvalues (inertia)
    import json
    import subprocess
    import sys

    env = dict(os.environ, SHELLBUCKLE_NO_MKL="1")
    done = subprocess.run([sys.executable, "-c", _NO_MKL_CHILD], env=env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.splitlines()[-1])
    assert out["mkl"] is False and out["name"] != "PardisoSolver"
    assert "needs Intel MKL" in out["pardiso"]
    assert out["residual"] <= 1e-10
    assert out["inertia"] == out["dense_inertia"] and out["inertia"][1] >= 2


@pytest.mark.parametrize("backend", BACKENDS)
def test_upper_triangle_input_is_the_same_matrix(backend):
    A = _random_symmetric(40, 3)
    upper = sp.triu(A, format="csr")
    upper.sort_indices()
    full, half = backend(), backend()
    full.factor(A)
    half.factor(upper, upper=True)
    assert half.inertia() == full.inertia()
    b = np.random.default_rng(3).standard_normal(40)
    np.testing.assert_allclose(A @ half.solve(b), b, atol=1e-10 * np.abs(b).max())


@pytest.mark.skipif(_load_mkl() is None, reason="Intel MKL not installed")
@pytest.mark.parametrize("seed", range(3))
def test_single_precision_pardiso_with_refinement(seed):
    # oracle: dense eigenvalues (inertia) and the residual of the refined solution
    A = _random_symmetric(60, seed) + 3.0 * sp.eye(60)
    eig = np.linalg.eigvalsh(A.toarray())
    solver = PardisoSolver(precision="single")
    solver.factor(A.tocsc())
    assert solver.inertia() == ((eig > 0).sum(), (eig < 0).sum(), 0)
    b = np.random.default_rng(seed).standard_normal(60)
    cond = np.abs(eig).max() / np.abs(eig).min()
    residual = np.linalg.norm(A @ solver.solve(b) - b) / np.linalg.norm(b)
    assert residual <= 1e-12 * cond ** 2 + 1e-13
    with pytest.raises(ValueError, match="precision must be"):
        PardisoSolver(precision="half")


def _shell_like_matrix(n_side=60):
    """A symmetric indefinite sparse matrix the size of a small shell KKT system (a 2D
    Laplacian's 3x3-block stencil, shifted so that some pivots are negative): big enough that
    PARDISO's factorization runs in parallel."""
    lap1 = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n_side, n_side))
    lap = sp.kronsum(lap1, lap1)
    block = np.array([[2.0, 0.3, 0.1], [0.3, 1.5, 0.2], [0.1, 0.2, 1.0]])
    return (sp.kron(lap, block) - 0.05 * sp.identity(3 * n_side * n_side)).tocsr()


@pytest.mark.skipif(_load_mkl() is None, reason="Intel MKL not installed")
def test_pardiso_gives_the_same_bits_on_any_number_of_threads():
    A = _shell_like_matrix()
    b = np.random.default_rng(3).standard_normal(A.shape[0])
    results = []
    for threads in (1, 2, 3):
        solver = PardisoSolver(n_threads=threads, reproducible=True)
        solver.factor(A)
        results.append((solver.inertia(), solver.solve(b)))
    for inertia, x in results[1:]:
        assert inertia == results[0][0]
        assert np.array_equal(x, results[0][1])  # bitwise: reproducibility mode
    assert results[0][0][1] > 0  # indefinite: Bunch-Kaufman pivots were exercised
    np.testing.assert_allclose(A @ results[0][1], b, atol=1e-9 * np.abs(b).max())


@pytest.mark.skipif(_load_mkl() is None, reason="Intel MKL not installed")
def test_pardiso_plain_mode_is_one_thread_deterministic_and_accurate():
    # the plain mode (the default on one thread) is faster and gives other bits than the
    # reproducible mode; it must give the same bits every time, in both precisions, and be
    # refused on several threads, where its results may depend on their number
    A = _shell_like_matrix()
    b = np.random.default_rng(4).standard_normal(A.shape[0])
    assert PardisoSolver(n_threads=1).reproducible is False
    assert PardisoSolver(n_threads=2).reproducible is True
    solutions = []
    for _ in range(2):
        solver = PardisoSolver(n_threads=1)
        for approximate in (False, True):
            for _ in range(2):
                solver.factor(A, approximate=approximate)
                solutions.append((approximate, solver.inertia(), solver.solve(b)))
    for approximate, inertia, x in solutions:
        same = [y for a, _, y in solutions if a == approximate]
        assert all(np.array_equal(x, y) for y in same)
        assert inertia == solutions[0][1] and inertia[1] > 0
        tol = 1e-4 if approximate else 1e-9  # single precision without refinement
        np.testing.assert_allclose(A @ x, b, atol=tol * np.abs(b).max())
    with pytest.raises(ValueError, match="plain mode .* runs on one thread, got 2 threads"):
        PardisoSolver(n_threads=2, reproducible=False)
    with pytest.raises(ValueError, match="reproducible must be True, False or None, got 'yes'"):
        make_solver("pardiso", threads=1, reproducible="yes")


def test_threads_are_checked_and_default_to_the_environment(monkeypatch):
    for bad in (0, -2, 1.5, "2", True):
        with pytest.raises(ValueError, match=f"threads must be an integer >= 1, got {bad!r}"):
            check_threads(bad)
    with pytest.raises(ValueError, match="got 0"):
        make_solver("qdldl", threads=0)
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")
    assert default_threads() == 3
    monkeypatch.setenv("MKL_NUM_THREADS", "not a number")
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    assert default_threads() == 2
    monkeypatch.delenv("MKL_NUM_THREADS")
    monkeypatch.delenv("OMP_NUM_THREADS")
    assert 1 <= default_threads() <= (os.cpu_count() or 1)
    if _load_mkl() is not None:
        assert make_solver("pardiso", threads=2).n_threads == 2


@pytest.mark.parametrize("backend", BACKENDS)
def test_counting_solver_counts_and_passes_everything_on(backend):
    # oracle: the wrapped solver's own answers and the dense inertia
    from shellbuckle.solve.linear import CountingSolver

    A = _random_symmetric(30, 7)
    eig = np.linalg.eigvalsh(A.toarray())
    b = np.random.default_rng(7).standard_normal(30)
    counting = CountingSolver(backend())
    counting.factor(A)
    x = counting.solve(b)
    counting.solve(2 * b)
    counting.factor(A, approximate=True)
    assert counting.counts == dict(double=1, single=1, solve=2) and counting.n_factor == 2
    assert counting.inertia() == ((eig > 0).sum(), (eig < 0).sum(), 0)
    np.testing.assert_allclose(A @ x, b, atol=1e-10 * np.abs(b).max())


@pytest.mark.skipif(_load_mkl() is None, reason="Intel MKL not installed")
def test_pardiso_keeps_the_previous_factorizations_of_each_precision():
    # oracle: dense solutions and inertias of four matrices with one pattern; PARDISO holds
    # the last two double-precision factorizations, and the approximate (single-precision)
    # ones in their own handle, so that neither kind overwrites the other
    base = _random_symmetric(50, 1)
    mats = [base + s * sp.eye(50) for s in (0.0, 4.0, -4.0, 2.0)]
    b = np.random.default_rng(1).standard_normal(50)
    solver = PardisoSolver()
    handles = []
    for A in mats[:2]:
        solver.factor(A)
        handles.append(solver.held())
    solver.factor(mats[2], approximate=True)  # does not touch the double factorizations
    single = solver.held()
    assert single is not None and single[0] == "single" and single not in handles
    for A, handle, tol in zip(mats[:3], handles + [single], (1e-9, 1e-9, 1e-3)):
        eig = np.linalg.eigvalsh(A.toarray())
        assert solver.activate(handle) and solver.held() == handle
        assert solver.inertia() == ((eig > 0).sum(), (eig < 0).sum(), 0)
        np.testing.assert_allclose(A @ solver.solve(b), b, atol=tol * np.abs(b).max())
    solver.factor(mats[3])  # overwrites the older of the two double ones, not the single one
    assert not solver.activate(handles[0]) and solver.activate(handles[1])
    np.testing.assert_allclose(mats[1] @ solver.solve(b), b, atol=1e-9 * np.abs(b).max())
    assert solver.activate(single)
    np.testing.assert_allclose(mats[2] @ solver.solve(b), b, atol=1e-3 * np.abs(b).max())
    assert not solver.activate(None)


@pytest.mark.skipif(_load_mkl() is None, reason="Intel MKL not installed")
def test_pardiso_solves_each_held_approximate_factorization_with_its_own_pivoting():
    # oracle: dense solutions and inertias. Approximate factorizations pivot on the diagonal
    # (1x1), a stable_pivots one with Bunch-Kaufman; PARDISO reads the pivoting in its solves
    # too, so a held 1x1 factorization solved after a Bunch-Kaufman one (or the reverse) must
    # still give the single-precision solution of its own matrix
    base = _random_symmetric(50, 1)
    mats = [base + s * sp.eye(50) for s in (0.0, 4.0)]
    b = np.random.default_rng(1).standard_normal(50)
    solver = PardisoSolver()
    solver.factor(mats[0], approximate=True)
    diagonal = solver.held()
    assert solver._approximate._slot_pivots[diagonal[1]] == 0
    solver.factor(mats[1], approximate=True, stable_pivots=True)
    stable = solver.held()
    assert solver._approximate._slot_pivots[stable[1]] == 1
    for _ in range(2):
        for A, handle in zip(mats, (diagonal, stable)):
            eig = np.linalg.eigvalsh(A.toarray())
            assert solver.activate(handle)
            assert solver.inertia() == ((eig > 0).sum(), (eig < 0).sum(), 0)
            np.testing.assert_allclose(A @ solver.solve(b), b, atol=1e-3 * np.abs(b).max())


@pytest.mark.skipif(_load_mkl() is None, reason="Intel MKL not installed")
def test_pardiso_reuses_the_ordering_of_a_pattern_with_the_same_bits(monkeypatch):
    # a solver keeps the orderings of the patterns it has analysed (shared with its
    # single-precision twin, or given to another solver); nothing is kept between solvers
    # otherwise. Oracle: a fresh solver's solve, bitwise
    A = _shell_like_matrix(30)
    B = A.copy()
    B.data = B.data * (1.0 + 0.1 * np.cos(np.arange(B.nnz)))  # same pattern, other values
    B = (B + B.T) / 2.0
    b = np.random.default_rng(5).standard_normal(A.shape[0])
    analyses = []
    real_call = PardisoSolver._call

    def call(self, phase, *args, **kwargs):
        if phase == 11:
            analyses.append(int(self._iparm[4]))  # 2: METIS's ordering; 1: a given one
        return real_call(self, phase, *args, **kwargs)

    monkeypatch.setattr(PardisoSolver, "_call", call)
    fresh = PardisoSolver(n_threads=1)
    fresh.factor(B)
    first = PardisoSolver(n_threads=1)
    second = PardisoSolver(n_threads=1, orderings=first.orderings)
    first.factor(A)
    second.factor(B)
    second.factor(B, approximate=True)  # the single-precision twin: the same ordering
    PardisoSolver(n_threads=1).factor(B)  # its own orderings: METIS again
    assert analyses == [2, 2, 1, 1, 2]
    assert second.n_symbolic == 1 and len(first.orderings) == 1
    assert second.orderings is first.orderings
    second.activate(("double", second._slot, second._serial[second._slot]))
    x = second.solve(b)
    assert np.array_equal(x, fresh.solve(b))  # bitwise: the ordering is METIS's, reused
    assert second.inertia() == fresh.inertia()
    np.testing.assert_allclose(B @ x, b, atol=1e-9 * np.abs(b).max())



@pytest.mark.skipif(_load_mkl() is None, reason="Intel MKL not installed")
def test_pardiso_orders_a_dense_constraint_row_last_and_the_rest_without_it(monkeypatch):
    """A KKT matrix's constraint row reaches every other row: METIS orders the rest alone,
    the dense row is eliminated last, and the factorization is that of the matrix (inertia
    of the tangent Hessian plus the constraint's (1, 1), solves to round-off)."""
    K = _shell_like_matrix(12) + 0.3 * sp.identity(432)
    g = np.random.default_rng(2).standard_normal(432)
    kkt = sp.bmat([[K, sp.csr_matrix(g[:, None])], [sp.csr_matrix(g[None, :]), None]],
                  format="csr")
    sizes, perms = [], []
    real_call = PardisoSolver._call

    def call(self, phase, *args, **kwargs):
        if phase == 11:
            sizes.append(self._n)
        err = real_call(self, phase, *args, **kwargs)
        if phase == 11 and kwargs.get("perm") is not None:
            perms.append(kwargs["perm"].copy())
        return err

    monkeypatch.setattr(PardisoSolver, "_call", call)
    solver = PardisoSolver(n_threads=1)
    solver.factor(kkt)
    assert sizes == [432, 433]  # METIS on the rest, then the analysis with that ordering
    order = perms[-1]
    assert sorted(order.tolist()) == list(range(433)) and order[-1] == 432
    Z = np.linalg.svd(g[None, :])[2][1:].T  # orthonormal basis of the tangent space
    tangent = np.linalg.eigvalsh(Z.T @ K.toarray() @ Z)
    n_pos, n_neg, n_zero = solver.inertia()
    assert (n_pos, n_neg, n_zero) == ((tangent > 0).sum() + 1, (tangent < 0).sum() + 1, 0)
    b = np.random.default_rng(3).standard_normal(433)
    np.testing.assert_allclose(kkt @ solver.solve(b), b, atol=1e-9 * np.abs(b).max())
    sizes.clear()
    PardisoSolver(n_threads=1).factor(K)  # no dense row: METIS on the whole, once
    assert sizes == [432]

def test_recent_keeps_the_last_used_entries():
    from shellbuckle.solve.recent import Recent

    cache = Recent(2)
    cache.put("a", 1)
    cache.put("b", 2)
    assert cache.get("a") == 1  # now the most recent
    cache.put("c", 3)  # drops "b", the least recently used
    assert (cache.get("b"), cache.peek("a"), cache.peek("c"), len(cache)) == (None, 1, 3, 2)
    cache.peek("a")  # no change of order: "a" is still older than "c"
    cache.put("d", 4)
    assert (cache.get("a"), cache.get("c"), cache.get("d")) == (None, 3, 4)
