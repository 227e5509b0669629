"""An animation of a run: one frame per stored step (or every K-th), as GIF or MP4.

Each frame is the rendering of the run gallery (:func:`shellbuckle.plots.render.render`,
coloured by the analysis' smoothed mean curvature on the gallery's fixed scale
``+-CURVATURE_LIMIT/R``) with one camera for the whole animation: along the dent axis of the
last frame (so the dent, once it forms, faces the viewer and does not jump), from the default
view when the last frame has no dent; one scale for all frames (the largest radius). The
title gives the run's gamma and nu; the caption the step, dV/V, the class and W (the table's
analysis columns when the run was analysed, else the classifier's result).

GIF is written by matplotlib's :class:`~matplotlib.animation.PillowWriter` (Pillow comes with
matplotlib); MP4 by :class:`~matplotlib.animation.FFMpegWriter`, which needs the ``ffmpeg``
program (:func:`mp4_available`).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

__all__ = ["FORMATS", "animate_run", "frame_steps", "mp4_available"]

#: Suffixes of the animations written.
FORMATS = (".gif", ".mp4")


def mp4_available() -> bool:
    """Whether matplotlib can write MP4: the ``ffmpeg`` program is found."""
    from matplotlib.animation import FFMpegWriter

    return bool(FFMpegWriter.isAvailable())


def frame_steps(steps, every: int | None = None) -> list[int]:
    """The steps shown: every ``every``-th of ``steps`` from the first, and the last."""
    steps = list(steps)
    if every is None or every == 1:
        return steps
    if int(every) < 1:
        raise ValueError(f"every must be a positive number of steps, got {every}")
    shown = steps[::int(every)]
    if shown[-1] != steps[-1]:
        shown.append(steps[-1])
    return shown


def animate_run(run, path, *, fps: int = 5, every: int | None = None, steps=None,
                dpi: int = 100, size: float = 4.0) -> Path:
    """Write the animation of ``run`` (a Run or a run folder) to ``path`` (``.gif`` or
    ``.mp4``); return the path. One frame per stored step, or per :func:`frame_steps` with
    ``every``, or exactly ``steps``; ``fps`` frames per second; frames ``size`` inches
    square at ``dpi``. ValueError for another suffix, an MP4 without ffmpeg or a run without
    steps."""
    from matplotlib.animation import FFMpegWriter, PillowWriter
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..analysis import ShapeAnalyzer
    from .paper import _open, conformation
    from .render import CURVATURE_LIMIT, render

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"an animation is written as {' or '.join(FORMATS)}, got "
                         f"{str(path)!r}")
    if suffix == ".mp4" and not mp4_available():
        raise ValueError("MP4 needs the ffmpeg program, which is not on PATH; write a .gif "
                         "instead (no extra program needed)")
    run = _open(run)
    if not run.steps:
        raise ValueError(f"run {str(run.path)!r} has no finished step")
    shown = frame_steps(run.steps, every) if steps is None else [run.step(k) for k in steps]
    faces = run.faces
    analyzer = ShapeAnalyzer(faces, n_vertices=len(run.positions(shown[0])), contact=False)
    confs = [conformation(run, k, analyzer) for k in shown]
    radius = max(float(np.linalg.norm(c.X - c.X.mean(axis=0), axis=1).max()) for c in confs)
    axis = confs[-1].axis
    params = run.params
    fig = Figure(figsize=(size, size + 0.5))
    FigureCanvasAgg(fig)
    writer = PillowWriter(fps=fps) if suffix == ".gif" else FFMpegWriter(fps=fps)
    title = (f"{Path(run.path).name}: $\\gamma$ = {params.gamma:g}, $\\nu$ = {params.nu:.3g}"
             + params.convention_note.replace("gamma_eff", r"$\gamma_{eff}$"))
    with writer.saving(fig, str(path), dpi):
        for c in confs:
            fig.clear()
            ax = fig.add_axes((0.0, 0.5 / (size + 0.5) * 0.6, 1.0, size / (size + 0.5)),
                              projection="3d")
            render(ax, c.X, faces, axis=axis, values=c.H, vlim=CURVATURE_LIMIT, radius=radius)
            fig.text(0.5, 0.985, title, ha="center", va="top", fontsize=9)
            fig.text(0.5, 0.02, f"step {c.step}, $\\Delta V/V$ = {c.dV_over_V:.3f}, {c.label}",
                     ha="center", va="bottom", fontsize=9)
            writer.grab_frame()
    log.info("%d frames of %s written to %s", len(confs), run.path, path)
    return path
