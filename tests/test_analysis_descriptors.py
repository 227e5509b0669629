"""Shape descriptors against geometric oracles: spheres, inverted caps, separated dimples."""

import numpy as np
import pytest

from shellbuckle.analysis import ShapeAnalyzer, describe
from shellbuckle.analysis.descriptors import MIN_DENT_RADIUS
from shellbuckle.mesh import icosphere
from shellbuckle.mesh.contact import ContactChecker

from test_analysis_shapes import dimpled, inverted_cap, jiggled, mesh, rotation

KINDS = ["icosphere", "random"]   # icosphere(19) and random(3594)


def _analyzer(kind):
    return ShapeAnalyzer(mesh(kind).topology, contact=False)


def _edge(kind):
    m = mesh(kind)
    e = m.topology.edges
    return np.linalg.norm(m.X[e[:, 1]] - m.X[e[:, 0]], axis=1).mean()


@pytest.mark.parametrize("kind", KINDS)
def test_sphere_has_no_dent_and_no_asphericity(kind):
    m = mesh(kind)
    d = _analyzer(kind).describe(m.X)
    assert d.n_dimples == 0 and d.rim is None
    assert d.asphericity < 1e-4  # gyration tensor of a sphere is isotropic
    assert np.isnan(d.dent_depth)
    assert d.geometry.R_area == pytest.approx(1.0, rel=0.01)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("amplitude", [0.01, 0.05, 0.1])
def test_jiggled_sphere_has_no_dent(kind, amplitude):
    # vertex noise up to 10 % of an edge: the discrete curvature is noisy, the shape a sphere
    rng = np.random.default_rng(7)
    X = jiggled(mesh(kind).X, amplitude * _edge(kind), rng)
    assert _analyzer(kind).describe(X).n_dimples == 0


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("alpha_deg", [20, 45, 70, 85])  # 90 deg: the image touches the far pole
def test_inverted_cap_depth_rim_and_axis(kind, alpha_deg):
    rng = np.random.default_rng(alpha_deg)
    alpha = np.radians(alpha_deg)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    Q = rotation(rng)
    X = inverted_cap(mesh(kind).X, alpha, axis) @ Q.T
    d = _analyzer(kind).describe(X)
    h = _edge(kind)
    assert d.n_dimples == 1
    # mirror buckling: the pole moves by 2 R (1 - cos alpha), the rim stays at R sin(alpha)
    assert d.dent_depth == pytest.approx(2 * (1 - np.cos(alpha)), abs=0.05 * h)
    assert d.dent_sagitta == pytest.approx(1 - np.cos(alpha), abs=0.5 * h)
    # the crest is the geometric rim; the outline of the depression (zero of the smoothed
    # curvature) lies inside it, by about the curvature smoothing length (1.25 h) and more
    assert d.rim.crest.radius == pytest.approx(np.sin(alpha), abs=0.5 * h)
    assert np.sin(alpha) - 2.5 * h < d.rim.outline.radius < d.rim.crest.radius
    assert d.rim.axis @ (Q @ axis) > np.cos(0.05)  # out of the dent, along the cap's axis
    for curve in (d.rim.crest, d.rim.outline):  # axisymmetric
        assert curve.spectrum[1:].max() * curve.radius < 0.15 * h


@pytest.mark.parametrize("kind", KINDS)
def test_descriptors_are_invariant_to_rotation_and_translation(kind):
    rng = np.random.default_rng(11)
    X = inverted_cap(mesh(kind).X, np.radians(60), (0.3, -0.2, 1.0))
    an = _analyzer(kind)
    a = an.describe(X)
    Q = rotation(rng)
    b = an.describe(X @ Q.T + np.array([3.0, -1.0, 2.0]))
    assert b.dent_depth == pytest.approx(a.dent_depth, abs=1e-9)
    assert b.asphericity == pytest.approx(a.asphericity, abs=1e-12)
    assert b.rim.axis == pytest.approx(Q @ a.rim.axis, abs=1e-6)
    # the rays sample the rim at other places of the mesh: equal to the sampling noise
    for ca, cb in ((a.rim.crest, b.rim.crest), (a.rim.outline, b.rim.outline)):
        assert cb.radius == pytest.approx(ca.radius, abs=0.02 * _edge(kind))
        np.testing.assert_allclose(cb.spectrum, ca.spectrum, atol=2e-3)


def test_descriptors_scale_with_the_shell():
    m = mesh("random")
    X = inverted_cap(m.X, np.radians(50), (1.0, 1.0, 0.0))
    an = _analyzer("random")
    a, b = an.describe(X), an.describe(2.5 * X)
    assert b.n_dimples == a.n_dimples == 1
    assert b.dent_depth == pytest.approx(2.5 * a.dent_depth, rel=1e-9)
    for ca, cb in ((a.rim.crest, b.rim.crest), (a.rim.outline, b.rim.outline)):
        assert cb.radius == pytest.approx(2.5 * ca.radius, rel=1e-6)
        np.testing.assert_allclose(cb.spectrum, ca.spectrum, atol=1e-9)


_T = 1 / np.sqrt(3)
_P = (1 + 5 ** 0.5) / 2
_ICO = np.array([[-1, _P, 0], [1, _P, 0], [-1, -_P, 0], [1, -_P, 0], [0, -1, _P], [0, 1, _P],
                 [0, -1, -_P], [0, 1, -_P], [_P, 0, -1], [_P, 0, 1], [-_P, 0, -1], [-_P, 0, 1]])
DIRECTIONS = {
    2: [(0, 0, 1), (0, 0, -1)],
    3: [(1, 0, 0), (-0.5, np.sqrt(3) / 2, 0), (-0.5, -np.sqrt(3) / 2, 0)],
    4: [(_T, _T, _T), (_T, -_T, -_T), (-_T, _T, -_T), (-_T, -_T, _T)],
    6: [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)],
    12: list(_ICO / np.linalg.norm(_ICO, axis=1)[:, None]),
}


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("k", sorted(DIRECTIONS))
def test_separated_dimples_are_counted(kind, k):
    rng = np.random.default_rng(k)
    Q = rotation(rng)
    beta = np.radians(20 if k == 12 else 30)  # icosahedral directions are 63 deg apart
    X = dimpled(mesh(kind).X, [Q @ np.asarray(d, float) for d in DIRECTIONS[k]], beta)
    d = _analyzer(kind).describe(X)
    assert d.n_dimples == k
    # each dent's axis (its vector area) points out of one of the caps
    dirs = np.array([Q @ np.asarray(v, float) for v in DIRECTIONS[k]])
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    match = np.array([dent.axis for dent in d.dents]) @ dirs.T
    assert sorted(np.argmax(match, axis=1)) == list(range(k))
    assert match.max(axis=1).min() > np.cos(np.radians(3))


@pytest.mark.parametrize("kind", KINDS)
def test_a_depression_cut_by_a_circular_fold_counts_once(kind):
    # a ring-shaped ridge of positive curvature on the floor of an inverted cap splits the
    # inverted region into a disc and an annulus, both above the dent size: one depression
    m = mesh(kind)
    alpha = np.radians(70)
    X = inverted_cap(m.X, alpha, (0, 0, 1.0))
    floor = m.X[:, 2] > np.cos(alpha)
    r = np.hypot(X[floor, 0], X[floor, 1])
    X[floor, 2] += 0.15 * np.exp(-0.5 * ((r - 0.45) / 0.06) ** 2)
    an = _analyzer(kind)
    pieces = an.inverted_components(an.geometry(X))
    assert len(pieces) == 2 and pieces[1].area > np.pi * (MIN_DENT_RADIUS ** 2)
    d = an.describe(X)
    assert d.n_dimples == 1
    assert d.rim.crest.radius == pytest.approx(np.sin(alpha), abs=0.05)


def test_dimples_below_the_noise_size_are_not_counted():
    # a cap much smaller than MIN_DENT_RADIUS R, with one well above it
    m = mesh("random")
    small = np.radians(0.5 * np.degrees(MIN_DENT_RADIUS))
    X = dimpled(m.X, [(0, 0, 1.0), (0, 0, -1.0)], small)
    X = inverted_cap(X, np.radians(40), (1.0, 0, 0))
    assert _analyzer("random").describe(X).n_dimples == 1


def test_contact_distance_is_the_far_vertex_distance():
    m = icosphere(6)
    X = inverted_cap(m.X, np.radians(100), (0, 0, 1.0))
    d = ShapeAnalyzer(m.topology).describe(X)
    expected = ContactChecker(m.topology, rings=2).min_vertex_distance(X)[0]
    assert d.contact_distance == expected


def test_describe_returns_plain_values():
    m = icosphere(8)
    out = describe(inverted_cap(m.X, np.radians(60), (0, 1.0, 0)), m.faces)
    assert out["n_dimples"] == 1
    assert len(out["rim_spectrum"]) == len(out["crest_spectrum"]) == 20
    assert len(out["dent_axis"]) == 3
    assert out["dent_axis"] == pytest.approx([0, 1, 0], abs=0.02)
    for key in ("asphericity", "dent_depth", "dent_sagitta", "rim_radius", "crest_radius",
                "contact_distance", "volume", "area"):
        assert isinstance(out[key], float)


@pytest.mark.parametrize("kind", KINDS)
def test_smoothing_by_conjugate_gradients_is_the_direct_solve(kind):
    """Geometry.smooth (diffusion steps solved by preconditioned conjugate gradients) equals
    the same steps solved by sparse LU, on a rough dented shape, for a scalar and a vector
    field and for both smoothing lengths of the analysis; a solve that cannot converge within
    its iteration limit falls back to LU with the same result."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    from shellbuckle.analysis import descriptors

    X = jiggled(inverted_cap(mesh(kind).X, 50.0), 0.3 * _edge(kind), np.random.default_rng(3))
    geom = _analyzer(kind).geometry(X)
    for length in (geom.H_smoothing_length, 0.5 * geom.mean_edge, 0.1 * geom.R_area):
        tau = length**2 / (2.0 * descriptors.SMOOTHING_STEPS)
        lu = splu((sp.diags(geom.vertex_area) + tau * geom.stiffness).tocsc())
        for values in (geom.H, geom.vertex_normal):
            ref = values.reshape(len(values), -1)
            for _ in range(descriptors.SMOOTHING_STEPS):
                ref = lu.solve(geom.vertex_area[:, None] * ref)
            ref = ref.reshape(values.shape)
            got = geom.smooth(values, length)
            assert np.abs(got - ref).max() <= 1e-9 * np.abs(ref).max()
    stuck = descriptors.Geometry(**{f: getattr(geom, f) for f in (
        "X", "face_area", "vertex_area", "vertex_normal", "H", "area", "volume", "R_area",
        "mean_edge", "stiffness")})
    original = descriptors.SMOOTHING_MAXITER
    try:
        descriptors.SMOOTHING_MAXITER = 1
        assert np.abs(stuck.smooth(geom.H, length) - geom.smooth(geom.H, length)).max() \
            <= 1e-9 * np.abs(geom.H).max()
        assert stuck._systems[float(length)][2] is not None   # the LU fallback was used
    finally:
        descriptors.SMOOTHING_MAXITER = original
