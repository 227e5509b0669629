"""Shape descriptors of one conformation: asphericity, dents, dent frame and depth, contact.

A conformation is vertex positions ``X (V, 3)`` on a closed, outward-oriented triangulation
``faces (F, 3)``. Lengths are in the units of ``X``; thresholds are relative to the
conformation's own size ``R_area = sqrt(area / 4 pi)`` (the radius of the sphere with the
same area, which the membrane keeps to within the strain, i.e. ``R`` to a few per cent), so
the descriptors do not depend on the unit of length.

Dents (inverted-curvature regions)
----------------------------------
``H_i`` is Jülicher's mean curvature (:class:`shellbuckle.energies.bending.Bending`,
``H = (c1 + c2) / 2``, ``1/R`` on a sphere, negative where the surface is concave seen from
outside). A second derivative on a mesh is noisy at the vertex scale, so ``H`` is first
smoothed over ``max(H_SMOOTHING_LENGTH R_area, H_SMOOTHING_EDGES h)`` (``h`` the mean edge
length; :meth:`Geometry.smooth`). The vertices with ``H_smooth < 0`` split into connected
components on the edge graph of the mesh. A component is a *dent* when its area (sum of the
vertex areas ``A_i = 1/3 sum_{f at i} area_f``) is at least ``pi (MIN_DENT_RADIUS R_area)^2``;
smaller components are curvature noise. Components lying mostly inside a larger dent's
depression (inside and below its crest, :mod:`.wrinkles`) belong to it, so a depression cut
into pieces by folds counts once. A component at least half of whose area lies within
``WALL_GAP R_area`` of a larger dent's surface, across the shell's interior (the two surfaces
facing away from each other), is the far sheet of that dent's wall and
not a dimple of its own: where a deep bowl's wall runs close to the outer side of the shell
(a fold of the rim pressed against it, near self-contact), the outer side follows it and is
concave there (:meth:`ShapeAnalyzer.dents`). ``n_dimples`` is the number of dents.

Dent frame
----------
The *dent axis* ``u`` of a dent is the unit vector area of the surface bounded by its rim,
``u ∝ sum_i A_i n_i`` over the dent's bowl (``n_i`` the area-weighted vertex normals). By
Stokes, the vector area of a surface patch only depends on its boundary curve, so ``u`` is the
normal of the rim's plane, pointing out of the dent (from the body towards the opening),
whatever the depth. (The line from the body's centroid to the dent's centroid, the obvious
alternative, turns over for an inverted cap at alpha = 90 deg, i.e. dV/V = 1/2, where the two
centroids coincide.) The frame origin ``o`` is on the dent's symmetry axis: first the
area-weighted centroid of the dent, then the centroid of the area enclosed by the crest's
projection (:mod:`.wrinkles`). ``z = (x - o) . u`` is the height along the axis.

Dent depth
----------
``dent_depth`` (the indentation ``delta``): the distance along ``u`` from the deepest point
of the dent to the apex, along ``u``, of the sphere fitted by least squares to the vertices
outside the dent's bowl (the undented part of the shell). For an inverted spherical cap of
half-angle ``alpha`` on a sphere of radius ``R`` (mirror buckling) this is the displacement of
the pole, ``2 (1 - cos alpha) R``, the ``delta`` of Pogorelov's theory.
``dent_sagitta``: the height of the mean crest plane (mean ``z`` of the crest, the ridge around
the dent) above the deepest point, ``(1 - cos alpha) R`` for the inverted cap.
``crest_radius``: the mean distance of the crest from the axis, ``sin(alpha) R`` for the
inverted cap; ``rim_radius``: that of the outline of the depression (:mod:`.wrinkles`).

Other descriptors
-----------------
``asphericity``: with ``l1 <= l2 <= l3`` the eigenvalues of the area-weighted gyration tensor
``G = sum_i A_i (x_i - xbar)(x_i - xbar)^T / sum_i A_i``,
``((l1 - l2)^2 + (l2 - l3)^2 + (l3 - l1)^2) / (2 (l1 + l2 + l3)^2)``, 0 for a sphere (and
any shape with cubic symmetry), 1 for a segment. ``contact_distance``: the smallest distance
between two vertices more than two edges apart
(:meth:`shellbuckle.mesh.contact.ContactChecker.min_vertex_distance`), i.e. how close the
dent's floor has come to the opposite side.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..energies.bending import Bending
from ..mesh.topology import Topology
from . import wrinkles

#: A component of the inverted-curvature region (``H_smooth < 0``) is a dent when its area is at
#: least ``pi (MIN_DENT_RADIUS R_area)^2``. Calibration (docs/analysis.md): spheres jiggled by up
#: to 0.1 mean edge lengths and all pre-buckling steps of real runs have no vertex with
#: ``H_smooth < 0``; at 0.3 edge lengths the largest inverted patch has an equivalent radius
#: below 0.07 R; after buckling, the runs analysed so far have no inverted component besides
#: the dent. Inverted caps are detected from a half-angle of 12 deg (3594 vertices).
MIN_DENT_RADIUS = 0.1
#: A component of ``H_smooth < 0`` is the far sheet of a larger dent's wall (not a dimple) when at
#: least half of its area is within WALL_GAP R_area of that dent's vertices across the shell's
#: interior (:meth:`ShapeAnalyzer.far_sheet`). Calibration (docs/analysis.md): on the
#: 3594-vertex runs at gamma >= 15163 the concave patches of the outer side beside a deep
#: wrinkled bowl have half their area within 0.27 R of its wall (within 0.15 R at
#: self-contact); two opposite dimples whose floors touch (a biconcave disc) have half their
#: area more than 0.42 R apart.
WALL_GAP = 0.3
#: Before the sign of H is taken, H is smoothed (:meth:`Geometry.smooth`) over
#: max(H_SMOOTHING_LENGTH R_area, H_SMOOTHING_EDGES h), h the mean edge length: the discrete
#: mean curvature of a rough mesh is noisy at the vertex scale.
H_SMOOTHING_LENGTH = 0.02
H_SMOOTHING_EDGES = 1.25
#: Implicit diffusion steps of :meth:`Geometry.smooth` (more steps: closer to a Gaussian kernel).
SMOOTHING_STEPS = 4
#: Relative residual of each of those steps' conjugate-gradient solves, and their iteration limit
#: (beyond it the step is solved by sparse LU).
SMOOTHING_RTOL = 1e-12
SMOOTHING_MAXITER = 500


def _unit(v: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, norm, out=np.zeros_like(v), where=norm > 0)


@dataclass(frozen=True, eq=False)
class Geometry:
    """Per-vertex and global geometry of one conformation.

    ``X (V, 3)``; ``face_area (F,)``; ``vertex_area (V,)`` (``1/3`` of the adjacent face
    areas); ``vertex_normal (V, 3)`` unit, area-weighted mean of the outward face normals;
    ``H (V,)`` Jülicher mean curvature and ``H_smooth (V,)`` the same smoothed over
    ``H_smoothing_length = max(H_SMOOTHING_LENGTH R_area, H_SMOOTHING_EDGES mean_edge)`` (its
    sign defines the dents); ``area``, ``volume`` (enclosed, positive for outward faces),
    ``R_area = sqrt(area / 4 pi)`` and ``mean_edge`` (mean edge length); ``stiffness``, the
    cotangent stiffness matrix used by :meth:`smooth`.
    """

    X: np.ndarray
    face_area: np.ndarray
    vertex_area: np.ndarray
    vertex_normal: np.ndarray
    H: np.ndarray
    area: float
    volume: float
    R_area: float
    mean_edge: float
    stiffness: sp.csr_matrix = field(repr=False)
    H_smooth: np.ndarray = field(default=None, repr=False)
    H_smoothing_length: float = math.nan
    _systems: dict = field(default_factory=dict, repr=False)

    def smooth(self, values, length: float) -> np.ndarray:
        """``values (V,)`` or ``(V, k)`` smoothed over ``length`` by diffusion on the surface.

        ``SMOOTHING_STEPS`` implicit steps of the heat equation ``ds/dt = Laplace(s)`` (cotangent
        Laplacian: ``K`` the P1 stiffness matrix, ``M = diag(vertex_area)``),
        ``(M + tau K) s_new = M s``, ``tau = length^2 / (2 SMOOTHING_STEPS)``: on a flat region
        the result approaches a Gaussian average of standard deviation ``length`` in each
        direction, independently of the mesh. ``length <= 0`` returns the values unchanged.

        Each step is solved by conjugate gradients preconditioned by the diagonal
        (:func:`_pcg`, relative residual ``SMOOTHING_RTOL``): ``M + tau K`` is symmetric positive
        definite with a condition number of order ``1 + tau / h^2`` (``h`` the mean edge), a
        few tens for the lengths used here on meshes of up to a million vertices, so a solve is a few tens of sparse
        products instead of a sparse factorization. A solve that does not converge within
        ``SMOOTHING_MAXITER`` iterations (a degenerate mesh) is made by sparse LU instead.
        """
        f = np.asarray(values, dtype=np.float64)
        if length <= 0:
            return f
        key = float(length)
        if key not in self._systems:
            tau = key * key / (2.0 * SMOOTHING_STEPS)
            A = (sp.diags(self.vertex_area) + tau * self.stiffness).tocsr()
            self._systems[key] = [A, 1.0 / A.diagonal(), None]
        A, d_inv, lu = self._systems[key]
        s = f.reshape(len(f), -1)
        for _ in range(SMOOTHING_STEPS):
            b = self.vertex_area[:, None] * s
            s_new = None if lu is not None else _pcg(A, d_inv, b, s)
            if s_new is None:
                if lu is None:
                    from scipy.sparse.linalg import splu

                    lu = self._systems[key][2] = splu(A.tocsc())
                s_new = lu.solve(b)
            s = s_new
        return s.reshape(f.shape)


def _pcg(A, d_inv, B, X0, rtol: float | None = None, maxiter: int | None = None):
    """Solve ``A X = B`` (``A`` symmetric positive definite, ``B (n, k)``) column by column by
    conjugate gradients preconditioned by ``diag(d_inv)`` from ``X0``: the solution when every
    column's residual is at most ``rtol`` times its right-hand side's norm, else ``None``."""
    rtol = SMOOTHING_RTOL if rtol is None else rtol
    maxiter = SMOOTHING_MAXITER if maxiter is None else maxiter
    X = np.array(X0, dtype=np.float64)
    R = B - A @ X
    target = rtol * np.linalg.norm(B, axis=0)
    Z = d_inv[:, None] * R
    P = Z.copy()
    rz = np.einsum("ij,ij->j", R, Z)
    for _ in range(maxiter):
        if (np.linalg.norm(R, axis=0) <= target).all():
            return X
        AP = A @ P
        pap = np.einsum("ij,ij->j", P, AP)
        alpha = np.divide(rz, pap, out=np.zeros_like(rz), where=pap > 0)
        X += alpha * P
        R -= alpha * AP
        Z = d_inv[:, None] * R
        rz_new = np.einsum("ij,ij->j", R, Z)
        beta = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz > 0)
        P = Z + beta * P
        rz = rz_new
    return X if (np.linalg.norm(R, axis=0) <= target).all() else None


@dataclass(frozen=True, eq=False)
class Dent:
    """One dent: its vertices ``vertices (n,)`` (indices), ``area``, the area-weighted
    ``centre (3,)`` and the unit ``axis (3,)`` (vector area of the dent, pointing out of it)."""

    vertices: np.ndarray
    area: float
    centre: np.ndarray
    axis: np.ndarray


@dataclass(frozen=True, eq=False)
class Descriptors:
    """Descriptors of one conformation (see the module docstring for the definitions).

    ``dents`` are sorted by decreasing area; ``rim`` is the rim of the largest dent
    (:class:`shellbuckle.analysis.wrinkles.Rim`) when exactly that dent could be framed, else
    ``None``; ``far_sheets``: the components of dent size found to be the far sheet of a dent's
    wall (:meth:`ShapeAnalyzer.far_sheet`), not counted as dimples. Lengths in the units of
    ``X``.
    """

    geometry: Geometry = field(repr=False)
    asphericity: float
    gyration: np.ndarray
    dents: tuple
    rim: "wrinkles.Rim | None"
    dent_depth: float
    dent_sagitta: float
    contact_distance: float
    far_sheets: tuple = ()

    @property
    def n_dimples(self) -> int:
        return len(self.dents)

    def as_dict(self) -> dict:
        """Plain JSON-able values (lists for vectors); NaN where a quantity does not apply."""
        g = self.geometry
        rim = self.rim
        main = self.dents[0] if self.dents else None
        out = {
            "n_vertices": int(len(g.X)), "area": g.area, "volume": g.volume, "R_area": g.R_area,
            "mean_edge": g.mean_edge, "asphericity": self.asphericity,
            "gyration_eigenvalues": [float(v) for v in self.gyration],
            "H_min": float(g.H.min()), "H_max": float(g.H.max()),
            "n_dimples": self.n_dimples,
            "dimple_areas": [float(d.area) for d in self.dents],
            "far_sheet_areas": [float(d.area) for d in self.far_sheets],
            "dent_area": float(main.area) if main else math.nan,
            "dent_axis": [float(v) for v in rim.axis] if rim else (
                [float(v) for v in main.axis] if main else None),
            "dent_centre": [float(v) for v in rim.origin] if rim else (
                [float(v) for v in main.centre] if main else None),
            "dent_depth": self.dent_depth, "dent_sagitta": self.dent_sagitta,
            "contact_distance": self.contact_distance,
        }
        out.update(wrinkles.rim_summary(rim))
        return out


class ShapeAnalyzer:
    """Descriptors of conformations of one triangulation, with the per-topology work done once.

    ``faces (F, 3)`` (closed, outward oriented) or a :class:`~shellbuckle.mesh.Topology`;
    ``contact``: also measure the self-contact distance (builds a
    :class:`~shellbuckle.mesh.contact.ContactChecker` on first use).
    """

    def __init__(self, faces_or_topology, n_vertices: int | None = None, contact: bool = True):
        if isinstance(faces_or_topology, Topology):
            topology = faces_or_topology
        else:
            topology = Topology.from_faces(np.asarray(faces_or_topology), n_vertices)
        self.topology = topology
        self.bending = Bending.from_mesh(topology)
        self.contact = contact
        self._checker = None

    # ------------------------------------------------------------------ geometry

    def geometry(self, X) -> Geometry:
        """:class:`Geometry` of positions ``X (V, 3)`` (ValueError for a wrong shape or a
        non-finite coordinate)."""
        X = np.asarray(X, dtype=np.float64)
        V = self.topology.n_vertices
        if X.shape != (V, 3):
            raise ValueError(f"positions must have shape ({V}, 3) for this mesh, got {X.shape}")
        if not np.isfinite(X).all():
            v = int(np.flatnonzero(~np.isfinite(X).all(axis=1))[0])
            raise ValueError(f"vertex {v} has a non-finite coordinate {X[v].tolist()}")
        F = self.topology.faces
        x0, x1, x2 = X[F[:, 0]], X[F[:, 1]], X[F[:, 2]]
        n = np.cross(x1 - x0, x2 - x0)
        face_area = 0.5 * np.linalg.norm(n, axis=1)
        vertex_area = np.bincount(F.ravel(), np.repeat(face_area, 3), minlength=V) / 3.0
        normal = np.stack([np.bincount(F.ravel(), np.repeat(n[:, c], 3), minlength=V)
                           for c in range(3)], axis=1)
        area = float(face_area.sum())
        volume = float(np.einsum("ij,ij->i", x0, np.cross(x1, x2)).sum() / 6.0)
        e = self.topology.edges
        mean_edge = float(np.linalg.norm(X[e[:, 1]] - X[e[:, 0]], axis=1).mean())
        H = self.bending.mean_curvature(X)
        geom = Geometry(X=X, face_area=face_area, vertex_area=vertex_area,
                        vertex_normal=_unit(normal), H=H, area=area, volume=volume,
                        R_area=math.sqrt(area / (4.0 * math.pi)), mean_edge=mean_edge,
                        stiffness=_cotan_stiffness(X, F, 2.0 * face_area))
        length = max(H_SMOOTHING_LENGTH * geom.R_area, H_SMOOTHING_EDGES * mean_edge)
        object.__setattr__(geom, "H_smooth", geom.smooth(H, length))
        object.__setattr__(geom, "H_smoothing_length", length)
        return geom

    # ------------------------------------------------------------------ dents

    def components(self, mask: np.ndarray) -> np.ndarray:
        """Labels ``(V,)`` of the connected components of the vertex set ``mask`` on the edge
        graph (``-1`` outside ``mask``), numbered from 0."""
        mask = np.asarray(mask, dtype=bool)
        e = self.topology.edges
        keep = mask[e[:, 0]] & mask[e[:, 1]]
        V = self.topology.n_vertices
        graph = sp.csr_matrix((np.ones(int(keep.sum())), (e[keep, 0], e[keep, 1])), shape=(V, V))
        _, labels = connected_components(graph, directed=False)
        _, labels_in = np.unique(labels[mask], return_inverse=True)
        out = np.full(V, -1, dtype=np.int64)
        out[mask] = labels_in
        return out

    def inverted_components(self, geom: Geometry) -> list:
        """All connected components of ``H_smooth < 0`` as :class:`Dent` objects, largest
        first (of any size)."""
        labels = self.components(geom.H_smooth < 0.0)
        if labels.max() < 0:
            return []
        inside = labels >= 0
        areas = np.bincount(labels[inside], geom.vertex_area[inside])
        groups = np.split(np.argsort(labels, kind="stable")[np.count_nonzero(~inside):],
                          np.cumsum(np.bincount(labels[inside]))[:-1])
        order = np.argsort(-areas, kind="stable")
        return [_dent(geom, groups[c]) for c in order]

    def dents(self, geom: Geometry, min_radius: float = MIN_DENT_RADIUS,
              with_sheets: bool = False):
        """Dents of a conformation, largest first, and the rim of the largest (or ``None``).

        Each component of ``H_smooth < 0`` with an area of at least ``pi (min_radius R_area)^2``
        seeds a dent, unless it is the far sheet of a larger dent's wall (:meth:`far_sheet`);
        the components (of any size) lying mostly (by area) in a larger dent's depression
        (inside and below its crest, facing out of it: :meth:`wrinkles.Rim.encloses`) belong
        to it, so a depression cut into pieces by folds of positive curvature counts once.
        Returns ``(dents, rim)``, and the far sheets as a third item with ``with_sheets``.
        """
        remaining = self.inverted_components(geom)
        threshold = math.pi * (min_radius * geom.R_area) ** 2
        dents, sheets, main_rim, trees = [], [], None, {}
        while remaining and remaining[0].area >= threshold:
            seed = remaining.pop(0)
            if any(self.far_sheet(geom, seed, d, trees) for d in dents):
                sheets.append(seed)
                continue
            rim = wrinkles.find_rim(geom, self.topology, seed, self.components)
            if rim is not None and remaining:
                inside = [c for c in remaining if geom.vertex_area[c.vertices][rim.encloses(
                    geom.X[c.vertices], geom.vertex_normal[c.vertices])].sum() > 0.5 * c.area]
                if inside:
                    seed = _dent(geom, np.concatenate([seed.vertices] + [c.vertices for c in inside]))
                    remaining = [c for c in remaining if not any(c is i for i in inside)]
                    rim = wrinkles.find_rim(geom, self.topology, seed, self.components)
            if not dents:
                main_rim = rim
            dents.append(seed)
        if with_sheets:
            return tuple(dents), main_rim, tuple(sheets)
        return tuple(dents), main_rim

    @staticmethod
    def far_sheet(geom: Geometry, part: Dent, dent: Dent, trees: dict | None = None) -> bool:
        """Whether the inverted region ``part`` is the far sheet of ``dent``'s wall: at least
        half of its area within ``WALL_GAP R_area`` of a vertex of ``dent`` across the shell's
        interior, i.e. with the two outward normals opposed (``n_i . n_j < 0``, ``j`` the
        nearest vertex of ``dent`` to vertex ``i`` of ``part``; which point is behind which is
        not tested: near contact the gap is below the edge length and its direction is noise).
        Where a deep bowl's wall comes
        close to the outer side of the shell the outer side follows it and is concave there,
        a concavity of the bowl's doubled wall, not a depression of the body. ``trees``: a
        cache of k-d trees keyed by ``id(dent)``."""
        trees = {} if trees is None else trees
        if id(dent) not in trees:
            trees[id(dent)] = cKDTree(geom.X[dent.vertices])
        X, n = geom.X, geom.vertex_normal
        i = part.vertices
        dist, k = trees[id(dent)].query(X[i], distance_upper_bound=WALL_GAP * geom.R_area)
        close = np.isfinite(dist)
        i, j = i[close], dent.vertices[k[close]]
        across = (n[i] * n[j]).sum(axis=1) < 0
        return bool(geom.vertex_area[i[across]].sum() >= 0.5 * part.area)

    # ------------------------------------------------------------------ all descriptors

    def contact_distance(self, X) -> float:
        if not self.contact:
            return math.nan
        if self._checker is None:
            from ..mesh.contact import ContactChecker

            self._checker = ContactChecker(self.topology, rings=2)
        return float(self._checker.min_vertex_distance(X)[0])

    def describe(self, X) -> Descriptors:
        """All descriptors of positions ``X (V, 3)``."""
        geom = self.geometry(X)
        w = geom.vertex_area
        xbar = (w[:, None] * geom.X).sum(axis=0) / w.sum()
        d = geom.X - xbar
        gyration = np.linalg.eigvalsh(np.einsum("i,ij,ik->jk", w, d, d) / w.sum())
        l1, l2, l3 = gyration
        asphericity = float(((l1 - l2) ** 2 + (l2 - l3) ** 2 + (l3 - l1) ** 2)
                            / (2.0 * (l1 + l2 + l3) ** 2))
        dents, rim, sheets = self.dents(geom, with_sheets=True)
        depth, sagitta = _depths(geom, rim) if rim is not None else (math.nan, math.nan)
        return Descriptors(geometry=geom, asphericity=asphericity, gyration=gyration,
                           dents=dents, rim=rim, dent_depth=depth, dent_sagitta=sagitta,
                           contact_distance=self.contact_distance(geom.X), far_sheets=sheets)


def _dent(geom: Geometry, idx: np.ndarray) -> Dent:
    idx = np.sort(idx)
    w = geom.vertex_area[idx]
    centre = (w[:, None] * geom.X[idx]).sum(axis=0) / w.sum()
    axis = _unit((w[:, None] * geom.vertex_normal[idx]).sum(axis=0))
    return Dent(vertices=idx, area=float(w.sum()), centre=centre, axis=axis)


def _cotan_stiffness(X, F, double_area) -> sp.csr_matrix:
    """P1 stiffness matrix ``K_ij = -(cot a_ij + cot b_ij) / 2``, ``K_ii = -sum_j K_ij``
    (symmetric positive semi-definite for any triangle shapes), ``(V, V)`` CSR."""
    V = len(X)
    rows, cols, vals = [], [], []
    for c in range(3):
        i, j, k = F[:, c], F[:, (c + 1) % 3], F[:, (c + 2) % 3]
        a, b = X[j] - X[i], X[k] - X[i]
        cot = np.einsum("ij,ij->i", a, b) / np.maximum(double_area, 1e-300)
        w = 0.5 * cot  # weight of the edge (j, k) opposite corner i
        rows += [j, k, j, k]
        cols += [k, j, j, k]
        vals += [-w, -w, w, w]
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(V, V))


def _fit_sphere(P: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, float]:
    """Weighted algebraic least-squares sphere ``|x|^2 = 2 c.x + k`` through points ``P (n, 3)``:
    centre ``c`` and radius ``sqrt(k + |c|^2)``."""
    sw = np.sqrt(w)[:, None]
    M = np.hstack([2.0 * P, np.ones((len(P), 1))]) * sw
    rhs = (P * P).sum(axis=1)[:, None] * sw
    sol = np.linalg.lstsq(M, rhs, rcond=None)[0].ravel()
    c, k = sol[:3], sol[3]
    return c, float(math.sqrt(max(k + c @ c, 0.0)))


def _depths(geom: Geometry, rim) -> tuple[float, float]:
    """Indentation ``delta`` and sagitta of the framed dent (module docstring)."""
    z = (geom.X - rim.origin) @ rim.axis
    bowl = rim.bowl
    z_min = float(z[bowl].min())
    sagitta = float(rim.crest.height - z_min)
    outside = ~bowl
    if outside.sum() < 4:
        return math.nan, sagitta
    c, radius = _fit_sphere(geom.X[outside], geom.vertex_area[outside])
    apex = float((c - rim.origin) @ rim.axis + radius)
    return apex - z_min, sagitta


def describe(X, faces) -> dict:
    """Descriptors of one conformation as a plain dict (see :class:`Descriptors`).

    ``X (V, 3)`` positions, ``faces (F, 3)`` closed and outward oriented. Keys: ``area``,
    ``volume``, ``R_area``, ``asphericity``, ``gyration_eigenvalues``, ``n_dimples``,
    ``dimple_areas``, ``dent_axis``, ``dent_centre``, ``dent_depth``, ``dent_sagitta``,
    ``crest_radius``, ``crest_height``, ``crest_spectrum``, ``rim_radius``, ``rim_spectrum``
    (relative amplitudes of the modes ``m = 1..20`` of the outline of the depression),
    ``rim_apices``, ``rim_concave_arcs``, ``rim_arc_sagitta`` (how far each arc between two
    apices dips inside their chord, relative to it), ``rim_apex_spacing`` (lengths along the
    outline), ``rim_resolution`` (the smallest spacing counted), ``rim_count_resolved``,
    ``rim_arc_curvature``, ``contact_distance``, ...
    """
    X = np.asarray(X, dtype=np.float64)
    return ShapeAnalyzer(faces, n_vertices=len(X)).describe(X).as_dict()
