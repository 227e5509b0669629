"""Newton at fixed volume (:mod:`shellbuckle.solve.newton`): constraint, stationarity,
pressure = -dE/dV, monotonicity, saddles, precision, certificates and the ``abandon`` tests.

Oracles: the KKT conditions recomputed from the energy terms; central differences of the
minimum energy along a sequence of target volumes; the exact uniformly shrunk icosahedron
(all twelve vertices equivalent, so uniform shrinking is an exact constrained equilibrium);
dense eigenvalues of the constrained Hessian for the inertia. The parts have their own tests:
test_solve_gauge, test_solve_kkt, test_solve_damping, test_solve_relax, test_solve_workspace.
"""

import numpy as np
import pytest
import scipy.linalg

from shellbuckle.energies.total import ShellEnergy
from shellbuckle.energies.volume import Volume
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.solve import NewtonOptions, Workspace, make_solver, minimize, newton
from shellbuckle.solve.gauge import pinned_dofs, rigid_modes
from shellbuckle.solve.linear import CountingSolver, _load_mkl
from shellbuckle.solve.linesearch import (ENERGY_NOISE, ENERGY_ROUNDOFF, max_displacement,
                                          projected_gradient)
from shellbuckle.solve.newton import ABANDONED, AT_FLOOR, AT_RESOLUTION
from shellbuckle.solve.system import gradient_floor
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


def tangent_problem_dense(energy, volume, X):
    """``(K, Z, r)``: the dense Hessian of the Lagrangian Hess E - lam Hess V, an orthonormal
    basis Z of {grad V, rigid modes}^perp and the projected gradient r (flat)."""
    gE, gV = energy.gradient(X), volume.gradient(X)
    lam, r = projected_gradient(gE, gV)
    K = (energy.hessian(X) - lam * volume.hessian(X)).toarray()
    C = np.column_stack([gV.ravel(), rigid_modes(X)])
    return K, scipy.linalg.null_space(C.T), r.ravel()


def tangent_inertia_dense(energy, volume, X):
    """Negative eigenvalues of Hess E - lam Hess V on {grad V, rigid modes}^perp (dense)."""
    K, Z, _ = tangent_problem_dense(energy, volume, X)
    ev = np.linalg.eigvalsh(Z.T @ K @ Z)
    return int((ev < -1e-8 * np.abs(ev).max()).sum())


def _jiggled_shell(sigma=0.3, seed=3):
    mesh, energy, volume, V0 = shell(4, 1000)
    shrunk = 0.95 ** (1 / 3) * mesh.X
    edge = np.linalg.norm(mesh.X[mesh.faces[:, 0]] - mesh.X[mesh.faces[:, 1]], axis=1).mean()
    X0 = shrunk + sigma * edge * np.random.default_rng(seed).standard_normal(mesh.X.shape)
    return mesh, energy, volume, 0.95 * V0, shrunk, X0


def _c0_cycle_problem():
    # the protocol's c0 cycle on a small dented shell: a minimum at c0 = 2/R, then c0 -> 0
    mesh, energy, volume, V0 = shell(4, 1000)
    X0 = 0.9 ** (1 / 3) * mesh.X
    X0 = X0 - 0.05 * np.exp(-20 * ((X0[:, 2:] - 0.97) ** 2)) * X0
    workspace = Workspace(CountingSolver(make_solver()))
    first = newton(energy, volume, X0, 0.9 * V0, workspace=workspace, pinned=pinned_dofs(mesh.X))
    assert first.success and first.factorization is not None
    return mesh, energy.with_c0(0.0), volume, 0.9 * V0, workspace, first


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


def test_bad_problem_is_refused():
    mesh, energy, volume, V0 = shell(1, 100)
    with pytest.raises(ValueError, match="V_target must be a positive finite volume"):
        newton(energy, volume, mesh.X, -1.0)
    with pytest.raises(ValueError, match=r"X0 must be a \(V, 3\) array"):
        newton(energy, volume, mesh.X[:, :2], V0)
    with pytest.raises(ValueError, match="unknown method"):
        minimize(energy, volume, mesh.X, V0, method="bfgs")
    with pytest.raises(ValueError, match=r"unknown Newton option\(s\) \['max_iters'\]"):
        newton(energy, volume, mesh.X, V0, max_iters=3)
    with pytest.raises(ValueError, match="Newton option max_quasi must be an integer >= 0"):
        newton(energy, volume, mesh.X, V0, max_quasi=-1)
    with pytest.raises(ValueError, match="either a workspace or a solver"):
        newton(energy, volume, mesh.X, V0, workspace=Workspace("qdldl"), solver="qdldl")


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


def test_newton_is_reproducible():
    mesh, energy, volume, V0 = shell(3, 1000)
    X0 = 0.9 ** (1 / 3) * mesh.X + 0.01 * np.random.default_rng(9).standard_normal(mesh.X.shape)
    a = newton(energy, volume, X0, 0.9 * V0)
    b = newton(energy, volume, X0, 0.9 * V0)
    assert np.array_equal(a.x, b.x) and a.fun == b.fun and a.nit == b.nit


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


def test_abandon_is_asked_after_the_relaxation_and_each_newton_step_only():
    # oracle: the result without the hook. A hook that never objects changes nothing; one that
    # always objects stops right after the relaxation, or after the first Newton step without
    # one; a converged point is never offered to it. (The start is close to the relaxed state:
    # no smooth-start shortcut here, this is about the relaxation.)
    options = NewtonOptions(relax_rough_min_move=0.0, history=True)
    mesh, energy, volume, V0 = shell(3, 1000)
    shrunk = 0.95 ** (1 / 3) * mesh.X
    X0 = shrunk + 0.01 * np.random.default_rng(5).standard_normal(mesh.X.shape)
    asked = []

    def never(X):
        asked.append(X.copy())

    ref = newton(energy, volume, X0, 0.95 * V0, options, precondition_at=shrunk)
    res = newton(energy, volume, X0, 0.95 * V0, options, precondition_at=shrunk, abandon=never)
    assert ref.success and np.array_equal(res.x, ref.x) and res.nit == ref.nit
    newton_steps = sum(h["step"] == "newton" for h in ref.history)
    assert 1 <= len(asked) <= newton_steps + 1
    assert all(not np.array_equal(X, ref.x) for X in asked)
    stop = newton(energy, volume, X0, 0.95 * V0, options, precondition_at=shrunk,
                  abandon=lambda X: "a test")
    assert not stop.success and stop.message == f"{ABANDONED}: a test"
    assert {h["step"] for h in stop.history} == {"relax"}
    first = newton(energy, volume, X0, 0.95 * V0, options, abandon=lambda X: "a test")
    assert not first.success and [h["step"] for h in first.history] == ["newton"]
    assert first.fun < energy.value(X0)
    done = newton(energy, volume, ref.x, 0.95 * V0, options, precondition_at=ref.x,
                  abandon=lambda X: "must not be asked")
    assert done.success


def test_the_thorough_abandon_test_is_asked_after_the_relaxation_and_where_steps_stall():
    # oracles: the minimization without the hook (a run whose steps all progress asks it only
    # after its relaxation, in place of the cheap test), and, with every Newton step counted
    # as one without progress (single_jam_steps = 0), the point the hook is shown is the one
    # the minimization stops at with the hook's reason
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
                     relax_rough_min_move=0.0,  # the relaxation, always
                     abandon=lambda X: cheap.append(X.copy()), abandon_thorough=hook(None))
    n_relax = sum(h["step"] == "relax" for h in relaxed.history)
    n_newton = sum(h["step"] == "newton" for h in relaxed.history)
    assert relaxed.success and n_relax > 0 and len(asked) == 1 and len(cheap) <= n_newton
    assert not any(np.array_equal(asked[0], X) for X in cheap)
    asked.clear()
    stop = newton(energy, volume, X0, 0.95 * V0, abandon_thorough=hook("stuck"),
                  single_jam_steps=0, history=True)
    assert not stop.success and stop.message == f"{ABANDONED}: stuck"
    assert len(asked) == 1 and np.array_equal(asked[0], stop.x)
    assert [h["step"] for h in stop.history] == []  # the first Newton step's point
    assert stop.fun == energy.value(stop.x) < energy.value(X0)


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


@pytest.mark.parametrize("warm", [False, pytest.param(True, marks=pytest.mark.skipif(
    _load_mkl() is None, reason="a warm start across a certificate needs PARDISO (Intel MKL), "
    "which holds two factorizations per precision"))])
def test_an_uncertified_minimization_ends_at_the_certified_minimum_with_fewer_factorizations(warm):
    # the c0 = 0 stage of the protocol's cycle. Oracles: the same minimization certified
    # (energy, point), KKT conditions and the dense tangent inertia at the uncertified end
    mesh, flat, volume, V, workspace, first = _c0_cycle_problem()
    solver = workspace.solver
    runs = []
    for certify in (True, False):
        n0 = dict(solver.counts)
        start = dict(warm_start=first.factorization) if warm else dict(precondition_at=first.x)
        res = newton(flat, volume, first.x, V, workspace=workspace, pinned=pinned_dofs(mesh.X),
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


@pytest.mark.skipif(_load_mkl() is None, reason="single precision needs PARDISO (Intel MKL)")
def test_a_single_precision_certificate_reaches_the_double_precision_minimum():
    # oracles: the same minimization certified in double precision (energy, pressure,
    # point), KKT conditions, and the dense tangent Hessian, whose smallest eigenvalue lies
    # above the certificate's shift (what inertia 0 of the shifted factorization claims)
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
    assert lam_min > NewtonOptions().certify_shift * scale
    # the certificate is the factorization the solver holds, and a later minimization may
    # start from it (warm start of the protocol's c0 cycle)
    tok = one.factorization
    assert tok is not None and tok.approximate and tok.certifies(energy, 0.95 * V0)


@pytest.mark.skipif(_load_mkl() is None, reason="single precision needs PARDISO (Intel MKL)")
def test_a_shift_above_the_smallest_eigenvalue_falls_back_to_double_precision():
    # oracle: the dense tangent Hessian; where its smallest eigenvalue lies below the shift
    # the single-precision try shows a negative eigenvalue, and the unshifted double one
    # certifies the minimum: the minimization without the try, to the last bit, with one
    # single-precision factorization more (one try per minimization)
    mesh, energy, volume, V0 = shell(4, 1000)
    X0, V, pinned = 0.95 ** (1 / 3) * mesh.X, 0.95 * V0, pinned_dofs(mesh.X)
    runs = {}
    for name, options in (("reference", dict(certify_single=False)), ("above", {})):
        if name == "above":
            lam_min, scale = _dense_tangent_hessian_min(energy, volume, runs["reference"][0].x,
                                                        pinned)
            options = dict(certify_shift=2.0 * lam_min / scale)
        solver = CountingSolver(make_solver())
        runs[name] = (newton(energy, volume, X0, V, solver=solver, pinned=pinned, **options),
                      dict(solver.counts))
    (reference, n_reference), (res, n_res) = runs["reference"], runs["above"]
    assert res.success and res.inertia == 0 and res.certificate == "double"
    assert np.array_equal(res.x, reference.x) and res.nit == reference.nit
    assert n_res["single"] == n_reference["single"] + 1
    assert n_res["double"] == n_reference["double"] >= 1
    res = newton(energy, volume, X0, V, pinned=pinned, certify_shift=0.5 * lam_min / scale)
    assert res.success and res.certificate == "single"
    assert res.fun == pytest.approx(reference.fun, rel=1e-12)
    assert np.abs(res.x - reference.x).max() <= 1e-6


def test_solvers_without_single_precision_certify_in_double():
    # QDLDL and SuperLU ignore approximate=True: a shifted "certificate" would save nothing,
    # so the minimum is certified as before. Oracle: the dense tangent inertia
    mesh, energy, volume, V0 = shell(3, 1000)
    for name in ("qdldl", "superlu"):
        solver = CountingSolver(name)
        res = newton(energy, volume, 0.95 ** (1 / 3) * mesh.X, 0.95 * V0, solver=solver)
        assert res.success and res.certificate == "double"
        assert tangent_inertia_dense(energy, volume, res.x) == 0


def test_keywords_are_the_options_of_the_same_name():
    # a keyword replaces that field of the options: the same minimization as with the
    # options value, to the last bit
    mesh, energy, volume, V0 = shell(3, 1000)
    X0 = 0.9 ** (1 / 3) * mesh.X + 0.01 * np.random.default_rng(9).standard_normal(mesh.X.shape)
    given = NewtonOptions(max_quasi=5, memory=4, tol_grad=1e-9, history=True)
    a = newton(energy, volume, X0, 0.9 * V0, given)
    b = newton(energy, volume, X0, 0.9 * V0, max_quasi=5, memory=4, tol_grad=1e-9, history=True)
    c = newton(energy, volume, X0, 0.9 * V0, NewtonOptions(max_quasi=5), memory=4,
               tol_grad=1e-9, history=True)
    for other in (b, c):
        assert np.array_equal(a.x, other.x) and a.nit == other.nit and a.fun == other.fun
        assert [h["step"] for h in a.history] == [h["step"] for h in other.history]


def floor_problem():
    """``(energy, volume, X0, V, plain)``: a start near the minimum of a shell at 97 % of its
    volume, and that minimum by the plain gradient test at tol_grad = 1e-12."""
    mesh, energy, volume, V0 = shell(4, 2333)
    V = 0.97 * V0
    X0 = 0.97 ** (1 / 3) * mesh.X + 1e-3 * np.random.default_rng(2).standard_normal(mesh.X.shape)
    return energy, volume, X0, V, newton(energy, volume, X0, V, tol_grad=1e-12)


def test_a_gradient_test_below_the_round_off_floor_ends_on_the_step_test():
    # tol_grad = atol_grad = 0 asks for a gradient the coordinates cannot resolve (the floor
    # of 160k-vertex meshes at the protocol's tolerance); the floor test is off. Oracles: the
    # minimum of the plain gradient test (energy, positions to the coordinates' precision),
    # the exact Newton step at the end (below tol_step of |X|), and the same run without the
    # step test, which stalls
    energy, volume, X0, V, plain = floor_problem()
    floor = newton(energy, volume, X0, V, tol_grad=0.0, atol_grad=0.0, tol_floor=0.0,
                   max_iter=40)
    assert plain.success and floor.success and floor.message == AT_RESOLUTION
    assert floor.inertia == 0 and floor.certificate == "double"
    # not asked to show the inertia: none reported
    quick = newton(energy, volume, X0, V, tol_grad=0.0, atol_grad=0.0, tol_floor=0.0,
                   max_iter=40, certify=False)
    assert quick.message == AT_RESOLUTION and quick.inertia is None and quick.certificate is None
    assert quick.fun == pytest.approx(plain.fun, rel=1e-13)
    assert floor.fun == pytest.approx(plain.fun, rel=1e-13)
    assert np.abs(floor.x - plain.x).max() <= 1e-12
    assert floor.grad_norm > 0.0
    # the Newton step at the end, from a dense solve of the KKT system (rigid modes fixed)
    K, Z, r = tangent_problem_dense(energy, volume, floor.x)
    s = Z @ np.linalg.solve(Z.T @ K @ Z, -Z.T @ r)
    assert max_displacement(s.reshape(-1, 3)) <= 1e-15 * np.abs(floor.x).max() * 4
    stalled = newton(energy, volume, X0, V, tol_grad=0.0, atol_grad=0.0, tol_step=0.0,
                     tol_floor=0.0, max_iter=40)
    assert not stalled.success


@pytest.mark.parametrize("n, gamma", [(3, 1000), (5, 15163)])
def test_the_gradient_floor_is_the_hessian_on_one_unit_in_the_last_place(n, gamma):
    # the floor is the change of r under a one-ulp change of every coordinate. Oracle: the
    # first-order change K d, from the assembled Hessian of the Lagrangian applied to the same
    # sign patterns
    mesh, energy, volume, V0 = shell(n, gamma)
    X = 0.95 ** (1 / 3) * mesh.X + 1e-3 * np.random.default_rng(3).standard_normal(mesh.X.shape)
    gE, gV = energy.gradient(X), volume.gradient(X)
    lam, r = projected_gradient(gE, gV)
    K = energy.hessian(X) - lam * volume.hessian(X)
    rng = np.random.default_rng(7)
    Kd = [np.linalg.norm(K @ (np.where(rng.random(X.shape) < 0.5, -1.0, 1.0)
                              * np.spacing(X)).ravel()) for _ in range(2)]
    floor = gradient_floor(energy, volume, X, r, seed=7)
    assert floor == pytest.approx(min(Kd), rel=0.05)
    # reproducible, and far below |r| away from a minimum
    assert gradient_floor(energy, volume, X, r, seed=7) == floor
    assert floor < 1e-6 * np.linalg.norm(r)


def test_a_gradient_test_below_the_round_off_floor_ends_on_the_floor_test():
    # as above, with the floor test on and the step test off. Oracles: the minimum of the
    # plain gradient test; |r| at the end within the floor measured there with other sign
    # patterns; no more steps than the step test takes to the same minimum
    energy, volume, X0, V, plain = floor_problem()
    floor = newton(energy, volume, X0, V, tol_grad=0.0, atol_grad=0.0, tol_step=0.0,
                   max_iter=40)
    assert floor.success and floor.message == AT_FLOOR
    assert floor.inertia == 0 and floor.certificate in ("single", "double")
    assert tangent_inertia_dense(energy, volume, floor.x) == 0
    assert floor.fun == pytest.approx(plain.fun, rel=1e-13)
    assert np.abs(floor.x - plain.x).max() <= 1e-12
    _, r = projected_gradient(energy.gradient(floor.x), volume.gradient(floor.x))
    assert 0.0 < floor.grad_norm <= 1.2 * gradient_floor(energy, volume, floor.x, r, seed=11)
    step = newton(energy, volume, X0, V, tol_grad=0.0, atol_grad=0.0, tol_floor=0.0,
                  max_iter=40)
    assert step.message == AT_RESOLUTION and floor.nit <= step.nit
    # a tol_floor below the rounding of a minimum (|r| ~ 0.29 floor) is never met: the step
    # test ends it
    strict = newton(energy, volume, X0, V, tol_grad=0.0, atol_grad=0.0, tol_floor=1e-3,
                    max_iter=40)
    assert strict.message == AT_RESOLUTION
