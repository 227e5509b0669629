import numpy as np
import pytest

from shellbuckle.mesh.topology import MeshError, Topology

OCTAHEDRON = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                       [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])


def test_octahedron_counts_and_euler():
    t = Topology.from_faces(OCTAHEDRON)
    assert (t.n_vertices, t.n_edges, t.n_faces) == (6, 12, 8)
    assert t.euler_characteristic == 2
    assert (t.valence() == 4).all()


def test_hinges_are_consistent_with_faces():
    t = Topology.from_faces(OCTAHEDRON)
    for e, (i, j, k, l) in enumerate(t.hinges):
        f0, f1 = t.faces[t.edge_faces[e]]
        # face 0 contains i -> j -> k cyclically, face 1 contains j -> i -> l
        assert any((np.roll(f0, s) == [i, j, k]).all() for s in range(3))
        assert any((np.roll(f1, s) == [j, i, l]).all() for s in range(3))
    for f in range(t.n_faces):
        for c in range(3):
            e = t.face_edges[f, c]
            assert set(t.edges[e]) == set(t.faces[f]) - {t.faces[f, c]}


def test_open_surface_is_refused_naming_the_edge():
    with pytest.raises(MeshError, match=r"edge \(\d+, \d+\) belongs to 1 faces"):
        Topology.from_faces(OCTAHEDRON[:-1])


def test_flipped_face_is_refused():
    faces = OCTAHEDRON.copy()
    faces[3] = faces[3, ::-1]
    with pytest.raises(MeshError, match="not consistently oriented"):
        Topology.from_faces(faces)
