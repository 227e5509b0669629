"""Exports of a stored step (shellbuckle.export): mesh formats, data fields, Surface Evolver."""


import meshio
import numpy as np
import pytest

from shellbuckle import ShellParameters
from shellbuckle.cli import main
from shellbuckle.energies.evolver import evolver_energy
from shellbuckle.export import FORMATS, export_step
from shellbuckle.mesh import icosphere
from shellbuckle.mesh.evolver_io import read_evolver
from shellbuckle.mesh.io import read_mesh
from shellbuckle.run import deflate, params_for_mesh, shell_from_file

GAMMA = 271.0
NU = 1.0 / 3.0


def _tiny_run(path, bending):
    """icosphere(3) (92 vertices), two volume steps past the start."""
    return deflate(icosphere(3), ShellParameters.from_gamma(GAMMA, nu=NU), schedule=[0.02, 0.04],
                   bending=bending, out=path)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("runs")
    return {b: _tiny_run(base / b, b) for b in ("juelicher", "evolver")}


def _row(run, step):
    table = run.table
    return table[table["step"] == step].iloc[0]


def _face_areas(X, faces):
    x = X[faces]
    return 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)


# ------------------------------------------------------------------------------ geometry
@pytest.mark.parametrize("fmt", ["vtk", "vtu", "ply", "obj", "fe"])
def test_read_back_gives_the_same_positions_and_faces(runs, tmp_path, fmt):
    run = runs["juelicher"]
    for step in run.steps:
        path = export_step(run, step, tmp_path / f"s{step}.{fmt}")
        mesh = read_mesh(path)  # also validates: closed, manifold, outward, genus 0
        np.testing.assert_array_equal(mesh.X, run.positions(step))
        np.testing.assert_array_equal(mesh.faces, run.faces)


def test_stl_read_back_gives_float32_positions_and_the_same_triangles(runs, tmp_path):
    run = runs["juelicher"]
    X = run.positions(2)
    mesh = read_mesh(export_step(run, 2, tmp_path / "s.stl"))
    X32 = X.astype(np.float32).astype(np.float64)
    assert len(mesh.X) == len(X)
    # STL keeps one vertex copy per facet: vertices come back renumbered; match them by value
    key = {tuple(p): i for i, p in enumerate(X32)}
    index = np.array([key[tuple(p)] for p in mesh.X])
    np.testing.assert_array_equal(mesh.X, X32[index])
    np.testing.assert_array_equal(index[mesh.faces], run.faces)


def test_format_is_taken_from_the_extension_or_appended(runs, tmp_path):
    run = runs["juelicher"]
    assert export_step(run, 1, tmp_path / "a.vtu").suffix == ".vtu"
    out = export_step(run, 1, tmp_path / "b", fmt="ply")
    assert out == tmp_path / "b.ply" and out.is_file()


def test_a_ply_file_is_written_without_a_warning_and_reads_back(runs, tmp_path, capfd):
    """PLY has no 64-bit integers: the faces are written as 32-bit ones, so meshio neither
    converts them nor prints its own warning, and they read back as they were."""
    import meshio

    run = runs["juelicher"]
    capfd.readouterr()
    out = export_step(run, 1, tmp_path / "c.ply")
    captured = capfd.readouterr()
    assert "Warning" not in captured.out + captured.err
    back = meshio.read(out)
    np.testing.assert_array_equal(back.cells_dict["triangle"], run.faces)
    np.testing.assert_allclose(back.points, run.positions(1), rtol=1e-15)


# ------------------------------------------------------------------------------ data fields
@pytest.mark.parametrize("fmt", ["vtk", "vtu"])
def test_point_and_cell_data(runs, tmp_path, fmt):
    run = runs["juelicher"]
    X0 = run.positions(0)
    faces = run.faces
    rest_area = _face_areas(X0, faces)
    for step in run.steps:
        m = meshio.read(export_step(run, step, tmp_path / f"s{step}.{fmt}"))
        X = run.positions(step)
        np.testing.assert_array_equal(m.point_data["displacement"], X - X0)
        # energy densities integrate to the table's energies: stretching per rest area of each
        # face, bending per Jülicher vertex area A_i = (1/3) sum of the areas of its faces
        w_s = m.cell_data["stretching_energy_density"][0]
        assert w_s.shape == (len(faces),) and (w_s >= 0).all()
        row = _row(run, step)
        assert np.dot(w_s, rest_area) == pytest.approx(row["E_stretch"], rel=1e-10, abs=1e-14)
        vertex_area = np.bincount(faces.ravel(), np.repeat(_face_areas(X, faces) / 3, 3))
        w_b = m.point_data["bending_energy_density"]
        assert np.dot(w_b, vertex_area) == pytest.approx(row["E_bend"], rel=1e-10)
        H = m.point_data["H"]
        np.testing.assert_allclose(w_b, 0.5 * (2 * H - 2.0) ** 2, rtol=1e-12, atol=1e-15)
    # step 0 is the stress-free initial sphere of radius 1: no strain; H near 1/R everywhere
    # (largest error at the 12 five-valent vertices) and total mean curvature near 4 pi R
    m0 = meshio.read(tmp_path / f"s0.{fmt}")
    assert np.abs(m0.cell_data["stretching_energy_density"][0]).max() < 1e-20
    H0 = m0.point_data["H"]
    assert (H0 > 0.95).all() and (H0 < 1.2).all()
    vertex_area0 = np.bincount(faces.ravel(), np.repeat(rest_area / 3, 3))
    assert np.dot(H0, vertex_area0) == pytest.approx(4 * np.pi, rel=0.02)


def test_ply_keeps_scalar_point_data(runs, tmp_path):
    run = runs["juelicher"]
    m = meshio.read(export_step(run, 2, tmp_path / "s.ply"))
    u = run.positions(2) - run.positions(0)
    for i, c in enumerate("xyz"):
        np.testing.assert_allclose(m.point_data[f"displacement_{c}"], u[:, i], rtol=0, atol=0)
    ref = meshio.read(export_step(run, 2, tmp_path / "s.vtu"))
    np.testing.assert_array_equal(m.point_data["H"], ref.point_data["H"])


# ------------------------------------------------------------------------------ Surface Evolver
def test_fe_energies_match_the_table_with_evolver_bending(runs, tmp_path):
    run = runs["evolver"]
    V0 = evolver_energy(export_step(run, 0, tmp_path / "s0.fe"))["volume"]
    for step in run.steps:
        e = evolver_energy(export_step(run, step, tmp_path / f"s{step}.fe"))
        row = _row(run, step)
        assert e["E_stretch"] == pytest.approx(row["E_stretch"], rel=1e-10, abs=1e-14)
        assert e["E_bend"] == pytest.approx(row["E_bend"], rel=1e-10)
        assert e["volume"] == pytest.approx(V0 * (1 - row["dV_over_V"]), rel=1e-12)


def test_fe_stretching_matches_the_table_with_juelicher_bending(runs, tmp_path):
    run = runs["juelicher"]
    for step in run.steps:
        e = evolver_energy(export_step(run, step, tmp_path / f"s{step}.fe"))
        assert e["E_stretch"] == pytest.approx(_row(run, step)["E_stretch"], rel=1e-10, abs=1e-14)


def test_fe_carries_the_run_parameters_and_the_initial_sphere_as_rest_state(runs, tmp_path):
    run = runs["juelicher"]
    evf = read_evolver(export_step(run, 2, tmp_path / "s.fe"))
    (stretch,) = evf.energy_quantities("linear_elastic")
    (bend,) = evf.energy_quantities("star_perp_sq_mean_curvature")
    assert stretch.modulus == GAMMA  # A = gamma kappa / R^2 with kappa = R = 1
    assert bend.modulus == 2.0  # 2 kappa
    assert evf.h_zero == 1.0  # c0 / 2 with c0 = 2/R
    np.testing.assert_array_equal(evf.poisson_ratio, NU)
    X0 = run.positions(0)
    s = X0[run.faces[:, 1]] - X0[run.faces[:, 0]]
    t = X0[run.faces[:, 2]] - X0[run.faces[:, 0]]
    expected = np.stack([(s * s).sum(1), (s * t).sum(1), (t * t).sum(1)], axis=1)
    np.testing.assert_allclose(evf.form_factors, expected, rtol=1e-15, atol=0)


def test_a_run_started_from_an_exported_fe_continues_with_the_same_energy(runs, tmp_path):
    parent = runs["evolver"]
    step = parent.steps[-1]
    mesh, found = shell_from_file(export_step(parent, step, tmp_path / "last.fe"))
    params = params_for_mesh(mesh, found)
    assert found["A"] == GAMMA and found["nu"] == NU and found["kappa"] == 1.0
    child = deflate(mesh, params, schedule=[0.05], bending="evolver", c0=found["c0"],
                    form_factors=found["form_factors"], out=tmp_path / "child")
    start, row = _row(child, 0), _row(parent, step)
    assert start["E_stretch"] == pytest.approx(row["E_stretch"], rel=1e-10)
    assert start["E_bend"] == pytest.approx(row["E_bend"], rel=1e-10)
    assert len(child.steps) == 2  # and it deflates on from there


def test_bad_step_and_format_are_refused_with_what_is_allowed(runs, tmp_path):
    run = runs["juelicher"]
    with pytest.raises(ValueError, match=r"allowed steps: 0\.\.2"):
        export_step(run, 7, tmp_path / "a.vtu")
    with pytest.raises(ValueError, match="allowed formats: " + ", ".join(FORMATS)):
        export_step(run, 1, tmp_path / "a.xyz", fmt="xyz")
    with pytest.raises(ValueError, match="give a format"):
        export_step(run, 1, tmp_path / "a.xyz")
    with pytest.raises(ValueError, match="does not match the format"):
        export_step(run, 1, tmp_path / "a.vtu", fmt="fe")


def test_negative_step_counts_from_the_last(runs, tmp_path):
    run = runs["juelicher"]
    mesh = read_mesh(export_step(run, -1, tmp_path / "last.obj"))
    np.testing.assert_array_equal(mesh.X, run.positions(run.steps[-1]))


def test_cli_export(runs, tmp_path, monkeypatch, capsys):
    run = runs["evolver"]
    out = tmp_path / "x.fe"
    assert main(["export", str(run.path), "--step", "2", "--format", "fe", "--out", str(out)]) == 0
    assert evolver_energy(out)["E_bend"] == pytest.approx(_row(run, 2)["E_bend"], rel=1e-10)
    monkeypatch.chdir(tmp_path)
    assert main(["export", str(run.path), "--step", "1", "--format", "VTU"]) == 0
    assert (tmp_path / f"{run.path.name}_step001.vtu").is_file()
    capsys.readouterr()
    assert main(["export", str(run.path), "--step", "5", "--format", "vtu"]) == 2
    assert "allowed steps: 0..2" in capsys.readouterr().err
    assert main(["export", str(run.path), "--step", "1", "--format", "gltf"]) == 2
    assert "allowed: vtk, vtu, ply, obj, stl, fe" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "missing"), "--step", "1", "--format", "vtu"]) == 2


def test_a_surface_evolver_file_keeps_its_bending_energy_by_default(tmp_path, capsys):
    """deflate --mesh FILE.fe with no --bending bends with the file's own
    star_perp_sq_mean_curvature: the stored step 0 has the energy Surface Evolver's quantities
    give for the file (evolver-energy), not the Jülicher discretization's."""
    from pathlib import Path

    from shellbuckle.run import Run

    fe = Path(__file__).parent / "fixtures" / "evolver" / "sphere_perturbed.fe"
    own = evolver_energy(read_evolver(fe))
    out = tmp_path / "run"
    assert main(["deflate", "--mesh", str(fe), "--schedule", "0.01", "--out", str(out),
                 "--no-plot", "--quiet", "--threads", "1"]) == 0
    run = Run.open(out)
    assert run.protocol.bending == "evolver"
    assert run.table["E_bend"].iloc[0] == pytest.approx(own["E_bend"], rel=1e-10)
    capsys.readouterr()
    # an option still overrides the file
    assert main(["deflate", "--mesh", str(fe), "--schedule", "0.01", "--bending", "juelicher",
                 "--out", str(tmp_path / "j"), "--no-plot", "--quiet", "--threads", "1"]) == 0
    assert Run.open(tmp_path / "j").protocol.bending == "juelicher"


def test_a_surface_evolver_file_with_an_energy_we_do_not_model_is_refused(tmp_path, capsys):
    from pathlib import Path

    text = (Path(__file__).parent / "fixtures" / "evolver" / "sphere_perturbed.fe").read_text()
    extra = "quantity gravity_like energy method sq_mean_curvature global\n"
    bad = tmp_path / "bad.fe"
    bad.write_text(extra + text)
    assert main(["deflate", "--mesh", str(bad), "--out", str(tmp_path / "r"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "gravity_like" in err and "sq_mean_curvature" in err and "Traceback" not in err
    assert not (tmp_path / "r").exists()


def test_an_export_never_overwrites_a_file_of_the_run(tmp_path):
    """The Python API too: an XDMF series named mesh.xdmf would write the run's mesh.h5 beside
    it; a step file inside steps/ would sit among the run's steps."""
    import hashlib

    from shellbuckle.export import export_series, export_step
    from shellbuckle.mesh import icosphere
    from shellbuckle.params import ShellParameters
    from shellbuckle.run import deflate

    run = deflate(icosphere(2), ShellParameters.from_gamma(271.0), dv=0.05, until=0.05,
                  seed=1, out=tmp_path / "run")
    digest = {p: hashlib.sha256(p.read_bytes()).hexdigest()
              for p in run.path.rglob("*") if p.is_file()}
    with pytest.raises(ValueError, match="mesh.h5"):
        export_series(run, run.path / "mesh.xdmf")
    with pytest.raises(ValueError, match="steps"):
        export_step(run, -1, run.path / "steps" / "s.vtu")
    after = {p: hashlib.sha256(p.read_bytes()).hexdigest()
             for p in run.path.rglob("*") if p.is_file()}
    assert after == digest
    # beside the run's files, any other name is fine
    assert export_step(run, -1, run.path / "shape.vtu").is_file()
