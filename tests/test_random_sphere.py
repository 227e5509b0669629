import numpy as np
import pytest
from scipy.special import eval_legendre

from shellbuckle.mesh import icosphere, mesh_quality, random_sphere, validate_surface
from shellbuckle.mesh.checks import face_angles

PAPER_N = 3594  # Quilliet et al. 2008, Figs. 4 and 10: 3594 vertices


@pytest.fixture(scope="module")
def paper_mesh():
    return random_sphere(PAPER_N, seed=0)


def _iid_second_moment_std(n):
    """Std of the entries of (1/n) sum u u^T for n i.i.d. uniform unit vectors.

    Diagonal: var(x^2) = E[x^4] - E[x^2]^2 = 1/5 - 1/9 = 4/45; off-diagonal: E[x^2 y^2] = 1/15.
    """
    return np.sqrt(4.0 / 45.0 / n), np.sqrt(1.0 / 15.0 / n)


def _assert_isotropic(u):
    """The second-moment tensor of unit vectors ``u`` is I/3 within 4 sigma of i.i.d. noise."""
    M = u.T @ u / len(u)
    sd_diag, sd_off = _iid_second_moment_std(len(u))
    assert np.abs(np.diag(M) - 1.0 / 3.0).max() < 4 * sd_diag
    off = M[~np.eye(3, dtype=bool)]
    assert np.abs(off).max() < 4 * sd_off
    np.testing.assert_allclose(np.trace(M), 1.0, rtol=1e-12)


@pytest.mark.parametrize("n", [4, 5, 7, 100, 642])
def test_exact_vertex_count_and_sphere_topology(n):
    m = random_sphere(n, seed=3, R=1.5)
    assert m.n_vertices == n
    # Euler: V - E + F = 2 with 3F = 2E  =>  F = 2V - 4, E = 3V - 6
    assert len(m.faces) == 2 * n - 4 and m.topology.n_edges == 3 * n - 6
    np.testing.assert_allclose(np.linalg.norm(m.X, axis=1), 1.5, rtol=1e-14)
    topo = validate_surface(m.X, m.faces)  # closed, manifold, genus 0, outward
    assert topo.euler_characteristic == 2


def test_paper_mesh_is_closed_outward_and_well_shaped(paper_mesh):
    m = paper_mesh
    assert m.n_vertices == PAPER_N and len(m.faces) == 2 * PAPER_N - 4
    validate_surface(m.X, m.faces)
    x = m.X[m.faces]
    normals = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    assert (np.einsum("ij,ij->i", normals, x.mean(axis=1)) > 0).all()  # every face outward
    q = mesh_quality(m)
    assert q.min_angle_deg > 25.0
    assert np.degrees(face_angles(m.X, m.faces)).min() == pytest.approx(q.min_angle_deg)


def test_relaxation_improves_the_raw_random_triangulation():
    raw = random_sphere(642, seed=1, iterations=0)
    relaxed = random_sphere(642, seed=1)
    q_raw, q_relaxed = mesh_quality(raw), mesh_quality(relaxed)
    assert q_relaxed.min_angle_deg > 25.0 > q_raw.min_angle_deg
    assert q_relaxed.edge_rel_std < 0.5 * q_raw.edge_rel_std


def test_same_seed_gives_a_bitwise_identical_mesh(paper_mesh):
    again = random_sphere(PAPER_N, seed=0)
    assert again.X.tobytes() == paper_mesh.X.tobytes()
    assert np.array_equal(again.faces, paper_mesh.faces)


def test_different_seeds_give_different_meshes():
    a, b = random_sphere(642, seed=0), random_sphere(642, seed=1)
    assert not np.allclose(a.X, b.X)
    # not a relabelling either: vertex sets differ
    d = np.linalg.norm(a.X[:, None] - b.X[None], axis=2).min(axis=1)
    assert np.median(d) > 1e-3


def test_radius_scales_positions_exactly():
    a, b = random_sphere(100, seed=2), random_sphere(100, seed=2, R=2.0)
    assert np.array_equal(2.0 * a.X, b.X) and np.array_equal(a.faces, b.faces)


def test_vertex_positions_and_face_normals_are_isotropic(paper_mesh):
    m = paper_mesh
    _assert_isotropic(m.X / np.linalg.norm(m.X, axis=1, keepdims=True))
    x = m.X[m.faces]
    n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    _assert_isotropic(n / np.linalg.norm(n, axis=1, keepdims=True))


def _valence_power(mesh, l):
    """Normalized degree-l angular power of the valence-defect field w = valence - 6.

    P_l = sum_ij w_i w_j P_l(u_i . u_j) / sum_i w_i^2 (addition theorem); its mean is 1 for
    uncorrelated defects at random positions, while an icosahedral arrangement concentrates
    power at l = 6 (the first degree with an icosahedral invariant).
    """
    u = mesh.X / np.linalg.norm(mesh.X, axis=1, keepdims=True)
    w = mesh.topology.valence() - 6.0
    w = w - w.mean()
    return float(w @ eval_legendre(l, np.clip(u @ u.T, -1.0, 1.0)) @ w / (w @ w))


def test_no_icosahedral_symmetry_and_no_preferred_axis():
    ico, rnd = icosphere(8), random_sphere(642, seed=4)
    # oracle: the 12 valence-5 corners of the icosahedron give P_6 near
    # 1 + 1 + 10 P_6(1/sqrt 5) = 5.28; random defects stay well below the uncorrelated value 1
    assert _valence_power(ico, 6) > 4.0
    for l in (2, 4, 6):
        assert _valence_power(rnd, l) < 0.5
    # randomness is kept: many more defects than the icosphere's twelve
    valence = rnd.topology.valence()
    assert (valence != 6).sum() > 4 * 12 and (valence == 7).sum() > 0


@pytest.mark.parametrize("bad", [3, 0, -5, 2.5, "100", True, None])
def test_refuses_a_bad_vertex_count(bad):
    with pytest.raises(ValueError, match="n_vertices must be an integer >= 4"):
        random_sphere(bad)


def test_accepts_numpy_integers():
    assert random_sphere(np.int64(50), seed=np.int32(1)).n_vertices == 50


@pytest.mark.parametrize("kwargs, name", [({"R": 0.0}, "radius R"), ({"R": np.nan}, "radius R"),
                                          ({"seed": -1}, "seed"), ({"seed": 1.5}, "seed"),
                                          ({"omega": 2.0}, "omega"),
                                          ({"iterations": -1}, "iterations")])
def test_refuses_bad_options(kwargs, name):
    with pytest.raises(ValueError, match=name):
        random_sphere(100, **kwargs)
