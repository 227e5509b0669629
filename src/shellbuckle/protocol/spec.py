"""What a run does, as data: :class:`Protocol` (the volume, pressure or parameter schedule,
the jiggle or smooth imperfection, the shell's shape imperfection, the minimizer and its
tolerance, the zero-curvature cycle), stored with each run, and the limits of its options.

Kept apart from the protocol's step (:mod:`.deflate`) so that what only describes or checks a
run (the command line's options and refusals, a sweep's grid) does not load the energies and
the solvers.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..energies.kinds import BENDING_KINDS
from .imperfection import DEFAULT_DEGREE, check_shape, reference_sphere, stress_free_shape
from .jiggle import EVOLVER_DEFAULT_TEMPERATURE, evolver_sigma, mean_edge_length
from .schedule import PAPER_DV, check_schedule, linear_schedule

METHODS = ("newton", "alternate", "cg", "gd")
CONTROLS = ("volume", "pressure", "gamma", "c0")
PARAMETER_CONTROLS = ("gamma", "c0")
"""Controls whose schedule is a parameter path at the fixed volume ``fixed_dV_over_V``."""

DEFAULT_MAX_ITER = 200
"""Newton steps (factorizations) of one minimization at most, not counting the quasi-Newton
steps between them; iterations with ``method="cg"`` or ``"gd"``."""

DEFAULT_TEMPERATURE = EVOLVER_DEFAULT_TEMPERATURE
"""Default jiggle: Surface Evolver's default temperature 0.05, sigma = 0.028 R per coordinate
(the paper's runs were made with Surface Evolver's jiggle; see :mod:`.jiggle`)."""

MAX_SMOOTH_JIGGLE = 0.1
"""Largest rms amplitude of the smooth imperfection, in units of the reference radius R: an
imperfection, not a new shape (at L = 20 its rms slope is already about 1 there)."""

MAX_SHAPE_DEGREE = 30
"""Highest degree L of the shape imperfection: the fixed grid on which its curvature is
checked (:data:`.imperfection.CHECK_POINTS`) samples 8 points per wavelength at L = 30."""

MAX_SMOOTH_DEGREE = 400
"""Highest degree L of the smooth imperfection: 4 mean edges per wavelength 2 pi R / L
(:data:`.imperfection.EDGES_PER_WAVELENGTH`) need about 10^6 vertices at L = 400."""


@dataclass(frozen=True)
class Protocol:
    """How a run moves through volume and minimizes; stored with the run.

    ``schedule``: target dV/V of steps 1, 2, ... (dV/V = 1 - V/V0, V0 the initial volume), or,
    with ``control = "pressure"``, the external overpressure p of each step (units kappa/R^3;
    positive compresses): the shell then minimizes ``E + p V`` at free volume; with
    ``control = "gamma"`` (or ``"c0"``), the gamma (or c0) of each step, at the volume
    ``V0 (1 - fixed_dV_over_V)`` (an empty schedule is allowed: the path's start only).
    ``c0``: spontaneous curvature (c = c1 + c2), None for the stress-free ``2/R``.
    ``c0_cycle``: the paper's zero-curvature cycle at each step. The jiggle is set by
    ``temperature`` (Surface Evolver's scale: sigma = 0.28 T overall_size, 0.028 R at the
    default T = 0.05) or by ``jiggle`` (sigma as a fraction of the mean edge length), not both;
    with neither, ``temperature = 0.05``. Instead of either, ``smooth_jiggle`` (a fraction of
    the reference radius R) sets a smooth imperfection: a random field of spherical harmonics
    of degrees 2 to ``smooth_degree`` (default :data:`~.imperfection.DEFAULT_DEGREE`) with a
    flat power per degree and an rms of ``smooth_jiggle R``, drawn from the step's random
    stream, evaluated at each vertex's material point on the reference sphere and applied
    along the current vertex normals: the same field on any mesh (:mod:`.imperfection`; the
    record's ``jiggle_sigma`` is then its rms, a length); runs stored before this option
    existed resume without it. ``method``: minimizer (``newton``, ``alternate`` = CG
    then Newton as in the paper, ``cg``, ``gd``). ``stop_at_contact``: stop when the surface
    intersects itself. ``tol``: relative projected-gradient tolerance of the minimizer.
    ``prerelax``: every Newton minimization starts with L-BFGS steps preconditioned by the
    (shifted) Hessian of the relaxed state it came from (the step's start before the jiggle,
    or the previous minimum of the c0 cycle), which removes the jiggle's roughness at the cost
    of one factorization (:mod:`shellbuckle.solve.newton`, "Preconditioned relaxation");
    runs stored before this option existed resume without it. ``direct_return``: the
    minimization back at the step's c0 after the zero-curvature cycle starts at the minimum
    before the cycle when the energy falls all along the straight path there from the flat
    minimum (:func:`~shellbuckle.protocol.deflate.downhill_path`; else it starts at the flat
    minimum); runs stored before this option existed resume without it.
    ``relax_imperfection``: a jiggled start is relaxed however small the jiggle is against the
    mesh (the minimizations of :func:`~shellbuckle.protocol.deflate.step`); runs stored before
    this option existed resume without it (a start closer than 0.3 mean edges to the step's
    start then takes quasi-Newton steps on the Hessian there, as they were made).
    ``rescale_start``: a volume step starts from the last minimum scaled uniformly to the
    step's volume (:func:`~shellbuckle.protocol.deflate.scaled_to_volume`), before the jiggle;
    without it (the default, as Surface Evolver does) the minimizer moves the start along the
    volume gradient, a move as uneven as the mesh's vertex areas, which costs iterations on
    fine meshes. The same minima before buckling; where a jiggle crosses a barrier (the
    buckling events), another jiggled start can cross it at another step.
    ``shape_imperfection`` (a fraction of R) makes the shell itself imperfect, once for the
    whole run and whatever the jiggle: its stress-free shape is the reference sphere with
    each material point moved radially by ``shape_imperfection R f(n)``, ``f`` a field of
    degrees 2 to ``shape_degree`` (default :data:`~.imperfection.DEFAULT_DEGREE`) drawn with
    the run's seed (rms 1), and its spontaneous curvature is that surface's curvature
    (:meth:`stress_free`, :func:`~.imperfection.stress_free_shape`); the run starts there, and
    ``V0`` is its volume.
    """

    schedule: tuple
    c0: float | None = None
    c0_cycle: bool = True
    jiggle: float | None = None
    temperature: float | None = None
    seed: int = 0
    bending: str = "juelicher"
    method: str = "newton"
    stop_at_contact: bool = True
    tol: float = 1e-9
    max_iter: int = DEFAULT_MAX_ITER
    control: str = "volume"
    fixed_dV_over_V: float | None = None
    prerelax: bool = True
    direct_return: bool = True
    smooth_jiggle: float | None = None
    smooth_degree: int | None = None
    relax_imperfection: bool = True
    rescale_start: bool = False
    shape_imperfection: float | None = None
    shape_degree: int | None = None

    def _check_types(self) -> None:
        """TypeError naming a field whose value is of the wrong kind: a number given as text
        (a numpy error deep inside, or a comparison of str and float, otherwise), a boolean
        where a number or an integer is meant (``seed=True`` was stored as ``true``)."""
        import numbers

        # (an integer field given a fractional number: the ValueError of its range)
        kinds = {name: "a number" for name in ("c0", "jiggle", "temperature", "tol",
                                               "fixed_dV_over_V", "smooth_jiggle",
                                               "shape_imperfection")}
        kinds |= {name: "an integer" for name in ("seed", "max_iter", "smooth_degree",
                                                  "shape_degree")}
        for name, kind in kinds.items():
            value = getattr(self, name)
            if value is not None and (isinstance(value, (bool, np.bool_))
                                      or not isinstance(value, numbers.Real)):
                raise TypeError(f"{name} must be {kind}, got {type(value).__name__} {value!r}")
        for name in ("c0_cycle", "stop_at_contact", "prerelax", "direct_return",
                     "relax_imperfection", "rescale_start"):
            value = getattr(self, name)
            if not isinstance(value, (bool, np.bool_)):
                raise TypeError(f"{name} must be True or False, got {type(value).__name__} "
                                f"{value!r}")

    def __post_init__(self):
        self._check_types()
        if self.control not in CONTROLS:
            raise ValueError(f"control must be one of {', '.join(CONTROLS)}, got {self.control!r}")
        if (self.fixed_dV_over_V is None) == (self.control in PARAMETER_CONTROLS):
            raise ValueError(f"fixed_dV_over_V (the volume held along a parameter path) is "
                             f"needed with control 'gamma' or 'c0' and only then; got "
                             f"{self.fixed_dV_over_V!r} with control {self.control!r}")
        if self.control == "volume":
            schedule = check_schedule(self.schedule)
        elif self.control in PARAMETER_CONTROLS:
            schedule = _check_parameter_path(self.control, self.schedule, self.fixed_dV_over_V)
            object.__setattr__(self, "fixed_dV_over_V", float(self.fixed_dV_over_V))
        else:
            schedule = np.atleast_1d(np.asarray(self.schedule, dtype=float))
            if schedule.ndim != 1 or len(schedule) == 0 or not np.isfinite(schedule).all():
                raise ValueError(f"a pressure schedule must be a non-empty list of finite "
                                 f"pressures, got {list(np.ravel(self.schedule))!r}")
        object.__setattr__(self, "schedule", tuple(float(x) for x in schedule))
        if self.bending not in BENDING_KINDS:
            raise ValueError(f"bending must be one of {', '.join(BENDING_KINDS)}, "
                             f"got {self.bending!r}")
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")
        if self.jiggle is not None and self.temperature is not None:
            raise ValueError(f"give either jiggle (fraction of the mean edge length, got "
                             f"{self.jiggle!r}) or temperature (Surface Evolver's jiggle scale, "
                             f"got {self.temperature!r}), not both")
        self._check_smooth()
        self._check_shape()
        if self.jiggle is None and self.temperature is None and self.smooth_jiggle is None:
            object.__setattr__(self, "temperature", DEFAULT_TEMPERATURE)
        if self.jiggle is not None and not (np.isfinite(self.jiggle) and 0 <= self.jiggle <= 0.5):
            raise ValueError(f"jiggle amplitude must be in [0, 0.5] (fraction of the mean edge "
                             f"length), got {self.jiggle!r}")
        if self.temperature is not None and not (np.isfinite(self.temperature)
                                                 and 0 <= self.temperature <= 1):
            raise ValueError(f"jiggle temperature must be in [0, 1] (Surface Evolver's scale; "
                             f"its default is 0.05), got {self.temperature!r}")
        if not (isinstance(self.seed, (int, np.integer)) and self.seed >= 0):
            raise ValueError(f"seed must be a non-negative integer, got {self.seed!r}")
        if self.c0 is not None and not np.isfinite(self.c0):
            raise ValueError(f"c0 must be finite, got {self.c0!r}")
        if not (isinstance(self.max_iter, (int, np.integer)) and self.max_iter >= 1):
            raise ValueError(f"max_iter must be an integer >= 1, got {self.max_iter!r}")
        if not (0 < self.tol < 1e-2):
            raise ValueError(f"tol must be in (0, 1e-2), got {self.tol!r}")
        if self.shape_imperfection:
            check_shape(self.shape_imperfection, self.shape_degree, self.seed)

    def _check_smooth(self) -> None:
        """The smooth imperfection's options: exclusive with the per-vertex jiggles, an
        amplitude in [0, MAX_SMOOTH_JIGGLE], a degree in [2, MAX_SMOOTH_DEGREE] (default
        DEFAULT_DEGREE) only with an amplitude."""
        a = self.smooth_jiggle
        if a is not None and (self.jiggle is not None or self.temperature is not None):
            raise ValueError(f"give either smooth_jiggle (a smooth imperfection, got {a!r}) or "
                             f"a per-vertex jiggle (jiggle {self.jiggle!r}, temperature "
                             f"{self.temperature!r}), not both")
        self._check_field("smooth", "smooth_jiggle", "rms amplitude in units of R",
                          MAX_SMOOTH_DEGREE)

    def _check_field(self, kind: str, amplitude: str, meaning: str, max_degree: int) -> None:
        """The amplitude field ``amplitude`` (``meaning``) of the ``kind`` imperfection in [0,
        MAX_SMOOTH_JIGGLE] and its degree ``<kind>_degree`` in [2, ``max_degree``] (default
        DEFAULT_DEGREE), the degree only with an amplitude; both stored as float and int."""
        degree = f"{kind}_degree"
        a, L = getattr(self, amplitude), getattr(self, degree)
        if a is None:
            if L is not None:
                raise ValueError(f"{degree} (got {L!r}) is the degree of the {kind} "
                                 f"imperfection: give it with {amplitude}")
            return
        if isinstance(a, bool) or not (isinstance(a, (int, float, np.integer, np.floating))
                                       and 0 <= a <= MAX_SMOOTH_JIGGLE):
            raise ValueError(f"{amplitude} ({meaning}) must be in [0, {MAX_SMOOTH_JIGGLE:g}], "
                             f"got {a!r}")
        L = DEFAULT_DEGREE if L is None else L
        if isinstance(L, bool) or not (isinstance(L, (int, np.integer))
                                       and 2 <= L <= max_degree):
            raise ValueError(f"{degree} (highest degree L of the {kind} imperfection) must be "
                             f"an integer in [2, {max_degree}], got {L!r}")
        object.__setattr__(self, amplitude, float(a))
        object.__setattr__(self, degree, int(L))

    def _check_shape(self) -> None:
        """The shape imperfection's options: an amplitude in [0, MAX_SMOOTH_JIGGLE], a degree
        in [2, MAX_SHAPE_DEGREE] (default DEFAULT_DEGREE) only with an amplitude; the
        stress-free shape's curvature positive everywhere is checked last
        (:func:`~.imperfection.check_shape`, which needs the seed)."""
        self._check_field("shape", "shape_imperfection", "rms radial displacement of the "
                          "stress-free shape in units of R", MAX_SHAPE_DEGREE)

    def stress_free(self, X_reference: np.ndarray):
        """The stress-free shape of the run's shell and the profile of its spontaneous
        curvature: ``(X_reference, None)`` (the reference sphere) without a shape
        imperfection, else :func:`~.imperfection.stress_free_shape` of the reference mesh,
        drawn with the run's seed."""
        X = np.asarray(X_reference, dtype=float)
        if not self.shape_imperfection:
            return X, None
        return stress_free_shape(X, self.shape_imperfection, self.shape_degree, self.seed)

    @classmethod
    def paper(cls, dv: float = PAPER_DV, until: float = 0.95, **options) -> "Protocol":
        """The paper's protocol: steps of ``dv`` up to ``until`` (or self-contact)."""
        return cls(schedule=tuple(linear_schedule(dv, until)), **options)

    def to_dict(self) -> dict:
        out = dataclasses.asdict(self) | {"schedule": list(self.schedule)}
        if self.fixed_dV_over_V is None:  # runs stored before parameter paths keep their identity
            del out["fixed_dV_over_V"]
        if self.smooth_jiggle is None:  # so do runs stored before the smooth imperfection
            del out["smooth_jiggle"], out["smooth_degree"]
        if self.shape_imperfection is None:  # and before the shape imperfection
            del out["shape_imperfection"], out["shape_degree"]
        if not self.rescale_start:  # and before the scaled start
            del out["rescale_start"]
        return out

    @classmethod
    def from_dict(cls, data: dict) -> "Protocol":
        names = {f.name for f in dataclasses.fields(cls)}
        data = {k: v for k, v in data.items() if k in names}
        if "temperature" not in data:  # stored before the temperature option existed
            data.setdefault("jiggle", 0.01)
        data.setdefault("prerelax", False)  # stored before the preconditioned relaxation
        data.setdefault("direct_return", False)  # stored before the direct return of the cycle
        data.setdefault("relax_imperfection", False)  # stored before jiggled starts were relaxed
        return cls(**data)

    def jiggle_sigma(self, X_reference: np.ndarray, X: np.ndarray, edges: np.ndarray) -> float:
        """The jiggle's displacement std per coordinate at positions ``X``; for the smooth
        imperfection, its rms normal displacement (``smooth_jiggle`` times the radius of the
        reference sphere)."""
        if self.smooth_jiggle is not None:
            return self.smooth_jiggle * reference_sphere(X_reference)[1]
        if self.temperature is not None:
            return evolver_sigma(self.temperature, X_reference)
        return float(self.jiggle) * mean_edge_length(X, edges)


def _check_parameter_path(control: str, schedule, fixed) -> np.ndarray:
    values = np.atleast_1d(np.asarray(schedule, dtype=float)).ravel()
    if not np.isfinite(values).all():
        raise ValueError(f"a {control} path must hold finite values, got {values.tolist()!r}")
    if control == "gamma" and (values <= 0).any():
        bad = float(values[values <= 0][0])
        raise ValueError(f"gamma = A R^2/kappa must be > 0 at every step of a gamma path, "
                         f"got {bad!r}")
    check_schedule([fixed])
    return values
