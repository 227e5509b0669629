"""Reading and writing Surface Evolver datafiles and dumps (shellbuckle.mesh.evolver_io)."""

import logging
from pathlib import Path

import numpy as np
import pytest

from shellbuckle.mesh import icosphere
from shellbuckle.mesh.evolver_io import read_evolver, write_evolver

FIXTURES = Path(__file__).parent / "fixtures" / "evolver"

# Regular-ish tetrahedron with vertex ids 10, 20, 30, 40 (not consecutive), faces given by signed
# edge lists that start at different edges, comments of both kinds, a spliced line, expressions
# and a read section holding text that is not valid datafile syntax.
TETRA = r"""
// hand-made tetrahedron
/* a block comment
   over two lines */
parameter side = 2
parameter hz = side/4   // 0.5
define facet attribute poisson_ratio real
define facet attribute form_factors real[3]
quantity bend energy modulus 3 method star_perp_sq_mean_curvature global
quantity stretch energy \
    modulus side*10 method linear_elastic global
parameter h_zero = hz

vertices
10  0 0 0   fixed
20  side 0 0
30  0 side 0
40  0 0 -(-side)   /* = 2 */

edges:   // ':' is whitespace in datafiles
1 10 20
2 20 30
3 30 10
4 10 40
5 20 40
6 30 40

faces
1  -3 -2 -1          // 10 -> 30 -> 20 : normal -z, outward
2  1 5 -4            // 10 -> 20 -> 40 : normal -y, outward
3  -5 2 6, poisson_ratio 0.3    // 40 -> 20 -> 30 : normal (1,1,1), outward
4  4 -6 3            // 10 -> 40 -> 30 : normal -x, outward

bodies
1  1 2 3 4  volume 1.5

read
this is { not "datafile syntax
gogo := { g 5; r }
"""


def _write(tmp_path, text, name="t.fe"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _cycle(face):
    """Rotation-invariant form of an oriented triangle."""
    k = int(np.argmin(face))
    return tuple(int(face[(k + j) % 3]) for j in range(3))


def test_handmade_tetrahedron_signed_edges(tmp_path, caplog):
    with caplog.at_level(logging.INFO, logger="shellbuckle.mesh.evolver_io"):
        evf = read_evolver(_write(tmp_path, TETRA))
    mesh = evf.mesh
    assert evf.vertex_ids.tolist() == [10, 20, 30, 40]
    np.testing.assert_array_equal(mesh.X, [[0, 0, 0], [2, 0, 0], [0, 2, 0], [0, 0, 2]])
    # each face starts at the tail of its first listed edge (Evolver's facet vertex order)
    idx = {10: 0, 20: 1, 30: 2, 40: 3}
    expected = [[10, 30, 20], [10, 20, 40], [40, 20, 30], [10, 40, 30]]
    assert mesh.faces.tolist() == [[idx[v] for v in f] for f in expected]
    # outward orientation: the divergence-theorem volume is the tetrahedron's, side^3/6
    x = mesh.X[mesh.faces]
    assert np.einsum("ij,ij->", x[:, 0], np.cross(x[:, 1], x[:, 2])) / 6 == pytest.approx(8 / 6)
    assert evf.facet_sign.tolist() == [1, 1, 1, 1]
    assert evf.fixed.tolist() == [True, False, False, False]
    assert evf.volume == 1.5
    assert evf.h_zero == 0.5
    assert evf.parameters["side"] == 2.0
    assert evf.poisson_ratio.tolist() == [0.0, 0.0, 0.3, 0.0]
    assert evf.form_factors.shape == (4, 3) and not evf.form_factors.any()
    methods = {q.name: (q.kind, q.method, q.modulus, q.is_global) for q in evf.quantities}
    assert methods == {"bend": ("energy", "star_perp_sq_mean_curvature", 3.0, True),
                       "stretch": ("energy", "linear_elastic", 20.0, True)}
    assert any("read" in s and "not executed" in s for s in evf.skipped)
    assert any("read" in r.getMessage() for r in caplog.records)


def test_inward_body_facets_are_reversed_with_their_form_factors(tmp_path):
    # The same tetrahedron with every facet listed inwards and the body listing them negative.
    # form_factors are the facets' own Gram matrices (in file vertex order), so after reading
    # they must equal the Gram matrices of the mesh faces: the shape is its own rest shape.
    X = np.array([[0, 0, 0], [2, 0, 0], [0, 2.5, 0], [0.3, 0.2, 1.7]])
    inward = [[0, 1, 2], [0, 3, 1], [3, 2, 1], [0, 2, 3]]  # file vertex order, normals inward
    edges = {(0, 1): 1, (1, 2): 2, (0, 2): 3, (0, 3): 4, (1, 3): 5, (2, 3): 6}
    lines = ["define facet attribute form_factors real[3]", "define facet attribute poisson_ratio real",
             "vertices"] + [f"{i + 1} {a!r} {b!r} {c!r}" for i, (a, b, c) in enumerate(X.tolist())] + ["edges"]
    lines += [f"{e} {i + 1} {j + 1}" for (i, j), e in edges.items()] + ["faces"]
    for k, f in enumerate(inward):
        signed = []
        for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
            signed.append(edges[(a, b)] if (a, b) in edges else -edges[(b, a)])
        s, t = X[f[1]] - X[f[0]], X[f[2]] - X[f[0]]
        lines.append(f"{k + 1} {signed[0]} {signed[1]} {signed[2]} poisson_ratio 0.3 "
                     f"form_factors {{{float(s @ s)!r}, {float(s @ t)!r}, {float(t @ t)!r}}}")
    lines += ["bodies", "1 -1 -2 -3 -4 volume 0.9"]
    evf = read_evolver(_write(tmp_path, "\n".join(lines)))
    assert evf.facet_sign.tolist() == [-1, -1, -1, -1]
    x = evf.mesh.X[evf.mesh.faces]
    assert np.einsum("ij,ij->", x[:, 0], np.cross(x[:, 1], x[:, 2])) > 0  # outward now
    s, t = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    gram = np.stack([(s * s).sum(1), (s * t).sum(1), (t * t).sum(1)], axis=1)
    np.testing.assert_allclose(evf.form_factors, gram, rtol=1e-14)
    # each reversed face still starts at the facet's first vertex
    assert [f[0] for f in evf.mesh.faces.tolist()] == [f[0] for f in inward]


def test_no_body_inward_surface_is_turned_outward(tmp_path):
    faces_in = ("faces\n1 1 2 3\n2 4 -5 -1\n3 -6 -2 5\n4 -3 6 -4\n")  # all normals inward
    start, end = TETRA.index("faces\n"), TETRA.index("read\n")
    evf = read_evolver(_write(tmp_path, TETRA[:start] + faces_in))
    x = evf.mesh.X[evf.mesh.faces]
    assert np.einsum("ij,ij->", x[:, 0], np.cross(x[:, 1], x[:, 2])) / 6 == pytest.approx(8 / 6)
    assert evf.facet_sign.tolist() == [-1, -1, -1, -1]
    assert evf.volume is None
    assert end > start


@pytest.mark.parametrize("line, expected", [
    ("1 0.5 -0.5 0", [0.5, -0.5, 0.0]),           # signed numbers are separate values
    ("1 1 - 0.5 0 0", [0.5, 0.0, 0.0]),           # '1 - 0.5' is one expression
    ("1 -sqrt(2)/2 2^3 (1 -1)", [-2 ** 0.5 / 2, 8.0, 0.0]),  # unary minus; inside () binary
    ("1 pi*0 1e-3 2.5D1", [0.0, 1e-3, 25.0]),
    ("1 w*2 -w 0x10", [3.0, -1.5, 16.0]),
])
def test_vertex_coordinate_expressions(tmp_path, line, expected):
    text = (f"parameter w = 1.5\nvertices\n{line}\n2 5 0 0\n3 0 5 0\n4 0 0 5\n"
            "edges\n1 1 2\n2 2 3\n3 3 1\n4 1 4\n5 2 4\n6 3 4\n"
            "faces\n1 -3 -2 -1\n2 1 5 -4\n3 2 6 -5\n4 3 4 -6\n")
    evf = read_evolver(_write(tmp_path, text))
    np.testing.assert_allclose(evf.mesh.X[0], expected, rtol=0, atol=1e-15)


def test_macros_and_include(tmp_path):
    (tmp_path / "common.inc").write_text("parameter hz = 0.25\n")
    text = '#define HZ hz\n#include "common.inc"\n' + TETRA.replace("parameter h_zero = hz",
                                                                    "parameter h_zero = 2*HZ")
    text = text.replace("parameter hz = side/4   // 0.5\n", "")
    evf = read_evolver(_write(tmp_path, text))
    assert evf.h_zero == 0.5


BAD = [
    ("10  0 0 0   fixed", "10  0 0   fixed", "line 15: vertex 10 needs 3 coordinates"),
    ("1  -3 -2 -1 ", "1  -3 -1 -2 ", "do not form a closed loop"),
    ("1  -3 -2 -1 ", "1  -3 -2 -7 ", "uses edge 7, which is not defined"),
    ("40  0 0 -(-side)", "40  0 0 -(-sidex)", "unknown name 'sidex'"),
    ("20  side 0 0", "20  side 0 0 shiny", "unknown vertex attribute or quantity 'shiny'"),
    ("parameter side = 2", "quadratic\nparameter side = 2", "the quadratic model is not supported"),
    ("1 10 20", "1 10 99", "uses vertex 99, which is not defined"),
    ("1  1 2 3 4  volume 1.5", "1  1 2 3 4  volume 1.5\n2 -1 -2 -3 -4", "only one closed body"),
]


@pytest.mark.parametrize("old, new, message", BAD)
def test_bad_input_names_the_problem(tmp_path, old, new, message):
    assert old in TETRA
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        read_evolver(_write(tmp_path, TETRA.replace(old, new, 1)))


def test_square_facet_is_refused(tmp_path):
    text = ("vertices\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\nedges\n1 1 2\n2 2 3\n3 3 4\n4 4 1\n"
            "faces\n1 1 2 3 4\n")
    with pytest.raises(ValueError, match=r"line 12: facet 1 has 4 edges; only triangles"):
        read_evolver(_write(tmp_path, text))


def test_open_surface_is_refused(tmp_path):
    text = TETRA.replace("4  4 -6 3            // 10 -> 40 -> 30 : normal -x, outward", "")
    text = text.replace("1  1 2 3 4  volume 1.5", "1  1 2 3  volume 1.5")
    with pytest.raises(ValueError, match="closed oriented surface"):
        read_evolver(_write(tmp_path, text))


def test_missing_file():
    with pytest.raises(FileNotFoundError):
        read_evolver("/nonexistent/nothing.fe")


def _perturbed_sphere(n=3, seed=3):
    mesh = icosphere(n)
    rng = np.random.default_rng(seed)
    return mesh.with_positions(mesh.X * (1 + 0.05 * rng.uniform(-1, 1, (mesh.n_vertices, 1))))


def test_write_read_round_trip_is_exact(tmp_path):
    mesh = _perturbed_sphere()
    rest = icosphere(3).X
    x = rest[mesh.faces]
    s, t = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    ff = np.stack([(s * s).sum(1), (s * t).sum(1), (t * t).sum(1)], axis=1)
    path = write_evolver(tmp_path / "w.fe", mesh, kappa=0.8, c0=1.7, A=123.4, nu=0.3,
                         form_factors=ff, volume=3.9)
    evf = read_evolver(path)
    np.testing.assert_array_equal(evf.mesh.X, mesh.X)
    np.testing.assert_array_equal(evf.mesh.faces, mesh.faces)
    np.testing.assert_array_equal(evf.form_factors, ff)
    np.testing.assert_array_equal(evf.poisson_ratio, np.full(len(mesh.faces), 0.3))
    np.testing.assert_array_equal(evf.facet_tension, 0.0)
    assert evf.h_zero == 0.85 and evf.volume == 3.9
    moduli = {q.method: q.modulus for q in evf.quantities if q.kind == "energy"}
    assert moduli == {"linear_elastic": 123.4, "star_perp_sq_mean_curvature": 1.6}
    assert evf.skipped == ()


def test_write_per_vertex_c0_as_h_zero_attribute(tmp_path):
    mesh = _perturbed_sphere(2)
    c0 = np.linspace(-1, 3, mesh.n_vertices)
    evf = read_evolver(write_evolver(tmp_path / "v.fe", mesh, c0=c0))
    np.testing.assert_array_equal(evf.h_zero, c0 / 2)
    # default rest shape: the written shape itself
    x = mesh.X[mesh.faces]
    s, t = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    np.testing.assert_allclose(evf.form_factors[:, 1], (s * t).sum(1), rtol=1e-15)


def test_writer_refuses_bad_values(tmp_path):
    mesh = icosphere(1)
    with pytest.raises(ValueError, match="nu"):
        write_evolver(tmp_path / "x.fe", mesh, nu=1.0)
    with pytest.raises(ValueError, match="c0"):
        write_evolver(tmp_path / "x.fe", mesh, c0=np.zeros(3))
    with pytest.raises(ValueError, match="non-finite"):
        write_evolver(tmp_path / "x.fe", mesh.with_positions(mesh.X * np.nan))


@pytest.mark.parametrize("case", ["sphere_perturbed", "dented", "octahedron_handmade"])
def test_evolver_dump_matches_its_datafile(case):
    """A dump written by Evolver 2.70 reads to the same elements and attributes as the file
    it came from (the positions differ: Evolver moved the vertices before dumping)."""
    fe, dmp = read_evolver(FIXTURES / f"{case}.fe"), read_evolver(FIXTURES / f"{case}.dmp")
    np.testing.assert_array_equal(dmp.mesh.faces, fe.mesh.faces)
    np.testing.assert_array_equal(dmp.vertex_ids, fe.vertex_ids)
    np.testing.assert_array_equal(dmp.facet_sign, fe.facet_sign)
    np.testing.assert_allclose(dmp.form_factors, fe.form_factors, rtol=1e-14)
    np.testing.assert_allclose(dmp.poisson_ratio, fe.poisson_ratio, rtol=1e-14)  # %.15g
    np.testing.assert_array_equal(dmp.fixed, fe.fixed)
    np.testing.assert_allclose(np.asarray(dmp.h_zero), np.asarray(fe.h_zero), rtol=1e-14)
    assert dmp.volume == pytest.approx(fe.volume, rel=1e-14)
    assert [(q.name, q.method, q.modulus, q.is_global) for q in dmp.quantities] == \
        [(q.name, q.method, q.modulus, q.is_global) for q in fe.quantities]
    assert any("VIEW_MATRIX" in s for s in dmp.skipped)
    assert any("'read' section" in s for s in dmp.skipped)
    assert not np.array_equal(dmp.mesh.X, fe.mesh.X)


def test_handmade_octahedron_non_global_quantity():
    evf = read_evolver(FIXTURES / "octahedron_handmade.fe")
    (bend,) = [q for q in evf.quantities if q.method == "star_perp_sq_mean_curvature"]
    assert not bend.is_global and bend.modulus == pytest.approx(2.0)
    # vertex 3 is the only one not listing the quantity
    assert sorted(evf.vertex_ids[bend.vertices].tolist()) == [1, 2, 4, 5, 6]
    np.testing.assert_array_equal(evf.facet_tension, [0, 0.5, 1, 0, 1, 1, 1, 1])
    np.testing.assert_array_equal(evf.h_zero, [0.1, 0.2, 0.3, 0.4, 0.5, -0.6])
    assert evf.mesh.X[5, 2] == -1.0 and evf.mesh.X[0, 0] == 1.1
