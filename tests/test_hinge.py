import numpy as np
import pytest

from shellbuckle.energies import hinge as hg
from shellbuckle.mesh import Topology
from fdcheck import triangulated_cube

STEPS = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7]


def _random_hinges(n, seed):
    """n independent hinges (4 private vertices each), well away from degenerate."""
    rng = np.random.default_rng(seed)
    base = np.array([[0.0, 0, 0], [1, 0, 0], [0.4, 0.9, 0.1], [0.6, -0.8, -0.2]])
    X = base[None] + 0.25 * rng.normal(size=(n, 4, 3))
    R = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
    X = np.einsum("nij,naj->nai", R, X) + rng.normal(size=(n, 1, 3))
    return X.reshape(-1, 3), np.arange(4 * n).reshape(n, 4)


def _best_rel_err(analytic, fd_of_h):
    errs = []
    for h in STEPS:
        fd = fd_of_h(h)
        errs.append(np.linalg.norm(fd - analytic) / np.linalg.norm(analytic))
    return min(errs)


def _central(f, X, nv, h):
    """Central-difference derivative of f (elementwise, shape (n, ...)) w.r.t. every local dof.

    Elements own vertices ``nv * e + a``; returns ``(n, ..., 3 nv)`` with the dof axis last.
    """
    n = len(X) // nv
    cols = []
    for a in range(nv):
        for c in range(3):
            Xp, Xm = X.copy(), X.copy()
            Xp[a::nv, c] += h
            Xm[a::nv, c] -= h
            cols.append((f(Xp) - f(Xm)) / (2 * h))
    return np.stack(cols, axis=-1).reshape((n,) + cols[0].shape[1:] + (3 * nv,))


@pytest.mark.parametrize("beta", [-3.1, -2.0, -0.5, -1e-3, 0.0, 1e-3, 0.4, 1.5, 2.9, 3.1])
def test_known_angle_and_sign(beta):
    # edge along x, face (i, j, k) in the plane z = 0 with outward normal +z; l rotated by beta
    # about the edge: for beta > 0 it lies below the plane, a convex ridge seen from +z.
    X = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -np.cos(beta), -np.sin(beta)]])
    theta = hg.dihedral_angles(X, [[0, 1, 2, 3]])
    np.testing.assert_allclose(theta, [beta], atol=1e-14)


def _regular_solid(name):
    if name == "tetrahedron":
        X = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
        F = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]])
        interior = np.arccos(1 / 3)
    else:
        X = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
        F = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                      [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
        interior = np.arccos(-1 / 3)
    # orient outward
    n = np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]])
    flip = (n * X[F].mean(axis=1)).sum(axis=1) < 0
    F[flip] = F[flip][:, ::-1]
    return X, F, interior


@pytest.mark.parametrize("name", ["tetrahedron", "octahedron"])
def test_regular_solids_have_the_exterior_dihedral_angle(name):
    X, F, interior = _regular_solid(name)
    t = Topology.from_faces(F)
    theta = hg.dihedral_angles(X, t.hinges)
    # angle between outward normals = pi - interior dihedral angle, positive (convex)
    np.testing.assert_allclose(theta, np.pi - interior, rtol=1e-13)
    # inside-out orientation: every hinge becomes a valley
    t_rev = Topology.from_faces(F[:, ::-1])
    np.testing.assert_allclose(hg.dihedral_angles(X, t_rev.hinges), -(np.pi - interior), rtol=1e-13)


def test_cube_total_mean_curvature_is_steiner():
    # Steiner: V(K + rB) = V + S r + M r^2 + 4 pi r^3 / 3 with M = 1/2 sum_e l_e theta_e = 3 pi s
    # for a cube of side s; the face diagonals of a triangulated cube are flat (theta = 0).
    s = 1.7
    X, F = triangulated_cube(s)
    t = Topology.from_faces(F)
    phi = hg.length_angle_hessian(X, t.hinges)[0]
    assert 0.5 * phi.sum() == pytest.approx(3 * np.pi * s, rel=1e-14)
    assert hg.face_areas(X, F).sum() == pytest.approx(6 * s * s, rel=1e-14)


def test_angle_invariant_under_rigid_motion_and_scaling():
    X, H = _random_hinges(50, seed=3)
    rng = np.random.default_rng(4)
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    R *= np.sign(np.linalg.det(R))
    theta = hg.dihedral_angles(X, H)
    np.testing.assert_allclose(hg.dihedral_angles(X @ R.T + [1, -2, 3], H), theta, atol=1e-13)
    np.testing.assert_allclose(hg.dihedral_angles(2.5 * X, H), theta, atol=1e-13)
    # a reflection reverses the orientation of the faces, hence the sign of the angle
    np.testing.assert_allclose(hg.dihedral_angles(X * [-1, 1, 1], H), -theta, atol=1e-13)


@pytest.mark.parametrize("seed", [0, 1])
def test_angle_gradient_and_hessian_match_finite_differences(seed):
    X, H = _random_hinges(40, seed)
    theta, g, Hs = hg.dihedral_angle_hessian(X, H)
    np.testing.assert_array_equal(theta, hg.dihedral_angles(X, H))
    grad_err = _best_rel_err(g.reshape(len(H), 12),
                             lambda h: _central(lambda Y: hg.dihedral_angles(Y, H), X, 4, h))
    hess_err = _best_rel_err(Hs, lambda h: _central(
        lambda Y: hg.dihedral_angle_gradient(Y, H)[1].reshape(len(H), 12), X, 4, h))
    assert grad_err < 1e-6
    assert hess_err < 1e-6
    np.testing.assert_array_equal(Hs, Hs.transpose(0, 2, 1))


@pytest.mark.parametrize("seed", [0, 1])
def test_length_angle_derivatives_match_finite_differences(seed):
    X, H = _random_hinges(40, seed)
    phi, g, Hs = hg.length_angle_hessian(X, H)
    L = np.linalg.norm(X[H[:, 1]] - X[H[:, 0]], axis=1)
    np.testing.assert_allclose(phi, L * hg.dihedral_angles(X, H), rtol=1e-15)
    grad_err = _best_rel_err(g.reshape(len(H), 12),
                             lambda h: _central(lambda Y: hg.length_angle_hessian(Y, H)[0], X, 4, h))
    hess_err = _best_rel_err(Hs, lambda h: _central(
        lambda Y: hg.length_angle_hessian(Y, H)[1].reshape(len(H), 12), X, 4, h))
    assert grad_err < 1e-6
    assert hess_err < 1e-6


def test_angle_derivatives_near_flat_and_near_folded():
    # atan2 keeps the derivatives accurate at theta ~ 0 and |theta| ~ pi
    for beta in (1e-6, np.pi - 1e-3, -np.pi + 1e-3):
        X = np.array([[0, 0, 0], [1, 0, 0], [0.3, 1, 0], [0.6, -np.cos(beta), -np.sin(beta)]])
        H = np.array([[0, 1, 2, 3]])
        _, g, Hs = hg.dihedral_angle_hessian(X, H)
        assert _best_rel_err(g.reshape(1, 12), lambda h: _central(
            lambda Y: hg.dihedral_angles(Y, H), X, 4, h)) < 1e-6
        assert _best_rel_err(Hs, lambda h: _central(
            lambda Y: hg.dihedral_angle_gradient(Y, H)[1].reshape(1, 12), X, 4, h)) < 1e-6


def test_face_area_derivatives_match_finite_differences():
    rng = np.random.default_rng(7)
    n = 60
    X = (np.array([[0.0, 0, 0], [1, 0, 0], [0.3, 0.8, 0]])[None] + 0.3 * rng.normal(size=(n, 3, 3))).reshape(-1, 3)
    F = np.arange(3 * n).reshape(n, 3)
    area, g, Hs = hg.face_area_hessian(X, F)
    ref = 0.5 * np.linalg.norm(np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]]), axis=1)
    np.testing.assert_allclose(area, ref, rtol=1e-14)
    assert _best_rel_err(g.reshape(n, 9), lambda h: _central(lambda Y: hg.face_areas(Y, F), X, 3, h)) < 1e-6
    assert _best_rel_err(Hs, lambda h: _central(
        lambda Y: hg.face_area_hessian(Y, F)[1].reshape(n, 9), X, 3, h)) < 1e-6
    np.testing.assert_array_equal(Hs, Hs.transpose(0, 2, 1))


def test_bad_shapes_are_refused():
    with pytest.raises(ValueError, match=r"\(n, 4\)"):
        hg.dihedral_angles(np.zeros((4, 3)), [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"\(V, 3\)"):
        hg.dihedral_angles(np.zeros((4, 2)), [[0, 1, 2, 3]])
