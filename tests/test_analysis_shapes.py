"""Synthetic conformations with known geometry, used by the analysis tests, and their checks.

All shapes are made from a sphere mesh of radius R by moving vertices; the surface stays closed
and outward oriented.

- ``inverted_cap``: mirror buckling, the cap ``x . u > R cos(alpha)`` reflected through the
  plane ``x . u = R cos(alpha)``. Rim radius ``R sin(alpha)``, pole displaced by
  ``2 R (1 - cos alpha)``, volume lost ``dV/V = (1 - cos alpha)^2 (2 + cos alpha) / 2``.
  Only ``alpha <= 90 deg`` is a surface without self-intersection (at 90 deg the image of the
  pole touches the opposite pole, dV/V = 1).
- ``modulated_cap``: the rim at azimuth ``phi`` is at ``R sin(alpha(phi))`` with
  ``sin(alpha(phi)) = sin(alpha0) f(phi)`` for a given periodic ``f``; inside, each meridian is
  reflected through the height of its own rim, blended towards ``cos(alpha0)`` at the axis so
  the dent's floor carries radial folds that fade towards the axis (continuous everywhere).
- ``dimpled``: small inverted caps about well separated directions.
"""

import numpy as np
import pytest

from shellbuckle.mesh import icosphere, random_sphere


def rotation(rng) -> np.ndarray:
    """A uniformly random rotation matrix (QR of a Gaussian matrix, sign-fixed, det +1)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def frame(axis):
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    a = np.eye(3)[int(np.argmin(np.abs(u)))]
    e1 = np.cross(u, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(u, e1), u


def inverted_cap(X, alpha, axis=(0.0, 0.0, 1.0)):
    R = np.linalg.norm(X, axis=1).max()  # the sphere's radius, also after other reflections
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    z = X @ u
    c = R * np.cos(alpha)
    return X - 2.0 * np.clip(z - c, 0.0, None)[:, None] * u


def cos_profile(m, eps):
    return lambda phi: 1.0 + eps * np.cos(m * phi)


def polygon_profile(m):
    """``f(phi)`` of a regular m-gon with straight sides: apices (``f = 1``) at
    ``phi = pi/m + 2 pi k/m``, the middles of the sides (``f = cos(pi/m)``) at ``2 pi k/m``."""
    def f(phi):
        t = np.mod(phi + np.pi / m, 2 * np.pi / m) - np.pi / m
        return np.cos(np.pi / m) / np.cos(t)
    return f


def modulated_cap(X, alpha0, profile, axis=(0.0, 0.0, 1.0), phase=0.0, blend=2):
    R = np.linalg.norm(X, axis=1).max()
    e1, e2, u = frame(axis)
    P = X / R
    x, y, z = P @ e1, P @ e2, P @ u
    theta = np.arccos(np.clip(z, -1, 1))
    phi = np.arctan2(y, x) - phase
    alpha = np.arcsin(np.clip(np.sin(alpha0) * profile(phi), 0, 1))
    inside = theta < alpha
    c0 = np.cos(alpha0)
    ct = c0 + (np.cos(alpha) - c0) * (theta / alpha) ** blend
    znew = np.where(inside, 2 * ct - z, z)
    return R * (x[:, None] * e1 + y[:, None] * e2 + znew[:, None] * u)


def dimpled(X, directions, beta):
    out = X.copy()
    for d in directions:
        out = inverted_cap(out, beta, d)
    return out


def jiggled(X, amplitude, rng):
    return X + amplitude * rng.uniform(-1, 1, size=X.shape)


MESHES = {"icosphere": lambda: icosphere(19), "random": lambda: random_sphere(3594, seed=2)}
_cache = {}


def mesh(kind):
    if kind not in _cache:
        _cache[kind] = MESHES[kind]()
    return _cache[kind]


def volume(X, faces):
    x0, x1, x2 = X[faces[:, 0]], X[faces[:, 1]], X[faces[:, 2]]
    return np.einsum("ij,ij->i", x0, np.cross(x1, x2)).sum() / 6.0


# ---------------------------------------------------------------------- checks of the shapes

@pytest.mark.parametrize("kind", sorted(MESHES))
@pytest.mark.parametrize("alpha_deg", [30, 60, 90])
def test_inverted_cap_loses_the_volume_of_mirror_buckling(kind, alpha_deg):
    m = mesh(kind)
    alpha = np.radians(alpha_deg)
    X = inverted_cap(m.X, alpha, axis=(1.0, 2.0, 3.0))
    V0, V = volume(m.X, m.faces), volume(X, m.faces)
    expected = 0.5 * (1 - np.cos(alpha)) ** 2 * (2 + np.cos(alpha))
    h = np.sqrt(4 * np.pi / len(m.X))  # mesh spacing: the cut through faces costs O(h^2)
    assert (V0 - V) / V0 == pytest.approx(expected, abs=h * h)


@pytest.mark.parametrize("kind", sorted(MESHES))
def test_modulated_cap_rim_follows_its_profile(kind):
    # the rim of every meridian stays where it was on the sphere: |x| = R at the rim
    m = mesh(kind)
    f = cos_profile(5, 0.1)
    X = modulated_cap(m.X, np.radians(60), f, axis=(0.0, 1.0, 1.0), phase=0.3)
    moved = np.linalg.norm(X - m.X, axis=1) > 1e-12
    r = np.linalg.norm(X[moved], axis=1)
    assert r.max() <= 1.0 + 1e-12
    assert np.isfinite(volume(X, m.faces))
