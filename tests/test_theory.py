import math
import warnings

import numpy as np
import pytest

from shellbuckle import theory as T
from shellbuckle.params import PhysicalRangeWarning, ShellParameters

P2333 = ShellParameters.from_gamma(2333, nu=1 / 3)
PARAMS = [P2333, ShellParameters.from_gamma(271, nu=0.2, kappa=2.0, R=1.5),
          ShellParameters.from_gamma(2e4, nu=-0.3)]


def _paper_bracket(alpha, delta):
    """The bracket of eq. Ucapsule exactly as printed."""
    return (np.sin(alpha) * (np.tan(alpha) - delta ** 0.5) ** 2
            + 4 * delta ** 0.5 * (1 - np.cos(alpha)))


# --- sphere ----------------------------------------------------------------------------------

@pytest.mark.parametrize("p", PARAMS)
def test_exact_sphere_energy_is_the_green_lagrange_energy(p):
    # oracle: build the Green-Lagrange strain from the deformation gradient of x -> s x
    # restricted to a tangent plane, and evaluate the paper's density per reference area
    x = np.array([-0.5, 0.01, 0.3, 0.9])
    s = (1 - x) ** (1 / 3)
    F = s[:, None, None] * np.eye(2)
    e = 0.5 * (np.transpose(F, (0, 2, 1)) @ F - np.eye(2))
    tr = np.trace(e, axis1=1, axis2=2)
    tr_e2 = np.trace(e @ e, axis1=1, axis2=2)
    density = p.A / (2 * (1 + p.nu)) * (tr_e2 + p.nu / (1 - p.nu) * tr ** 2)
    np.testing.assert_allclose(T.U_sphere_exact(x, p), 4 * np.pi * p.R ** 2 * density,
                               rtol=1e-13)


@pytest.mark.parametrize("p", PARAMS)
def test_exact_sphere_energy_tends_to_eq_usphere(p):
    assert abs(T.U_sphere_exact(0.01, p) / T.U_sphere(0.01, p) - 1) < 0.01
    # series: U_exact / U_sphere = (1 + x/6)^2 (1 + O(x^2)) from s^2 - 1 = -2x/3 - x^2/9 + ...
    x = np.geomspace(1e-6, 1e-2, 9)
    ratio = T.U_sphere_exact(x, p) / T.U_sphere(x, p)
    assert np.all(np.abs(ratio - 1 - x / 3) < x ** 2)


@pytest.mark.parametrize("p", PARAMS)
def test_sphere_pressures_are_minus_dU_dV(p):
    V0 = 4 * np.pi * p.R ** 3 / 3
    x = np.array([-0.3, 0.001, 0.05, 0.4, 0.8])
    h = 1e-6
    # V = V0 (1 - x): -dU/dV = (1/V0) dU/dx
    fd_exact = (T.U_sphere_exact(x + h, p) - T.U_sphere_exact(x - h, p)) / (2 * h * V0)
    np.testing.assert_allclose(T.pressure_sphere_exact(x, p), fd_exact, rtol=1e-7)
    fd_small = (T.U_sphere(x + h, p) - T.U_sphere(x - h, p)) / (2 * h * V0)
    np.testing.assert_allclose(T.pressure_sphere(x, p), fd_small, rtol=1e-7)
    assert math.isclose(T.pressure_sphere_exact(1e-7, p), T.pressure_sphere(1e-7, p),
                        rel_tol=1e-6)


# --- cap geometry ------------------------------------------------------------------------------

def test_dV_of_alpha_is_twice_the_cap_volume():
    alpha = np.linspace(0, np.pi, 37)
    h = 1 - np.cos(alpha)  # cap height for R = 1
    cap = np.pi * h ** 2 * (3 - h) / 3
    np.testing.assert_allclose(T.dV_over_V_of_alpha(alpha), 2 * cap / (4 * np.pi / 3),
                               atol=1e-15)
    np.testing.assert_allclose(T.dV_over_V_of_alpha(alpha),
                               0.5 * (1 - np.cos(alpha)) ** 2 * (2 + np.cos(alpha)), atol=1e-15)
    assert T.dV_over_V_of_alpha(np.pi / 2) == pytest.approx(1.0, abs=1e-15)


def test_alpha_inverse_round_trips():
    alpha = np.linspace(0, np.pi, 1001)
    # near pi the map is flat (2 - dV/V ~ 3 (pi - a)^4 / 8): the accuracy allowed by one ulp
    # of dV/V is (8 eps / 3)^(1/4) ~ 1e-4 at pi, ~ 1e-8 at the grid's last interior point
    back = T.alpha_of_dV_over_V(T.dV_over_V_of_alpha(alpha))
    np.testing.assert_allclose(back[:-50], alpha[:-50], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(back, alpha, atol=1e-7)
    x = np.concatenate([np.geomspace(1e-300, 1e-2, 50), np.linspace(0, 2, 401)])
    np.testing.assert_allclose(T.dV_over_V_of_alpha(T.alpha_of_dV_over_V(x)), x,
                               rtol=1e-13, atol=1e-15)
    assert T.alpha_of_dV_over_V(0.0) == 0.0
    assert T.alpha_of_dV_over_V(1.0) == pytest.approx(np.pi / 2, abs=1e-15)
    assert T.alpha_of_dV_over_V(2.0) == pytest.approx(np.pi, abs=1e-15)
    # leading order at small volume: dV/V = 3 a^4 / 8
    np.testing.assert_allclose(T.alpha_of_dV_over_V(1e-12), (8e-12 / 3) ** 0.25, rtol=1e-6)


def test_functions_are_vectorized_and_keep_shapes():
    x = np.linspace(0.05, 0.6, 12).reshape(3, 4)
    for f in (T.U_sphere, T.U_sphere_exact, T.U_axisym_of_dV, T.pressure_sphere_exact):
        out = f(x, P2333)
        assert out.shape == (3, 4)
        np.testing.assert_allclose(out.ravel(), [f(v, P2333) for v in x.ravel()], rtol=1e-14)
    assert isinstance(T.U_axisym(0.3, P2333), float)


# --- capsule energy ------------------------------------------------------------------------------

@pytest.mark.parametrize("p", PARAMS)
def test_U_axisym_is_eq_ucapsule(p):
    alpha = np.linspace(0.05, 1.5, 30)
    delta = p.d_over_R
    printed = np.pi * p.A * p.R ** 2 / p.gamma * delta ** -0.5 * _paper_bracket(alpha, delta)
    np.testing.assert_allclose(T.U_axisym(alpha, p), printed, rtol=1e-12)
    x = T.dV_over_V_of_alpha(alpha)
    np.testing.assert_allclose(T.U_axisym_of_dV(x, p), printed, rtol=1e-10)


@pytest.mark.parametrize("p", PARAMS)
def test_paper_asymptotic_prefactors(p):
    alpha = np.linspace(0.01, 0.5, 10)
    # pi / 12^(1/4) A R^2 gamma^(-3/4) (1 - 2nu^2/(1-nu))^(-1/4) is pi kappa (d/R)^(-1/2)
    np.testing.assert_allclose(T.U_axisym_asymptotic(alpha, p),
                               np.pi * p.kappa * p.d_over_R ** -0.5 * alpha ** 3, rtol=1e-13)
    # the dV/V form is the alpha form at the leading-order alpha = (8 x / 3)^(1/4): no typo
    x = np.geomspace(1e-8, 0.5, 10)
    np.testing.assert_allclose(T.U_axisym_asymptotic_of_dV(x, p),
                               T.U_axisym_asymptotic((8 * x / 3) ** 0.25, p), rtol=1e-13)


@pytest.mark.parametrize("nu", [1 / 3, 0.0])
def test_asymptotic_forms_match_in_the_thin_small_angle_limit(nu):
    # valid for (d/R)^(1/2) << a << 1: follow a = (d/R)^(1/4) while gamma -> inf; the series
    # of the bracket gives ratio - 1 = d/a^2 - d^(1/2) a/2 + a^2/2 + ... = O(d^(1/2))
    errors_alpha, errors_dV = [], []
    for gamma in 10.0 ** np.arange(4, 17, 2):
        p = ShellParameters.from_gamma(gamma, nu=nu)
        delta = p.d_over_R
        a = delta ** 0.25
        e_a = abs(T.U_axisym(a, p) / T.U_axisym_asymptotic(a, p) - 1)
        x = T.dV_over_V_of_alpha(a)
        e_x = abs(T.U_axisym_of_dV(x, p) / T.U_axisym_asymptotic_of_dV(x, p) - 1)
        assert e_a < 3 * delta ** 0.5 and e_x < 3 * delta ** 0.5
        errors_alpha.append(e_a)
        errors_dV.append(e_x)
    assert np.all(np.diff(errors_alpha) < 0) and np.all(np.diff(errors_dV) < 0)
    assert errors_alpha[-1] < 1e-3 and errors_dV[-1] < 1e-3


@pytest.mark.parametrize("p", PARAMS)
def test_small_alpha_form_at_fixed_thickness(p):
    alpha = np.geomspace(1e-6, 1e-1, 11)
    ratio = T.U_axisym(alpha, p) / T.U_axisym_small_alpha(alpha, p)
    # next terms -d^(1/2) a^4/2 + a^5/2 over a^3 + d a: bounded by a (d^(1/2) + a)
    assert np.all(np.abs(ratio - 1) <= alpha * (p.d_over_R ** 0.5 + alpha))
    # whereas the paper's thin-shell form misses the d a term at fixed gamma
    assert T.U_axisym(1e-4, p) / T.U_axisym_asymptotic(1e-4, p) > 100


# --- crossing and classical threshold ------------------------------------------------------

@pytest.mark.parametrize("p", PARAMS)
@pytest.mark.parametrize("sphere", ["small_strain", "exact"])
def test_crossing_solves_the_energy_balance(p, sphere):
    u_sphere = T.U_sphere if sphere == "small_strain" else T.U_sphere_exact
    xc = T.crossing(p, sphere=sphere)
    assert 0 < xc < 1
    assert math.isclose(T.U_axisym_of_dV(xc, p), u_sphere(xc, p), rel_tol=1e-10)
    below = np.linspace(1e-9, xc, 400)[:-1]
    assert np.all(T.U_axisym_of_dV(below, p) > u_sphere(below, p))  # the first crossing
    above = xc * np.array([1.01, 1.1, 1.5])
    assert np.all(T.U_axisym_of_dV(above, p) < u_sphere(above, p))


def test_crossing_follows_the_three_fifths_power_law():
    gammas = np.geomspace(1e3, 1e6, 13)
    xc = np.array([T.crossing(ShellParameters.from_gamma(g)) for g in gammas])
    slope = np.polyfit(np.log(gammas), np.log(xc), 1)[0]
    assert abs(slope - (-3 / 5)) < 0.05  # eq. PowerLawBuckling2
    # the exact crossing approaches the asymptotic one; the correction d/a^2 ~ gamma^(-1/5)
    big = np.array([1e9, 1e12, 1e15])
    rel = np.array([T.crossing(ShellParameters.from_gamma(g))
                    / T.crossing_asymptotic(ShellParameters.from_gamma(g)) - 1 for g in big])
    assert np.all(rel > 0) and rel[-1] < 2e-3
    local = np.diff(np.log(rel)) / np.diff(np.log(big))
    np.testing.assert_allclose(local, -1 / 5, atol=0.03)


def test_crossing_asymptotic_solves_the_asymptotic_balance():
    for p in PARAMS:
        xa = T.crossing_asymptotic(p)
        assert math.isclose(T.U_sphere(xa, p), T.U_axisym_asymptotic_of_dV(xa, p), rel_tol=1e-12)


def test_no_crossing_for_thick_shells():
    p = ShellParameters.from_gamma(10)
    x = np.linspace(1e-6, 1 - 1e-6, 20001)
    assert np.all(T.U_axisym_of_dV(x, p) > T.U_sphere(x, p))
    with pytest.raises(ValueError, match="no crossing"):
        T.crossing(p)
    s = T.summary(p)
    assert s["crossing_dV_over_V"] is None and s["classical_dV_over_V"] > 1


def test_classical_threshold():
    E, sigma, d, R = 3.0, 0.3, 0.02, 1.0
    kappa = E * d ** 3 / (12 * (1 - sigma ** 2))
    p = ShellParameters.from_gamma(E * d * R ** 2 / kappa, nu=sigma, kappa=kappa, R=R)
    th = T.classical_threshold(p)
    # textbook Zoelly pressure with the 2D modulus E d
    assert math.isclose(th.pressure, 2 * E * d ** 2 / (math.sqrt(3 * (1 - sigma ** 2)) * R ** 2),
                        rel_tol=1e-13)
    assert math.isclose(T.classical_pressure(p), th.pressure, rel_tol=1e-15)
    for q in PARAMS:
        th = T.classical_threshold(q)
        assert math.isclose(th.pressure, 4 * math.sqrt(q.kappa * q.A) / q.R ** 2, rel_tol=1e-14)
        assert T.classical_pressure(q) == th.pressure  # the progress bar's p_c, no root search
        assert math.isclose(th.dV_over_V, 6 * (1 - q.nu) / math.sqrt(q.gamma), rel_tol=1e-14)
        assert math.isclose(T.pressure_sphere(th.dV_over_V, q), th.pressure, rel_tol=1e-12)
        assert math.isclose(T.pressure_sphere_exact(th.dV_over_V_exact, q), th.pressure,
                            rel_tol=1e-10)
        # the exact pressure grows faster than linearly: threshold reached earlier
        assert th.dV_over_V_exact < th.dV_over_V


def test_summary_collects_the_numbers():
    s = T.summary(P2333)
    assert s["d_over_R"] == P2333.d_over_R
    assert s["crossing_dV_over_V"] == T.crossing(P2333)
    assert s["crossing_dV_over_V_exact_sphere"] == T.crossing(P2333, sphere="exact")
    assert s["classical_pressure"] == T.classical_threshold(P2333).pressure
    assert s["crossing_dV_over_V"] < s["classical_dV_over_V"]
    with pytest.warns(PhysicalRangeWarning):
        q = ShellParameters.from_gamma(1000, nu=0.6)
    s = T.summary(q)
    assert s["d_over_R"] is None and s["crossing_dV_over_V"] is None
    assert s["classical_pressure"] > 0


@pytest.mark.parametrize("call, name", [
    (lambda: T.U_axisym(np.pi / 2, P2333), "alpha"),
    (lambda: T.U_axisym(-0.1, P2333), "alpha"),
    (lambda: T.U_axisym_of_dV(1.0, P2333), "dV_over_V"),
    (lambda: T.alpha_of_dV_over_V(2.5), "dV_over_V"),
    (lambda: T.dV_over_V_of_alpha([0.1, np.nan]), "alpha"),
    (lambda: T.U_sphere(1.2, P2333), "dV_over_V"),
    (lambda: T.pressure_sphere_exact(1.0, P2333), "dV_over_V"),
    (lambda: T.crossing(P2333, sphere="linear"), "sphere"),
])
def test_out_of_range_arguments_are_refused_by_name(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def test_capsule_needs_a_thickness():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PhysicalRangeWarning)
        p = ShellParameters.from_gamma(1000, nu=0.5)
    with pytest.raises(ValueError, match="nu"):
        T.U_axisym(0.3, p)
    with pytest.raises(ValueError, match="nu"):
        T.crossing_asymptotic(p)
