"""Newton at fixed volume: constraint, stationarity, pressure = -dE/dV, monotonicity, saddles.

Oracles: the KKT conditions recomputed from the energy terms; central differences of the
minimum energy along a sequence of target volumes; the exact uniformly shrunk icosahedron
(all twelve vertices equivalent, so uniform shrinking is an exact constrained equilibrium);
dense eigenvalues of the constrained Hessian for the inertia.
"""

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse as sp

from shellbuckle.energies.total import ShellEnergy
from shellbuckle.energies.volume import Volume
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.solve import make_solver, minimize, newton
from shellbuckle.solve.linear import CountingSolver, _load_mkl
from shellbuckle.solve.linesearch import ENERGY_NOISE, ENERGY_ROUNDOFF, projected_gradient
from shellbuckle.solve.newton import (KKTAssembler, _fixes_gauge, pinned_dofs, remove_rigid,
                                     rigid_modes)
from test_solve_energies import spring_shell


def shell(n, gamma, nu=1.0 / 3.0, c0=None):
    mesh = icosphere(n)
    energy = ShellEnergy.build(mesh, ShellParameters.from_gamma(gamma, nu=nu), c0=c0)
    volume = Volume(mesh.faces, mesh.n_vertices)
    return mesh, energy, volume, volume.value(mesh.X)


def assert_kkt(energy, volume, res, V_target, rtol=1e-8):
    gE, gV = energy.gradient(res.x), volume.gradient(res.x)
    assert res.volume_error <= 1e-12
    assert abs(volume.value(res.x) - V_target) <= 1e-12 * V_target
    # grad E = lam grad V with lam = -pressure
    assert np.linalg.norm(gE + res.pressure * gV) <= rtol * np.linalg.norm(gE) + 1e-10
    lam, r = projected_gradient(gE, gV)
    assert res.grad_norm == pytest.approx(np.linalg.norm(r), rel=1e-6, abs=1e-12)


def tangent_inertia_dense(energy, volume, X):
    """Negative eigenvalues of Hess E - lam Hess V on {grad V, rigid modes}^perp (dense)."""
    gE, gV = energy.gradient(X), volume.gradient(X)
    lam, _ = projected_gradient(gE, gV)
    K = (energy.hessian(X) - lam * volume.hessian(X)).toarray()
    C = np.column_stack([gV.ravel(), rigid_modes(X)])
    Z = scipy.linalg.null_space(C.T)
    ev = np.linalg.eigvalsh(Z.T @ K @ Z)
    return int((ev < -1e-8 * np.abs(ev).max()).sum())


@pytest.mark.parametrize("factor", [1.05, 0.97])
def test_spring_shell_minimum_satisfies_kkt_conditions(factor):
    mesh, energy = spring_shell(3, kb=0.01)
    volume = Volume(mesh.faces, mesh.n_vertices)
    V_target = factor * volume.value(mesh.X)
    res = newton(energy, volume, mesh.X, V_target)
    assert res.success and res.inertia == 0
    assert_kkt(energy, volume, res, V_target)
    # inflation stretches the springs: dE/dV > 0, i.e. negative (inward) pressure
    assert np.sign(res.pressure) == (-1 if factor > 1 else 1)


@pytest.mark.parametrize("solver", ["qdldl", "superlu"])
def test_shell_minimum_before_buckling(solver):
    mesh, energy, volume, V0 = shell(5, 2333)
    V_target = 0.981 * V0
    res = newton(energy, volume, mesh.X, V_target, solver=solver)
    assert res.success and res.inertia == 0 and res.pressure > 0
    assert_kkt(energy, volume, res, V_target)
    assert tangent_inertia_dense(energy, volume, res.x) == 0
    # the uniformly shrunk mesh is a feasible point, so the minimum cannot be above it
    s = (V_target / V0) ** (1.0 / 3.0)
    assert res.fun <= energy.value(s * mesh.X)


@pytest.mark.parametrize("gamma", [100.0, 2333.0])
def test_icosahedron_matches_exact_uniform_shrink(gamma):
    # n = 1: all vertices equivalent, uniform shrinking is the exact constrained equilibrium;
    # Green-Lagrange strain e = (s^2 - 1)/2 in every face, energy rest_area A e^2 / (1 - nu)
    nu = 1.0 / 3.0
    mesh, energy, volume, V0 = shell(1, gamma, nu)
    dV = 0.019
    s = (1.0 - dV) ** (1.0 / 3.0)
    e = (s * s - 1.0) / 2.0
    exact = energy.stretching.rest_area.sum() * gamma * e * e / (1.0 - nu) + energy.bending.value(s * mesh.X)
    X0 = mesh.X + 0.01 * np.random.default_rng(0).standard_normal(mesh.X.shape)
    res = newton(energy, volume, X0, (1.0 - dV) * V0)
    assert res.success and res.inertia == 0
    assert res.fun == pytest.approx(exact, rel=1e-12)


def test_pressure_is_minus_derivative_of_minimum_energy():
    mesh, energy, volume, V0 = shell(4, 2333)
    V_t, h = 0.97 * V0, 1e-4
    res = newton(energy, volume, mesh.X, V_t)
    plus = newton(energy, volume, res.x, V_t * (1 + h))
    minus = newton(energy, volume, res.x, V_t * (1 - h))
    assert res.inertia == plus.inertia == minus.inertia == 0
    dE_dV = (plus.fun - minus.fun) / (2 * h * V_t)
    assert res.pressure == pytest.approx(-dE_dV, rel=1e-6)


def test_newton_steps_never_raise_the_energy_at_fixed_volume():
    mesh, energy, volume, V0 = shell(4, 1000)
    X0 = (0.95 ** (1 / 3)) * mesh.X + 0.02 * np.random.default_rng(1).standard_normal(mesh.X.shape)
    res = newton(energy, volume, X0, 0.95 * V0, history=True)
    assert res.success
    E = np.array([h["energy"] for h in res.history])
    E0 = newton(energy, volume, X0, 0.95 * V0, max_iter=0).fun  # the start, on the constraint
    steps = np.diff(np.concatenate([[E0], E]))
    assert (steps <= ENERGY_NOISE * np.abs(E)).all()
    big = np.abs(steps) > ENERGY_NOISE * np.abs(E)
    assert (steps[big] < ENERGY_ROUNDOFF * np.abs(E)[big]).all()


def test_newton_leaves_the_symmetric_saddle():
    # gamma = 1000: classical threshold dV/V ~ 6 (1 - nu) / sqrt(gamma) = 0.13; at 0.3 the
    # uniformly shrunk sphere is far past it and the symmetric branch is a saddle
    mesh, energy, volume, V0 = shell(4, 1000)
    X0 = (0.7 ** (1 / 3)) * mesh.X
    stuck = newton(energy, volume, X0, 0.7 * V0, escape_saddles=False)
    assert stuck.success and stuck.inertia > 0
    assert tangent_inertia_dense(energy, volume, stuck.x) == stuck.inertia
    res = newton(energy, volume, X0, 0.7 * V0)
    assert res.success and res.inertia == 0
    assert tangent_inertia_dense(energy, volume, res.x) == 0
    assert res.fun < 0.9 * stuck.fun
    assert_kkt(energy, volume, res, 0.7 * V0)


def test_result_does_not_depend_on_a_rigid_motion_of_the_start():
    mesh, energy, volume, V0 = shell(3, 500)
    X0 = mesh.X + 0.02 * np.random.default_rng(2).standard_normal(mesh.X.shape)
    Q = scipy.linalg.expm(np.array([[0, -0.3, 0.2], [0.3, 0, -0.5], [-0.2, 0.5, 0]]))
    a = newton(energy, volume, X0, 0.96 * V0)
    b = newton(energy, volume, X0 @ Q.T + [1.0, -2.0, 0.5], 0.96 * V0)
    assert a.fun == pytest.approx(b.fun, rel=1e-10)
    assert a.pressure == pytest.approx(b.pressure, rel=1e-8)


def test_pinned_dofs_fix_the_rigid_gauge():
    X = icosphere(3).X
    pinned = pinned_dofs(X)
    assert len(set(pinned)) == 6
    assert np.linalg.matrix_rank(rigid_modes(X)[pinned]) == 6


def test_the_gauge_test_reads_the_rows_of_the_rigid_modes():
    # oracle: the rows of the whole (3V, 6) array of rigid modes, exactly; a gauge of three
    # translations only of one vertex and its neighbour cannot fix the rotations
    from shellbuckle.solve.newton import _rigid_rows

    rng = np.random.default_rng(8)
    X = icosphere(2).X * [1.0, 0.7, 0.4] + [0.3, -1.0, 2.0]
    for _ in range(5):
        dofs = rng.choice(X.size, 6, replace=False)
        assert np.array_equal(_rigid_rows(X, dofs), rigid_modes(X)[dofs])
    assert _fixes_gauge(X, pinned_dofs(X))
    assert not _fixes_gauge(X, np.array([0, 1, 2, 3, 4, 5]))


def test_remove_rigid_is_the_least_squares_projection_off_rigid_motions():
    # oracle: the least-squares solve with the six rigid modes; the result is orthogonal to
    # them, a rigid motion is removed entirely, and a rigid-free field is left unchanged
    rng = np.random.default_rng(4)
    X = icosphere(2).X * [1.0, 0.7, 0.4] + [0.3, -1.0, 2.0]
    p = rng.standard_normal(X.shape)
    M = rigid_modes(X)
    expected = p - (M @ np.linalg.solve(M.T @ M, M.T @ p.ravel())).reshape(p.shape)
    q = remove_rigid(X, p)
    np.testing.assert_allclose(q, expected, atol=1e-13)
    assert np.abs(M.T @ q.ravel()).max() < 1e-12 * np.abs(M.T @ p.ravel()).max()
    rigid = (M @ rng.standard_normal(6)).reshape(X.shape)
    assert np.abs(remove_rigid(X, rigid)).max() < 1e-13 * np.abs(rigid).max()
    np.testing.assert_allclose(remove_rigid(X, q + rigid), q, atol=1e-12)


def test_bad_problem_is_refused():
    mesh, energy, volume, V0 = shell(1, 100)
    with pytest.raises(ValueError, match="V_target must be a positive finite volume"):
        newton(energy, volume, mesh.X, -1.0)
    with pytest.raises(ValueError, match=r"X0 must be a \(V, 3\) array"):
        newton(energy, volume, mesh.X[:, :2], V0)
    with pytest.raises(ValueError, match="unknown method"):
        minimize(energy, volume, mesh.X, V0, method="bfgs")


def test_kkt_assembler_matches_the_dense_kkt_matrix():
    # oracle: [[c1 M1 + c2 M2 + mu I, g], [g^T, 0]] on the free dofs, built densely
    rng = np.random.default_rng(4)
    n_dofs = 30
    mats = []
    for seed in (1, 2):
        M = sp.random(n_dofs, n_dofs, density=0.2, random_state=seed)
        mats.append((M + M.T).tocsr())
    free = np.setdiff1d(np.arange(n_dofs), [3, 17, 22])
    g = rng.standard_normal((n_dofs // 3, 3))
    coefs, mu = (1.0, -0.7), 0.3
    kkt = KKTAssembler(free, n_dofs)
    data = kkt.build(list(zip(mats, coefs)), g)
    upper = kkt.matrix(data, mu)
    assert (sp.tril(upper, k=-1).nnz == 0) and upper.has_sorted_indices
    full = (upper + sp.triu(upper, k=1).T).toarray()
    K = sum(c * M.toarray() for M, c in zip(mats, coefs))[np.ix_(free, free)]
    K += mu * np.eye(len(free))
    gf = g.ravel()[free]
    expected = np.block([[K, gf[:, None]], [gf[None, :], np.zeros((1, 1))]])
    np.testing.assert_allclose(full, expected, rtol=0, atol=1e-14)
    # same patterns again: same index arrays (the solver keeps its symbolic analysis)
    again = kkt.matrix(kkt.build(list(zip(mats, coefs)), g))
    assert np.shares_memory(again.indices, upper.indices)
    assert np.shares_memory(again.indptr, upper.indptr)


def test_kkt_assembler_follows_a_change_of_term_patterns():
    # oracle: the dense KKT matrix after each change; a term whose pattern lies within the
    # current one keeps the matrix pattern, one with new entries widens it
    rng = np.random.default_rng(5)
    n_dofs = 36
    free = np.setdiff1d(np.arange(n_dofs), [0, 7, 20, 21, 30, 35])
    g = rng.standard_normal((n_dofs // 3, 3))

    def sym(density, seed):
        M = sp.random(n_dofs, n_dofs, density=density, random_state=seed)
        return (M + M.T).tocsr()

    wide, other = sym(0.3, 1), sym(0.1, 2)
    half = sp.triu(wide, format="csr")
    half.data[rng.random(half.nnz) < 0.5] = 0.0
    half.eliminate_zeros()
    narrow = (half + sp.triu(half, k=1).T).tocsr()  # symmetric, a sub-pattern of ``wide``
    kkt = KKTAssembler(free, n_dofs)
    patterns = []
    for mats in ([wide, other], [narrow, other], [wide, sym(0.3, 3)]):
        terms = list(zip(mats, (1.0, 0.5)))
        upper = kkt.matrix(kkt.build(terms, g))
        full = (upper + sp.triu(upper, k=1).T).toarray()
        K = sum(c * M.toarray() for M, c in terms)[np.ix_(free, free)]
        gf = g.ravel()[free]
        expected = np.block([[K, gf[:, None]], [gf[None, :], np.zeros((1, 1))]])
        np.testing.assert_allclose(full, expected, rtol=0, atol=1e-14)
        patterns.append(upper.indices.size)
    assert patterns[1] == patterns[0]  # kept
    assert patterns[2] > patterns[0]  # widened


@pytest.mark.parametrize("max_quasi", [0, 10])
def test_quasi_newton_steps_reach_the_newton_minimum(max_quasi):
    # oracle: KKT conditions, dense inertia at the final point, agreement with plain Newton
    mesh, energy, volume, V0 = shell(4, 1000)
    X0 = (0.9 ** (1 / 3)) * mesh.X + 0.01 * np.random.default_rng(6).standard_normal(mesh.X.shape)
    res = newton(energy, volume, X0, 0.9 * V0, max_quasi=max_quasi)
    ref = newton(energy, volume, X0, 0.9 * V0, max_quasi=0, inertia_step=0.0)
    assert res.success and res.inertia == 0
    assert_kkt(energy, volume, res, 0.9 * V0)
    assert tangent_inertia_dense(energy, volume, res.x) == 0
    assert res.fun == pytest.approx(ref.fun, rel=1e-10)
    assert res.pressure == pytest.approx(ref.pressure, rel=1e-7)


def test_pinned_dofs_are_a_gauge_choice_only():
    mesh, energy, volume, V0 = shell(3, 500)
    X0 = mesh.X + 0.02 * np.random.default_rng(8).standard_normal(mesh.X.shape)
    a = newton(energy, volume, X0, 0.96 * V0)
    b = newton(energy, volume, X0, 0.96 * V0, pinned=pinned_dofs(mesh.X))
    c = newton(energy, volume, X0, 0.96 * V0, pinned=[0, 0, 1, 2, 3, 4])  # invalid: replaced
    for other in (b, c):
        assert other.success and other.inertia == 0
        assert other.fun == pytest.approx(a.fun, rel=1e-10)
        assert other.pressure == pytest.approx(a.pressure, rel=1e-8)


def test_newton_is_reproducible():
    mesh, energy, volume, V0 = shell(3, 1000)
    X0 = 0.9 ** (1 / 3) * mesh.X + 0.01 * np.random.default_rng(9).standard_normal(mesh.X.shape)
    a = newton(energy, volume, X0, 0.9 * V0)
    b = newton(energy, volume, X0, 0.9 * V0)
    assert np.array_equal(a.x, b.x) and a.fun == b.fun and a.nit == b.nit


@pytest.mark.parametrize("sigma", [0.2, 0.3])
def test_preconditioned_relaxation_reaches_the_newton_minimum(sigma):
    # a jiggle of sigma mean edge lengths per coordinate from the shrunk sphere (0.3: hundreds
    # of negative eigenvalues at the start; both farther than RELAX_ROUGH_MIN_MOVE rms);
    # oracles: KKT conditions, dense inertia, plain Newton's minimum
    mesh, energy, volume, V0 = shell(4, 1000)
    shrunk = 0.95 ** (1 / 3) * mesh.X
    edge = np.linalg.norm(mesh.X[mesh.faces[:, 0]] - mesh.X[mesh.faces[:, 1]], axis=1).mean()
    X0 = shrunk + sigma * edge * np.random.default_rng(3).standard_normal(mesh.X.shape)
    ref = newton(energy, volume, X0, 0.95 * V0, max_iter=300)
    res = newton(energy, volume, X0, 0.95 * V0, precondition_at=shrunk, history=True,
                 max_iter=300)
    assert ref.success and res.success and res.inertia == 0
    assert_kkt(energy, volume, res, 0.95 * V0)
    assert tangent_inertia_dense(energy, volume, res.x) == 0
    assert res.fun == pytest.approx(ref.fun, rel=1e-10)
    assert res.pressure == pytest.approx(ref.pressure, rel=1e-7)
    steps = [h["step"] for h in res.history]
    assert steps[0] == "relax" and res.nit == len(steps)
    relax = [h["energy"] for h in res.history if h["step"] == "relax"]
    assert all(b <= a * (1 + ENERGY_ROUNDOFF) for a, b in zip(relax, relax[1:]))


def _jiggled_shell(sigma=0.3, seed=3):
    mesh, energy, volume, V0 = shell(4, 1000)
    shrunk = 0.95 ** (1 / 3) * mesh.X
    edge = np.linalg.norm(mesh.X[mesh.faces[:, 0]] - mesh.X[mesh.faces[:, 1]], axis=1).mean()
    X0 = shrunk + sigma * edge * np.random.default_rng(seed).standard_normal(mesh.X.shape)
    return mesh, energy, volume, 0.95 * V0, shrunk, X0


def test_rough_relaxation_stage_takes_full_steps_sooner():
    # oracles: the relaxation without the rough stage, KKT conditions and the dense inertia.
    # The rough stage (a larger shift first) damps the soft modes that made the first
    # directions far too long, so fewer steps are cut by the line search; it ends with one
    # more (single-precision) factorization at the small shift, and the minimum is the same.
    # Without the self-scaling of the later steps, which also lengthens the cut ones
    from shellbuckle.solve.newton import RELAX_ROUGH_SHIFT

    mesh, energy, volume, V, shrunk, X0 = _jiggled_shell()
    runs = {}
    for rough in (0.0, RELAX_ROUGH_SHIFT):
        solver = CountingSolver(make_solver())
        res = newton(energy, volume, X0, V, precondition_at=shrunk, history=True, solver=solver,
                     relax_rough_shift=rough, max_iter=300, relax_scaling=False)
        relax = [h for h in res.history if h["step"] == "relax"]
        runs[rough] = (res, relax, solver.counts["single"])
    (plain, relax_plain, single_plain), (rough, relax_rough, single_rough) = runs.values()
    assert plain.success and rough.success and rough.inertia == 0
    assert_kkt(energy, volume, rough, V)
    assert tangent_inertia_dense(energy, volume, rough.x) == 0
    assert rough.fun == pytest.approx(plain.fun, rel=1e-10)
    assert rough.pressure == pytest.approx(plain.pressure, rel=1e-7)
    cut = [sum(h["alpha"] < 1.0 for h in relax) for relax in (relax_plain, relax_rough)]
    assert cut[1] < cut[0]
    assert single_rough == single_plain + 1
    energies = [h["energy"] for h in relax_rough]
    assert all(b <= a * (1 + ENERGY_ROUNDOFF) for a, b in zip(energies, energies[1:]))


def test_the_relaxation_scale_is_the_parabola_minimizer_along_the_step():
    # oracle: an exact parabola E(a) = E0 + g a + c a^2 / 2 has its minimum at -g / c; the
    # scale is multiplied by it, clipped to [0.1, 2] per step and kept within [1e-3, 1]
    from shellbuckle.solve.newton import _rescaled

    E0, g = 3.0, -2.0
    for c, alpha, tau in ((8.0, 0.25, 1.0), (8.0, 1.0, 0.5), (2.5, 1.0, 0.4)):
        E1 = E0 + g * alpha + 0.5 * c * alpha ** 2
        assert _rescaled(tau, E0, E1, g, alpha) == pytest.approx(tau * -g / c, rel=1e-12)
    assert _rescaled(0.4, E0, E0 + g + 0.5 * 0.1, g, 1.0) == pytest.approx(0.8)  # x2 at most
    assert _rescaled(0.5, E0, E0 + g + 0.5 * 1e3, g, 1.0) == pytest.approx(0.05)  # x0.1
    assert _rescaled(1.0, E0, E0 + g + 0.5 * 1.0, g, 1.0) == 1.0  # never above 1
    assert _rescaled(1e-3, E0, E0 + g + 0.5 * 1e3, g, 1.0) == 1e-3
    assert _rescaled(0.3, E0, E0 + 2 * g, g, 1.0) == pytest.approx(0.6)  # concave: longer


@pytest.mark.parametrize("sigma", [0.3, 0.5])
def test_a_self_scaled_relaxation_reaches_the_same_minimum(sigma):
    # oracles: the relaxation without the scaling, KKT conditions and the dense inertia; the
    # relaxation's energies never rise
    mesh, energy, volume, V, shrunk, X0 = _jiggled_shell(sigma=sigma)
    plain, scaled = (newton(energy, volume, X0, V, precondition_at=shrunk, history=True,
                            relax_scaling=scaling, max_iter=300) for scaling in (False, True))
    assert plain.success and scaled.success and scaled.inertia == 0
    assert_kkt(energy, volume, scaled, V)
    assert tangent_inertia_dense(energy, volume, scaled.x) == 0
    assert scaled.fun == pytest.approx(plain.fun, rel=1e-10)
    assert scaled.pressure == pytest.approx(plain.pressure, rel=1e-7)
    energies = [h["energy"] for h in scaled.history if h["step"] == "relax"]
    assert all(b <= a * (1 + ENERGY_ROUNDOFF) for a, b in zip(energies, energies[1:]))


def test_rough_stage_is_skipped_for_a_start_far_from_or_close_to_the_relaxed_state():
    # a perturbation larger than the edges (2 edge lengths rms per vertex) tangles the mesh;
    # the relaxation then runs without the rough stage: exactly the run with it switched off
    mesh, energy, volume, V, shrunk, X0 = _jiggled_shell(sigma=2.0 / np.sqrt(3.0))
    runs = [newton(energy, volume, X0, V, precondition_at=shrunk, max_iter=20,
                   relax_rough_shift=rough) for rough in (1e-1, 0.0)]
    assert np.array_equal(runs[0].x, runs[1].x) and runs[0].nit == runs[1].nit
    mesh, energy, volume, V, shrunk, X0 = _jiggled_shell()  # 0.5 edge lengths rms: used
    runs = [newton(energy, volume, X0, V, precondition_at=shrunk, max_iter=20,
                   relax_rough_shift=rough) for rough in (1e-1, 0.0)]
    assert not np.array_equal(runs[0].x, runs[1].x)
    # a start closer than 0.3 edge lengths rms has no roughness to remove: no rough stage
    mesh, energy, volume, V, shrunk, X0 = _jiggled_shell(sigma=0.1)  # 0.17 rms
    runs = [newton(energy, volume, X0, V, precondition_at=shrunk, max_iter=20,
                   relax_rough_shift=rough) for rough in (1e-1, 0.0)]
    assert np.array_equal(runs[0].x, runs[1].x) and runs[0].nit == runs[1].nit


def test_single_precision_steps_reach_the_double_precision_minimum():
    # oracles: the same minimization with every factorization in double precision, KKT
    # conditions and the dense inertia; the single-precision Newton steps never report an
    # inertia, and (without single-precision certificates) the inertia that certifies the
    # minimum comes from a double factorization
    mesh, energy, volume, V, shrunk, X0 = _jiggled_shell()
    runs = []
    for single in (False, True):
        solver = CountingSolver(make_solver())
        res = newton(energy, volume, X0, V, history=True, solver=solver, max_iter=300,
                     single_precision_steps=single, certify_single=False)
        runs.append((res, dict(solver.counts)))
    (double, counts_double), (mixed, counts_mixed) = runs
    assert double.success and mixed.success and mixed.inertia == 0
    assert_kkt(energy, volume, mixed, V)
    assert tangent_inertia_dense(energy, volume, mixed.x) == 0
    assert mixed.fun == pytest.approx(double.fun, rel=1e-10)
    assert mixed.pressure == pytest.approx(double.pressure, rel=1e-7)
    assert counts_double["single"] == 0 and counts_mixed["single"] >= 3
    assert 1 <= counts_mixed["double"] < counts_double["double"]
    # (every Newton step of this problem is taken at an unconverged point)
    assert any(h["inertia"] is not None for h in double.history if h["step"] == "newton")
    assert all(h["inertia"] is None for h in mixed.history if h["step"] == "newton")
    # without saddle escape (a search for any stationary point) every factorization is double
    solver = CountingSolver(make_solver())
    newton(energy, volume, X0, V, solver=solver, escape_saddles=False, max_iter=300)
    assert solver.counts["single"] == 0


def test_kkt_pattern_does_not_depend_on_values():
    # on the exact reference icosphere some stretching and bending entries cancel; the
    # solver's pattern (and so its ordering and round-off) must be the same as elsewhere
    mesh, energy, volume, V0 = shell(3, 271)
    X1 = mesh.X + 1e-3 * np.random.default_rng(2).standard_normal(mesh.X.shape)
    assert energy.hessian(mesh.X).nnz < energy.hessian(X1).nnz  # the cancellation exists
    for a, b in zip(energy.hessian_terms(mesh.X), energy.hessian_terms(X1)):
        assert np.array_equal(a.indptr, b.indptr) and np.array_equal(a.indices, b.indices)
    assert np.allclose(sum(energy.hessian_terms(X1)).toarray(), energy.hessian(X1).toarray(),
                       rtol=0, atol=1e-12)


def test_a_gauge_lost_during_a_minimization_is_replaced():
    """Pinned dofs that fixed the rigid motions at the start can stop doing so as the shell
    deforms (here: x, y, z of vertex a, x, y of vertex b and y of vertex c, with c moved onto
    the line ab, so the rotation about that line leaves all six unchanged). Newton's method must
    notice and pin others, or K on the free dofs is singular and the residual on the pinned dofs
    stays (a late step of a gamma = 271 run stalled 4.5e-4 kappa above its minimum that way)."""
    from shellbuckle.solve.linear import make_solver
    from shellbuckle.solve.newton import _fixes_gauge, _Newton

    mesh, energy, volume, V0 = shell(4, 500)
    X = mesh.X.copy()
    a, b = 0, int(np.argmax(np.linalg.norm(X - X[0], axis=1)))  # nearly antipodal
    c = int(np.argmin(np.linalg.norm(X - 0.5 * (X[a] + X[b]) - [0.0, 0.0, 0.3], axis=1)))
    pinned = np.array([3 * a, 3 * a + 1, 3 * a + 2, 3 * b, 3 * b + 1, 3 * c + 1])
    assert _fixes_gauge(X, pinned)
    nt = _Newton(energy, volume, 0.9 * V0, make_solver(), X, True, pinned,
                 np.random.default_rng(0))
    assert np.array_equal(nt.pinned, np.sort(pinned)) and not nt.gauge_lost(X)
    Y = X.copy()
    Y[c] = X[a] + 0.5 * (X[b] - X[a])  # c on the line ab
    assert np.linalg.cond(rigid_modes(Y)[pinned]) > 1e12
    assert nt.gauge_lost(Y)
    assert nt.set_gauge(Y) and _fixes_gauge(Y, nt.pinned) and not nt.gauge_lost(Y)
    assert len(nt.free) == X.size - 6 and nt.kkt.n == len(nt.free)
    # a minimization started on the lost gauge still converges to a KKT point
    res = newton(energy, volume, 0.97 * X, 0.9 * V0, pinned=pinned)
    assert res.success and res.inertia == 0
    assert_kkt(energy, volume, res, 0.9 * V0)


def test_a_poorly_conditioned_gauge_is_chosen_again_and_a_fresh_one_is_kept():
    """Pins on which the rigid modes are conditioned worse than GAUGE_MAX_COND (here c moved
    most of the way onto the line ab) are replaced by :func:`pinned_dofs` at the point, which
    the gauge test then accepts, also on elongated shells where even the best choice is
    conditioned worse than GAUGE_MAX_COND (no re-choosing at every factorization). A gamma =
    271 capsule whose run-long pins had drifted to cond 374 crawled 1035 iterations without
    converging; with pins chosen again it converged in 29 Newton iterations."""
    from shellbuckle.solve.linear import make_solver
    from shellbuckle.solve.newton import GAUGE_MAX_COND, _fixes_gauge, _Newton

    mesh, energy, volume, V0 = shell(4, 500)
    X = mesh.X.copy()
    a, b = 0, int(np.argmax(np.linalg.norm(X - X[0], axis=1)))
    c = int(np.argmin(np.linalg.norm(X - 0.5 * (X[a] + X[b]) - [0.0, 0.0, 0.3], axis=1)))
    pinned = np.array([3 * a, 3 * a + 1, 3 * a + 2, 3 * b, 3 * b + 1, 3 * c + 1])
    Y = X.copy()
    Y[c] = 0.1 * X[c] + 0.9 * (X[a] + 0.5 * (X[b] - X[a]))
    cond = np.linalg.cond(rigid_modes(Y)[pinned])
    assert GAUGE_MAX_COND < cond < 1e3  # accepted by the old threshold (1e3)
    assert not _fixes_gauge(Y, pinned)
    nt = _Newton(energy, volume, 0.9 * V0, make_solver(), Y, True, pinned,
                 np.random.default_rng(0))
    assert not np.array_equal(nt.pinned, np.sort(pinned)) and not nt.gauge_lost(Y)
    assert np.linalg.cond(rigid_modes(Y)[nt.pinned]) <= GAUGE_MAX_COND
    res = newton(energy, volume, 0.97 * Y, 0.9 * V0, pinned=pinned)
    assert res.success and res.inertia == 0
    assert_kkt(energy, volume, res, 0.9 * V0)
    for scale in ([1.0, 0.7, 0.4], [1.0, 0.05, 0.05]):  # the best choice is always accepted
        Z = X * scale
        assert _fixes_gauge(Z, pinned_dofs(Z))
    Z = X * [1.0, 0.05, 0.05]
    assert np.linalg.cond(rigid_modes(Z)[pinned_dofs(Z)]) > GAUGE_MAX_COND


def test_abandon_is_asked_after_the_relaxation_and_each_newton_step_only(monkeypatch):
    # oracle: the result without the hook. A hook that never objects changes nothing; one that
    # always objects stops right after the relaxation, or after the first Newton step without
    # one; a converged point is never offered to it. (The start is close to the relaxed state:
    # no smooth-start shortcut here, this is about the relaxation.)
    import importlib

    from shellbuckle.solve.newton import ABANDONED

    monkeypatch.setattr(importlib.import_module("shellbuckle.solve.newton"),
                        "RELAX_ROUGH_MIN_MOVE", 0.0)
    mesh, energy, volume, V0 = shell(3, 1000)
    shrunk = 0.95 ** (1 / 3) * mesh.X
    X0 = shrunk + 0.01 * np.random.default_rng(5).standard_normal(mesh.X.shape)
    asked = []

    def never(X):
        asked.append(X.copy())

    ref = newton(energy, volume, X0, 0.95 * V0, precondition_at=shrunk, history=True)
    res = newton(energy, volume, X0, 0.95 * V0, precondition_at=shrunk, history=True,
                 abandon=never)
    assert ref.success and np.array_equal(res.x, ref.x) and res.nit == ref.nit
    newton_steps = sum(h["step"] == "newton" for h in ref.history)
    assert 1 <= len(asked) <= newton_steps + 1
    assert all(not np.array_equal(X, ref.x) for X in asked)
    stop = newton(energy, volume, X0, 0.95 * V0, precondition_at=shrunk, history=True,
                  abandon=lambda X: "a test")
    assert not stop.success and stop.message == f"{ABANDONED}: a test"
    assert {h["step"] for h in stop.history} == {"relax"}
    first = newton(energy, volume, X0, 0.95 * V0, history=True, abandon=lambda X: "a test")
    assert not first.success and [h["step"] for h in first.history] == ["newton"]
    assert first.fun < energy.value(X0)
    done = newton(energy, volume, ref.x, 0.95 * V0, precondition_at=ref.x,
                  abandon=lambda X: "must not be asked")
    assert done.success


def test_a_relaxation_step_cut_short_asks_abandon_and_a_reason_stops_there(monkeypatch):
    # a fold made by the jiggle cuts every relaxation step to nothing: the hook is asked after
    # a run of such steps, not only once the relaxation has run its course. Oracle: the
    # number of relaxation steps taken before the hook objects (every step counts as cut here)
    import importlib

    from shellbuckle.solve.newton import ABANDONED

    newton_module = importlib.import_module("shellbuckle.solve.newton")  # not the function
    monkeypatch.setattr(newton_module, "RELAX_ROUGH_MIN_MOVE", 0.0)  # the relaxation, always

    mesh, energy, volume, V0 = shell(3, 1000)
    shrunk = 0.95 ** (1 / 3) * mesh.X
    X0 = shrunk + 0.01 * np.random.default_rng(5).standard_normal(mesh.X.shape)
    ref = newton(energy, volume, X0, 0.95 * V0, precondition_at=shrunk, history=True)
    n_relax = sum(h["step"] == "relax" for h in ref.history)
    first_ask = newton_module.RELAX_ASK_STEPS
    assert n_relax >= first_ask + 3
    monkeypatch.setattr(newton_module, "RELAX_ASK_ALPHA", 1.5)
    calls = []

    def third(X):
        calls.append(1)
        return "folded" if len(calls) >= 3 else None

    res = newton(energy, volume, X0, 0.95 * V0, precondition_at=shrunk, history=True,
                 abandon=third)
    assert not res.success and res.message == f"{ABANDONED}: folded"
    n_stop = first_ask + 2  # asked after steps first_ask, first_ask + 1, first_ask + 2
    assert [h["step"] for h in res.history] == ["relax"] * n_stop
    assert res.fun == pytest.approx(ref.history[n_stop - 1]["energy"], rel=1e-12)
    # a thorough test, when given, is not asked at the cut steps: the cheap one is (a freshly
    # jiggled surface may still pass through itself where the relaxation will remove it); it
    # is asked once the relaxation has stopped
    calls.clear()
    thorough = []
    cheap = newton(energy, volume, X0, 0.95 * V0, precondition_at=shrunk, history=True,
                   abandon=third, abandon_thorough=lambda X: thorough.append(1) or "folded")
    assert cheap.message == f"{ABANDONED}: folded" and np.array_equal(cheap.x, res.x)
    assert len(calls) == 3 and len(thorough) == 1
    assert [h["step"] for h in cheap.history] == ["relax"] * n_stop


@pytest.mark.parametrize("bending", ["juelicher", "evolver"])
def test_fused_value_and_gradient_are_the_separate_ones(bending):
    # oracle: the separate calls (Newton evaluates accepted points once, value and gradient
    # together, and must see the same numbers) and central differences of the value
    mesh = icosphere(3)
    energy = ShellEnergy.build(mesh, ShellParameters.from_gamma(500), bending=bending)
    X = 0.97 * mesh.X + 0.01 * np.random.default_rng(2).standard_normal(mesh.X.shape)
    E, g = energy.value_and_gradient(X)
    assert E == energy.value(X) and np.array_equal(g, energy.gradient(X))
    d = np.random.default_rng(3).standard_normal(X.shape)
    h = 1e-6
    fd = (energy.value(X + h * d) - energy.value(X - h * d)) / (2 * h)
    assert float(np.sum(g * d)) == pytest.approx(fd, rel=1e-6)


def _c0_cycle_problem():
    # the protocol's c0 cycle on a small dented shell: a minimum at c0 = 2/R, then c0 -> 0
    mesh, energy, volume, V0 = shell(4, 1000)
    X0 = 0.9 ** (1 / 3) * mesh.X
    X0 = X0 - 0.05 * np.exp(-20 * ((X0[:, 2:] - 0.97) ** 2)) * X0
    solver = CountingSolver(make_solver())
    first = newton(energy, volume, X0, 0.9 * V0, solver=solver, pinned=pinned_dofs(mesh.X))
    assert first.success and first.factorization is not None
    return mesh, energy.with_c0(0.0), volume, 0.9 * V0, solver, first


def test_warm_start_reaches_the_cold_minimum_with_the_held_factorization():
    # oracles: the cold minimization from the same point (relaxation + Newton), KKT
    # conditions, and the dense inertia; the warm one starts with quasi-Newton steps on the
    # factorization the solver still holds from the first minimization
    mesh, flat, volume, V, solver, first = _c0_cycle_problem()
    options = dict(solver=solver, pinned=pinned_dofs(mesh.X), precondition_at=first.x)
    n0 = solver.n_factor
    warm = newton(flat, volume, first.x, V, warm_start=first.factorization, history=True,
                  **options)
    n_warm = solver.n_factor - n0
    cold = newton(flat, volume, first.x, V, history=True, **options)
    n_cold = solver.n_factor - n0 - n_warm
    assert warm.success and cold.success and warm.inertia == 0
    assert_kkt(flat, volume, warm, V)
    assert tangent_inertia_dense(flat, volume, warm.x) == 0
    assert warm.fun == pytest.approx(cold.fun, rel=1e-12)
    assert warm.pressure == pytest.approx(cold.pressure, rel=1e-8)
    assert np.abs(warm.x - cold.x).max() <= 1e-6
    # the cold start lies at the relaxed state itself: quasi-Newton steps on the Hessian
    # factored there ("Smooth starts"), one factorization more than with the held one
    assert warm.history[0]["step"] == "quasi-newton" and cold.history[0]["step"] == "quasi-newton"
    assert n_warm < n_cold


@pytest.mark.parametrize("warm", [False, True])
def test_an_uncertified_minimization_ends_at_the_certified_minimum_with_fewer_factorizations(warm):
    # the c0 = 0 stage of the protocol's cycle. Oracles: the same minimization certified
    # (energy, point), KKT conditions and the dense tangent inertia at the uncertified end
    mesh, flat, volume, V, solver, first = _c0_cycle_problem()
    runs = []
    for certify in (True, False):
        n0 = dict(solver.counts)
        start = dict(warm_start=first.factorization) if warm else dict(precondition_at=first.x)
        res = newton(flat, volume, first.x, V, solver=solver, pinned=pinned_dofs(mesh.X),
                     certify=certify, **start)
        runs.append((res, {k: solver.counts[k] - n0[k] for k in n0}))
        assert res.success
    (certified, n_certified), (uncertified, n_uncertified) = runs
    assert certified.inertia == 0 and uncertified.inertia is None
    assert_kkt(flat, volume, uncertified, V)
    assert tangent_inertia_dense(flat, volume, uncertified.x) == 0
    assert uncertified.fun == pytest.approx(certified.fun, rel=1e-12)
    assert np.abs(uncertified.x - certified.x).max() <= 1e-6
    assert certified.certificate in ("single", "double") and uncertified.certificate is None
    assert n_uncertified["double"] + n_uncertified["single"] < \
        n_certified["double"] + n_certified["single"]


def test_a_warm_start_at_a_certified_minimum_of_the_same_energy_certifies_it():
    # the protocol's return to c0 = 2/R: the factorization at the minimum before the cycle
    # (two minimizations back; PARDISO still holds it) serves the first steps and, where the
    # shell returns to that minimum, certifies it. Oracles: KKT, the dense tangent inertia,
    # the first minimum's energy; a token of another energy or volume never certifies
    mesh, energy, volume, V0 = shell(4, 1000)
    X0 = 0.9 ** (1 / 3) * mesh.X
    X0 = X0 - 0.05 * np.exp(-20 * ((X0[:, 2:] - 0.97) ** 2)) * X0
    solver = CountingSolver(make_solver())
    options = dict(solver=solver, pinned=pinned_dofs(mesh.X))
    first = newton(energy, volume, X0, 0.9 * V0, **options)
    tok = first.factorization
    assert first.success and tok.certifies(energy, 0.9 * V0)
    assert not tok.certifies(energy.with_c0(2.0), 0.9 * V0)  # another object: not trusted
    assert not tok.certifies(energy, 0.8 * V0)
    # a point near the minimum, as the flat minimum of the cycle is
    d = np.random.default_rng(0).standard_normal(X0.shape)
    start = first.x + 1e-7 * d
    flat = newton(energy.with_c0(0.0), volume, first.x, 0.9 * V0, warm_start=tok, **options)
    assert flat.success and flat.factorization is not tok  # factored in between
    n_double, n_single = solver.counts["double"], solver.counts["single"]
    back = newton(energy, volume, start, 0.9 * V0, warm_start=[None, tok], history=True,
                  **options)
    assert back.success and back.inertia == 0 and back.history[0]["step"] == "quasi-newton"
    assert back.fun == pytest.approx(first.fun, rel=1e-12)
    assert_kkt(energy, volume, back, 0.9 * V0)
    assert tangent_inertia_dense(energy, volume, back.x) == 0
    if _load_mkl() is not None:  # PARDISO keeps two factorizations: no new one at all
        assert solver.counts["double"] == n_double and solver.counts["single"] == n_single
        assert back.factorization is tok


def test_a_smooth_start_steps_on_the_hessian_at_the_relaxed_state(monkeypatch):
    # the protocol without a jiggle: the next volume step starts at the last minimum, whose
    # certifying factorization the solver still holds. Oracles: KKT conditions, the dense
    # tangent inertia, the minimum reached through the relaxation; the same bits without the
    # held factorization (a resumed run), which then factors the same matrix once more
    import importlib

    newton_module = importlib.import_module("shellbuckle.solve.newton")
    mesh, energy, volume, V0 = shell(4, 1000)
    solver = CountingSolver(make_solver())
    options = dict(solver=solver, pinned=pinned_dofs(mesh.X))
    first = newton(energy, volume, 0.97 ** (1 / 3) * mesh.X, 0.97 * V0, inertia_step=0.0,
                   **options)  # certified by a factorization at its very end point
    assert first.success and np.array_equal(first.factorization.X, first.x)
    runs, counts = {}, {}
    for name, token in (("held", first.factorization), ("fresh", None)):
        n0 = dict(solver.counts)
        runs[name] = newton(energy, volume, first.x, 0.94 * V0, precondition_at=first.x,
                            precondition_token=token, history=True, **options)
        counts[name] = {k: solver.counts[k] - n0[k] for k in n0}
    monkeypatch.setattr(newton_module, "RELAX_ROUGH_MIN_MOVE", 0.0)  # no smooth start
    n0 = dict(solver.counts)
    relaxed = newton(energy, volume, first.x, 0.94 * V0, precondition_at=first.x, history=True,
                     **options)
    n_relaxed = sum(solver.counts[k] - n0[k] for k in ("double", "single"))
    held, fresh = runs["held"], runs["fresh"]
    assert held.success and held.inertia == 0
    assert_kkt(energy, volume, held, 0.94 * V0)
    assert tangent_inertia_dense(energy, volume, held.x) == 0
    assert np.array_equal(held.x, fresh.x) and held.nit == fresh.nit
    n_fresh, n_held = (counts[k]["double"] + counts[k]["single"] for k in ("fresh", "held"))
    assert n_fresh == n_held + 1
    assert counts["held"]["double"] + counts["held"]["single"] < n_relaxed
    assert held.history[0]["step"] == "quasi-newton" and relaxed.history[0]["step"] == "relax"
    assert held.fun == pytest.approx(relaxed.fun, rel=1e-12)
    assert np.abs(held.x - relaxed.x).max() <= 1e-6


def test_a_stale_warm_start_is_ignored():
    # once the solver no longer holds the factorization (PARDISO keeps the last two of each
    # precision; each minimization below factors at least once, its certificate) the token
    # no longer describes it: the minimization must then be exactly the cold one
    mesh, flat, volume, V, solver, first = _c0_cycle_problem()
    options = dict(solver=solver, pinned=pinned_dofs(mesh.X), precondition_at=first.x)
    newton(flat, volume, first.x, V, **options)
    n_factor = solver.n_factor
    cold = newton(flat, volume, first.x, V, **options)  # first's token is stale now
    assert solver.n_factor > n_factor
    again = newton(flat, volume, first.x, V, warm_start=first.factorization, **options)
    assert np.array_equal(again.x, cold.x) and again.nit == cold.nit
    # a valid token brings its gauge: asked for another one, the minimization keeps the held
    # factorization's pins (and so its KKT pattern) while they fix the rigid motions ...
    i, j, k = np.argmax(first.x, axis=0)  # the tangent dofs at the three extreme vertices
    other = np.sort([3 * i + 1, 3 * i + 2, 3 * j, 3 * j + 2, 3 * k, 3 * k + 1])
    assert _fixes_gauge(first.x, other) and not np.array_equal(other, pinned_dofs(mesh.X))
    kept = newton(flat, volume, first.x, V, warm_start=again.factorization, solver=solver,
                  pinned=other, precondition_at=first.x, history=True)
    assert kept.history[0]["step"] == "quasi-newton"
    assert kept.fun == pytest.approx(cold.fun, rel=1e-12)
    # ... and a token whose pins do not fix them there (two whole vertices leave the rotation
    # about their axis free) is not used with another gauge
    token = kept.factorization
    token.pinned = np.arange(6)
    assert not _fixes_gauge(first.x, token.pinned)
    n_factor = solver.n_factor
    res = newton(flat, volume, first.x, V, warm_start=token, solver=solver, pinned=other,
                 precondition_at=first.x, history=True)
    assert solver.n_factor > n_factor  # the smooth start's own factorization
    assert res.fun == pytest.approx(cold.fun, rel=1e-12)


def test_a_warm_start_token_keeps_no_solver_alive():
    # sweeps run many runs in one worker: a kept result must not hold on to its run's
    # factorization (tens of MB each)
    import gc
    import weakref

    mesh, energy, volume, V0 = shell(3, 1000)
    solver = make_solver()
    res = newton(energy, volume, 0.95 ** (1 / 3) * mesh.X, 0.95 * V0, solver=solver)
    assert res.factorization is not None
    alive = weakref.ref(solver)
    del solver
    gc.collect()
    assert alive() is None


def test_levenberg_marquardt_shift_follows_the_model_of_the_step():
    # oracle: the trust-region update (Nocedal & Wright §4.1) and the relation that defines the
    # shift after a cut step, (q + mu) / (q + mu') = alpha along the step's own direction
    from shellbuckle.solve.newton import _damping_next

    q, mu = 10.0, 2.0
    assert _damping_next(mu, q, "newton", 1.0, 0.9) == pytest.approx(mu / 4)  # good model
    assert _damping_next(mu, q, "newton", 1.0, 0.5) == mu  # fair model
    for alpha in (0.5, 0.1):  # cut: the shift that gives that length
        new = _damping_next(mu, q, "newton", alpha, 0.9)
        assert (q + mu) / (q + new) == pytest.approx(alpha)
    assert _damping_next(1e-3 * q, q, "newton", 1.0, 0.9) == 0.0  # negligible: pure Newton
    assert _damping_next(mu, q, "quasi-newton", 0.1, np.nan) == mu  # no model: unchanged
    # below the energy's noise (no measurable decrease, rho NaN), near a minimum: a full step
    # counts as a good model, so the shift is released and the tail converges quadratically
    # (left as it was, it kept a minimization at gamma = 20995 converging linearly: 175
    # iterations and 5 double-precision factorizations against 154 and 1 to the same minimum);
    # a cut step says nothing about the model there
    assert _damping_next(mu, q, "newton", 1.0, np.nan) == pytest.approx(mu / 4)
    assert _damping_next(mu, q, "newton", 0.5, np.nan) == mu


def test_the_thorough_abandon_test_is_asked_after_the_relaxation_and_where_steps_stall(
        monkeypatch):
    # oracles: the minimization without the hook (a run whose steps all progress asks it only
    # after its relaxation, in place of the cheap test), and, with the progress test made to
    # report a jam after the second Newton step, the point the hook is shown is the one the
    # minimization stops at with the hook's reason
    import importlib

    from shellbuckle.solve.newton import ABANDONED

    newton_module = importlib.import_module("shellbuckle.solve.newton")  # not the function
    monkeypatch.setattr(newton_module, "RELAX_ROUGH_MIN_MOVE", 0.0)  # the relaxation, always
    mesh, energy, volume, V0 = shell(3, 1000)
    X0 = 0.95 ** (1 / 3) * mesh.X + 0.01 * np.random.default_rng(5).standard_normal(mesh.X.shape)
    asked = []

    def hook(reason):
        return lambda X: asked.append(X.copy()) or reason

    ref = newton(energy, volume, X0, 0.95 * V0)
    res = newton(energy, volume, X0, 0.95 * V0, abandon_thorough=hook(None))
    assert ref.success and np.array_equal(res.x, ref.x) and res.nit == ref.nit and not asked
    shrunk = 0.95 ** (1 / 3) * mesh.X
    cheap = []
    relaxed = newton(energy, volume, X0, 0.95 * V0, precondition_at=shrunk, history=True,
                     abandon=lambda X: cheap.append(X.copy()), abandon_thorough=hook(None))
    n_relax = sum(h["step"] == "relax" for h in relaxed.history)
    n_newton = sum(h["step"] == "newton" for h in relaxed.history)
    assert relaxed.success and n_relax > 0 and len(asked) == 1 and len(cheap) <= n_newton
    assert not any(np.array_equal(asked[0], X) for X in cheap)
    asked.clear()
    jammed = newton_module._jammed

    def jam_after_two(trail, tol_energy, steps=newton_module.JAM_STEPS):
        if steps == newton_module.SINGLE_JAM_STEPS:
            return len(trail) >= 2
        return jammed(trail, tol_energy, steps)

    monkeypatch.setattr(newton_module, "_jammed", jam_after_two)
    stop = newton(energy, volume, X0, 0.95 * V0, abandon_thorough=hook("stuck"))
    assert not stop.success and stop.message == f"{ABANDONED}: stuck"
    assert len(asked) == 1 and np.array_equal(asked[0], stop.x)
    assert stop.fun == energy.value(stop.x) < energy.value(X0)


def _dense_tangent_hessian_min(energy, volume, X, pinned):
    """What the KKT matrix of Newton's method with the dofs ``pinned`` factors, densely: the
    smallest eigenvalue of ``K = Hess E - lam Hess V`` on the free dofs orthogonal to
    ``grad V``, and the mean absolute diagonal of that KKT matrix (``K`` on the free dofs and
    the constraint's zero)."""
    gE, gV = energy.gradient(X), volume.gradient(X)
    lam, _ = projected_gradient(gE, gV)
    free = np.setdiff1d(np.arange(X.size), pinned)
    K = (energy.hessian(X) - lam * volume.hessian(X)).toarray()[np.ix_(free, free)]
    Z = scipy.linalg.null_space(gV.ravel()[free][None, :])
    return (float(np.linalg.eigvalsh(Z.T @ K @ Z)[0]),
            float(np.abs(np.diag(K)).sum() / (free.size + 1)))


@pytest.mark.skipif(_load_mkl() is None, reason="single precision needs PARDISO (Intel MKL)")
def test_a_single_precision_certificate_reaches_the_double_precision_minimum():
    # oracles: the same minimization certified in double precision (energy, pressure,
    # point), KKT conditions, and the dense tangent Hessian, whose smallest eigenvalue lies
    # above the certificate's shift (what inertia 0 of the shifted factorization claims)
    from shellbuckle.solve.newton import CERTIFY_SHIFT

    mesh, energy, volume, V0 = shell(4, 1000)
    pinned = pinned_dofs(mesh.X)
    runs = {}
    for single in (True, False):
        solver = CountingSolver(make_solver())
        res = newton(energy, volume, 0.95 ** (1 / 3) * mesh.X, 0.95 * V0, solver=solver,
                     pinned=pinned, certify_single=single)
        runs[single] = (res, dict(solver.counts))
    (one, n_one), (two, n_two) = runs[True], runs[False]
    assert one.success and two.success and one.inertia == two.inertia == 0
    assert one.certificate == "single" and two.certificate == "double"
    assert n_one["double"] == 0 and n_two["double"] >= 1
    assert one.fun == pytest.approx(two.fun, rel=1e-12)
    assert one.pressure == pytest.approx(two.pressure, rel=1e-8)
    assert np.abs(one.x - two.x).max() <= 1e-6
    assert_kkt(energy, volume, one, 0.95 * V0)
    lam_min, scale = _dense_tangent_hessian_min(energy, volume, one.x, pinned)
    assert lam_min > CERTIFY_SHIFT * scale
    # the certificate is the factorization the solver holds, and a later minimization may
    # start from it (warm start of the protocol's c0 cycle)
    tok = one.factorization
    assert tok is not None and tok.approximate and tok.certifies(energy, 0.95 * V0)


@pytest.mark.skipif(_load_mkl() is None, reason="single precision needs PARDISO (Intel MKL)")
def test_a_shift_above_the_smallest_eigenvalue_falls_back_to_double_precision(monkeypatch):
    # oracle: the dense tangent Hessian; where its smallest eigenvalue lies below the shift
    # the single-precision try shows a negative eigenvalue, and the unshifted double one
    # certifies the minimum, tried once per minimization
    import importlib

    newton_module = importlib.import_module("shellbuckle.solve.newton")
    mesh, energy, volume, V0 = shell(4, 1000)
    X0, V, pinned = 0.95 ** (1 / 3) * mesh.X, 0.95 * V0, pinned_dofs(mesh.X)
    reference = newton(energy, volume, X0, V, pinned=pinned, certify_single=False)
    lam_min, scale = _dense_tangent_hessian_min(energy, volume, reference.x, pinned)
    monkeypatch.setattr(newton_module, "CERTIFY_SHIFT", 2.0 * lam_min / scale)
    tries = []
    certify = newton_module._Newton.certify_single
    monkeypatch.setattr(newton_module._Newton, "certify_single",
                        lambda nt: tries.append(certify(nt)) or tries[-1])
    solver = CountingSolver(make_solver())
    res = newton(energy, volume, X0, V, solver=solver, pinned=pinned)
    assert res.success and res.inertia == 0 and res.certificate == "double"
    assert tries == [False] and solver.counts["double"] >= 1
    assert res.fun == pytest.approx(reference.fun, rel=1e-12)
    assert np.abs(res.x - reference.x).max() <= 1e-6
    monkeypatch.setattr(newton_module, "CERTIFY_SHIFT", 0.5 * lam_min / scale)
    res = newton(energy, volume, X0, V, pinned=pinned)
    assert res.success and res.certificate == "single" and tries[-1] is True


def test_solvers_without_single_precision_certify_in_double():
    # QDLDL and SuperLU ignore approximate=True: a shifted "certificate" would save nothing,
    # so the minimum is certified as before. Oracle: the dense tangent inertia
    mesh, energy, volume, V0 = shell(3, 1000)
    for name in ("qdldl", "superlu"):
        solver = CountingSolver(name)
        res = newton(energy, volume, 0.95 ** (1 / 3) * mesh.X, 0.95 * V0, solver=solver)
        assert res.success and res.certificate == "double"
        assert tangent_inertia_dense(energy, volume, res.x) == 0
