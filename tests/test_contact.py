"""Self-contact measures against independent references.

References used here and nowhere in the library:
- the separating-axis theorem (SAT) for two closed triangles, axes n1, n2, e_i x f_j and the
  in-plane edge normals n x e (exact in integer arithmetic);
- an exact segment-triangle test in rational arithmetic (``fractions.Fraction``): two
  non-coplanar closed triangles meet iff an edge of one meets the other;
- brute force over all vertex pairs / vertex-face pairs with graph distances from
  ``scipy.sparse.csgraph`` breadth-first search;
- analytic gaps of hand-built shapes.
"""

from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import shortest_path
from scipy.spatial.transform import Rotation

from shellbuckle.mesh import icosphere, random_sphere
from shellbuckle.mesh.contact import (ContactChecker, min_nonadjacent_distance,
                                      min_vertex_face_distance, point_triangle_distance,
                                      self_intersections, triangles_intersect)

# ---------------------------------------------------------------------------------------------
# references


def sat_intersect(T1, T2):
    """Closed-triangle intersection by the separating-axis theorem, vectorized over pairs."""
    e1 = T1[:, [1, 2, 0]] - T1
    e2 = T2[:, [1, 2, 0]] - T2
    n1 = np.cross(e1[:, 0], e1[:, 1])
    n2 = np.cross(e2[:, 0], e2[:, 1])
    axes = [n1[:, None], n2[:, None],
            np.cross(e1[:, :, None], e2[:, None, :]).reshape(-1, 9, 3),
            np.cross(n1[:, None], e1), np.cross(n2[:, None], e2)]
    axes = np.concatenate(axes, axis=1)  # (n, 17, 3)
    p1 = np.einsum("nak,nvk->nav", axes, T1)
    p2 = np.einsum("nak,nvk->nav", axes, T2)
    separated = (p1.max(2) < p2.min(2)) | (p2.max(2) < p1.min(2))
    return ~separated.any(axis=1)


def _sub(a, b):
    return [x - y for x, y in zip(a, b)]


def _cross3(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _dot3(a, b):
    return sum(x * y for x, y in zip(a, b))


def _o2(a, b, c):
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def _sgn(x):
    return (x > 0) - (x < 0)


def _drop(points, n):
    k = max(range(3), key=lambda i: abs(n[i]))
    keep = [i for i in range(3) if i != k]
    return [[p[i] for i in keep] for p in points]


def _seg_seg_2d(a, b, c, d):
    o1, o2, o3, o4 = _sgn(_o2(a, b, c)), _sgn(_o2(a, b, d)), _sgn(_o2(c, d, a)), _sgn(_o2(c, d, b))
    if o1 == o2 == o3 == o4 == 0:
        return all(max(min(a[i], b[i]), min(c[i], d[i])) <= min(max(a[i], b[i]), max(c[i], d[i]))
                   for i in range(2))
    return o1 * o2 <= 0 and o3 * o4 <= 0


def _in_tri_2d(p, t):
    s = [_sgn(_o2(t[k], t[(k + 1) % 3], p)) for k in range(3)]
    return all(x >= 0 for x in s) or all(x <= 0 for x in s)


def _seg_tri_exact(p, q, tri):
    n = _cross3(_sub(tri[1], tri[0]), _sub(tri[2], tri[0]))
    dp, dq = _dot3(n, _sub(p, tri[0])), _dot3(n, _sub(q, tri[0]))
    if dp * dq > 0:
        return False
    if dp == 0 and dq == 0:  # segment in the triangle's plane
        P, Q, *t = _drop([p, q, *tri], n)
        return (_in_tri_2d(P, t) or _in_tri_2d(Q, t)
                or any(_seg_seg_2d(P, Q, t[k], t[(k + 1) % 3]) for k in range(3)))
    s = Fraction(dp) / (dp - dq)
    x = [pi + s * (qi - pi) for pi, qi in zip(p, q)]
    X, *t = _drop([x, *tri], n)
    return _in_tri_2d(X, t)


def tri_tri_exact(A, B):
    """Exact closed-triangle intersection of two non-degenerate triangles (rationals)."""
    A = [[Fraction(float(v)) for v in p] for p in A]
    B = [[Fraction(float(v)) for v in p] for p in B]
    n = _cross3(_sub(A[1], A[0]), _sub(A[2], A[0]))
    if all(_dot3(n, _sub(b, A[0])) == 0 for b in B):  # coplanar
        a2, b2 = _drop(A, n), _drop(B, n)
        return (any(_seg_seg_2d(a2[i], a2[(i + 1) % 3], b2[j], b2[(j + 1) % 3])
                    for i in range(3) for j in range(3))
                or _in_tri_2d(a2[0], b2) or _in_tri_2d(b2[0], a2))
    return (any(_seg_tri_exact(A[i], A[(i + 1) % 3], B) for i in range(3))
            or any(_seg_tri_exact(B[i], B[(i + 1) % 3], A) for i in range(3)))


def graph_distances(topology):
    V = topology.n_vertices
    e = topology.edges
    A = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(V, V))
    return shortest_path(A, directed=False, unweighted=True)


def brute_vertex_min(X, topology, rings):
    G = graph_distances(topology)
    D = np.linalg.norm(X[:, None] - X[None], axis=2)
    D[G <= rings] = np.inf
    return D.min(), D


def brute_face_min(X, topology, rings):
    G = graph_distances(topology)
    F = topology.faces
    far = (G[:, F] > rings).all(axis=2)  # (V, F) admissible vertex-face pairs
    v, f = np.nonzero(far)
    return point_triangle_distance(X[v], X[F[f]]).min()


def brute_intersections(X, topology):
    F = topology.faces
    T = X[F]
    lo, hi = T.min(1), T.max(1)
    box = ((lo[:, None] <= hi[None]) & (lo[None] <= hi[:, None])).all(axis=2)
    a, b = np.nonzero(np.triu(box, 1))
    share = (F[a][:, :, None] == F[b][:, None, :]).any(axis=(1, 2))
    a, b = a[~share], b[~share]
    hit = sat_intersect(T[a], T[b])
    return {(int(i), int(j)) for i, j in zip(a[hit], b[hit])}


def segment_distance(p, u, q, v):
    """Distance between segments p + s u and q + t v, (s, t) in [0, 1]^2: the minimum of a convex
    quadratic on the unit square is at its stationary point or on one of the four sides."""
    def at(s, t):
        return np.linalg.norm(p + s * u - q - t * v)

    def clamp(x):
        return min(1.0, max(0.0, x))
    w = p - q
    a, b, c, d, e = u @ u, u @ v, v @ v, u @ w, v @ w
    candidates = [at(0.0, clamp(e / c)), at(1.0, clamp((e + b) / c)),
                  at(clamp(-d / a), 0.0), at(clamp((b - d) / a), 1.0)]
    det = a * c - b * b
    if det > 1e-14 * a * c:
        s, t = (b * e - c * d) / det, (a * e - b * d) / det
        if 0 <= s <= 1 and 0 <= t <= 1:
            candidates.append(at(s, t))
    return min(candidates)


def triangle_distance(A, B):
    """Distance between two closed disjoint triangles: vertex-triangle and edge-edge minima."""
    d = min(point_triangle_distance(A, np.array([B] * 3)).min(),
            point_triangle_distance(B, np.array([A] * 3)).min())
    for i in range(3):
        for j in range(3):
            d = min(d, segment_distance(A[i], A[(i + 1) % 3] - A[i], B[j], B[(j + 1) % 3] - B[j]))
    return d


def assert_same_pairs_up_to_touching(got, ref, X, faces, tol=1e-9):
    """``got`` holds every truly intersecting pair; any extra pair touches within ``tol * L``
    (the test's documented convention counts such contacts as intersections)."""
    assert ref <= got
    for f, g in got - ref:
        A, B = X[faces[f]], X[faces[g]]
        L = max(np.linalg.norm(A[[1, 2, 0]] - A, axis=1).max(),
                np.linalg.norm(B[[1, 2, 0]] - B, axis=1).max())
        assert triangle_distance(A, B) <= tol * L, (f, g)


def random_rigid(rng):
    return Rotation.random(random_state=rng).as_matrix(), rng.normal(size=3) * 3


def integer_pairs(rng, n, lo=-2, hi=2):
    T = rng.integers(lo, hi + 1, size=(4 * n, 2, 3, 3)).astype(float)
    normal = lambda t: np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])  # noqa: E731
    ok = (np.abs(normal(T[:, 0])).sum(1) > 0) & (np.abs(normal(T[:, 1])).sum(1) > 0)
    T = T[ok][:n]
    return T[:, 0], T[:, 1]


# ---------------------------------------------------------------------------------------------
# the two references agree with each other


def test_references_agree_on_integer_triangles():
    rng = np.random.default_rng(0)
    A, B = integer_pairs(rng, 600)
    sat = sat_intersect(A, B)
    exact = np.array([tri_tri_exact(a, b) for a, b in zip(A, B)])
    np.testing.assert_array_equal(sat, exact)
    assert 0.2 < exact.mean() < 0.8


# ---------------------------------------------------------------------------------------------
# triangle-triangle test


def test_triangle_test_is_exact_on_integer_triangles_including_degenerate_contacts():
    rng = np.random.default_rng(1)
    pairs = [integer_pairs(rng, 10000, lo, hi) for lo, hi in [(-2, 2), (-1, 1), (0, 2)]]
    A = np.concatenate([p[0] for p in pairs])
    B = np.concatenate([p[1] for p in pairs])
    ref = sat_intersect(A, B)
    got = triangles_intersect(A, B)
    nA = np.cross(A[:, 1] - A[:, 0], A[:, 2] - A[:, 0])
    coplanar = (np.einsum("nk,nvk->nv", nA, B - A[:, None, 0]) == 0).all(1)
    assert coplanar.sum() > 150 and (~ref & coplanar).sum() > 10
    mismatch = np.flatnonzero(got != ref)
    assert len(mismatch) == 0, (A[mismatch[:3]], B[mismatch[:3]], ref[mismatch[:3]])


def test_triangle_test_counts_touching_as_intersecting():
    A = np.array([[[0, 0, 0], [2, 0, 0], [0, 2, 0]]], float)
    cases = {  # second triangle, expected
        "vertex on face": ([[0.5, 0.5, 0], [0.5, 0.5, 1], [1.5, 0.5, 1]], True),
        "vertex on edge": ([[1, 0, 0], [1, -1, 1], [2, -1, 1]], True),
        "edge crossing edge": ([[1, -1, 0], [1, 1, 0], [1, 0, 1]], True),
        "shared vertex position": ([[2, 0, 0], [3, 0, 1], [3, 1, 1]], True),
        "coplanar edge contact": ([[2, 0, 0], [0, 2, 0], [2, 2, 0]], True),
        "coplanar inside": ([[0.2, 0.2, 0], [0.6, 0.2, 0], [0.2, 0.6, 0]], True),
        "coplanar apart": ([[2.1, 0, 0], [3, 0, 0], [3, 1, 0]], False),
        "just above": ([[0.5, 0.5, 1e-6], [0.5, 0.5, 1], [1.5, 0.5, 1]], False),
        "just below a vertex": ([[0.5, 0.5, -1e-6], [0.5, 0.5, -1], [1.5, 0.5, -1]], False),
        "piercing": ([[0.5, 0.5, -1], [0.5, 0.5, 1], [1.5, 0.7, 1]], True),
    }
    for name, (b, expected) in cases.items():
        B = np.array([b], float)
        assert triangles_intersect(A, B)[0] == expected, name
        assert triangles_intersect(B, A)[0] == expected, name
        assert tri_tri_exact(A[0], B[0]) == expected, name


def test_triangle_test_is_invariant_under_rigid_motions_of_degenerate_pairs():
    """Rotated integer configurations are coplanar or touching only up to rounding; within the
    documented tolerance they keep the exact answer of the unrotated pair."""
    rng = np.random.default_rng(2)
    A, B = integer_pairs(rng, 5000)
    ref = sat_intersect(A, B)
    for _ in range(3):
        Q, t = random_rigid(rng)
        scale = 10.0 ** rng.uniform(-3, 2)
        got = triangles_intersect(scale * (A @ Q.T + t), scale * (B @ Q.T + t))
        np.testing.assert_array_equal(got, ref)


def test_triangle_test_on_near_coplanar_pairs():
    """Coplanar integer pairs lifted off their plane by 1e-13 (below the 1e-10 L tolerance)
    keep the coplanar answer; lifted by 1e-6 L they are separated."""
    rng = np.random.default_rng(3)
    A = rng.integers(-3, 4, size=(20000, 3, 3)).astype(float)
    B = rng.integers(-3, 4, size=(20000, 3, 3)).astype(float)
    A[:, :, 2] = 0.0
    B[:, :, 2] = 0.0
    area = lambda t: np.abs(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])[:, 2])  # noqa: E731
    ok = (area(A) > 0) & (area(B) > 0)
    A, B = A[ok], B[ok]
    ref = sat_intersect(A, B)
    assert 0.2 < ref.mean() < 0.8
    Bz = B.copy()
    Bz[:, :, 2] = rng.uniform(-1e-13, 1e-13, size=B.shape[:2])
    np.testing.assert_array_equal(triangles_intersect(A, Bz), ref)
    Bz[:, :, 2] = 1e-6 * 6  # whole triangle above the plane of A
    assert not triangles_intersect(A, Bz).any()


def test_triangle_test_agrees_with_references_on_random_float_pairs():
    rng = np.random.default_rng(4)
    n = 20000
    A = rng.normal(size=(n, 3, 3))
    B = rng.normal(size=(n, 3, 3)) * rng.uniform(0.2, 1, size=(n, 1, 1)) + rng.normal(size=(n, 1, 3))
    ref = sat_intersect(A, B)
    got = triangles_intersect(A, B)
    assert 0.03 < ref.mean() < 0.9
    np.testing.assert_array_equal(got, ref)
    for k in range(300):  # exact rational reference on a subset
        assert got[k] == tri_tri_exact(A[k], B[k])


def test_triangle_test_refuses_bad_shapes():
    with pytest.raises(ValueError, match=r"\(n, 3, 3\)"):
        triangles_intersect(np.zeros((4, 3, 3)), np.zeros((3, 3, 3)))


# ---------------------------------------------------------------------------------------------
# point-triangle distance


def test_point_triangle_distance_against_dense_sampling():
    rng = np.random.default_rng(5)
    n, m = 300, 120
    T = rng.normal(size=(n, 3, 3))
    P = rng.normal(size=(n, 3)) * 1.5
    d = point_triangle_distance(P, T)
    u, v = np.meshgrid(np.linspace(0, 1, m + 1), np.linspace(0, 1, m + 1))
    keep = u + v <= 1
    bary = np.stack([1 - u[keep] - v[keep], u[keep], v[keep]], 1)  # (S, 3)
    S = np.einsum("sk,nkc->nsc", bary, T)
    sampled = np.linalg.norm(S - P[:, None], axis=2).min(1)
    longest = np.linalg.norm(T[:, [1, 2, 0]] - T, axis=2).max(1)
    assert (d <= sampled + 1e-12).all()
    assert (d >= sampled - longest / m).all()


def test_point_triangle_distance_special_positions():
    T = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]] * 4, float)
    P = np.array([[0.2, 0.2, 0.7], [2, 0, 0], [0.5, -1, 0], [-3, -4, 12]], float)
    np.testing.assert_allclose(point_triangle_distance(P, T), [0.7, 1.0, 1.0, 13.0])


# ---------------------------------------------------------------------------------------------
# meshes


def pole_aligned_icosphere(n):
    """Icosphere rotated so that vertex 0 is the north pole (its antipode is a vertex too)."""
    m = icosphere(n)
    X = m.X
    z = X[0] / np.linalg.norm(X[0])
    axis = np.cross(z, [0, 0, 1.0])
    angle = np.arccos(np.clip(z[2], -1, 1))
    Q = Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()
    X = X @ Q.T
    north = int(np.argmax(X[:, 2]))
    south = int(np.argmin(X[:, 2]))
    assert np.isclose(X[north, 2], 1) and np.isclose(X[south, 2], -1)
    return m.with_positions(X), north, south


def smoothstep(t):
    t = np.clip(t, 0, 1)
    return t * t * (3 - 2 * t)


def piston_dent(X, gap, zf=-0.8, r1=0.2, r2=0.4):
    """Flatten the south cap onto the plane z = zf and push the north cap down into a flat disc
    at z = zf + gap (radius r1) joined to the sphere by a smooth wall for r1 < rho < r2.
    Below radius r2 the lower sheet is the flat disc (r2 < sqrt(1 - zf^2) - |gap|), so the two
    sheets are parallel discs at distance ``gap``; elsewhere every point is farther apart."""
    X = X.copy()
    rho = np.hypot(X[:, 0], X[:, 1])
    upper = X[:, 2] > 0
    zb = zf + gap
    s = smoothstep((rho - r1) / (r2 - r1))
    X[upper, 2] = zb + (X[upper, 2] - zb) * s[upper]
    X[~upper, 2] = np.maximum(X[~upper, 2], zf)
    return X


@pytest.mark.parametrize("rings", [0, 1, 2, 3])
def test_sphere_min_distance_is_brute_force_and_of_order_rings_edges(rings):
    m = icosphere(6)
    X = m.X
    cc = ContactChecker(m.topology, rings=rings)
    d, (i, j) = cc.min_vertex_distance(X)
    ref, D = brute_vertex_min(X, m.topology, rings)
    assert d == pytest.approx(ref, rel=1e-14)
    assert D[i, j] == pytest.approx(d, rel=1e-14) and i < j
    assert graph_distances(m.topology)[i, j] > rings
    lengths = np.linalg.norm(X[m.topology.edges[:, 0]] - X[m.topology.edges[:, 1]], axis=1)
    assert 0.5 * (rings + 1) * lengths.min() <= d <= (rings + 1) * lengths.max()
    result = cc.check(X)
    assert not result.intersects and result.n_pairs == 0 and result.first_pair is None
    assert result.pairs.shape == (0, 2)


def test_random_sphere_distances_match_brute_force_after_random_deformation():
    rng = np.random.default_rng(6)
    m = random_sphere(400, seed=3)
    X = m.X * (1 + 0.15 * np.sin(3 * m.X[:, [0]]) * np.cos(2 * m.X[:, [1]]))
    X = X + rng.normal(scale=0.01, size=X.shape)
    cc = ContactChecker(m.topology, rings=2)
    assert cc.min_vertex_distance(X)[0] == pytest.approx(brute_vertex_min(X, m.topology, 2)[0],
                                                         rel=1e-14)
    df, (v, f) = cc.min_face_distance(X)
    assert df == pytest.approx(brute_face_min(X, m.topology, 2), rel=1e-12)
    assert (graph_distances(m.topology)[v, m.topology.faces[f]] > 2).all()
    # with a cutoff below the gap there is nothing to report
    assert cc.min_face_distance(X, cutoff=0.9 * df) == (np.inf, None)
    assert cc.min_face_distance(X, cutoff=1.1 * df)[0] == pytest.approx(df, rel=1e-14)


@pytest.mark.parametrize("gap", [0.05, 0.01, 1e-4])
def test_dented_sphere_min_distances_equal_the_analytic_gap(gap):
    m, north, south = pole_aligned_icosphere(8)
    X = piston_dent(m.X, gap)
    cc = ContactChecker(m.topology)
    result = cc.check(X)
    assert not result.intersects
    assert result.min_distance == pytest.approx(gap, rel=1e-12, abs=1e-14)
    assert result.min_pair == tuple(sorted((north, south)))
    assert result.min_face_distance == pytest.approx(gap, rel=1e-12, abs=1e-14)
    assert brute_face_min(X, m.topology, 2) == pytest.approx(gap, rel=1e-12, abs=1e-14)
    v, f = result.min_face_pair
    assert (m.X[v, 2] > 0) != (m.X[m.faces[f], 2].mean() > 0)  # on opposite sheets


@pytest.mark.parametrize("gap", [-0.05, -0.3])
def test_dent_pushed_through_the_opposite_side_intersects(gap):
    m, _, _ = pole_aligned_icosphere(8)
    X = piston_dent(m.X, gap)
    result = ContactChecker(m.topology).check(X)
    assert result.intersects
    got = {tuple(map(int, p)) for p in result.pairs}
    ref = brute_intersections(X, m.topology)
    assert_same_pairs_up_to_touching(got, ref, X, m.faces)
    assert result.n_pairs == len(got)
    assert result.first_pair == min(got)
    for f, g in sorted(ref)[:10]:  # exact rational check of reported pairs
        assert tri_tri_exact(X[m.faces[f]], X[m.faces[g]])
        assert not set(m.faces[f]) & set(m.faces[g])


def test_inverted_cap_pushed_through_the_south_side_intersects():
    m = icosphere(6)
    X = m.X.copy()
    cap = X[:, 2] > 0.5
    X[cap, 2] = -1.5 * X[cap, 2]
    pairs = self_intersections(X, m.topology)
    got = {tuple(map(int, p)) for p in pairs}
    ref = brute_intersections(X, m.topology)
    assert len(ref) > 50
    # mirror-symmetric vertices make some edges of the two sheets cross within rounding
    assert_same_pairs_up_to_touching(got, ref, X, m.faces)
    assert (pairs[:, 0] < pairs[:, 1]).all()
    assert (np.lexsort((pairs[:, 1], pairs[:, 0])) == np.arange(len(pairs))).all()
    for f, g in sorted(ref)[:10]:
        assert tri_tri_exact(X[m.faces[f]], X[m.faces[g]])
    first3 = self_intersections(X, m.topology, max_pairs=3)
    np.testing.assert_array_equal(first3, pairs[:3])


def test_check_is_invariant_under_rigid_motions():
    rng = np.random.default_rng(7)
    m, _, _ = pole_aligned_icosphere(8)
    cc = ContactChecker(m.topology)
    for gap in (0.02, -0.05):
        X = piston_dent(m.X, gap) + rng.normal(scale=1e-3, size=m.X.shape)
        ref = cc.check(X)
        for _ in range(3):
            Q, t = random_rigid(rng)
            got = cc.check(X @ Q.T + t)
            np.testing.assert_array_equal(got.pairs, ref.pairs)
            assert got.min_pair == ref.min_pair and got.min_face_pair == ref.min_face_pair
            assert got.min_distance == pytest.approx(ref.min_distance, rel=1e-12)
            assert got.min_face_distance == pytest.approx(ref.min_face_distance, rel=1e-12)


def test_one_shot_functions_match_the_checker():
    m = icosphere(5)
    X = piston_dent(pole_aligned_icosphere(5)[0].X, 0.03)
    cc = ContactChecker(m.topology, rings=1)
    assert min_nonadjacent_distance(X, m.topology, rings=1) == cc.min_vertex_distance(X)
    assert min_vertex_face_distance(X, m.topology, rings=1) == cc.min_face_distance(X)


def test_no_nonadjacent_pair_gives_infinity():
    m = icosphere(1)  # icosahedron: graph diameter 3
    assert min_nonadjacent_distance(m.X, m.topology, rings=3) == (np.inf, None)
    d, (i, j) = min_nonadjacent_distance(m.X, m.topology, rings=2)
    assert d == pytest.approx(2.0)  # antipodal vertices of the unit icosahedron


def test_bad_inputs_are_refused():
    m = icosphere(2)
    with pytest.raises(ValueError, match="rings"):
        ContactChecker(m.topology, rings=-1)
    with pytest.raises(ValueError, match="rings"):
        ContactChecker(m.topology, rings=1.5)
    with pytest.raises(TypeError, match="Topology"):
        ContactChecker(m.faces)
    cc = ContactChecker(m.topology)
    with pytest.raises(ValueError, match="shape"):
        cc.check(m.X[:-1])
    X = m.X.copy()
    X[3, 1] = np.nan
    with pytest.raises(ValueError, match="vertex 3"):
        cc.check(X)
    with pytest.raises(ValueError, match="max_pairs"):
        cc.intersecting_pairs(m.X, max_pairs=0)
    with pytest.raises(ValueError, match="cutoff"):
        cc.min_face_distance(m.X, cutoff=-1.0)


@pytest.mark.parametrize("rings", [0, 1, 2, 3])
def test_adjacency_sets_match_graph_distances(rings):
    m = random_sphere(200, seed=2)
    t = m.topology
    cc = ContactChecker(t, rings=rings)
    i, j = np.meshgrid(np.arange(t.n_vertices), np.arange(t.n_vertices), indexing="ij")
    np.testing.assert_array_equal(cc.adjacent(i, j), graph_distances(t) <= rings)
    f, g = np.meshgrid(np.arange(t.n_faces), np.arange(t.n_faces), indexing="ij")
    F = t.faces
    share = (F[:, None, :, None] == F[None, :, None, :]).any(axis=(2, 3))
    np.testing.assert_array_equal(cc.share_vertex(f, g), share)
