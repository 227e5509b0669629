"""The reduced KKT matrix (:mod:`shellbuckle.solve.kkt`): its assembly and its pattern.

Oracles: the dense KKT matrix ``[[sum c_t M_t + mu I, g], [g^T, 0]]`` on the free dofs; the
Hessian terms' patterns at the exact reference sphere and off it.
"""

import numpy as np
import scipy.sparse as sp

from shellbuckle.solve.kkt import KKTAssembler
from test_solve_newton import shell


def test_kkt_assembler_matches_the_dense_kkt_matrix():
    # oracle: [[c1 M1 + c2 M2 + mu I, g], [g^T, 0]] on the free dofs, built densely
    rng = np.random.default_rng(4)
    n_dofs = 30
    mats = []
    for seed in (1, 2):
        M = sp.random(n_dofs, n_dofs, density=0.2, random_state=seed)
        mats.append((M + M.T).tocsr())
    free = np.setdiff1d(np.arange(n_dofs), [3, 17, 22])
    g = rng.standard_normal((n_dofs // 3, 3))
    coefs, mu = (1.0, -0.7), 0.3
    kkt = KKTAssembler(free, n_dofs)
    data = kkt.build(list(zip(mats, coefs)), g)
    upper = kkt.matrix(data, mu)
    assert (sp.tril(upper, k=-1).nnz == 0) and upper.has_sorted_indices
    full = (upper + sp.triu(upper, k=1).T).toarray()
    K = sum(c * M.toarray() for M, c in zip(mats, coefs))[np.ix_(free, free)]
    K += mu * np.eye(len(free))
    gf = g.ravel()[free]
    expected = np.block([[K, gf[:, None]], [gf[None, :], np.zeros((1, 1))]])
    np.testing.assert_allclose(full, expected, rtol=0, atol=1e-14)
    # same patterns again: same index arrays (the solver keeps its symbolic analysis)
    again = kkt.matrix(kkt.build(list(zip(mats, coefs)), g))
    assert np.shares_memory(again.indices, upper.indices)
    assert np.shares_memory(again.indptr, upper.indptr)


def test_kkt_assembler_follows_a_change_of_term_patterns():
    # oracle: the dense KKT matrix after each change; a term whose pattern lies within the
    # current one keeps the matrix pattern, one with new entries widens it
    rng = np.random.default_rng(5)
    n_dofs = 36
    free = np.setdiff1d(np.arange(n_dofs), [0, 7, 20, 21, 30, 35])
    g = rng.standard_normal((n_dofs // 3, 3))

    def sym(density, seed):
        M = sp.random(n_dofs, n_dofs, density=density, random_state=seed)
        return (M + M.T).tocsr()

    wide, other = sym(0.3, 1), sym(0.1, 2)
    half = sp.triu(wide, format="csr")
    half.data[rng.random(half.nnz) < 0.5] = 0.0
    half.eliminate_zeros()
    narrow = (half + sp.triu(half, k=1).T).tocsr()  # symmetric, a sub-pattern of ``wide``
    kkt = KKTAssembler(free, n_dofs)
    patterns = []
    for mats in ([wide, other], [narrow, other], [wide, sym(0.3, 3)]):
        terms = list(zip(mats, (1.0, 0.5)))
        upper = kkt.matrix(kkt.build(terms, g))
        full = (upper + sp.triu(upper, k=1).T).toarray()
        K = sum(c * M.toarray() for M, c in terms)[np.ix_(free, free)]
        gf = g.ravel()[free]
        expected = np.block([[K, gf[:, None]], [gf[None, :], np.zeros((1, 1))]])
        np.testing.assert_allclose(full, expected, rtol=0, atol=1e-14)
        patterns.append(upper.indices.size)
    assert patterns[1] == patterns[0]  # kept
    assert patterns[2] > patterns[0]  # widened


def test_kkt_pattern_does_not_depend_on_values():
    # on the exact reference icosphere some stretching and bending entries cancel; the
    # solver's pattern (and so its ordering and round-off) must be the same as elsewhere
    mesh, energy, volume, V0 = shell(3, 271)
    X1 = mesh.X + 1e-3 * np.random.default_rng(2).standard_normal(mesh.X.shape)
    assert energy.hessian(mesh.X).nnz < energy.hessian(X1).nnz  # the cancellation exists
    for a, b in zip(energy.hessian_terms(mesh.X), energy.hessian_terms(X1)):
        assert np.array_equal(a.indptr, b.indptr) and np.array_equal(a.indices, b.indices)
    assert np.allclose(sum(energy.hessian_terms(X1)).toarray(), energy.hessian(X1).toarray(),
                       rtol=0, atol=1e-12)
