"""``shellbuckle animate DIR [--out FILE.gif|.mp4] [--fps N] [--every K] [--dpi D]``: an
animation of a run's stored steps (:func:`shellbuckle.plots.animation.animate_run`)."""

from __future__ import annotations

from pathlib import Path

from ..plots import limits as figure_limits
from ._checks import Range, add_command, add_number, output_file, run_folder, the_work

#: Frames per second of the animation.
FPS = Range(*figure_limits.FPS, integer=True,
            reason="a frame per second at least; screens show at most 60")


def register(sub) -> None:
    parser = add_command(
        sub, "animate", help="write an animation (GIF or MP4) of a run's steps",
        description="Write an animation of the run folder DIR, one frame per stored step (or "
                    "every K-th and the last): the surface as in the run gallery, seen along "
                    "the dent axis of the last frame, coloured by mean curvature, with the "
                    "step, dV/V and the shape's class under it. GIF needs nothing beyond the "
                    "package; MP4 needs the ffmpeg program on PATH.")
    parser.add_argument("dir", metavar="DIR", help="run folder")
    parser.add_argument("--out", metavar="FILE",
                        help="animation to write, .gif or .mp4 (default <run folder name>.gif "
                             "here)")
    parser.add_argument("--fps", default="5", metavar="N",
                        help=f"frames per second (default 5); allowed: {FPS.explained()}")
    add_number(parser, "--every", "every", "show every K-th stored step and the last "
               "(default: every step)", default=None, metavar="K")
    add_number(parser, "--dpi", "dpi", "resolution, dots per inch of the 4-inch frames "
               "(default 100)", default=100)
    parser.set_defaults(func=_cmd)


def _fps(text: str) -> int:
    try:
        value = int(str(text).strip())
    except ValueError:
        raise ValueError(f"--fps {text}: not an integer; allowed: {FPS.explained()}") from None
    problem = FPS.problem(value)
    if problem:
        raise ValueError(f"--fps {text}: {problem}")
    return value


def _cmd(args) -> int:
    from ..plots.animation import FORMATS, animate_run, frame_steps, mp4_available

    fps = _fps(args.fps)
    run_path = Path(args.dir)
    out = Path(args.out) if args.out else Path(f"{run_path.resolve().name}.gif")
    output_file("--out", out, suffixes=FORMATS)
    if out.suffix.lower() == ".mp4" and not mp4_available():
        raise ValueError(f"--out {args.out}: MP4 needs the ffmpeg program, which is not on "
                         "PATH; install it or write a .gif instead")
    run = run_folder("DIR", args.dir)
    if not run.steps:
        raise ValueError(f"DIR {args.dir}: holds a run with no finished step yet")
    with the_work():
        path = animate_run(run, out, fps=fps, every=args.every, dpi=args.dpi)
    n = len(frame_steps(run.steps, args.every))
    print(f"{path} ({n} frames, {fps} per second)")
    return 0
