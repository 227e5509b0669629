"""Pressure control: the equilibrium at overpressure p is the volume-controlled one with
pressure p (same stationarity condition), and matches the shrunk-sphere theory."""

import numpy as np
import pytest

from shellbuckle import theory
from shellbuckle.energies.total import ShellEnergy
from shellbuckle.energies.volume import Volume
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.solve import newton
from shellbuckle.solve.pressure import minimize_at_pressure


@pytest.fixture(scope="module")
def shell():
    mesh = icosphere(5)
    params = ShellParameters.from_gamma(1000.0, nu=1 / 3)
    return mesh, params, ShellEnergy.build(mesh, params), Volume(mesh.faces, mesh.n_vertices)


def test_pressure_control_agrees_with_volume_control(shell):
    mesh, params, energy, volume = shell
    p = 0.4 * theory.classical_threshold(params).pressure
    rng = np.random.default_rng(0)
    X0 = mesh.X + 1e-3 * rng.standard_normal(mesh.X.shape)
    res = minimize_at_pressure(energy, volume, X0, p)
    assert res.success and res.inertia == 0
    V = volume.value(res.x)
    assert V < volume.value(mesh.X)
    back = newton(energy, volume, res.x, V)
    assert back.pressure == pytest.approx(p, rel=1e-7)
    assert back.fun == pytest.approx(res.fun, rel=1e-9)
    dV = 1 - V / volume.value(mesh.X)
    assert theory.pressure_sphere_exact(dV, params) == pytest.approx(p, rel=0.02)


def test_zero_pressure_returns_to_the_stress_free_sphere(shell):
    mesh, params, energy, volume = shell
    res = minimize_at_pressure(energy, volume, 0.97 * mesh.X, 0.0)
    assert res.success and res.inertia == 0
    # the discrete sphere is not exactly a bending equilibrium (c0 = 2/R), so the unloaded
    # minimum is the reference up to a relaxation of the order of that residual energy
    assert res.fun <= energy.value(mesh.X)
    assert volume.value(res.x) == pytest.approx(volume.value(mesh.X), rel=1e-4)


def test_bad_pressure_is_refused(shell):
    mesh, params, energy, volume = shell
    with pytest.raises(ValueError, match="pressure"):
        minimize_at_pressure(energy, volume, mesh.X, float("nan"))


@pytest.mark.parametrize("ending", ["converged", "maximum", "line search failed"])
def test_the_iterations_counted_are_the_steps_taken_and_heard(shell, ending, monkeypatch):
    """``nit`` counts the accepted Newton steps, whatever ends the minimization: the listener
    hears each of them once, and a pass that takes no step (converged, or its line search
    failed) is not counted."""
    import shellbuckle.solve.pressure as pressure
    from shellbuckle.solve.listen import listening

    mesh, params, energy, volume = shell
    p = 0.4 * theory.classical_threshold(params).pressure
    X0 = mesh.X + 1e-3 * np.random.default_rng(1).standard_normal(mesh.X.shape)
    max_iter = 3 if ending == "maximum" else 200
    if ending == "line search failed":
        searches = []
        real = pressure.backtracking

        def failing_third(*args, **kwargs):
            searches.append(1)
            return None if len(searches) == 3 else real(*args, **kwargs)

        monkeypatch.setattr(pressure, "backtracking", failing_third)
    heard = []
    with listening(lambda E, r: heard.append(E)):
        res = minimize_at_pressure(energy, volume, X0, p, max_iter=max_iter)
    assert res.message.startswith(ending)
    assert res.nit == len(heard) > 0
    assert res.nit == {"maximum": 3, "line search failed": 2}.get(ending, res.nit)
    assert np.all(np.diff(heard) <= 1e-14 * abs(heard[0]))  # no step raised the enthalpy
