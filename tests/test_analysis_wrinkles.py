"""Rim curves: Fourier spectrum, apices and concavity against analytic planar curves."""

import numpy as np
import pytest

from shellbuckle.analysis.wrinkles import APEX_PROMINENCE, CONCAVITY, N_MODES, Curve, rim_shape

from test_analysis_shapes import star_modulation

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
def test_local_curvature_of_cosine_rims(m):
    # rho = r0 (1 + eps cos m phi) has negative curvature at its minima iff eps (m^2 + 1) > 1
    # (rho^2 + 2 rho'^2 - rho rho'' < 0 at phi = pi/m)
    convex = rim_shape(R0 * (1 + 0.5 / (m * m + 1) * np.cos(m * PHI)), SMOOTH)
    inflected = rim_shape(R0 * (1 + 3.0 / (m * m + 1) * np.cos(m * PHI)), SMOOTH)
    assert convex["curvature"].min() > 0
    assert inflected["curvature"].min() < 0
    assert len(inflected["apices"]) == m
    if 2 * 0.5 / (m * m + 1) >= APEX_PROMINENCE:  # peak-to-trough above the apex threshold
        assert len(convex["apices"]) == m
        assert (convex["arc_curvature"] > 0.1).all()


@pytest.mark.parametrize("m", range(3, 13))
@pytest.mark.parametrize("sagitta", [0.01, 0.05, 0.15])
def test_star_rim_dips_inside_the_chord_between_apices(m, sagitta):
    # r0 (1 + eps cos m phi) with eps = star_modulation(m, s): the middle between two apices
    # lies s chords inside the chord joining them (test_analysis_shapes)
    eps = star_modulation(m, sagitta)
    shape = rim_shape(R0 * (1 + eps * np.cos(m * PHI)), SMOOTH)
    assert len(shape["apices"]) == m
    # the smoothing multiplies mode m by exp(-(m SMOOTH / R0)^2 / 2): the smoothed curve is the
    # star of that smaller eps
    eps_smooth = eps * np.exp(-0.5 * (m * SMOOTH / R0) ** 2)
    c, s_ = np.cos(np.pi / m), np.sin(np.pi / m)
    expected = ((1 + eps_smooth) * c - (1 - eps_smooth)) / (2 * (1 + eps_smooth) * s_)
    np.testing.assert_allclose(shape["arc_sagitta"], expected, rtol=0.02, atol=2e-4)
    assert (shape["arc_sagitta"] > CONCAVITY).all()
    np.testing.assert_allclose(shape["arc_chord"], 2 * R0 * (1 + eps_smooth) * s_, rtol=1e-3)


@pytest.mark.parametrize("m", range(3, 13))
def test_rim_bulging_out_of_its_chords_is_not_concave(m):
    # the middle between two apices outside the chord (even where the curve turns inwards
    # locally, eps (m^2 + 1) > 1 for the larger m): no arc dips inside its chord
    eps = star_modulation(m, -0.01)
    shape = rim_shape(R0 * (1 + eps * np.cos(m * PHI)), SMOOTH)
    if 2 * eps >= APEX_PROMINENCE:
        assert len(shape["apices"]) == m
    assert (shape["arc_sagitta"] == 0).all()


@pytest.mark.parametrize("m", range(3, 11))
def test_polygon_has_m_apices_and_straight_sides(m):
    s = rim_shape(polygon(m, phase=0.1), SMOOTH)
    assert len(s["apices"]) == m
    apex_phi = np.sort(PHI[s["apices"]])
    expected = np.sort(np.mod(0.1 + np.pi / m + 2 * np.pi * np.arange(m) / m, 2 * np.pi))
    assert np.abs(np.angle(np.exp(1j * (apex_phi - expected)))).max() <= 2 * np.pi / K
    # the middle of every side is straight: zero curvature, neither concave nor convex
    assert np.abs(s["arc_curvature"]).max() < 0.02
    assert s["arc_sagitta"].max() < 0.2 * CONCAVITY
    # the arcs run along the sides: the spacing of the apices is the side length, a little
    # less where the smoothing cuts the corner (the sharper, the more: 4 % for a triangle)
    side = 2 * R0 * np.sin(np.pi / m)
    assert ((s["spacing"] < side) & (s["spacing"] > 0.95 * side)).all()


def star_polygon(m, inner):
    """Polar equation of a star with ``m`` apices at radius R0 (azimuths ``2 pi k/m``) joined
    by straight segments to ``m`` inner corners at radius ``inner`` halfway between them."""
    t = np.mod(PHI + np.pi / m, 2 * np.pi / m) - np.pi / m   # from the nearest apex
    a = np.array([R0, 0.0])
    b = inner * np.array([np.cos(np.pi / m), np.sin(np.pi / m)])
    d = b - a
    u = np.abs(t)
    # the ray at angle u meets the segment a + s d: cross((a + s d), (cos u, sin u)) = 0
    s_ = (a[1] * np.cos(u) - a[0] * np.sin(u)) / (d[0] * np.sin(u) - d[1] * np.cos(u))
    return np.hypot(a[0] + s_ * d[0], a[1] + s_ * d[1])


@pytest.mark.parametrize("m", [4, 5, 7, 10])
def test_star_polygon_sagitta_is_its_inner_corner_depth(m):
    inner = 0.9 * R0 * np.cos(np.pi / m)   # the inner corners 10 % inside the chord's distance
    shape = rim_shape(star_polygon(m, inner), SMOOTH)
    assert len(shape["apices"]) == m
    truth = (R0 * np.cos(np.pi / m) - inner) / (2 * R0 * np.sin(np.pi / m))
    # the smoothing fills the sharp inner corners in more than it rounds the tips off
    assert ((shape["arc_sagitta"] > 0.6 * truth) & (shape["arc_sagitta"] <= truth)).all()
    assert (shape["arc_sagitta"] > CONCAVITY).all()


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
    for key in ("arc_curvature", "arc_sagitta", "arc_chord", "spacing"):
        np.testing.assert_allclose(np.sort(b[key]), np.sort(a[key]), atol=1e-9)


def test_smoothing_removes_sub_resolution_ripples():
    # a ripple of wavelength 2 pi R0 / 60 ~ 0.08 is below a smoothing length of 0.05
    m = 6
    clean = R0 * (1 + 3.0 / (m * m + 1) * np.cos(m * PHI))
    rough = clean + 0.03 * R0 * np.cos(60 * PHI)
    s = rim_shape(rough, 0.05)
    assert len(s["apices"]) == m
    assert (s["arc_sagitta"] > CONCAVITY).all()
    assert len(rim_shape(rough, 0.0)["apices"]) > m  # unsmoothed, every ripple is an apex


def _curve(rho, resolution):
    return Curve.analysed(PHI, rho, np.zeros(K), SMOOTH, resolution=resolution)


@pytest.mark.parametrize("m", [4, 8, 12])
def test_apices_closer_than_the_resolution_are_not_counted(m):
    rho = R0 * (1 + star_modulation(m, 0.05) * np.cos(m * PHI))
    spacing = rim_shape(rho, SMOOTH)["spacing"]
    assert _curve(rho, 0.9 * spacing.min()).count_resolved
    assert not _curve(rho, 1.1 * spacing.min()).count_resolved


def test_a_finer_pattern_partly_found_is_not_counted():
    # 12 bumps whose amplitude fades to nothing on two sides: only some pass the apex
    # prominence, and mode 12 dominates the mode of their count
    rho = R0 * (1 + 0.02 * (1 + np.cos(2 * PHI)) * np.cos(12 * PHI))
    curve = _curve(rho, 0.01)
    assert 2 <= curve.n_apices < 12
    assert not curve.count_resolved
    full = _curve(R0 * (1 + 0.02 * np.cos(12 * PHI)), 0.01)
    assert full.n_apices == 12 and full.count_resolved


def test_the_rim_envelope_tests_only_nearby_rays_with_the_same_result():
    """The envelope of the rim's segments cut by uniform rays (each segment tested against the
    rays of its azimuth span) equals, bit for bit, the test of every ray against every segment:
    on closed curves around the axis, with segments anywhere, through the axis and ending on it."""
    from shellbuckle.analysis.wrinkles import _envelope, _envelope_dense

    rng = np.random.default_rng(0)
    for trial in range(120):
        K = int(rng.choice([8, 64, 256, 1024]))
        phi = 2.0 * np.pi * np.arange(K) / K
        S = int(rng.integers(1, 400))
        th = np.sort(rng.uniform(0, 2 * np.pi, S))
        r0 = 1 + 0.3 * rng.standard_normal(S)
        A = np.stack([r0 * np.cos(th), r0 * np.sin(th)], 1)
        B = np.roll(A, -1, 0)
        junk = rng.random(S) < 0.2
        A[junk], B[junk] = rng.normal(size=(junk.sum(), 2)), rng.normal(size=(junk.sum(), 2))
        if trial % 7 == 0:
            A[0] = 0.0
        if trial % 5 == 0:
            A[-1] = -B[-1]
        zA, zB = rng.normal(size=S), rng.normal(size=S)
        got, want = _envelope(A, B, zA, zB, phi), _envelope_dense(A, B, zA, zB, phi)
        assert np.array_equal(got[0], want[0], equal_nan=True)
        assert np.array_equal(got[1], want[1], equal_nan=True)
        assert np.isfinite(got[0]).sum() > 0


def test_prominent_peaks_are_scipys():
    """The rim's apices use SciPy's definitions of a peak and of its prominence
    (scipy.signal.find_peaks, the oracle) without importing scipy.signal: the same indices and
    prominences on random signals, walks and signals with flat tops, for several thresholds."""
    from scipy.signal import find_peaks

    from shellbuckle.analysis.wrinkles import _prominent_peaks

    rng = np.random.default_rng(1)
    for trial in range(600):
        x = rng.normal(size=int(rng.integers(1, 300)))
        if trial % 3 == 0:
            x = np.round(x * 2) / 2
        if trial % 5 == 0:
            x = np.cumsum(x)
        threshold = float(rng.choice([0.0, 0.1, 0.5, 2.0]))
        got, prominences = _prominent_peaks(x, threshold)
        want, props = find_peaks(x, prominence=threshold)
        assert np.array_equal(got, want)
        assert np.array_equal(prominences, props["prominences"])


def test_the_analysis_does_not_import_scipy_signal():
    """scipy.signal (and the scipy.stats it pulls in) costs about a second of start-up."""
    import subprocess
    import sys

    code = ("import sys, shellbuckle.analysis, shellbuckle.locate, shellbuckle.cli; "
            "print('scipy.signal' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
