"""L-BFGS secant pairs and the two-loop recursion.

Oracles: the BFGS update of the inverse Hessian written out as dense matrices,
``H <- (I - rho s y^T) H (I - rho y s^T) + rho s s^T`` applied pair after pair to ``H0``
(Nocedal & Wright, eq. 6.17 and Algorithm 7.4), and the secant equation ``H y = s`` that
the newest pair satisfies exactly.
"""

import numpy as np
import pytest

from shellbuckle.solve.lbfgs import SecantPairs


def _dense_bfgs(H0, pairs):
    H = H0.copy()
    n = len(H0)
    for s, y in pairs:
        rho = 1.0 / (s @ y)
        V = np.eye(n) - rho * np.outer(y, s)
        H = V.T @ H @ V + rho * np.outer(s, s)
    return H


def _problem(n=12, m=7, seed=0):
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((n, n))
    A = B @ B.T + n * np.eye(n)  # a convex quadratic: every pair has s.y > 0
    H0 = np.linalg.inv(np.diag(np.diag(A)))
    steps = rng.standard_normal((m, n))
    return A, H0, [(s, A @ s) for s in steps]


@pytest.mark.parametrize("memory", [3, 7, 20])
def test_two_loop_is_the_dense_bfgs_update_of_the_last_pairs(memory):
    A, H0, pairs = _problem()
    lbfgs = SecantPairs(len(A), memory)
    for s, y in pairs:
        lbfgs.add(s, y)
    assert len(lbfgs) == min(memory, len(pairs))
    r = np.random.default_rng(1).standard_normal(len(A))
    H = _dense_bfgs(H0, pairs[-memory:])
    np.testing.assert_allclose(lbfgs.apply(r, lambda q: H0 @ q), H @ r, rtol=1e-12,
                               atol=1e-12 * np.abs(H @ r).max())
    s, y = pairs[-1]  # the secant equation of the newest pair
    np.testing.assert_allclose(lbfgs.apply(y, lambda q: H0 @ q), s, rtol=1e-10, atol=1e-12)


def test_a_pair_without_positive_curvature_is_not_kept_and_clear_empties():
    A, H0, pairs = _problem()
    lbfgs = SecantPairs(len(A), 4)
    s, y = pairs[0]
    lbfgs.add(s, -y)  # s.y < 0
    lbfgs.add(s, np.zeros_like(y))
    assert len(lbfgs) == 0
    r = np.arange(len(A), dtype=float)
    np.testing.assert_array_equal(lbfgs.apply(r, lambda q: 2.0 * q), 2.0 * r)  # H0 alone
    lbfgs.add(s, y)
    assert len(lbfgs) == 1
    lbfgs.clear()
    assert len(lbfgs) == 0
    assert len(SecantPairs(len(A), 0).apply(r, lambda q: q)) == len(A)  # no memory at all


def test_the_start_vector_is_not_changed():
    A, H0, pairs = _problem()
    lbfgs = SecantPairs(len(A), 5)
    for s, y in pairs:
        lbfgs.add(s, y)
    r = np.random.default_rng(2).standard_normal(len(A))
    kept = r.copy()
    lbfgs.apply(r, lambda q: q)  # an H0 that returns its argument, changed in place later
    np.testing.assert_array_equal(r, kept)
