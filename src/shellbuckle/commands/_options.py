"""Options that several commands share, declared once: the shell, the protocol, threads, steps.

The defaults shown in the help are read from the library (:data:`shellbuckle.params.MAIN_JOB_GAMMA`,
the fields of :class:`~shellbuckle.protocol.spec.Protocol` and the arguments of
:meth:`Protocol.paper`), and the options themselves default to None, so that a command can
tell an option given from one left out: ``deflate`` then lets the library's defaults apply,
``continue`` keeps the stored run's. ``sweep`` declares the same options as comma-separated
lists (``listed=True``), read with :func:`values`.
"""

from __future__ import annotations

import dataclasses
import inspect
from functools import lru_cache

from ._checks import RANGES, Number, allowed, check_value, typed

#: 2D Poisson ratio of every command's default shell (an incompressible material).
DEFAULT_NU = 1.0 / 3.0

NU_HELP = ("2D Poisson ratio nu (default 1/3, incompressible); the same rule in every command: "
           "-1 < nu < 1/2, where the thickness d/R is defined; a 3D material gives nu <= 1/3 "
           "(larger values are warned about in one line)")


def default_gamma() -> float:
    """The one default gamma of the command line: the main job's (it wrinkles)."""
    from ..params import MAIN_JOB_GAMMA

    return MAIN_JOB_GAMMA


def gamma_help() -> str:
    return (f"Foppl-von Karman number gamma = A R^2/kappa (default {default_gamma():g}, "
            "the main job: a capsule that turns polygonal, then wrinkles); the mesh must "
            "resolve the elastic length R gamma^-1/4: at least 1.47 sqrt(gamma) vertices")


def _listed(text: str, listed: bool) -> str:
    return f"comma-separated list of: {text}" if listed else text


# --------------------------------------------------------------------------- the shell

def add_shell_options(parser, *, material: bool = True, listed: bool = False,
                      defaults: bool = False, convention_default=None) -> None:
    """``--gamma --nu`` (with ``material``: or ``--E --sigma --d --R``) and
    ``--energy-convention``. With ``defaults`` the options hold the default shell's values
    (a command without a material); otherwise None, resolved by :func:`params_from_args`."""
    if material:
        parser = parser.add_argument_group(
            "shell parameters (either gamma and nu, or a 3D material)")
    def kind(name):
        return str if listed else Number(name)

    def text(help_text, name):
        return _listed(f"{help_text}; {allowed(name)}", listed).replace("%", "%%")

    parser.add_argument("--gamma", type=kind("gamma"), metavar="G,.." if listed else None,
                        default=default_gamma() if defaults else None,
                        help=text(gamma_help(), "gamma"))
    parser.add_argument("--nu", type=kind("nu"), metavar="NU,.." if listed else None,
                        default=DEFAULT_NU if defaults else None, help=text(NU_HELP, "nu"))
    if material:
        parser.add_argument("--E", type=Number("E"),
                            help=text("3D Young modulus of the material", "E"))
        parser.add_argument("--sigma", type=Number("sigma"),
                            help=text("3D Poisson ratio of the material", "sigma"))
        parser.add_argument("--d", type=Number("d"), help=text("shell thickness", "d"))
        parser.add_argument("--R", type=Number("R"),
                            help=text("shell radius (with --E --sigma --d)", "R"))
    add_convention_option(parser, default=convention_default, listed=listed)


def add_convention_option(parser, default=None, listed: bool = False) -> None:
    from ..params import CONVENTION_HELP, ENERGY_CONVENTIONS

    if listed:
        parser.add_argument("--energy-convention", metavar="C,..",
                            help=_listed(CONVENTION_HELP, listed))
        return
    parser.add_argument("--energy-convention", choices=list(ENERGY_CONVENTIONS),
                        default=default, metavar="{" + ",".join(ENERGY_CONVENTIONS) + "}",
                        help=CONVENTION_HELP)


def params_from_args(args, fallback=None):
    """The shell of ``--gamma --nu`` or of the material ``--E --sigma --d --R``; without them,
    ``fallback`` if given, else gamma = :func:`default_gamma`, nu = 1/3."""
    from ..params import DEFAULT_CONVENTION, ShellParameters

    material = [args.E, args.sigma, args.d, args.R]
    convention = getattr(args, "energy_convention", None) or DEFAULT_CONVENTION
    if any(v is not None for v in material):
        if any(v is None for v in material):
            raise ValueError("a material needs all of --E, --sigma, --d and --R")
        if args.gamma is not None or args.nu is not None:
            raise ValueError("give either --gamma/--nu or the material --E --sigma --d --R, "
                             "not both")
        d, R = typed(args, "--d", args.d), typed(args, "--R", args.R)
        if not args.d < args.R:
            raise ValueError(f"--d {d}: allowed: a thickness below --R {R}")
        params = ShellParameters.from_material(args.E, args.sigma, args.d, args.R,
                                               energy_convention=convention)
        if RANGES["gamma"].problem(params.gamma):
            raise ValueError(f"--d {d} with --R {R}: gives gamma = "
                             f"{params.gamma:.6g}; {allowed('gamma')}")
        return params
    if fallback is not None and args.gamma is None and args.nu is None:
        return fallback
    gamma = args.gamma if args.gamma is not None else (
        fallback.gamma if fallback else default_gamma())
    nu = args.nu if args.nu is not None else (fallback.nu if fallback else DEFAULT_NU)
    return ShellParameters.from_gamma(gamma, nu=nu, energy_convention=convention)


# --------------------------------------------------------------------------- the protocol

@dataclasses.dataclass(frozen=True)
class _Option:
    """One protocol option: its flag, the Protocol field it sets, what it is (``help``) and its
    default (``default``, the words in parentheses after the help; empty for none), its type,
    choices and metavar in a list; a switch (store_true) sets the field to ``value``.
    ``words``: (word, meaning) pairs a numeric option also takes (:class:`._checks.Number`)."""

    flag: str
    field: str
    help: str
    default: str = ""
    type: object = float
    value: object = None
    choices: tuple = ()
    metavar: str = ""
    range: str = ""
    words: tuple = ()


@lru_cache(maxsize=1)
def protocol_defaults() -> dict:
    """The protocol's defaults: the fields of :class:`Protocol` and the ``dv``/``until`` of
    :meth:`Protocol.paper`, with the jiggle's default temperature and the smooth
    imperfection's default degree."""
    from ..protocol.spec import DEFAULT_TEMPERATURE, Protocol
    from ..protocol.imperfection import DEFAULT_DEGREE

    out = {f.name: f.default for f in dataclasses.fields(Protocol)
           if f.default is not dataclasses.MISSING}
    out |= {name: p.default for name, p in inspect.signature(Protocol.paper).parameters.items()
            if p.default is not inspect.Parameter.empty}
    out["temperature"] = DEFAULT_TEMPERATURE
    out["smooth_degree"] = DEFAULT_DEGREE
    out["shape_degree"] = DEFAULT_DEGREE
    return out


@lru_cache(maxsize=1)
def _options() -> dict:
    from ..energies.kinds import BENDING_KINDS
    from ..protocol.imperfection import CRITICAL
    from ..protocol.spec import METHODS
    from ..protocol.schedule import MAX_DV_OVER_V

    d = protocol_defaults()
    options = [
        _Option("--seed", "seed", "random seed of the mesh and the jiggle",
                f"default {d['seed']}", type=int, metavar="S,..", range="seed"),
        _Option("--dv", "dv", "volume step / V0", f"default {d['dv']:g}",
                metavar="DV,..", range="dv"),
        _Option("--until", "until", f"last target dV/V, below {MAX_DV_OVER_V:g}",
                f"default {d['until']:g}; the run stops earlier at self-contact",
                metavar="U,..", range="until"),
        _Option("--schedule", "schedule", "comma-separated target dV/V values instead of "
                "--dv/--until; each " + RANGES["schedule"].explained(), type=str),
        _Option("--pressures", "pressures", "pressure control: comma-separated external "
                "overpressures (units kappa/R^3; Pa for a shell given by --E --sigma --d --R), "
                "one per step, instead of a volume schedule; each in [-gamma kappa/R^3, p_c): "
                "below the classical buckling pressure p_c = 4 sqrt(kappa A)/R^2 (above it a "
                "pressure-controlled shell turns inside out)", type=str),
        _Option("--no-c0-cycle", "c0_cycle", "skip the zero-spontaneous-curvature cycle, "
                "which gives the paper's 'potato' shapes", value=False),
        _Option("--temperature", "temperature", "jiggle temperature on Surface Evolver's "
                "scale, in [0, 1]: displacements of std 0.28 T times the size of the initial "
                "surface", f"default {d['temperature']:g}, as Surface Evolver: 0.028 R",
                metavar="T,..", range="temperature"),
        _Option("--jiggle", "jiggle", "jiggle amplitude as a fraction of the mean edge "
                "length, instead of --temperature", metavar="J,..", range="jiggle"),
        _Option("--smooth-jiggle", "smooth_jiggle", "a smooth imperfection instead of "
                "--temperature/--jiggle, the same field on any mesh (for mesh-refinement "
                "studies): at each step a seeded random field of spherical harmonics of "
                "degrees 2 to --smooth-degree with equal power per degree, applied along the "
                "normals, with this rms amplitude in units of R", range="smooth_jiggle"),
        _Option("--smooth-jiggle-d", "smooth_jiggle_d", "the rms amplitude of --smooth-jiggle "
                "in units of the shell thickness d (d/R = sqrt(12 (1 - 2 nu^2/(1-nu))/gamma), "
                "with the effective gamma of the energy convention: 4 gamma under paper); "
                "stored in units of R", range="smooth_jiggle_d"),
        _Option("--smooth-degree", "smooth_degree", "highest degree L of the smooth "
                "imperfection (shortest wavelength 2 pi R/L); the mesh must resolve it with 4 "
                "mean edges per wavelength", f"default {d['smooth_degree']}: it holds the "
                "classical buckling degree gamma^(1/4) up to gamma = 1.6e5, and the paper's "
                "3594-vertex mesh resolves it", type=int, range="smooth_degree"),
        _Option("--shape-imperfection", "shape_imperfection", "an imperfect shell, the same "
                "on any mesh: its stress-free shape (rest state and spontaneous curvature) is "
                "the sphere with each material point moved radially by a seeded random field of "
                "spherical harmonics of degrees 2 to --shape-degree with equal power per "
                "degree, of this rms amplitude in units of R; the run starts there; combine "
                "with --smooth-jiggle 0 for no jiggle", range="shape_imperfection"),
        _Option("--shape-imperfection-d", "shape_imperfection_d", "the rms amplitude of "
                "--shape-imperfection in units of the shell thickness d (as for "
                "--smooth-jiggle-d: the effective thickness of the energy convention); stored "
                "in units of R",
                range="shape_imperfection_d"),
        _Option("--shape-degree", "shape_degree", "highest degree L of the shape imperfection, "
                f"or {CRITICAL!r}: the highest degree that holds the classical buckling band, "
                "ceil(l_c) + 1 with l_c (l_c + 1) = sqrt(gamma_eff); the mesh must resolve it "
                "with 4 mean edges per wavelength", f"default {d['shape_degree']}", type=int,
                range="shape_degree",
                words=((CRITICAL, "the shell's buckling degree + 1"),)),
        _Option("--bending", "bending", "bending discretization, one of "
                f"{', '.join(BENDING_KINDS)}", f"default {d['bending']}; a Surface Evolver "
                "--mesh file that bends with star_perp_sq_mean_curvature brings evolver",
                type=str, choices=BENDING_KINDS, metavar="B,.."),
        _Option("--method", "method", f"minimizer, one of {', '.join(METHODS)} (alternate: "
                "CG then Newton, as the paper)", f"default {d['method']}", type=str,
                choices=METHODS, metavar="M,.."),
        _Option("--max-iter", "max_iter", "Newton steps (factorizations) of each "
                "minimization at most, or iterations with --method cg/gd",
                f"default {d['max_iter']}; a small budget with --method cg quenches as a fixed "
                "Surface Evolver script", type=int, range="max_iter"),
        _Option("--c0", "c0", "spontaneous curvature c = c1 + c2; |c0| at most 2/(mean edge): "
                "the preferred radius is at least an edge", "default 2/R", range="c0"),
        _Option("--no-prerelax", "prerelax", "start each Newton minimization at once, "
                "without the relaxation preconditioned by the step's starting state: slower, "
                "for comparisons", value=False),
        _Option("--no-direct-return", "direct_return", "after the zero-curvature cycle "
                "always minimize from the flat minimum, never from the minimum before the "
                "cycle: slower, for comparisons", value=False),
        _Option("--rescale-start", "rescale_start", "start each volume step from the last "
                "minimum scaled uniformly to the new volume, not moved along the volume "
                "gradient (as Surface Evolver does, unevenly on a randomized mesh): the same "
                "minima before buckling, about three times faster per step there on 40000 "
                "vertices", value=True),
    ]
    return {o.field: o for o in options}


def add_protocol_options(parser, names, *, listed: bool = False, inherited: bool = False,
                         flags: dict | None = None, ranges: dict | None = None) -> None:
    """Add the protocol options ``names`` (Protocol fields, plus ``dv``, ``until``,
    ``schedule``, ``pressures``, ``smooth_jiggle_d``, ``shape_imperfection_d``) to ``parser``;
    each defaults to None. ``listed``: as comma-separated lists (a sweep's axes). ``inherited``: a continued run keeps the stored
    run's value of an option left out, which the help says. ``flags`` renames options
    (a sweep's ``{"seed": "--seeds"}``). ``ranges`` replaces the range of an option
    (:data:`._checks.RANGES`; ``{"dv": "dv_signed"}`` where a negative step re-inflates)."""
    options = _options()
    for name in names:
        o = options[name]
        flag = (flags or {}).get(name, o.flag)
        default = "default: the run's" if inherited else o.default
        help_text = f"{o.help} ({default})" if default else o.help
        span = (ranges or {}).get(name, o.range)
        if span:
            help_text = f"{help_text}; {allowed(span)}"
        help_text = help_text.replace("%", "%%")
        if o.value is not None:
            parser.add_argument(flag, action="store_true", help=help_text)
        elif listed and o.metavar:
            parser.add_argument(flag, metavar=o.metavar, help=_listed(help_text, True))
        else:
            parser.add_argument(flag, type=Number(span, dict(o.words)) if span else o.type,
                                choices=list(o.choices) or None, help=help_text)


def protocol_values(args, names) -> dict:
    """The protocol options among ``names`` given on the command line, as Protocol fields
    (a switch given sets its field; ``--no-c0-cycle`` gives ``c0_cycle=False``)."""
    options = _options()
    out = {}
    for name in names:
        o = options[name]
        given = getattr(args, o.flag[2:].replace("-", "_"))
        if o.value is not None:
            if given:
                out[o.field] = o.value
        elif given is not None:
            out[o.field] = given
    return out


def values(option: str, text: str, kind=float, span: str = "") -> list:
    """The comma-separated values of ``option`` as ``kind`` (``int``, ``float`` or ``str``;
    integers also as inclusive ranges ``a-b``); empty items are skipped. ValueError naming the
    item that is not a ``kind``, or (with ``span``, a name of :data:`._checks.RANGES`) not in
    its range."""
    out = []
    for item in (part.strip() for part in text.split(",")):
        if not item:
            continue
        try:
            if kind is int and "-" in item[1:]:
                low, high = (int(x) for x in item.split("-", 1))
                if high < low:
                    raise ValueError
                if high - low >= 20_000:
                    raise ValueError(f"{option}: {item!r} holds {high - low + 1} values; "
                                     "allowed: at most 20000")
                bounds = [low, high]
            else:
                bounds = [kind(item)]
        except ValueError as exc:
            if "allowed" in str(exc):
                raise
            what = {int: "an integer (or a range a-b)", float: "a number"}.get(kind, "a name")
            extra = f"; {allowed(span)}" if span else ""
            raise ValueError(f"{option}: {item!r} is not {what}{extra}") from None
        if span:
            for value in bounds:
                check_value(option, span, value, item)
        out.extend(range(bounds[0], bounds[1] + 1) if len(bounds) == 2 else bounds)
    return out


# --------------------------------------------------------------------------- runs and steps

def add_threads_option(parser) -> None:
    parser.add_argument("--threads", type=Number("threads"),
                        help="threads of the sparse factorization (default: the cores this "
                             "process may use, or MKL_NUM_THREADS); one thread runs PARDISO's "
                             "faster plain mode, several its reproducible mode (the same bits "
                             "on any number); a run keeps its mode when resumed; "
                             + allowed("threads"))


def add_run_output_options(parser, plot: str = "do not write the figures at the end") -> None:
    """``--no-plot`` (its help: ``plot``) and ``--quiet`` of the commands that make or extend
    a run."""
    parser.add_argument("--no-plot", action="store_true", help=plot)
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def stored_step(run, k: int, option: str = "--step") -> int:
    """:meth:`shellbuckle.run.Run.step` for a command-line option: the message names it."""
    try:
        return run.step(k)
    except ValueError as exc:
        raise ValueError(f"{option} {k}: {exc}") from None


def shape_degrees(text: str) -> list:
    """``--shape-degree``: comma-separated integers (or ranges a-b) in range, or ``critical``
    (the sweep's list; the refinement study takes one)."""
    words = dict(_options()["shape_degree"].words)
    out = []
    for item in (part.strip() for part in text.split(",")):
        if item in words:
            out.append(item)
        elif item:
            try:
                out += values("--shape-degree", item, int, "shape_degree")
            except ValueError as exc:
                raise ValueError(f"{exc}{Number('shape_degree', words).or_words()}") from None
    return out
