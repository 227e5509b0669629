"""3D renderings: the view looks along the dent axis, the picture follows matplotlib's camera
convention, the colours follow the curvature, and the rendering ignores rigid motions."""

import math

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d import proj3d

from shellbuckle.mesh import icosphere
from shellbuckle.plots import render as rmod
from shellbuckle.plots.render import camera_frame, render, render_figure

from test_analysis_shapes import inverted_cap, rotation

ALPHA = math.radians(45.0)


@pytest.fixture(scope="module")
def sphere():
    return icosphere(12)  # 1442 vertices


def _axis(seed):
    v = np.random.default_rng(seed).normal(size=3)
    return v / np.linalg.norm(v)


def _pixels(size=3.0, dpi=100, **options):
    """RGB image (rows top to bottom) of one rendering filling a square figure."""
    fig = Figure(figsize=(size, size), dpi=dpi)
    ax = fig.add_axes((0, 0, 1, 1), projection="3d")
    rendering = render(ax, **options)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].astype(int), rendering


def _moments(mask):
    """Centroid (x right, y up; pixels from the image centre) and principal axis ratio."""
    rows, cols = np.nonzero(mask)
    h, w = mask.shape
    x, y = cols + 0.5 - w / 2, h / 2 - (rows + 0.5)
    cx, cy = x.mean(), y.mean()
    cov = np.cov(np.stack([x - cx, y - cy]))
    return cx, cy, cov


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dent_view_puts_the_dent_at_the_centre_seen_head_on(sphere, seed):
    # inverted cap about a random axis: the inverted region (blue) is a disc bounded by the rim
    # circle; seen along the axis its picture is a disc centred on the picture's centre
    u = _axis(seed)
    X = inverted_cap(sphere.X, ALPHA, u)
    img, rendering = _pixels(X=X, faces=sphere.faces, view="dent", ambient=1.0)  # unshaded
    assert abs(rendering.axis @ u) > 0.999
    assert rendering.axis @ u > 0  # the camera is on the dent's side (looks into it)
    blue = img[..., 2] > img[..., 0] + 40
    cx, cy, cov = _moments(blue)
    width = img.shape[1]
    assert blue.sum() > 0.05 * img.shape[0] * width
    assert abs(cx) < 0.01 * width and abs(cy) < 0.01 * width
    evals = np.linalg.eigvalsh(cov)
    assert math.sqrt(evals[0] / evals[1]) > 0.97  # a circle, not an ellipse


@pytest.mark.parametrize("tilt", [20.0, 35.0])
def test_tilted_dent_view_shows_the_rim_as_an_ellipse_of_aspect_cos_tilt(sphere, tilt):
    # seen at an angle t from its axis, a flat disc projects to an ellipse with axes 1 : cos t,
    # the short one vertical (the camera is raised towards 'up')
    X = inverted_cap(sphere.X, ALPHA, _axis(7))
    img, _ = _pixels(size=4.0, X=X, faces=sphere.faces, view="dent", tilt=tilt, ambient=1.0)
    blue = img[..., 2] > img[..., 0] + 40
    cx, _, cov = _moments(blue)
    assert abs(cx) < 0.01 * img.shape[1]
    assert abs(cov[0, 1]) < 0.02 * cov[0, 0]
    assert math.sqrt(cov[1, 1] / cov[0, 0]) == pytest.approx(math.cos(math.radians(tilt)),
                                                             abs=0.04)


def _display(ax, data_points):
    xs, ys, _ = proj3d.proj_transform(*np.asarray(data_points, float).T, ax.get_proj())
    return ax.transData.transform(np.column_stack([xs, ys]))


@pytest.mark.parametrize("elev, azim", [(20.0, -60.0), (-35.0, 110.0), (70.0, 200.0)])
def test_explicit_view_is_matplotlibs_camera(sphere, elev, azim):
    # the same points drawn by matplotlib itself at (elev, azim), orthographic: the picture
    # coordinates must agree up to one scale and a shift
    X = inverted_cap(sphere.X, ALPHA, _axis(3))
    fig = Figure(figsize=(4, 4))
    ax = fig.add_axes((0, 0, 1, 1), projection="3d")
    rendering = render(ax, X, sphere.faces, view=(elev, azim), color_by="none")
    e, a = math.radians(elev), math.radians(azim)
    np.testing.assert_allclose(rendering.frame[2], [math.cos(e) * math.cos(a),
                                                    math.cos(e) * math.sin(a), math.sin(e)],
                               atol=1e-12)
    ref = Figure(figsize=(4, 4)).add_axes((0, 0, 1, 1), projection="3d")
    ref.set_proj_type("ortho")
    ref.view_init(elev=elev, azim=azim)
    r = 1.5
    ref.set(xlim=(-r, r), ylim=(-r, r), zlim=(-r, r))
    ref.set_box_aspect((1, 1, 1))
    FigureCanvasAgg(ref.figure).draw()
    theirs = _display(ref, X)
    ours = rendering.to_screen(X)
    theirs = theirs - theirs.mean(axis=0)
    ours = ours - ours.mean(axis=0)
    scale = np.linalg.norm(theirs) / np.linalg.norm(ours)
    np.testing.assert_allclose(ours * scale, theirs, atol=1e-6 * np.abs(theirs).max())


def test_picture_coordinates_are_where_matplotlib_draws(sphere):
    # to_screen (data units, origin at the picture's centre) against the pixels matplotlib
    # puts the drawn points at: linear, same scale on both axes, centre at the axis' centre
    X = inverted_cap(sphere.X, ALPHA, _axis(4))
    fig = Figure(figsize=(5, 3))
    ax = fig.add_axes((0, 0, 1, 1), projection="3d")
    rendering = render(ax, X, sphere.faces, view="dent", tilt=25.0)
    FigureCanvasAgg(fig).draw()
    P = (X - rendering.centre) @ rendering.frame.T  # right, up, depth
    pix = _display(ax, P[:, [2, 0, 1]])  # drawn as (depth, right, up), camera on +x
    centre = np.array([ax.bbox.x0 + ax.bbox.width / 2, ax.bbox.y0 + ax.bbox.height / 2])
    screen = rendering.to_screen(X)
    scale = np.linalg.norm(pix - centre) / np.linalg.norm(screen)
    np.testing.assert_allclose(centre + scale * screen, pix, atol=1e-6 * scale)
    # the shape fits inside the (square) axis box
    assert scale * rendering.radius < 0.5 * min(ax.bbox.width, ax.bbox.height)


def test_rendering_is_invariant_to_rigid_motions(sphere):
    # rotate and translate the shape: along the dent axis, the distances of the vertices from
    # the picture's centre and their depths are the same, and so are the colours
    X = inverted_cap(sphere.X, ALPHA, _axis(5))
    Q = rotation(np.random.default_rng(11))
    Y = X @ Q.T + np.array([3.0, -1.0, 2.0])
    ax1 = Figure().add_subplot(projection="3d")
    ax2 = Figure().add_subplot(projection="3d")
    a = render(ax1, X, sphere.faces)
    b = render(ax2, Y, sphere.faces)
    np.testing.assert_allclose(np.linalg.norm(b.to_screen(Y), axis=1),
                               np.linalg.norm(a.to_screen(X), axis=1), atol=1e-6)
    np.testing.assert_allclose(b.depth(Y), a.depth(X), atol=1e-6)
    np.testing.assert_allclose(b.face_values, a.face_values, atol=1e-8)
    assert (a.visible == b.visible).mean() > 0.995
    assert b.radius == pytest.approx(a.radius, rel=1e-12)


@pytest.mark.parametrize("R", [1.0, 2.5])
def test_sphere_is_coloured_by_its_mean_curvature_on_the_positive_side(R):
    mesh = icosphere(10)
    X = R * mesh.X
    ax = Figure().add_subplot(projection="3d")
    rendering = render(ax, X, mesh.faces, view="dent", smooth=False)
    # discrete H is 1/R to 1 % except next to the 12 five-fold vertices (5 % at this size)
    assert np.median(rendering.face_values) == pytest.approx(1.0 / R, rel=0.01)
    np.testing.assert_allclose(rendering.face_values, 1.0 / R, rtol=0.06)
    norm = rendering.mappable.norm
    assert norm.vmin == pytest.approx(-rmod.CURVATURE_LIMIT / R, rel=0.01)  # 1/R_area
    assert norm.vmax == -norm.vmin  # diverging scale centred on zero
    rgba = rendering.mappable.to_rgba(rendering.face_values)
    assert (rgba[:, 0] > rgba[:, 2]).all()  # positive curvature: the red side
    assert rendering.axis is None  # no dent: the default view
    np.testing.assert_allclose(rendering.frame, rmod._view_frame(rmod.DEFAULT_VIEW, None, 0.0))


def test_only_faces_turned_to_the_camera_are_drawn_and_the_light_peaks_where_it_points():
    mesh = icosphere(10)
    ax = Figure().add_subplot(projection="3d")
    rendering = render(ax, mesh.X, mesh.faces, view=(30.0, 40.0), color_by="none")
    e = rendering.frame[2]
    centroid = mesh.X[mesh.faces].mean(axis=1)
    toward = centroid @ e / np.linalg.norm(centroid, axis=1)
    clear = np.abs(toward) > 0.05
    np.testing.assert_array_equal(rendering.visible[clear], toward[clear] > 0)
    # Lambert: the brightest face faces the light (light fixed in the camera frame); the
    # darkest drawn faces get the ambient part only
    light = rendering.frame.T @ (np.asarray(rmod.LIGHT) / np.linalg.norm(rmod.LIGHT))
    normals = centroid / np.linalg.norm(centroid, axis=1, keepdims=True)
    assert normals[np.argmax(rendering.shade)] @ light > math.cos(math.radians(6.0))
    assert rendering.shade[rendering.visible].min() == pytest.approx(rmod.AMBIENT, abs=0.02)
    np.testing.assert_allclose(rendering.shade, rmod.AMBIENT + (1 - rmod.AMBIENT)
                               * np.clip(normals @ light, 0, None), atol=0.03)
    # the collection holds the drawn faces with those colours (in its own depth order)
    colors = np.asarray(rendering.collection.get_facecolor())[:, :3]
    expected = np.asarray(rmod.GREY)[None] * rendering.shade[rendering.visible][:, None]
    np.testing.assert_allclose(np.sort(colors.sum(axis=1)), np.sort(expected.sum(axis=1)),
                               atol=1e-12)


def test_camera_frame_is_a_rotation_with_up_towards_the_hint():
    for seed in range(5):
        e = _axis(seed)
        F = camera_frame(e)
        np.testing.assert_allclose(F @ F.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(F) == pytest.approx(1.0)
        np.testing.assert_allclose(F[2], e, atol=1e-12)
        z = np.array([0.0, 0.0, 1.0])
        np.testing.assert_allclose(F[1], (z - (z @ e) * e) / np.linalg.norm(z - (z @ e) * e))
    F = camera_frame([0.0, 0.0, -1.0])  # looking from below: +y is up
    np.testing.assert_allclose(F[1], [0.0, 1.0, 0.0], atol=1e-12)


def test_render_figure_writes_png_and_pdf(sphere, tmp_path):
    X = inverted_cap(sphere.X, ALPHA, _axis(9))
    fig = render_figure(X, sphere.faces, title="inverted cap, 45 deg")
    assert fig.get_figwidth() == pytest.approx(rmod.COLUMN_WIDTH)
    png, pdf = tmp_path / "cap.png", tmp_path / "cap.pdf"
    fig.savefig(png, dpi=200)
    fig.savefig(pdf)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    assert pdf.read_bytes()[:5] == b"%PDF-" and pdf.stat().st_size > 10_000
    assert [a.name for a in fig.axes].count("3d") == 1


def test_bad_input_is_refused(sphere):
    ax3 = Figure().add_subplot(projection="3d")
    with pytest.raises(ValueError, match="3D axis"):
        render(Figure().add_subplot(), sphere.X, sphere.faces)
    with pytest.raises(ValueError, match="color_by"):
        render(ax3, sphere.X, sphere.faces, color_by="strain")
    with pytest.raises(ValueError, match="view"):
        render(ax3, sphere.X, sphere.faces, view="side")
    with pytest.raises(ValueError, match="faces"):
        render(ax3, sphere.X, sphere.faces + len(sphere.X))
    with pytest.raises(ValueError, match="positions"):
        render(ax3, sphere.X[:, :2], sphere.faces)


@pytest.mark.parametrize("alpha_deg", [45.0, 88.0])  # at 88 deg the old rule looked at the back
def test_the_run_figure_looks_into_the_dent_also_of_a_deep_bowl(sphere, alpha_deg):
    """The deflation figure's 3D panel looks from out of the dent: for a cap inverted about u
    the view axis is +u, also when the bowl is so deep that its inverted vertices lie past
    the centre (their mean position points to -u)."""
    from shellbuckle.plots.run import view_axis

    u = _axis(3)
    X = inverted_cap(sphere.X, math.radians(alpha_deg), axis=u)
    axis = view_axis(X, sphere.faces)
    assert axis is not None and float(axis @ u) > 0.95
