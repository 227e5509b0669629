"""Shell parameters: Foppl-von Karman number gamma and 2D Poisson ratio nu, or a 3D material.

The model (Quilliet et al., EPJE 27, 13 (2008), section 3) has three surface moduli: the bending
modulus ``kappa``, the 2D Young modulus ``A`` and the 2D Poisson ratio ``nu``. Conformations
depend only on

    gamma = A R^2 / kappa            (Foppl-von Karman number)

and ``nu``. A shell cut from an isotropic 3D material of Young modulus ``E``, Poisson ratio
``sigma`` and thickness ``d`` has (paper, after Landau's "longitudinal" deformation)

    kappa = E d^3 / (12 (1 - sigma^2))                       (paper eq. StretchModulusX2)
    A     = (1 + 2 sigma) / (1 + sigma)^2 * E d
    nu    = sigma / (1 + sigma)          <=>  sigma = nu / (1 - nu)
    gamma = 12 (1 - 2 sigma^2/(1 + sigma)) (R/d)^2
          = 12 (1 - 2 nu^2/(1 - nu)) (R/d)^2                 (paper eq. DefFvK_lambda)

so ``d/R = sqrt(12 (1 - 2 nu^2/(1 - nu)) / gamma)``, defined for -1 < nu < 1/2. Since
sigma <= 1/2 for any isotropic material, nu <= 1/3; a larger nu is accepted (the 2D model is
well posed for -1 < nu < 1) but warned about.

Units: ``R = 1`` and ``kappa = 1`` unless given, so ``A = gamma``.

Energy convention (which bending energy ``kappa`` multiplies). The paper's eq. (1) writes
``1/2 kappa (c - c0)^2`` with ``c0 = 1/R`` on the stress-free sphere, so its ``c`` is a mean
curvature, while the standard thin-plate energy has ``c = c1 + c2``. Three readings
(:data:`ENERGY_CONVENTIONS`), all the same model up to the factor ``f`` on ``kappa``:

    helfrich         1/2 kappa (c1 + c2 - c0)^2,  c0 = 2/R    f = 1    (thin plate; default)
    paper            1/2 kappa (H - H0)^2,        H0 = 1/R    f = 1/4  (eq. (1) read literally)
    evolver-modulus  kappa (H - H0)^2,            H0 = 1/R    f = 1/2  (Surface Evolver's
                     star_perp_sq_mean_curvature with modulus kappa, h_zero = 1/R)

with ``H = (c1 + c2)/2``. A shell of parameters (gamma, nu, kappa) under a convention is the
standard (helfrich) shell with bending modulus ``f kappa`` and the same ``A``: its shapes are
those of the standard shell at ``gamma_effective = gamma / f`` (4 gamma under ``paper``), and
its energies are those of that shell in absolute units. ``gamma``, ``kappa``, ``E/kappa`` and
pressures in ``kappa/R^3`` are always in the units of the ``kappa`` given. The material
conversions below define ``kappa`` and ``A`` as the paper does; under ``paper`` a shell of
thickness ``d`` then behaves as the standard shell of thickness ``d/2`` (``d/sqrt(2)`` under
``evolver-modulus``): :attr:`ShellParameters.d_over_R_effective`.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from decimal import Decimal

import numpy as np

__all__ = ["ShellParameters", "PhysicalRangeWarning", "d_over_R", "gamma_from_d_over_R",
           "thickness_factor", "check_caption", "ENERGY_CONVENTIONS", "DEFAULT_CONVENTION",
           "bending_factor", "check_convention", "convention_formula", "UNITS", "UNIT_SYSTEMS",
           "unit_scale", "to_si", "to_reduced"]

_REL_TOL = 1e-9  # agreement required between stored derived values and recomputed ones


ENERGY_CONVENTIONS = {
    "helfrich": "1/2 kappa (c1 + c2 - c0)^2, c0 = 2/R (standard thin-plate reading)",
    "paper": "1/2 kappa (H - H0)^2, H = (c1 + c2)/2, H0 = 1/R (the paper's eq. (1) read "
             "literally): the helfrich shell with kappa/4, i.e. at 4 gamma",
    "evolver-modulus": "kappa (H - H0)^2, H0 = 1/R (Surface Evolver's "
                       "star_perp_sq_mean_curvature with modulus kappa): the helfrich shell "
                       "with kappa/2, i.e. at 2 gamma",
}
"""The energy conventions: name -> the bending energy density that ``kappa`` multiplies."""
DEFAULT_CONVENTION = "helfrich"
_FACTORS = {"helfrich": 1.0, "paper": 0.25, "evolver-modulus": 0.5}
_DENSITIES = {"helfrich": "1/2 kappa (c1 + c2 - c0)^2", "paper": "1/2 kappa (H - H0)^2",
              "evolver-modulus": "kappa (H - H0)^2"}

MAIN_JOB_GAMMA = 15163.0
"""gamma of ``deflate()`` and ``shellbuckle deflate`` without parameters: in the wrinkled regime
of our runs on the paper's mesh (a capsule, polygonal from dV/V = 0.13, wrinkled with W = 4-5
from 0.27; docs/reproduction.md)."""


def convention_formula(convention: str) -> str:
    """The bending energy density of a convention, e.g. ``"1/2 kappa (H - H0)^2"``."""
    return _DENSITIES[check_convention(convention)]


CONVENTION_HELP = (
    "which bending energy kappa multiplies: helfrich = 1/2 kappa (c1+c2-c0)^2, c0 = 2/R (the "
    "standard thin plate; default); paper = 1/2 kappa (H-H0)^2, H0 = 1/R, the paper's eq. (1) "
    "read literally (the helfrich shell at 4 gamma: a material of thickness d behaves as one "
    "of thickness d/2); evolver-modulus = kappa (H-H0)^2, Surface Evolver's "
    "star_perp_sq_mean_curvature with modulus kappa (2 gamma, thickness d/sqrt(2)). gamma = "
    "A R^2/kappa, E/kappa and pressures in kappa/R^3 are in units of the kappa given")
"""The energy conventions explained in one paragraph (command-line help)."""


def check_convention(name) -> str:
    """``name`` if it is an energy convention, else ``ValueError`` naming it and the choices."""
    if not isinstance(name, str) or name not in _FACTORS:
        raise ValueError(f"energy convention must be one of {', '.join(_FACTORS)}, got {name!r}")
    return name


def bending_factor(convention: str) -> float:
    """``f`` of an energy convention: its bending energy is the helfrich one with ``f kappa``
    (1 for helfrich, 1/4 for paper, 1/2 for evolver-modulus)."""
    return _FACTORS[check_convention(convention)]


class PhysicalRangeWarning(UserWarning):
    """A parameter is mathematically allowed but no isotropic 3D material has it."""


def thickness_factor(nu):
    """The factor ``1 - 2 nu^2 / (1 - nu)`` of paper eq. DefFvK_lambda (vectorized).

    It equals ``(1 + 2 sigma)(1 - sigma)/(1 + sigma)`` with ``sigma = nu/(1 - nu)``, is 2/3 at
    nu = 1/3 and is positive exactly for -1 < nu < 1/2.
    """
    nu = np.asarray(nu, dtype=float)
    return 1.0 - 2.0 * nu ** 2 / (1.0 - nu)


def _check_nu_for_thickness(nu) -> np.ndarray:
    nu = np.asarray(nu, dtype=float)
    if not np.all(np.isfinite(nu)) or np.any(nu <= -1.0) or np.any(nu >= 0.5):
        bad = float(nu[~(np.isfinite(nu) & (nu > -1.0) & (nu < 0.5))].ravel()[0])
        raise ValueError(
            f"d/R is undefined for nu = {bad!r}: gamma = 12 (1 - 2 nu^2/(1-nu)) (R/d)^2 needs "
            f"1 - 2 nu^2/(1-nu) > 0, i.e. -1 < nu < 1/2")
    return nu


def d_over_R(gamma, nu=1.0 / 3.0):
    """Relative thickness ``d/R = sqrt(12 (1 - 2 nu^2/(1 - nu)) / gamma)`` (vectorized).

    Inverse of paper eq. DefFvK_lambda. ``gamma > 0`` (finite) and ``-1 < nu < 1/2``; at
    nu = 1/3 this is ``sqrt(8 / gamma)``. Broadcasts ``gamma`` and ``nu``; returns a float for
    scalar input.
    """
    gamma = np.asarray(gamma, dtype=float)
    bad = ~(np.isfinite(gamma) & (gamma > 0))
    if np.any(bad):
        first = float(gamma[bad].ravel()[0])
        raise ValueError(f"gamma must be a finite number > 0, got {first!r}")
    nu = _check_nu_for_thickness(nu)
    out = np.sqrt(12.0 * thickness_factor(nu) / gamma)
    return float(out) if out.ndim == 0 else out


def gamma_from_d_over_R(d_over_R, nu=1.0 / 3.0):
    """Foppl-von Karman number ``gamma = 12 (1 - 2 nu^2/(1 - nu)) (R/d)^2`` (paper eq.
    DefFvK_lambda, vectorized). ``0 < d/R < 1`` and ``-1 < nu < 1/2``."""
    ratio = np.asarray(d_over_R, dtype=float)
    bad = ~(np.isfinite(ratio) & (ratio > 0) & (ratio < 1))
    if np.any(bad):
        first = float(ratio[bad].ravel()[0])
        raise ValueError(f"d_over_R must be a number in (0, 1), got {first!r}")
    nu = _check_nu_for_thickness(nu)
    out = 12.0 * thickness_factor(nu) / ratio ** 2
    return float(out) if out.ndim == 0 else out


def _half_unit_of_last_digit(x) -> float:
    """Half a unit in the last written decimal of ``x`` (given as str, int or shortest float)."""
    # a string keeps its trailing zeros; a number is read from its shortest repr
    digits = Decimal(x.strip()) if isinstance(x, str) else Decimal(repr(float(x))).normalize()
    exponent = digits.as_tuple().exponent
    return 0.5 * 10.0 ** min(int(exponent), 0) if isinstance(exponent, int) else 0.0


def check_caption(gamma, d_over_R_caption, nu=1.0 / 3.0) -> bool:
    """Whether a printed pair (gamma, d/R) agrees with eq. DefFvK_lambda to its printed precision.

    Each printed number stands for an interval of half a unit in its last written digit
    (``0.064`` for [0.0635, 0.0645], ``2916`` for [2915.5, 2916.5]); pass the numbers as
    printed (a float's shortest repr, or a string, e.g. ``"0.0640"`` to keep a trailing zero).
    The pair agrees when d/R computed from some gamma in its interval falls in the d/R
    interval. ``nu`` is used as given (the paper's captions print nu = 0.333 for 1/3).
    """
    g, r = float(gamma), float(d_over_R_caption)
    dg, dr = _half_unit_of_last_digit(gamma), _half_unit_of_last_digit(d_over_R_caption)
    # d/R decreases with gamma: the image of [g - dg, g + dg] is [d(g + dg), d(g - dg)]
    lo = d_over_R(g + dg, nu)
    hi = d_over_R(max(g - dg, np.nextafter(0.0, 1.0)), nu)
    eps = 1e-12 * max(r, hi)
    return bool(lo <= r + dr + eps and hi >= r - dr - eps)


#: The physical dimensions of the quantities of a run: name -> (reduced unit, SI unit, powers
#: of kappa and R in the reduced unit). Energies in kappa, pressures in kappa/R^3 (the paper's
#: p R^3/kappa), lengths in R, curvatures in 1/R, forces (energy gradients) in kappa/R.
UNITS = {"energy": ("kappa", "J", 1, 0), "pressure": ("kappa/R^3", "Pa", 1, -3),
         "length": ("R", "m", 0, 1), "curvature": ("1/R", "1/m", 0, -1),
         "force": ("kappa/R", "N", 1, -1)}
#: The unit systems of a run's results: reduced (kappa, R) and SI (a material's).
UNIT_SYSTEMS = ("reduced", "si")


def unit_scale(params: ShellParameters, dimension: str) -> float:
    """The reduced unit of ``dimension`` (:data:`UNITS`) in the units of ``params``:
    ``kappa`` for an energy, ``kappa/R^3`` for a pressure, ``R`` for a length, ``1/R`` for a
    curvature, ``kappa/R`` for a force. For a shell made from a material
    (:meth:`ShellParameters.from_material`, ``kappa = E d^3/(12 (1 - sigma^2))``) given in SI
    (E in Pa, d and R in m) it is in J, Pa, m, 1/m, N."""
    if dimension not in UNITS:
        raise ValueError(f"dimension must be one of {', '.join(UNITS)}, got {dimension!r}")
    _, _, kappa_power, R_power = UNITS[dimension]
    return params.kappa ** kappa_power * params.R ** R_power


def to_si(value, dimension: str, params: ShellParameters):
    """``value`` given in reduced units (``E/kappa``, ``p R^3/kappa``, ``x/R``, ...) in the
    units of the material of ``params`` (SI when E, d and R were given in SI): ``value *
    unit_scale(params, dimension)``, vectorized. ``ValueError`` for a shell given by gamma
    alone, which has no physical size."""
    if not params.is_material:
        raise ValueError("the shell has no material (E, sigma, d, R): its results have no SI "
                         "values; make it with ShellParameters.from_material")
    return np.asarray(value, dtype=float) * unit_scale(params, dimension) \
        if np.ndim(value) else float(value) * unit_scale(params, dimension)


def to_reduced(value, dimension: str, params: ShellParameters):
    """``value`` in the units of ``params`` (as a run stores it) in reduced units:
    ``value / unit_scale(params, dimension)``, vectorized."""
    return np.asarray(value, dtype=float) / unit_scale(params, dimension) \
        if np.ndim(value) else float(value) / unit_scale(params, dimension)


_ALLOWED = {"gamma": "> 0", "nu": "in (-1, 1)", "kappa": "> 0", "R": "> 0", "E": "> 0",
            "d": "in (0, R)", "sigma": "in (-1, 0.5]"}


def _require_finite(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a real number {_ALLOWED[name]}, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number {_ALLOWED[name]}, got {value!r}")
    return value


@dataclass(frozen=True)
class ShellParameters:
    """Elastic parameters of a thin spherical shell (immutable).

    Defining fields: ``gamma`` (Foppl-von Karman number A R^2/kappa, > 0), ``nu`` (2D Poisson
    ratio, in (-1, 1)), ``kappa`` (bending modulus, energy, > 0) and ``R`` (initial radius,
    > 0). ``E`` (3D Young modulus, energy/length^3) and ``d`` (thickness, 0 < d < R) are set
    only for a shell built from a material (:meth:`from_material`), then both are set and
    consistent with ``gamma``, ``nu`` and ``kappa``.

    Derived: ``A = gamma kappa / R^2`` (2D Young modulus), ``sigma = nu/(1 - nu)`` (3D Poisson
    ratio), ``d_over_R`` from eq. DefFvK_lambda. Construct with :meth:`from_gamma` or
    :meth:`from_material`; bad values raise ``ValueError`` naming the value and the allowed
    range; nu > 1/3 warns with :class:`PhysicalRangeWarning`.

    ``energy_convention`` (module docstring): which bending energy ``kappa`` multiplies,
    ``"helfrich"`` (default), ``"paper"`` or ``"evolver-modulus"``. The energy terms use
    :attr:`kappa_helfrich`; :attr:`gamma_effective` is the gamma of the equivalent standard
    shell (:meth:`helfrich_equivalent`).
    """

    gamma: float
    nu: float = 1.0 / 3.0
    kappa: float = 1.0
    R: float = 1.0
    E: float | None = None
    d: float | None = None
    energy_convention: str = DEFAULT_CONVENTION

    def __post_init__(self):
        check_convention(self.energy_convention)
        for name in ("gamma", "nu", "kappa", "R"):
            object.__setattr__(self, name, _require_finite(name, getattr(self, name)))
        for name in ("E", "d"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _require_finite(name, getattr(self, name)))
        if self.gamma <= 0:
            raise ValueError(f"gamma = A R^2/kappa must be > 0, got {self.gamma!r}")
        if not -1.0 < self.nu < 1.0:
            raise ValueError(f"nu (2D Poisson ratio) must be in (-1, 1), got {self.nu!r}")
        if self.kappa <= 0:
            raise ValueError(f"kappa (bending modulus) must be > 0, got {self.kappa!r}")
        if self.R <= 0:
            raise ValueError(f"R (radius) must be > 0, got {self.R!r}")
        if (self.E is None) != (self.d is None):
            raise ValueError("E and d must be given together (a material) or not at all, got "
                             f"E = {self.E!r}, d = {self.d!r}")
        if self.E is not None:
            self._check_material()
        if self.nu > 1.0 / 3.0:
            warnings.warn(
                f"nu = {self.nu:.4g} > 1/3: no isotropic 3D material has a 2D Poisson ratio "
                "nu = sigma/(1+sigma) above 1/3 (sigma <= 1/2)", PhysicalRangeWarning,
                stacklevel=3)

    def _check_material(self) -> None:
        if self.E <= 0:
            raise ValueError(f"E (3D Young modulus) must be > 0, got {self.E!r}")
        if self.d <= 0 or self.d >= self.R:
            raise ValueError(f"d (thickness) must be in (0, R) = (0, {self.R!r}), got {self.d!r}")
        sigma = self.sigma
        kappa = self.E * self.d ** 3 / (12.0 * (1.0 - sigma ** 2))
        gamma = gamma_from_d_over_R(self.d / self.R, self.nu)
        for name, stored, expected in (("kappa", self.kappa, kappa), ("gamma", self.gamma, gamma)):
            if not math.isclose(stored, expected, rel_tol=_REL_TOL):
                raise ValueError(f"{name} = {stored!r} is inconsistent with the material "
                                 f"(E = {self.E!r}, sigma = {sigma!r}, d = {self.d!r}, "
                                 f"R = {self.R!r}), which gives {name} = {expected!r}")

    # -- constructors ---------------------------------------------------------------------
    @classmethod
    def from_gamma(cls, gamma: float, nu: float = 1.0 / 3.0, kappa: float = 1.0,
                   R: float = 1.0, energy_convention: str = DEFAULT_CONVENTION
                   ) -> ShellParameters:
        """Parameters from the Foppl-von Karman number; ``A = gamma kappa / R^2``."""
        return cls(gamma=gamma, nu=nu, kappa=kappa, R=R, energy_convention=energy_convention)

    @classmethod
    def from_material(cls, E: float, sigma: float, d: float, R: float,
                      energy_convention: str = DEFAULT_CONVENTION) -> ShellParameters:
        """Parameters of a shell of thickness ``d`` and radius ``R`` cut from an isotropic
        material (Young modulus ``E``, Poisson ratio ``sigma`` in (-1, 1/2]).

        kappa = E d^3/(12(1 - sigma^2)), A = (1 + 2 sigma)/(1 + sigma)^2 E d,
        nu = sigma/(1 + sigma), gamma = A R^2/kappa = 12(1 - 2 nu^2/(1 - nu))(R/d)^2.
        sigma must also exceed -1/2 for A > 0 (equivalently nu > -1).
        ``kappa`` multiplies the bending energy of ``energy_convention``: under ``paper`` the
        shell behaves as the standard one of thickness ``d/2`` (:attr:`d_over_R_effective`).
        """
        check_convention(energy_convention)
        E, sigma = _require_finite("E", E), _require_finite("sigma", sigma)
        d, R = _require_finite("d", d), _require_finite("R", R)
        if not -1.0 < sigma <= 0.5:
            raise ValueError(f"sigma (3D Poisson ratio) must be in (-1, 0.5], got {sigma!r}")
        if sigma <= -0.5:
            raise ValueError(f"sigma = {sigma!r} gives nu = sigma/(1+sigma) = "
                             f"{sigma / (1 + sigma):.4g} and A <= 0; the 2D model needs "
                             "sigma in (-0.5, 0.5]")
        if R <= 0:
            raise ValueError(f"R (radius) must be > 0, got {R!r}")
        if E <= 0:
            raise ValueError(f"E (3D Young modulus) must be > 0, got {E!r}")
        if d <= 0 or d >= R:
            raise ValueError(f"d (thickness) must be in (0, R) = (0, {R!r}), got {d!r}")
        kappa = E * d ** 3 / (12.0 * (1.0 - sigma ** 2))
        A = (1.0 + 2.0 * sigma) / (1.0 + sigma) ** 2 * E * d
        nu = sigma / (1.0 + sigma)
        return cls(gamma=A * R ** 2 / kappa, nu=nu, kappa=kappa, R=R, E=E, d=d,
                   energy_convention=energy_convention)

    def with_gamma(self, gamma: float) -> ShellParameters:
        """The same shell (nu, kappa, R, energy convention) at another gamma (another A); a
        material's E and d are dropped unless gamma is unchanged."""
        if gamma == self.gamma:
            return self
        return ShellParameters(gamma=gamma, nu=self.nu, kappa=self.kappa, R=self.R,
                               energy_convention=self.energy_convention)

    def with_convention(self, energy_convention: str) -> ShellParameters:
        """The same numbers (gamma, nu, kappa, R; E and d) read under another convention."""
        return dataclasses.replace(self, energy_convention=check_convention(energy_convention))

    def helfrich_equivalent(self) -> ShellParameters:
        """The standard (helfrich) shell with the same energy: bending modulus
        :attr:`kappa_helfrich`, the same ``A``, ``nu`` and ``R``, ``gamma_effective``. Itself
        under helfrich; a material's E and d are dropped otherwise."""
        if self.energy_convention == DEFAULT_CONVENTION:
            return self
        return ShellParameters(gamma=self.gamma_effective, nu=self.nu, kappa=self.kappa_helfrich,
                               R=self.R)

    # -- derived quantities ---------------------------------------------------------------
    @property
    def A(self) -> float:
        """2D Young modulus ``gamma kappa / R^2`` (energy / length^2)."""
        return self.gamma * self.kappa / self.R ** 2

    @property
    def bending_factor(self) -> float:
        """``f``: the bending energy is the helfrich one with ``f kappa`` (module docstring)."""
        return bending_factor(self.energy_convention)

    @property
    def kappa_helfrich(self) -> float:
        """Bending modulus of the energy written ``1/2 kappa_H (c1 + c2 - c0)^2``, ``f kappa``:
        the modulus the energy terms use."""
        return self.bending_factor * self.kappa

    @property
    def gamma_effective(self) -> float:
        """``A R^2 / kappa_helfrich = gamma / f``: the gamma of the standard shell with these
        shapes (4 gamma under ``paper``, 2 gamma under ``evolver-modulus``)."""
        return self.gamma / self.bending_factor

    @property
    def d_over_R_effective(self) -> float:
        """Relative thickness of the standard thin-plate shell that behaves as this one,
        ``d_over_R(gamma_effective, nu)``: :attr:`d_over_R` times ``sqrt(f)``."""
        return d_over_R(self.gamma_effective, self.nu)

    @property
    def convention_note(self) -> str:
        """``""`` under helfrich, else ``", energy convention paper (gamma_eff = 11664)"``:
        to append to a title or a line that names gamma."""
        if self.energy_convention == DEFAULT_CONVENTION:
            return ""
        return (f", energy convention {self.energy_convention} "
                f"(gamma_eff = {self.gamma_effective:.6g})")

    @property
    def sigma(self) -> float:
        """3D Poisson ratio ``nu / (1 - nu)`` of the material this shell would be cut from."""
        return self.nu / (1.0 - self.nu)

    @property
    def d_over_R(self) -> float:
        """Relative thickness from eq. DefFvK_lambda; ``ValueError`` unless -1 < nu < 1/2."""
        return d_over_R(self.gamma, self.nu)

    @property
    def is_material(self) -> bool:
        """True when built from a 3D material (``E`` and ``d`` set)."""
        return self.E is not None

    # -- storage and display --------------------------------------------------------------
    def to_dict(self) -> dict:
        """Plain-float dictionary: the defining fields (``E``, ``d`` only for a material) and,
        for readers without this package, the derived ``A``, ``sigma`` and ``d_over_R``
        (omitted when undefined, nu >= 1/2)."""
        out = {"gamma": self.gamma, "nu": self.nu, "kappa": self.kappa, "R": self.R}
        if self.is_material:
            out.update(E=self.E, d=self.d)
        out["energy_convention"] = self.energy_convention
        out.update(A=self.A, sigma=self.sigma, gamma_effective=self.gamma_effective)
        if self.nu < 0.5:
            out["d_over_R"] = self.d_over_R
        return out

    @classmethod
    def from_dict(cls, data: dict) -> ShellParameters:
        """Inverse of :meth:`to_dict`. Derived entries, when present, must agree with the
        defining ones (relative 1e-9); unknown keys are refused. Without
        ``energy_convention`` (files written before it existed) the convention is helfrich."""
        defining = {"gamma", "nu", "kappa", "R", "E", "d", "energy_convention"}
        derived = {"A", "sigma", "d_over_R", "gamma_effective"}
        unknown = set(data) - defining - derived
        if unknown:
            raise ValueError(f"unknown shell parameter key(s) {sorted(unknown)}; "
                             f"allowed: {sorted(defining | derived)}")
        if "gamma" not in data:
            raise ValueError("shell parameters need 'gamma'")
        params = cls(**{k: data[k] for k in defining if k in data})
        for key in derived & set(data):
            expected = getattr(params, key)
            if not math.isclose(float(data[key]), expected, rel_tol=_REL_TOL):
                raise ValueError(f"stored {key} = {data[key]!r} disagrees with the value "
                                 f"{expected!r} computed from the defining parameters")
        return params

    def describe(self) -> str:
        """One line per group: gamma, nu (sigma), d/R; moduli; material when set."""
        if self.nu < 0.5:
            thickness = f"d/R = {self.d_over_R:.4g}"
        else:
            thickness = "d/R undefined (nu >= 1/2)"
        lines = [f"gamma = {self.gamma:.6g}, nu = {self.nu:.4g} (3D sigma = {self.sigma:.4g}), "
                 f"{thickness}",
                 f"kappa = {self.kappa:.6g}, A = {self.A:.6g}, R = {self.R:.6g}"]
        if self.energy_convention != DEFAULT_CONVENTION:
            same = (f", d/R = {self.d_over_R_effective:.4g}" if self.nu < 0.5 else "")
            lines.append(f"energy convention {self.energy_convention}: "
                         f"{convention_formula(self.energy_convention)}; the "
                         f"standard shell at gamma = {self.gamma_effective:.6g}{same}")
        if self.is_material:
            lines.append(f"material: E = {self.E:.6g}, sigma = {self.sigma:.4g}, "
                         f"d = {self.d:.6g}")
        return "\n".join(lines)
