"""Power-law fits of thresholds, crossings and W averages: synthetic data with known answers.

Coverage oracle: over many seeded data sets with multiplicative log-normal noise, the true
exponent must lie within the reported 1-sigma error as often as the error's sampling
distribution says (normal with known sigma; Student t with n - 2 degrees of freedom when the
error comes from the residual scatter)."""

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from shellbuckle.analysis.fits import (PowerLawFit, critical_gamma, crossover, fit_power_law,
                                       gamma_at, wrinkle_average)

GAMMA = np.geomspace(271, 29160, 12)
A_TRUE, B_TRUE = 2.8, -0.55


def noisy(rng, x, s_log, a=A_TRUE, b=B_TRUE):
    return a * x ** b * np.exp(s_log * rng.standard_normal(len(x)))


def test_exact_recovery_without_noise():
    fit = fit_power_law(GAMMA, A_TRUE * GAMMA ** B_TRUE)
    assert fit.prefactor == pytest.approx(A_TRUE, rel=1e-12)
    assert fit.exponent == pytest.approx(B_TRUE, abs=1e-13)
    assert fit.residual_std == pytest.approx(0.0, abs=1e-12)
    assert fit.exponent_err == pytest.approx(0.0, abs=1e-12)
    assert fit(1000.0) == pytest.approx(A_TRUE * 1000.0 ** B_TRUE, rel=1e-12)
    assert fit.n == len(GAMMA) and not fit.fixed_exponent


def test_recovery_within_reported_errors_with_noise():
    rng = np.random.default_rng(1)
    y = noisy(rng, GAMMA, 0.05)
    fit = fit_power_law(GAMMA, y)
    assert abs(fit.exponent - B_TRUE) < 3 * fit.exponent_err
    assert abs(math.log(fit.prefactor / A_TRUE)) < 3 * fit.log_prefactor_err
    assert fit.residual_std == pytest.approx(0.05, rel=0.5)


@pytest.mark.parametrize("known_sigma", [True, False])
def test_one_sigma_coverage(known_sigma):
    rng = np.random.default_rng(2024)
    n_sets, s_log, x = 1000, 0.08, GAMMA[::2]          # 6 points per data set
    hits_b = hits_a = 0
    for _ in range(n_sets):
        y = noisy(rng, x, s_log)
        fit = fit_power_law(x, y, sigma=s_log * y if known_sigma else None)
        hits_b += abs(fit.exponent - B_TRUE) <= fit.exponent_err
        hits_a += abs(math.log(fit.prefactor / A_TRUE)) <= fit.log_prefactor_err
    # sigma = s_log * y is the first-order std of y; the fit uses sigma/y = s_log exactly
    expected = (2 * stats.norm.cdf(1) - 1 if known_sigma
                else 2 * stats.t.cdf(1, df=len(x) - 2) - 1)
    tol = 3 * math.sqrt(expected * (1 - expected) / n_sets)
    assert abs(hits_b / n_sets - expected) < tol
    assert abs(hits_a / n_sets - expected) < tol


def test_fixed_exponent_recovers_prefactor_and_its_error():
    rng = np.random.default_rng(5)
    s_log = 0.1
    y = noisy(rng, GAMMA, s_log, a=850.0, b=-1.0)
    fit = fit_power_law(GAMMA, y, exponent=-1)
    # the fixed-exponent estimate is the geometric mean of y * gamma
    assert fit.prefactor == pytest.approx(math.exp(np.mean(np.log(y * GAMMA))), rel=1e-12)
    assert fit.exponent == -1 and fit.fixed_exponent and fit.exponent_err == 0
    weighted = fit_power_law(GAMMA, y, sigma=s_log * y, exponent=-1)
    assert weighted.log_prefactor_err == pytest.approx(s_log / math.sqrt(len(GAMMA)), rel=1e-12)
    one = fit_power_law([850.0], [1.0], exponent=-1)
    assert one.prefactor == pytest.approx(850.0) and math.isnan(one.prefactor_err)


def test_weights_follow_sigma():
    # two clean points and one far outlier with a huge sigma: the fit follows the clean ones
    x = np.array([100.0, 1000.0, 10000.0])
    y = A_TRUE * x ** B_TRUE
    y_bad = y.copy()
    y_bad[1] *= 3.0
    fit = fit_power_law(x, y_bad, sigma=[1e-6 * y[0], 1e3 * y_bad[1], 1e-6 * y[2]])
    assert fit.exponent == pytest.approx(B_TRUE, abs=1e-6)


def test_bootstrap_interval_matches_covariance_and_is_seeded():
    rng = np.random.default_rng(3)
    x = np.geomspace(271, 29160, 40)
    y = noisy(rng, x, 0.05)
    fit = fit_power_law(x, y, bootstrap=400, seed=7)
    lo, hi = fit.exponent_interval
    assert lo < fit.exponent < hi
    assert (hi - lo) / 2 == pytest.approx(fit.exponent_err, rel=0.25)
    assert fit_power_law(x, y, bootstrap=400, seed=7).exponent_interval == (lo, hi)
    assert fit_power_law(x, y).exponent_interval is None


def test_str_and_dict():
    fit = PowerLawFit(2.8, -0.55, 0.15, 0.02, 10, False, 0.1)
    assert str(fit) == "2.80(±0.15) γ^-0.55(±0.02)"
    d = fit.to_dict()
    assert d["prefactor"] == 2.8 and d["exponent_err"] == 0.02 and d["n"] == 10
    assert "fixed" in str(fit_power_law([850.0, 1000.0], [1.0, 0.85], exponent=-1))


@pytest.mark.parametrize("args, kwargs, match", [
    (([1.0], [2.0]), {}, "at least 2"),
    (([], []), {"exponent": -1}, "at least 1"),
    (([1.0, 2.0], [1.0]), {}, "same length"),
    (([1.0, 2.0], [1.0, -1.0]), {}, "> 0"),
    (([0.0, 2.0], [1.0, 1.0]), {}, "> 0"),
    (([1.0, 2.0], [1.0, np.nan]), {}, "finite"),
    (([1.0, 2.0], [1.0, 2.0]), {"sigma": [0.1, 0.0]}, "sigma"),
    (([1.0, 2.0], [1.0, 2.0]), {"sigma": [0.1, 0.1, 0.1]}, "sigma"),
    (([3.0, 3.0], [1.0, 2.0]), {}, "distinct"),
])
def test_bad_input(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        fit_power_law(*args, **kwargs)


def test_critical_gamma_of_paper_law_and_error_propagation():
    rng = np.random.default_rng(11)
    y = noisy(rng, GAMMA, 0.05, a=850.0, b=-1.0)
    fit = fit_power_law(GAMMA, y, exponent=-1)
    gc = critical_gamma(fit)
    assert gc.value == pytest.approx(fit.prefactor, rel=1e-12)    # a / gamma = 1
    assert gc.err == pytest.approx(fit.prefactor_err, rel=1e-12)
    # free exponent: check the delta-method error against a Monte Carlo over the covariance
    free = fit_power_law(GAMMA, y)
    g = gamma_at(free, 1.0)
    assert free(g.value) == pytest.approx(1.0, rel=1e-12)
    draws = rng.multivariate_normal([math.log(free.prefactor), free.exponent], free.cov, 20000)
    mc = np.exp(-draws[:, 0] / draws[:, 1])
    assert np.std(np.log(mc)) == pytest.approx(g.err / g.value, rel=0.1)


def test_crossover_of_two_laws():
    p = PowerLawFit(2.8, -0.55, 0.0, 0.0, 5, False, 0.0, cov=((0.0, 0.0), (0.0, 0.0)))
    s = PowerLawFit(850.0, -1.0, 0.0, 0.0, 5, True, 0.0, cov=((0.0, 0.0), (0.0, 0.0)))
    c = crossover(p, s)
    assert p(c.value) == pytest.approx(s(c.value), rel=1e-12)
    assert c.value == pytest.approx((850 / 2.8) ** (1 / 0.45), rel=1e-12)
    assert c.err == 0.0
    one = PowerLawFit(1.0, 0.0, 0.0, 0.0, 1, True, math.nan, cov=((0.0, 0.0), (0.0, 0.0)))
    assert crossover(one, s).value == pytest.approx(critical_gamma(s).value, rel=1e-12)
    # independent errors add in quadrature in ln gamma (exponents 0 and -1: d ln gamma/d ln a = 1)
    s_err = PowerLawFit(850.0, -1.0, 85.0, 0.0, 5, True, 0.0, cov=((0.01, 0.0), (0.0, 0.0)))
    one_err = PowerLawFit(1.0, 0.0, 0.1, 0.0, 5, True, 0.0, cov=((0.01, 0.0), (0.0, 0.0)))
    c = crossover(one_err, s_err)
    assert c.err / c.value == pytest.approx(math.sqrt(0.02), rel=1e-12)


def test_wrinkle_average_window_and_shape():
    table = pd.DataFrame({
        "dV_over_V": [0.50, 0.53, 0.60, 0.65, 0.70, 0.76, 0.80],
        "shape": ["wrinkled", "wrinkled", "polygonal", "wrinkled", "wrinkled", "wrinkled",
                  "wrinkled"],
        "W": [9, 5, 0, 6, 6, 7, 9]})
    avg = wrinkle_average(table)
    chosen = np.array([5, 6, 6, 7], float)  # in [0.53, 0.76] and wrinkled
    assert avg.n == 4
    assert avg.mean == pytest.approx(chosen.mean())
    assert avg.std == pytest.approx(chosen.std())
    assert wrinkle_average(table, window=(0.0, 0.52)) == (9.0, 0.0, 1)
    empty = wrinkle_average(table, window=(0.9, 1.0))
    assert empty.n == 0 and math.isnan(empty.mean)
    with pytest.raises(ValueError, match="analy"):
        wrinkle_average(table.drop(columns="shape"))
