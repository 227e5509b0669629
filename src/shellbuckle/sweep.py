"""Parameter sweeps: many deflations as Dask tasks, resumable, with a catalogue.

A :class:`SweepSpec` is a grid: every combination of ``gamma``, ``nu``, mesh (randomized
spheres of ``vertices`` vertices, and icosahedral spheres of ``icosphere`` levels), ``seeds``
and the protocol options ``dv``, ``until``, ``c0_cycle``, ``jiggle``, ``bending``,
``method`` and the smooth imperfection (``smooth_jiggle``, ``smooth_degree``) is one run. :func:`run_sweep` gives each run its own run folder in the sweep folder,
named from its parameters (:func:`run_name`, e.g. ``g2333_nu0.333_v3594_s0``), runs them as
Dask tasks and rewrites the catalogue (:mod:`shellbuckle.store.catalogue`) as they finish::

    from shellbuckle.sweep import SweepSpec, run_sweep
    spec = SweepSpec(gamma=[271, 2333, 29160], seeds=[0, 1, 2], vertices=3594)
    catalogue = run_sweep(spec, "sweeps/paper")          # pandas DataFrame, one row per run

Execution: a local ``distributed.LocalCluster`` with one single-threaded worker process per
core by default (``OMP_NUM_THREADS``, ``MKL_NUM_THREADS`` and ``OPENBLAS_NUM_THREADS`` set to
1 in the workers: parallelism comes from the runs), or any Dask scheduler: an address
(``tcp://host:8786``), a ``distributed.Client``, or a cluster object such as dask-jobqueue's
``SLURMCluster`` (see ``docs/sweeps.md``). Workers must see the sweep folder (a shared file
system on a cluster).

Resuming: running the same sweep again in the same folder skips the finished runs without
opening them for writing, resumes the others from their last finished step (the run store
guarantees that a finished step is never recomputed or lost, and the random stream of a step
depends only on the seed and the step index, so the result equals an uninterrupted run) and
retries the failed ones. A failing run is recorded (status ``failed``, message, traceback in
``logs/<name>.traceback.txt``) and the others continue.

The random mesh of a run with seed ``s`` is ``random_sphere(vertices, seed=s)``, as in
:func:`shellbuckle.run.deflate`; the seed also drives the jiggle.
"""

from __future__ import annotations

import itertools
import logging
import math
import numbers
import os
import socket
import sys
import threading
import time
import tomllib
import traceback as _traceback
from contextlib import contextmanager
from dataclasses import dataclass, fields
from pathlib import Path

from .protocol.spec import DEFAULT_MAX_ITER, DEFAULT_TEMPERATURE, METHODS
from .protocol.schedule import MAX_DV_OVER_V, PAPER_DV
from .store.catalogue import (AFTER_RUN_FAILURES, Catalogue, analysis_complete,
                              check_sweep_folder, failure_stands, read_attempts,
                              record_attempt, write_sweep_file)
from .store.names import LOGS_DIR, STEPS_DIR, SWEEP_JSON
from .util import interrupt_of, now

log = logging.getLogger(__name__)

#: Environment of local workers: one BLAS/OpenMP thread per worker process.
WORKER_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
#: Variables Dask's nanny would set in local workers (``distributed.nanny.pre-spawn-environ``)
#: that are left unset: ``MALLOC_TRIM_THRESHOLD_`` makes NumPy's temporaries page-fault.
WORKER_ENV_UNSET = ("MALLOC_TRIM_THRESHOLD_",)
NANNY_ENV = "distributed.nanny.pre-spawn-environ"
#: Default mesh: the paper's randomized sphere.
PAPER_VERTICES = 3594
#: Seconds between checks while another process writes a run this sweep wants to continue.
LOCK_POLL_S = 2.0

_AXES = ("gamma", "nu", "seeds", "vertices", "icosphere", "dv", "until", "c0_cycle", "jiggle",
         "bending", "method", "energy_convention", "smooth_jiggle", "smooth_degree",
         "shape_imperfection", "shape_imperfection_d", "shape_degree")
#: Axes of the smooth imperfection: left out of ``sweep.json`` and of the run points while
#: unset, so that a sweep stored before them resumes with the same description.
SMOOTH_AXES = ("smooth_jiggle", "smooth_degree")
#: Axes of the shape imperfection, likewise (each amplitude axis left out while unset).
SHAPE_AXES = ("shape_imperfection", "shape_imperfection_d", "shape_degree")
#: Largest amplitude in units of the thickness (an rms radial displacement of 1000 d is a new
#: shape, not an imperfection; the value in units of R is checked per run).
MAX_SHAPE_IN_D = 1000.0


def _bending_kinds() -> tuple:
    from .energies.kinds import BENDING_KINDS

    return BENDING_KINDS


def _values(name: str, value) -> tuple:
    """``value`` as a tuple without repeats (order kept); a scalar is a one-element axis."""
    if isinstance(value, (str, bytes, numbers.Number)) or value is None:
        value = (value,)
    try:
        items = tuple(value)
    except TypeError:
        raise ValueError(f"{name} must be a value or a list of values, got {value!r}") from None
    if not items:
        raise ValueError(f"{name} must hold at least one value, got an empty list")
    return tuple(dict.fromkeys(items))


def _empty(value) -> bool:
    """Whether an axis is given as an empty list."""
    return isinstance(value, (list, tuple)) and len(value) == 0


def _convention(value) -> str:
    from .params import check_convention

    return check_convention(value)


def _real(name: str, v, low=-math.inf, high=math.inf, *, low_open=True, high_open=True,
          allowed: str = "") -> float:
    if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
        raise ValueError(f"{name} must be a finite real number, got {v!r}")
    v = float(v)
    if (v < low or (low_open and v == low)) or (v > high or (high_open and v == high)):
        raise ValueError(f"{name} = {v!r} is out of range; allowed: {allowed}")
    return v


def _integer(name: str, v, minimum: int, allowed: str) -> int:
    if isinstance(v, bool) or not isinstance(v, numbers.Integral):
        if isinstance(v, float) and v.is_integer():
            v = int(v)
        else:
            raise ValueError(f"{name} must be an integer, got {v!r}")
    if v < minimum:
        raise ValueError(f"{name} = {v!r} is out of range; allowed: {allowed}")
    return int(v)


def _fmt(x: float, digits: int = 6) -> str:
    return format(float(x), f".{digits}g").replace("e+", "e")


@dataclass(frozen=True)
class SweepSpec:
    """A grid of deflation runs; every combination of the axes is one run.

    Each axis takes a value or a list of values (repeats are dropped):

    - ``gamma`` (> 0): Foppl-von Karman numbers A R^2/kappa (default 2333);
    - ``nu`` (in (-1, 1)): 2D Poisson ratios (default 1/3);
    - ``seeds`` (integers >= 0): seed of the randomized mesh and of the jiggle (default 0);
    - ``vertices`` (integers >= 4): randomized isotropic spheres with that many vertices;
      ``icosphere`` (integers >= 1): icosahedral spheres of that level (10 n^2 + 2 vertices).
      Both may be given; with neither, the paper's randomized sphere of 3594 vertices;
    - protocol (:func:`shellbuckle.run.deflate`): ``dv`` (volume step / V0, in (0, 0.5];
      default 0.019), ``until`` (last target dV/V, in (0, 0.99); default 0.95), ``c0_cycle``
      (booleans; default True), ``temperature`` (jiggle on Surface Evolver's scale, in
      [0, 1]; default 0.05), ``jiggle`` (jiggle as a fraction of the mean edge length, in
      [0, 0.5], replacing the temperature for those runs; default none), ``bending``
      (``juelicher`` or ``evolver``), ``method`` (``newton``, ``alternate``, ``cg``, ``gd``);
    - ``energy_convention``: which bending energy kappa multiplies (``helfrich``, the default,
      ``paper`` or ``evolver-modulus``; :mod:`shellbuckle.params`);
    - ``smooth_jiggle`` (rms normal displacement in units of R, in [0, 0.1]; default None: the
      per-vertex jiggle) and ``smooth_degree`` (highest spherical-harmonic degree L, integers
      in [2, 400]; None: :data:`~shellbuckle.protocol.imperfection.DEFAULT_DEGREE`): the smooth
      imperfection of :mod:`shellbuckle.protocol.imperfection`, the same field on any mesh
      (for mesh refinement). It replaces Surface Evolver's jiggle in those runs: a sweep with
      smooth amplitudes only refuses ``jiggle`` and a ``temperature`` other than the default;
      ``None`` among the amplitudes adds the per-vertex runs too. ``smooth_degree`` needs an
      amplitude;
    - ``shape_imperfection`` (rms radial displacement of the stress-free shape in units of R,
      in [0, 0.1]; default None: a spherical shell) and ``shape_degree`` (integers in [2, 30];
      None: the default degree): the shell's own imperfection
      (:meth:`~shellbuckle.protocol.spec.Protocol.stress_free`), drawn with each run's
      seed, whatever the jiggle; ``None`` among the amplitudes adds spherical shells too.
      ``shape_imperfection_d`` gives amplitudes in units of each shell's thickness instead
      (in [0, 1000]; the effective thickness of the energy convention,
      :attr:`~shellbuckle.params.ShellParameters.d_over_R_effective`, so that ``0.1`` is the
      same imperfection for the mechanics of every gamma and convention; the value in units of
      R must lie in [0, 0.1]); ``shape_degree`` may be ``"critical"``: per shell
      :func:`~shellbuckle.protocol.imperfection.critical_shape_degree` of its effective gamma
      (the classical buckling band, degree ``ceil(l_c) + 1``).

    ``tol`` (minimizer tolerance), ``max_iter`` (iterations per minimization; a small budget
    with ``method = "cg"`` quenches, see docs/protocol.md), ``stop_at_contact`` and
    ``rescale_start`` (each volume step starts from the last minimum scaled to the new
    volume, :class:`~shellbuckle.protocol.spec.Protocol`; runs named ``..._rs``) are the same
    for every run. Each value
    is checked here (ValueError naming it); a combination that cannot run (``until < dv`` for
    one pair) fails that run only, unless no pair of ``dv`` and ``until`` can run at all.
    """

    gamma: tuple = (2333.0,)
    nu: tuple = (1.0 / 3.0,)
    seeds: tuple = (0,)
    vertices: tuple | None = None
    icosphere: tuple | None = None
    dv: tuple = (PAPER_DV,)
    until: tuple = (0.95,)
    c0_cycle: tuple = (True,)
    jiggle: tuple = (None,)
    temperature: tuple = (DEFAULT_TEMPERATURE,)
    bending: tuple = ("juelicher",)
    method: tuple = ("newton",)
    energy_convention: tuple = ("helfrich",)
    smooth_jiggle: tuple = (None,)
    smooth_degree: tuple = (None,)
    shape_imperfection: tuple = (None,)
    shape_imperfection_d: tuple = (None,)
    shape_degree: tuple = (None,)
    tol: float = 1e-9
    max_iter: int = DEFAULT_MAX_ITER
    stop_at_contact: bool = True
    rescale_start: bool = False

    def __post_init__(self):
        put = lambda name, value: object.__setattr__(self, name, value)  # noqa: E731
        put("gamma", tuple(_real("gamma", g, 0.0, allowed="gamma > 0")
                           for g in _values("gamma", self.gamma)))
        put("nu", tuple(_real("nu", n, -1.0, 1.0, allowed="-1 < nu < 1")
                        for n in _values("nu", self.nu)))
        put("seeds", tuple(_integer("seed", s, 0, "integers >= 0")
                           for s in _values("seeds", self.seeds)))
        vertices, levels = self.vertices, self.icosphere
        # an empty axis is an unset one (to_dict writes both), unless both are
        if _empty(vertices) and levels is not None and not _empty(levels):
            vertices = None
        if _empty(levels) and vertices is not None and not _empty(vertices):
            levels = None
        if vertices is None and levels is None:
            vertices = (PAPER_VERTICES,)
        put("vertices", () if vertices is None else tuple(
            _integer("vertices", n, 4, "integers >= 4") for n in _values("vertices", vertices)))
        put("icosphere", () if levels is None else tuple(
            _integer("icosphere", n, 1, "integers >= 1") for n in _values("icosphere", levels)))
        put("dv", tuple(_real("dv", d, 0.0, 0.5, high_open=False, allowed="0 < dv <= 0.5")
                        for d in _values("dv", self.dv)))
        put("until", tuple(_real("until", u, 0.0, MAX_DV_OVER_V,
                                 allowed=f"0 < until < {MAX_DV_OVER_V}")
                           for u in _values("until", self.until)))
        put("jiggle", tuple(None if j is None else
                            _real("jiggle", j, 0.0, 0.5, low_open=False, high_open=False,
                                  allowed="0 <= jiggle <= 0.5")
                            for j in _values("jiggle", self.jiggle)))
        put("temperature", tuple(_real("temperature", t, 0.0, 1.0, low_open=False,
                                       high_open=False, allowed="0 <= temperature <= 1")
                                 for t in _values("temperature", self.temperature)))
        cycles = _values("c0_cycle", self.c0_cycle)
        if not all(isinstance(c, bool) for c in cycles):
            raise ValueError(f"c0_cycle must be true or false, got {list(cycles)!r}")
        put("c0_cycle", cycles)
        for name, allowed in (("bending", _bending_kinds()), ("method", METHODS)):
            values = _values(name, getattr(self, name))
            for v in values:
                if v not in allowed:
                    raise ValueError(f"{name} {v!r} is not known; allowed: {', '.join(allowed)}")
            put(name, values)
        put("energy_convention", tuple(_convention(c) for c in
                                       _values("energy_convention", self.energy_convention)))
        self._check_smooth(put)
        self._check_shape(put)
        put("tol", _real("tol", self.tol, 0.0, 1e-2, allowed="0 < tol < 1e-2"))
        put("max_iter", _integer("max_iter", self.max_iter, 1, "integers >= 1"))
        if not isinstance(self.stop_at_contact, bool):
            raise ValueError(f"stop_at_contact must be true or false, got {self.stop_at_contact!r}")
        if not isinstance(self.rescale_start, bool):
            raise ValueError(f"rescale_start must be true or false, got {self.rescale_start!r}")
        if not any(u >= d for d in self.dv for u in self.until):
            raise ValueError(f"no run has a volume step: every until {list(self.until)} is "
                             f"smaller than every dv {list(self.dv)}; allowed: until >= dv")
        self.points()  # refuses two grid points with the same run name

    def _check_smooth(self, put) -> None:
        """The smooth imperfection's axes: in range, and exclusive with the per-vertex jiggle
        (:class:`~shellbuckle.protocol.spec.Protocol` takes one or the other)."""
        from .protocol.spec import MAX_SMOOTH_DEGREE

        self._check_field_axes(put, "smooth", "smooth_jiggle", MAX_SMOOTH_DEGREE)
        smooth = [a for a in self.smooth_jiggle if a is not None]
        if not smooth:
            return
        if None not in self.smooth_jiggle and (
                self.jiggle != (None,) or self.temperature != (DEFAULT_TEMPERATURE,)):
            raise ValueError(f"give either smooth_jiggle {smooth} (a smooth imperfection) or a "
                             f"per-vertex jiggle (jiggle {list(self.jiggle)}, temperature "
                             f"{list(self.temperature)}), not both; allowed: none among "
                             "smooth_jiggle to add per-vertex runs")

    def _check_field_axes(self, put, kind: str, amplitude: str, max_degree: int,
                          in_d: str | None = None, keyword: str | None = None) -> None:
        """The axes of the ``kind`` imperfection: amplitudes ``amplitude`` in [0,
        MAX_SMOOTH_JIGGLE] (units of R) or None (and ``in_d``'s in [0, MAX_SHAPE_IN_D], units
        of d, if given), degrees ``<kind>_degree`` in [2, ``max_degree``], ``keyword`` or
        None, a degree only with an amplitude."""
        from .protocol.spec import MAX_SMOOTH_JIGGLE

        degree = f"{kind}_degree"
        put(amplitude, tuple(
            None if a is None else
            _real(amplitude, a, 0.0, MAX_SMOOTH_JIGGLE, low_open=False, high_open=False,
                  allowed=f"0 <= {amplitude} <= {MAX_SMOOTH_JIGGLE:g} (units of R), or none")
            for a in _values(amplitude, getattr(self, amplitude))))
        amplitudes = [a for a in getattr(self, amplitude) if a is not None]
        if in_d is not None:
            put(in_d, tuple(
                None if b is None else
                _real(in_d, b, 0.0, MAX_SHAPE_IN_D, low_open=False, high_open=False,
                      allowed=f"0 <= {in_d} <= {MAX_SHAPE_IN_D:g} (units of d), or none")
                for b in _values(in_d, getattr(self, in_d))))
            amplitudes += [b for b in getattr(self, in_d) if b is not None]
        allowed = f"integers in [2, {max_degree}]" + (f", {keyword!r}" if keyword else "") + \
            ", or none"
        for L in _values(degree, getattr(self, degree)):
            if isinstance(L, str) and L != keyword:
                raise ValueError(f"{degree} = {L!r} is not known; allowed: {allowed}")
        put(degree, tuple(
            L if L is None or (keyword and L == keyword) else _integer(degree, L, 2, allowed)
            for L in _values(degree, getattr(self, degree))))
        for L in getattr(self, degree):
            if isinstance(L, int) and L > max_degree:
                raise ValueError(f"{degree} = {L!r} is out of range; allowed: {allowed}")
        if not amplitudes and getattr(self, degree) != (None,):
            raise ValueError(f"{degree} {list(getattr(self, degree))} is the degree of the "
                             f"{kind} imperfection: give it with {amplitude}"
                             + (f" or {in_d}" if in_d else ""))

    def _check_shape(self, put) -> None:
        """The shape imperfection's axes: in range; a degree only with an amplitude; every
        shell of the grid with a positive curvature (and, in units of d, an amplitude in range
        in units of R)."""
        from .protocol.spec import MAX_SHAPE_DEGREE, MAX_SMOOTH_JIGGLE
        from .protocol.imperfection import CRITICAL, DEFAULT_DEGREE, check_shape

        self._check_field_axes(put, "shape", "shape_imperfection", MAX_SHAPE_DEGREE,
                               in_d="shape_imperfection_d", keyword=CRITICAL)
        if any(b is not None for b in self.shape_imperfection_d) and \
                any(a is not None for a in self.shape_imperfection):
            raise ValueError("give either shape_imperfection (units of R) or "
                             "shape_imperfection_d (units of d), not both")
        if any(b is not None for b in self.shape_imperfection_d):
            for nu in self.nu:
                if nu >= 0.5:
                    raise ValueError(f"shape_imperfection_d needs a thickness: d/R is undefined "
                                     f"for nu = {nu!r}; allowed: nu < 1/2")
        for convention, gamma, nu in itertools.product(self.energy_convention, self.gamma,
                                                       self.nu):
            for a, L, b in self.shapes(convention, gamma, nu):
                where = f"gamma = {gamma:g} ({convention})"
                if b is not None and not 0.0 <= a <= MAX_SMOOTH_JIGGLE:
                    raise ValueError(f"shape_imperfection_d = {b:g}: gives an rms amplitude of "
                                     f"{a:.4g} R at {where}; allowed: at most "
                                     f"{MAX_SMOOTH_JIGGLE:g} R")
                if L is not None and L > MAX_SHAPE_DEGREE:  # "critical" of a very thin shell
                    raise ValueError(f"shape_degree = {CRITICAL}: gives L = {L} at {where}; "
                                     f"allowed: at most {MAX_SHAPE_DEGREE} (the grid of the "
                                     "curvature check resolves 30)")
                for seed in self.seeds if a else ():
                    try:
                        check_shape(a, DEFAULT_DEGREE if L is None else L, seed)
                    except ValueError as exc:
                        name, value = ("shape_imperfection", a) if b is None else \
                            ("shape_imperfection_d", b)
                        raise ValueError(f"{name} = {value:g}: at {where}: {exc}") from None

    def shapes(self, convention: str, gamma: float, nu: float) -> list[tuple]:
        """The shells of the grid at one (convention, gamma, nu): ``(a, L, b)`` with the
        amplitude ``a`` in units of R, the degree ``L`` (``None``: the default) and the
        amplitude ``b`` in units of d it came from (``None`` if given in R), each shell once
        (``critical`` and an integer can give the same degree); ``(None, None, None)`` is a
        spherical shell."""
        from .params import bending_factor, d_over_R
        from .protocol.imperfection import CRITICAL, critical_shape_degree

        gamma_effective = gamma / bending_factor(convention)

        def degree(L):
            return critical_shape_degree(gamma_effective) if L == CRITICAL else L

        out = [(None, None, None)] if None in self.shape_imperfection and \
            None in self.shape_imperfection_d else []
        out += [(a, degree(L), None) for a in self.shape_imperfection if a is not None
                for L in self.shape_degree]
        if any(b is not None for b in self.shape_imperfection_d):
            d = float(d_over_R(gamma_effective, nu))
            out += [(b * d, degree(L), b) for b in self.shape_imperfection_d if b is not None
                    for L in self.shape_degree]
        return list(dict.fromkeys(out))

    # ------------------------------------------------------------------ input

    @classmethod
    def from_dict(cls, data: dict) -> "SweepSpec":
        """A spec from plain values (lists or scalars); unknown keys are refused by name."""
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(data) - set(names))
        if unknown:
            raise ValueError(f"unknown sweep option(s) {', '.join(map(repr, unknown))}; "
                             f"allowed: {', '.join(names)}")
        return cls(**data)

    @classmethod
    def from_toml(cls, path, *, defaults: dict | None = None, **overrides) -> "SweepSpec":
        """A spec from a TOML file (see ``examples/sweep.toml``), ``overrides`` taking precedence.

        Keys are the :class:`SweepSpec` fields, at the top level or in tables ``[sweep]``,
        ``[mesh]`` and ``[protocol]`` (grouping only). Giving ``vertices`` or ``icosphere`` in
        ``overrides`` replaces both mesh axes of the file. ``defaults`` gives values for the
        fields that neither the file nor ``overrides`` give (the command line's defaults).
        """
        path = Path(path)
        try:
            with open(path, "rb") as fh:
                raw = tomllib.load(fh)
        except FileNotFoundError:
            raise ValueError(f"sweep file {str(path)!r} does not exist") from None
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"sweep file {str(path)!r} is not valid TOML ({exc})") from None
        data: dict = {}
        for key, value in raw.items():
            items = value.items() if key in ("sweep", "mesh", "protocol") and \
                isinstance(value, dict) else [(key, value)]
            for k, v in items:
                if k in data:
                    raise ValueError(f"sweep file {str(path)!r} gives {k!r} twice")
                data[k] = v
        if "vertices" in overrides or "icosphere" in overrides:
            data.pop("vertices", None)
            data.pop("icosphere", None)
        data.update(overrides)
        return cls.from_dict((defaults or {}) | data)

    def to_dict(self) -> dict:
        """Plain JSON values (lists for the axes), as stored in ``sweep.json``; the smooth
        imperfection's axes only when set (a sweep without them keeps its description)."""
        out = {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
               for f in fields(self)}
        if self.smooth_jiggle == (None,):
            for name in SMOOTH_AXES:
                del out[name]
        for name in ("shape_imperfection", "shape_imperfection_d"):
            if getattr(self, name) == (None,):
                del out[name]
        if self.shape_imperfection == (None,) and self.shape_imperfection_d == (None,):
            del out["shape_degree"]
        if not self.rescale_start:
            del out["rescale_start"]
        return out

    # ------------------------------------------------------------------ the grid

    def meshes(self) -> list[tuple[str, int]]:
        return [("random", n) for n in self.vertices] + [("icosphere", n) for n in self.icosphere]

    def points(self) -> list[dict]:
        """Every run of the grid: a dict of its parameters with its ``name`` (see
        :func:`run_name`), in grid order (energy convention slowest, then gamma; method
        fastest)."""
        out, names = [], {}
        # a jiggle amplitude replaces the temperature; None in ``jiggle`` means "by temperature";
        # a smooth imperfection replaces both, None in ``smooth_jiggle`` means "per vertex"
        jiggles = [(None, t, None, None) for t in self.temperature if None in self.jiggle] + \
                  [(j, None, None, None) for j in self.jiggle if j is not None]
        if None not in self.smooth_jiggle:
            jiggles = []
        jiggles += [(None, None, a, L) for a in self.smooth_jiggle if a is not None
                    for L in self.smooth_degree]
        for convention, gamma, nu, (mesh, n), seed, dv, until, cycle, (jig, temp, a, L) in \
                itertools.product(self.energy_convention, self.gamma, self.nu, self.meshes(),
                                  self.seeds, self.dv, self.until, self.c0_cycle, jiggles):
            for (shape, shape_L, shape_d), bend, method in itertools.product(
                    self.shapes(convention, gamma, nu), self.bending, self.method):
                point = {"gamma": gamma, "nu": nu, "seed": seed, "mesh": mesh,
                         "n_vertices": n if mesh == "random" else 10 * n * n + 2,
                         "icosphere": n if mesh == "icosphere" else None, "dv": dv,
                         "until": until, "c0_cycle": cycle, "jiggle": jig, "temperature": temp,
                         "bending": bend, "method": method, "energy_convention": convention,
                         "tol": self.tol, "max_iter": self.max_iter,
                         "stop_at_contact": self.stop_at_contact}
                if a is not None:  # only then: the points of earlier sweeps keep their keys
                    point.update(smooth_jiggle=a, smooth_degree=L)
                if self.rescale_start:  # so too here
                    point.update(rescale_start=True)
                if shape is not None:
                    point.update(shape_imperfection=shape, shape_degree=shape_L)
                if shape_d is not None:
                    point.update(shape_imperfection_d=shape_d)
                name = run_name(point)
                if name in names:
                    raise ValueError(f"two runs of the sweep would share the folder {name!r}: "
                                     f"{names[name]} and {point}; give values that differ in "
                                     "their first 3 (nu) or 6 (others) significant digits")
                names[name] = point
                out.append({"name": name, **point})
        return out

    def __len__(self) -> int:
        return len(self.points())


def run_name(point: dict) -> str:
    """Folder name of a run: ``g<gamma>_nu<nu>_v<vertices>|ico<level>_s<seed>`` followed by
    the protocol options that differ from the defaults (``_dv<dv>``, ``_until<until>``,
    ``_noc0``, ``_j<jiggle>`` or ``_T<temperature>`` or ``_sj<smooth_jiggle>[_L<degree>]``,
    ``_si<shape_imperfection>`` or ``_sid<shape_imperfection_d>``, then ``[_Ls<degree>]``,
    ``_<bending>``, ``_<method>``,
    ``_it<max_iter>``, ``_<energy convention>``, ``_rs`` for the scaled start), e.g.
    ``g2333_nu0.333_v3594_s0`` or ``g271_nu0.333_ico4_s1_until0.2_noc0``. It depends on the
    run's own parameters only, so a run keeps its folder when the sweep grows."""
    mesh = f"v{point['n_vertices']}" if point["mesh"] == "random" else f"ico{point['icosphere']}"
    name = f"g{_fmt(point['gamma'])}_nu{_fmt(point['nu'], 3)}_{mesh}_s{point['seed']}"
    if point["dv"] != PAPER_DV:
        name += f"_dv{_fmt(point['dv'])}"
    if point["until"] != 0.95:
        name += f"_until{_fmt(point['until'])}"
    if not point["c0_cycle"]:
        name += "_noc0"
    if point.get("smooth_jiggle") is not None:
        name += f"_sj{_fmt(point['smooth_jiggle'])}"
        if point.get("smooth_degree") is not None:
            name += f"_L{point['smooth_degree']}"
    elif point.get("jiggle") is not None:
        name += f"_j{_fmt(point['jiggle'])}"
    elif point.get("temperature", DEFAULT_TEMPERATURE) != DEFAULT_TEMPERATURE:
        name += f"_T{_fmt(point['temperature'])}"
    if point.get("shape_imperfection_d") is not None:
        name += f"_sid{_fmt(point['shape_imperfection_d'])}"
    elif point.get("shape_imperfection") is not None:
        name += f"_si{_fmt(point['shape_imperfection'])}"
    if point.get("shape_imperfection") is not None and point.get("shape_degree") is not None:
        name += f"_Ls{point['shape_degree']}"
    if point["bending"] != "juelicher":
        name += f"_{point['bending']}"
    if point["method"] != "newton":
        name += f"_{point['method']}"
    if point.get("max_iter", DEFAULT_MAX_ITER) != DEFAULT_MAX_ITER:
        name += f"_it{point['max_iter']}"
    if point.get("energy_convention", "helfrich") != "helfrich":
        name += f"_{point['energy_convention']}"
    if point.get("rescale_start"):
        name += "_rs"
    return name


# --------------------------------------------------------------------------- one run (worker)

def _run_state(folder: Path, analyze: bool) -> str:
    """``done`` (finished, and analysed when asked), ``analyze`` (finished, not analysed),
    ``locate`` (finished and analysed, its events' location not finished: it was interrupted,
    :func:`shellbuckle.locate.pending`), ``damaged`` (finished with a mesh.h5 that is not its
    run.json's: the catalogue lists it as failed, and no new attempt can mend it),
    ``failed``, or ``todo`` (absent or resumable). Reads only; never takes a lock."""
    from .store.run import RUN_JSON, RunStore

    if not (folder / RUN_JSON).exists():
        return "todo"
    try:
        store = RunStore.open(folder)
    except ValueError:
        return "todo"
    if store.status == "finished":
        try:
            store.check_mesh()
        except ValueError:
            return "damaged"
        if analyze and _analysis_available():
            if not analysis_complete(store):
                return "analyze"
            from .locate import pending

            try:
                if pending(folder):
                    return "locate"
            except Exception:  # an unreadable record: the worker's locate says why, logged
                return "locate"
        return "done"
    return "failed" if store.status == "failed" else "todo"


def _analysis_available() -> bool:
    try:
        from .analysis import analyze_run  # noqa: F401
    except ImportError:  # pragma: no cover - analysis module absent
        return False
    return True


def _build(point: dict):
    from .mesh import icosphere, random_sphere
    from .params import ShellParameters

    params = ShellParameters.from_gamma(point["gamma"], nu=point["nu"],
                                        energy_convention=point.get("energy_convention",
                                                                    "helfrich"))
    if point["mesh"] == "random":
        mesh = random_sphere(point["n_vertices"], seed=point["seed"])
    else:
        mesh = icosphere(point["icosphere"])
    return mesh, params


def _deflate(point: dict, folder: Path):
    """Create or resume the run; waits while another live process writes the same run (a
    task of an earlier, killed client that a remote cluster still runs)."""
    from .run import Run, deflate

    mesh, params = _build(point)
    while True:
        try:
            return deflate(mesh, params, dv=point["dv"], until=point["until"],
                           c0_cycle=point["c0_cycle"], jiggle=point["jiggle"],
                           temperature=point.get("temperature"),
                           smooth_jiggle=point.get("smooth_jiggle"),
                           smooth_degree=point.get("smooth_degree"),
                           shape_imperfection=point.get("shape_imperfection"),
                           shape_degree=point.get("shape_degree"),
                           seed=point["seed"], bending=point["bending"], method=point["method"],
                           tol=point["tol"], max_iter=point.get("max_iter", DEFAULT_MAX_ITER),
                           stop_at_contact=point["stop_at_contact"],
                           rescale_start=point.get("rescale_start", False),
                           out=folder, progress=False)
        except ValueError:
            if not _writer_active(folder):
                raise
        log.warning("run %s is being written by another process; waiting for it", folder)
        while _writer_active(folder):
            time.sleep(LOCK_POLL_S)
        if _run_state(folder, analyze=False) == "done":
            return Run.open(folder)


def _writer_active(folder: Path) -> bool:
    from .store.run import RUN_JSON, RunStore

    return (folder / RUN_JSON).exists() and RunStore.open(folder).writer_active


def _worker_name() -> str | None:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return None


class _RunLabels(logging.Formatter):
    """Prefixes a record with the name of the run that the logging thread is computing."""

    def format(self, record):
        text = super().format(record)
        with _LABEL_LOCK:
            label = _LABELS.get(record.thread)
        return f"{label}: {text}" if label else text


_LABEL_LOCK = threading.Lock()
_LABELS: dict[int, str] = {}  # thread id -> name of the run it computes
_label_handler: list = []  # the handler while runs compute, installed by the first of them


@contextmanager
def _named_logs(name: str):
    """While this thread computes run ``name``, shellbuckle's warnings on stderr start with
    that name: the workers of a sweep interleave the messages of many runs on one stream
    ("step 22: minimizer did not converge" did not say which run). Only when logging is not
    configured (no handler on the root or the ``shellbuckle`` logger, i.e. Python's
    last-resort output); a configured format is left alone."""
    logger = logging.getLogger("shellbuckle")
    thread = threading.get_ident()
    with _LABEL_LOCK:
        if not _label_handler and (logger.handlers or logging.getLogger().handlers):
            active = False
        else:
            active = True
            if not _label_handler:
                handler = logging.StreamHandler()
                handler.setLevel(logging.WARNING)
                handler.setFormatter(_RunLabels("%(message)s"))
                logger.addHandler(handler)
                _label_handler.append(handler)
            _LABELS[thread] = name
    try:
        yield
    finally:
        if active:
            with _LABEL_LOCK:
                _LABELS.pop(thread, None)
                if not _LABELS and _label_handler:
                    logger.removeHandler(_label_handler.pop())


def run_point(point: dict, out_dir, *, analyze: bool = True) -> dict:
    """Compute (or resume, or analyse) one run of a sweep; never raises for a failing run.

    The run folder is ``out_dir/<name>``. A finished (analysed and located) run is left
    untouched; a finished run whose location was interrupted is located (after another
    process that is locating it now, if any: the points it stored are kept). Returns
    ``{"name", "outcome", "status", "message", "wall_s"}`` with ``outcome`` one of ``skipped``,
    ``finished``, ``paused``, ``failed``, ``analysis failed`` or ``location failed`` (the run
    is finished, the classification of its steps or the location of its events raised; the
    next sweep retries it). A sweep stopped while the task ran ends its attempt with the
    outcome ``interrupted`` (:func:`sweep_client`). The attempt is logged in
    ``out_dir/logs/<name>.json`` (and the traceback of a failure beside it). This is the Dask
    task of :func:`run_sweep`; it also runs on its own.
    """
    out_dir = Path(out_dir)
    name = point["name"]
    folder = out_dir / name
    state = _run_state(folder, analyze)
    if state == "done":
        return {"name": name, "outcome": "skipped", "status": "finished", "message": None,
                "wall_s": 0.0}
    t0, cpu0 = time.perf_counter(), time.process_time()
    attempt = {"started": now(), "ended": None, "wall_s": None, "cpu_s": None,
               "host": socket.gethostname(),
               "pid": os.getpid(), "worker": _worker_name(),
               "action": state if state in ("analyze", "locate") else "deflate",
               "outcome": "running",
               "status": None, "message": None}
    record_attempt(out_dir, name, attempt, earlier=_ended_if_killed)
    tb = None
    try:
        from .run import Run

        with _named_logs(name):
            run = Run.open(folder) if state in ("analyze", "locate") else _deflate(point, folder)
        status, message = run.store.current_status()
        outcome = "finished" if status == "finished" else "paused"
    except Exception as exc:  # recorded, the sweep goes on
        status, message, outcome = "failed", f"{type(exc).__name__}: {exc}", "failed"
        tb = _traceback.format_exc()
        log.warning("run %s failed: %s", name, message)
    if outcome == "finished" and analyze and _analysis_available():
        from .analysis import analyze_run

        try:
            analyze_run(run)
        except Exception as exc:  # the run stands; the next sweep retries the analysis
            outcome, message = "analysis failed", f"analysis: {type(exc).__name__}: {exc}"
            tb = _traceback.format_exc()
            log.warning("run %s: %s", name, message)
    if outcome == "finished" and analyze and _analysis_available():
        from .locate import locate

        try:  # what an interrupted location left, or what another process (the run's writer,
            # in another sweep) is still locating: this waits for it and keeps what it stored;
            # nothing to do (deflate locates the runs it finishes) returns before any lock
            with _named_logs(name):
                locate(run)
        except Exception as exc:  # the run stands; the next sweep locates it again
            if interrupt_of(exc) is not None:
                raise
            outcome, message = "location failed", f"location: {type(exc).__name__}: {exc}"
            tb = _traceback.format_exc()
            log.warning("run %s: %s", name, message)
    attempt.update(ended=now(), wall_s=time.perf_counter() - t0,
                   cpu_s=time.process_time() - cpu0, outcome=outcome,
                   status=status, message=message)
    record_attempt(out_dir, name, attempt, replace_last=True, traceback=tb)
    return {"name": name, "outcome": outcome, "status": status, "message": message,
            "wall_s": attempt["wall_s"]}


# --------------------------------------------------------------------------- the sweep (client)

def default_workers() -> int:
    """Cores available to this process."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _client(scheduler, workers):
    """``(client, owned)``: a Dask client for ``scheduler`` and the objects to close after."""
    from distributed import Client, LocalCluster

    if workers is not None:
        workers = _integer("workers", workers, 1, "integers >= 1")
    if scheduler is None:
        import dask

        # Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in its workers by default; with it glibc
        # stops adapting its mmap threshold, every NumPy temporary above 128 kB is mapped and
        # unmapped again, and a deflation step spends about a third of its time in page faults
        # (10 times as many as in a plain process). The local workers keep glibc's defaults.
        with dask.config.set({f"{NANNY_ENV}.{k}": None for k in WORKER_ENV_UNSET}):
            try:
                # the scheduler's HTTP server (Dask always starts one) on a free local port,
                # without the dashboard: on its default port a second sweep on the machine
                # warned that it was taken
                cluster = LocalCluster(n_workers=workers or default_workers(),
                                       threads_per_worker=1, processes=True,
                                       dashboard_address="127.0.0.1:0",
                                       scheduler_kwargs={"dashboard": False},
                                       env=dict(WORKER_ENV))
            except RuntimeError as exc:
                script = getattr(sys.modules.get("__main__"), "__file__", None)
                if script is not None and script.startswith("<"):  # e.g. "<stdin>"
                    raise RuntimeError(
                        "the local Dask cluster could not start its worker processes: they "
                        "import the calling script, which Python read from standard input; "
                        "save it to a file and put the sweep under "
                        "`if __name__ == \"__main__\":`") from exc
                raise RuntimeError(
                    f"the local Dask cluster could not start its worker processes ({exc}); "
                    "in a script, call the sweep under `if __name__ == \"__main__\":`, since "
                    "the workers import the script") from exc
        client = Client(cluster)
        return client, [client, cluster]
    if isinstance(scheduler, Client):
        if workers is not None:
            raise ValueError("workers applies to the local cluster or to a cluster object, "
                             "not to an existing Client")
        return scheduler, []
    if isinstance(scheduler, str):
        if workers is not None:
            raise ValueError("workers applies to the local cluster or to a cluster object; "
                             "with a scheduler address the cluster has its own workers")
        client = Client(scheduler)
        return client, [client]
    if hasattr(scheduler, "scheduler_address"):  # a Cluster (dask-jobqueue, LocalCluster...)
        if workers is not None:
            scheduler.scale(workers)
        client = Client(scheduler)
        return client, [client]
    raise ValueError(f"scheduler must be None (local cluster), an address string, a "
                     f"distributed.Client or a cluster object, got {type(scheduler).__name__}")


def check_scheduler(scheduler) -> None:
    """Refuse a scheduler address that cannot be an address (before any work)."""
    if scheduler is None or not isinstance(scheduler, str):
        return
    text = scheduler.strip()
    if not text or any(c.isspace() for c in text):
        raise ValueError(f"scheduler address {scheduler!r} is not an address "
                         "(e.g. tcp://host:8786)")
    body = text.split("://", 1)[1] if "://" in text else text
    host, sep, port = body.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"scheduler address {scheduler!r} must be [protocol://]host:port with "
                         "a port in 1..65535 (e.g. tcp://host:8786)")


def _cost(point: dict) -> float:
    """Relative cost estimate (vertices times steps), to start the longest runs first."""
    return point["n_vertices"] * max(1, int(point["until"] / point["dv"]))


def run_sweep(spec: SweepSpec, out_dir, *, scheduler=None, workers: int | None = None,
              progress: bool = True, analyze: bool = True,
              retry_failed: bool = True):
    """Run every point of ``spec`` in ``out_dir`` on Dask; return the catalogue (DataFrame).

    ``scheduler``: None for a local cluster of ``workers`` single-threaded processes (default:
    one per core), an address (``tcp://host:8786``), a ``distributed.Client``, or a cluster
    object (``workers`` then scales it). ``analyze``: classify the steps of each finished run
    on its worker (:func:`shellbuckle.analysis.analyze_run`) so the catalogue has thresholds
    and W. ``retry_failed``: run again the points whose last attempt failed (they resume from
    their last finished step; a finished run whose analysis or location failed is analysed or
    located again). The catalogue (``out_dir/catalogue.csv``) is rewritten after
    every finished task; finished runs are skipped without being opened for writing.
    """
    if not isinstance(spec, SweepSpec):
        raise ValueError(f"spec must be a SweepSpec, got {type(spec).__name__}")
    check_scheduler(scheduler)
    if workers is not None:
        _integer("workers", workers, 1, "integers >= 1")
    from .store.run import RunStore

    out_dir = Path(out_dir)
    points = spec.points()
    write_sweep_file(out_dir, spec.to_dict(), _runs(points))
    catalogue = Catalogue(out_dir)
    todo = []
    for p in points:
        state = _run_state(out_dir / p["name"], analyze)
        if state == "damaged":
            log.warning("run %s finished, but its mesh.h5 is not the mesh its run.json describes "
                        "(changed or damaged): listed as failed and not computed again (a "
                        "resume refuses it); restore its folder from a backup, or move it "
                        "aside and the next sweep computes it anew", out_dir / p["name"])
            continue
        last = read_attempts(out_dir, p["name"])[-1:]
        outcome = last[0].get("outcome") if last else None
        failed = state == "failed" or (outcome == "failed" and state != "done") or (
            outcome in AFTER_RUN_FAILURES and state in ("analyze", "locate")
            and failure_stands(RunStore.open(out_dir / p["name"]), last[0]))
        if state == "done" or (failed and not retry_failed):
            continue
        todo.append(p)
    todo.sort(key=_cost, reverse=True)
    catalogue.write()
    log.info("sweep %s: %d runs, %d to compute", out_dir, len(points), len(todo))
    if todo:
        _execute(todo, out_dir, catalogue, scheduler=scheduler, workers=workers,
                 progress=progress, analyze=analyze, total=len(points))
    return catalogue.write()


def check_sweep(spec: SweepSpec, out_dir) -> None:
    """The refusals of :func:`run_sweep` for the folder ``out_dir`` (ValueError: a file, a
    non-empty folder that is no sweep, a run name there that stands for other parameters),
    before any work and without writing."""
    check_sweep_folder(Path(out_dir), _runs(spec.points()))


def _runs(points) -> dict[str, dict]:
    """The points of a sweep by run name, as ``sweep.json`` holds them."""
    return {p["name"]: {k: v for k, v in p.items() if k != "name"} for p in points}


def _execute(todo, out_dir: Path, catalogue: Catalogue, *, scheduler, workers, progress,
             analyze, total) -> None:
    import distributed  # noqa: F401  (its import sets the level of its loggers)

    # Dask logs at INFO (cluster start and stop); show that only when shellbuckle logs at INFO
    quiet = None if log.isEnabledFor(logging.INFO) else logging.getLogger("distributed")
    level = quiet.level if quiet is not None else None
    if quiet is not None:
        quiet.setLevel(logging.WARNING)
    try:
        _gather(todo, out_dir, catalogue, scheduler=scheduler, workers=workers,
                progress=progress, analyze=analyze, total=total)
    finally:
        if quiet is not None:
            quiet.setLevel(level)


def _gather(todo, out_dir: Path, catalogue: Catalogue, *, scheduler, workers, progress,
            analyze, total) -> None:
    from distributed import as_completed

    with sweep_client(scheduler, workers, [out_dir]) as client:
        bar = None
        futures = []
        try:
            futures = [client.submit(run_point, p, str(out_dir), analyze=analyze, pure=False,
                                     key=f"shellbuckle-{p['name']}-{os.urandom(4).hex()}")
                       for p in todo]
            names = {f.key: p["name"] for f, p in zip(futures, todo)}
            if progress:
                from tqdm.auto import tqdm

                bar = tqdm(total=total, initial=total - len(todo), unit="run", desc="sweep",
                           dynamic_ncols=True)
            failed, shown = 0, _Shown(bar, out_dir, [p["name"] for p in todo])
            for future in _completed(as_completed(futures), shown):
                try:
                    result = future.result()
                except Exception as exc:  # the task itself died: worker killed, cancelled...
                    name = names[future.key]
                    message = f"{type(exc).__name__}: {exc}"
                    log.warning("run %s: task failed: %s", name, message)
                    record_attempt(out_dir, name, {
                        "started": None, "ended": now(), "wall_s": None, "host": None,
                        "pid": None, "worker": None, "action": "deflate", "outcome": "failed",
                        "status": "failed", "message": message},
                        traceback="".join(_traceback.format_exception(exc)))
                    result = {"outcome": "failed"}
                failed += result["outcome"] == "failed"
                catalogue.write()
                shown.done(names[future.key], failed)
        except BaseException:
            for f in futures:
                f.cancel()
            raise
        finally:
            if bar is not None:
                bar.close()


#: How often a sweep's progress bar counts the steps its unfinished runs have stored (s): on a
#: terminal or in a notebook, and where the bar is written to a file or a pipe (a batch log).
STEPS_EVERY_S = 5.0
STEPS_EVERY_S_LOG = 60.0


class _Shown:
    """What a sweep's progress bar (``bar``, or None: nothing shown) says beside the runs
    done: the failed runs, and the steps the sweep has stored so far (a run on a fine mesh is
    hours of steps): the steps in the folders of the runs ``names`` beyond those they held
    when it began, counted every :data:`STEPS_EVERY_S` (:data:`STEPS_EVERY_S_LOG` in a log;
    :meth:`tick`) and, for a run, once more when it is done."""

    def __init__(self, bar, out_dir: Path, names):
        self.bar, self.out_dir = bar, Path(out_dir)
        self.before = ({name: _steps_stored(self.out_dir / name) for name in names}
                       if bar is not None else {})
        self.seen = {}  # the steps made by each run not done yet, at the last count
        self.made, self.failed, self.last = 0, 0, time.monotonic()
        if bar is not None:
            from .run import interactive

            self.every = STEPS_EVERY_S if interactive(bar) else STEPS_EVERY_S_LOG

    def done(self, name: str, failed: int) -> None:
        self.failed = failed
        if self.bar is None:
            return
        before = self.before.pop(name, None)
        self.seen.pop(name, None)
        if before is not None:
            self.made += _steps_stored(self.out_dir / name) - before
        self.bar.update(1)
        self.bar.set_postfix_str(self._text(), refresh=True)

    def tick(self) -> None:
        if self.bar is None or time.monotonic() - self.last < self.every:
            return
        self.last = time.monotonic()
        self.seen = {name: _steps_stored(self.out_dir / name) - before
                     for name, before in self.before.items()}
        self.bar.set_postfix_str(self._text(), refresh=True)

    def _text(self) -> str:
        return f"failed {self.failed}, steps made {self.made + sum(self.seen.values())}"


def _steps_stored(folder: Path) -> int:
    """Step files in a run folder (0 if it has none yet), after step 0 (the sphere)."""
    from .store.layout import _step_indices

    try:
        return max(len(list(_step_indices(os.listdir(folder / STEPS_DIR)))) - 1, 0)
    except OSError:
        return 0


def _completed(futures, shown: _Shown):
    """The futures of ``futures`` (a ``distributed.as_completed``) as they complete; while
    none does and a bar is shown, :meth:`_Shown.tick` every quarter second."""
    if shown.bar is None:
        yield from futures
        return
    while not futures.is_empty():
        batch = futures.next_batch(block=False)
        if not batch:
            shown.tick()
            time.sleep(0.25)
        yield from batch


@contextmanager
def sweep_client(scheduler, workers, folders):
    """The Dask client for the sweeps into ``folders`` (:func:`_client`), closed after. When
    they stop on an exception (Ctrl-C, SIGTERM, an error) and the cluster is the local one
    made here, closing it kills its workers (after Dask's grace of about 4 s) in the middle of
    their runs; those runs are then recorded as interrupted (:func:`_mark_stopped`) and each
    folder's catalogue is written again. A second Ctrl-C or SIGTERM meanwhile is held off
    until that is done (then the first interrupt is raised)."""
    since = now()  # the attempts begun here start from here
    client, owned = _client(scheduler, workers)
    try:
        yield client
    except BaseException as exc:
        if scheduler is None:  # the local cluster: its workers end when it closes
            with _signals_held():
                _close(owned)
                owned = []
                for folder in map(Path, folders):
                    _mark_folder(folder, exc, since)
        raise
    finally:
        _close(owned)


def _close(owned) -> None:
    for obj in owned:
        obj.close()


@contextmanager
def _signals_held():
    """Ctrl-C and SIGTERM ignored inside the block (main thread only: elsewhere they cannot
    be handled and keep their disposition): the sweep is stopping already."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    import signal

    previous = {s: signal.signal(s, lambda signum, frame: None)
                for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _mark_folder(folder: Path, exc: BaseException, since: str) -> None:
    """:func:`_mark_stopped` for every run of the sweep folder ``folder`` with an attempts log,
    then its catalogue written again; a failure is logged, never raised (the sweep's own
    exception is the one to report)."""
    if not (folder / SWEEP_JSON).exists():
        return
    try:
        names = sorted(p.name.removesuffix(".json") for p in (folder / LOGS_DIR).glob("*.json"))
        _mark_stopped(folder, names, exc, since)
        Catalogue(folder).write()
    except Exception as failure:  # noqa: BLE001 - reported, the interrupt goes on
        log.warning("sweep %s: its stopped runs could not all be recorded as interrupted "
                    "(%s: %s); the same sweep resumes them all the same", folder,
                    type(failure).__name__, failure)


def _process_gone(attempt: dict) -> bool:
    """The process that made ``attempt`` ran on this host and has ended."""
    pid = attempt.get("pid")
    if attempt.get("host") != socket.gethostname() or not isinstance(pid, int) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:  # it exists (another user's, e.g. a reused pid)
        return False
    return False


def _ended_if_killed(attempt: dict) -> dict:
    """``attempt`` ended with the outcome ``killed`` if it is still open (outcome "running")
    while its process, on this host, has ended: it was killed outright (SIGKILL, out of
    memory, the machine stopped) and could not end it; otherwise ``attempt`` as it is. When
    it ended is not known (``ended`` stays None)."""
    if attempt.get("outcome") != "running" or not _process_gone(attempt):
        return attempt
    return attempt | {"outcome": "killed", "message": (
        f"its process (pid {attempt.get('pid')} on {attempt.get('host')}) ended without "
        "ending this attempt: killed outright (SIGKILL, out of memory, or the machine "
        "stopped); found when a later attempt began")}


def _same_attempt(a: dict, b: dict) -> bool:
    return all(a.get(k) == b.get(k) for k in ("started", "host", "pid", "worker"))


def _mark_stopped(out_dir: Path, names, exc: BaseException, since: str) -> None:
    """After a sweep stopped (``exc``: an interrupt, or an error of its own) and its local
    cluster closed, killing the workers in the middle of their runs: each run whose last
    attempt began in this sweep (at or after ``since``), is still open, and whose process on
    this host has ended, is recorded as interrupted in run.json (if it says "running" and no
    live process holds its writer lock; resumable: the same sweep resumes it), and the attempt
    as ended, so that neither run.json nor the catalogue says "running" or "pending" of a run
    nobody computes. What a live process still works on, and what earlier sweeps left, is
    left as it is. A run that cannot be recorded is logged and skipped."""
    from .store.run import RUN_JSON, RunStore

    interrupt = interrupt_of(exc)
    if interrupt is not None:
        why = f"interrupted ({interrupt})" if str(interrupt) else "interrupted"
    else:
        why = f"interrupted (the sweep stopped: {type(exc).__name__}: {exc})"
    for name in names:
        folder = out_dir / name
        try:
            attempts = read_attempts(out_dir, name)
            last = attempts[-1] if attempts else {}
            started = last.get("started")
            if (last.get("outcome") != "running" or not isinstance(started, str)
                    or started < since or not _process_gone(last)):
                continue
            status = None
            if (folder / RUN_JSON).exists():
                store = RunStore.open(folder)
                try:
                    status = store.status
                    if status == "running":
                        if store.writer_active:
                            continue
                        where = ("before step 0 was stored" if store.last_step is None
                                 else f"after step {store.last_step}")
                        status = "interrupted"
                        store.set_status(status, f"{why} with the sweep {where}; the same "
                                         f"sweep command or `shellbuckle resume {folder}` "
                                         "continues it")
                finally:
                    store.close()
            now_last = read_attempts(out_dir, name)[-1:]
            if now_last and _same_attempt(now_last[0], last):  # nobody began another since
                record_attempt(out_dir, name, last | {
                    "ended": now(), "outcome": "interrupted", "status": status,
                    "message": f"{why} with the sweep"}, replace_last=True)
        except Exception as failure:  # noqa: BLE001 - reported, the others go on
            log.warning("run %s: not recorded as interrupted (%s: %s)", folder,
                        type(failure).__name__, failure)
