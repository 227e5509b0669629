"""Total area and per-face areas/normals: derivatives, invariances and analytic values."""

import numpy as np
import pytest

from shellbuckle.energies.area import Area, face_areas_normals
from shellbuckle.mesh import icosphere

from fdcheck import fd_gradient_error as _fd_gradient_error
from fdcheck import fd_hessian_error as _fd_hessian_error
from fdcheck import perturbed as _perturbed
from fdcheck import random_rotation as _random_rotation


@pytest.fixture
def perturbed():
    m = icosphere(2)
    return m, _perturbed(m.X, np.random.default_rng(11))


def test_gradient_and_hessian_match_finite_differences(perturbed):
    m, X = perturbed
    area = Area(m.faces, m.n_vertices)
    assert _fd_gradient_error(area.value, area.gradient, X) < 1e-6
    assert _fd_hessian_error(area.gradient, area.hessian, X) < 1e-6
    H = area.hessian(X)
    assert abs(H - H.T).max() <= 1e-12 * abs(H).max()


def test_invariant_under_rigid_motions(perturbed):
    m, X = perturbed
    rng = np.random.default_rng(5)
    area = Area(m.faces, m.n_vertices)
    R, c = _random_rotation(rng), rng.standard_normal(3)
    Y = X @ R.T + c
    assert area.value(Y) == pytest.approx(area.value(X), rel=1e-13)
    np.testing.assert_allclose(area.gradient(Y), area.gradient(X) @ R.T, atol=1e-13)
    Rb = np.kron(np.eye(m.n_vertices), R)
    np.testing.assert_allclose(area.hessian(Y).toarray(), Rb @ area.hessian(X).toarray() @ Rb.T,
                               atol=1e-11)


def test_scaling_and_euler_homogeneity(perturbed):
    """area(sX) = s^2 area(X); by Euler's theorem for a degree-2 homogeneous function,
    sum_v x_v . grad_v = 2 area and H X = grad (degree-1 homogeneous gradient)."""
    m, X = perturbed
    area = Area(m.faces, m.n_vertices)
    assert area.value(1.7 * X) == pytest.approx(1.7 ** 2 * area.value(X), rel=1e-13)
    g = area.gradient(X)
    assert np.sum(X * g) == pytest.approx(2 * area.value(X), rel=1e-13)
    np.testing.assert_allclose(area.hessian(X) @ X.ravel(), g.ravel(), atol=1e-12)


def test_icosphere_area_converges_to_4_pi_at_second_order():
    ns = np.array([4, 8, 16, 32])
    errors = np.array([4 * np.pi - Area(m.faces, m.n_vertices).value(m.X)
                       for m in (icosphere(int(n)) for n in ns)])
    assert (errors > 0).all()  # inscribed polyhedron
    slope = np.polyfit(np.log(1.0 / ns), np.log(errors), 1)[0]
    assert slope == pytest.approx(2.0, abs=0.1)


def test_face_areas_normals_on_a_known_triangle_and_the_sphere():
    X = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 0.0]])
    areas, normals = face_areas_normals(X, np.array([[0, 1, 2], [0, 2, 1], [0, 1, 3]]))
    np.testing.assert_allclose(areas, [3.0, 3.0, 0.0])
    np.testing.assert_allclose(normals, [[0, 0, 1], [0, 0, -1], [0, 0, 0]])
    m = icosphere(6)
    areas, normals = face_areas_normals(m.X, m.faces)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    centroids = m.X[m.faces].mean(axis=1)
    assert (np.einsum("ij,ij->i", normals, centroids) > 0.99 * np.linalg.norm(centroids, axis=1)).all()
    assert areas.sum() == pytest.approx(Area(m.faces, m.n_vertices).value(m.X), rel=1e-14)


def test_bad_inputs_are_refused():
    m = icosphere(1)
    with pytest.raises(ValueError, match="integer"):
        Area(m.faces.astype(float), m.n_vertices)
    with pytest.raises(ValueError, match="must lie in"):
        Area(m.faces, m.n_vertices - 1)
    with pytest.raises(ValueError, match="positions must have shape"):
        Area(m.faces, m.n_vertices).value(m.X[:-1])
