"""Enclosed volume: derivatives, invariances, scaling and convergence to the ball volume."""

import numpy as np
import pytest

from shellbuckle.energies.volume import Volume
from shellbuckle.mesh import icosphere

from fdcheck import fd_gradient_error as _fd_gradient_error
from fdcheck import fd_hessian_error as _fd_hessian_error
from fdcheck import perturbed as _perturbed
from fdcheck import random_rotation as _random_rotation


@pytest.fixture
def perturbed():
    m = icosphere(2)
    return m, _perturbed(m.X, np.random.default_rng(13))


def test_gradient_and_hessian_match_finite_differences(perturbed):
    m, X = perturbed
    vol = Volume(m.faces, m.n_vertices)
    assert _fd_gradient_error(vol.value, vol.gradient, X) < 1e-6
    assert _fd_hessian_error(vol.gradient, vol.hessian, X) < 1e-6
    H = vol.hessian(X)
    assert abs(H - H.T).max() <= 1e-12 * abs(H).max()


def test_invariant_under_rigid_motions(perturbed):
    m, X = perturbed
    rng = np.random.default_rng(17)
    vol = Volume(m.faces, m.n_vertices)
    R, c = _random_rotation(rng), 3.0 * rng.standard_normal(3)
    Y = X @ R.T + c
    assert vol.value(Y) == pytest.approx(vol.value(X), rel=1e-12)
    np.testing.assert_allclose(vol.gradient(Y), vol.gradient(X) @ R.T, atol=1e-12)
    Rb = np.kron(np.eye(m.n_vertices), R)
    np.testing.assert_allclose(vol.hessian(Y).toarray(), Rb @ vol.hessian(X).toarray() @ Rb.T,
                               atol=1e-11)


def test_scaling_and_euler_homogeneity(perturbed):
    """V(sX) = s^3 V(X); for a degree-3 homogeneous function sum_v x_v . grad_v = 3 V and
    H X = 2 grad."""
    m, X = perturbed
    vol = Volume(m.faces, m.n_vertices)
    for s in (0.5, 1.3, 2.0):
        assert vol.value(s * X) == pytest.approx(s ** 3 * vol.value(X), rel=1e-13)
    g = vol.gradient(X)
    assert np.sum(X * g) == pytest.approx(3 * vol.value(X), rel=1e-13)
    np.testing.assert_allclose(vol.hessian(X) @ X.ravel(), 2 * g.ravel(), atol=1e-12)


def test_gradient_of_a_sphere_is_its_area_vector():
    """dV/dx_v = (1/3) sum of the area vectors (x1-x0)x(x2-x0)/2 of the faces around v, which on
    a fine sphere points radially with the vertex's share of area."""
    m = icosphere(8)
    g = Volume(m.faces, m.n_vertices).gradient(m.X)
    radial = np.einsum("ij,ij->i", g, m.X)
    assert np.linalg.norm(g - radial[:, None] * m.X) < 1e-2 * np.linalg.norm(g)
    assert radial.sum() == pytest.approx(4 * np.pi, rel=1e-2)


def test_icosphere_volume_converges_to_the_ball_at_second_order():
    ns = np.array([4, 8, 16, 32])
    errors = np.array([4 / 3 * np.pi - Volume(m.faces, m.n_vertices).value(m.X)
                       for m in (icosphere(int(n)) for n in ns)])
    assert (errors > 0).all()  # inscribed polyhedron
    slope = np.polyfit(np.log(1.0 / ns), np.log(errors), 1)[0]
    assert slope == pytest.approx(2.0, abs=0.1)
    assert errors[-1] < 1e-2


def test_reversed_orientation_gives_the_negative_volume():
    m = icosphere(3)
    assert Volume(m.faces[:, ::-1].copy(), m.n_vertices).value(m.X) == pytest.approx(
        -Volume(m.faces, m.n_vertices).value(m.X), rel=1e-14)


def test_volume_along_a_line_is_the_exact_cubic(perturbed):
    """V(X + t D) is a polynomial of degree 3 in t (V is linear in each vertex): the cubic of
    ``along`` matches direct evaluations, its slope at 0 is grad V . D, and its curvature
    D^T H D."""
    m, X = perturbed
    vol = Volume(m.faces, m.n_vertices)
    D = np.random.default_rng(5).standard_normal(X.shape)
    c = vol.along(X, D)
    for t in (-1.7, -0.2, 0.3, 2.5):
        assert np.polyval(c[::-1], t) == pytest.approx(vol.value(X + t * D), rel=1e-12, abs=1e-12)
    assert c[0] == pytest.approx(vol.value(X), rel=1e-14)
    assert c[1] == pytest.approx(np.sum(vol.gradient(X) * D), rel=1e-12)
    assert 2 * c[2] == pytest.approx(D.ravel() @ (vol.hessian(X) @ D.ravel()), rel=1e-12)
    value, grad = vol.value_and_gradient(X)
    assert value == vol.value(X)
    np.testing.assert_array_equal(grad, vol.gradient(X))


def test_hessian_has_no_diagonal_blocks(perturbed):
    """V is linear in each vertex, so d2V/dx_v2 = 0."""
    m, X = perturbed
    H = Volume(m.faces, m.n_vertices).hessian(X).toarray()
    blocks = H.reshape(m.n_vertices, 3, m.n_vertices, 3)
    v = np.arange(m.n_vertices)
    assert np.abs(blocks[v, :, v, :]).max() == 0.0
    assert np.abs(H).max() > 0.0


def test_the_sum_over_faces_is_exact_to_round_off_on_a_fine_mesh():
    # 160k faces: a plain running sum of their terms errs by ~sqrt(F) eps V (about 1e-14 V,
    # which the pressure turns into energy noise that stalls Newton's method); the kernel
    # sums with compensation. Oracle: math.fsum of the same face terms (exactly rounded).
    import math

    m = icosphere(90)
    X = _perturbed(m.X, np.random.default_rng(5), 0.2)
    a, b, c = (X[m.faces[:, i]] for i in range(3))
    terms = np.einsum("ij,ij->i", a, np.cross(b, c))
    exact = math.fsum(terms) / 6.0
    vol = Volume(m.faces, m.n_vertices)
    assert len(m.faces) > 160_000
    assert abs(vol.value(X) - exact) <= 4 * np.spacing(exact)
    # the volume along a direction (the cubic the restoration solves) starts at the same value
    D = np.random.default_rng(6).standard_normal(X.shape)
    assert abs(vol.along(X, D)[0] - exact) <= 4 * np.spacing(exact)
    # (what a plain sum gives, for scale: many ulps off)
    plain = 0.0
    for t in terms.tolist():
        plain += t
    assert abs(plain / 6.0 - exact) > 16 * np.spacing(exact)
