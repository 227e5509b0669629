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

Two families are built independently of ``modulated_cap``'s azimuthal profile: the sphere
above a *roof* ``z = h(x, y)`` (``z`` along the dent axis ``u``) is reflected through it along
the axis, ``z -> 2 h - z``; the map is continuous because ``h`` is, so the surface stays closed.
The rim is where the sphere meets the roof, an implicit curve rather than a polar profile.

- ``faceted_cap``: the roof is a pyramid pointing into the shell, the maximum of ``m`` planes
  tilted by ``beta``: the dent is the intersection of ``m`` circular caps. Its rim is a convex
  curvilinear m-gon with sharp corners at ``phase + pi/m + 2 pi k/m`` and sides that are arcs
  of the caps' circles, a side's middle at ``R sin(alpha)`` from the axis with curvature
  ``kappa rho = cos(beta) sin(alpha) / sin(alpha + beta)`` (1 for a circle, 0 for a straight
  side: a steep pyramid gives nearly straight sides). The floor is made of inverted spherical
  pieces meeting in valleys along the pyramid's edges: a polygonal dent.
- ``rippled_cap``: the roof is a plane normal to the axis plus the harmonic ripple
  ``Re((x + i y)^m)``, largest at the rim and fading towards the axis as ``rho^m``: the rim
  has ``m`` apices and, for a large enough ripple, dips inwards between them (the floor rises
  in a radial fold there): a wrinkled bowl. ``ripple_amplitude`` gives the ripple for a chosen
  depth of the rim between its apices.
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


def _roof_reflection(X, axis, roof):
    """Reflect along the unit axis through the roof: ``z -> 2 roof(x, y) - z`` where
    ``z > roof`` (coordinates of the unit sphere in the frame of ``axis``)."""
    R = np.linalg.norm(X, axis=1).max()
    e1, e2, u = frame(axis)
    P = X / R
    x, y, z = P @ e1, P @ e2, P @ u
    h = roof(x, y)
    znew = z - 2.0 * np.clip(z - h, 0.0, None)
    return R * (x[:, None] * e1 + y[:, None] * e2 + znew[:, None] * u)


def faceted_cap(X, m, alpha, beta, axis=(0.0, 0.0, 1.0), phase=0.0, floor=None):
    """Convex polygonal dent: the sphere inside ``m`` planes (a pyramid) reflected through them
    along the axis (module docstring). Plane ``k`` has unit normal ``cos(beta) u - sin(beta)
    (cos phi_k e1 + sin phi_k e2)``, ``phi_k = phase + 2 pi k / m``, and cuts the sphere along
    the circle at angle ``alpha + beta`` from it, so side ``k`` faces ``phi_k`` at distance
    ``R sin(alpha)`` from the axis; the corners are between the sides. ``floor``: the pyramid
    is cut by the plane normal to the axis at ``R cos(floor)`` (a truncated pyramid, whose
    dent is no deeper than the inverted cap of half-angle ``floor``)."""
    phi = phase + 2.0 * np.pi * np.arange(m) / m
    d = np.cos(alpha + beta)
    low = -np.inf if floor is None else np.cos(floor)

    def roof(x, y):
        p = x[:, None] * np.cos(phi) + y[:, None] * np.sin(phi)
        return np.maximum(low, ((d + np.sin(beta) * p) / np.cos(beta)).max(axis=1))

    return _roof_reflection(X, axis, roof)


#: ``rippled_cap``'s ripple stops growing beyond this multiple of the unperturbed rim radius,
#: so that it stays a feature of the dent's rim.
RIPPLE_REACH = 1.25


def rippled_cap(X, m, alpha, amplitude, axis=(0.0, 0.0, 1.0), phase=0.0, lift=1.0):
    """Wrinkled bowl: the sphere above the roof ``z = cos(alpha) + amplitude sin(alpha)
    (lift - Re(w^m))``, ``w = (x + i y) e^(-i phase) / sin(alpha)``, reflected through it along
    the axis (module docstring). The ripple ``Re(w^m)`` is harmonic: it leaves the floor's mean
    curvature that of the inverted sphere and fades towards the axis as ``rho^m``, like folds
    running into the bowl. Apices at azimuths ``phase + 2 pi k/m``. To first order the rim is
    ``sin(alpha) (1 + eps (cos m phi - lift))``, ``eps = amplitude cot(alpha)``: with
    ``lift = 1`` the apices are on the circle of half-angle ``alpha`` and the middles between
    them pulled in by ``2 eps sin(alpha)``; with ``lift = 0`` the rim is centred on that
    circle."""
    s = np.sin(alpha)

    def roof(x, y):
        w = (x + 1j * y) * np.exp(-1j * phase) / s
        w = w * np.minimum(1.0, RIPPLE_REACH / np.maximum(np.abs(w), 1e-300))
        return np.cos(alpha) + amplitude * s * (lift - (w ** m).real)

    return _roof_reflection(X, axis, roof)


def ripple_amplitude(m, alpha, sagitta, lift=1.0):
    """``rippled_cap``'s amplitude whose rim (to first order) dips ``sagitta`` chords inside the
    chord between two successive apices: the rim ``r0 (1 + eps' cos m phi)`` with ``eps' =
    star_modulation(m, sagitta) = eps / (1 - lift eps)``."""
    e = star_modulation(m, sagitta)
    return e / (1.0 + lift * e) * np.tan(alpha)


def star_modulation(m, sagitta):
    """Relative amplitude ``eps`` of the rim ``r0 (1 + eps cos m phi)`` whose arcs between two
    successive apices dip inside the chord joining them by ``sagitta`` times the chord
    (negative: bulge out of it). For ``sagitta = 0`` the arc's innermost point lies on the
    chord: ``eps = tan^2(pi / 2m)``."""
    c, s = np.cos(np.pi / m), np.sin(np.pi / m)
    return (1 - c + 2 * sagitta * s) / (1 + c - 2 * sagitta * s)


def dimpled(X, directions, beta):
    out = X.copy()
    for d in directions:
        out = inverted_cap(out, beta, d)
    return out


def jiggled(X, amplitude, rng):
    return X + amplitude * rng.uniform(-1, 1, size=X.shape)


MESHES = {"icosphere": lambda: icosphere(19), "random": lambda: random_sphere(3594, seed=2),
          "icosphere(16)": lambda: icosphere(16), "icosphere(32)": lambda: icosphere(32),
          "random(10242)": lambda: random_sphere(10242, seed=3),
          "icosphere(63)": lambda: icosphere(63), "icosphere(126)": lambda: icosphere(126)}
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


def _moved_rim(X0, X, axis, phase=0.0):
    """Azimuths (from ``phase``) and distances from ``axis`` of the vertices that moved, at
    their positions on the sphere, as ``(phi, rho)`` on the unit sphere."""
    e1, e2, u = frame(axis)
    moved = np.linalg.norm(X - X0, axis=1) > 1e-12
    P = X0[moved] / np.linalg.norm(X0, axis=1).max()
    return np.mod(np.arctan2(P @ e2, P @ e1) - phase, 2 * np.pi), np.hypot(P @ e1, P @ e2)


def _reach(phi, rho, centre, half_width):
    """Largest ``rho`` within ``half_width`` of azimuth ``centre``."""
    near = np.abs(np.angle(np.exp(1j * (phi - centre)))) <= half_width
    return rho[near].max()


@pytest.mark.parametrize("kind", ["icosphere(16)", "random"])
@pytest.mark.parametrize("m", [3, 6, 10])
def test_faceted_cap_rim_is_the_polygon_cut_by_the_pyramid(kind, m):
    # side k faces phi_k at R sin(alpha); the corner between sides k and k + 1 is where the
    # planes k, k + 1 and the sphere meet: cos(beta) z - sin(beta) rho cos(pi/m) = cos(alpha +
    # beta), rho^2 + z^2 = 1
    mm = mesh(kind)
    alpha, beta, phase, axis = np.radians(40), np.radians(60), 0.4, (0.3, -0.5, 1.0)
    X = faceted_cap(mm.X, m, alpha, beta, axis, phase, floor=np.radians(60))
    phi, rho = _moved_rim(mm.X, X, axis, phase)
    h = np.sqrt(4 * np.pi / len(mm.X))
    b, c = np.sin(beta) * np.cos(np.pi / m), np.cos(alpha + beta)
    q = np.cos(beta) ** 2 + b * b
    z = (c * np.cos(beta) + b * np.sqrt(q - c * c)) / q
    corner = np.sqrt(1 - z * z)
    width = h / np.sin(alpha)  # an edge length, in azimuth
    for k in range(m):
        # the vertices just inside the rim are less than about an edge from it
        side = _reach(phi, rho, 2 * np.pi * k / m, width)
        assert np.sin(alpha) - 1.5 * h < side <= np.sin(alpha) / np.cos(width)
        assert corner - 1.5 * h < _reach(phi, rho, 2 * np.pi * k / m + np.pi / m, width)
    assert rho.max() <= corner + 1e-9


@pytest.mark.parametrize("kind", ["icosphere(16)", "random"])
@pytest.mark.parametrize("m, alpha_deg, lift", [(3, 35, 0.0), (4, 55, 1.0), (6, 55, 1.0),
                                                (10, 70, 1.0)])
def test_rippled_cap_has_m_apices_and_stays_closed(kind, m, alpha_deg, lift):
    mm = mesh(kind)
    alpha, phase, axis = np.radians(alpha_deg), 1.1, (1.0, 0.2, -0.4)
    amplitude = ripple_amplitude(m, alpha, 0.04, lift)
    eps = amplitude / np.tan(alpha)
    X = rippled_cap(mm.X, m, alpha, amplitude, axis, phase, lift)
    phi, rho = _moved_rim(mm.X, X, axis, phase)
    h = np.sqrt(4 * np.pi / len(mm.X))
    width = h / np.sin(alpha)
    tips = [_reach(phi, rho, 2 * np.pi * k / m, width) for k in range(m)]
    gaps = [_reach(phi, rho, 2 * np.pi * k / m + np.pi / m, width) for k in range(m)]
    # to first order the tips are at sin(alpha) (1 + eps (1 - lift)), the middles between them
    # 2 eps sin(alpha) further in; to within the distance of the vertices from the rim and the
    # second order
    tip = np.sin(alpha) * (1 + eps * (1 - lift))
    assert np.abs(np.array(tips) - tip).max() < 1.5 * h + 0.1 * eps
    assert min(tips) - max(gaps) > 2 * eps * np.sin(alpha) - 1.5 * h
    # the map is continuous: a tear would stretch an edge across the dent's depth
    # (2 (1 - cos alpha) R, about 13 edge lengths), the steep roof only by a few times
    e = mm.topology.edges
    ratio = np.linalg.norm(X[e[:, 1]] - X[e[:, 0]], axis=1) / np.linalg.norm(
        mm.X[e[:, 1]] - mm.X[e[:, 0]], axis=1)
    assert ratio.max() < 6.0
    assert volume(X, mm.faces) < volume(mm.X, mm.faces)


@pytest.mark.parametrize("m", range(3, 11))
@pytest.mark.parametrize("sagitta", [-0.02, 0.0, 0.03, 0.1])
def test_star_modulation_gives_the_depth_between_apices(m, sagitta):
    # measured on the exact curve r0 (1 + eps cos m phi), apices at 0 and 2 pi / m
    eps = star_modulation(m, sagitta)
    t = np.linspace(0, 2 * np.pi / m, 20001)
    r = 1 + eps * np.cos(m * t)
    P = np.stack([r * np.cos(t), r * np.sin(t)], axis=1)
    chord = P[-1] - P[0]
    inward = (chord[0] * (P[:, 1] - P[0, 1]) - chord[1] * (P[:, 0] - P[0, 0])) / np.hypot(*chord)
    middle = inward[len(t) // 2] / np.hypot(*chord)  # the innermost point, phi = pi / m
    assert middle == pytest.approx(sagitta, abs=1e-9)
