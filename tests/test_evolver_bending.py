"""Surface Evolver's star_perp_sq_mean_curvature bending (shellbuckle.energies.evolver_bending)."""

import numpy as np
import pytest

from shellbuckle.energies.evolver_bending import StarPerpBending
from shellbuckle.mesh import icosphere

STEPS = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7]


def _perturbed(n=2, amplitude=0.08, seed=0):
    mesh = icosphere(n)
    rng = np.random.default_rng(seed)
    return mesh, mesh.X + amplitude * rng.standard_normal(mesh.X.shape)


def _terms(mesh, seed=1):
    rng = np.random.default_rng(seed)
    V = mesh.n_vertices
    return [
        StarPerpBending(mesh.faces, V, kappa=1.0, c0=2.0),
        StarPerpBending(mesh.faces, V, kappa=0.37, c0=rng.uniform(-2, 3, V),
                        vertices=rng.choice(V, V // 2, replace=False)),
    ]


@pytest.mark.parametrize("which", [0, 1])
def test_gradient_matches_central_differences(which):
    mesh, X = _perturbed()
    term = _terms(mesh)[which]
    g = term.gradient(X)
    rng = np.random.default_rng(5)
    for _ in range(3):
        d = rng.standard_normal(X.shape)
        exact = float(np.sum(g * d))
        errors = [abs((term.value(X + h * d) - term.value(X - h * d)) / (2 * h) - exact) / abs(exact)
                  for h in STEPS]
        assert min(errors) < 1e-6, errors


@pytest.mark.parametrize("which", [0, 1])
def test_hessian_matches_central_differences_of_gradient(which):
    mesh, X = _perturbed()
    term = _terms(mesh)[which]
    H = term.hessian(X)
    assert abs(H - H.T).max() < 1e-10 * abs(H).max()
    rng = np.random.default_rng(6)
    for _ in range(3):
        d = rng.standard_normal(X.shape)
        exact = H @ d.ravel()
        errors = [np.linalg.norm((term.gradient(X + h * d) - term.gradient(X - h * d)).ravel() / (2 * h)
                                 - exact) / np.linalg.norm(exact) for h in STEPS]
        assert min(errors) < 1e-6, errors


def test_rigid_motion_invariance():
    mesh, X = _perturbed(seed=2)
    term = _terms(mesh)[1]
    q, _ = np.linalg.qr(np.random.default_rng(3).standard_normal((3, 3)))
    q *= np.sign(np.linalg.det(q))  # a rotation
    Y = X @ q.T + np.array([0.3, -1.2, 2.0])
    assert term.value(Y) == pytest.approx(term.value(X), rel=1e-12)
    np.testing.assert_allclose(term.gradient(Y), term.gradient(X) @ q.T, atol=1e-10 * abs(term.gradient(X)).max())


def test_scale_invariance_without_spontaneous_curvature():
    # h ~ 1/length and star area ~ length^2: with c0 = 0 the energy does not change with size
    mesh, X = _perturbed(seed=4)
    term = StarPerpBending(mesh.faces, mesh.n_vertices, kappa=1.0, c0=0.0)
    assert term.value(2.5 * X) == pytest.approx(term.value(X), rel=1e-12)
    np.testing.assert_allclose(term.mean_curvature(2.5 * X), term.mean_curvature(X) / 2.5, rtol=1e-12)


def test_regular_octahedron_analytic():
    # Vertex (0, 0, 1) of the octahedron with vertices +-e_i: its four faces have area sqrt(3)/2
    # (S = 2 sqrt 3), the area gradient is (0, 0, 4/sqrt 3) and the sum of face area vectors is
    # (0, 0, 2) (3x the volume gradient 2/3), so h = (3/2)(8/sqrt 3)/4 = sqrt 3 at every vertex
    # and E = 2 kappa * 6 (sqrt 3 - c0/2)^2 S / 3 = 8 sqrt(3) kappa (sqrt 3 - c0/2)^2.
    X = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                      [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    for kappa, c0 in ((1.0, 0.0), (0.3, 1.4), (2.0, -1.0)):
        term = StarPerpBending(faces, 6, kappa=kappa, c0=c0)
        np.testing.assert_allclose(term.mean_curvature(X), np.sqrt(3), rtol=1e-14)
        assert term.value(X) == pytest.approx(8 * np.sqrt(3) * kappa * (np.sqrt(3) - c0 / 2) ** 2, rel=1e-14)
        g = term.gradient(X)  # radial by symmetry
        np.testing.assert_allclose(np.cross(g, X), 0.0, atol=1e-13)
    # reversing the faces flips the sign of h (Evolver measures along the facet orientation)
    flipped = StarPerpBending(faces[:, ::-1], 6, kappa=1.0, c0=0.0)
    np.testing.assert_allclose(flipped.mean_curvature(X), -np.sqrt(3), rtol=1e-14)


def test_sphere_with_stress_free_curvature():
    # Continuum: 1/2 kappa (c - 2/R)^2 vanishes on the sphere and 1/2 kappa c^2 integrates to
    # 8 pi kappa. The discrete energies approach these at second order in the edge length.
    energies = {}
    for n in (4, 8, 16):
        mesh = icosphere(n, R=1.7)
        stress_free = StarPerpBending(mesh.faces, mesh.n_vertices, kappa=1.0, c0=2 / 1.7)
        flat = StarPerpBending(mesh.faces, mesh.n_vertices, kappa=1.0, c0=0.0)
        energies[n] = stress_free.value(mesh.X), flat.value(mesh.X)
        h = stress_free.mean_curvature(mesh.X)
        regular = mesh.topology.valence() == 6
        assert np.abs(h[regular] * 1.7 - 1).max() < 2.0 / n ** 2
    assert energies[16][0] < 1e-4 * 8 * np.pi
    assert energies[16][1] == pytest.approx(8 * np.pi, rel=2e-3)
    slope = np.log2(energies[8][0] / energies[16][0])
    assert 1.8 < slope < 2.5
    slope = np.log2((energies[8][1] - 8 * np.pi) / (energies[16][1] - 8 * np.pi))
    assert 1.8 < slope < 2.5


def test_evolver_parameter_mapping():
    mesh, X = _perturbed()
    a = StarPerpBending.from_evolver(mesh.faces, mesh.n_vertices, modulus=3.0, h_zero=0.8)
    b = StarPerpBending(mesh.faces, mesh.n_vertices, kappa=1.5, c0=1.6)
    assert a.value(X) == b.value(X)
    assert a.modulus == 3.0 and np.all(a.h_zero == 0.8)
    # Evolver's formula written out: modulus * sum (3/4) S (F.M/M.M - 2 h0/3)^2, M = sum n_f / 2
    x = X[mesh.faces]
    n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    area = np.linalg.norm(n, axis=1) / 2
    V = mesh.n_vertices
    M = np.zeros((V, 3))
    S = np.zeros(V)
    for c in range(3):
        np.add.at(M, mesh.faces[:, c], n / 2)
        np.add.at(S, mesh.faces[:, c], area)
    F = np.zeros((V, 3))  # area gradient by central differences of the star area
    h = 1e-6
    for k in range(3):
        d = np.zeros(3)
        d[k] = h
        for v in range(V):
            star = np.flatnonzero((mesh.faces == v).any(axis=1))
            def star_area(Y):
                y = Y[mesh.faces[star]]
                return np.linalg.norm(np.cross(y[:, 1] - y[:, 0], y[:, 2] - y[:, 0]), axis=1).sum() / 2
            Yp, Ym = X.copy(), X.copy()
            Yp[v] += d
            Ym[v] -= d
            F[v, k] = (star_area(Yp) - star_area(Ym)) / (2 * h)
    fn, nn = (F * M).sum(1), (M * M).sum(1)
    evolver = 3.0 * np.sum(0.75 * S * (fn / nn - 2 * 0.8 / 3) ** 2)
    assert a.value(X) == pytest.approx(evolver, rel=1e-8)


def test_bad_parameters():
    mesh = icosphere(1)
    with pytest.raises(ValueError, match="c0"):
        StarPerpBending(mesh.faces, mesh.n_vertices, c0=np.zeros(3))
    with pytest.raises(ValueError, match="kappa"):
        StarPerpBending(mesh.faces, mesh.n_vertices, kappa=np.nan)
    with pytest.raises(ValueError, match="vertices"):
        StarPerpBending(mesh.faces, mesh.n_vertices, vertices=[0, 99])


@pytest.mark.parametrize("c0", [0.0, 2.0, "per-vertex"])
def test_with_c0_is_the_term_built_with_that_c0(c0):
    # oracle: the term constructed from scratch; with_c0 only shares the topology tables
    from shellbuckle.energies.total import with_c0

    mesh, X = _perturbed()
    if c0 == "per-vertex":
        c0 = np.linspace(0.5, 2.5, mesh.n_vertices)
    base = StarPerpBending(mesh.faces, mesh.n_vertices, kappa=1.3, c0=1.0)
    base.hessian(X)  # the pattern exists before the copy, as in a run
    fresh = StarPerpBending(mesh.faces, mesh.n_vertices, kappa=1.3, c0=c0)
    new = with_c0(base, c0)
    assert new._tables is base._tables  # the c0 cycle does not rebuild the Hessian pattern
    assert new.value(X) == fresh.value(X)
    assert np.array_equal(new.gradient(X), fresh.gradient(X))
    assert (new.hessian(X) != fresh.hessian(X)).nnz == 0
    assert base.value(X) == StarPerpBending(mesh.faces, mesh.n_vertices, kappa=1.3,
                                            c0=1.0).value(X)  # the original is unchanged
    with pytest.raises(ValueError, match="c0 must be"):
        with_c0(base, np.ones(3))
