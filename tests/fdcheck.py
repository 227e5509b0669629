"""Finite-difference oracles shared by the energy-term tests: central differences over
several step sizes, best relative error (libshell's scan from 1e-2 to 1e-7)."""

import numpy as np

STEPS = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7]


def perturbed(X, rng, fraction=0.05):
    """Move every vertex by ~``fraction`` of a mean edge length in a random direction."""
    h = 4.0 / np.sqrt(len(X))  # ~ edge length of a unit icosphere
    return X + fraction * h * rng.standard_normal(X.shape)


def fd_gradient_error(value, gradient, X):
    g = gradient(X).ravel()
    errs = []
    for h in STEPS:
        fd = np.empty(X.size)
        for i in range(X.size):
            Xp, Xm = X.copy().ravel(), X.copy().ravel()
            Xp[i] += h
            Xm[i] -= h
            fd[i] = (value(Xp.reshape(X.shape)) - value(Xm.reshape(X.shape))) / (2 * h)
        errs.append(np.linalg.norm(fd - g) / np.linalg.norm(g))
    return min(errs)


def fd_hessian_error(gradient, hessian, X):
    H = hessian(X).toarray()
    errs = []
    for h in STEPS:
        fd = np.empty_like(H)
        for i in range(X.size):
            Xp, Xm = X.copy().ravel(), X.copy().ravel()
            Xp[i] += h
            Xm[i] -= h
            fd[:, i] = (gradient(Xp.reshape(X.shape)) - gradient(Xm.reshape(X.shape))).ravel() / (2 * h)
        errs.append(np.linalg.norm(fd - H) / np.linalg.norm(H))
    return min(errs)


def random_rotation(rng) -> np.ndarray:
    """A uniformly random rotation (QR of a Gaussian matrix, signs fixed, det +1)."""
    Q, R = np.linalg.qr(rng.standard_normal((3, 3)))
    Q = Q * np.sign(np.diag(R))
    return Q if np.linalg.det(Q) > 0 else -Q


def triangulated_cube(s: float):
    """Vertices (8, 3) and outward-oriented faces (12, 3) of a cube of side ``s`` with one
    corner at the origin, each square split along a diagonal (Steiner-formula oracles)."""
    X = s * np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    F = np.array([[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads])
    n = np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]])
    flip = (n * (X[F].mean(axis=1) - s / 2)).sum(axis=1) < 0
    F[flip] = F[flip][:, ::-1]
    return X, F
