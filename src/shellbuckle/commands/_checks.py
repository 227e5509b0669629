"""Bad input refused before any work, in one line that names the option, the value as typed
and what is allowed (docs/errors.md).

- :data:`RANGES`: the allowed range of every numeric option, with the reason (what the physics
  or the machine can do). :func:`add_number` declares an option with its range, which its
  ``--help`` shows; :class:`Number`, the option's ``type``, never fails: a value that is not a
  number or out of range becomes an :class:`Invalid`, which :class:`CommandParser` turns into a
  ``ValueError`` (exit code 2, :func:`shellbuckle.cli.main`) before the command runs.
- :class:`CommandParser`: the parser of every sub-command (:func:`add_command`). Its errors
  (an unknown option, a missing argument, a bad choice) are one line, exit code 2; it reads
  ``-1e3`` as a negative number, not as an option; it prints warnings as one line.
- The rules that involve several options: :func:`check_mesh` (the mesh must resolve the
  elastic length), :func:`check_smooth_degree` (and the smooth imperfection), :func:`check_c0`, :func:`check_pressures`, :func:`check_steps`,
  :func:`check_parallel`; and the paths: :func:`input_file`, :func:`run_folder`,
  :func:`output_file`, :func:`output_folder`, :func:`sweep_folder`; and
  :func:`scheduler_address`.
- :func:`the_work`: around a command's work, once its input is checked: a ``ValueError``
  raised there is a failure (:class:`WorkFailed`, exit code 1), not bad input.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import errno
import math
import os
import re
import sys
import tempfile
import warnings
from pathlib import Path

from ..plots import limits as figure_limits
from ..resolution import c0_limit, gamma_resolved, mean_edge, vertices_needed  # noqa: F401
from ..store.names import refuse_store_file
from ..util import interrupt_of


class WorkFailed(RuntimeError):
    """A command's work failed (exit code 1) with a ``ValueError`` (NumPy's ``LinAlgError``, a
    shape that cannot be classified): its input had been accepted."""


@contextlib.contextmanager
def the_work():
    """Around a command's work, after its input is checked: a ``ValueError`` raised inside
    becomes :class:`WorkFailed` (exit code 1, not the exit code 2 of bad input); an interrupt
    stays one."""
    try:
        yield
    except ValueError as exc:
        if interrupt_of(exc) is not None:
            raise
        raise WorkFailed(f"{type(exc).__name__}: {exc}") from exc


#: Most vertices of a mesh: a Newton step factorizes the sparse 3N x 3N Hessian, whose fill-in
#: at 10^6 vertices already takes tens of GB of memory.
MAX_VERTICES = 1_000_000
#: Fewest vertices of a mesh: a dent with its rim needs a vertex, its ring of neighbours and
#: the next ring (1 + 6 + 12 vertices) with the rest of the shell around them.
MIN_VERTICES = 20
#: Most stored steps of one run (volume steps, schedule values, path increments): every step is
#: a full minimization and a stored conformation (20000 steps of the 3594-vertex mesh take
#: about 2 GB and days of computing).
MAX_STEPS = 20_000
#: Threads or worker processes per core at most: more only share the same cores.
PER_CORE = 4
#: Edges per buckling wavelength 2 pi l_el at least (the mesh resolves the elastic length).
EDGES_PER_WAVELENGTH = 2


def cores() -> int:
    """The cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


# --------------------------------------------------------------------------- ranges

def _g(x) -> str:
    return str(x) if isinstance(x, int) else f"{x:g}".replace("e+", "e")


@dataclasses.dataclass(frozen=True)
class Range:
    """An interval ``[low, high]`` (``low_open``/``high_open``: excluded ends; None: no end),
    of integers with ``integer``; ``min_abs`` excludes every value nearer 0 than it.
    ``reason``: why these ends."""

    low: float | None
    high: float | None
    low_open: bool = False
    high_open: bool = False
    integer: bool = False
    min_abs: float | None = None
    reason: str = ""

    def __str__(self) -> str:
        kind = "an integer" if self.integer else "a number"
        if self.low is not None and self.high is not None:
            text = (f"{kind} in {'(' if self.low_open else '['}{_g(self.low)}, "
                    f"{_g(self.high)}{')' if self.high_open else ']'}")
        elif self.low is not None:
            text = f"{kind} {'>' if self.low_open else '>='} {_g(self.low)}"
        elif self.high is not None:
            text = f"{kind} {'<' if self.high_open else '<='} {_g(self.high)}"
        else:
            text = f"a finite {kind[2:]}" if not self.integer else kind
        if self.min_abs is not None:
            return text + f", at least {_g(self.min_abs)} from 0"
        return text

    def explained(self) -> str:
        return f"{self}" + (f" ({self.reason})" if self.reason else "")

    def problem(self, value) -> str | None:
        """None when ``value`` is allowed, else what is wrong, with the range and its reason."""
        if not math.isfinite(value):
            return f"not a finite number; allowed: {self.explained()}"
        low_bad = self.low is not None and (value <= self.low if self.low_open
                                            else value < self.low)
        high_bad = self.high is not None and (value >= self.high if self.high_open
                                              else value > self.high)
        near = self.min_abs is not None and abs(value) < self.min_abs
        if low_bad or high_bad or near:
            return f"allowed: {self.explained()}"
        return None


#: Levels of an icosahedral sphere: its meshes of 42 to 998562 vertices.
ICOSPHERE = (2, 316)

_DV = ("dV/V steps smaller than 1e-4 take more than 10^4 steps to reach 1; above 0.5 one step "
       "takes half the volume")
_DVV = "dV/V = 0.99 leaves 1% of the volume, -1 doubles it"

#: The allowed range of every numeric option, by name (docs/errors.md lists them).
RANGES = {
    "gamma": Range(1, 1e11, reason="gamma = 12 (1 - 2 nu^2/(1-nu)) (R/d)^2 is 8 for a shell as "
                   "thick as its radius at nu = 1/3; above 1e11 the mesh that resolves the "
                   f"elastic length needs more than {MAX_VERTICES} vertices"),
    "nu": Range(-1, 0.5, low_open=True, high_open=True,
                reason="the 2D Poisson ratio where the thickness d/R = sqrt(12 (1 - 2 nu^2/"
                       "(1-nu))/gamma) is defined; above 1/3 no isotropic 3D material has it "
                       "(a warning)"),
    "E": Range(0, 1e100, low_open=True, reason="a 3D Young modulus, any units"),
    "sigma": Range(-0.5, 0.5, low_open=True,
                   reason="the 3D Poisson ratio of a material whose 2D modulus A is > 0"),
    "d": Range(0, 1e100, low_open=True, reason="a thickness, below --R"),
    "R": Range(0, 1e100, low_open=True, reason="a radius, any units"),
    "vertices": Range(MIN_VERTICES, MAX_VERTICES, integer=True,
                      reason=f"a dent and its rim need about {MIN_VERTICES} vertices; above "
                             f"{MAX_VERTICES} a Newton step needs tens of GB of memory"),
    "icosphere": Range(*ICOSPHERE, integer=True,
                       reason=f"10 N^2 + 2 vertices, from {10 * ICOSPHERE[0] ** 2 + 2} to "
                              f"{10 * ICOSPHERE[1] ** 2 + 2}"),
    "seed": Range(0, 2 ** 32 - 1, integer=True, reason="a 32-bit random seed"),
    "seeds": Range(1, 100, integer=True, reason="each seed is a full study"),
    "dv": Range(1e-4, 0.5, reason=_DV),
    "dv_signed": Range(-0.5, 0.5, min_abs=1e-4, reason="a negative step re-inflates; " + _DV),
    "until": Range(-1, 0.99, low_open=True, high_open=True, reason=_DVV),
    "until_deflated": Range(0, 0.99, low_open=True, high_open=True,
                            reason="dV/V = 0.99 leaves 1% of the volume"),
    "schedule": Range(-1, 0.99, low_open=True, high_open=True, reason=_DVV),
    "pressures": Range(-1e12, 1e12, reason="an overpressure in kappa/R^3; the shell's own "
                       "limits, -gamma to the classical buckling pressure, are checked next"),
    "temperature": Range(0, 1, reason="Surface Evolver's jiggle scale"),
    "jiggle": Range(0, 0.5, reason="a fraction of the mean edge: more tangles the mesh"),
    "smooth_jiggle": Range(0, 0.1, reason="an rms normal displacement in units of R: an "
                           "imperfection, not a new shape"),
    "smooth_jiggle_d": Range(0, 1000, reason="in units of the thickness d; d/R times it must "
                             "lie in [0, 0.1] (units of R), which is checked next"),
    "shape_imperfection": Range(0, 0.1, reason="the rms radial displacement of the stress-free "
                                "shape in units of R: an imperfection, not a new shape"),
    "shape_imperfection_d": Range(0, 1000, reason="in units of the thickness d; d/R times it "
                                  "must lie in [0, 0.1] (units of R), which is checked next"),
    "shape_degree": Range(2, 30, integer=True,
                          reason="degree 0 is a volume change and 1 a translation; the "
                                 "shape's curvature is checked on a grid that resolves 30; the "
                                 "mesh's own limit is checked next"),
    "smooth_degree": Range(2, 400, integer=True,
                           reason="degree 0 is a volume change and 1 a translation; at 400 the "
                                  f"mesh that resolves it needs about {MAX_VERTICES} vertices; "
                                  "the mesh's own limit is checked next"),
    "max_iter": Range(1, 100_000, integer=True,
                      reason="each Newton step is a sparse factorization"),
    "c0": Range(-1e6, 1e6, reason="a curvature c1 + c2 in 1/length; the mesh's own limit, "
                                  "2/(mean edge), is checked next"),
    "step": Range(-10 ** 9, 10 ** 9, integer=True,
                  reason="a stored step; negative counts from the last"),
    "threads": Range(1, PER_CORE * cores(), integer=True,
                     reason=f"{PER_CORE} per core of the {cores()} this process may use: more "
                            "only slow the factorization"),
    "workers": Range(1, PER_CORE * cores(), integer=True,
                     reason=f"{PER_CORE} per core of the {cores()} this process may use; a "
                            "Dask --scheduler has its own workers"),
    "increments": Range(0, MAX_STEPS, integer=True,
                        reason="each increment is a minimization and a stored step"),
    "path_increments": Range(1, MAX_STEPS, integer=True,
                             reason="each increment is a minimization and a stored step"),
    "sensitivity": Range(1, 100, integer=True, reason="each seed is a set of runs"),
    "dpi": Range(*figure_limits.DPI, integer=True, reason="below 50 nothing is legible; a "
                 "figure at 1200 dpi is already about 10000 pixels wide (hundreds of MB in "
                 "memory)"),
    "at": Range(0, 1, high_open=True, reason="a dV/V"),
    "every": Range(1, MAX_STEPS, integer=True, reason="every K-th stored step"),
    "locate_tol": Range(1e-7, 0.1, reason="a width in dV/V: each halving is one more "
                        "minimization; below 1e-7 it resolves the minimizer's tolerance"),
}


def allowed(name: str) -> str:
    """The range of option ``name`` as the help shows it: ``allowed: ...``."""
    return f"allowed: {RANGES[name].explained()}"


class Invalid:
    """A value that is not a number or not in its range, with what is wrong (``problem``): the
    option's ``type`` returns it, :class:`CommandParser` refuses it before the command runs."""

    def __init__(self, text: str, problem: str):
        self.text, self.problem = text, problem

    def __repr__(self) -> str:
        return f"Invalid({self.text!r})"


class Number:
    """The ``type`` of a numeric option: the value, or an :class:`Invalid`. ``words`` are
    names it also takes, each with what it means (``{"critical": "the shell's buckling
    degree + 1"}``); a word is returned as typed, to be resolved where the run is known."""

    def __init__(self, name: str, words: dict | None = None):
        self.name, self.range, self.words = name, RANGES[name], dict(words or {})
        self.__name__ = "integer" if self.range.integer else "number"

    def __call__(self, text):
        text = str(text)
        if text.strip() in self.words:
            return text.strip()
        try:
            value = int(text.strip()) if self.range.integer else float(text)
        except ValueError:
            return Invalid(text, f"not {'an integer' if self.range.integer else 'a number'}; "
                                 f"{allowed(self.name)}{self.or_words()}")
        problem = self.range.problem(value)
        return Invalid(text, problem + self.or_words()) if problem else value

    def or_words(self) -> str:
        """The words, for a message: ``, or 'critical' (the shell's ...)``; empty for none."""
        return "".join(f", or {word!r} ({meaning})" for word, meaning in self.words.items())


def check_value(option: str, name: str, value, text=None):
    """``value`` if it is in the range ``RANGES[name]``, else ``ValueError`` naming ``option``
    and the value as typed (``text``; else the value)."""
    if isinstance(value, Invalid):
        raise ValueError(f"{option} {value.text}: {value.problem}")
    problem = RANGES[name].problem(value)
    if problem:
        raise ValueError(f"{option} {_typed(text, value)}: {problem}")
    return value


def typed(args, flag: str, value=None) -> str:
    """``flag``'s value as typed on the command line (its last occurrence), else ``value``."""
    argv = getattr(args, "typed_argv_", None) or []
    found = None
    for i, word in enumerate(argv):
        if word == flag and i + 1 < len(argv):
            found = argv[i + 1]
        elif word.startswith(flag + "="):
            found = word[len(flag) + 1:]
    return found if found is not None else _typed(None, value)


def _typed(text, value) -> str:
    if text is not None:
        return str(text)
    return f"{value:g}" if isinstance(value, float) else str(value)


def add_number(parser, flag: str, name: str, help: str, **kwargs):
    """Add the numeric option ``flag`` (range ``RANGES[name]``, shown in the help)."""
    return parser.add_argument(flag, type=Number(name),
                               help=f"{help}; {allowed(name)}".replace("%", "%%"), **kwargs)


# --------------------------------------------------------------------------- the parser

#: What argparse reads as a negative number rather than an option: -1, -.5, -1e3, -1:2, -inf.
NEGATIVE_NUMBER = re.compile(r"^-\.?\d|^-(inf|infinity|nan)$", re.IGNORECASE)


class CommandParser(argparse.ArgumentParser):
    """The parser of a sub-command: one-line errors (exit code 2), ``-1e3`` read as a number,
    values of :class:`Number` options checked before the command runs, warnings in one line."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message):
        message = re.sub(r"^argument ([^:]+): ", r"\1: ", message)
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def parse_known_args(self, args=None, namespace=None):
        namespace, extras = super().parse_known_args(args, namespace)
        if extras:
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        namespace.typed_argv_ = list(sys.argv[1:] if args is None else args)
        return namespace, extras

    def set_defaults(self, **kwargs):
        if "func" in kwargs:
            kwargs["func"] = _Checked(kwargs["func"], self)
        super().set_defaults(**kwargs)


class _Checked:
    """A command that first refuses an :class:`Invalid` value, then runs with warnings printed
    as one line."""

    def __init__(self, func, parser):
        self.func, self.parser = func, parser

    def __call__(self, args):
        for action in self.parser._actions:
            value = getattr(args, action.dest, None)
            for item in value if isinstance(value, list) else [value]:
                if isinstance(item, Invalid):
                    option = action.option_strings[0] if action.option_strings else \
                        (action.metavar or action.dest)
                    raise ValueError(f"{option} {item.text}: {item.problem}")
        prog = self.parser.prog

        def show(message, category, filename, lineno, file=None, line=None):
            print(f"{prog}: warning: {message}", file=sys.stderr)

        with warnings.catch_warnings():
            warnings.showwarning = show
            return self.func(args)


def add_command(sub, name: str, **kwargs):
    """``sub.add_parser(name, **kwargs)`` as a :class:`CommandParser`."""
    previous = sub._parser_class
    sub._parser_class = CommandParser
    try:
        return sub.add_parser(name, **kwargs)
    finally:
        sub._parser_class = previous


# --------------------------------------------------------------------------- rules of several options

MESH_RULE = ("the mesh must resolve the elastic length l_el = R gamma^(-1/4): at least "
             f"{EDGES_PER_WAVELENGTH} edges per classical buckling wavelength 2 pi l_el, a mean "
             "edge sqrt(8 pi/(sqrt(3) N)) R <= pi l_el, i.e. N >= 1.47 sqrt(gamma) vertices")


def check_mesh(option: str, text, gamma: float, n_vertices: int, *, gamma_effective=None,
               mesh: str = "the mesh") -> None:
    """``ValueError`` when a mesh of ``n_vertices`` cannot resolve the elastic length at
    ``gamma`` (:data:`MESH_RULE`); ``gamma_effective`` under another energy convention."""
    g = gamma if gamma_effective is None else gamma_effective
    need = vertices_needed(g)
    if n_vertices >= need:
        return
    l_el = g ** -0.25
    under = "" if gamma_effective is None or gamma_effective == gamma else \
        f" (effective gamma {g:g} under the energy convention)"
    raise ValueError(
        f"{option} {text}: the mesh cannot resolve the elastic length{under}: gamma = {g:g} "
        f"needs edges shorter than pi l_el = {math.pi * l_el:.3g} R (l_el = R gamma^-1/4 = "
        f"{l_el:.3g} R): about {need} vertices, and {mesh} has {n_vertices} (mean edge "
        f"{mean_edge(n_vertices):.3g} R; it resolves gamma <= {gamma_resolved(n_vertices):.4g})")


def check_c0(option: str, text, c0: float, n_vertices: int, R: float = 1.0) -> None:
    """``ValueError`` when the preferred radius 2/|c0| is shorter than the mean edge."""
    limit = c0_limit(n_vertices, R)
    if abs(c0) > limit:
        raise ValueError(f"{option} {_typed(text, c0)}: allowed |c0| <= {limit:.4g} on "
                         f"{n_vertices} vertices (the preferred radius 2/|c0| must be at least "
                         f"the mean edge {mean_edge(n_vertices) * R:.3g}; c0 = 2/R = {2 / R:g} "
                         "is the stress-free sphere)")


def check_pressures(option: str, texts, pressures, params) -> None:
    """Each overpressure, in the shell's units (kappa/R^3; Pa for a material), in
    [-gamma kappa/R^3, p_c) (:func:`~shellbuckle.theory.pressure_bounds`): above the classical
    buckling pressure p_c a pressure-controlled shell has no equilibrium near the sphere (it
    turns inside out); below -gamma kappa/R^3 it more than doubles its volume."""
    from ..theory import pressure_bounds

    low, high = pressure_bounds(params)
    unit = "Pa" if params.is_material else "kappa/R^3"
    for text, p in zip(texts, pressures):
        if not low <= p < high:
            raise ValueError(f"{option} {text}: allowed overpressures in [{low:.6g}, "
                             f"{high:.6g}) {unit} at gamma = {params.gamma:g} (above the "
                             "classical buckling pressure p_c = 4 sqrt(kappa A)/R^2 a "
                             "pressure-controlled shell turns inside out; below -gamma "
                             "kappa/R^3 it more than doubles its volume)")


def degree_resolved(n_vertices: int) -> int:
    """The highest degree L of the smooth imperfection a mesh of ``n_vertices`` resolves: its
    shortest wavelength 2 pi R / L spans at least
    :data:`~shellbuckle.protocol.imperfection.EDGES_PER_WAVELENGTH` mean edges."""
    from ..protocol.imperfection import EDGES_PER_WAVELENGTH

    return int(2.0 * math.pi / (EDGES_PER_WAVELENGTH * mean_edge(n_vertices)))


def check_smooth_degree(option: str, text, degree: int, n_vertices: int,
                        mesh: str = "the mesh", kind: str = "smooth",
                        degree_text: str | None = None) -> None:
    """``ValueError`` when a mesh of ``n_vertices`` cannot resolve the ``kind`` (``smooth`` or
    ``shape``) imperfection of highest degree ``degree`` (:func:`degree_resolved`);
    ``degree_text`` says what the default degree is where it is not a number."""
    from ..protocol.imperfection import EDGES_PER_WAVELENGTH

    best = degree_resolved(n_vertices)
    if degree <= best:
        return
    wavelength = 2.0 * math.pi / degree
    flag = f"--{kind}-degree"
    default = "" if option == flag else \
        f" (the default {flag} {degree_text or degree}; give a lower one or more vertices)"
    raise ValueError(
        f"{option} {_typed(text, degree)}: the mesh cannot resolve the {kind} imperfection of "
        f"degree L = {degree}{default}: its shortest wavelength 2 pi R/L = {wavelength:.3g} R "
        f"needs {EDGES_PER_WAVELENGTH} edges of at most {wavelength / EDGES_PER_WAVELENGTH:.3g} "
        f"R, and {mesh} has a mean edge of {mean_edge(n_vertices):.3g} R (it resolves "
        f"L <= {best})")


def check_steps(option: str, text, n_steps: float) -> None:
    """``ValueError`` when a run would have more than :data:`MAX_STEPS` steps."""
    if n_steps > MAX_STEPS:
        raise ValueError(f"{option} {text}: {n_steps:.0f} steps; allowed: at most {MAX_STEPS} "
                         "steps in one run (each is a minimization and a stored step)")


def check_parallel(option: str, n) -> int | None:
    """``n`` threads or workers, refused above :data:`PER_CORE` per core."""
    if n is None:
        return None
    name = option.lstrip("-")
    return check_value(option, name if name in RANGES else "threads", n)


def floats(option: str, text: str, name: str) -> list[float]:
    """The comma-separated numbers of ``option``, each in ``RANGES[name]``."""
    out = []
    for item in (part.strip() for part in text.split(",")):
        if not item:
            continue
        try:
            value = float(item)
        except ValueError:
            raise ValueError(f"{option} {item}: not a number; {allowed(name)}") from None
        check_value(option, name, value, item)
        out.append(value)
    if not out:
        raise ValueError(f"{option} {text!r}: no value; {allowed(name)}")
    return out


# --------------------------------------------------------------------------- paths

def input_file(option: str, path) -> Path:
    """An existing, readable file (not a folder)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{option} {path}: does not exist")
    if path.is_dir():
        raise ValueError(f"{option} {path}: is a folder; expected a file")
    if not os.access(path, os.R_OK):
        raise ValueError(f"{option} {path}: cannot be read (permissions)")
    return path


def _parent(option: str, path: Path) -> None:
    """The folder of ``path`` exists, is a folder and is writable."""
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.exists():
        missing = parent
        while not missing.parent.exists() and missing.parent != missing:
            missing = missing.parent
        if missing.parent.exists() and not missing.parent.is_dir():
            raise ValueError(f"{option} {path}: {missing.parent} is a file, not a folder")
        raise FileNotFoundError(f"{option} {path}: the folder {parent} does not exist "
                                "(create it first)")
    if not parent.is_dir():
        raise ValueError(f"{option} {path}: {parent} is a file, not a folder")
    _writable(option, path, parent)


def _writable(option: str, path: Path, folder: Path) -> None:
    """A file can be made in ``folder``. ``os.access`` answers from the permissions alone
    (and lets the superuser write anywhere); the file system itself answers the creation of
    a nameless file (``O_TMPFILE``), and refuses in ``/proc`` or ``/sys``."""
    what = f"the folder {folder}" if folder != path else "the folder"
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {path}: {what} is not writable")
    refused = _refuses_files(folder)
    if refused:
        raise ValueError(f"{option} {path}: {what} is not writable ({refused})")


def _refuses_files(folder: Path) -> str | None:
    """Why the file system refuses a new file in ``folder``, or None. A nameless file where the
    file system has them (Linux's ``O_TMPFILE``: nothing appears in the folder); else a
    hidden probe file, removed at once (where it cannot be removed, the folder is taken as
    writable: it just was)."""
    flag = getattr(os, "O_TMPFILE", 0)
    if flag:
        try:
            os.close(os.open(folder, flag | os.O_WRONLY, 0o600))
            return None
        except OSError as e:
            if e.errno not in (errno.EOPNOTSUPP, errno.EISDIR, errno.EINVAL):
                return e.strerror or type(e).__name__
    try:
        fd, name = tempfile.mkstemp(prefix=".shellbuckle-probe-", dir=folder)
    except OSError as e:
        return e.strerror or type(e).__name__
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(name)
    return None


def output_file(option: str, path, suffixes=(), *, beside=()) -> Path:
    """A file to write: not a folder, in an existing writable folder, with one of
    ``suffixes`` when given, and never a file of a run or sweep folder (run.json, mesh.h5,
    a step, the catalogue: :func:`~shellbuckle.store.names.store_file`). ``beside``: the
    suffixes of files the writer also makes next to it (an XDMF file's ``.h5``), checked as
    well."""
    if not str(path).strip():
        raise ValueError(f"{option} {str(path)!r}: an empty name; give a file name")
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{option} {path}: is a folder; expected a file name")
    if suffixes and path.suffix.lower() not in suffixes:
        raise ValueError(f"{option} {path}: allowed suffixes {', '.join(suffixes)}")
    refuse_store_file(path, [path.with_suffix(s) for s in beside], option=option)
    _parent(option, path)
    if path.exists() and not os.access(path, os.W_OK):
        raise ValueError(f"{option} {path}: the file exists and is not writable")
    return path


def output_folder(option: str, path, *, run: bool = False) -> Path:
    """A folder to write in: an existing writable folder, or a new one in an existing writable
    folder, never a folder of a run or sweep folder's store (its ``steps/``, ``logs/``).
    ``run``: a run folder, which may be a previous run there (it is resumed or refused by the
    run's own rules)."""
    if not str(path).strip():
        raise ValueError(f"{option} {str(path)!r}: an empty name; give a folder")
    path = Path(path)
    refuse_store_file(path, option=option)
    if path.exists():
        if not path.is_dir():
            raise ValueError(f"{option} {path}: is an existing file; expected a folder")
        _writable(option, path, path)
        return path
    _parent(option, path)
    return path


def sweep_folder(option: str, path, spec, *, what: str = "a sweep") -> Path:
    """The folder of the sweep ``spec`` (a :class:`~shellbuckle.sweep.SweepSpec`): new, empty,
    or a sweep to resume or extend; never a run folder, a non-empty folder that is no sweep, or
    a sweep whose record has a run of ``spec``'s names with other parameters. ``what`` names the
    sweep in the refusal of a run folder. Checked before any work, writing nothing."""
    from ..sweep import check_sweep

    folder = output_folder(option, path)
    not_a_run_folder(option, path, folder, what)
    try:
        check_sweep(spec, folder)
    except ValueError as exc:  # the sweep's own refusal, which begins with the folder
        reason = str(exc).removeprefix(f"{folder} ")
        raise ValueError(f"{option} {path}: {reason}") from None
    return folder


def not_a_run_folder(option: str, text, folder: Path, what: str) -> None:
    """``ValueError`` when ``folder`` (given as ``text``) holds a run: ``what`` (a sweep, a
    study) needs a folder of its own."""
    from ..store.names import RUN_JSON

    if (folder / RUN_JSON).exists():
        raise ValueError(f"{option} {text}: is a run folder; {what} needs its own folder")


def scheduler_address(option: str, text) -> None:
    """A Dask scheduler's address that can be one (``[protocol://]host:port``), or None."""
    from ..sweep import check_scheduler

    try:
        check_scheduler(text)
    except ValueError as exc:
        raise ValueError(f"{option} {text}: {str(exc).removeprefix('scheduler address ')}") \
            from None


def run_folder(option: str, path, *, mesh: bool = True, params: bool = True):
    """The :class:`~shellbuckle.run.Run` in ``path``, its ``mesh.h5`` the one its ``run.json``
    describes (unless ``mesh`` is False: a command that reads only the table, which salvages
    a run whose mesh is lost) and its parameters readable (unless ``params`` is False: a
    command that reads only the stored shapes); ``ValueError`` naming the option (a path that
    is missing or a file is refused before the run store is loaded)."""
    from ..store.folder import check_run_folder

    try:
        check_run_folder(path)
        from ..run import Run

        run = Run.open(path)
        if mesh:
            run.store.check_mesh()
            if params:
                run.params  # noqa: B018 -- raises naming run.json when it cannot be read
        else:  # run.json is still the run mesh.h5 was written for
            run.store.check_owner()
        return run
    except (ValueError, FileNotFoundError) as exc:
        message = str(exc)
        named = str(path).rstrip("/") or str(path)
        for head in (f"{path}: ", f"{path} ", f"{named}: ", f"{named} "):  # named once
            if message.startswith(head):
                message = message[len(head):]
                break
        raise ValueError(f"{option} {path}: {message}") from None


def as_option(message: str, names: dict) -> str:
    """A refusal of the Python API (``name = value: reason``, ``name [values] reason``) named
    with the command-line option and its value as typed: ``names`` maps a field name to
    ``(flag, text)``. Other messages are returned as they are."""
    for name, (flag, text) in names.items():
        match = re.match(rf"^{re.escape(name)}(?: = \S+?| \[[^\]]*\])?:? ", message)
        if match:
            return f"{flag} {text}: {message[match.end():]}"
    return message
