"""Stretching (Evolver ``linear_elastic``): derivatives, invariances and analytic values."""

import numpy as np
import pytest

from shellbuckle.energies.stretching import Stretching, rotate_form_factors
from shellbuckle.mesh import icosphere

from fdcheck import fd_gradient_error as _fd_gradient_error
from fdcheck import fd_hessian_error as _fd_hessian_error
from fdcheck import perturbed as _perturbed
from fdcheck import random_rotation as _random_rotation


@pytest.fixture
def strained():
    """A perturbed rest shape and an independently perturbed, partly compressed state."""
    rng = np.random.default_rng(7)
    m = icosphere(2)
    X_rest = _perturbed(m.X, rng)
    X = _perturbed(0.93 * m.X, rng)
    return m, X_rest, X


@pytest.mark.parametrize("nu", [-0.5, 0.0, 1 / 3, 0.9])
def test_gradient_matches_finite_differences(strained, nu):
    m, X_rest, X = strained
    st = Stretching.from_reference(X_rest, m.faces, m.n_vertices, A=2.5, nu=nu)
    assert _fd_gradient_error(st.value, st.gradient, X) < 1e-6


@pytest.mark.parametrize("nu", [-0.5, 1 / 3, 0.9])
def test_hessian_matches_finite_differences_of_gradient(strained, nu):
    m, X_rest, X = strained
    st = Stretching.from_reference(X_rest, m.faces, m.n_vertices, A=2.5, nu=nu)
    assert _fd_hessian_error(st.gradient, st.hessian, X) < 1e-6


def test_open_patch_derivatives_match_finite_differences():
    """A surface with a boundary (a spherical cap) goes through the general assembly path."""
    rng = np.random.default_rng(19)
    m = icosphere(2)
    keep = m.faces[m.X[m.faces].mean(axis=1)[:, 2] > 0.2]
    used, faces = np.unique(keep, return_inverse=True)
    faces = faces.reshape(-1, 3)
    X_rest = _perturbed(m.X[used], rng)
    X = _perturbed(0.95 * m.X[used], rng)
    st = Stretching.from_reference(X_rest, faces, len(used), A=1.0, nu=0.3)
    assert not st._assembler.closed
    assert _fd_gradient_error(st.value, st.gradient, X) < 1e-6
    assert _fd_hessian_error(st.gradient, st.hessian, X) < 1e-6


def test_hessian_is_symmetric_and_kills_translations(strained):
    m, X_rest, X = strained
    st = Stretching.from_reference(X_rest, m.faces, m.n_vertices, A=1.0, nu=0.3)
    H = st.hessian(X)
    assert H.shape == (3 * m.n_vertices, 3 * m.n_vertices)
    assert abs(H - H.T).max() <= 1e-12 * abs(H).max()
    for c in range(3):  # E(X + a e_c) = E(X) for every a, so H e_c = 0
        shift = np.zeros((m.n_vertices, 3))
        shift[:, c] = 1.0
        assert np.abs(H @ shift.ravel()).max() <= 1e-10 * abs(H).max()


def test_value_and_gradient_agree_with_separate_calls(strained):
    m, X_rest, X = strained
    st = Stretching.from_reference(X_rest, m.faces, m.n_vertices, A=1.7, nu=0.2)
    E, g = st.value_and_gradient(X)
    assert E == pytest.approx(st.value(X), rel=1e-14)
    np.testing.assert_allclose(g, st.gradient(X), rtol=0, atol=1e-14 * np.abs(g).max())
    np.testing.assert_allclose(np.dot(st.density(X), st.rest_area), E, rtol=1e-13)


def test_invariant_under_rigid_motions(strained):
    m, X_rest, X = strained
    rng = np.random.default_rng(3)
    st = Stretching.from_reference(X_rest, m.faces, m.n_vertices, A=1.0, nu=1 / 3)
    R, c = _random_rotation(rng), rng.standard_normal(3)
    Y = X @ R.T + c
    assert st.value(Y) == pytest.approx(st.value(X), rel=1e-12)
    np.testing.assert_allclose(st.gradient(Y), st.gradient(X) @ R.T, atol=1e-12)
    Rb = np.kron(np.eye(m.n_vertices), R)
    np.testing.assert_allclose(st.hessian(Y).toarray(), Rb @ st.hessian(X).toarray() @ Rb.T,
                               atol=1e-11)
    # the rest shape may itself be moved rigidly: nothing changes
    st2 = Stretching.from_reference(X_rest @ R.T + c, m.faces, m.n_vertices, A=1.0, nu=1 / 3)
    assert st2.value(X) == pytest.approx(st.value(X), rel=1e-12)


def test_energy_equals_surface_evolver_formula_face_by_face(strained):
    """Surface Evolver manual, method linear_elastic: S = Gram matrix of the unstrained facet,
    Q = S^-1, F = Gram matrix of the strained facet, C = (F Q - I)/2, energy density
    (1/2/(1+v)) (Tr(C^2) + v (Tr C)^2 / (1 - v)) times the modulus, integrated over the
    unstrained area sqrt(det S)/2. Evaluated here with plain 2x2 matrix algebra."""
    m, X_rest, X = strained
    A, nu = 1.9, 0.37
    st = Stretching.from_reference(X_rest, m.faces, m.n_vertices, A=A, nu=nu)

    def gram(Y):
        s = Y[m.faces[:, 1]] - Y[m.faces[:, 0]]
        t = Y[m.faces[:, 2]] - Y[m.faces[:, 0]]
        edges = np.stack([s, t], axis=2)  # (F, 3, 2)
        return edges.transpose(0, 2, 1) @ edges

    S, Fg = gram(X_rest), gram(X)
    C = (Fg @ np.linalg.inv(S) - np.eye(2)) / 2
    trC = np.trace(C, axis1=1, axis2=2)
    density = A / (2 * (1 + nu)) * (np.trace(C @ C, axis1=1, axis2=2) + nu * trC ** 2 / (1 - nu))
    np.testing.assert_allclose(st.density(X), density, rtol=1e-11, atol=1e-15)
    np.testing.assert_allclose(st.rest_area, np.sqrt(np.linalg.det(S)) / 2, rtol=1e-13)
    assert st.value(X) == pytest.approx(np.dot(density, np.sqrt(np.linalg.det(S)) / 2), rel=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_affine_deformation_of_a_triangle_matches_the_papers_elasticity_tensor(seed):
    """Quilliet et al. (2008) eq. (1) with K_xxxx = K_yyyy = A/(1-nu^2),
    K_xxyy = K_yyxx = nu A/(1-nu^2), K_xyxy = K_yxyx = A/(1+nu): the energy density
    1/2 eps_ij K_ijkl eps_kl of the Green-Lagrange strain eps = (M^T M - I)/2 of the affine
    map x = M X applied to a unit right triangle in the (x, y) plane (rest area 1/2)."""
    rng = np.random.default_rng(seed)
    A, nu = 3.0, rng.uniform(-0.9, 0.9)
    X_rest = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    M = np.eye(3, 2) + 0.3 * rng.standard_normal((3, 2))
    X = X_rest[:, :2] @ M.T + rng.standard_normal(3)
    eps = (M.T @ M - np.eye(2)) / 2
    k1, k2, k3 = A / (1 - nu ** 2), nu * A / (1 - nu ** 2), A / (1 + nu)
    w = 0.5 * (k1 * (eps[0, 0] ** 2 + eps[1, 1] ** 2) + 2 * k2 * eps[0, 0] * eps[1, 1]
               + k3 * (eps[0, 1] ** 2 + eps[1, 0] ** 2))
    st = Stretching.from_reference(X_rest, np.array([[0, 1, 2]]), 3, A=A, nu=nu)
    assert st.value(X) == pytest.approx(0.5 * w, rel=1e-12)


@pytest.mark.parametrize("n", [2, 5])
def test_zero_energy_and_force_on_the_reference(n):
    m = icosphere(n)
    st = Stretching.from_reference(m.X, m.faces, m.n_vertices, A=3.0, nu=0.3)
    E, g = st.value_and_gradient(m.X)
    assert abs(E) < 1e-25
    assert np.abs(g).max() < 1e-12
    assert np.abs(st.density(m.X)).max() < 1e-25


def test_reference_hessian_is_psd_with_only_rigid_zero_modes():
    """At the stress-free reference the Hessian is the material stiffness, positive
    semi-definite; a closed convex triangulated polyhedron is infinitesimally rigid (Dehn), so
    exactly the 6 rigid motions have zero energy to second order."""
    m = icosphere(2)
    st = Stretching.from_reference(m.X, m.faces, m.n_vertices, A=1.0, nu=0.25)
    w = np.linalg.eigvalsh(st.hessian(m.X).toarray())
    tol = 1e-9 * w.max()
    assert w.min() > -tol
    assert (w < tol).sum() == 6


@pytest.mark.parametrize("scale", [0.8, 0.97, 1.0, 1.05, 1.3])
@pytest.mark.parametrize("nu", [0.0, 1 / 3, -0.4])
def test_uniformly_scaled_sphere_has_the_exact_green_lagrange_energy(scale, nu):
    """X = s X0 gives a = s^2 abar on every face, so e = (s^2 - 1)/2 I, Tr(e^2) = 2 e^2 and
    (Tr e)^2 = 4 e^2. The density is A/(2(1+nu)) (2 + 4 nu/(1-nu)) e^2 = A e^2 / (1 - nu) and
    the energy is (total rest area) A e^2 / (1 - nu), with no discretisation error."""
    m = icosphere(6)
    A = 2.0
    st = Stretching.from_reference(m.X, m.faces, m.n_vertices, A=A, nu=nu)
    e = (scale ** 2 - 1) / 2
    exact = st.rest_area.sum() * A * e ** 2 / (1 - nu)
    assert st.value(scale * m.X) == pytest.approx(exact, rel=1e-12, abs=1e-25)
    np.testing.assert_allclose(st.density(scale * m.X), A * e ** 2 / (1 - nu), rtol=1e-11,
                               atol=1e-25)


def test_small_uniform_shrinking_matches_U_sphere():
    """U_sphere = 4 pi R^2 A / (9 (1 - nu)) (dV/V)^2 (Quilliet et al. 2008, eq. Usphere) is the
    small-strain limit of the exact value: at dV/V = 0.01 they agree within 1 %."""
    m = icosphere(16)
    A, nu, dv = 1.0, 1 / 3, 0.01
    st = Stretching.from_reference(m.X, m.faces, m.n_vertices, A=A, nu=nu)
    s = (1 - dv) ** (1 / 3)
    E = st.value(s * m.X)
    assert E / (4 * np.pi * A / (9 * (1 - nu)) * dv ** 2) == pytest.approx(1.0, abs=0.01)
    assert E / (st.rest_area.sum() * A / (9 * (1 - nu)) * dv ** 2) == pytest.approx(1.0, abs=0.01)


def test_form_factors_constructor_equals_reference_constructor(strained):
    m, X_rest, X = strained
    F = m.faces
    s = X_rest[F[:, 1]] - X_rest[F[:, 0]]
    t = X_rest[F[:, 2]] - X_rest[F[:, 0]]
    ff = np.stack([(s * s).sum(1), (s * t).sum(1), (t * t).sum(1)], axis=1)
    a = Stretching.from_reference(X_rest, F, m.n_vertices, A=1.3, nu=0.3)
    b = Stretching.from_form_factors(F, m.n_vertices, ff, A=1.3, nu=0.3)
    np.testing.assert_allclose(b.abar_inv, a.abar_inv, rtol=1e-12)
    np.testing.assert_allclose(b.rest_area, a.rest_area, rtol=1e-12)
    assert b.value(X) == pytest.approx(a.value(X), rel=1e-12)
    np.testing.assert_allclose(b.gradient(X), a.gradient(X), rtol=1e-10, atol=1e-13)
    assert abs(b.hessian(X) - a.hessian(X)).max() < 1e-10


def test_rotated_faces_with_rotated_form_factors_give_the_same_energy(strained):
    m, X_rest, X = strained
    F = m.faces
    s = X_rest[F[:, 1]] - X_rest[F[:, 0]]
    t = X_rest[F[:, 2]] - X_rest[F[:, 0]]
    ff = np.stack([(s * s).sum(1), (s * t).sum(1), (t * t).sum(1)], axis=1)
    shift = np.random.default_rng(1).integers(0, 3, len(F))
    rows = np.arange(len(F))[:, None]
    F_rot = F[rows, (np.arange(3) + shift[:, None]) % 3]
    a = Stretching.from_form_factors(F, m.n_vertices, ff, A=1.0, nu=0.3)
    b = Stretching.from_form_factors(F_rot, m.n_vertices, rotate_form_factors(ff, shift),
                                     A=1.0, nu=0.3)
    c = Stretching.from_reference(X_rest, F_rot, m.n_vertices, A=1.0, nu=0.3)
    assert b.value(X) == pytest.approx(a.value(X), rel=1e-12)
    assert c.value(X) == pytest.approx(a.value(X), rel=1e-12)


def test_bad_inputs_are_refused_with_clear_messages():
    m = icosphere(1)
    V, F = m.n_vertices, m.faces
    with pytest.raises(ValueError, match="Young modulus A"):
        Stretching.from_reference(m.X, F, V, A=0.0, nu=0.3)
    with pytest.raises(ValueError, match="Young modulus A"):
        Stretching.from_reference(m.X, F, V, A=float("nan"), nu=0.3)
    for nu in (1.0, -1.0, 2.0, float("nan")):
        with pytest.raises(ValueError, match=r"Poisson ratio nu must lie in the open interval"):
            Stretching.from_reference(m.X, F, V, A=1.0, nu=nu)
    X_bad = m.X.copy()
    a, b, c = F[4]
    X_bad[c] = 0.5 * (X_bad[a] + X_bad[b])  # collinear rest triangle
    with pytest.raises(ValueError, match="degenerate"):
        Stretching.from_reference(X_bad, F, V, A=1.0, nu=0.3)
    ff = np.tile([1.0, 1.0, 1.0], (len(F), 1))  # det = 0
    with pytest.raises(ValueError, match="face 0 is degenerate"):
        Stretching.from_form_factors(F, V, ff, A=1.0, nu=0.3)
    with pytest.raises(ValueError, match="form_factors must have shape"):
        Stretching.from_form_factors(F, V, ff[:, :2], A=1.0, nu=0.3)
    with pytest.raises(ValueError, match="reference positions"):
        Stretching.from_reference(m.X[:-1], F, V, A=1.0, nu=0.3)
    st = Stretching.from_reference(m.X, F, V, A=1.0, nu=0.3)
    with pytest.raises(ValueError, match="positions must have shape"):
        st.value(m.X[:-1])
