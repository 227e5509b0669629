"""GMRES refinement of single-precision solves (:mod:`shellbuckle.solve.krylov`).

Oracles: dense solves of the same systems (NumPy), the residual recomputed from the matrix,
and, for the KKT solve of a thin shell, the double-precision factorization's solution.
"""

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse as sp

from shellbuckle.energies.total import ShellEnergy
from shellbuckle.energies.volume import Volume
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.solve import NewtonOptions, Workspace, make_solver
from shellbuckle.solve.krylov import gmres, symmetric_matvec
from shellbuckle.solve.linear import _load_mkl
from shellbuckle.solve.system import KKTSystem, with_last_gradient


def _saddle_matrix(n=300, seed=0, cond=1e6):
    """A KKT-like symmetric indefinite matrix: an SPD block with eigenvalues spread over
    ``cond`` and one bordering constraint row."""
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    K = (Q * np.geomspace(1.0, cond, n)) @ Q.T
    g = rng.standard_normal(n)
    A = np.zeros((n + 1, n + 1))
    A[:n, :n], A[:n, n], A[n, :n] = K, g, g
    return A


def _single_precision_solve(A):
    """``v -> A^-1 v`` through an LU factorization of ``A`` rounded to single precision."""
    lu = scipy.linalg.lu_factor(A.astype(np.float32))
    return lambda v: scipy.linalg.lu_solve(lu, v.astype(np.float32)).astype(np.float64)


def test_symmetric_matvec_is_the_product_with_the_whole_matrix():
    A = sp.random(50, 50, density=0.1, random_state=1) + sp.eye(50)
    A = (A + A.T).tocsr()
    v = np.random.default_rng(2).standard_normal(50)
    assert np.allclose(symmetric_matvec(sp.triu(A).tocsr())(v), A @ v, rtol=1e-14, atol=1e-14)


def test_gmres_turns_a_single_precision_solve_into_a_double_precision_one():
    A = _saddle_matrix(cond=1e6)
    b = np.random.default_rng(3).standard_normal(len(A))
    exact = np.linalg.solve(A, b)
    precondition = _single_precision_solve(A)
    plain = precondition(b)
    refined = gmres(lambda v: A @ v, precondition, b, rtol=1e-10, max_iter=30)
    # the residual reported is the true one: the tolerance asked, up to the rounding of the
    # products with A (the least-squares estimate GMRES stops on is exact only in exact
    # arithmetic)
    assert refined.residual == pytest.approx(np.linalg.norm(b - A @ refined.x) / np.linalg.norm(b))
    assert refined.residual <= 1e-9 and 1 <= refined.iterations <= 30
    error = lambda x: np.linalg.norm(x - exact) / np.linalg.norm(exact)  # noqa: E731
    # cond = 1e6 leaves single precision with two or three correct digits; GMRES recovers
    # what double precision gives (cond eps = 2e-10)
    assert error(plain) > 1e-4
    assert error(refined.x) < 1e-8


def test_gmres_stops_at_its_iteration_limit_and_reports_the_residual_reached():
    A = _saddle_matrix(cond=1e11)
    b = np.ones(len(A))
    precondition = _single_precision_solve(A)
    none = gmres(lambda v: A @ v, precondition, b, rtol=1e-14, max_iter=0)
    assert none.iterations == 0 and np.array_equal(none.x, precondition(b))
    two = gmres(lambda v: A @ v, precondition, b, rtol=1e-14, max_iter=2)
    assert two.iterations == 2
    assert two.residual == pytest.approx(np.linalg.norm(b - A @ two.x) / np.linalg.norm(b))
    # GMRES minimizes the residual over a growing space: more iterations never do worse
    four = gmres(lambda v: A @ v, precondition, b, rtol=1e-14, max_iter=4)
    assert four.residual <= two.residual * (1 + 1e-6) and two.residual <= none.residual


def test_gmres_of_a_zero_right_hand_side_is_zero():
    A = _saddle_matrix(n=20)
    out = gmres(lambda v: A @ v, _single_precision_solve(A), np.zeros(21), 1e-10, 5)
    assert out.iterations == 0 and not out.x.any()


@pytest.mark.skipif(_load_mkl() is None, reason="single precision needs PARDISO (Intel MKL)")
def test_a_refined_single_precision_kkt_solve_is_the_double_precision_one():
    # a thin shell on a fine mesh, whose KKT matrix is ill-conditioned enough that a plain
    # single-precision solve is off in its leading digits along the soft modes
    mesh = icosphere(32)
    energy = ShellEnergy.build(mesh, ShellParameters.from_gamma(1e5, nu=1.0 / 3.0))
    volume = Volume(mesh.faces, mesh.n_vertices)
    X = 0.97 ** (1.0 / 3.0) * mesh.X
    system = KKTSystem(with_last_gradient(energy), volume, volume.value(X),
                       Workspace(make_solver("pardiso")), X, NewtonOptions(), None,
                       np.random.default_rng(0))
    lam, r, gE, gV = system.gradients(X)
    system.assemble(X, lam, gV)
    rhs = np.random.default_rng(4).standard_normal(len(system.free))
    for mu in (0.0, 1e-3 * system.diag_scale):
        assert system.factor(mu)[0]
        exact = system.solve(rhs, 0.25)
        assert system.factor(mu, approximate=True)[0] and system.token.approximate
        plain, refined = system.solve(rhs, 0.25), system.solve(rhs, 0.25, refine=True)
        error = lambda x: np.linalg.norm(x - exact) / np.linalg.norm(exact)  # noqa: E731
        assert error(refined) < 1e-7
        assert error(plain) > 10 * error(refined)
    # a double-precision factorization is not refined: the same bits with or without
    assert system.factor(0.0)[0]
    assert np.array_equal(system.solve(rhs, 0.25, refine=True), system.solve(rhs, 0.25))


@pytest.mark.skipif(_load_mkl() is None, reason="single precision needs PARDISO (Intel MKL)")
def test_refined_and_plain_single_precision_steps_reach_the_same_minimum():
    # an exact equivalence of two paths: the refinement changes the steps, not the minimum
    from shellbuckle.solve import newton

    mesh = icosphere(8)
    energy = ShellEnergy.build(mesh, ShellParameters.from_gamma(1e4, nu=1.0 / 3.0))
    volume = Volume(mesh.faces, mesh.n_vertices)
    V = 0.97 * volume.value(mesh.X)
    shrunk = 0.97 ** (1.0 / 3.0) * mesh.X
    X0 = shrunk + 0.01 * np.random.default_rng(7).standard_normal(mesh.X.shape)
    plain, refined = (newton(energy, volume, X0, V, solver="pardiso", precondition_at=shrunk,
                             refine_iterations=k) for k in (0, 20))
    assert plain.success and refined.success and plain.inertia == refined.inertia == 0
    assert refined.fun == pytest.approx(plain.fun, rel=1e-10)
    assert refined.pressure == pytest.approx(plain.pressure, rel=1e-7)
    assert np.abs(refined.x - plain.x).max() < 1e-6
    assert refined.timings.get("refine", 0.0) > 0.0 and "refine" not in plain.timings
