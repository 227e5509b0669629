"""Interactive viewer of a run: one self-contained HTML page (no network access needed).

The page (template ``viewer.html`` beside this module) shows the surface of every stored step
with a step slider and a play button (opening at the last step), coloured by one of

- ``curvature``: vertex mean curvature ``H = (c1 + c2)/2`` of the run's bending discretization,
  in ``1/R``, on a diverging scale centred on 0 (negative where the surface is inverted);
- ``strain``: stretching energy per rest area of each constant-strain triangle, ``kappa/R^2``;
- ``bending``: bending energy per area at each vertex, ``kappa/2 (2 H - c0)^2``, ``kappa/R^2``

(see :class:`shellbuckle.export.RunFields`), with a colour legend, the per-step table (current
row highlighted, a click selects a step) and the energies and pressure against dV/V as small
SVG charts with a marker at the current step. A renderer written for the page draws
flat-shaded triangles with per-vertex colours and a directional light: WebGL when the browser
offers it, else a depth-sorted canvas-2D painter (add ``?renderer=canvas2d`` to the address to
force it). Drag rotates, the wheel zooms, a double-click resets the view; arrow keys step and
space plays.

Compactness: positions are quantized to uint16 on the bounding box of all steps (error at most
``extent / 131070``, 1.5e-5 R for a sphere of radius 1) and every colour field to the uint8
index of its 256-colour scale (range shared by all steps, the extreme 2 % of the values
clipped), all little-endian base64: about 10 bytes per vertex and step, so 3612 vertices x 50
steps make a page of 2.5 MB (tests/test_viewer.py::test_page_size_for_the_papers_mesh).

After it has drawn a frame the page sets ``data-rendered`` (frames drawn), ``data-renderer``
(``webgl`` or ``canvas2d``), ``data-step``, ``data-triangles`` (of the first frame) and
``data-frame-ms`` (time of the last draw call) on its ``<html>`` element; a script error sets
``data-error``. The address may carry ``?step=K&color=strain&renderer=canvas2d``.

The functions here take a :class:`~shellbuckle.run.Run` or a run folder; the page itself is
built by :mod:`shellbuckle.plots.viewer_page` from a run object (what
:meth:`shellbuckle.run.Run.view` uses).
"""

from __future__ import annotations

from pathlib import Path

from ..store.view import Run
from .viewer_page import COLORS, ViewerPage, page_of

__all__ = ["COLORS", "ViewerPage", "html_page", "write_html", "show"]


def html_page(run, color: str = "curvature", step: int = -1) -> str:
    """The viewer page of ``run`` (a :class:`~shellbuckle.run.Run` or a run folder) as text.

    ``color`` is the initial colouring, one of ``COLORS``; the page can switch between them.
    ``step``: the step it opens at (negative counts from the last; default the last).
    """
    if color not in COLORS:
        raise ValueError(f"color must be one of {', '.join(COLORS)}, got {color!r}")
    return page_of(Run.of(run), color, step)


def write_html(run, path, color: str = "curvature", step: int = -1) -> Path:
    """Write the self-contained viewer page of ``run`` to ``path``; return the path.

    See the module docstring for what the page shows; ``color`` and ``step`` as in
    :func:`html_page`.
    """
    from ..store.names import refuse_store_file

    path = Path(path)
    refuse_store_file(path)  # before the page is built
    if not path.parent.is_dir():
        raise FileNotFoundError(f"directory {str(path.parent)!r} does not exist")
    return ViewerPage(html_page(run, color, step)).write(path)


def show(run, color: str = "curvature", height: int = 760, step: int = -1):
    """Show the viewer inline in Jupyter: an ``IPython.display.HTML`` holding an iframe.

    The page goes in the iframe's ``srcdoc``, so nothing is served or fetched. Without
    IPython the page is written to a temporary file, opened in the default web browser, and
    its path returned. (:meth:`shellbuckle.run.Run.view` does the same from the run object.)
    """
    page = ViewerPage(html_page(run, color, step), height=height)
    try:
        from IPython.display import HTML
    except ImportError:
        import tempfile

        fd, name = tempfile.mkstemp(prefix="shellbuckle_view_", suffix=".html")
        with open(fd, "w", encoding="utf-8") as f:
            f.write(page.html)
        page.path = Path(name)
        page.open()
        return page.path
    return HTML(page.iframe())
