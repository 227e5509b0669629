"""Compiled kernels against the NumPy element kernels and central differences.

Oracles: the NumPy element derivatives and Hessians of :mod:`shellbuckle.energies.hinge`
scattered with ``np.add.at``; the NumPy volume formula; central differences of
the compiled value; the exact cubic of the volume along a line.
"""

import numpy as np
import pytest

from shellbuckle.energies import hinge as hg
from shellbuckle.energies import kernels
from shellbuckle.energies.bending import Bending
from shellbuckle.energies.stretching import Stretching
from shellbuckle.energies.volume import Volume
from shellbuckle.mesh import icosphere
from shellbuckle.mesh.random_sphere import random_sphere


@pytest.fixture(scope="module")
def shell():
    mesh = random_sphere(400, seed=3)
    rng = np.random.default_rng(4)
    X = 0.93 * mesh.X + 0.02 * rng.standard_normal(mesh.X.shape)
    return mesh, X


def _numpy_bending(bending, X):
    """Value and gradient of the Jülicher energy from the NumPy hinge and face kernels."""
    p = bending._plan
    XT = np.ascontiguousarray(X.T)
    hk = hg.hinge_kernel(XT, p.HT, order=1)
    fk = hg.face_kernel(XT, p.FT, order=1)
    M, A = p.vertex_sums(hk.phi, fk.area)
    H, w_hinge, w_face = bending._weights(M, A)
    value = 0.5 * bending.kappa * float(((2.0 * H - bending.c0) ** 2 * A).sum())
    G = np.zeros_like(X)
    for a in range(4):
        np.add.at(G, p.HT[a], (w_hinge * hk.dphi[:, a]).T)
    for a in range(3):
        np.add.at(G, p.FT[a], (w_face * fk.grad[:, a]).T)
    return value, G


def _numpy_bending_hessian(bending, X):
    """Dense Hessian of the Jülicher energy from the NumPy hinge and face Hessians (module
    :mod:`shellbuckle.energies.hinge`) and the rank-one star terms ``(4 kappa / A_i) g_i g_i^T``,
    ``g_i = grad M_i - H_i grad A_i``, built row by row with ``np.add.at``."""
    p, V = bending._plan, len(X)
    XT = np.ascontiguousarray(X.T)
    hk = hg.hinge_kernel(XT, p.HT, order=2)
    fk = hg.face_kernel(XT, p.FT, order=2)
    M, A = p.vertex_sums(hk.phi, fk.area)
    H, w_hinge, w_face = bending._weights(M, A)
    out = np.zeros((3 * V, 3 * V))
    for elements, local in ((p.HT, hg._dense(hk.hess.upper_blocks(w_hinge), hg.HINGE_UPPER_BLOCKS, 4)),
                            (p.FT, hg._dense(fk.hess.upper_blocks(w_face), hg.FACE_UPPER_BLOCKS, 3))):
        dofs = (3 * elements.T[:, :, None] + np.arange(3)).reshape(elements.shape[1], -1)
        np.add.at(out, (dofs[:, :, None], dofs[:, None, :]), local)
    grad_M, grad_A = np.zeros((V, 3 * V)), np.zeros((V, 3 * V))
    for c in range(3):
        for end in range(2):
            for a in range(4):
                np.add.at(grad_M, (p.HT[end], 3 * p.HT[a] + c), 0.25 * hk.dphi[c, a])
        for centre in range(3):
            for a in range(3):
                np.add.at(grad_A, (p.FT[centre], 3 * p.FT[a] + c), fk.grad[c, a] / 3.0)
    g = grad_M - H[:, None] * grad_A
    return out + (g.T * (4.0 * bending.kappa / A)) @ g


@pytest.mark.parametrize("c0", [0.0, 2.0, -1.3])
def test_juelicher_hessian_matches_the_numpy_element_kernels(shell, c0):
    mesh, X = shell
    bending = Bending.from_mesh(mesh, kappa=1.7, c0=c0)
    H = bending.hessian(X)
    ref = _numpy_bending_hessian(bending, X)
    np.testing.assert_allclose(H.toarray(), ref, rtol=0, atol=1e-13 * np.abs(ref).max())
    assert abs(H - H.T).max() == 0.0


@pytest.mark.parametrize("c0", [0.0, 2.0, -1.3])
def test_juelicher_matches_the_numpy_element_kernels(shell, c0):
    mesh, X = shell
    bending = Bending.from_mesh(mesh, kappa=1.7, c0=c0)
    value, G = bending.value_and_gradient(X)
    ref_value, ref_G = _numpy_bending(bending, X)
    assert value == pytest.approx(ref_value, rel=1e-13)
    np.testing.assert_allclose(G, ref_G, rtol=0, atol=1e-12 * np.abs(ref_G).max())
    assert bending.value(X) == value  # the same number whether or not the gradient is asked


def test_stretching_matches_the_numpy_strain_and_stress(shell):
    mesh, X = shell
    st = Stretching.from_reference(mesh.X, mesh.faces, mesh.n_vertices, A=3.1, nu=0.3)
    value, G = st.value_and_gradient(X)
    s, t = st._edges(X)
    E = st._strain(s, t)
    S11, S12, S22 = S = st._stress(E)
    assert value == pytest.approx(float(st._face_energy(E, S).sum()), rel=1e-13)
    k = st._k
    ref = np.zeros_like(X)
    gs, gt = (S11 * s + S12 * t).T, (S12 * s + S22 * t).T
    np.add.at(ref, k["f1"], gs)
    np.add.at(ref, k["f2"], gt)
    np.add.at(ref, k["f0"], -(gs + gt))
    np.testing.assert_allclose(G, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert st.value(X) == value


def test_volume_matches_the_divergence_formula_and_its_derivatives(shell):
    mesh, X = shell
    vol = Volume(mesh.faces, mesh.n_vertices)
    x0, x1, x2 = (X[mesh.faces[:, k]] for k in range(3))
    assert vol.value(X) == pytest.approx(np.einsum("ij,ij->", x0, np.cross(x1, x2)) / 6.0,
                                         rel=1e-14)
    d = np.random.default_rng(5).standard_normal(X.shape)
    h = 1e-6
    fd = (vol.value(X + h * d) - vol.value(X - h * d)) / (2 * h)
    assert float(np.sum(vol.gradient(X) * d)) == pytest.approx(fd, rel=1e-8)
    c = vol.along(X, d)  # exact cubic: four points determine it
    ts = np.array([-0.3, -0.1, 0.2, 0.4])
    np.testing.assert_allclose(np.polyval(c[::-1], ts), [vol.value(X + t * d) for t in ts],
                               rtol=1e-12)


@pytest.mark.parametrize("term", ["bending", "stretching", "volume"])
def test_compiled_gradients_match_central_differences(term):
    mesh = icosphere(2)
    X = 0.95 * mesh.X + 0.01 * np.random.default_rng(6).standard_normal(mesh.X.shape)
    energy = {"bending": lambda: Bending.from_mesh(mesh, kappa=1.0, c0=2.0),
              "stretching": lambda: Stretching.from_reference(mesh.X, mesh.faces,
                                                              mesh.n_vertices, A=10.0, nu=1 / 3),
              "volume": lambda: Volume(mesh.faces, mesh.n_vertices)}[term]()
    d = np.random.default_rng(7).standard_normal(X.shape)
    h = 1e-6
    fd = (energy.value(X + h * d) - energy.value(X - h * d)) / (2 * h)
    assert float(np.sum(energy.gradient(X) * d)) == pytest.approx(fd, rel=1e-6)


def test_kernels_refuse_positions_of_another_mesh():
    mesh = icosphere(1)
    for term in (Bending.from_mesh(mesh), Volume(mesh.faces, mesh.n_vertices),
                 Stretching.from_reference(mesh.X, mesh.faces, mesh.n_vertices, A=1.0, nu=0.3)):
        with pytest.raises(ValueError, match=rf"\({mesh.n_vertices}, 3\)"):
            term.value(mesh.X[:-1])
        with pytest.raises(ValueError, match=rf"\({mesh.n_vertices}, 3\)"):
            term.gradient(np.zeros((mesh.n_vertices, 2)))


def test_value_only_and_value_with_gradient_are_one_computation():
    # Newton's method keeps the gradient of the point whose value a line search accepted: the
    # two calls must give the same number bit for bit
    mesh = icosphere(2)
    X = 0.9 * mesh.X
    p = Bending.from_mesh(mesh)._plan
    c0 = np.full(mesh.n_vertices, 2.0)
    v0, G0 = kernels.juelicher(X, p.HT, p.FT, 1.0, c0, False)
    v1, G1 = kernels.juelicher(X, p.HT, p.FT, 1.0, c0, True)
    assert v0 == v1 and G0.shape == (0, 3) and G1.shape == X.shape


def test_face_side_lengths_round_as_numpy_and_give_the_icosahedron_edge(shell):
    from shellbuckle.solve.linesearch import mean_edge_length

    mesh, X = shell
    faces = np.asarray(mesh.faces)
    sides = X[np.roll(faces, -1, axis=1)] - X[faces]
    expected = np.linalg.norm(sides, axis=-1).ravel()
    assert np.array_equal(kernels.face_side_lengths(X, faces), expected)  # the same rounding
    assert mean_edge_length(faces, X) == float(expected.mean())
    # a regular icosahedron of circumradius 1 has edge 4 / sqrt(10 + 2 sqrt 5)
    ico = icosphere(1)  # the icosahedron itself
    scale = 2.5
    edge = scale * 4.0 / np.sqrt(10.0 + 2.0 * np.sqrt(5.0))
    assert mean_edge_length(np.asarray(ico.faces), scale * ico.X) == pytest.approx(edge, rel=1e-14)


def test_add_scaled_at_sums_as_numpy_fancy_indexing():
    rng = np.random.default_rng(7)
    values = rng.standard_normal(500)
    keep = rng.choice(500, size=300, replace=False)
    slot = rng.choice(1000, size=300, replace=False)  # distinct slots, as in one KKT term
    data = rng.standard_normal(1000)
    expected = data.copy()
    expected[slot] += -2.5 * values[keep]
    kernels.add_scaled_at(data, slot, values, keep, -2.5)
    assert np.array_equal(data, expected)
