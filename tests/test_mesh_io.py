import struct

import meshio
import numpy as np
import pytest
from scipy.spatial import cKDTree

from shellbuckle.mesh import Mesh, MeshError, icosphere, random_sphere, read_mesh, write_mesh
from shellbuckle.mesh.io import MESHIO_FORMATS

EXACT = [".vtk", ".vtu", ".ply", ".obj", ".off", ".msh", ".mesh", ".inp"]


@pytest.fixture(scope="module")
def mesh():
    m = random_sphere(200, seed=7, R=1.3)
    # a non-spherical, non-round-number shape to exercise the float output
    return m.with_positions(m.X * np.array([1.0, 0.8, 1.2]) + np.array([0.1, -0.2, 1.0 / 3.0]))


def _oriented_face_set(faces):
    shift = np.argmin(faces, axis=1)
    rolled = np.take_along_axis(faces, (shift[:, None] + np.arange(3)) % 3, axis=1)
    return {tuple(f) for f in rolled.tolist()}


@pytest.mark.parametrize("ext", EXACT)
def test_round_trip_is_exact(tmp_path, mesh, ext):
    path = write_mesh(tmp_path / f"m{ext}", mesh)
    back = read_mesh(path)
    assert back.X.tobytes() == mesh.X.tobytes()
    assert np.array_equal(back.faces, mesh.faces)


def test_xdmf_round_trip(tmp_path, mesh):
    pytest.importorskip("h5py")
    back = read_mesh(write_mesh(tmp_path / "m.xdmf", mesh))
    assert np.array_equal(back.X, mesh.X) and np.array_equal(back.faces, mesh.faces)


def test_stl_round_trip_merges_vertices(tmp_path, mesh):
    back = read_mesh(write_mesh(tmp_path / "m.stl", mesh))
    # STL stores every vertex once per facet, as float32: same vertex count after merging,
    # positions within float32 rounding, same oriented faces up to the vertex numbering
    assert back.n_vertices == mesh.n_vertices and len(back.faces) == len(mesh.faces)
    dist, perm = cKDTree(mesh.X).query(back.X)
    assert dist.max() < 4 * np.finfo(np.float32).eps * np.abs(mesh.X).max()
    assert len(np.unique(perm)) == mesh.n_vertices
    assert _oriented_face_set(perm[back.faces]) == _oriented_face_set(mesh.faces)


def test_hand_written_binary_stl_is_merged(tmp_path):
    # an octahedron as 8 independent facets (24 vertex records for 6 vertices)
    X = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                      [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    path = tmp_path / "octa.stl"
    with open(path, "wb") as fh:
        fh.write(b"solid-looking header but binary".ljust(80, b" "))
        fh.write(struct.pack("<I", len(faces)))
        for f in faces:
            fh.write(struct.pack("<12fH", 0, 0, 0, *X[f].ravel(), 0))
    m = read_mesh(path)
    assert m.n_vertices == 6 and len(m.faces) == 8
    x0, x1, x2 = (m.X[m.faces[:, k]] for k in range(3))
    assert np.einsum("ij,ij->", x0, np.cross(x1, x2)) / 6 == pytest.approx(4.0 / 3.0)


@pytest.mark.parametrize("ext", [".vtu", ".vtk", ".msh"])
def test_point_and_cell_data_are_written(tmp_path, mesh, ext):
    h = np.linalg.norm(mesh.X, axis=1)
    u = mesh.X - mesh.X.mean(axis=0)
    area = np.arange(len(mesh.faces), dtype=float)
    path = write_mesh(tmp_path / f"d{ext}", mesh, point_data={"h": h, "u": u},
                      cell_data={"area": area})
    m = meshio.read(path)
    np.testing.assert_array_equal(m.point_data["h"], h)
    np.testing.assert_array_equal(m.point_data["u"], u)
    np.testing.assert_array_equal(m.cell_data["area"][0], area)


def test_ply_keeps_scalar_point_data_and_refuses_vectors(tmp_path, mesh):
    h = np.linalg.norm(mesh.X, axis=1)
    m = meshio.read(write_mesh(tmp_path / "d.ply", mesh, point_data={"h": h}))
    np.testing.assert_array_equal(m.point_data["h"], h)
    with pytest.raises(ValueError, match="scalar point data only"):
        write_mesh(tmp_path / "v.ply", mesh, point_data={"u": mesh.X})


def test_data_for_a_format_without_data_is_refused(tmp_path, mesh):
    with pytest.raises(ValueError, match=r"\.obj files cannot store point_data"):
        write_mesh(tmp_path / "d.obj", mesh, point_data={"h": np.zeros(mesh.n_vertices)})
    with pytest.raises(ValueError, match="length 396"):
        write_mesh(tmp_path / "d.vtu", mesh, cell_data={"a": np.zeros(3)})


@pytest.mark.parametrize("name", ["m.xyz", "m", "m.vtk.bak"])
def test_unsupported_extension_lists_the_allowed_ones(tmp_path, mesh, name):
    with pytest.raises(ValueError, match=r"unsupported mesh file extension.*allowed: .vtk"):
        write_mesh(tmp_path / name, mesh)
    with pytest.raises(ValueError, match=r"\.fe, \.dmp"):
        read_mesh(tmp_path / name)


def test_every_listed_extension_is_known_to_meshio():
    from meshio._helpers import extension_to_filetypes
    for ext, (fmt, _) in MESHIO_FORMATS.items():
        assert fmt in extension_to_filetypes[ext]


def test_other_cell_types_are_refused(tmp_path):
    points = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    path = tmp_path / "quad.vtu"
    meshio.write(path, meshio.Mesh(points, [("quad", np.array([[0, 1, 2, 3]]))]))
    with pytest.raises(ValueError, match="contains quad cells; only triangle"):
        read_mesh(path)


def test_reading_an_open_surface_names_the_edge(tmp_path):
    m = icosphere(2)
    faces = m.faces[1:]
    path = tmp_path / "open.vtu"
    meshio.write(path, meshio.Mesh(m.X, [("triangle", faces)]))
    f0 = np.sort(m.faces[0])
    with pytest.raises(MeshError, match=rf"edge \({f0[0]}, {f0[1]}\) belongs to only one face"):
        read_mesh(path)


def test_reading_an_inward_surface_says_flip(tmp_path):
    m = icosphere(2)
    path = tmp_path / "inward.off"
    meshio.write(path, meshio.Mesh(m.X, [("triangle", m.faces[:, ::-1])]))
    with pytest.raises(MeshError, match="inward.*flip"):
        read_mesh(path)


def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        read_mesh(tmp_path / "nothere.vtu")


def test_evolver_round_trip(tmp_path, mesh):
    pytest.importorskip("shellbuckle.mesh.evolver_io")
    back = read_mesh(write_mesh(tmp_path / "m.fe", mesh))
    assert isinstance(back, Mesh) and back.n_vertices == mesh.n_vertices
    dist, perm = cKDTree(mesh.X).query(back.X)
    assert dist.max() < 1e-12
    assert _oriented_face_set(perm[back.faces]) == _oriented_face_set(mesh.faces)
