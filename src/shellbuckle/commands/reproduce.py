"""``shellbuckle reproduce-paper``: the paper's study as a sweep, then figures and report.

A thin layer over :func:`shellbuckle.studies.quilliet2008.reproduce.reproduce_paper`; see
``docs/reproduce.md``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ._checks import (add_command, add_number, allowed, check_mesh, not_a_run_folder,
                      output_folder, scheduler_address, the_work)
from ._options import add_convention_option, add_protocol_options, values


def register(sub) -> None:
    parser = add_command(
        sub, "reproduce-paper", help="run the paper's study (sweep on Dask), write figures and report",
        description="Run Quilliet et al. (2008)'s simulations as a resumable Dask sweep: every "
                    "gamma the paper names (271 ... 29160), nu = 1/3, the paper's protocol, "
                    "several seeds, on randomized 3594-vertex meshes; plus the runs of Fig. 3 "
                    "(gamma = 743 with and without the zero-curvature cycle, dV/V = 0.171) and "
                    "Fig. 11 (a capsule taken from gamma = 743 to 15163 at dV/V = 0.646 against "
                    "the wrinkled bowl of progressive deflation); then the figures (OUT/figures) "
                    "and the reproduction report (OUT/report.md, .html). Running the same "
                    "command again resumes. --quick runs a reduced study in a couple of minutes "
                    "on 2 cores.")
    parser.add_argument("--quick", action="store_true",
                        help="reduced preset: gamma 271, 2333, 15163, one seed, 400 vertices, "
                             "dV/V up to 0.4 (other options override it)")
    parser.add_argument("--gammas", metavar="G,..",
                        help="gamma values (default: the paper's 271,583,743,933,2333,2916,"
                             "7465,15163,20995,29160); each " + allowed("gamma"))
    add_number(parser, "--seeds", "seeds", "seeds 0..N-1 (default 3)", metavar="N")
    add_number(parser, "--vertices", "vertices", "randomized mesh size(s) (default 3594; "
               "several: a mesh-convergence study, e.g. --vertices 3594 10000 20000); each must "
               "resolve every gamma (1.47 sqrt(gamma) vertices at least)", nargs="+",
               metavar="N")
    add_protocol_options(parser, ("until", "dv"), ranges={"until": "until_deflated"})
    add_number(parser, "--path-increments", "path_increments",
               "gamma increments of the Fig. 11 path (default 8)", metavar="N")
    add_convention_option(parser)
    parser.add_argument("--compare-conventions", action="store_true",
                        help="run the study under each energy convention (helfrich, paper, "
                             "evolver-modulus) in OUT/<convention>/, special runs for every "
                             "seed, and score each reading against every number of the paper: "
                             "OUT/conventions.md, .json and conventions_thresholds.png")
    add_number(parser, "--sensitivity", "sensitivity", metavar="SEEDS", nargs="?", const=2,
               help="with --compare-conventions: also the sensitivity table at gamma "
                             "2333 and 15163 under helfrich and the best other reading (jiggle "
                             "temperature 0.01/0.2, a CG quench, Evolver's bending, a 10242-"
                             "vertex mesh), with SEEDS seeds (default 2): OUT/sensitivity.md")
    parser.add_argument("--no-special", action="store_true",
                        help="only the sweep: no Fig. 3 and Fig. 11 runs")
    parser.add_argument("--formats", default="png,pdf", help="figure formats (default png,pdf)")
    add_number(parser, "--workers", "workers", "local Dask worker processes (default: cores)",
               metavar="N")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="address of a running Dask scheduler (e.g. tcp://host:8786)")
    parser.add_argument("--out", default="reproduction", metavar="DIR",
                        help="output folder (default ./reproduction): new (in an existing "
                             "folder), empty, or a previous study to resume; never a run folder")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from ..studies.quilliet2008.reproduce import Study, reproduce_paper

    given = {}
    if args.gammas is not None:
        given["gammas"] = tuple(values("--gammas", args.gammas, float, "gamma"))
    for option, name in (("seeds", "seeds"), ("until", "until"), ("dv", "dv"),
                         ("path_increments", "path_increments")):
        if getattr(args, option) is not None:
            given[name] = getattr(args, option)
    if args.vertices is not None:
        given["vertices"] = tuple(args.vertices)
    if args.no_special:
        given["special"] = False
    if args.energy_convention is not None:
        given["energy_convention"] = args.energy_convention
    study = Study.quick(**given) if args.quick else Study(**given)
    if study.dv > study.until:
        raise ValueError(f"--until {study.until:g}: allowed: at least the step --dv "
                         f"{study.dv:g}")
    _check_meshes(study, args)
    _check_out(args.out, args.compare_conventions)
    scheduler_address("--scheduler", args.scheduler)
    if args.workers is not None and args.scheduler is not None:
        raise ValueError("--workers applies to the local cluster; a --scheduler has its own "
                         "workers")
    formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
    bad = [f for f in formats if f not in ("png", "pdf", "svg")]
    if bad or not formats:
        raise ValueError(f"--formats must be among png, pdf, svg; got {args.formats!r}")
    if args.sensitivity is not None and not args.compare_conventions:
        raise ValueError("--sensitivity needs --compare-conventions (it uses the best reading)")
    if args.compare_conventions:
        if args.energy_convention is not None:
            raise ValueError("--compare-conventions runs every convention; do not give "
                             f"--energy-convention (got {args.energy_convention!r})")
        from ..studies.quilliet2008.conventions import COMPARISON_MD, compare_conventions

        with the_work():
            data = compare_conventions(args.out, study, workers=args.workers,
                                       scheduler=args.scheduler, progress=not args.quiet,
                                       formats=formats, sensitivity_seeds=args.sensitivity)
        print((Path(args.out) / COMPARISON_MD).read_text(encoding="utf-8"))
        print(f"wall time: {data['wall_s']:.0f} s")
        return 0
    with the_work():
        summary = reproduce_paper(args.out, study, workers=args.workers,
                                  scheduler=args.scheduler, progress=not args.quiet,
                                  formats=formats)
    _print(summary, args.out)
    return 1 if summary["failed"] else 0


def _check_meshes(study, args) -> None:
    """The coarsest mesh resolves the largest gamma of the sweep (under every convention the
    study runs)."""
    from ..params import ENERGY_CONVENTIONS, bending_factor

    conventions = ENERGY_CONVENTIONS if args.compare_conventions else [study.energy_convention]
    factor = min(bending_factor(c) for c in conventions)
    gamma, n = max(study.gammas), min(study.vertices)
    option = "--gammas" if args.gammas is not None else "--vertices"
    text = args.gammas if args.gammas is not None else " ".join(map(str, args.vertices or [n]))
    check_mesh(option, text, gamma, n, gamma_effective=gamma / factor,
               mesh=f"the {n}-vertex mesh")


#: What a folder holds when it is a previous study (or comparison of conventions) to resume.
STUDY_MARKS = ("reproduction.json", "conventions.json", "sweep", "special", "paths", "helfrich",
               "paper", "evolver-modulus")


def _check_out(out, comparison: bool) -> None:
    """A new folder, an empty one, or a previous study; never a run folder."""
    path = output_folder("--out", out)
    if not path.exists():
        return
    not_a_run_folder("--out", out, path, "a study")
    if any(path.iterdir()) and not any((path / mark).exists() for mark in STUDY_MARKS):
        raise ValueError(f"--out {out}: is a non-empty folder that is not a previous study "
                         f"(none of {', '.join(STUDY_MARKS[:2])}, sweep/); give a new or empty "
                         "folder")


def _print(summary: dict, out) -> None:
    for kind, counts in summary["runs"].items():
        rest = ", ".join(f"{k} {v}" for k, v in counts.items() if k != "total")
        print(f"{kind}: {counts['total']} runs ({rest})")
    for key, label in (("fig3", "Fig. 3 E_potato/E_capsule"),
                       ("fig11", "Fig. 11 E_bowl/E_path")):
        result = summary.get(key)
        if result:
            print(f"{label} = {result['ratio']:.3f} (paper {result['paper_ratio']:.2f}) at "
                  f"gamma = {result['a']['gamma']:g}, dV/V = {result['a']['dV_over_V']:.3f}: "
                  f"{result['b']['shape']} vs {result['a']['shape']}")
    print(f"files written: {len(summary['written'])} (figures in {out}/figures)")
    for item in summary["missing"]:
        print(f"  not produced: {item}", file=sys.stderr)
    for name in summary["failed"]:
        print(f"  failed run: {name}", file=sys.stderr)
    wall = summary["wall_s"]
    print(f"wall time: {wall['total']:.0f} s (runs {wall['runs']:.0f} s, Fig. 11 path "
          f"{wall['fig11_path']:.0f} s, figures and report {wall['outputs']:.0f} s)")
    print(f"summary: {out}/reproduction.json")
