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

from . import limits

log = logging.getLogger(__name__)

__all__ = ["FORMATS", "animate_run", "animation_frame", "frame_steps", "mp4_available"]

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


def _shown(run, every, steps) -> list[int]:
    if not run.steps:
        raise ValueError(f"run {str(run.path)!r} has no finished step")
    if steps is not None and not len(steps):
        raise ValueError("steps is empty: give at least one step to show, or None for every "
                         "step")
    return frame_steps(run.steps, every) if steps is None else [run.step(k) for k in steps]


def _check_number(name: str, value, low: float, high: float, integer: bool = False) -> None:
    """ValueError unless ``value`` is a number in ``[low, high]`` (an integer if asked)."""
    import numbers

    kind = numbers.Integral if integer else numbers.Real
    if isinstance(value, bool) or not isinstance(value, kind) or not low <= value <= high:
        raise ValueError(f"{name} = {value!r}: allowed: {'an integer' if integer else 'a number'}"
                         f" from {low:g} to {high:g}")


def _camera(run, shown, analyzer):
    """The animation's camera and scale: the dent axis of its last frame (None: the default
    view) and the largest distance of a vertex from its shape's centroid over the frames."""
    from .paper import conformation

    radius = max(float(np.linalg.norm(X - X.mean(axis=0), axis=1).max())
                 for X in (run.positions(k) for k in shown))
    return conformation(run, shown[-1], analyzer).axis, radius


def _title(run) -> str:
    params = run.params
    return (f"{Path(run.path).name}: $\\gamma$ = {params.gamma:g}, $\\nu$ = {params.nu:.3g}"
            + params.convention_note.replace("gamma_eff", r"$\gamma_{eff}$"))


def _draw_frame(fig, conf, axis, radius: float, title: str, size: float) -> None:
    """One frame on ``fig`` (cleared): the rendering of ``conf`` from ``axis`` at ``radius``,
    the title above it and the step, dV/V and class below."""
    from .render import CURVATURE_LIMIT, render

    fig.clear()
    ax = fig.add_axes((0.0, 0.5 / (size + 0.5) * 0.6, 1.0, size / (size + 0.5)),
                      projection="3d")
    render(ax, conf.X, conf.faces, axis=axis, values=conf.H, vlim=CURVATURE_LIMIT / conf.R,
           radius=radius)
    fig.text(0.5, 0.985, title, ha="center", va="top", fontsize=9)
    fig.text(0.5, 0.02, f"step {conf.step}, $\\Delta V/V$ = {conf.dV_over_V:.3f}, {conf.label}",
             ha="center", va="bottom", fontsize=9)


def animation_frame(run, step: int = -1, *, every: int | None = None, steps=None,
                    size: float = 4.0):
    """The frame of ``step`` (default: the last) of the animation :func:`animate_run` writes
    with ``every`` or ``steps``, as a :class:`~matplotlib.figure.Figure` (Agg canvas,
    ``size`` inches wide): the same camera, scale and texts."""
    from .paper import conformation

    run, shown, analyzer, axis, radius, fig = _setting(run, every, steps, size)
    _draw_frame(fig, conformation(run, run.step(step), analyzer), axis, radius, _title(run),
                size)
    return fig


def _setting(run, every, steps, size: float):
    """What every frame of an animation shares: the run opened, the steps shown, the shape
    analyzer, the camera (axis, radius) and the figure (Agg canvas, ``size`` inches wide)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..analysis import ShapeAnalyzer
    from .paper import _open

    run = _open(run)
    shown = _shown(run, every, steps)
    analyzer = ShapeAnalyzer(run.faces, n_vertices=len(run.positions(shown[0])), contact=False)
    axis, radius = _camera(run, shown, analyzer)
    fig = Figure(figsize=(size, size + 0.5))
    FigureCanvasAgg(fig)
    return run, shown, analyzer, axis, radius, fig


def animate_run(run, path, *, fps: int = 5, every: int | None = None, steps=None,
                dpi: int = 100, size: float = 4.0) -> Path:
    """Write the animation of ``run`` (a Run or a run folder) to ``path`` (``.gif`` or
    ``.mp4``); return the path. One frame per stored step, or per :func:`frame_steps` with
    ``every``, or exactly ``steps``; ``fps`` frames per second; frames ``size`` inches
    square at ``dpi`` (:func:`animation_frame` draws one). ValueError for another suffix, an
    MP4 without ffmpeg or a run without steps."""
    from matplotlib.animation import FFMpegWriter, PillowWriter

    from .paper import conformation

    from ..store.names import refuse_store_file

    _check_number("fps", fps, *limits.FPS, integer=True)
    _check_number("dpi", dpi, *limits.DPI, integer=True)
    _check_number("size", size, *limits.FRAME_SIZE)
    path = Path(path)
    refuse_store_file(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"an animation is written as {' or '.join(FORMATS)}, got "
                         f"{str(path)!r}")
    if suffix == ".mp4" and not mp4_available():
        raise ValueError("MP4 needs the ffmpeg program, which is not on PATH; write a .gif "
                         "instead (no extra program needed)")
    run, shown, analyzer, axis, radius, fig = _setting(run, every, steps, size)
    writer = PillowWriter(fps=fps) if suffix == ".gif" else FFMpegWriter(fps=fps)
    title = _title(run)
    with writer.saving(fig, str(path), dpi):
        for k in shown:
            _draw_frame(fig, conformation(run, k, analyzer), axis, radius, title, size)
            writer.grab_frame()
    log.info("%d frames of %s written to %s", len(shown), run.path, path)
    return path
