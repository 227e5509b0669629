"""Rim curves: Fourier spectrum, apices and concavity against analytic planar curves."""

import numpy as np
import pytest

from shellbuckle.analysis.wrinkles import APEX_PROMINENCE, CONCAVITY, N_MODES, rim_shape

K = 256
PHI = 2 * np.pi * np.arange(K) / K
R0 = 0.8
SMOOTH = 0.02  # much shorter than any feature below


def polygon(m, phase=0.0):
    """Polar equation of a regular m-gon with straight sides, apices at radius R0 and azimuths
    ``phase + pi/m + 2 pi k/m`` (the middle of a side at ``phase``)."""
    t = np.mod(PHI - phase + np.pi / m, 2 * np.pi / m) - np.pi / m
    return R0 * np.cos(np.pi / m) / np.cos(t)


def test_circle():
    s = rim_shape(np.full(K, R0), SMOOTH)
    assert s["spectrum"] == pytest.approx(np.zeros(N_MODES), abs=1e-14)
    assert len(s["apices"]) == 0 and len(s["arc_curvature"]) == 0
    # kappa * radius = 1 on a circle
    assert s["curvature"] == pytest.approx(np.ones(K), abs=1e-12)


@pytest.mark.parametrize("m", range(2, N_MODES + 1, 3))
@pytest.mark.parametrize("phase", [0.0, 0.37, 2.0])
def test_spectrum_is_the_relative_mode_amplitude(m, phase):
    eps = 0.03
    rho = R0 * (1 + eps * np.cos(m * PHI + phase) + 0.01 * np.sin(1 * PHI))
    s = rim_shape(rho, SMOOTH)
    expected = np.zeros(N_MODES)
    expected[m - 1] = eps
    expected[0] = 0.01
    np.testing.assert_allclose(s["spectrum"], expected, atol=1e-12)


@pytest.mark.parametrize("m", range(3, 13))
def test_convex_and_concave_cosine_rims(m):
    # rho = r0 (1 + eps cos m phi) has negative curvature at its minima iff eps (m^2 + 1) > 1
    # (rho^2 + 2 rho'^2 - rho rho'' < 0 at phi = pi/m)
    convex = rim_shape(R0 * (1 + 0.5 / (m * m + 1) * np.cos(m * PHI)), SMOOTH)
    concave = rim_shape(R0 * (1 + 3.0 / (m * m + 1) * np.cos(m * PHI)), SMOOTH)
    assert convex["curvature"].min() > 0
    assert concave["curvature"].min() < 0
    assert len(concave["apices"]) == m
    assert (concave["arc_curvature"] < -CONCAVITY).all()
    if 2 * 0.5 / (m * m + 1) >= APEX_PROMINENCE:  # peak-to-trough above the apex threshold
        assert len(convex["apices"]) == m
        assert (convex["arc_curvature"] > CONCAVITY).all()


@pytest.mark.parametrize("m", range(3, 11))
def test_polygon_has_m_apices_and_straight_sides(m):
    s = rim_shape(polygon(m, phase=0.1), SMOOTH)
    assert len(s["apices"]) == m
    apex_phi = np.sort(PHI[s["apices"]])
    expected = np.sort(np.mod(0.1 + np.pi / m + 2 * np.pi * np.arange(m) / m, 2 * np.pi))
    assert np.abs(np.angle(np.exp(1j * (apex_phi - expected)))).max() <= 2 * np.pi / K
    # the middle of every side is straight: zero curvature, neither concave nor convex
    assert np.abs(s["arc_curvature"]).max() < 0.2 * CONCAVITY


def test_apex_across_the_start_of_the_samples_counts_once():
    rho = R0 * (1 + 0.1 * np.exp(-0.5 * (np.angle(np.exp(1j * PHI)) / 0.2) ** 2))
    s = rim_shape(rho, SMOOTH)
    assert list(s["apices"]) == [0]
    s = rim_shape(np.roll(rho, 5), SMOOTH)
    assert list(s["apices"]) == [5]


@pytest.mark.parametrize("shift", [1, 17, 128])
def test_rotating_the_rim_permutes_apices_and_arcs(shift):
    rho = R0 * (1 + 0.08 * np.cos(5 * PHI) + 0.03 * np.cos(2 * PHI + 1.0))
    a, b = rim_shape(rho, SMOOTH), rim_shape(np.roll(rho, shift), SMOOTH)
    np.testing.assert_allclose(b["spectrum"], a["spectrum"], atol=1e-12)
    assert sorted((a["apices"] + shift) % K) == sorted(b["apices"])
    np.testing.assert_allclose(np.sort(b["arc_curvature"]), np.sort(a["arc_curvature"]),
                               atol=1e-9)


def test_smoothing_removes_sub_resolution_ripples():
    # a ripple of wavelength 2 pi R0 / 60 ~ 0.08 is below a smoothing length of 0.05
    m = 6
    clean = R0 * (1 + 3.0 / (m * m + 1) * np.cos(m * PHI))
    rough = clean + 0.03 * R0 * np.cos(60 * PHI)
    s = rim_shape(rough, 0.05)
    assert len(s["apices"]) == m
    assert (s["arc_curvature"] < -CONCAVITY).all()
    assert len(rim_shape(rough, 0.0)["apices"]) > m  # unsmoothed, every ripple is an apex
