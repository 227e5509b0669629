"""``shellbuckle reproduce-paper``: the paper's study as a sweep, then figures and report.

A thin layer over :func:`shellbuckle.studies.quilliet2008.reproduce.reproduce_paper`; see
``docs/reproduce.md``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ._options import add_convention_option, add_protocol_options, values


def register(sub) -> None:
    parser = sub.add_parser(
        "reproduce-paper", help="run the paper's study (sweep on Dask), write figures and report",
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
                             "7465,15163,20995,29160)")
    parser.add_argument("--seeds", type=int, metavar="N", help="seeds 0..N-1 (default 3)")
    parser.add_argument("--vertices", type=int, nargs="+", metavar="N",
                        help="randomized mesh size(s) (default 3594; several: a mesh-"
                             "convergence study, e.g. --vertices 3594 10000 20000)")
    add_protocol_options(parser, ("until", "dv"))
    parser.add_argument("--path-increments", type=int, metavar="N",
                        help="gamma increments of the Fig. 11 path (default 8)")
    add_convention_option(parser)
    parser.add_argument("--compare-conventions", action="store_true",
                        help="run the study under each energy convention (helfrich, paper, "
                             "evolver-modulus) in OUT/<convention>/, special runs for every "
                             "seed, and score each reading against every number of the paper: "
                             "OUT/conventions.md, .json and conventions_thresholds.png")
    parser.add_argument("--sensitivity", type=int, metavar="SEEDS", nargs="?", const=2,
                        help="with --compare-conventions: also the sensitivity table at gamma "
                             "2333 and 15163 under helfrich and the best other reading (jiggle "
                             "temperature 0.01/0.2, a CG quench, Evolver's bending, a 10242-"
                             "vertex mesh), with SEEDS seeds (default 2): OUT/sensitivity.md")
    parser.add_argument("--no-special", action="store_true",
                        help="only the sweep: no Fig. 3 and Fig. 11 runs")
    parser.add_argument("--formats", default="png,pdf", help="figure formats (default png,pdf)")
    parser.add_argument("--workers", type=int, metavar="N",
                        help="local Dask worker processes (default: cores)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="address of a running Dask scheduler (e.g. tcp://host:8786)")
    parser.add_argument("--out", default="reproduction", metavar="DIR",
                        help="output folder (default ./reproduction)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from ..studies.quilliet2008.reproduce import Study, reproduce_paper

    given = {}
    if args.gammas is not None:
        given["gammas"] = tuple(values("--gammas", args.gammas))
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
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be >= 1, got {args.workers}")
    if args.workers is not None and args.scheduler is not None:
        raise ValueError("--workers applies to the local cluster; a --scheduler has its own "
                         "workers")
    formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
    bad = [f for f in formats if f not in ("png", "pdf", "svg")]
    if bad or not formats:
        raise ValueError(f"--formats must be among png, pdf, svg; got {args.formats!r}")
    if args.sensitivity is not None and not args.compare_conventions:
        raise ValueError("--sensitivity needs --compare-conventions (it uses the best reading)")
    if args.sensitivity is not None and args.sensitivity < 1:
        raise ValueError(f"--sensitivity must be a number of seeds >= 1, got {args.sensitivity}")
    if args.compare_conventions:
        if args.energy_convention is not None:
            raise ValueError("--compare-conventions runs every convention; do not give "
                             f"--energy-convention (got {args.energy_convention!r})")
        from ..studies.quilliet2008.conventions import COMPARISON_MD, compare_conventions

        data = compare_conventions(args.out, study, workers=args.workers,
                                   scheduler=args.scheduler, progress=not args.quiet,
                                   formats=formats, sensitivity_seeds=args.sensitivity)
        print((Path(args.out) / COMPARISON_MD).read_text(encoding="utf-8"))
        print(f"wall time: {data['wall_s']:.0f} s")
        return 0
    summary = reproduce_paper(args.out, study, workers=args.workers, scheduler=args.scheduler,
                              progress=not args.quiet, formats=formats)
    _print(summary, args.out)
    return 1 if summary["failed"] else 0


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
