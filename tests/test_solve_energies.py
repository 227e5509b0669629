"""Small exact test energies for the solver tests, and checks of their derivatives.

``EdgeSprings``: E = sum_e k/2 (l_e - l0_e)^2 (rest lengths from a reference configuration).
``Umbrella``: E = kb/2 |L X|^2 with L the graph Laplacian (umbrella operator) of the mesh, a
quadratic bending-like term that suppresses short wavelengths. Both are invariant under rigid
motions, as the shell energies are.
"""

import numpy as np
import pytest
import scipy.sparse as sp

from shellbuckle.energies.assembly import ElementAssembler
from shellbuckle.energies.base import Sum
from shellbuckle.mesh import icosphere


class EdgeSprings:
    def __init__(self, edges, X_ref, k=1.0):
        self.edges = np.asarray(edges)
        self.l0 = np.linalg.norm(X_ref[self.edges[:, 1]] - X_ref[self.edges[:, 0]], axis=1)
        self.k = k
        self._asm = ElementAssembler(self.edges, len(X_ref))

    def _geometry(self, X):
        d = X[self.edges[:, 1]] - X[self.edges[:, 0]]
        l = np.linalg.norm(d, axis=1)
        return d / l[:, None], l

    def value(self, X):
        _, l = self._geometry(X)
        return float(0.5 * self.k * ((l - self.l0) ** 2).sum())

    def gradient(self, X):
        u, l = self._geometry(X)
        f = (self.k * (l - self.l0))[:, None] * u
        return self._asm.gradient(np.stack([-f, f], axis=1))

    def hessian(self, X):
        u, l = self._geometry(X)
        uu = u[:, :, None] * u[:, None, :]
        H = self.k * (uu + ((l - self.l0) / l)[:, None, None] * (np.eye(3) - uu))
        local = np.block([[H, -H], [-H, H]])
        return self._asm.hessian(local)


class Umbrella:
    def __init__(self, edges, n_vertices, kb=1.0):
        e = np.asarray(edges)
        W = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n_vertices,) * 2)
        W = (W + W.T).tocsr()
        L = (W - sp.diags(np.asarray(W.sum(axis=1)).ravel())).tocsr()
        self.kb = kb
        self.LtL = (L.T @ L).tocsr()
        self._H = (kb * sp.kron(self.LtL, sp.eye(3))).tocsr()

    def value(self, X):
        return float(0.5 * self.kb * np.einsum("ij,ij->", X, self.LtL @ X))

    def gradient(self, X):
        return self.kb * (self.LtL @ X)

    def hessian(self, X):
        return self._H.copy()


def spring_shell(n=3, k=1.0, kb=0.05):
    """Icosphere(n) with edge springs at rest on the sphere plus the umbrella term."""
    mesh = icosphere(n)
    edges = mesh.topology.edges
    energy = Sum([EdgeSprings(edges, mesh.X, k), Umbrella(edges, mesh.n_vertices, kb)])
    return mesh, energy


def _perturbed(n, seed, amplitude=0.03):
    mesh = icosphere(n)
    rng = np.random.default_rng(seed)
    return mesh, mesh.X + amplitude * rng.standard_normal(mesh.X.shape)


@pytest.mark.parametrize("term", ["springs", "umbrella"])
def test_test_energies_derivatives_match_central_differences(term):
    mesh, X = _perturbed(2, seed=1)
    edges = mesh.topology.edges
    e = EdgeSprings(edges, mesh.X, 1.3) if term == "springs" else Umbrella(edges, mesh.n_vertices, 0.7)
    rng = np.random.default_rng(2)
    v = rng.standard_normal(X.shape)
    g, H = e.gradient(X), e.hessian(X)
    errs_g, errs_h = [], []
    for h in [1e-2, 1e-3, 1e-4, 1e-5, 1e-6]:
        fd = (e.value(X + h * v) - e.value(X - h * v)) / (2 * h)
        errs_g.append(abs(fd - np.sum(g * v)) / abs(np.sum(g * v)))
        fdg = (e.gradient(X + h * v) - e.gradient(X - h * v)) / (2 * h)
        exact = (H @ v.ravel()).reshape(-1, 3)
        errs_h.append(np.linalg.norm(fdg - exact) / np.linalg.norm(exact))
    assert min(errs_g) < 1e-6 and min(errs_h) < 1e-6


def test_test_energies_are_rigid_invariant():
    mesh, energy = spring_shell(2)
    _, X = _perturbed(2, seed=3)
    c, s = np.cos(0.7), np.sin(0.7)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    Y = X @ Rz.T + np.array([0.3, -1.0, 2.0])
    assert energy.value(Y) == pytest.approx(energy.value(X), rel=1e-12)
