"""The factorization workspace (:mod:`shellbuckle.solve.workspace`): warm starts from the
factorizations it holds, and nothing shared outside it.

Oracles: the cold minimization from the same point (KKT conditions, dense tangent inertia),
the same calls in another workspace to the last bit, and the solver's count of
factorizations.
"""

import numpy as np
import pytest

from shellbuckle.solve import Workspace, make_solver, newton
from shellbuckle.solve.gauge import fixes_gauge, pinned_dofs
from shellbuckle.solve.linear import CountingSolver, _load_mkl
from test_solve_newton import _c0_cycle_problem, assert_kkt, shell, tangent_inertia_dense


def test_warm_start_reaches_the_cold_minimum_with_the_held_factorization():
    # oracles: the cold minimization from the same point (relaxation + Newton), KKT
    # conditions, and the dense inertia; the warm one starts with quasi-Newton steps on the
    # factorization the workspace's solver still holds from the first minimization
    mesh, flat, volume, V, workspace, first = _c0_cycle_problem()
    solver = workspace.solver
    options = dict(workspace=workspace, pinned=pinned_dofs(mesh.X), precondition_at=first.x)
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


def test_a_warm_start_at_a_certified_minimum_of_the_same_energy_certifies_it():
    # the protocol's return to c0 = 2/R: the factorization at the minimum before the cycle
    # (two minimizations back; PARDISO still holds it) serves the first steps and, where the
    # shell returns to that minimum, certifies it. Oracles: KKT, the dense tangent inertia,
    # the first minimum's energy; a token of another energy or volume never certifies
    mesh, energy, volume, V0 = shell(4, 1000)
    X0 = 0.9 ** (1 / 3) * mesh.X
    X0 = X0 - 0.05 * np.exp(-20 * ((X0[:, 2:] - 0.97) ** 2)) * X0
    workspace = Workspace(CountingSolver(make_solver()))
    solver = workspace.solver
    options = dict(workspace=workspace, pinned=pinned_dofs(mesh.X))
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
    assert back.success and back.inertia == 0
    assert back.fun == pytest.approx(first.fun, rel=1e-12)
    assert_kkt(energy, volume, back, 0.9 * V0)
    assert tangent_inertia_dense(energy, volume, back.x) == 0
    if _load_mkl() is not None:  # PARDISO keeps two factorizations: no new one at all
        assert back.history[0]["step"] == "quasi-newton"  # on the held one (QDLDL: stale)
        assert solver.counts["double"] == n_double and solver.counts["single"] == n_single
        assert back.factorization is tok


def test_a_stale_warm_start_is_ignored():
    # once the solver no longer holds the factorization (PARDISO keeps the last two of each
    # precision; each minimization below factors at least once, its certificate) the token
    # no longer describes it: the minimization must then be exactly the cold one
    mesh, flat, volume, V, workspace, first = _c0_cycle_problem()
    solver = workspace.solver
    options = dict(workspace=workspace, pinned=pinned_dofs(mesh.X), precondition_at=first.x)
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
    assert fixes_gauge(first.x, other) and not np.array_equal(other, pinned_dofs(mesh.X))
    kept = newton(flat, volume, first.x, V, warm_start=again.factorization,
                  workspace=workspace, pinned=other, precondition_at=first.x, history=True)
    assert kept.history[0]["step"] == "quasi-newton"
    assert kept.fun == pytest.approx(cold.fun, rel=1e-12)
    # ... and a token whose pins do not fix them there (two whole vertices leave the rotation
    # about their axis free) is not used with another gauge
    token = kept.factorization
    token.pinned = np.arange(6)
    assert not fixes_gauge(first.x, token.pinned)
    n_factor = solver.n_factor
    res = newton(flat, volume, first.x, V, warm_start=token, workspace=workspace,
                 pinned=other, precondition_at=first.x, history=True)
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
    # nor its workspace, and with it the solver
    workspace = Workspace()
    res = newton(energy, volume, 0.95 ** (1 / 3) * mesh.X, 0.95 * V0, workspace=workspace)
    assert res.factorization is not None
    alive = weakref.ref(workspace.solver), weakref.ref(workspace)
    del workspace
    gc.collect()
    assert alive[0]() is None and alive[1]() is None


def _cycle(workspace, mesh, energy, volume, X0, V):
    """The protocol's three minimizations of a step (c0 = 2/R, c0 = 0, back) in
    ``workspace``, as generators: each ``next`` runs one more."""
    options = dict(workspace=workspace, pinned=pinned_dofs(mesh.X))
    first = newton(energy, volume, X0, V, **options)
    yield first
    flat = newton(energy.with_c0(0.0), volume, first.x, V, warm_start=first.factorization,
                  precondition_at=first.x, certify=False, **options)
    yield flat
    yield newton(energy, volume, flat.x, V, warm_start=[first.factorization, flat.factorization],
                 precondition_at=flat.x, **options)


def test_workspaces_share_nothing():
    # a workspace is all the state minimizations share: two made alike, given the same calls
    # interleaved with each other, take exactly the path of one given them alone (oracle: that
    # run, to the last bit); a token of one workspace is never used in another (oracle: the
    # cold minimization in a fresh workspace)
    mesh, energy, volume, V0 = shell(4, 1000)
    X0 = 0.9 ** (1 / 3) * mesh.X
    X0 = X0 - 0.05 * np.exp(-20 * ((X0[:, 2:] - 0.97) ** 2)) * X0
    alone = list(_cycle(Workspace(), mesh, energy, volume, X0, 0.9 * V0))
    a = _cycle(Workspace(), mesh, energy, volume, X0, 0.9 * V0)
    b = _cycle(Workspace(), mesh, energy, volume, X0, 0.9 * V0)
    for ref in alone:
        for res in (next(a), next(b)):
            assert np.array_equal(res.x, ref.x) and res.nit == ref.nit
            assert res.fun == ref.fun and res.certificate == ref.certificate
    flat = energy.with_c0(0.0)
    options = dict(pinned=pinned_dofs(mesh.X), precondition_at=alone[0].x)
    foreign = newton(flat, volume, alone[0].x, 0.9 * V0, warm_start=alone[0].factorization,
                     workspace=Workspace(), **options)
    cold = newton(flat, volume, alone[0].x, 0.9 * V0, workspace=Workspace(), **options)
    assert np.array_equal(foreign.x, cold.x) and foreign.nit == cold.nit
