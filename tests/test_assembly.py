"""Element assembly: scattering local gradients and Hessians into global arrays."""

import numpy as np
import pytest
import scipy.sparse as sp

from shellbuckle.energies.assembly import ElementAssembler
from shellbuckle.mesh import random_sphere


def _edges(faces):
    pairs = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return np.unique(np.sort(pairs, axis=1), axis=0)


@pytest.mark.parametrize("kind", ["faces", "edges"])
def test_element_assembly_sums_as_scipy_coo_in_canonical_csr(kind):
    mesh = random_sphere(300, seed=4)
    elements = mesh.faces if kind == "faces" else _edges(mesh.faces)
    # a shuffled vertex numbering, so that no order of the mesh's own helps
    relabel = np.random.default_rng(1).permutation(mesh.n_vertices)
    elements = relabel[elements]
    asm = ElementAssembler(elements, mesh.n_vertices)
    n_el, k = elements.shape
    rng = np.random.default_rng(2)
    local = rng.standard_normal((n_el, 3 * k, 3 * k))
    H = asm.hessian(local)
    dofs = (3 * elements[:, :, None] + np.arange(3)).reshape(n_el, 3 * k)
    rows = np.broadcast_to(dofs[:, :, None], local.shape).ravel()
    cols = np.broadcast_to(dofs[:, None, :], local.shape).ravel()
    oracle = sp.coo_matrix((local.ravel(), (rows, cols)), shape=H.shape).tocsr()
    oracle.sum_duplicates()
    assert H.has_canonical_format
    np.testing.assert_array_equal(H.indptr, oracle.indptr)
    np.testing.assert_array_equal(H.indices, oracle.indices)
    np.testing.assert_allclose(H.data, oracle.data, rtol=1e-13, atol=1e-13)
    g = rng.standard_normal((n_el, k, 3))
    expected = np.zeros((mesh.n_vertices, 3))
    np.add.at(expected, elements, g)
    np.testing.assert_allclose(asm.gradient(g), expected, rtol=1e-13, atol=1e-13)
