"""Conjugate gradient and gradient descent at fixed volume, and their agreement with Newton."""

import numpy as np
import pytest

from shellbuckle.energies.volume import Volume
from shellbuckle.solve import conjugate_gradient, gradient_descent, minimize, newton
from shellbuckle.solve.linesearch import ENERGY_ROUNDOFF, restore_volume
from test_solve_energies import spring_shell
from test_solve_newton import assert_kkt, shell


def test_cg_and_newton_agree_on_a_prebuckling_shell_minimum():
    mesh, energy, volume, V0 = shell(3, 100)
    X0 = mesh.X + 0.01 * np.random.default_rng(3).standard_normal(mesh.X.shape)
    ref = newton(energy, volume, X0, 0.981 * V0)
    res = conjugate_gradient(energy, volume, X0, 0.981 * V0, max_iter=3000)
    assert res.success and ref.success and ref.inertia == 0
    assert res.fun == pytest.approx(ref.fun, rel=1e-8)
    assert res.pressure == pytest.approx(ref.pressure, rel=1e-5)
    assert_kkt(energy, volume, res, 0.981 * V0, rtol=1e-6)


@pytest.mark.parametrize("method", [conjugate_gradient, gradient_descent])
def test_first_order_methods_on_spring_shell(method):
    mesh, energy = spring_shell(3, kb=0.01)
    volume = Volume(mesh.faces, mesh.n_vertices)
    V_target = 0.97 * volume.value(mesh.X)
    ref = newton(energy, volume, mesh.X, V_target)
    res = method(energy, volume, mesh.X, V_target, history=True, max_iter=3000)
    assert res.success and res.volume_error <= 1e-12
    assert res.fun == pytest.approx(ref.fun, rel=1e-8)
    E = np.array([h["energy"] for h in res.history])
    assert (np.diff(E) <= ENERGY_ROUNDOFF * np.abs(E[1:])).all()  # monotone at fixed volume


def test_cg_needs_fewer_iterations_than_gradient_descent():
    mesh, energy = spring_shell(4, kb=0.01)
    volume = Volume(mesh.faces, mesh.n_vertices)
    V_target = 0.97 * volume.value(mesh.X)
    cg = conjugate_gradient(energy, volume, mesh.X, V_target, max_iter=3000)
    gd = gradient_descent(energy, volume, mesh.X, V_target, max_iter=3000)
    assert cg.success and cg.nit < gd.nit


def test_alternate_relaxes_with_cg_then_converges_with_newton():
    mesh, energy, volume, V0 = shell(3, 500)
    res = minimize(energy, volume, mesh.X, 0.96 * V0, method="alternate", cg_iter=5)
    ref = minimize(energy, volume, mesh.X, 0.96 * V0, method="newton")
    assert res.method == "alternate" and res.success and res.inertia == 0
    assert res.fun == pytest.approx(ref.fun, rel=1e-10)


def test_restore_volume_reaches_the_target_to_round_off():
    mesh = spring_shell(3)[0]
    volume = Volume(mesh.faces, mesh.n_vertices)
    X = mesh.X + 0.05 * np.random.default_rng(4).standard_normal(mesh.X.shape)
    target = 0.8 * volume.value(mesh.X)
    Y, err = restore_volume(volume, X, target)
    assert err <= 1e-14 and abs(volume.value(Y) - target) <= 1e-14 * target


def test_restore_volume_moves_along_the_normal_of_the_trial_point():
    """The restoration is one move along grad V at the trial point (the root of the exact
    cubic), and agrees with the Newton iteration along successive normals to second order in
    the volume defect."""
    mesh = spring_shell(3)[0]
    volume = Volume(mesh.faces, mesh.n_vertices)
    X = mesh.X + 0.05 * np.random.default_rng(4).standard_normal(mesh.X.shape)
    g = volume.gradient(X)
    for defect in (1e-2, 1e-4):
        target = (1.0 - defect) * volume.value(X)
        Y, err = restore_volume(volume, X, target)
        assert err <= 1e-15
        t = np.sum((Y - X) * g) / np.sum(g * g)
        assert np.abs(Y - X - t * g).max() <= 1e-14 * np.abs(X).max()

        class Plain:  # the same volume without its cubic: Newton along successive normals
            value, gradient = volume.value, volume.gradient
        Z, err_plain = restore_volume(Plain(), X, target)
        assert err_plain <= 1e-14
        assert np.abs(Z - Y).max() <= 10 * defect ** 2 * np.abs(X).max()
