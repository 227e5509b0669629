"""The rim of a dent as curves: extraction, Fourier spectrum, apices, concavity, wrinkles W.

Two closed curves around the dent axis are traced, in the dent frame (origin ``o`` on the axis,
unit axis ``u`` pointing out of the dent, see :mod:`.descriptors`), each sampled by ``K``
rays from the axis at azimuths ``phi_k = 2 pi k / K`` (:func:`rim_samples`: at least
``RAYS_PER_EDGE`` rays per mean edge length along ``2 pi R_area``, so a fine mesh is sampled as
finely as a coarse one):

Crest (the geometric rim)
-------------------------
Let ``rhohat_i`` be the unit vector from the axis to vertex ``i`` (perpendicular to ``u``) and
``n_i`` the vertex normal (smoothed over a short length, see the constants). The dent's wall
faces the axis, ``n . rhohat < 0``; the outer shell faces away from it, ``n . rhohat > 0``. The
*bowl* is the connected region of vertices with ``n . rhohat < 0`` that contains the dent, and
the *crest* is its outer boundary: the ridge where the normal's radial tilt changes sign, i.e.
the highest points of the shell along the axis; for mirror buckling, the circle where the
inverted cap meets the rest of the sphere (radius ``R sin(alpha)``). The zero crossing of
``n . rhohat`` is interpolated linearly on every edge leaving the bowl; the two crossings in
each face leaving it form a segment; the segments, projected on the plane normal to ``u``, are
cut by the rays, and the outermost cut of each ray gives ``rho(phi_k)`` and the height
``z(phi_k)``. The frame is refined twice: ``u`` becomes the unit vector area ``sum A_i n_i`` of
the bowl (the normal of the crest's plane, by Stokes) and ``o`` moves to the centroid of the
area enclosed by the projected crest. If a ray misses the crest (the bowl does not surround
the axis) the dent has no rim.

Outline (the limit of the depression)
-------------------------------------
The outer boundary of the dent itself, the zero crossing of the smoothed mean curvature
(:mod:`.descriptors`), traced in the same frame in the same way. This is the curve the paper
looks at: loss of axisymmetry "when the rim of the depression becomes polygonal", then wrinkles
when "the inner part of the rim becomes convex between two successive apices" (the "limits of
the depression concave between the apices"; Quilliet et al. 2008, §4.3-4.4). On a polygonal
dent the apices of the outline are the sharp tips of the inverted region at the corners (the
d-cone tips), which the rounded crest may hardly show. On a smooth dent the outline lies
inside the crest, by about the half-width of the ridge plus the curvature smoothing.

Spectrum
--------
``rho(phi) = c_0 + sum_m (a_m cos m phi + b_m sin m phi)``; ``spectrum[m - 1] =
sqrt(a_m^2 + b_m^2) / c_0`` for ``m = 1 .. N_MODES``: a curve ``r0 (1 + eps cos(m phi))`` has
``spectrum[m - 1] = eps``. The amplitudes do not depend on where ``phi = 0`` is, so they are
invariant to rotations of the shell. ``m = 1`` measures an off-centre frame and is not used
for axisymmetry.

Apices, concavity and W
-----------------------
``rho`` is smoothed with a periodic Gaussian of standard deviation ``ell`` in arc length
(``ell / radius`` in azimuth, applied to the Fourier coefficients), with
``ell = max(RIM_SMOOTHING_LENGTH R_area, RIM_SMOOTHING_EDGES h)`` (``h`` the mean edge length):
a physical length, raised to the mesh resolution on coarse meshes, where shorter details are
discretization noise. *Apices* are the local maxima of the smoothed ``rho`` whose topographic
prominence is at least ``APEX_PROMINENCE`` times the radius and ``APEX_RELATIVE`` times the
largest prominence; each is placed between the samples (the vertex of the parabola through the
three samples about the maximum).

The arc between two successive apices is *concave* when it dips inside the chord joining them:
``arc_sagitta``, the largest distance of the arc inside the chord (on the side of the axis)
divided by the chord's length, exceeds ``CONCAVITY``, and that distance exceeds
``CONCAVITY_EDGES h`` (the noise of the traced curve). A straight side gives 0, a convex one 0
(no point inside), a star-shaped outline its depth between the tips. This is the paper's
"limits of the depression concave between the apices" read on positions only: scale-free (the
same fraction of the chord for any ``m`` and any rim radius) and far less noisy than a
curvature: on the straight-sided outlines of polygonal dents with 8 to 10 corners on
10242-vertex meshes the mean ``kappa * radius`` of the middle of a side scatters down to -0.6,
their sagitta stays 0 (docs/analysis.md). The number of wrinkles
``W`` is the number of apices of an outline on which at least ``WRINKLED_FRACTION`` of the arcs
are concave (:mod:`.classify`). ``arc_curvature`` (the mean ``kappa * radius`` over the middle
``ARC_WINDOW`` of the arc, ``kappa = (rho^2 + 2 rho'^2 - rho rho'') / (rho^2 + rho'^2)^(3/2)``)
is reported but not used.

Resolution
----------
The outline is the zero line of ``H`` smoothed over ``ell_H`` and then smoothed over ``ell``
along itself; apices closer than ``APEX_SPACING sqrt(ell_H^2 + ell^2)`` along it (the crest:
the normals' smoothing instead of ``ell_H``) are not resolved. :attr:`Curve.count_resolved`
says whether a count can be trusted: no two successive apices closer than that, and no mode
of the curve above the count ``MODE_DOMINANCE`` times stronger than the count's own (a finer
pattern found in part) nor a mode below it ``LOWER_MODE_DOMINANCE`` times stronger (spurious
apices on a coarser shape). An untrusted count is not reported (:mod:`.classify`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Rays from the axis at which the rim is sampled (uniform in azimuth): at least RIM_SAMPLES,
#: and at least RAYS_PER_EDGE per mean edge length along the circumference 2 pi R_area (rounded
#: up to a power of two), so that fine meshes are sampled as finely as coarse ones.
RIM_SAMPLES = 256
RAYS_PER_EDGE = 4
#: Number of Fourier modes of the rim reported, m = 1 .. N_MODES.
N_MODES = 20
#: Smoothing of the rim curve, standard deviation in arc length, in units of R_area ...
RIM_SMOOTHING_LENGTH = 0.04
#: ... but at least this many mean edge lengths (below the mesh resolution the rim is noise).
RIM_SMOOTHING_EDGES = 0.75
#: An apex is a maximum of the smoothed rim radius with a prominence of at least APEX_PROMINENCE
#: times the rim radius and at least APEX_RELATIVE times the largest prominence on the rim.
APEX_PROMINENCE = 0.01
APEX_RELATIVE = 0.1
#: Vertex normals are smoothed over max(NORMAL_SMOOTHING_LENGTH R_area, NORMAL_SMOOTHING_EDGES h)
#: before the crest is located (diffusion on the surface, :meth:`Geometry.smooth`).
NORMAL_SMOOTHING_LENGTH = 0.02
NORMAL_SMOOTHING_EDGES = 0.5
#: The window of an arc in which its mean curvature ``arc_curvature`` is measured (reported, not
#: used to classify): this fraction of the arc, centred on the arc's innermost point.
ARC_WINDOW = 0.5
#: An arc between two successive apices is concave when it dips inside the chord joining them
#: by more than CONCAVITY times the chord (``arc_sagitta``) and by more than CONCAVITY_EDGES
#: mean edge lengths (the noise of the traced curve). A straight or convex side gives 0.
#: Calibration: docs/analysis.md.
CONCAVITY = 0.005
CONCAVITY_EDGES = 0.05
#: Resolution: apices closer than APEX_SPACING blur lengths (along the smoothed curve) are not
#: resolved, the blur length being sqrt(ell_field^2 + ell^2) with ell_field the smoothing of
#: the field whose zero line is the curve (H for the outline, the normals for the crest) and
#: ell the smoothing of the curve itself. A count n is also not trusted when a mode above n
#: (up to N_MODES, or the highest mode resolved if that is more) is MODE_DOMINANCE times
#: stronger than mode n (the apices of a finer pattern were partly missed), or a mode between
#: 2 and n - 1 is LOWER_MODE_DOMINANCE times stronger (spurious apices on a coarser shape).
#: Calibration: docs/analysis.md.
APEX_SPACING = 3.0
MODE_DOMINANCE = 2.0
LOWER_MODE_DOMINANCE = 4.0
#: Refinements of the dent frame (axis from the bowl's vector area, origin at the rim centroid).
FRAME_ITERATIONS = 2


@dataclass(frozen=True, eq=False)
class Curve:
    """A closed curve around the dent axis and its analysis (module docstring).

    ``phi (K,)`` azimuths, ``rho (K,)`` distances from the axis, ``z (K,)`` heights along it;
    ``smoothing_length``, ``rho_smooth (K,)``, ``curvature (K,)`` (``kappa * radius``),
    ``spectrum (N_MODES,)`` and ``amplitudes (K // 2,)`` (relative amplitudes of the modes
    ``m = 1, 2, ...``), ``apices (n,)`` (indices into ``phi``), ``prominences (n,)``
    (relative to the radius); per arc from apex ``j`` to apex ``j + 1`` (cyclically; empty with
    fewer than two apices): ``arc_curvature (n,)`` (mean ``kappa * radius`` in the middle
    window), ``arc_chord (n,)`` (distance between the two apices), ``arc_sagitta (n,)`` (how far
    the arc dips inside that chord, relative to it; 0 for a straight or convex side) and
    ``spacing (n,)`` (arc length along the smoothed curve). ``resolution``: the smallest apex
    spacing resolved (a length); ``depth_floor``: the smallest depth ``arc_sagitta * arc_chord``
    of a concave arc (the noise of the curve).
    """

    phi: np.ndarray
    rho: np.ndarray
    z: np.ndarray
    smoothing_length: float
    rho_smooth: np.ndarray
    curvature: np.ndarray
    spectrum: np.ndarray
    amplitudes: np.ndarray
    apices: np.ndarray
    prominences: np.ndarray
    arc_curvature: np.ndarray
    arc_chord: np.ndarray
    arc_sagitta: np.ndarray
    spacing: np.ndarray
    resolution: float = 0.0
    depth_floor: float = 0.0

    @classmethod
    def analysed(cls, phi, rho, z, smoothing_length: float, resolution: float = 0.0,
                 depth_floor: float = 0.0) -> "Curve":
        return cls(phi=phi, rho=rho, z=z, smoothing_length=float(smoothing_length),
                   resolution=float(resolution), depth_floor=float(depth_floor),
                   **rim_shape(rho, smoothing_length))

    @property
    def radius(self) -> float:
        return float(self.rho.mean())

    @property
    def height(self) -> float:
        return float(self.z.mean())

    @property
    def n_apices(self) -> int:
        return int(len(self.apices))

    @property
    def concave(self) -> np.ndarray:
        """``(n,)`` bool: the arcs that dip inside their chord (:data:`CONCAVITY`)."""
        return ((self.arc_sagitta > CONCAVITY)
                & (self.arc_sagitta * self.arc_chord > self.depth_floor))

    @property
    def n_concave(self) -> int:
        return int(self.concave.sum())

    @property
    def dominant_mode(self) -> int:
        """The mode ``m >= 2`` of largest amplitude."""
        return int(np.argmax(self.spectrum[1:]) + 2)

    @property
    def dominant_amplitude(self) -> float:
        return float(self.spectrum[1:].max())

    @property
    def max_resolved_mode(self) -> int:
        """The highest mode whose wavelength along the curve, ``2 pi radius / m``, is at least
        the ``resolution``."""
        if self.resolution <= 0:
            return len(self.amplitudes)
        return int(min(len(self.amplitudes), 2.0 * math.pi * self.radius // self.resolution))

    @property
    def count_resolved(self) -> bool:
        """Whether the number of apices can be trusted: every two successive apices are at least
        ``resolution`` apart along the curve, and no resolved mode above ``n_apices`` is
        :data:`MODE_DOMINANCE` times stronger than mode ``n_apices`` (a finer pattern whose
        apices were only partly found). True with fewer than two apices (nothing counted)."""
        n = self.n_apices
        if n < 2:
            return True
        if self.spacing.min() < self.resolution:
            return False
        own = self.amplitudes[n - 1]
        higher = self.amplitudes[n:max(self.max_resolved_mode, N_MODES)]
        lower = self.amplitudes[1:n - 1]
        return not ((len(higher) and higher.max() > MODE_DOMINANCE * own)
                    or (len(lower) and lower.max() > LOWER_MODE_DOMINANCE * own))


@dataclass(frozen=True, eq=False)
class Rim:
    """The rim of a dent: frame, bowl, crest and outline (module docstring).

    Frame: ``origin (3,)``, unit ``axis (3,)`` out of the dent, ``e1``, ``e2`` completing a
    right-handed basis (``phi`` measured from ``e1`` towards ``e2``). ``bowl (V,)`` bool: the
    vertices of the bowl. ``crest`` and ``outline``: :class:`Curve`.
    """

    origin: np.ndarray
    axis: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    bowl: np.ndarray
    crest: Curve
    outline: Curve

    def cylindrical(self, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(rho, phi, z)`` of ``points (n, 3)`` in the dent frame (``phi`` in [0, 2 pi))."""
        rel = np.asarray(points, dtype=np.float64) - self.origin
        x, y, z = rel @ self.e1, rel @ self.e2, rel @ self.axis
        return np.hypot(x, y), np.mod(np.arctan2(y, x), 2.0 * np.pi), z

    def encloses(self, points, normals) -> np.ndarray:
        """Whether each of ``points (n, 3)`` with unit outward ``normals (n, 3)`` is a point of
        the depression's surface: inside the crest seen along the axis, below it
        (``rho < rho_crest(phi)`` and ``z < z_crest(phi)``, the crest interpolated linearly in
        ``phi``) and facing out of the dent (``n . axis > 0``; the far side of the shell,
        also inside and below the crest, faces the other way)."""
        rho, phi, z = self.cylindrical(points)
        K = len(self.crest.phi)
        t = phi / (2.0 * np.pi) * K
        k = np.floor(t).astype(np.int64) % K
        f = t - np.floor(t)
        k1 = (k + 1) % K
        rho_c = (1 - f) * self.crest.rho[k] + f * self.crest.rho[k1]
        z_c = (1 - f) * self.crest.z[k] + f * self.crest.z[k1]
        return (rho < rho_c) & (z < z_c) & (np.asarray(normals) @ self.axis > 0)


def _basis(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.zeros(3)
    a[int(np.argmin(np.abs(u)))] = 1.0
    e1 = np.cross(u, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(u, e1)


def _unit(v):
    n = np.linalg.norm(v)
    return v / n if n > 0 else v


def _envelope(A2, B2, zA, zB, phi):
    """Outermost cut of the segments ``A2 -> B2`` (``(S, 2)``, heights ``zA``, ``zB``) by rays
    from the origin at azimuths ``phi (K,)``: radii and heights ``(K,)``, NaN where none.

    For rays uniform in azimuth (``phi = 2 pi k / K``) each segment is tested only against the
    rays within its azimuth span (and one more on each side), so the cost is the number of
    segment-ray crossings rather than ``K S``; the tests and the choice among them (the largest
    radius, the first segment on a tie) are those of :func:`_envelope_dense`, bit for bit."""
    K, S = len(phi), len(A2)
    if K == 0 or S == 0 or not np.array_equal(phi, 2.0 * np.pi * np.arange(K) / K):
        return _envelope_dense(A2, B2, zA, zB, phi)
    pa = np.arctan2(A2[:, 1], A2[:, 0])
    span = np.remainder(np.arctan2(B2[:, 1], B2[:, 0]) - pa + np.pi, 2.0 * np.pi) - np.pi
    lo = np.minimum(pa, pa + span)
    k0 = np.floor(lo * K / (2.0 * np.pi)).astype(np.int64) - 1
    k1 = np.ceil((lo + np.abs(span)) * K / (2.0 * np.pi)).astype(np.int64) + 1
    count = k1 - k0 + 1
    # A segment through (or ending at) the origin, or as wide as half a turn: every ray.
    every = ((np.abs(span) > np.pi - 1e-6) | ~(A2 != 0).any(axis=1) | ~(B2 != 0).any(axis=1)
             | (count >= K))
    k0[every], count[every] = 0, K
    seg = np.repeat(np.arange(S), count)
    start = np.cumsum(count) - count
    ray = np.remainder(np.repeat(k0, count) + np.arange(int(count.sum())) - np.repeat(start, count),
                       K)
    d = np.stack([np.cos(phi), np.sin(phi)], axis=1)[ray]
    delta = B2[seg] - A2[seg]
    a = A2[seg]
    den = delta[:, 0] * d[:, 1] - delta[:, 1] * d[:, 0]
    num = a[:, 0] * d[:, 1] - a[:, 1] * d[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -num / den
        r = ((a + t[:, None] * delta) * d).sum(axis=-1)
    valid = (den != 0) & (t >= 0) & (t <= 1) & (r > 0)
    seg, ray, t, r = seg[valid], ray[valid], t[valid], r[valid]
    order = np.lexsort((seg, -r, ray))  # per ray: the largest radius, then the first segment
    first = order[np.r_[True, ray[order][1:] != ray[order][:-1]]] if len(order) else order
    rho = np.full(K, np.nan)
    z = np.full(K, np.nan)
    k = seg[first]
    rho[ray[first]] = r[first]
    z[ray[first]] = zA[k] + t[first] * (zB[k] - zA[k])
    return rho, z


def _envelope_dense(A2, B2, zA, zB, phi):
    """:func:`_envelope` by testing every ray against every segment (any azimuths)."""
    d = np.stack([np.cos(phi), np.sin(phi)], axis=1)[:, None, :]  # (K, 1, 2)
    delta = (B2 - A2)[None]
    den = delta[..., 0] * d[..., 1] - delta[..., 1] * d[..., 0]
    num = A2[None, :, 0] * d[..., 1] - A2[None, :, 1] * d[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -num / den
        r = ((A2[None] + t[..., None] * delta) * d).sum(axis=-1)
    valid = (den != 0) & (t >= 0) & (t <= 1) & (r > 0)
    r = np.where(valid, r, -np.inf)
    k = np.argmax(r, axis=1)
    rows = np.arange(len(phi))
    rho = r[rows, k]
    missing = ~np.isfinite(rho)
    tk = np.where(missing, 0.0, t[rows, k])
    z = zA[k] + tk * (zB[k] - zA[k])
    rho[missing] = np.nan
    z[missing] = np.nan
    return rho, z


def _crossings(geom, topology, bowl, n_rho):
    """Boundary segments of the vertex set ``bowl``: for every face leaving it, the two zero
    crossings of the field ``n_rho`` (negative inside) interpolated on its edges that leave it.
    Returns ``(S, 2, 3)`` end points."""
    e = topology.edges
    boundary = bowl[e[:, 0]] != bowl[e[:, 1]]
    inner = np.where(bowl[e[:, 0]], e[:, 0], e[:, 1])
    outer = np.where(bowl[e[:, 0]], e[:, 1], e[:, 0])
    a, b = n_rho[inner], n_rho[outer]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip(np.where(b - a > 0, -a / (b - a), 0.0), 0.0, 1.0)
    X = geom.X
    points = X[inner] + t[:, None] * (X[outer] - X[inner])
    fe = topology.face_edges
    hit = boundary[fe]
    faces = np.flatnonzero(hit.sum(axis=1) == 2)
    pick = np.sort(np.where(hit[faces], fe[faces], -1), axis=1)[:, 1:]  # the two boundary edges
    return points[pick]


def rim_samples(R_area: float, mean_edge: float) -> int:
    """Number of rays: at least :data:`RIM_SAMPLES` and :data:`RAYS_PER_EDGE` per mean edge
    length along ``2 pi R_area``, rounded up to a power of two."""
    need = RAYS_PER_EDGE * 2.0 * math.pi * R_area / mean_edge
    return max(RIM_SAMPLES, 1 << int(math.ceil(math.log2(max(need, 1.0)))))


def find_rim(geom, topology, dent, components, samples: int | None = None):
    """Rim of ``dent`` (:class:`shellbuckle.analysis.descriptors.Dent`) on the conformation
    ``geom`` (:class:`~shellbuckle.analysis.descriptors.Geometry`, whose ``H_smooth`` defines
    the dent), or ``None`` if the bowl or the dent does not surround the dent's axis.
    ``components(mask)`` labels connected vertex sets (:meth:`ShapeAnalyzer.components`).
    ``samples``: number of rays (default :func:`rim_samples`)."""
    if samples is None:
        samples = rim_samples(geom.R_area, geom.mean_edge)
    X = geom.X
    in_dent = np.zeros(len(X), dtype=bool)
    in_dent[dent.vertices] = True
    u, o = dent.axis, dent.centre.copy()
    n_length = max(NORMAL_SMOOTHING_LENGTH * geom.R_area, NORMAL_SMOOTHING_EDGES * geom.mean_edge)
    normal = geom.smooth(geom.vertex_normal, n_length)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    phi = 2.0 * np.pi * np.arange(samples) / samples
    for it in range(FRAME_ITERATIONS + 1):
        e1, e2 = _basis(u)
        rel = X - o
        z = rel @ u
        P = rel - z[:, None] * u
        rho = np.linalg.norm(P, axis=1)
        rhat = np.divide(P, rho[:, None], out=np.zeros_like(P), where=rho[:, None] > 0)
        n_rho = (normal * rhat).sum(axis=1)
        labels = components(n_rho < 0.0)
        hit = np.unique(labels[in_dent & (labels >= 0)])
        bowl = np.isin(labels, hit) & (labels >= 0) | in_dent
        r, zr = _trace(geom, topology, bowl, n_rho, o, u, e1, e2, phi)
        if r is None:
            return None
        if it == FRAME_ITERATIONS:
            break
        # refine: axis normal to the rim's plane, origin at the projected rim's area centroid
        x, y = r * np.cos(phi), r * np.sin(phi)
        xn, yn = np.roll(x, -1), np.roll(y, -1)
        cross = x * yn - xn * y
        area2 = cross.sum()
        cx, cy = ((x + xn) * cross).sum() / (3 * area2), ((y + yn) * cross).sum() / (3 * area2)
        o = o + cx * e1 + cy * e2
        w = geom.vertex_area[bowl]
        u = _unit((w[:, None] * normal[bowl]).sum(axis=0))
    ro, zo = _trace(geom, topology, in_dent, geom.H_smooth, o, u, e1, e2, phi)
    if ro is None:
        return None
    length = max(RIM_SMOOTHING_LENGTH * geom.R_area, RIM_SMOOTHING_EDGES * geom.mean_edge)
    floor = CONCAVITY_EDGES * geom.mean_edge
    return Rim(origin=o, axis=u, e1=e1, e2=e2, bowl=bowl,
               crest=Curve.analysed(phi, r, zr, length, resolution(n_length, length), floor),
               outline=Curve.analysed(phi, ro, zo, length,
                                      resolution(geom.H_smoothing_length, length), floor))


def resolution(field_smoothing: float, curve_smoothing: float) -> float:
    """Smallest apex spacing resolved on a curve traced as the zero line of a field smoothed
    over ``field_smoothing`` and then smoothed over ``curve_smoothing`` along itself:
    :data:`APEX_SPACING` times the combined blur ``sqrt(field^2 + curve^2)``."""
    if not math.isfinite(field_smoothing):
        field_smoothing = 0.0
    return APEX_SPACING * math.hypot(field_smoothing, curve_smoothing)


def _trace(geom, topology, region, field, o, u, e1, e2, phi):
    """Outer boundary of the vertex set ``region`` (where ``field < 0``) cut by the rays:
    ``(rho (K,), z (K,))``, or ``(None, None)`` if some ray misses it."""
    seg = _crossings(geom, topology, region, field)
    if len(seg) == 0:
        return None, None
    rel = seg - o
    A2 = np.stack([rel[:, 0] @ e1, rel[:, 0] @ e2], axis=1)
    B2 = np.stack([rel[:, 1] @ e1, rel[:, 1] @ e2], axis=1)
    r, z = _envelope(A2, B2, rel[:, 0] @ u, rel[:, 1] @ u, phi)
    if not np.isfinite(r).all():
        return None, None
    return r, z


def rim_shape(rho, smoothing_length: float) -> dict:
    """Spectrum, smoothed curve, curvature, apices and arcs of a rim ``rho (K,)`` sampled
    uniformly in azimuth (module docstring). ``smoothing_length`` in the units of ``rho``.
    Returns a dict with ``rho_smooth``, ``curvature``, ``spectrum``, ``amplitudes``,
    ``apices``, ``prominences``, ``arc_curvature``, ``arc_chord``, ``arc_sagitta``,
    ``spacing``."""
    rho = np.asarray(rho, dtype=np.float64)
    K = len(rho)
    c = np.fft.rfft(rho) / K
    c0 = c[0].real
    amplitudes = 2.0 * np.abs(c[1:]) / c0
    m = np.arange(len(c))
    sigma = smoothing_length / c0
    cs = c * np.exp(-0.5 * (m * sigma) ** 2)
    r = np.fft.irfft(cs * K, n=K)
    r1 = np.fft.irfft(1j * m * cs * K, n=K)
    r2 = np.fft.irfft(-(m ** 2) * cs * K, n=K)
    kappa = (r * r + 2 * r1 * r1 - r * r2) / (r * r + r1 * r1) ** 1.5 * c0
    apices, prominences = _periodic_peaks(r, APEX_PROMINENCE * c0)
    if len(apices):
        keep = prominences >= APEX_RELATIVE * prominences.max()
        apices, prominences = apices[keep], prominences[keep]
    # tangent angle psi = phi + beta, beta = angle from the radial direction to the tangent
    phi = 2.0 * np.pi * np.arange(K) / K
    psi = np.unwrap(phi + np.arctan2(r, r1))
    ds = np.sqrt(r * r + r1 * r1) * (2.0 * np.pi / K)
    s = np.concatenate([[0.0], np.cumsum(ds)])  # arc length from sample 0, (K + 1,)
    points = np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)
    n = len(apices) if len(apices) >= 2 else 0
    arcs, chords, sagittas, spacing = (np.zeros(n) for _ in range(4))
    # apices between the samples (parabola through the three samples about each maximum),
    # their points from the smoothed series and their arc length from the nearest sample
    shift = _vertex_offset(r[(apices - 1) % K], r[apices], r[(apices + 1) % K])
    tip_phi = (apices + shift) * (2.0 * np.pi / K)
    tip_r = c0 + 2.0 * (cs[1:, None] * np.exp(1j * np.outer(m[1:], tip_phi))).real.sum(axis=0)
    tips = np.stack([tip_r * np.cos(tip_phi), tip_r * np.sin(tip_phi)], axis=1)
    tip_s = s[apices] + shift * ds[apices]
    for j in range(n):
        k = (j + 1) % len(apices)
        idx = _arc(apices[j], apices[k], K)
        centre = int(np.argmin(r[idx]))
        half = max(1, int(round(0.5 * ARC_WINDOW * (len(idx) - 1))))
        lo, hi = centre - half, centre + half
        window = np.arange(idx[0] + lo, idx[0] + hi + 1)
        turn = (psi[window[-1] % K] - psi[window[0] % K]
                + 2.0 * np.pi * ((window[-1] // K) - (window[0] // K)))
        arcs[j] = turn / ds[window[:-1] % K].sum() * c0
        chords[j], sagittas[j] = _sagitta(np.concatenate([tips[j:j + 1], points[idx[1:-1]],
                                                          tips[k:k + 1]]))
        spacing[j] = (tip_s[k] - tip_s[j]) % s[-1] or s[-1]
    return dict(rho_smooth=r, curvature=kappa, spectrum=amplitudes[:N_MODES].copy(),
                amplitudes=amplitudes, apices=apices, prominences=prominences / c0,
                arc_curvature=arcs, arc_chord=chords, arc_sagitta=sagittas, spacing=spacing)


def _vertex_offset(left, centre, right):
    """Offset, in samples, of the vertex of the parabola through three equally spaced samples
    from the middle one (in [-0.5, 0.5] at a maximum)."""
    den = left - 2.0 * centre + right
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(den < 0, 0.5 * (left - right) / den, 0.0)
    return np.clip(out, -0.5, 0.5)


def _sagitta(points: np.ndarray) -> tuple[float, float]:
    """Chord length between the ends of the arc ``points (n, 2)`` (traversed counterclockwise
    about the origin) and the largest distance of the arc inside the chord (on its left, the
    side of the axis for a curve around it), relative to the chord; 0 when no point is."""
    a, b = points[0], points[-1]
    chord = b - a
    length = float(np.hypot(*chord))
    if length == 0.0:
        return 0.0, 0.0
    rel = points - a
    left = (chord[0] * rel[:, 1] - chord[1] * rel[:, 0]) / length
    return length, max(0.0, float(left.max())) / length


def _arc(i: int, j: int, K: int) -> np.ndarray:
    """Sample indices from ``i`` to ``j`` going forward cyclically (both included)."""
    return np.arange(i, i + ((j - i) % K or K) + 1) % K


def _periodic_peaks(r: np.ndarray, prominence: float):
    """Maxima of a periodic signal with topographic prominence >= ``prominence``: indices
    (sorted) and prominences. The signal is rotated to start at its global minimum, where no
    peak can be, so the prominence of every peak is the periodic one."""
    K = len(r)
    start = int(np.argmin(r))
    rolled = np.concatenate([np.roll(r, -start), [r[start]]])
    peaks, prominences = _prominent_peaks(rolled, prominence)
    idx = (peaks + start) % K
    order = np.argsort(idx)
    return idx[order], prominences[order]


def _prominent_peaks(x: np.ndarray, prominence: float) -> tuple[np.ndarray, np.ndarray]:
    """Local maxima of ``x`` (a flat top counts once, at its middle; the end samples never)
    with topographic prominence ``>= prominence``: indices (ascending) and prominences, as
    ``scipy.signal.find_peaks(x, prominence=prominence)`` defines them (without importing
    ``scipy.signal``, a second of start-up). The prominence of a peak is its height above the
    higher of the two lowest points reached on each side before a higher sample or the end."""
    x = np.asarray(x, dtype=np.float64)
    n = len(x)
    peaks = []
    i = 1
    while i < n - 1:
        if x[i - 1] < x[i]:
            ahead = i + 1
            while ahead < n - 1 and x[ahead] == x[i]:
                ahead += 1
            if x[ahead] < x[i]:
                peaks.append((i + ahead - 1) // 2)
                i = ahead
        i += 1
    peaks = np.asarray(peaks, dtype=np.intp)
    prom = np.empty(len(peaks))
    for j, p in enumerate(peaks):
        higher = np.flatnonzero(x[:p] > x[p])
        left = x[(higher[-1] + 1 if len(higher) else 0):p + 1].min()
        higher = np.flatnonzero(x[p + 1:] > x[p])
        right = x[p:(p + 1 + higher[0] if len(higher) else n)].min()
        prom[j] = x[p] - max(left, right)
    keep = prom >= prominence
    return peaks[keep], prom[keep]


def rim_summary(rim: Rim | None) -> dict:
    """Flat JSON-able rim descriptors (NaN/None without a rim): ``crest_*`` for the crest,
    ``rim_*`` for the outline of the depression."""
    if rim is None:
        return {"crest_radius": math.nan, "crest_height": math.nan, "crest_spectrum": None,
                "rim_radius": math.nan, "rim_spectrum": None, "rim_dominant_mode": None,
                "rim_dominant_amplitude": math.nan, "rim_apices": 0, "rim_concave_arcs": 0,
                "rim_arc_curvature": None, "rim_arc_sagitta": None, "rim_apex_spacing": None,
                "rim_resolution": math.nan, "rim_count_resolved": True,
                "rim_smoothing_length": math.nan, "rim_samples": 0}
    c, o = rim.crest, rim.outline
    return {"crest_radius": c.radius, "crest_height": c.height,
            "crest_spectrum": [float(v) for v in c.spectrum],
            "rim_radius": o.radius, "rim_spectrum": [float(v) for v in o.spectrum],
            "rim_dominant_mode": o.dominant_mode, "rim_dominant_amplitude": o.dominant_amplitude,
            "rim_apices": o.n_apices, "rim_concave_arcs": o.n_concave,
            "rim_arc_curvature": [float(v) for v in o.arc_curvature],
            "rim_arc_sagitta": [float(v) for v in o.arc_sagitta],
            "rim_apex_spacing": [float(v) for v in o.spacing],
            "rim_resolution": o.resolution, "rim_count_resolved": o.count_resolved,
            "rim_smoothing_length": o.smoothing_length, "rim_samples": len(o.phi)}
