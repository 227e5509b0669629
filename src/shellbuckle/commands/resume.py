"""``shellbuckle resume DIR``: continue an interrupted run from its last finished step."""

from __future__ import annotations

from ._checks import add_command, run_folder
from ._options import add_run_output_options, add_threads_option
from .locate import add_locate_options, locate_arguments


def register(sub) -> None:
    parser = add_command(sub, "resume", help="continue a stored run from its last finished step",
                            description="Continue the run in DIR from its last finished step; "
                                        "the result is the same as an uninterrupted run (its "
                                        "protocol is the stored one).")
    parser.add_argument("dir", metavar="DIR", help="run folder")
    add_threads_option(parser)
    add_run_output_options(parser)
    add_locate_options(parser)
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from ..run import resume
    from ._output import report_run

    run_folder("DIR", args.dir)
    located = locate_arguments(args)
    return report_run(resume(args.dir, progress=not args.quiet, threads=args.threads,
                             **located), plot=not args.no_plot)
