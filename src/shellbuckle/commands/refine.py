"""``shellbuckle refine --out DIR``: the mesh-refinement study (docs/mesh-convergence.md)."""

from __future__ import annotations

from ._checks import (add_command, add_number, allowed, check_mesh, check_smooth_degree,
                      check_value, output_folder, typed)
from ._options import values


def register(sub) -> None:
    from ..studies.refinement import CONVENTIONS, GAMMAS, VERTICES

    parser = add_command(
        sub, "refine", help="the mesh-refinement study: thresholds, W and energies against "
                            "the mesh size, extrapolated to h -> 0",
        description="Deflate every (energy convention, gamma, mesh size, seed) with the smooth "
                    "imperfection (the same field on every mesh) as one sweep in DIR (resumable: "
                    "running the command again continues), then write DIR/refinement.md, "
                    "DIR/refinement.csv and DIR/refinement.png: per convention, gamma and mesh "
                    "the located primary threshold, loss of axisymmetry, wrinkle onset, W near "
                    "dV/V = 0.645 and E/kappa at dV/V = 0.1, 0.3, 0.5 (mean and spread over "
                    "seeds), each extrapolated to a zero mean edge h (Richardson), and the "
                    "error of the paper's 3594-vertex mesh against it.")
    parser.add_argument("--gamma", metavar="G,..", default=",".join(f"{g:g}" for g in GAMMAS),
                        help="comma-separated gammas (default %(default)s); " + allowed("gamma"))
    parser.add_argument("--energy-convention", metavar="C,..", default=",".join(CONVENTIONS),
                        help="comma-separated energy conventions (default %(default)s)")
    parser.add_argument("--vertices", metavar="N,..", default=",".join(map(str, VERTICES)),
                        help="comma-separated mesh sizes of randomized spheres (default "
                             "%(default)s; at least two, three for a fitted order); "
                             + allowed("vertices"))
    parser.add_argument("--seeds", metavar="S,..", default="0",
                        help="comma-separated seeds or ranges a-b (default 0: one seed); "
                             + allowed("seed"))
    add_number(parser, "--smooth-jiggle", "smooth_jiggle",
               "rms amplitude (units of R) of the smooth imperfection (default: the part of "
               "the paper's jiggle, 0.028 R at its 3594 vertices, in the degrees 2..L: 0.028 "
               "sqrt(((L+1)^2 - 4)/3594) R, 0.0098 R for L = 20)")
    add_number(parser, "--smooth-degree", "smooth_degree",
               "highest degree L of the smooth imperfection (default 20); every mesh must "
               "resolve it with 4 mean edges per wavelength 2 pi R/L")
    add_number(parser, "--shape-imperfection", "shape_imperfection",
               "shells with a shape imperfection of this rms (units of R; default none: "
               "spherical shells): the stress-free shape moved radially by a seeded field, the "
               "same shell on every mesh of a seed (give --smooth-jiggle 0 for no jiggle)")
    add_number(parser, "--shape-degree", "shape_degree",
               "highest degree L of the shape imperfection (default 20); every mesh must "
               "resolve it")
    add_number(parser, "--until", "until_deflated", "last target dV/V (default 0.95, the "
               "paper's protocol to self-contact; W is read near dV/V = 0.645)")
    add_number(parser, "--workers", "workers", "local worker processes (default: cores)")
    parser.add_argument("--report-only", action="store_true",
                        help="compute nothing: rebuild the table, figure and CSV from the "
                             "finished runs in DIR")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="study folder (a sweep folder): new, empty, or a study to resume")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from pathlib import Path

    from ..studies import refinement

    if args.report_only:
        _study_folder(args.out)
        table = refinement.report(args.out)
    else:
        options = _options(args)
        _out(args.out)
        table = refinement.run_study(args.out, workers=args.workers, progress=not args.quiet,
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
    from ..protocol.imperfection import DEFAULT_DEGREE, check_shape

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
    degree = DEFAULT_DEGREE if args.smooth_degree is None else args.smooth_degree
    option = "--smooth-degree" if args.smooth_degree is not None else "--vertices"
    check_smooth_degree(option, typed(args, option, degree if option != "--vertices" else n),
                        degree, n, mesh=f"--vertices {n}")
    if args.shape_degree is not None and args.shape_imperfection is None:
        raise ValueError(f"--shape-degree {typed(args, '--shape-degree')}: allowed: only with "
                         "--shape-imperfection (the highest degree of the shape imperfection)")
    if args.shape_imperfection is not None:
        degree = DEFAULT_DEGREE if args.shape_degree is None else args.shape_degree
        option = "--shape-degree" if args.shape_degree is not None else "--shape-imperfection"
        check_smooth_degree(option, typed(args, option), degree, n, mesh=f"--vertices {n}",
                            kind="shape")
        for seed in seeds:
            try:
                check_shape(args.shape_imperfection, degree, seed)
            except ValueError as exc:
                raise ValueError(f"--shape-imperfection {typed(args, '--shape-imperfection')}: "
                                 f"{exc}") from None
    until = 0.95 if args.until is None else args.until
    if until < 0.019:
        raise ValueError(f"--until {typed(args, '--until', until)}: allowed: at least the volume "
                         "step 0.019 and below 0.99")
    return {"gammas": gammas, "conventions": conventions, "vertices": vertices,
            "seeds": seeds, "smooth_jiggle": args.smooth_jiggle,
            "smooth_degree": args.smooth_degree,
            "shape_imperfection": args.shape_imperfection, "shape_degree": args.shape_degree,
            "until": until}


def _out(out) -> None:
    """A study folder: new, empty, or a sweep (run_sweep says so); never a run folder."""
    from pathlib import Path

    from ..store.run import RUN_JSON

    path = output_folder("--out", out)
    if (Path(path) / RUN_JSON).exists():
        raise ValueError(f"--out {out}: is a run folder; the study needs its own folder")


def _study_folder(out) -> None:
    from pathlib import Path

    from ..store.catalogue import SWEEP_JSON

    if not (Path(out) / SWEEP_JSON).exists():
        raise ValueError(f"--out {out}: holds no study (no {SWEEP_JSON}); --report-only "
                         "rebuilds the report of a folder `shellbuckle refine --out DIR` "
                         "made")
