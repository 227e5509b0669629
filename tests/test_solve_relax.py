"""The relaxation before Newton's method and the smooth start (:mod:`shellbuckle.solve.relax`).

Oracles: the minimum of plain Newton's method (KKT conditions, dense tangent inertia), the same
minimization with a stage switched off, an exact parabola for the self-scaling, and the
energies of the relaxation's steps, which never rise.
"""

import numpy as np
import pytest

from shellbuckle.solve import NewtonOptions, Workspace, make_solver, newton
from shellbuckle.solve.gauge import pinned_dofs
from shellbuckle.solve.linear import CountingSolver
from shellbuckle.solve.linesearch import ENERGY_ROUNDOFF
from shellbuckle.solve.newton import ABANDONED
from shellbuckle.solve.relax import rescaled
from test_solve_newton import _jiggled_shell, assert_kkt, shell, tangent_inertia_dense


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


def test_rough_relaxation_stage_takes_full_steps_sooner():
    # oracles: the relaxation without the rough stage, KKT conditions and the dense inertia.
    # The rough stage (a larger shift first) damps the soft modes that made the first
    # directions far too long, so fewer steps are cut by the line search; it ends with one
    # more (single-precision) factorization at the small shift, and the minimum is the same.
    # Without the self-scaling of the later steps, which also lengthens the cut ones
    mesh, energy, volume, V, shrunk, X0 = _jiggled_shell()
    runs = {}
    for rough in (0.0, NewtonOptions().relax_rough_shift):
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
    E0, g = 3.0, -2.0
    for c, alpha, tau in ((8.0, 0.25, 1.0), (8.0, 1.0, 0.5), (2.5, 1.0, 0.4)):
        E1 = E0 + g * alpha + 0.5 * c * alpha ** 2
        assert rescaled(tau, E0, E1, g, alpha) == pytest.approx(tau * -g / c, rel=1e-12)
    assert rescaled(0.4, E0, E0 + g + 0.5 * 0.1, g, 1.0) == pytest.approx(0.8)  # x2 at most
    assert rescaled(0.5, E0, E0 + g + 0.5 * 1e3, g, 1.0) == pytest.approx(0.05)  # x0.1
    assert rescaled(1.0, E0, E0 + g + 0.5 * 1.0, g, 1.0) == 1.0  # never above 1
    assert rescaled(1e-3, E0, E0 + g + 0.5 * 1e3, g, 1.0) == 1e-3
    assert rescaled(0.3, E0, E0 + 2 * g, g, 1.0) == pytest.approx(0.6)  # concave: longer


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


def test_a_relaxation_step_cut_short_asks_abandon_and_a_reason_stops_there():
    # a fold made by the jiggle cuts every relaxation step to nothing: the hook is asked after
    # a run of such steps, not only once the relaxation has run its course. Oracle: the
    # number of relaxation steps taken before the hook objects (every step counts as cut here)
    always = NewtonOptions(relax_rough_min_move=0.0, history=True)  # the relaxation, always
    mesh, energy, volume, V0 = shell(3, 1000)
    shrunk = 0.95 ** (1 / 3) * mesh.X
    X0 = shrunk + 0.01 * np.random.default_rng(5).standard_normal(mesh.X.shape)
    ref = newton(energy, volume, X0, 0.95 * V0, always, precondition_at=shrunk)
    n_relax = sum(h["step"] == "relax" for h in ref.history)
    first_ask = always.relax_ask_steps
    assert n_relax >= first_ask + 3
    every_step_cut = always.replace(relax_ask_alpha=1.5)
    calls = []

    def third(X):
        calls.append(1)
        return "folded" if len(calls) >= 3 else None

    res = newton(energy, volume, X0, 0.95 * V0, every_step_cut, precondition_at=shrunk,
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
    cheap = newton(energy, volume, X0, 0.95 * V0, every_step_cut, precondition_at=shrunk,
                   abandon=third, abandon_thorough=lambda X: thorough.append(1) or "folded")
    assert cheap.message == f"{ABANDONED}: folded" and np.array_equal(cheap.x, res.x)
    assert len(calls) == 3 and len(thorough) == 1
    assert [h["step"] for h in cheap.history] == ["relax"] * n_stop


def test_a_smooth_start_steps_on_the_hessian_at_the_relaxed_state():
    # the protocol without a jiggle: the next volume step starts at the last minimum, whose
    # certifying factorization the workspace still holds. Oracles: KKT conditions, the dense
    # tangent inertia, the minimum reached through the relaxation; the same bits without the
    # held factorization (a resumed run), which then factors the same matrix once more
    mesh, energy, volume, V0 = shell(4, 1000)
    workspace = Workspace(CountingSolver(make_solver()))
    solver = workspace.solver
    options = dict(workspace=workspace, pinned=pinned_dofs(mesh.X))
    first = newton(energy, volume, 0.97 ** (1 / 3) * mesh.X, 0.97 * V0, inertia_step=0.0,
                   **options)  # certified by a factorization at its very end point
    assert first.success and np.array_equal(first.factorization.X, first.x)
    runs, counts = {}, {}
    for name, token in (("held", first.factorization), ("fresh", None)):
        n0 = dict(solver.counts)
        runs[name] = newton(energy, volume, first.x, 0.94 * V0, precondition_at=first.x,
                            precondition_token=token, history=True, **options)
        counts[name] = {k: solver.counts[k] - n0[k] for k in n0}
    n0 = dict(solver.counts)
    relaxed = newton(energy, volume, first.x, 0.94 * V0, precondition_at=first.x, history=True,
                     relax_rough_min_move=0.0, **options)  # no smooth start
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
