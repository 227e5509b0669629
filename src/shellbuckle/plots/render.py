"""Publication renderings of one conformation: flat-shaded triangles coloured by mean curvature.

A conformation (positions ``X (V, 3)`` on a closed, outward-oriented triangulation
``faces (F, 3)``) is drawn on a matplotlib 3D axis as one
:class:`~mpl_toolkits.mplot3d.art3d.Poly3DCollection` (Agg canvas, PNG or PDF).

View convention
---------------
The picture is an orthographic projection (no perspective, so sizes compare across panels).
The camera is described by three orthonormal directions: ``e`` (from the shape towards the
camera), ``up`` (vertical on the picture) and ``right = up x e`` (horizontal). The shape is
translated so that its vertex centroid is at the centre of the picture and rotated into the
camera frame before it is handed to matplotlib (which then always looks from elevation 0,
azimuth 0), so the picture's horizontal and vertical axes are exactly ``right`` and ``up``
(:meth:`Rendering.to_screen`).

``view="dent"`` (default)
    the camera looks along the dent axis ``u`` of the largest dent
    (:mod:`shellbuckle.analysis.descriptors`: the unit vector area of the dent, pointing out of
    it), so the dent faces the viewer and every conformation is shown the same way. The roll
    about ``u`` keeps the stored ``+z`` axis pointing up on the picture as far as possible (its
    projection on the picture plane is ``up``; when ``u`` is within 1e-6 of ``+-z``, the stored
    ``+y`` axis is used instead). ``tilt`` (degrees) raises the camera above the dent axis by
    that angle, towards ``up``, for a three-quarter view into the bowl (``tilt=0``: head-on).
    A shape without a dent (a sphere) is shown from :data:`DEFAULT_VIEW`.
``view=(elev, azim)``
    matplotlib's convention in the stored frame: the camera is at
    ``e = (cos elev cos azim, cos elev sin azim, sin elev)`` (degrees), with the stored ``+z``
    axis up.

The half-width of the picture is ``radius`` (default: the largest distance of a vertex from the
centroid, which does not depend on the view), so panels drawn with one ``radius`` share a
scale.

Colour
------
``color_by="mean_curvature"`` colours each face by the mean of its three vertices' mean
curvature ``H = (c1 + c2)/2`` (positive on a sphere, ``1/R``; negative where the surface is
concave seen from outside). By default (``smooth=True``) this is the smoothed curvature
``H_smooth`` of the analysis (:class:`shellbuckle.analysis.descriptors.Geometry`), whose sign
defines the analysis' dents; ``smooth=False`` uses Jülicher's discrete ``H``
(:meth:`shellbuckle.energies.bending.Bending.mean_curvature`) as it is. The colour map is
diverging (``RdBu_r``) and centred on **zero**, so inverted regions are blue and the rest red,
with symmetric limits ``+-vlim`` (default ``CURVATURE_LIMIT / R_area``, ``R_area`` the radius
of the sphere of equal area; values beyond are clipped to the end colours). ``H`` is in the
inverse units of ``X`` (``1/R`` for a run, where ``R = 1``). ``color_by="none"`` paints every
face in one grey.

Shading and ordering
--------------------
Flat (per-face) Lambert shading: the face colour is multiplied by
``ambient + (1 - ambient) max(0, n . l)``, ``n`` the outward unit normal of the face and ``l``
the light direction, fixed in the camera frame (:data:`LIGHT`: from the upper left, in front),
so a dent, whose faces turn away from the light, reads as a depression. Faces turned away from
the camera (``n . e <= 0``) are not drawn: on a closed surface they are always hidden, and
dropping them halves the work and removes most depth-ordering conflicts; the remaining faces are
drawn in the painter's order of :class:`Poly3DCollection` (sorted by mean depth, far to near).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

__all__ = ["CURVATURE_LIMIT", "DEFAULT_VIEW", "LEGEND_LOCATIONS", "LIGHT", "Rendering",
           "camera_frame", "drawn_points", "place_legend", "render", "render_figure"]

log = logging.getLogger(__name__)

#: Colour limit of the mean curvature, in units of ``1/R_area``: ``|H| R_area`` above it takes
#: the end colours. A sphere (``H R = 1``) is a light red; the rims of dents go beyond.
CURVATURE_LIMIT = 3.0
#: Camera (elevation, azimuth) in degrees for ``view="dent"`` when the shape has no dent.
DEFAULT_VIEW = (20.0, -60.0)
#: Light direction in the camera frame, (right, up, towards the viewer) components: from the
#: upper left and in front; normalized before use.
LIGHT = (-0.45, 0.55, 1.0)
#: Fraction of the light that is ambient (reaches every face whatever its orientation).
AMBIENT = 0.35
#: Colour of every face with ``color_by="none"``.
GREY = (0.78, 0.80, 0.84)
COLOR_BY = ("mean_curvature", "none")
#: mplot3d's zoom: the picture's half-width (``radius``) then spans 0.95 of the axis'
#: half-width (with zoom 1, 0.59 of it).
ZOOM = 1.6


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def camera_frame(direction, up_hint=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Rotation ``(3, 3)`` whose rows are ``right``, ``up`` and ``e`` (module docstring).

    ``direction``: from the shape towards the camera; ``up_hint``: the stored direction to show
    as up as far as possible (its projection on the picture plane); the stored ``+y`` axis is
    used when ``up_hint`` is within 1e-6 of ``+-direction``.
    """
    e = _unit(direction)
    hint = np.asarray(up_hint, dtype=np.float64)
    if abs(float(_unit(hint) @ e)) > 1.0 - 1e-6:
        hint = np.array([0.0, 1.0, 0.0]) if abs(e[1]) < 1.0 - 1e-6 else np.array([1.0, 0, 0])
    up = _unit(hint - (hint @ e) * e)
    return np.stack([np.cross(up, e), up, e])


def _view_frame(view, axis, tilt: float) -> np.ndarray:
    if isinstance(view, str):
        if view != "dent":
            raise ValueError(f"view must be 'dent' or (elevation, azimuth) in degrees, "
                             f"got {view!r}")
        if axis is None:
            return _view_frame(DEFAULT_VIEW, None, 0.0)
        base = camera_frame(axis)
        t = math.radians(float(tilt))
        return camera_frame(math.cos(t) * base[2] + math.sin(t) * base[1],
                            -math.sin(t) * base[2] + math.cos(t) * base[1])
    try:
        elev, azim = (math.radians(float(a)) for a in view)
    except (TypeError, ValueError):
        raise ValueError(f"view must be 'dent' or (elevation, azimuth) in degrees, "
                         f"got {view!r}") from None
    e = (math.cos(elev) * math.cos(azim), math.cos(elev) * math.sin(azim), math.sin(elev))
    if abs(math.cos(elev)) < 1e-9:  # looking straight down or up: keep matplotlib's azimuth
        return camera_frame(e, (-math.cos(azim), -math.sin(azim), 0.0))
    return camera_frame(e)


@dataclass(frozen=True, eq=False)
class Rendering:
    """What :func:`render` drew.

    ``collection`` (the visible faces, far to near as matplotlib sorts them), ``frame``
    (rotation ``(3, 3)``, rows ``right``, ``up``, ``e``), ``centre (3,)`` (the stored point at
    the picture's centre), ``radius`` (half-width of the picture), ``visible (F,)`` (faces
    turned towards the camera, the ones drawn), ``shade (F,)`` (Lambert factor of each face;
    the drawn colour is the colour of its value times this), ``face_values (F,)`` (curvature
    per face, or ``None``), ``axis`` (the dent axis used, or ``None``), ``mappable`` (for a
    colour bar, or ``None``).
    """

    collection: object
    frame: np.ndarray
    centre: np.ndarray
    radius: float
    visible: np.ndarray
    shade: np.ndarray
    face_values: np.ndarray | None
    axis: np.ndarray | None
    mappable: object

    def to_screen(self, points) -> np.ndarray:
        """Picture coordinates ``(n, 2)`` (``right``, ``up``; data units, origin at the centre)
        of stored points ``(n, 3)``."""
        return (np.asarray(points, dtype=np.float64) - self.centre) @ self.frame[:2].T

    def depth(self, points) -> np.ndarray:
        """Distance ``(n,)`` of stored points towards the camera from the centre's plane."""
        return (np.asarray(points, dtype=np.float64) - self.centre) @ self.frame[2]


def _curvature(X, faces, analyzer, smooth: bool):
    """Per-vertex H (smoothed or not) and the dent axis of the largest dent (or None)."""
    from ..analysis.descriptors import ShapeAnalyzer

    if analyzer is None:
        analyzer = ShapeAnalyzer(faces, n_vertices=len(X), contact=False)
    geom = analyzer.geometry(X)
    dents, rim = analyzer.dents(geom)
    axis = rim.axis if rim is not None else (dents[0].axis if dents else None)
    return (geom.H_smooth if smooth else geom.H), axis, geom.R_area


def _check(X, faces):
    X = np.asarray(X, dtype=np.float64)
    faces = np.asarray(faces)
    if X.ndim != 2 or X.shape[1] != 3 or not np.isfinite(X).all():
        raise ValueError(f"positions must be a finite (V, 3) array, got shape {X.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.min() < 0 or faces.max() >= len(X):
        raise ValueError(f"faces must be an (F, 3) array of vertex indices below {len(X)}, "
                         f"got shape {faces.shape}")
    return X, faces.astype(np.int64)


def render(ax, X, faces, *, color_by: str = "mean_curvature", view="dent", tilt: float = 0.0,
           axis=None, values=None, smooth: bool = True, vlim: float | None = None,
           cmap: str = "RdBu_r", radius: float | None = None, colorbar: bool = False,
           edges: bool = False, rasterized: bool = True, ambient: float | None = None,
           analyzer=None) -> Rendering:
    """Draw one conformation on the 3D axis ``ax`` (view, colour and shading: module docstring).

    ``X (V, 3)``, ``faces (F, 3)`` closed and outward oriented. ``color_by``:
    ``"mean_curvature"`` or ``"none"``. ``view``: ``"dent"`` or ``(elev, azim)`` in degrees;
    ``tilt``: camera elevation above the dent axis (degrees, ``view="dent"`` only). ``axis``
    overrides the dent axis (unit vector out of the dent) and ``values (V,)`` the curvature, so
    a caller that already analysed the shape does not repeat it; ``analyzer``: a
    :class:`~shellbuckle.analysis.descriptors.ShapeAnalyzer` of ``faces`` to reuse.
    ``vlim``: colour limit of ``|H|``. ``colorbar``: add a colour bar labelled ``H``.
    ``edges``: outline the triangles. ``ambient``: the ambient fraction of the light (default
    :data:`AMBIENT`; 1 turns the shading off). ``rasterized``: the surface is stored as an image in
    vector outputs (PDF), keeping them small. Returns a :class:`Rendering`.
    """
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    if not hasattr(ax, "view_init"):
        raise ValueError("render needs a 3D axis (add_subplot(..., projection='3d'))")
    if color_by not in COLOR_BY:
        raise ValueError(f"color_by must be one of {COLOR_BY}, got {color_by!r}")
    X, faces = _check(X, faces)
    need_analysis = (view == "dent" and axis is None) or (color_by != "none" and values is None)
    R_area = None
    if need_analysis:
        H, found_axis, R_area = _curvature(X, faces, analyzer, smooth)
        values = H if values is None else values
        axis = found_axis if axis is None else axis
    frame = _view_frame(view, None if axis is None else np.asarray(axis, float), tilt)
    centre = X.mean(axis=0)
    P = (X - centre) @ frame.T  # camera coordinates (right, up, towards the viewer)
    r = float(np.linalg.norm(X - centre, axis=1).max()) if radius is None else float(radius)
    tri = P[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    visible = n[:, 2] > 0.0
    light = _unit(LIGHT)
    ambient = AMBIENT if ambient is None else float(ambient)
    shade = ambient + (1.0 - ambient) * np.clip(n @ light, 0.0, None)
    mappable = face_values = None
    if color_by == "mean_curvature":
        values = np.asarray(values, dtype=np.float64)
        face_values = values[faces].mean(axis=1) if len(values) == len(X) else values
        if face_values.shape != (len(faces),):
            raise ValueError(f"values must have one entry per vertex ({len(X)}) or face "
                             f"({len(faces)}), got {values.shape}")
        if vlim is None:
            if R_area is None:
                R_area = math.sqrt(_area(X, faces) / (4.0 * math.pi))
            vlim = CURVATURE_LIMIT / R_area
        norm = Normalize(-vlim, vlim, clip=True)
        import matplotlib

        colormap = matplotlib.colormaps[cmap]
        rgb = colormap(norm(face_values))[:, :3]
        from matplotlib.cm import ScalarMappable

        mappable = ScalarMappable(norm=norm, cmap=colormap)
    else:
        rgb = np.tile(GREY, (len(faces), 1))
    rgba = np.column_stack([rgb * shade[:, None], np.ones(len(faces))])[visible]
    # matplotlib looks from +x (elev 0, azim 0): data x = depth, y = right, z = up
    polys = tri[visible][:, :, [2, 0, 1]]
    collection = Poly3DCollection(polys, facecolors=rgba,
                                  edgecolors=(0, 0, 0, 0.25) if edges else rgba,
                                  linewidths=0.15 if edges else 0.3, zsort="average")
    collection.set_rasterized(rasterized)
    ax.add_collection3d(collection)
    ax.set_proj_type("ortho")
    ax.view_init(elev=0.0, azim=0.0, roll=0.0)
    ax.set(xlim=(-r, r), ylim=(-r, r), zlim=(-r, r))
    ax.set_box_aspect((1, 1, 1), zoom=ZOOM)
    # mplot3d shifts its picture window up and left to make room for axis labels; with the axes
    # off, centre it so the picture's centre is the axis' centre
    for interval in ("intervalx", "intervaly"):
        lo, hi = getattr(ax.viewLim, interval)
        setattr(ax.viewLim, interval, (-(hi - lo) / 2.0, (hi - lo) / 2.0))
    ax.set_axis_off()
    if colorbar and mappable is not None:
        ax.figure.colorbar(mappable, ax=ax, shrink=0.7, pad=0.0, fraction=0.05,
                           label=r"mean curvature $H$ ($1/R$)")
    return Rendering(collection=collection, frame=frame, centre=centre, radius=r,
                     visible=visible, shade=shade, face_values=face_values,
                     axis=None if axis is None else _unit(axis), mappable=mappable)


def _area(X, faces) -> float:
    x0, x1, x2 = X[faces[:, 0]], X[faces[:, 1]], X[faces[:, 2]]
    return float(0.5 * np.linalg.norm(np.cross(x1 - x0, x2 - x0), axis=1).sum())


#: Width of a journal column, inches (EPJE, APS: 3.3-3.4 in).
COLUMN_WIDTH = 3.4


def render_figure(X, faces, *, size: float = COLUMN_WIDTH, title: str | None = None,
                  colorbar: bool = True, **options) -> Figure:
    """A one-panel :class:`~matplotlib.figure.Figure` (Agg, ``size`` inches wide) with the
    rendering of :func:`render` (``options`` are passed on), by default with its colour bar to
    the right, and ``title`` above. Save it with ``fig.savefig(path, dpi=300)``."""
    bar = 0.8 if colorbar else 0.0  # inches for the colour bar and its label
    side = size - bar
    top = 0.3 if title else 0.0
    height = side + top
    fig = Figure(figsize=(size, height))
    ax = fig.add_axes((0.0, 0.0, side / size, side / height), projection="3d")
    rendering = render(ax, X, faces, **options)
    if colorbar and rendering.mappable is not None:
        cax = fig.add_axes(((side + 0.02) / size, 0.15 * side / height, 0.12 / size,
                            0.7 * side / height))
        fig.colorbar(rendering.mappable, cax=cax).set_label(r"mean curvature $H$ ($1/R$)",
                                                              fontsize=8)
        cax.tick_params(labelsize=7)
    if title:
        fig.text(0.5 * side / size, 1.0 - 0.5 * top / height, title, ha="center",
                 va="center", fontsize=9)
    return fig


# ---------------------------------------------------------------------- legends off the data

#: Where :func:`place_legend` tries a legend inside its axes, in this order.
LEGEND_LOCATIONS = ("upper left", "upper right", "lower right", "lower left", "center right",
                    "center left", "upper center", "lower center")


def _layout(fig):
    """The renderer of ``fig`` after its layout (axes at their final places), on an Agg
    canvas (attached when the figure has none)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    fig.draw_without_rendering()
    return fig.canvas.get_renderer()


def _along(P: np.ndarray, step: float) -> np.ndarray:
    """The points ``P (n, 2)`` and points every ``step`` along the segments between them
    (skipping segments with a non-finite end)."""
    a, b = P[:-1], P[1:]
    ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    a, b = a[ok], b[ok]
    counts = np.maximum(np.ceil(np.linalg.norm(b - a, axis=1) / step).astype(int), 1)
    seg = np.repeat(np.arange(len(a)), counts)
    t = (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)) / counts[seg]
    return np.concatenate([P[np.isfinite(P).all(axis=1)], a[seg] + t[:, None] * (b - a)[seg]])


def drawn_points(ax, step: float = 2.0) -> np.ndarray:
    """Display coordinates ``(n, 2)`` (pixels) of what the 2D axes ``ax`` draws as data, inside
    its box: the vertices of every visible line, and points every ``step`` pixels along its
    segments when it is drawn as a line; the segments of line collections (error bars); the
    offsets of scattered markers. Valid after the figure's layout."""
    from matplotlib.collections import LineCollection, PathCollection

    pieces = [np.zeros((0, 2))]
    for line in ax.get_lines():
        P = np.asarray(line.get_xydata(), float)
        if not line.get_visible() or not len(P):
            continue
        P = line.get_transform().transform(P)
        joined = line.get_linestyle() not in ("None", "", " ") and len(P) > 1
        pieces.append(_along(P, step) if joined else P[np.isfinite(P).all(axis=1)])
    for collection in ax.collections:
        if not collection.get_visible():
            continue
        if isinstance(collection, LineCollection):
            for segment in collection.get_segments():
                if len(segment):
                    pieces.append(_along(collection.get_transform().transform(segment), step))
        elif isinstance(collection, PathCollection):
            offsets = np.asarray(collection.get_offsets(), float)
            pieces.append(collection.get_offset_transform().transform(offsets))
    P = np.concatenate(pieces)
    box = ax.get_window_extent()
    inside = ((P[:, 0] >= box.x0) & (P[:, 0] <= box.x1) & (P[:, 1] >= box.y0)
              & (P[:, 1] <= box.y1))
    return P[inside]


def place_legend(ax, *, outside: bool = True, pad: float = 4.0, **options):
    """Add the legend of the 2D axes ``ax`` where it covers no data, and return it.

    ``loc="best"`` lets a legend cover data when the data fill the axes. Here each place of
    :data:`LEGEND_LOCATIONS` is tried in turn, after the figure's layout, and the first whose
    box grown by ``pad`` points holds none of :func:`drawn_points` and overlaps no text of the
    axes is kept. When none is free the legend goes beside the axes with ``outside``
    (right, top-aligned: a constrained layout makes room for it; a figure with fixed margins
    must leave it), else where it covers the fewest points. Call it once the axes hold all
    their data and limits. ``options`` go to :meth:`matplotlib.axes.Axes.legend`."""
    renderer = _layout(ax.figure)
    points = drawn_points(ax)
    texts = [t.get_window_extent(renderer) for t in ax.texts
             if t.get_visible() and t.get_text().strip()]
    options.setdefault("borderaxespad", 0.4)
    legend = ax.legend(**options)
    grow = pad * ax.figure.dpi / 72.0
    covered = {}
    for loc in LEGEND_LOCATIONS:
        legend.set_loc(loc)
        box = legend.get_window_extent(renderer).padded(grow)
        covered[loc] = (box.count_contains(points)
                        + 10 ** 6 * sum(box.overlaps(t) for t in texts))
        if covered[loc] == 0:
            return legend
    if outside:
        legend.set_loc("upper left")
        legend.set_bbox_to_anchor((1.02, 1.0), transform=ax.transAxes)
        legend.borderaxespad = 0.0
    else:
        legend.set_loc(min(covered, key=covered.get))
    return legend
