"""Classification against synthetic shapes of known class and a small real deflation."""

import numpy as np
import pytest

from shellbuckle.analysis import SHAPES, ShapeAnalyzer, classify, classify_descriptors
from shellbuckle.mesh import icosphere
from shellbuckle.mesh.icosphere import _icosahedron

from test_analysis_descriptors import DIRECTIONS
from test_analysis_shapes import (MESHES, cos_profile, dimpled, inverted_cap, jiggled, mesh,
                                  modulated_cap, polygon_profile, rotation)

KINDS = sorted(MESHES)
ALPHA0 = np.radians(45)
_analyzers = {}


def _classify(kind, X):
    if kind not in _analyzers:
        _analyzers[kind] = ShapeAnalyzer(mesh(kind).topology, contact=False)
    return classify_descriptors(_analyzers[kind].describe(X))


def wrinkle_profile(m):
    """Crest ``r0 (1 + eps cos m phi)`` with ``eps (m^2 + 1) = 5``: the crest itself is concave
    between its apices (``eps (m^2 + 1) > 1``), and so is the outline of the depression."""
    return cos_profile(m, min(0.4, 5.0 / (m * m + 1)))


def polygonal_profile(m):
    """Crest ``r0 (1 + eps cos m phi)`` with ``eps (m^2 + 1) = 0.35``: a weak modulation whose
    crest and depression outline stay convex between the apices."""
    return cos_profile(m, 0.35 / (m * m + 1))


def _random_placement(rng):
    axis = rng.normal(size=3)
    return axis / np.linalg.norm(axis), rng.uniform(0, 2 * np.pi), rotation(rng)


@pytest.mark.parametrize("kind", KINDS)
def test_sphere_and_jiggled_sphere(kind):
    m = mesh(kind)
    assert _classify(kind, m.X).shape == "sphere"
    e = m.topology.edges
    h = np.linalg.norm(m.X[e[:, 1]] - m.X[e[:, 0]], axis=1).mean()
    c = _classify(kind, jiggled(m.X, 0.05 * h, np.random.default_rng(3)))
    assert (c.shape, c.n_dimples, c.corners, c.W) == ("sphere", 0, 0, 0)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("alpha_deg", [25, 50, 75, 85])
def test_inverted_cap_is_a_capsule(kind, alpha_deg):
    rng = np.random.default_rng(alpha_deg)
    axis, _, Q = _random_placement(rng)
    c = _classify(kind, inverted_cap(mesh(kind).X, np.radians(alpha_deg), axis) @ Q.T)
    assert (c.shape, c.n_dimples, c.corners, c.W) == ("capsule", 1, 0, 0)
    assert c.dent_depth == pytest.approx(2 * (1 - np.cos(np.radians(alpha_deg))), abs=0.01)


def _icosahedral_axes():
    X, F = _icosahedron()
    vertex = X[0]                     # five-fold axis
    face = X[F[0]].mean(axis=0)       # three-fold axis
    edge = X[F[0][:2]].mean(axis=0)   # two-fold axis
    return {"5-fold": vertex, "3-fold": face / np.linalg.norm(face),
            "2-fold": edge / np.linalg.norm(edge)}


@pytest.mark.parametrize("axis_name", ["5-fold", "3-fold", "2-fold"])
@pytest.mark.parametrize("n", [8, 19])
def test_capsule_centred_on_an_icosahedral_symmetry_axis_stays_a_capsule(axis_name, n):
    # the mesh itself has 5-, 3- or 2-fold symmetry about these axes: it must not make the rim
    # look polygonal
    m = icosphere(n)
    axis = _icosahedral_axes()[axis_name]
    for alpha_deg in (40, 70):
        c = classify(inverted_cap(m.X, np.radians(alpha_deg), axis), m.faces)
        assert c.shape == "capsule", (alpha_deg, c.dominant_mode, c.dominant_amplitude)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("m", range(3, 11))
def test_wrinkled_rim_gives_W_equal_m_after_random_rotations(kind, m):
    rng = np.random.default_rng(100 + m)
    for _ in range(2):
        axis, phase, Q = _random_placement(rng)
        X = modulated_cap(mesh(kind).X, ALPHA0, wrinkle_profile(m), axis, phase) @ Q.T
        c = _classify(kind, X)
        assert (c.shape, c.n_dimples, c.W, c.corners) == ("wrinkled", 1, m, m)


@pytest.mark.parametrize("m", [3, 5, 6])
def test_wrinkles_on_an_icosahedral_axis_of_the_same_symmetry(m):
    # W = m also when the dent sits on the icosphere's m-fold (or 2-fold) axis
    axis = _icosahedral_axes()["5-fold" if m == 5 else ("3-fold" if m in (3, 6) else "2-fold")]
    X = modulated_cap(mesh("icosphere").X, ALPHA0, wrinkle_profile(m), axis, 0.2)
    c = _classify("icosphere", X)
    assert (c.shape, c.W) == ("wrinkled", m)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("m", range(2, 6))
def test_polygonal_rim_without_concavity_has_m_corners(kind, m):
    rng = np.random.default_rng(200 + m)
    for _ in range(2):
        axis, phase, Q = _random_placement(rng)
        X = modulated_cap(mesh(kind).X, ALPHA0, polygonal_profile(m), axis, phase) @ Q.T
        c = _classify(kind, X)
        assert (c.shape, c.n_dimples, c.corners, c.W) == ("polygonal", 1, m, 0)
        assert c.dominant_mode == m


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("m", range(3, 11))
def test_straight_sided_polygonal_crest_has_m_corners(kind, m):
    # a crest with straight sides: the depression inside it is pinched at the corners
    # (concave between them), so the shape reads as wrinkled or polygonal, with m corners
    rng = np.random.default_rng(300 + m)
    axis, phase, Q = _random_placement(rng)
    X = modulated_cap(mesh(kind).X, ALPHA0, polygon_profile(m), axis, phase) @ Q.T
    c = _classify(kind, X)
    assert c.shape in ("polygonal", "wrinkled") and c.corners == m
    assert c.descriptors.rim.crest.n_apices == m


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("k", [2, 3, 4, 6])
def test_separated_dimples_make_a_dimpled_shape(kind, k):
    rng = np.random.default_rng(k)
    Q = rotation(rng)
    X = dimpled(mesh(kind).X, [Q @ np.asarray(d, float) for d in DIRECTIONS[k]], np.radians(30))
    c = _classify(kind, X)
    assert (c.shape, c.n_dimples, c.corners, c.W) == ("dimples", k, 0, 0)


def test_classification_does_not_depend_on_scale_or_position():
    m = mesh("random")
    X = modulated_cap(m.X, ALPHA0, wrinkle_profile(6), (1.0, 0.0, 0.5), 0.4)
    a = _classify("random", X)
    b = _classify("random", 3.7 * X + np.array([10.0, -4.0, 2.0]))
    assert (a.shape, a.W) == (b.shape, b.W) == ("wrinkled", 6)
    assert b.dent_depth == pytest.approx(3.7 * a.dent_depth, rel=1e-9)


def test_classification_columns_and_dict():
    m = icosphere(8)
    c = classify(inverted_cap(m.X, np.radians(60), (0, 0, 1.0)), m.faces)
    assert c.shape in SHAPES
    cols = c.columns()
    assert {"shape", "n_dimples", "corners", "W"} <= set(cols)
    assert all(not isinstance(v, (list, tuple, dict)) for v in cols.values())
    d = c.as_dict()
    assert len(d["rim_spectrum"]) == 20 and d["descriptors"]["n_dimples"] == 1


# ---------------------------------------------------------------------- a real deflation

_RUNS = {}


def deflated_271(tmp_path_factory):
    """gamma = 271 on a 642-vertex icosphere up to dV/V = 0.3 (the paper's Fig. 8b regime),
    made once per test session (also used by test_analysis_events)."""
    from shellbuckle.params import ShellParameters
    from shellbuckle.run import Run, deflate

    if "g271" not in _RUNS:
        out = tmp_path_factory.mktemp("analysis") / "g271"
        deflate(icosphere(8), ShellParameters.from_gamma(271.0, nu=1 / 3), until=0.3, seed=1,
                out=out)
        _RUNS["g271"] = out
    return Run.open(_RUNS["g271"])


@pytest.fixture
def run_271(tmp_path_factory):
    return deflated_271(tmp_path_factory)


def test_gamma_271_is_a_sphere_then_a_capsule(run_271):  # about 15 s
    from shellbuckle.analysis import analyze_run

    table = analyze_run(run_271)
    p = table["pressure"].to_numpy()
    drop = int(np.flatnonzero(p[1:] < 0.7 * p[:-1])[0]) + 1  # the snap-through
    shapes = table["shape"].tolist()
    assert shapes[:drop] == ["sphere"] * drop
    assert shapes[drop:] == ["capsule"] * (len(shapes) - drop)
    assert (table["W"] == 0).all() and (table["n_dimples"] == (table.index >= drop)).all()


@pytest.mark.slow
def test_gamma_271_stays_a_capsule_until_self_contact(tmp_path):  # about 5 min
    # Paper §4.3 and Fig. 7a: at gamma = 271 (d/R = 0.172) the shell buckles into one
    # axisymmetric dent and stays a capsule until the surface touches itself, on the paper's
    # randomized 3594-vertex mesh with its protocol.
    from shellbuckle.analysis import analyze_run, events
    from shellbuckle.params import ShellParameters
    from shellbuckle.run import deflate

    run = deflate(None, ShellParameters.from_gamma(271.0, nu=1 / 3), seed=0, out=tmp_path / "r")
    assert run.store.meta.get("message", "").startswith("self-intersection")
    table = analyze_run(run)
    assert table["dV_over_V"].iloc[-1] > 0.6  # self-contact deep in the deflation
    shapes = table["shape"].tolist()
    first = shapes.index("capsule")
    assert set(shapes[:first]) == {"sphere"}
    assert set(shapes[first:-1]) == {"capsule"}  # the last step touches itself
    assert not {"axisymmetry_loss", "wrinkles"} & {e.name for e in events(run)}


@pytest.mark.slow
def test_gamma_15163_capsule_becomes_polygonal_then_wrinkled(tmp_path):  # about 10 min
    # Paper §4.3-4.4: above the secondary threshold the capsule's rim loses axisymmetry
    # (polygonal dent) and then wrinkles, W between 4 and 8 at mid deflation. The paper puts
    # this from gamma ~ 933; on the paper's mesh with its protocol our shells do it from
    # gamma ~ 7465 (docs/reproduction.md), so the sequence is asserted at gamma = 15163.
    from shellbuckle.analysis import analyze_run, events
    from shellbuckle.params import ShellParameters
    from shellbuckle.run import deflate

    run = deflate(None, ShellParameters.from_gamma(15163.0, nu=1 / 3), seed=0,
                  until=0.5, out=tmp_path / "r")
    table = analyze_run(run)
    shapes = table["shape"].tolist()
    order = [shapes.index(s) for s in ("sphere", "capsule", "polygonal", "wrinkled")]
    assert order == sorted(order)
    mid = table[(table["dV_over_V"] > 0.35) & (table["shape"] == "wrinkled")]
    assert len(mid) >= 3 and mid["W"].between(3, 8).all()
    names = [e.name for e in events(run)]
    assert names.index("primary_buckling") < names.index("axisymmetry_loss") < names.index("wrinkles")
