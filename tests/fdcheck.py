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
