"""Smooth imperfection: a seeded random field on the sphere, the same whatever the mesh.

Surface Evolver's jiggle (:mod:`.jiggle`) is white noise at the vertices: on a finer mesh the
same temperature is another, rougher perturbation. The smooth imperfection is a normal
displacement defined on the reference sphere,

    u(n) = a R f(n),   f(n) = sum_{l=2}^{L} sum_{m=-l}^{l} f_lm Y_lm(n),

evaluated at each vertex's material point ``n`` (its direction from the centre of the
reference sphere, :func:`reference_directions`) and applied along the area-weighted vertex
normal of the current conformation (:func:`vertex_normals`). The same material point moves by
the same amount on any mesh and at any deformation; only its sampling changes.

Harmonics. ``Y_lm`` are the real 4 pi-normalized spherical harmonics of geodesy (Wieczorek &
Meschede, "SHTools: Tools for working with spherical harmonics", Geochem. Geophys. Geosyst.
19, 2574 (2018), §2): ``Y_lm = Pbar_lm(cos theta) cos(m phi)`` for ``m >= 0`` and
``Pbar_l|m|(cos theta) sin(|m| phi)`` for ``m < 0``, without the Condon-Shortley phase, with
``(1/4 pi) int Y_lm Y_l'm' dOmega = delta_ll' delta_mm'``. In terms of SciPy's complex
orthonormal ``Y_l^m`` (which has the phase): ``Y_l0 = sqrt(4 pi) Y_l^0`` and, for ``m > 0``,
``Y_lm = sqrt(8 pi) (-1)^m Re Y_l^m``, ``Y_l,-m = sqrt(8 pi) (-1)^m Im Y_l^m``. ``Pbar_lm``
follow the standard forward column recursion of Holmes & Featherstone (J. Geodesy 76, 279
(2002), eqs. 11-13), stable far beyond the degrees used here, with the factor ``sin^m theta``
carried by ``(x + i y)^m`` so that no angle is computed and the poles need no care.

Spectrum. With this normalization the mean square of ``f`` over the sphere is the sum of the
squared coefficients, and degree ``l`` contributes its "power per degree" ``S_l = sum_m
f_lm^2`` (Wieczorek & Meschede, eq. 12). The field has a flat spectrum in that sense: every
degree from 2 to L carries exactly the same power ``S_l = 1/(L - 1)``, so that ``f`` has an
rms of exactly 1 over the sphere and ``u`` an rms of ``a R``. The coefficients of degree
``l`` are a Gaussian vector of ``2l + 1`` standard normal numbers scaled to that power: its
direction is uniform on the sphere of R^(2l+1), which rotations of the shell leave
invariant (they act on each degree as orthogonal matrices), so the field is statistically
isotropic. Degree 0 (a change of volume, which the constraint removes) and degree 1 (a
translation) are left out. (Cosmology's "flat" angular power spectrum, constant
``C_l = S_l/(2l + 1)``, would put ever more power in the highest degrees.)

Cost: one pass over the ``(L + 1)(L + 2)/2`` pairs ``(l, m >= 0)``, vectorized over the
vertices (0.25 s for 160k vertices at L = 30 on one core).
"""

from __future__ import annotations

import functools
import math

import numpy as np

LOWEST_DEGREE = 2
"""Degrees 0 (a volume change the constraint removes) and 1 (a translation) are left out."""

DEFAULT_DEGREE = 20
"""Default highest degree L. It covers the classical buckling mode of every shell of the
paper's range: the critical degree is ``l_c ~ gamma^(1/4)`` (wavelength ``2 pi l_el``,
``l_el = R gamma^(-1/4)``): 7 at gamma = 2333, 13 at 29160, 18.5 at 4 x 29160 (the paper's
gamma read as four times ours); and the paper's 3594-vertex mesh (mean edge 0.063 R)
resolves its shortest wavelength ``2 pi R / L = 0.31 R`` with five edges
(:data:`EDGES_PER_WAVELENGTH`)."""

EDGES_PER_WAVELENGTH = 4
"""A mesh resolves degree L when the wavelength ``2 pi R / L`` spans at least this many mean
edges: the interpolation error of the field on the mesh is then a few % of its rms
(tests/test_imperfection.py)."""


def n_harmonics(degree: int) -> int:
    """Number of real harmonics of degrees 0..``degree``: ``(L + 1)^2``; coefficient
    ``(l, m)`` is at index ``l^2 + l + m``."""
    return (int(degree) + 1) ** 2


def harmonic_index(l, m):
    """Index of the coefficient of ``Y_lm`` in a coefficient vector (``l^2 + l + m``)."""
    return np.asarray(l) ** 2 + np.asarray(l) + np.asarray(m)


def _check_degree(degree) -> int:
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) \
            or degree < LOWEST_DEGREE:
        raise ValueError(f"the degree L of the smooth imperfection must be an integer >= "
                         f"{LOWEST_DEGREE}, got {degree!r}")
    return int(degree)


def random_coefficients(degree: int, rng: np.random.Generator) -> np.ndarray:
    """Coefficients ``((L + 1)^2,)`` of a field with a flat power per degree (module
    docstring): zero for degrees 0 and 1, and for each degree ``l = 2..L`` the direction of
    ``2l + 1`` standard normal numbers drawn from ``rng`` (all at once, degree by degree,
    ``m`` from ``-l`` to ``l``) with norm ``1/sqrt(L - 1)``. The field's rms over the sphere
    is exactly 1."""
    L = _check_degree(degree)
    out = np.zeros(n_harmonics(L))
    start = LOWEST_DEGREE ** 2
    out[start:] = rng.standard_normal(n_harmonics(L) - start)
    for l in range(LOWEST_DEGREE, L + 1):
        block = out[l * l:(l + 1) ** 2]
        block *= 1.0 / (np.sqrt(np.dot(block, block)) * np.sqrt(L - LOWEST_DEGREE + 1))
    return out


def power_per_degree(coefficients) -> np.ndarray:
    """``S_l = sum_m f_lm^2`` for ``l = 0..L``: the mean square over the sphere of each
    degree's part of the field."""
    a = np.asarray(coefficients, dtype=float)
    L = _degree_of(a)
    return np.array([np.dot(a[l * l:(l + 1) ** 2], a[l * l:(l + 1) ** 2])
                     for l in range(L + 1)])


def _degree_of(coefficients: np.ndarray) -> int:
    L = math.isqrt(len(coefficients)) - 1 if coefficients.ndim == 1 else -1
    if L < 0 or n_harmonics(L) != len(coefficients):
        raise ValueError(f"a coefficient vector holds (L + 1)^2 values, got shape "
                         f"{coefficients.shape}")
    return L


def evaluate(coefficients, directions) -> np.ndarray:
    """``f(n) = sum_lm f_lm Y_lm(n)`` at unit vectors ``directions (N, 3)``: ``(N,)``.

    For each order ``m >= 0``, ``Pbar_lm / sin^m theta`` runs up the column ``l = m..L`` by
    Holmes & Featherstone's recursion (the sectoral seed ``Pbar_mm / sin^m theta`` is a
    number); ``sin^m theta (cos m phi, sin m phi)`` is ``(x + i y)^m``. Elementwise operations
    in a fixed order, no BLAS: the same bits on any number of threads."""
    a = np.asarray(coefficients, dtype=float)
    L = _degree_of(a)
    n = np.asarray(directions, dtype=float)
    if n.ndim != 2 or n.shape[1] != 3:
        raise ValueError(f"directions must be an (N, 3) array, got shape {n.shape}")
    x, y, t = n[:, 0], n[:, 1], n[:, 2]
    f = np.zeros(len(n))
    re, im = np.ones(len(n)), np.zeros(len(n))  # (x + i y)^m
    sectoral = 1.0  # Pbar_mm / sin^m theta
    p, p1, p2 = (np.empty(len(n)) for _ in range(3))
    for m in range(L + 1):
        if m:
            re, im = re * x - im * y, re * y + im * x
            sectoral *= np.sqrt(3.0) if m == 1 else np.sqrt((2 * m + 1) / (2 * m))
        cos_part = np.full(len(n), a[harmonic_index(m, m)] * sectoral)
        sin_part = np.full(len(n), a[harmonic_index(m, -m)] * sectoral) if m else None
        p1.fill(sectoral)
        p2.fill(0.0)
        for l in range(m + 1, L + 1):
            alpha = np.sqrt((2 * l - 1) * (2 * l + 1) / ((l - m) * (l + m)))
            beta = np.sqrt((2 * l + 1) * (l + m - 1) * (l - m - 1)
                           / ((l - m) * (l + m) * (2 * l - 3))) if l > m + 1 else 0.0
            np.multiply(t, p1, out=p)
            p *= alpha
            if beta:
                p -= beta * p2
            cos_part += a[harmonic_index(l, m)] * p
            if m:
                sin_part += a[harmonic_index(l, -m)] * p
            p, p1, p2 = p2, p, p1
        f += cos_part * re
        if m:
            f += sin_part * im
    return f


def reference_sphere(X_reference) -> tuple[np.ndarray, float]:
    """Centre ``(3,)`` and radius of the sphere through the reference vertices ``(V, 3)``
    (the algebraic least-squares fit ``|x|^2 = 2 c.x + r^2 - |c|^2``, exact for vertices on
    a sphere; sums in NumPy's fixed order and a 4 x 4 solve)."""
    X = np.asarray(X_reference, dtype=float)
    design = np.column_stack([2.0 * X, np.ones(len(X))])
    rhs = np.sum(X * X, axis=1)
    normal = np.array([[np.sum(design[:, i] * design[:, j]) for j in range(4)]
                       for i in range(4)])
    c = np.linalg.solve(normal, np.array([np.sum(design[:, i] * rhs) for i in range(4)]))
    return c[:3], float(np.sqrt(c[3] + np.dot(c[:3], c[:3])))


def reference_directions(X_reference) -> np.ndarray:
    """The material point of each vertex: its unit direction ``(V, 3)`` from the centre of
    the reference sphere (:func:`reference_sphere`)."""
    centre, _ = reference_sphere(X_reference)
    d = np.asarray(X_reference, dtype=float) - centre
    return d / np.linalg.norm(d, axis=1)[:, None]


def vertex_normals(X, faces) -> np.ndarray:
    """Area-weighted unit vertex normals ``(V, 3)``: the sum of the normals of the faces at
    each vertex, each weighted by its area (``cross(x1 - x0, x2 - x0)``), normalized; outward
    for outward-oriented faces."""
    X = np.asarray(X, dtype=float)
    corners = X[faces]
    weighted = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    out = np.zeros_like(X)
    for k in range(3):
        for corner in range(3):
            out[:, k] += np.bincount(faces[:, corner], weighted[:, k], minlength=len(X))
    return out / np.linalg.norm(out, axis=1)[:, None]


def smooth_displacement(X, faces, directions, amplitude: float, degree: int,
                        rng: np.random.Generator) -> np.ndarray:
    """The displacements ``(V, 3)`` of one smooth imperfection: ``amplitude f(n) N(X)`` with
    ``f`` drawn from ``rng`` (:func:`random_coefficients`, degrees 2..``degree``, rms 1),
    evaluated at the material points ``directions`` (:func:`reference_directions`), along the
    vertex normals ``N`` of the current positions ``X`` (:func:`vertex_normals`). The rms
    normal displacement over the sphere is ``amplitude`` (a length)."""
    f = evaluate(random_coefficients(degree, rng), directions)
    return (float(amplitude) * f)[:, None] * vertex_normals(X, faces)


def smooth_jiggle(X, faces, directions, amplitude: float, degree: int,
                  rng: np.random.Generator) -> np.ndarray:
    """``X`` plus :func:`smooth_displacement`; no random numbers are drawn for
    ``amplitude = 0`` (as :func:`.jiggle.jiggle`)."""
    X = np.asarray(X, dtype=float)
    if amplitude == 0:
        return X.copy()
    return X + smooth_displacement(X, faces, directions, amplitude, degree, rng)


# ------------------------------------------------------------------ shape imperfection

CRITICAL = "critical"
"""The shape degree that covers a shell's classical buckling band:
:func:`critical_shape_degree`."""


def buckling_degree(gamma_effective: float) -> float:
    """The degree ``l_c`` of the classical buckling mode of a sphere with FvK number
    ``gamma_effective = A R^2 / kappa_H``: ``l_c (l_c + 1) = sqrt(gamma_effective)``. The
    pressure at which degree ``l`` buckles is ``p_l = (2/R^3) (kappa_H lambda + A R^2/lambda)``,
    ``lambda = l (l + 1)`` (the large-``l`` form of Zoelly's result; Hutchinson, J. Appl. Mech.
    34, 49 (1967)), least at ``lambda = sqrt(gamma)`` where it is ``p_c = 4 sqrt(kappa_H A)/R^2``
    (:func:`shellbuckle.theory.classical_threshold`). 6.47 at gamma = 2333, 12.6 at 29160."""
    lam = math.sqrt(float(gamma_effective))
    return (math.sqrt(1.0 + 4.0 * lam) - 1.0) / 2.0


def critical_shape_degree(gamma_effective: float) -> int:
    """The highest degree of a shape imperfection that contains the classical buckling band:
    ``ceil(l_c) + 1`` (:func:`buckling_degree`), at least :data:`LOWEST_DEGREE`. 8 at gamma =
    2333, 12 at 15163, 14 at 29160 (under the ``paper`` convention, gamma_eff = 4 gamma: 11,
    17, 19)."""
    return max(LOWEST_DEGREE, math.ceil(buckling_degree(gamma_effective)) + 1)


SHAPE_STREAM = 0x5348415045
"""The random stream of the shape imperfection is ``default_rng([seed, SHAPE_STREAM])``
(the steps' jiggles draw from ``[seed, step]``, ``[seed, step, attempt]``)."""


def shape_coefficients(degree: int, seed: int) -> np.ndarray:
    """The coefficients of the shape imperfection of a run with this ``seed``
    (:func:`random_coefficients` from the stream ``[seed, SHAPE_STREAM]``): the same field,
    and so the same shell, on every mesh made with that seed."""
    return random_coefficients(degree, np.random.default_rng([int(seed), SHAPE_STREAM]))


def _fd_step(degree: int) -> float:
    """Step of the central differences of :func:`radial_graph_curvature` on the unit sphere:
    their relative error is about ``(L delta)^2 / 12`` (3e-5), their round-off
    ``1e-16 / delta^2`` of the field (below 1e-8 up to L = 400)."""
    return 0.02 / max(int(degree), 10)


def radial_graph_curvature(w, directions, radius: float, delta: float) -> np.ndarray:
    """Total curvature ``c = c1 + c2`` (outward normal, ``2/r`` on a sphere of radius r) of
    the surface ``x(n) = radius exp(w(n)) n`` at the unit vectors ``directions (N, 3)``;
    ``w`` maps unit vectors ``(M, 3)`` to ``(M,)``.

    With ``W(x) = w(x/|x|)`` (homogeneous of degree 0, so that its gradient at a unit vector
    is the gradient of ``w`` on the unit sphere, and its Hessian there, restricted to the
    tangent plane, the covariant Hessian of ``w``), the outward normal is ``N = (n - grad w)
    / q``, ``q = sqrt(1 + |grad w|^2)``, a function of the direction only, and

        c = div N = exp(-w) / radius * (2 / q - lap w / q + grad w . Hess w . grad w / q^3).

    The first and second derivatives of ``W`` at each direction are central differences of
    step ``delta`` (19 evaluations of ``w``)."""
    n = np.asarray(directions, dtype=float)
    N = len(n)
    eye = np.eye(3)

    def W(points):
        return w(points / np.linalg.norm(points, axis=1)[:, None])

    w0 = W(n)
    plus = [W(n + delta * eye[i]) for i in range(3)]
    minus = [W(n - delta * eye[i]) for i in range(3)]
    grad = np.column_stack([(plus[i] - minus[i]) / (2.0 * delta) for i in range(3)])
    hess = np.empty((N, 3, 3))
    for i in range(3):
        hess[:, i, i] = (plus[i] - 2.0 * w0 + minus[i]) / delta ** 2
        for j in range(i + 1, 3):
            d = delta * (eye[i] + eye[j]), delta * (eye[i] - eye[j])
            hess[:, i, j] = hess[:, j, i] = (W(n + d[0]) - W(n + d[1]) - W(n - d[1])
                                             + W(n - d[0])) / (4.0 * delta ** 2)
    grad2 = np.einsum("ni,ni->n", grad, grad)
    q = np.sqrt(1.0 + grad2)
    laplacian = np.trace(hess, axis1=1, axis2=2)
    along = np.einsum("ni,nij,nj->n", grad, hess, grad)
    return np.exp(-w0) / float(radius) * (2.0 / q - laplacian / q + along / q ** 3)


CHECK_POINTS = 20000
"""Directions of the fixed grid on which :func:`lowest_curvature` looks for the stress-free
shape's lowest curvature (a Fibonacci lattice, mean spacing 0.025 R: eight points per
wavelength at L = 30), so that whether a shape imperfection is allowed does not depend on the
mesh."""


def fibonacci_directions(n: int) -> np.ndarray:
    """``n`` nearly uniform unit vectors ``(n, 3)`` (the Fibonacci lattice of the sphere)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    r = np.sqrt(1.0 - z * z)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


@functools.lru_cache(maxsize=64)
def lowest_curvature(amplitude: float, degree: int, seed: int) -> float:
    """The lowest total curvature of the stress-free shape of a shape imperfection, in units
    of the sphere's ``2/R``, over :data:`CHECK_POINTS` fixed directions. At or below zero the
    shape has regions of inverted curvature: dimples of its own, not an imperfect sphere
    (:func:`check_shape`)."""
    a, L = float(amplitude), _check_degree(degree)
    coefficients = shape_coefficients(L, seed)
    n = fibonacci_directions(CHECK_POINTS)
    if not (1.0 + a * evaluate(coefficients, n)).min() > 0.5:
        return -math.inf
    c = radial_graph_curvature(lambda d: np.log1p(a * evaluate(coefficients, d)), n, 1.0,
                               _fd_step(L))
    return float(0.5 * c.min())


def check_shape(amplitude: float, degree: int, seed: int) -> None:
    """``ValueError`` unless the stress-free shape of this shape imperfection has a positive
    curvature everywhere (:func:`lowest_curvature`)."""
    low = lowest_curvature(float(amplitude), int(degree), int(seed))
    if not low > 0:
        raise ValueError(
            f"a shape imperfection of rms {float(amplitude):.4g} R up to degree {int(degree)} "
            f"(seed {int(seed)}) inverts the curvature of the shell somewhere (lowest curvature "
            f"{low:.3g} times the sphere's): a dimpled shell, not an imperfect sphere; give a "
            "smaller amplitude or a lower degree (the curvature varies as the amplitude times "
            "about L^2/2)")


def stress_free_shape(X_reference, amplitude: float, degree: int, seed: int):
    """The stress-free shape of a shell with a shape imperfection, and its curvature.

    The surface ``x(n) = c + R (1 + a f(n)) n`` over the reference sphere (centre ``c``,
    radius ``R``, :func:`reference_sphere`), with ``f`` the field of :func:`shape_coefficients`
    (rms 1 over the sphere, degrees 2 to ``degree``) and ``a = amplitude`` (the rms of the
    radial displacement in units of R). Returns the positions ``(V, 3)`` of the vertices at
    their material points (:func:`reference_directions`), the rest state of the stretching
    energy, and the profile ``(V,)`` of the spontaneous curvature: the exact total curvature
    of that surface at each material point (:func:`radial_graph_curvature`) divided by
    ``2/R``, so that ``c0 = 2/R`` makes the bending energy vanish on the smooth surface, as it
    does on the reference sphere, whatever the mesh."""
    centre, R = reference_sphere(X_reference)
    n = reference_directions(X_reference)
    a, L = float(amplitude), _check_degree(degree)
    coefficients = shape_coefficients(L, seed)
    f = evaluate(coefficients, n)
    if not (1.0 + a * f).min() > 0.5:
        raise ValueError(f"a shape imperfection of rms {a:g} R pulls the surface to "
                         f"{(1.0 + a * f).min():.3g} R of the centre: not an imperfection "
                         "(keep it above 0.5 R)")
    X = centre + (R * (1.0 + a * f))[:, None] * n
    curvature = radial_graph_curvature(lambda d: np.log1p(a * evaluate(coefficients, d)), n, R,
                                       _fd_step(L))
    return X, 0.5 * R * curvature
