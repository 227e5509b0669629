"""``shellbuckle refine --out DIR``: the mesh-refinement study (docs/mesh-convergence.md)."""

from __future__ import annotations

from ._checks import (add_command, add_number, allowed, as_option, check_mesh,
                      check_smooth_degree, check_value, sweep_folder, the_work, typed)
from ._options import shape_degrees, values


#: The options of the study's runs (dest -> flag): given with --report-only, they choose the
#: runs of the report.
STUDY_OPTIONS = {"gamma": "--gamma", "energy_convention": "--energy-convention",
                 "vertices": "--vertices", "seeds": "--seeds", "smooth_jiggle": "--smooth-jiggle",
                 "smooth_degree": "--smooth-degree",
                 "shape_imperfection_d": "--shape-imperfection-d",
                 "shape_imperfection": "--shape-imperfection", "shape_degree": "--shape-degree",
                 "until": "--until"}


def _defaults() -> dict:
    """The defaults of the study's options given as lists (the others default to None)."""
    from ..studies.refinement import CONVENTIONS, GAMMAS, VERTICES

    return {"gamma": ",".join(f"{g:g}" for g in GAMMAS),
            "energy_convention": ",".join(CONVENTIONS),
            "vertices": ",".join(map(str, VERTICES)), "seeds": "0"}


def _with_defaults(args):
    """``args`` with the study options' defaults where none was typed (the parser keeps them
    None, so that --report-only sees which were given)."""
    for dest, value in _defaults().items():
        if getattr(args, dest) is None:
            setattr(args, dest, value)
    return args


def register(sub) -> None:
    defaults = _defaults()
    parser = add_command(
        sub, "refine", help="the mesh-refinement study: thresholds, W and energies against "
                            "the mesh size, extrapolated to h -> 0",
        description="Deflate every (energy convention, gamma, mesh size, seed) as one sweep in "
                    "DIR (resumable: running the command again continues), the same shell on "
                    "every mesh: by default a shape imperfection of 0.1 times each shell's "
                    "thickness in the degrees up to its classical buckling band, no jiggle "
                    "(spherical shells with a smooth jiggle: --shape-imperfection-d 0); then "
                    "write DIR/refinement.md, "
                    "DIR/refinement.csv and DIR/refinement.png: per convention, gamma and mesh "
                    "the located primary threshold, loss of axisymmetry, wrinkle onset, W near "
                    "dV/V = 0.645 and E/kappa at dV/V = 0.1, 0.3, 0.5 (mean and spread over "
                    "seeds), each extrapolated to a zero mean edge h (Richardson), and the "
                    "error of the paper's 3594-vertex mesh against it; and the angle between "
                    "each mesh's dent axis and the finest mesh's at those dV/V.")
    parser.add_argument("--gamma", metavar="G,..",
                        help=f"comma-separated gammas (default {defaults['gamma']}); "
                             + allowed("gamma"))
    parser.add_argument("--energy-convention", metavar="C,..",
                        help="comma-separated energy conventions (default "
                             f"{defaults['energy_convention']})")
    parser.add_argument("--vertices", metavar="N,..",
                        help="comma-separated mesh sizes of randomized spheres (default "
                             f"{defaults['vertices']}; at least two, three for a fitted order); "
                             + allowed("vertices"))
    parser.add_argument("--seeds", metavar="S,..",
                        help="comma-separated seeds or ranges a-b (default 0: one seed); "
                             + allowed("seed"))
    add_number(parser, "--smooth-jiggle", "smooth_jiggle",
               "rms amplitude (units of R) of the smooth imperfection, the jiggle of every "
               "step (default: 0 on imperfect shells; on spherical ones the part of the "
               "paper's jiggle, 0.028 R at its 3594 vertices, in the degrees 2..L: 0.028 "
               "sqrt(((L+1)^2 - 4)/3594) R, 0.0098 R for L = 20)")
    add_number(parser, "--smooth-degree", "smooth_degree",
               "highest degree L of the smooth imperfection (default 20); every mesh must "
               "resolve it with 4 mean edges per wavelength 2 pi R/L")
    add_number(parser, "--shape-imperfection-d", "shape_imperfection_d",
               "rms of the shells' shape imperfection in units of each shell's effective "
               "thickness (default 0.1; 0: spherical shells): the stress-free shape moved "
               "radially by a seeded field, the same shell on every mesh of a seed")
    add_number(parser, "--shape-imperfection", "shape_imperfection",
               "the same rms in units of R, for every gamma (instead of --shape-imperfection-d)")
    parser.add_argument("--shape-degree", metavar="L",
                        help="highest degree of the shape imperfection: an integer in [2, 30], "
                             "or 'critical' (the default): per shell ceil(l_c) + 1 with l_c "
                             "(l_c + 1) = sqrt(gamma_eff), the classical buckling band (8 at "
                             "gamma_eff = 2333, 14 at 29160); every mesh must resolve it")
    add_number(parser, "--until", "until_deflated", "last target dV/V (default 0.95, the "
               "paper's protocol to self-contact; W is read near dV/V = 0.645)")
    add_number(parser, "--workers", "workers", "local worker processes (default: cores)")
    parser.add_argument("--carry", action="store_true",
                        help="also carry, per gamma and seed, each coarser mesh's step nearest "
                             "dV/V = 0.645 to the finest mesh and relax it there (shellbuckle "
                             "transfer): the report then says whether the coarse mesh's W is a "
                             "state of the shell (the same W at the finest mesh's energy) or of "
                             "its mesh; kept in DIR/carried.json, each done once (one "
                             "minimization on the finest mesh each: minutes on 40000 vertices; "
                             "--workers at once)")
    parser.add_argument("--report-only", action="store_true",
                        help="compute nothing: rebuild the table, figure and CSV from the "
                             "finished runs in DIR (with study options, from the runs of "
                             "that study only, as the command without --report-only does)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="study folder (a sweep folder): new, empty, or a study to resume")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from pathlib import Path

    from ..studies import refinement

    if args.report_only:
        if args.carry:
            raise ValueError("--carry: allowed: without --report-only (carrying computes one "
                             "minimization per state; the report reads what is kept)")
        chosen = any(getattr(args, dest) is not None for dest in STUDY_OPTIONS)  # typed
        options = _options(_with_defaults(args)) if chosen else None
        _study_folder(args.out)
        paths = None
        if options is not None:  # the runs of that study, as `refine` with them reports
            paths = refinement.study_folders(args.out, refinement.study_spec(**options))
            if not paths:
                raise ValueError(f"--out {args.out}: holds no run of the study these options "
                                 "give (its report is left as it is)")
        with the_work():
            table = refinement.report(args.out, paths)
    else:
        options = _options(_with_defaults(args))
        sweep_folder("--out", args.out, refinement.study_spec(**options), what="the study")
        with the_work():
            table = refinement.run_study(args.out, workers=args.workers,
                                         progress=not args.quiet, carry_states=args.carry,
                                         **options)
    out = Path(args.out)
    print(f"refinement {out}: {table.groupby(refinement.GROUP).ngroups} groups, "
          f"{table['n_vertices'].nunique()} mesh sizes")
    for name in (refinement.MARKDOWN, refinement.CSV, refinement.FIGURE):
        print(f"  {out / name}")
    return 0


def _options(args) -> dict:
    """The study's options, every one checked (ValueError naming it) before any work."""
    from ..params import ENERGY_CONVENTIONS, bending_factor
    from ..protocol.imperfection import DEFAULT_DEGREE

    gammas = values("--gamma", args.gamma, float, "gamma")
    conventions = values("--energy-convention", args.energy_convention, str)
    for c in conventions:
        if c not in ENERGY_CONVENTIONS:
            raise ValueError(f"--energy-convention {c}: allowed: "
                             f"{', '.join(ENERGY_CONVENTIONS)}")
    vertices = values("--vertices", args.vertices, int, "vertices")
    if len(set(vertices)) < 2:
        raise ValueError(f"--vertices {args.vertices}: allowed: at least two mesh sizes "
                         "(three for a fitted order of convergence)")
    seeds = values("--seeds", args.seeds, int, "seed")
    check_value("--seeds", "seeds", len(seeds), args.seeds)
    if not gammas or not conventions or not seeds:
        raise ValueError("--gamma, --energy-convention and --seeds need at least one value")
    n = min(vertices)
    g_eff = max(g / bending_factor(c) for g in gammas for c in conventions)
    g = max(gammas)
    check_mesh("--vertices", typed(args, "--vertices"), g, n, gamma_effective=g_eff if g_eff != g else None,
               mesh=f"--vertices {n}")
    shape = _shape(args)
    spherical = not next(iter(shape.values()))
    if args.smooth_degree is not None and not spherical and args.smooth_jiggle is None:
        raise ValueError(f"--smooth-degree {typed(args, '--smooth-degree')}: allowed: only with "
                         "--smooth-jiggle (imperfect shells have no jiggle by default)")
    if args.smooth_jiggle != 0 and (args.smooth_jiggle is not None or spherical):
        degree = DEFAULT_DEGREE if args.smooth_degree is None else args.smooth_degree
        option = "--smooth-degree" if args.smooth_degree is not None else "--vertices"
        check_smooth_degree(option, typed(args, option, degree if option != "--vertices" else n),
                            degree, n, mesh=f"--vertices {n}")
    until = 0.95 if args.until is None else args.until
    if until < 0.019:
        raise ValueError(f"--until {typed(args, '--until', until)}: allowed: at least the volume "
                         "step 0.019 and below 0.99")
    options = {"gammas": gammas, "conventions": conventions, "vertices": vertices,
               "seeds": seeds, "smooth_jiggle": args.smooth_jiggle,
               "smooth_degree": args.smooth_degree, **shape, "until": until}
    _check_shells(args, options, n)
    return options


def _shape(args) -> dict:
    """The shape imperfection's options of the study (refinement.study_spec): one amplitude
    (units of d or of R), a degree an integer in range or ``critical``, none for spherical
    shells."""
    from ..protocol.spec import MAX_SHAPE_DEGREE
    from ..protocol.imperfection import CRITICAL
    from ..studies.refinement import SHAPE_IN_D

    if args.shape_imperfection is not None and args.shape_imperfection_d is not None:
        raise ValueError(f"--shape-imperfection-d {typed(args, '--shape-imperfection-d')}: give "
                         "either --shape-imperfection (units of R) or --shape-imperfection-d "
                         "(units of d)")
    if args.shape_imperfection is not None:
        flag, amplitude = "--shape-imperfection", args.shape_imperfection
    else:
        flag = "--shape-imperfection-d"
        amplitude = SHAPE_IN_D if args.shape_imperfection_d is None else args.shape_imperfection_d
    degrees = [CRITICAL] if args.shape_degree is None else shape_degrees(args.shape_degree)
    if len(degrees) != 1:
        raise ValueError(f"--shape-degree {args.shape_degree}: allowed: one integer in [2, "
                         f"{MAX_SHAPE_DEGREE}] or {CRITICAL!r}")
    degree = degrees[0]
    if amplitude == 0:
        if args.shape_degree is not None:
            raise ValueError(f"--shape-degree {args.shape_degree}: allowed: only with a shape "
                             f"imperfection ({flag} is 0: spherical shells)")
        return {flag[2:].replace("-", "_"): 0.0}
    return {flag[2:].replace("-", "_"): amplitude, "shape_degree": degree}


def _check_shells(args, options: dict, n: int) -> None:
    """The study's shells as its sweep makes them (refinement.study_spec, which checks each
    shell's amplitude in units of R, degree and curvature; its refusals named with the option
    as typed), and the coarsest mesh resolving every shell's shape degree."""
    from ..studies.refinement import SHAPE_IN_D, study_spec

    flags = {"shape_imperfection_d": "--shape-imperfection-d",
             "shape_imperfection": "--shape-imperfection", "shape_degree": "--shape-degree"}
    try:
        spec = study_spec(**{k: v for k, v in options.items() if k != "vertices"},
                          vertices=[n])
    except ValueError as exc:
        defaults = {"--shape-imperfection-d": f"{SHAPE_IN_D:g} (the default)",
                    "--shape-degree": "critical (the default)"}
        texts = {name: (flag, typed(args, flag, getattr(args, name))
                        if getattr(args, name) is not None else defaults.get(flag))
                 for name, flag in flags.items()}
        raise ValueError(as_option(str(exc), texts)) from None
    for point in spec.points():
        L = point.get("shape_degree")
        if not point.get("shape_imperfection") or L is None:
            continue
        where = f"gamma {point['gamma']:g} ({point['energy_convention']})"
        if args.shape_degree is not None:
            option, text, shown = "--shape-degree", args.shape_degree, None
        else:
            option, text = "--vertices", args.vertices
            shown = f"critical, {L} at {where}"
        check_smooth_degree(option, text, L, n, mesh=f"--vertices {n}", kind="shape",
                            degree_text=shown)


def _study_folder(out) -> None:
    """A folder `shellbuckle refine --out DIR` made: its sweep record readable."""
    from pathlib import Path

    from ..store.catalogue import SWEEP_JSON, read_sweep_file

    if not (Path(out) / SWEEP_JSON).exists():
        raise ValueError(f"--out {out}: holds no study (no {SWEEP_JSON}); --report-only "
                         "rebuilds the report of a folder `shellbuckle refine --out DIR` "
                         "made")
    try:
        read_sweep_file(out)
    except ValueError as exc:
        raise ValueError(f"--out {out}: {exc}") from None
