import numpy as np
import pytest

from shellbuckle.mesh import Mesh, MeshError, icosphere, mesh_quality, validate_surface


def octahedron(scale_z=1.0):
    X = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, scale_z],
                  [0, 0, -scale_z]], dtype=float)
    faces = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                      [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return X, faces


def tetrahedron(offset=(0.0, 0.0, 0.0)):
    X = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float) + offset
    faces = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    return X, faces


def torus(n_major=8, n_minor=6, R=2.0, r=0.7):
    i, j = np.meshgrid(np.arange(n_major), np.arange(n_minor), indexing="ij")
    u, v = 2 * np.pi * i.ravel() / n_major, 2 * np.pi * j.ravel() / n_minor
    X = np.stack([(R + r * np.cos(v)) * np.cos(u), (R + r * np.cos(v)) * np.sin(u),
                  r * np.sin(v)], axis=1)
    idx = lambda a, b: (a % n_major) * n_minor + (b % n_minor)  # noqa: E731
    a, b = i.ravel(), j.ravel()
    q = [idx(a, b), idx(a + 1, b), idx(a + 1, b + 1), idx(a, b + 1)]
    faces = np.concatenate([np.stack([q[0], q[1], q[2]], 1), np.stack([q[0], q[2], q[3]], 1)])
    return X, faces


def _volume(X, faces):
    x0, x1, x2 = (X[faces[:, k]] for k in range(3))
    return np.einsum("ij,ij->", x0, np.cross(x1, x2)) / 6.0


def test_fixtures_have_the_intended_orientation():
    # oracles for the hand-made meshes: octahedron volume 4/3, tetrahedron 8/3, torus > 0
    assert _volume(*octahedron()) == pytest.approx(4.0 / 3.0)
    assert _volume(*tetrahedron()) == pytest.approx(8.0 / 3.0)
    assert _volume(*torus()) > 0


@pytest.mark.parametrize("make", [octahedron, tetrahedron, lambda: (icosphere(3).X, icosphere(3).faces)])
def test_valid_closed_surfaces_pass(make):
    X, faces = make()
    topo = validate_surface(X, faces)
    assert topo.euler_characteristic == 2 and topo.n_vertices == len(X)


def test_mesh_error_is_a_value_error():
    assert issubclass(MeshError, ValueError)


def test_non_finite_coordinate_names_the_vertex():
    X, faces = octahedron()
    X[3, 1] = np.nan
    with pytest.raises(MeshError, match=r"vertex 3 has a non-finite"):
        validate_surface(X, faces)


@pytest.mark.parametrize("shape", [(6, 2), (6,), (0, 3)])
def test_bad_position_shape(shape):
    with pytest.raises(MeshError, match="positions"):
        validate_surface(np.zeros(shape), octahedron()[1])


def test_non_triangle_faces_are_refused():
    X, _ = octahedron()
    with pytest.raises(MeshError, match="triangles"):
        validate_surface(X, np.array([[0, 2, 1, 3]]))


def test_out_of_range_index_names_the_face():
    X, faces = octahedron()
    faces[5, 1] = 99
    with pytest.raises(MeshError, match=r"face 5 .* outside \[0, 5\]"):
        validate_surface(X, faces)


def test_repeated_vertex_names_the_face():
    X, faces = octahedron()
    faces[6] = [3, 3, 5]
    with pytest.raises(MeshError, match=r"face 6 \[3, 3, 5\] repeats a vertex"):
        validate_surface(X, faces)


def test_unused_vertex_is_named():
    X, faces = octahedron()
    X = np.vstack([X, [[5.0, 5.0, 5.0]]])
    with pytest.raises(MeshError, match=r"vertex 6 belongs to no face"):
        validate_surface(X, faces)


@pytest.mark.parametrize("flip", [False, True])
def test_duplicate_face_names_both_faces(flip):
    X, faces = octahedron()
    extra = faces[2][::-1] if flip else faces[2]
    faces = np.vstack([faces, extra])
    with pytest.raises(MeshError, match=r"face 8 .* duplicates face 2"):
        validate_surface(X, faces)


def test_open_surface_names_a_boundary_edge():
    X, faces = octahedron()
    removed = faces[4]  # (2, 0, 5): its three edges become boundary edges
    faces = np.delete(faces, 4, axis=0)
    first = min(tuple(sorted(e)) for e in [(removed[0], removed[1]), (removed[1], removed[2]),
                                           (removed[2], removed[0])])
    with pytest.raises(MeshError, match=rf"edge \({first[0]}, {first[1]}\) belongs to only one "
                                        r"face .*not closed"):
        validate_surface(X, faces)


def test_non_manifold_edge_names_the_edge():
    X, faces = octahedron()
    # a fin on edge (0, 2) with a new vertex 6: edge (0, 2) now has three faces
    X = np.vstack([X, [[1.0, 1.0, 0.0]]])
    faces = np.vstack([faces, [0, 2, 6]])
    with pytest.raises(MeshError, match=r"edge \(0, 2\) is shared by 3 faces \[0, 4, 8\]"):
        validate_surface(X, faces)


def test_inconsistent_orientation_names_the_flipped_face():
    X, faces = octahedron()
    faces[3] = faces[3][::-1]  # (4, 0, 3): its first sorted edge is (0, 3), shared with face 7
    with pytest.raises(MeshError, match=r"edge \(0, 3\) .* same direction by faces 3 and 7"):
        validate_surface(X, faces)


def test_bowtie_vertex_is_named():
    # two tetrahedra sharing only vertex 0: every edge has two faces, consistently oriented.
    # The second is the point reflection of the first through its vertex 0 (det = -1, so its
    # faces are reversed to stay outward).
    Xa, fa = tetrahedron()
    Xb = 2 * Xa[0] - Xa
    X = np.vstack([Xa, Xb[1:]])
    fb = np.where(fa == 0, 0, fa + 3)[:, ::-1]
    faces = np.vstack([fa, fb])
    with pytest.raises(MeshError, match=r"vertex 0 is a non-manifold \(bowtie\) vertex: its faces "
                                        r"form 2 separate fans"):
        validate_surface(X, faces)


def test_two_components_are_refused():
    Xa, fa = tetrahedron()
    Xb, fb = tetrahedron(offset=(10.0, 0.0, 0.0))
    with pytest.raises(MeshError, match=r"2 connected components \(vertex 4"):
        validate_surface(np.vstack([Xa, Xb]), np.vstack([fa, fb + 4]))


def test_torus_is_refused_by_its_euler_characteristic():
    X, faces = torus()
    n = len(X)  # V - E + F = n - 3n + 2n = 0 for a torus
    with pytest.raises(MeshError, match=rf"= {n} - {3 * n} \+ {2 * n} = 0, i.e. genus 1"):
        validate_surface(X, faces)


def test_zero_area_face_is_named():
    X, faces = octahedron()
    X[4] = 0.5 * (X[0] + X[2])  # face 0 = (0, 2, 4) becomes collinear; no other face does
    with pytest.raises(MeshError, match=r"face 0 \[0, 2, 4\] is degenerate"):
        validate_surface(X, faces)


def test_inward_orientation_says_flip():
    X, faces = octahedron()
    with pytest.raises(MeshError, match=r"volume is negative \(-1.33333\).*inward.*flip"):
        validate_surface(X, faces[:, ::-1])


def test_quality_of_the_icosahedron():
    # regular icosahedron inscribed in the unit sphere: edge 4 / sqrt(10 + 2 sqrt 5), all
    # angles 60 deg, twelve vertices of valence 5
    q = mesh_quality(icosphere(1))
    a = 4.0 / np.sqrt(10.0 + 2.0 * np.sqrt(5.0))
    assert (q.n_vertices, q.n_edges, q.n_faces) == (12, 30, 20)
    assert q.min_angle_deg == pytest.approx(60.0) and q.max_angle_deg == pytest.approx(60.0)
    assert q.edge_min == pytest.approx(a) and q.edge_max == pytest.approx(a)
    assert q.edge_rel_std == pytest.approx(0.0, abs=1e-12)
    assert q.area_ratio == pytest.approx(1.0)
    assert q.valence_histogram == {5: 12}


def test_quality_of_a_stretched_octahedron():
    # apex (0, 0, 2), base (1, 0, 0), (0, 1, 0): apex angle acos(4/5), base angles half the
    # rest; 4 equatorial edges sqrt 2 and 8 slanted edges sqrt 5
    q = mesh_quality(Mesh.from_arrays(*octahedron(scale_z=2.0)))
    apex = np.degrees(np.arccos(0.8))
    assert q.min_angle_deg == pytest.approx(apex)
    assert q.max_angle_deg == pytest.approx((180.0 - apex) / 2.0)
    assert q.mean_angle_deg == pytest.approx(60.0)  # angles of a triangle sum to 180
    lengths = np.array([np.sqrt(2)] * 4 + [np.sqrt(5)] * 8)
    assert q.edge_min == pytest.approx(np.sqrt(2)) and q.edge_max == pytest.approx(np.sqrt(5))
    assert q.edge_mean == pytest.approx(lengths.mean())
    assert q.edge_rel_std == pytest.approx(lengths.std() / lengths.mean())
    assert q.valence_histogram == {4: 6}
    text = str(q)
    assert "6 vertices, 12 edges, 8 faces" in text and f"min {apex:.2f}" in text
    assert q.to_dict()["valence_histogram"] == {4: 6}
