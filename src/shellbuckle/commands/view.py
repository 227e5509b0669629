"""``shellbuckle view DIR [--out FILE.html] [--color C] [--step K]``: an interactive page of a
run."""

from __future__ import annotations

from ._checks import add_command, add_number, output_file, run_folder
from ._options import stored_step


def register(sub) -> None:
    parser = add_command(
        sub, "view", help="write a self-contained interactive HTML page of a run",
        description="Write one self-contained HTML file (no network access needed to open it) "
                    "showing the surface of every stored step of the run folder DIR: a step "
                    "slider and play button, drag to rotate, wheel to zoom, a colour legend, "
                    "the per-step table and the energies and pressure against dV/V. Colours: "
                    "curvature (vertex mean curvature H, 1/R), strain (stretching energy per "
                    "rest area of each triangle, kappa/R^2) or bending (bending energy per "
                    "area, kappa/R^2); the page can switch between them.")
    parser.add_argument("dir", metavar="DIR", help="run folder")
    parser.add_argument("--out", metavar="FILE.html",
                        help="page to write (default DIR/view.html)")
    parser.add_argument("--color", default="curvature",
                        help="initial colouring: curvature (default), strain or bending")
    add_number(parser, "--step", "step", "step the page opens at (negative counts from the "
               "last; default -1)", metavar="K")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from pathlib import Path

    from ..plots.viewer import COLORS, write_html
    if args.color not in COLORS:
        raise ValueError(f"--color must be one of {', '.join(COLORS)}, got {args.color!r}")
    run = run_folder("DIR", args.dir)
    out = Path(args.out) if args.out else run.path / "view.html"
    output_file("--out", out, suffixes=(".html", ".htm"))
    step = stored_step(run, -1 if args.step is None else args.step)
    path = write_html(run, out, color=args.color, step=step)
    print(f"{path} ({path.stat().st_size / 1e6:.2f} MB, {len(run.steps)} steps)")
    return 0
