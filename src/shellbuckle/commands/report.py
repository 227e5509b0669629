"""``shellbuckle report DIR... [--out FILE] [--format md|html]``: the reproduction report
(:func:`shellbuckle.studies.quilliet2008.report.write_report`)."""

from __future__ import annotations

from ._checks import add_command, input_file, output_file


def register(sub) -> None:
    parser = add_command(
        sub, "report", help="write the reproduction report (our numbers next to the paper's)",
        description="Collect the runs in DIR... (run folders, sweep folders, or folders of run "
                    "folders; nothing is recomputed), fit the buckling thresholds vs gamma and "
                    "write a report that puts our numbers next to every number of the paper's "
                    "reference file (shipped as shellbuckle/data/quilliet2008.json): "
                    "difference, verdict, the disagreements, the paper's inconsistent "
                    "gamma/d-R captions, the figures and the provenance of every run.")
    parser.add_argument("dirs", nargs="+", metavar="DIR", help="run or sweep folder")
    parser.add_argument("--out", default=None,
                        help="report file, in an existing folder (default: "
                             "reproduction_report.md or .html)")
    parser.add_argument("--format", dest="fmt", default=None, choices=("md", "html"),
                        help="md (Markdown, figures as PNG files beside it) or html (one file, "
                             "figures embedded); default from the --out suffix, else md")
    parser.add_argument("--reference", default=None, metavar="FILE",
                        help="the paper's reference JSON (default: found beside the package, "
                             "or $SHELLBUCKLE_REFERENCE)")
    parser.add_argument("--no-figures", action="store_true", help="leave the figures out")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from pathlib import Path

    from ..analysis.collect import check_folder
    from ..studies.quilliet2008.report import write_report

    fmt = args.fmt
    if fmt is None:
        suffix = Path(args.out).suffix.lower() if args.out else ""
        fmt = "html" if suffix in (".html", ".htm") else "md"
    out = args.out or f"reproduction_report.{fmt}"
    for folder in args.dirs:
        if not Path(folder).exists():
            raise FileNotFoundError(f"DIR {folder}: does not exist")
        if not Path(folder).is_dir():
            raise ValueError(f"DIR {folder}: is a file; expected a run or sweep folder")
        check_folder("DIR", folder)
    if args.reference is not None:
        input_file("--reference", args.reference)
    output_file("--out", out, suffixes=(".md",) if fmt == "md" else (".html", ".htm"))
    path = write_report(args.dirs, out, fmt, reference=args.reference,
                        figures=not args.no_figures)
    print(path)
    return 0
