"""``shellbuckle locate DIR [--tol T] [--again]``: the buckling events of a run located by
bisection in volume (:mod:`shellbuckle.locate`)."""

from __future__ import annotations

from ._checks import add_command, add_number, run_folder, the_work
from ._options import add_threads_option


def register(sub) -> None:
    parser = add_command(
        sub, "locate", help="locate a run's buckling events between its volume steps",
        description="Locate the primary buckling, the loss of axisymmetry and the onset of "
                    "wrinkles of the deflation run in DIR by bisection in volume between the "
                    "two stored steps around each: from the stored step before the event, the "
                    "protocol's step (same jiggle, minimizations and zero-curvature cycle) is "
                    "made to the middle volume and classified, until the bracket is narrower "
                    "than --tol. The located points (volume, energies, pressure, the lowest "
                    "eigenvalue of the constrained Hessian on both sides, the mechanism: "
                    "where the old branch, followed without jiggle, ends) are "
                    "stored in DIR/located.json; the steps and the table are not changed. "
                    "Thresholds, fits and Fig. 10 then use them. `deflate` does this at the "
                    "end of every finished run unless --no-locate.")
    parser.add_argument("dir", metavar="DIR", nargs="+",
                        help="run folder, or a sweep or study folder: every deflation in it "
                             "(those that cannot be located are named and skipped)")
    add_number(parser, "--tol", "locate_tol", "width in dV/V of the final bracket "
               "(default 1e-4)", default=None, metavar="T")
    parser.add_argument("--again", action="store_true",
                        help="locate again events already located to --tol")
    parser.add_argument("--json", action="store_true", help="print the located points as JSON")
    add_threads_option(parser)
    parser.set_defaults(func=_cmd)


def add_locate_options(parser) -> None:
    """``--no-locate`` and ``--locate-tol`` of the commands that make or extend a deflation."""
    group = parser.add_argument_group(
        "located bifurcations (at the end of a finished run; `shellbuckle locate DIR` later)")
    group.add_argument("--no-locate", action="store_true",
                       help="do not locate the buckling events between the volume steps")
    add_number(group, "--locate-tol", "locate_tol", "width in dV/V to which the events are "
               "located (default 1e-4)", default=None, metavar="T")


def locate_arguments(args) -> dict:
    """The ``locate``/``locate_tol`` arguments of :func:`shellbuckle.run.deflate`."""
    from ..store.located import LOCATE_TOL as DEFAULT_TOL  # the locator's, without its imports

    if args.no_locate and args.locate_tol is not None:
        raise ValueError(f"--locate-tol {args.locate_tol:g}: cannot be combined with "
                         "--no-locate")
    return {"locate": not args.no_locate,
            "locate_tol": DEFAULT_TOL if args.locate_tol is None else args.locate_tol}


def _cmd(args) -> int:
    import sys
    from pathlib import Path

    from ..analysis.collect import run_folders
    from ..locate import DEFAULT_TOL, locatable, locate

    runs = []
    for name in args.dir:
        try:
            folders = run_folders(name) if Path(name).is_dir() else []
        except ValueError:
            folders = []
        # no run in it: run_folder says what is wrong with the folder itself
        runs += [run_folder("DIR", folder) for folder in folders or [name]]
    if len(runs) == 1:
        why = locatable(runs[0])
        if why is not None:
            raise ValueError(f"DIR {args.dir[0]}: its events cannot be located: {why}")
    found = {}
    for run in runs:
        why = locatable(run)
        if why is not None:
            print(f"{run.path}: not located: {why}", file=sys.stderr)  # stdout: the results
            continue
        with the_work():
            found[str(run.path)] = points = locate(
                run, tol=DEFAULT_TOL if args.tol is None else args.tol, threads=args.threads,
                again=args.again)
        if not args.json:
            from ._output import print_located

            if len(runs) > 1:
                print(f"{run.path}:")
            print_located(run, points)
    if args.json:
        from ._output import print_json

        return print_json(found if len(runs) > 1 else next(iter(found.values())), indent=1)
    return 0
