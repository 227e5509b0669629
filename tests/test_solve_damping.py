"""The Levenberg–Marquardt shift of Newton's method (:mod:`shellbuckle.solve.damping`).

Oracles: the trust-region update (Nocedal & Wright §4.1) and the relation that defines the
shift after a cut step; a shifted factorization's inertia against dense eigenvalues.
"""

import numpy as np
import pytest
import scipy.linalg

from shellbuckle.solve import NewtonOptions, Workspace
from shellbuckle.solve.damping import damping_next, factor_positive
from shellbuckle.solve.linesearch import projected_gradient
from shellbuckle.solve.system import KKTSystem
from test_solve_newton import shell


def test_levenberg_marquardt_shift_follows_the_model_of_the_step():
    # oracle: the trust-region update (Nocedal & Wright §4.1) and the relation that defines the
    # shift after a cut step, (q + mu) / (q + mu') = alpha along the step's own direction
    q, mu = 10.0, 2.0
    assert damping_next(mu, q, "newton", 1.0, 0.9) == pytest.approx(mu / 4)  # good model
    assert damping_next(mu, q, "newton", 1.0, 0.5) == mu  # fair model
    for alpha in (0.5, 0.1):  # cut: the shift that gives that length
        new = damping_next(mu, q, "newton", alpha, 0.9)
        assert (q + mu) / (q + new) == pytest.approx(alpha)
    assert damping_next(1e-3 * q, q, "newton", 1.0, 0.9) == 0.0  # negligible: pure Newton
    assert damping_next(mu, q, "quasi-newton", 0.1, np.nan) == mu  # no model: unchanged
    # below the energy's noise (no measurable decrease, rho NaN), near a minimum: a full step
    # counts as a good model, so the shift is released and the tail converges quadratically
    # (left as it was, it kept a minimization at gamma = 20995 converging linearly: 175
    # iterations and 5 double-precision factorizations against 154 and 1 to the same minimum);
    # a cut step says nothing about the model there
    assert damping_next(mu, q, "newton", 1.0, np.nan) == pytest.approx(mu / 4)
    assert damping_next(mu, q, "newton", 0.5, np.nan) == mu


def _tangent_eigenvalues(energy, volume, X, pinned):
    """Eigenvalues of ``K = Hess E - lam Hess V`` on the free dofs orthogonal to ``grad V``:
    the tangent Hessian whose inertia the KKT factorization of Newton's method shows."""
    gE, gV = energy.gradient(X), volume.gradient(X)
    lam, _ = projected_gradient(gE, gV)
    free = np.setdiff1d(np.arange(X.size), pinned)
    K = (energy.hessian(X) - lam * volume.hessian(X)).toarray()[np.ix_(free, free)]
    Z = scipy.linalg.null_space(gV.ravel()[free][None, :])
    return np.linalg.eigvalsh(Z.T @ K @ Z)


def _shrunk_far_past_buckling():
    """``(energy, volume, X, system)``: the uniformly shrunk sphere far past its buckling
    threshold (gamma = 1000, dV/V = 0.3), its KKT matrix assembled at ``X``."""
    mesh, energy, volume, V0 = shell(3, 1000)
    X = 0.7 ** (1 / 3) * mesh.X
    system = KKTSystem(energy, volume, 0.7 * V0, Workspace("qdldl"), X, NewtonOptions(), None,
                       np.random.default_rng(0))
    lam, _, _, gV = system.gradients(X)
    system.assemble(X, lam, gV)
    return energy, volume, X, system


def test_the_shift_search_stops_at_the_first_shift_that_makes_the_tangent_hessian_definite():
    # the uniformly shrunk sphere far past its buckling threshold (gamma = 1000, dV/V = 0.3).
    # Oracle: the dense tangent Hessian. The unshifted factorization shows its negative
    # eigenvalues; the shift found is 1e-4 mean|diag K| times a power of 4 that makes it
    # positive definite, a quarter of it does not
    energy, volume, X, system = _shrunk_far_past_buckling()
    eig = _tangent_eigenvalues(energy, volume, X, system.pinned)
    mu, inertia, indefinite = factor_positive(system, 0.0, escape_saddles=True)
    assert indefinite and inertia == int((eig < 0).sum()) > 0
    power = np.log(mu / (1e-4 * system.diag_scale)) / np.log(4.0)
    assert power == pytest.approx(round(power), abs=1e-9) and round(power) >= 1
    assert eig[0] + mu > 0 and eig[0] + mu / 4.0 < 0
    # without saddle escape the unshifted factorization is taken as it is
    assert factor_positive(system, 0.0, escape_saddles=False) == (0.0, inertia, True)


def test_no_shift_is_searched_for_an_overflowed_hessian():
    # a Hessian whose mean diagonal overflowed (gamma = 1e300) has no finite shift bound:
    # the search gives up at once (it used to raise an infinite shift forever: inf <= inf),
    # and the minimization ends with its reason instead of hanging. Oracle: the same system
    # with a finite diagonal finds its shift
    system = _shrunk_far_past_buckling()[3]
    assert factor_positive(system, 0.0, escape_saddles=True) is not None
    system.diag_scale = np.inf
    assert factor_positive(system, 0.0, escape_saddles=True) is None
    assert factor_positive(system, np.inf, escape_saddles=True) is None
    system.diag_scale = 1.0
    assert factor_positive(system, np.nan, escape_saddles=True) is None
