"""Analytic theory of a deflated spherical shell (Quilliet et al., EPJE 27, 13 (2008), section 3).

Two candidate conformations of a shell of radius ``R`` whose enclosed volume decreases by
``dV`` from ``V = 4 pi R^3 / 3`` (``x = dV/V``, positive on deflation):

* the shrunk sphere, energy ``U_sphere`` (paper eq. Usphere, small strain) and its exact
  Green-Lagrange (St Venant-Kirchhoff) value :func:`U_sphere_exact`, the energy that the
  simulation's stretching term gives for a uniformly shrunk sphere;
* the "capsule": a spherical cap of half-angle ``alpha`` (apex at the centre) mirror-inverted,
  energy ``U_axisym`` (paper eq. Ucapsule) with ``x = 1/2 (1 - cos a)^2 (2 + cos a)`` (paper
  eq. deltaV_vs_alpha).

Their crossing ``U_sphere = U_axisym`` scales as ``gamma^(-3/5)`` (paper eq.
PowerLawBuckling2); the classical (Zoelly) buckling pressure of a sphere is
``p_c = 4 sqrt(kappa A) / R^2``.

Units: energies in the units of ``kappa`` (``kappa = 1``, ``R = 1`` by default, then
``A = gamma``), pressures in energy / length^3.

Energy convention: the formulas are those of the standard (helfrich) thin-plate energy
``1/2 kappa (c1 + c2 - c0)^2``. Parameters under another convention
(:mod:`shellbuckle.params`) are evaluated as their standard equivalent
(:meth:`~shellbuckle.params.ShellParameters.helfrich_equivalent`: bending modulus ``f kappa``,
the same ``A``, gamma / f), so every curve is the theory of the model that is simulated, in
absolute units: divide by the ``kappa`` given to get E/kappa. Under ``paper`` every function
equals the helfrich one at 4 gamma, with energies divided by 4 in units of kappa. Functions are vectorized over ``dV_over_V`` or
``alpha`` (any shape; a float for scalar input) and take a :class:`ShellParameters`.
Pressure sign: ``p = -dU/dV`` is the outside-minus-inside pressure difference holding the
shell at volume ``V``; it is positive on deflation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .params import (ShellParameters, check_caption, d_over_R, gamma_from_d_over_R,
                     thickness_factor)

__all__ = ["U_sphere", "U_sphere_exact", "pressure_sphere", "pressure_sphere_exact",
           "pressure_sphere_bending",
           "dV_over_V_of_alpha", "alpha_of_dV_over_V", "U_axisym", "U_axisym_of_dV",
           "U_axisym_small_alpha", "U_axisym_asymptotic", "U_axisym_asymptotic_of_dV",
           "crossing", "crossing_asymptotic", "ClassicalThreshold", "classical_threshold",
           "summary", "d_over_R", "gamma_from_d_over_R", "check_caption"]


def _checked(name: str, value, lo: float, hi: float, *, lo_open=False, hi_open=False):
    """``value`` as a float array, or ValueError naming it and the allowed interval."""
    arr = np.asarray(value, dtype=float)
    ok = np.isfinite(arr) & ((arr > lo) if lo_open else (arr >= lo))
    ok &= (arr < hi) if hi_open else (arr <= hi)
    if not np.all(ok):
        bad = float(arr[~ok].ravel()[0])
        interval = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"
        raise ValueError(f"{name} must be in {interval}, got {bad!r}")
    return arr


def _out(arr: np.ndarray):
    return float(arr) if np.ndim(arr) == 0 else arr


# --- uniformly shrunk sphere ------------------------------------------------------------------

def U_sphere(dV_over_V, params: ShellParameters):
    """Stretching energy of a uniformly shrunk sphere, small strain (paper eq. Usphere).

        U_sphere = 4 pi R^2 * A / (9 (1 - nu)) * (dV/V)^2

    The leading term of :func:`U_sphere_exact` as dV/V -> 0 (no bending change is counted).
    ``dV_over_V <= 1`` (negative values are an inflation).
    """
    x = _checked("dV_over_V", dV_over_V, -np.inf, 1.0, lo_open=True)
    p = params
    return _out(4.0 * np.pi * p.R ** 2 * p.A / (9.0 * (1.0 - p.nu)) * x ** 2)


def _stretch(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear stretch ratio ``s = (1 - dV/V)^(1/3)`` of a uniformly shrunk sphere and
    ``s^2 - 1 = expm1(2/3 log1p(-dV/V))`` (accurate also for tiny dV/V)."""
    with np.errstate(divide="ignore"):  # dV/V = 1: s = 0, s^2 - 1 = -1
        log_s = np.log1p(-x) / 3.0
    return np.exp(log_s), np.expm1(2.0 * log_s)


def U_sphere_exact(dV_over_V, params: ShellParameters):
    """Exact Green-Lagrange stretching energy of a uniformly shrunk sphere.

    A sphere shrunk to radius ``s R``, ``s = (1 - dV/V)^(1/3)``, has the isotropic
    Green-Lagrange strain ``e = (s^2 - 1)/2`` in both tangent directions. The St Venant-Kirchhoff
    density ``A/(2(1+nu)) [tr(e^2) + nu/(1-nu) (tr e)^2]`` (paper, after eq. Elastic energy)
    is then ``A/(2(1+nu)) [2 e^2 + 4 nu e^2/(1-nu)] = A e^2/(1-nu)`` per reference area, so

        U = 4 pi R^2 * A / (1 - nu) * ((s^2 - 1)/2)^2.

    With ``s^2 - 1 = -2x/3 + O(x^2)`` this is ``U_sphere (1 + x/3 + O(x^2))`` with
    ``x = dV/V``: the two agree to 1 % at dV/V = 0.03. ``dV_over_V <= 1``.
    """
    x = _checked("dV_over_V", dV_over_V, -np.inf, 1.0, lo_open=True)
    p = params
    e = 0.5 * _stretch(x)[1]
    return _out(4.0 * np.pi * p.R ** 2 * p.A / (1.0 - p.nu) * e ** 2)


def pressure_sphere(dV_over_V, params: ShellParameters):
    """Pressure of the small-strain sphere, ``-dU_sphere/dV`` (linear in dV/V):

        p = 2 A / (3 (1 - nu) R) * dV/V.

    ``dV_over_V <= 1``.
    """
    x = _checked("dV_over_V", dV_over_V, -np.inf, 1.0, lo_open=True)
    p = params
    return _out(2.0 * p.A / (3.0 * (1.0 - p.nu) * p.R) * x)


def pressure_sphere_exact(dV_over_V, params: ShellParameters):
    """Exact pressure ``p = -dU/dV`` of the uniformly shrunk sphere of :func:`U_sphere_exact`.

    With ``V = s^3 V0``, ``V0 = 4 pi R^3/3``, ``de/ds = s``:
    ``dU/dV = (8 pi R^2 A e / (1 - nu)) s / (3 s^2 V0)``, hence

        p = -dU/dV = A (1 - s^2) / ((1 - nu) s R),   s = (1 - dV/V)^(1/3),

    which tends to :func:`pressure_sphere` as dV/V -> 0 and diverges as dV/V -> 1.
    ``dV_over_V < 1``.
    """
    x = _checked("dV_over_V", dV_over_V, -np.inf, 1.0, lo_open=True, hi_open=True)
    p = params
    s, s2_minus_1 = _stretch(x)
    return _out(-p.A * s2_minus_1 / ((1.0 - p.nu) * s * p.R))


def pressure_sphere_bending(dV_over_V, params: ShellParameters, c0: float):
    """The bending part of the uniformly shrunk sphere's pressure with spontaneous curvature
    ``c0`` (``c = c1 + c2``, units 1/length): its bending energy ``2 pi f kappa (2 - c0 r)^2``
    at radius ``r = s R`` gives

        p_b = -dE_b/dV = f kappa c0 (2 - c0 r) / r^2,   s = (1 - dV/V)^(1/3),

    (``f`` the convention's bending factor), to be added to :func:`pressure_sphere_exact`:
    small for the sphere's own ``c0 = 2/R`` (``4 f kappa (1 - s)/(s^2 R^3)``, 1e-4 of the
    stretching part at the paper's γ), not for a shell that prefers another curvature."""
    x = _checked("dV_over_V", dV_over_V, -np.inf, 1.0, lo_open=True, hi_open=True)
    p = params
    r = np.cbrt(1.0 - x) * p.R
    return _out(p.bending_factor * p.kappa * c0 * (2.0 - c0 * r) / r ** 2)


# --- inverted spherical cap (capsule) -----------------------------------------------------------

def dV_over_V_of_alpha(alpha):
    """Relative volume lost by mirror-inverting a cap of half-angle ``alpha`` (paper eq.
    deltaV_vs_alpha):

        dV/V = 1/2 (1 - cos a)^2 (2 + cos a) = 2 sin^4(a/2) (2 + cos a)

    (twice the cap volume ``pi R^3 (1 - cos a)^2 (2 + cos a)/3`` over ``4 pi R^3/3``; the second
    form is free of cancellation at small ``a``, where dV/V = 3 a^4/8 + O(a^6)).
    Increasing on ``alpha in [0, pi]`` (derivative 3/2 sin^3 a) onto [0, 2]; the physical
    range is ``alpha <= pi/2`` (dV/V <= 1), beyond it the cap would cross the opposite side.
    """
    a = _checked("alpha", alpha, 0.0, np.pi)
    return _out(2.0 * np.sin(0.5 * a) ** 4 * (2.0 + np.cos(a)))


def alpha_of_dV_over_V(dV_over_V):
    """Inverse of :func:`dV_over_V_of_alpha` in closed form, ``dV_over_V in [0, 2]`` ->
    ``alpha in [0, pi]`` (physical range [0, 1] -> [0, pi/2]).

    ``c = cos a`` solves the cubic ``c^3 - 3c + 2 - 2x = 0``; its root in [-1, 1] is
    (trigonometric method) ``c = 2 cos((pi + psi)/3)`` with ``psi = arccos(1 - x)
    = 2 arcsin(sqrt(x/2))``. Written without cancellation, with ``chi = pi - psi
    = 2 arcsin(sqrt((2 - x)/2))``:

        (1 - c)/2 = 2 sin(pi/3 + psi/6) sin(psi/6),   alpha = 2 arcsin(sqrt((1 - c)/2))
        (1 + c)/2 = 2 cos(psi/6) sin(chi/6),          alpha = pi - 2 arcsin(sqrt((1 + c)/2))

    the first used for x <= 1, the second for x > 1, so that alpha is accurate to a few ulps
    at both ends (alpha = (8x/3)^(1/4) for small x). The inverse is ill-conditioned near x = 2
    (2 - x ~ 3 (pi - alpha)^4 / 8).
    """
    x = _checked("dV_over_V", dV_over_V, 0.0, 2.0)
    psi = 2.0 * np.arcsin(np.sqrt(0.5 * x))
    chi = 2.0 * np.arcsin(np.sqrt(0.5 * (2.0 - x)))
    half_one_minus_c = 2.0 * np.sin(np.pi / 3.0 + psi / 6.0) * np.sin(psi / 6.0)
    half_one_plus_c = 2.0 * np.cos(psi / 6.0) * np.sin(chi / 6.0)
    small = 2.0 * np.arcsin(np.sqrt(np.clip(half_one_minus_c, 0.0, 1.0)))
    large = np.pi - 2.0 * np.arcsin(np.sqrt(np.clip(half_one_plus_c, 0.0, 1.0)))
    return _out(np.where(x <= 1.0, small, large))


def _delta(params: ShellParameters) -> float:
    return params.d_over_R  # ValueError unless -1 < nu < 1/2


def _standard(params: ShellParameters) -> ShellParameters:
    """The helfrich shell with the energy of ``params`` (module docstring)."""
    return params.helfrich_equivalent()


def U_axisym(alpha, params: ShellParameters):
    """Energy of the capsule, an inverted cap of half-angle ``alpha`` (paper eq. Ucapsule):

        U_axisym = pi (A R^2/gamma) (d/R)^(-1/2)
                   [ sin a (tan a - (d/R)^(1/2))^2 + 4 (d/R)^(1/2) (1 - cos a) ]

    with ``A R^2/gamma = kappa`` and ``d/R`` from gamma, nu (eq. DefFvK_lambda; needs
    -1 < nu < 1/2). The bracket is evaluated in the equivalent form
    ``sin^3 a / cos^2 a - 2 (d/R)^(1/2) (1 - cos a)^2 / cos a + (d/R) sin a``, which has no
    cancellation of its O(a^2) terms. ``alpha in [0, pi/2)``: the formula diverges as
    ``alpha -> pi/2`` (dV/V -> 1) like ``(1 - dV/V)^(-2)``, which makes ``U_axisym`` cross
    ``U_sphere`` a second time near dV/V ~ 0.9; that crossing is an artefact of the formula.
    """
    a = _checked("alpha", alpha, 0.0, np.pi / 2.0, hi_open=True)
    params = _standard(params)
    delta = _delta(params)
    root = math.sqrt(delta)
    sin_a, cos_a = np.sin(a), np.cos(a)
    one_minus_cos = 2.0 * np.sin(0.5 * a) ** 2
    bracket = (sin_a ** 3 / cos_a ** 2 - 2.0 * root * one_minus_cos ** 2 / cos_a
               + delta * sin_a)
    return _out(np.pi * params.kappa / root * bracket)


def U_axisym_of_dV(dV_over_V, params: ShellParameters):
    """:func:`U_axisym` at ``alpha = alpha_of_dV_over_V(dV/V)``, ``dV_over_V in [0, 1)``."""
    x = _checked("dV_over_V", dV_over_V, 0.0, 1.0, hi_open=True)
    return U_axisym(alpha_of_dV_over_V(x), params)


def U_axisym_small_alpha(alpha, params: ShellParameters):
    """Leading terms of :func:`U_axisym` as ``alpha -> 0`` at fixed d/R:

        U_axisym = pi kappa (d/R)^(-1/2) [ a^3 + (d/R) a - (d/R)^(1/2) a^4 / 2 + a^5 / 2 + ... ]
                ~= pi kappa (d/R)^(-1/2) (a^3 + (d/R) a)

    (the O(a^2) terms of the bracket cancel). The ``(d/R) a`` term dominates for
    ``a < (d/R)^(1/2)``; the paper's thin-shell form :func:`U_axisym_asymptotic` drops it.
    """
    a = _checked("alpha", alpha, 0.0, np.pi / 2.0, hi_open=True)
    params = _standard(params)
    delta = _delta(params)
    return _out(np.pi * params.kappa / math.sqrt(delta) * (a ** 3 + delta * a))


def U_axisym_asymptotic(alpha, params: ShellParameters):
    """Paper's thin-shell, small-angle form of eq. Ucapsule, in ``alpha``:

        U_axisym ~= pi / 12^(1/4) * A R^2 gamma^(-3/4) [1 - 2 nu^2/(1 - nu)]^(-1/4) * a^3

    which is ``pi kappa (d/R)^(-1/2) a^3``, exactly (prefactor checked). Valid for
    ``(d/R)^(1/2) << a << 1``: relative to :func:`U_axisym` the error is
    ``(d/R)/a^2 - (d/R)^(1/2) a/2 + a^2/2 + ...``, so at fixed gamma the ratio does *not*
    tend to 1 as ``a -> 0`` (see :func:`U_axisym_small_alpha`); it does when gamma -> inf with
    ``a`` small, e.g. along ``a = (d/R)^(1/4)``.
    """
    a = _checked("alpha", alpha, 0.0, np.pi / 2.0, hi_open=True)
    p = _standard(params)
    factor = thickness_factor(p.nu)
    if not factor > 0:
        _delta(p)  # raises: nu outside (-1, 1/2)
    pref = np.pi / 12.0 ** 0.25 * p.A * p.R ** 2 * p.gamma ** -0.75 * float(factor) ** -0.25
    return _out(pref * a ** 3)


def U_axisym_asymptotic_of_dV(dV_over_V, params: ShellParameters):
    """Paper's thin-shell, small-volume form of eq. Ucapsule, in ``x = dV/V``:

        U_axisym ~= 4/3 * pi / 2^(1/4) * A R^2 gamma^(-3/4) [1 - 2 nu^2/(1 - nu)]^(-1/4) x^(3/4)

    This is :func:`U_axisym_asymptotic` with ``a = (8x/3)^(1/4)`` (leading order of eq.
    deltaV_vs_alpha), since ``12^(-1/4) (8/3)^(3/4) = 2^(7/4)/3 = (4/3) 2^(-1/4)``: the
    printed prefactor is right (checked in the tests; no typo). Same validity as the alpha
    form: ``d/R << (dV/V)^(1/2) << 1``. ``dV_over_V in [0, 1)``.
    """
    x = _checked("dV_over_V", dV_over_V, 0.0, 1.0, hi_open=True)
    p = _standard(params)
    factor = thickness_factor(p.nu)
    if not factor > 0:
        _delta(p)
    pref = (4.0 / 3.0) * np.pi / 2.0 ** 0.25 * p.A * p.R ** 2 * p.gamma ** -0.75
    return _out(pref * float(factor) ** -0.25 * x ** 0.75)


# --- primary buckling estimates -----------------------------------------------------------------

def crossing_asymptotic(params: ShellParameters) -> float:
    """``dV/V`` where U_sphere equals the paper's asymptotic U_axisym (eq. PowerLawBuckling2):

        dV/V = [3 (1 - nu)]^(4/5) 2^(-1/5) [1 - 2 nu^2/(1 - nu)]^(-1/5) gamma^(-3/5)

    (= 2^(3/5) (3/2)^(1/5) gamma^(-3/5) ~= 1.644 gamma^(-3/5) at nu = 1/3). The exact crossing
    (:func:`crossing`) approaches it as gamma -> inf, with a relative correction ~ d/R / a^2,
    which decays only like gamma^(-1/5). ``gamma`` is the effective one of the convention.
    """
    p = _standard(params)
    factor = thickness_factor(p.nu)
    if not factor > 0:
        _delta(p)
    return float((3.0 * (1.0 - p.nu)) ** 0.8 * 2.0 ** -0.2 * float(factor) ** -0.2
                 * p.gamma ** -0.6)


def crossing(params: ShellParameters, sphere: str = "small_strain") -> float:
    """First ``dV/V`` at which ``U_sphere = U_axisym`` (eq. Ucapsule with eq. deltaV_vs_alpha),
    the energetic threshold of the sphere -> capsule buckling (the simulated buckling happens
    later, with hysteresis).

    ``sphere="small_strain"`` uses eq. Usphere (as the paper's Fig. 9), ``"exact"`` uses
    :func:`U_sphere_exact`. Solved with ``brentq`` on ``log U_axisym - log U_sphere`` in
    ``log(dV/V)``, bracketed by the first sign change on a fine logarithmic grid. U_axisym is
    above U_sphere near 0 (as (dV/V)^(1/4) against (dV/V)^2) and near 1 (divergence); below
    some gamma (~ 60 at nu = 1/3) it is above everywhere and ``ValueError`` is raised.
    """
    energies = {"small_strain": U_sphere, "exact": U_sphere_exact}
    if sphere not in energies:
        raise ValueError(f"sphere must be one of {sorted(energies)}, got {sphere!r}")
    u_sphere = energies[sphere]
    _delta(_standard(params))

    def gap(t):
        x = np.exp(t)
        return np.log(U_axisym_of_dV(x, params)) - np.log(u_sphere(x, params))

    t_lo = math.log(min(1e-3, 1e-3 * crossing_asymptotic(params)))
    t = np.linspace(t_lo, math.log1p(-1e-9), 4001)
    g = gap(t)
    change = np.flatnonzero((g[:-1] > 0) & (g[1:] <= 0))
    if change.size == 0:
        raise ValueError(f"U_axisym > U_sphere for all dV/V in (0, 1) at gamma = "
                         f"{params.gamma:g}, nu = {params.nu:g}: no crossing (gamma too small)")
    i = int(change[0])
    if g[i + 1] == 0.0:
        return float(np.exp(t[i + 1]))
    from scipy.optimize import brentq  # SciPy's optimize takes 0.4 s to import

    return float(np.exp(brentq(gap, t[i], t[i + 1], xtol=1e-14, rtol=1e-14)))


@dataclass(frozen=True)
class ClassicalThreshold:
    """Classical (Zoelly) buckling of a pressurized sphere and its volume-control estimate.

    ``pressure``: ``p_c = 4 sqrt(kappa A) / R^2`` (energy / length^3), linear shell theory,
    independent of nu; with kappa = E d^3/(12(1-sigma^2)) and A -> E d it is the textbook
    ``2 E d^2 / (sqrt(3(1 - sigma^2)) R^2)``.
    ``dV_over_V``: the sphere's linear pressure-volume relation
    ``p = 2 A/(3(1 - nu) R) dV/V`` (:func:`pressure_sphere`) at ``p = p_c``:
    ``dV/V = 6 (1 - nu) sqrt(kappa/A) / R = 6 (1 - nu) / sqrt(gamma)``
    (> 1 for gamma < 36 (1-nu)^2: no threshold within reach).
    ``dV_over_V_exact``: the same with the exact Green-Lagrange pressure
    (:func:`pressure_sphere_exact`), always in (0, 1).
    """

    pressure: float
    dV_over_V: float
    dV_over_V_exact: float


def classical_pressure(params: ShellParameters) -> float:
    """The classical buckling pressure ``p_c = 4 sqrt(kappa A) / R^2`` of
    :class:`ClassicalThreshold` alone, without the root search of its exact ``dV/V`` (which
    needs SciPy's optimize, 0.3 s to import in a run that only shows ``p/p_c``)."""
    p = _standard(params)
    return 4.0 * math.sqrt(p.kappa * p.A) / p.R ** 2


def pressure_bounds(params: ShellParameters) -> tuple[float, float]:
    """The overpressures a pressure-controlled shell can take, ``[low, high)`` in its own
    units (kappa/R^3 in reduced units, Pa for a material): ``low = -gamma kappa/R^3`` (below
    it the shell more than doubles its volume) and ``high`` the classical buckling pressure
    (above it the shell has no equilibrium near the sphere and turns inside out)."""
    return -params.gamma * params.kappa / params.R ** 3, classical_pressure(params)


def classical_threshold(params: ShellParameters) -> ClassicalThreshold:
    """Classical buckling pressure and the dV/V at which the shrunk sphere reaches it (with the
    bending modulus and gamma of the standard equivalent of the convention)."""
    p = _standard(params)
    p_c = classical_pressure(params)
    linear = 6.0 * (1.0 - p.nu) / math.sqrt(p.gamma)
    from scipy.optimize import brentq

    # p_exact increases from 0 (x = 0) to +inf (x -> 1); bracket [0, 1 - 1e-15]
    exact = brentq(lambda x: pressure_sphere_exact(x, p) - p_c, 0.0, 1.0 - 1e-15,
                   xtol=1e-15, rtol=1e-14)
    return ClassicalThreshold(pressure=p_c, dV_over_V=linear, dV_over_V_exact=float(exact))


def summary(params: ShellParameters) -> dict:
    """The theory's numbers for ``params`` as a plain dictionary.

    Keys: ``gamma``, ``nu``, ``kappa``, ``A``, ``R``, ``d_over_R`` (None if nu >= 1/2),
    ``energy_convention``, ``gamma_effective`` and ``d_over_R_effective`` (the standard shell
    with the same energy; equal to gamma and d_over_R under helfrich),
    ``crossing_dV_over_V`` (eq. Usphere = eq. Ucapsule), ``crossing_dV_over_V_exact_sphere``
    (Green-Lagrange sphere), ``crossing_asymptotic_dV_over_V`` (power law), each None when
    undefined (no crossing, or nu >= 1/2), ``classical_pressure`` (p_c),
    ``classical_dV_over_V`` (6 (1 - nu)/sqrt(gamma)) and ``classical_dV_over_V_exact``.
    """
    p = params
    out = {"gamma": p.gamma, "nu": p.nu, "kappa": p.kappa, "A": p.A, "R": p.R,
           "energy_convention": p.energy_convention, "gamma_effective": p.gamma_effective,
           "d_over_R": None, "d_over_R_effective": None, "crossing_dV_over_V": None,
           "crossing_dV_over_V_exact_sphere": None, "crossing_asymptotic_dV_over_V": None}
    if p.nu < 0.5:
        out["d_over_R"] = p.d_over_R
        out["d_over_R_effective"] = p.d_over_R_effective
        out["crossing_asymptotic_dV_over_V"] = crossing_asymptotic(p)
        for key, sphere in (("crossing_dV_over_V", "small_strain"),
                            ("crossing_dV_over_V_exact_sphere", "exact")):
            try:
                out[key] = crossing(p, sphere=sphere)
            except ValueError:  # no crossing at this gamma
                out[key] = None
    threshold = classical_threshold(p)
    out.update(classical_pressure=threshold.pressure, classical_dV_over_V=threshold.dV_over_V,
               classical_dV_over_V_exact=threshold.dV_over_V_exact)
    return out
