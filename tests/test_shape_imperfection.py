"""The shape imperfection: a shell whose stress-free shape is a seeded smooth surface near the
sphere, the same surface on every mesh (protocol.imperfection, "shape imperfection")."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from shellbuckle.energies.bending import Bending
from shellbuckle.energies.evolver_bending import StarPerpBending
from shellbuckle.energies.total import with_c0
from shellbuckle.mesh import icosphere
from shellbuckle.mesh.random_sphere import random_sphere
from shellbuckle.params import ShellParameters
from shellbuckle.protocol.deflate import Protocol, init
from shellbuckle.protocol.imperfection import (evaluate, harmonic_index, n_harmonics,
                                               radial_graph_curvature, reference_directions,
                                               shape_coefficients, stress_free_shape)

from test_bending import _fd_errors, _perturbed_icosphere


def _directions(n, seed=0):
    d = np.random.default_rng(seed).standard_normal((n, 3))
    return d / np.linalg.norm(d, axis=1)[:, None]


def test_the_curvature_of_a_translated_sphere_is_two_over_its_radius_everywhere():
    # oracle: a sphere of radius r whose centre is off the origin by t is the radial graph
    # rho(n) = t.n + sqrt(r^2 - |t|^2 + (t.n)^2), far from a sphere about the origin (rho
    # varies by 40 %), and its total curvature is exactly 2/r at every point
    r, t = 1.3, np.array([0.15, -0.1, 0.2])
    n = _directions(500)
    c = radial_graph_curvature(lambda d: np.log((d @ t + np.sqrt(r * r - t @ t + (d @ t) ** 2))
                                                / 0.7), n, 0.7, 1e-3)
    np.testing.assert_allclose(c, 2.0 / r, rtol=1e-6)


@pytest.mark.parametrize("l, m", [(2, 0), (5, -3), (12, 7)])
def test_a_small_harmonic_bump_has_the_curvature_of_linear_theory(l, m):
    # oracle: for r = R (1 + a Y_lm), c = (2 + a (l(l+1) - 2) Y_lm) / R + O(a^2) (the Laplacian
    # of the unit sphere has eigenvalue -l(l+1)); the O(a^2) rest shrinks 10-fold with a
    coefficients = np.zeros(n_harmonics(l))
    coefficients[harmonic_index(l, m)] = 1.0
    n = _directions(400, seed=l)
    Y = evaluate(coefficients, n)
    R = 2.0
    rests = []
    for a in (1e-3, 1e-4):
        c = radial_graph_curvature(lambda d: np.log1p(a * evaluate(coefficients, d)), n, R,
                                   0.02 / max(l, 10))
        linear = (2.0 + a * (l * (l + 1) - 2.0) * Y) / R
        rests.append(np.abs(c - linear).max() / (a * (l * (l + 1)) / R))
    assert rests[0] < 0.05 and rests[1] < 0.2 * rests[0]


def test_the_stress_free_shape_is_the_same_surface_on_two_meshes_and_reproducible():
    # oracle: every vertex of either mesh lies on r(n) = R (1 + a f(n)) at its own material
    # point, with the same f (the seed's field); the radial displacement has the requested
    # rms over the sphere (a R, mean over a fine mesh's nearly uniform vertices); the same
    # seed gives the same shape, another seed another
    a, L = 0.004, 12
    f = shape_coefficients(L, seed=3)
    for mesh in (icosphere(20), random_sphere(3000, seed=3)):
        X, profile = stress_free_shape(mesh.X, a, L, seed=3)
        n = reference_directions(mesh.X)
        R = np.linalg.norm(mesh.X, axis=1).mean()
        np.testing.assert_allclose(np.linalg.norm(X, axis=1), R * (1 + a * evaluate(f, n)),
                                   rtol=1e-13)
        np.testing.assert_allclose(np.cross(X, n), 0.0, atol=1e-13)  # moved radially
        rms = np.sqrt(np.mean((np.linalg.norm(X, axis=1) - R) ** 2))
        assert rms == pytest.approx(a * R, rel=0.05)
        again = stress_free_shape(mesh.X, a, L, seed=3)
        np.testing.assert_array_equal(again[0], X)
        np.testing.assert_array_equal(again[1], profile)
        other = stress_free_shape(mesh.X, a, L, seed=4)[0]
        assert np.abs(other - X).max() > 0.1 * a * R


def test_the_discrete_curvature_of_the_stress_free_shape_converges_to_the_profile():
    # oracle: Jülicher's discrete total curvature 2 H_i of the imperfect mesh tends to the
    # exact curvature of the smooth surface, 2 p_i / R, under refinement (icospheres, whose
    # curvature error falls with the edge)
    a, L = 0.005, 8
    errors = []
    for level in (8, 16, 32):
        mesh = icosphere(level)
        X, profile = stress_free_shape(mesh.X, a, L, seed=1)
        H = Bending.from_mesh(mesh).mean_curvature(X)
        errors.append(np.sqrt(np.mean((2.0 * H - 2.0 * profile) ** 2)))
    assert errors[1] < 0.5 * errors[0] and errors[2] < 0.5 * errors[1]
    assert np.ptp(2.0 * profile) > 10 * errors[2]  # the profile is far from uniform


@pytest.mark.parametrize("seed", [0, 1])
def test_bending_with_a_profile_has_exact_derivatives(seed):
    m, X = _perturbed_icosphere(2, seed)
    profile = 1.0 + 0.3 * np.random.default_rng(seed).standard_normal(m.n_vertices)
    b = Bending.from_mesh(m, kappa=1.3, c0=2.0, c0_profile=profile)
    assert _fd_errors(b.value, lambda Y: b.gradient(Y).ravel(), X) < 1e-6
    assert _fd_errors(lambda Y: b.gradient(Y).ravel(), lambda Y: b.hessian(Y).toarray(),
                      X) < 1e-6


def test_a_profile_is_a_per_vertex_c0_and_survives_the_c0_cycle():
    # exact equivalences: Jülicher with profile p equals the formula with c0_i = c0 p_i;
    # Evolver's star_perp with a profile equals star_perp with the per-vertex c0 array; a
    # profile of ones is no profile, bit for bit; with_c0 keeps the profile (c0 = 0 clears it)
    m, X = _perturbed_icosphere(3, seed=4)
    p = 1.0 + 0.2 * np.random.default_rng(4).standard_normal(m.n_vertices)
    b = Bending.from_mesh(m, kappa=0.8, c0=1.7, c0_profile=p)
    M_over_A = b.mean_curvature(X)
    A = b.vertex_areas(X)
    assert b.value(X) == pytest.approx(0.4 * np.sum((2 * M_over_A - 1.7 * p) ** 2 * A),
                                       rel=1e-12)
    np.testing.assert_array_equal(b.c0_vertices, 1.7 * p)
    ones = Bending.from_mesh(m, kappa=0.8, c0=1.7, c0_profile=np.ones(m.n_vertices))
    plain = Bending.from_mesh(m, kappa=0.8, c0=1.7)
    assert ones.value(X) == plain.value(X)
    np.testing.assert_array_equal(ones.gradient(X), plain.gradient(X))
    assert abs(ones.hessian(X) - plain.hessian(X)).max() == 0.0
    flat = b.with_c0(0.0)
    assert flat.value(X) == Bending.from_mesh(m, kappa=0.8, c0=0.0).value(X)
    assert b.with_c0(0.0).with_c0(1.7).value(X) == b.value(X)
    s = StarPerpBending(m.faces, m.n_vertices, kappa=0.8, c0=1.7, c0_profile=p)
    s_array = StarPerpBending(m.faces, m.n_vertices, kappa=0.8, c0=1.7 * p)
    assert s.value(X) == s_array.value(X)
    np.testing.assert_array_equal(s.c0_vertices, 1.7 * p)
    assert with_c0(s, 0.0).value(X) == StarPerpBending(m.faces, m.n_vertices, kappa=0.8,
                                                       c0=0.0).value(X)
    assert with_c0(with_c0(s, 0.0), 1.7).value(X) == s.value(X)


PARAMS = ShellParameters.from_gamma(2333.0, nu=1 / 3)


def test_a_shell_without_shape_imperfection_is_todays_shell_bit_for_bit():
    mesh = random_sphere(800, seed=1)
    base = init(mesh, PARAMS, Protocol.paper(until=0.1, smooth_jiggle=0.0))
    zero = init(mesh, PARAMS, Protocol.paper(until=0.1, smooth_jiggle=0.0,
                                             shape_imperfection=0.0))
    assert zero[0].V0 == base[0].V0
    np.testing.assert_array_equal(zero[1].X, base[1].X)
    X = 0.97 * mesh.X
    assert zero[0].energy.value(X) == base[0].energy.value(X)


def test_the_run_starts_at_the_stress_free_shape_where_the_energy_vanishes_with_the_mesh():
    # oracle: the stretching energy of the stress-free shape is zero (its own rest state), and
    # its bending energy, the mismatch between the discrete curvature and the smooth
    # surface's, falls under refinement towards zero, as the sphere's does with c0 = 2/R
    a, L = 0.003, 8
    bend = []
    for level in (8, 16, 32):
        mesh = icosphere(level)
        protocol = Protocol.paper(until=0.1, smooth_jiggle=0.0, shape_imperfection=a,
                                  shape_degree=L, seed=2)
        ctx, state = init(mesh, PARAMS, protocol)
        X, _ = stress_free_shape(mesh.X, a, L, seed=2)
        np.testing.assert_array_equal(state.X, X)
        assert ctx.V0 == ctx.volume.value(X)
        parts = ctx.energy.parts(state.X)
        assert abs(parts["E_stretch"]) < 1e-20
        bend.append(parts["E_bend"])
    assert bend[1] < 0.5 * bend[0] and bend[2] < 0.5 * bend[1]
    # the imperfect shape costs energy when made from a perfect shell: it is not a shape
    # the plain sphere would keep
    plain = init(icosphere(32), PARAMS, Protocol.paper(until=0.1, smooth_jiggle=0.0))[0]
    assert plain.energy.value(state.X) > 100 * bend[2]


def test_the_protocol_stores_the_shape_imperfection_and_old_runs_have_none():
    p = Protocol.paper(until=0.1, shape_imperfection=0.002, seed=4)
    d = p.to_dict()
    assert d["shape_imperfection"] == 0.002 and d["shape_degree"] == 20
    assert Protocol.from_dict(json.loads(json.dumps(d))) == p
    old = Protocol.paper(until=0.1).to_dict()
    assert "shape_imperfection" not in old and Protocol.from_dict(old).shape_imperfection is None
    for bad, match in (({"shape_imperfection": 0.2}, "shape_imperfection"),
                       ({"shape_imperfection": -1e-3}, "shape_imperfection"),
                       ({"shape_degree": 8}, "give it with shape_imperfection"),
                       ({"shape_imperfection": 1e-3, "shape_degree": 1}, "shape_degree")):
        with pytest.raises(ValueError, match=match):
            Protocol.paper(until=0.1, **bad)


def test_an_imperfect_run_resumes_bit_for_bit_and_exports_its_own_rest_state(tmp_path):
    from shellbuckle.export import RunFields
    from shellbuckle.run import deflate, resume

    mesh = random_sphere(600, seed=2)
    params = ShellParameters.from_gamma(271.0, nu=1 / 3)
    options = dict(schedule=[0.03, 0.06, 0.09], smooth_jiggle=0.0, shape_imperfection=0.004,
                   shape_degree=6, seed=2, threads=1, locate=False)
    full = deflate(mesh, params, out=tmp_path / "full", **options)
    part = deflate(mesh, params, out=tmp_path / "part", max_steps=1, **options)
    assert full.status == "finished" and part.status == "paused"
    done = resume(tmp_path / "part", threads=1, locate=False)
    for k in full.steps:
        np.testing.assert_array_equal(done.positions(k), full.positions(k))
    # the export measures from the stress-free shape: no displacement and the table's energy
    # at step 0, with the per-vertex c0 of the profile
    fields = RunFields.of(full)
    X0 = full.positions(0)
    np.testing.assert_array_equal(fields.displacement(X0), 0.0)
    bend = fields.bending.value(X0)
    assert bend == pytest.approx(full.table["E_bend"].iloc[0], rel=1e-12)
    assert fields.c0_vertices is not None and np.ptp(fields.c0_vertices) > 0.01
    # its .fe export carries the c0 profile as h_zero per vertex: the same profile, which a
    # run from that file (uniform c0 only) refuses rather than drop
    from shellbuckle.export import export_step
    from shellbuckle.mesh.evolver_io import read_evolver
    from shellbuckle.run import shell_from_file

    fe = export_step(full, 0, tmp_path / "start.fe")
    np.testing.assert_allclose(2.0 * read_evolver(fe).h_zero, fields.c0_vertices, rtol=1e-12)
    with pytest.raises(ValueError, match="h_zero that varies from vertex to vertex"):
        shell_from_file(fe)


def test_a_shape_that_inverts_the_curvature_somewhere_is_refused_whatever_the_mesh():
    # oracle: the lowest curvature over the fixed grid is the lowest over a fine mesh's
    # vertices to the grid's resolution, and it falls linearly with the amplitude (linear
    # theory: 1 + a (l(l+1) - 2) f / 2); at or below zero the protocol refuses the shell
    from shellbuckle.protocol.imperfection import lowest_curvature

    a, L = 0.01, 12
    low = lowest_curvature(a, L, 0)
    _, profile = stress_free_shape(icosphere(60).X, a, L, seed=0)
    assert low == pytest.approx(profile.min(), abs=0.02)
    half = lowest_curvature(a / 2, L, 0)
    assert 1.0 - half == pytest.approx((1.0 - low) / 2, rel=0.1)
    assert low < 0.5 and half > 0
    Protocol.paper(until=0.1, shape_imperfection=a / 2, shape_degree=L)
    with pytest.raises(ValueError, match="inverts the curvature"):
        Protocol.paper(until=0.1, shape_imperfection=3 * a, shape_degree=L)


def test_a_sweep_names_its_imperfect_shells_and_old_sweeps_keep_their_description():
    from shellbuckle.studies.refinement import study_spec
    from shellbuckle.sweep import SweepSpec

    spec = SweepSpec(vertices=[600], shape_imperfection=[None, 0.003], shape_degree=[8],
                     smooth_jiggle=[0.0])
    names = [p["name"] for p in spec.points()]
    assert names == ["g2333_nu0.333_v600_s0_sj0", "g2333_nu0.333_v600_s0_sj0_si0.003_Ls8"]
    imperfect = spec.points()[1]
    assert (imperfect["shape_imperfection"], imperfect["shape_degree"]) == (0.003, 8)
    assert "shape_imperfection" not in spec.points()[0]
    from shellbuckle.store.catalogue import _parameters  # the sweep's catalogue row says it

    row = _parameters(imperfect, {"params": {}, "protocol": {"shape_imperfection": 0.003,
                                                             "shape_degree": 8}})
    assert (row["shape_imperfection"], row["shape_degree"]) == (0.003, 8)
    stored = spec.to_dict()
    assert stored["shape_imperfection"] == [None, 0.003] and stored["shape_degree"] == [8]
    assert "shape_imperfection" not in SweepSpec(vertices=[600]).to_dict()
    study = study_spec([2333], ["helfrich"], [600, 1000], shape_imperfection=0.002)
    assert {p["shape_imperfection"] for p in study.points()} == {0.002}
    assert {p["shape_degree"] for p in study.points()} == {8}  # critical at gamma 2333
    with pytest.raises(ValueError, match="shape_degree"):
        SweepSpec(shape_degree=[8])


def test_amplitudes_in_units_of_the_thickness_are_converted_per_shell_and_round_trip():
    from shellbuckle.params import d_over_R
    from shellbuckle.store.catalogue import _parameters
    from shellbuckle.sweep import SweepSpec

    spec = SweepSpec(gamma=[2333, 29160], energy_convention=["helfrich", "paper"],
                     vertices=[3594], shape_imperfection_d=[0.1], smooth_jiggle=[0.0],
                     shape_degree=["critical", 8])
    points = spec.points()
    # per shell: 0.1 of the effective thickness (gamma_eff = 4 gamma under paper), the
    # critical degree and 8 (at gamma 2333 under helfrich they coincide: one run)
    assert len(points) == 7
    for p in points:
        g_eff = p["gamma"] * (4 if p["energy_convention"] == "paper" else 1)
        assert p["shape_imperfection"] == pytest.approx(0.1 * d_over_R(g_eff, 1 / 3),
                                                        rel=1e-12)
        assert p["shape_imperfection_d"] == 0.1
        assert f"_sid0.1_Ls{p['shape_degree']}" in p["name"]
    assert {p["shape_degree"] for p in points if p["gamma"] == 29160} == {8, 14, 19}
    # through sweep.json and back: the same grid
    again = SweepSpec.from_dict(json.loads(json.dumps(spec.to_dict())))
    assert again == spec and again.points() == points
    assert _parameters(points[0], None)["shape_imperfection_d"] == 0.1
    # a sweep without these axes keeps its description and names
    plain = SweepSpec(vertices=[3594], shape_imperfection=[0.003], shape_degree=[8])
    assert "shape_imperfection_d" not in plain.to_dict()
    assert [p["name"] for p in plain.points()] == ["g2333_nu0.333_v3594_s0_si0.003_Ls8"]
    assert "shape_imperfection_d" not in plain.points()[0]
    with pytest.raises(ValueError, match="gives L = 31"):  # critical above the checked grid
        SweepSpec(gamma=[2e5], energy_convention=["paper"], shape_imperfection_d=[0.05],
                  shape_degree=["critical"])
    with pytest.raises(ValueError, match="not both"):
        SweepSpec(shape_imperfection=[0.001], shape_imperfection_d=[0.1])


def test_deflate_counts_amplitudes_in_the_effective_thickness(tmp_path):
    from shellbuckle.cli import main
    from shellbuckle.params import d_over_R
    from shellbuckle.store.run import RunStore

    for convention, factor in (("helfrich", 1), ("paper", 4)):
        out = tmp_path / convention
        assert main(["deflate", "--gamma", "271", "--vertices", "600", "--energy-convention",
                     convention, "--shape-imperfection-d", "0.05", "--shape-degree", "4",
                     "--smooth-jiggle-d", "0.02", "--smooth-degree", "6", "--until", "0.019",
                     "--no-plot", "--no-locate", "--quiet", "--out", str(out)]) == 0
        protocol = RunStore.open(out).meta["protocol"]
        d = d_over_R(271 * factor, 1 / 3)
        assert protocol["shape_imperfection"] == pytest.approx(0.05 * d, rel=1e-12)
        assert protocol["smooth_jiggle"] == pytest.approx(0.02 * d, rel=1e-12)


def test_deflate_takes_the_critical_degree_of_the_sweep_for_the_same_shell(tmp_path, capsys):
    from shellbuckle.cli import main
    from shellbuckle.store.run import RunStore
    from shellbuckle.sweep import SweepSpec

    for convention in ("helfrich", "paper"):
        out = tmp_path / convention
        assert main(["deflate", "--gamma", "2333", "--vertices", "1000", "--energy-convention",
                     convention, "--shape-imperfection-d", "0.1", "--shape-degree", "critical",
                     "--smooth-jiggle", "0", "--until", "0.019", "--no-plot", "--no-locate",
                     "--quiet", "--out", str(out)]) == 0
        (point,) = SweepSpec(gamma=[2333], energy_convention=[convention], vertices=[1000],
                             shape_imperfection_d=[0.1], shape_degree=["critical"]).points()
        stored = RunStore.open(out).meta["protocol"]
        assert stored["shape_degree"] == point["shape_degree"] == {"helfrich": 8,
                                                                    "paper": 11}[convention]
    # above the checked grid: refused before any folder, naming the degree it gives
    out = tmp_path / "thin"
    assert main(["deflate", "--gamma", "2e5", "--energy-convention", "paper",
                 "--shape-imperfection-d", "0.05", "--shape-degree", "critical",
                 "--out", str(out)]) == 2
    assert "--shape-degree critical (gives L = 31): allowed: an integer in [2, 30]" in \
        capsys.readouterr().err
    assert not out.exists()
    # a mesh file brings its own shell: the shape imperfection is refused first, whatever the
    # degree it would give
    fe = Path(__file__).parent / "fixtures" / "evolver" / "sphere_perturbed.fe"
    for degree in ("critical", "3"):
        assert main(["deflate", "--mesh", str(fe), "--shape-imperfection-d", "0.1",
                     "--shape-degree", degree, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "--shape-imperfection-d 0.1: allowed: on a randomized or icosahedral sphere" \
            in err and "not on a --mesh file" in err and "resolve" not in err
        assert not out.exists()


def test_an_imperfect_shell_dents_at_the_same_place_on_two_meshes(tmp_path):
    # invariance: the same shape imperfection (seed, amplitude, degree) on two randomized
    # meshes of different sizes is the same shell, so it follows the same pressure path and
    # its dent lies at the same material point; a kicked perfect sphere dents where the mesh
    # decides (tens of degrees apart, docs/protocol.md). At a tenth of this amplitude the
    # imperfection no longer dominates the meshes' own (the two runs of this test then end
    # with dents 88 degrees apart)
    from shellbuckle.run import deflate

    params = ShellParameters.from_gamma(271.0, nu=1 / 3)
    runs = [deflate(random_sphere(n, seed=n), params, out=tmp_path / f"v{n}",
                    schedule=[0.05, 0.1, 0.15, 0.2, 0.25, 0.3], smooth_jiggle=0.0,
                    shape_imperfection=0.03, shape_degree=4, seed=3, threads=1, locate=False)
            for n in (1500, 4000)]
    assert all(run.status == "finished" for run in runs)
    p = [run.table["pressure"].to_numpy()[1:] for run in runs]
    assert p[0][3] < 0.95 * p[0][2]  # it buckled
    np.testing.assert_allclose(p[0], p[1], rtol=0.03)
    from shellbuckle.studies.refinement import material_dent_axis

    axes = [material_dent_axis(run.store.X0, run.positions(-1)) for run in runs]
    assert np.degrees(np.arccos(np.clip(axes[0] @ axes[1], -1.0, 1.0))) < 3.0


def test_a_continued_imperfect_shell_keeps_its_seed_and_the_api_refuses_before_any_folder(
        tmp_path):
    from shellbuckle.run import continue_from, deflate

    mesh = random_sphere(600, seed=2)
    params = ShellParameters.from_gamma(271.0, nu=1 / 3)
    run = deflate(mesh, params, out=tmp_path / "p", schedule=[0.03], smooth_jiggle=0.0,
                  shape_imperfection=0.004, shape_degree=6, seed=2, threads=1, locate=False)
    with pytest.raises(ValueError, match="keeps the seed"):
        continue_from(run, 1, tmp_path / "b", schedule=[0.06], seed=7)
    assert not (tmp_path / "b").exists()
    with pytest.raises(ValueError, match="form_factors"):
        deflate(mesh, params, out=tmp_path / "ff", schedule=[0.03], smooth_jiggle=0.0,
                shape_imperfection=0.004, form_factors=np.ones((len(mesh.faces), 3)))
    assert not (tmp_path / "ff").exists()
    # a mesh off its sphere (one vertex pushed in by 1 %) would be moved onto it: refused
    from shellbuckle.mesh import Mesh

    X = mesh.X.copy()
    X[0] *= 0.99
    with pytest.raises(ValueError, match="lie on a sphere"):
        deflate(Mesh.from_arrays(X, mesh.faces), params, out=tmp_path / "off", schedule=[0.03],
                smooth_jiggle=0.0, shape_imperfection=0.004, shape_degree=6)
    assert not (tmp_path / "off").exists()
    with pytest.raises(ValueError, match="shape_degree"):
        Protocol.paper(until=0.1, shape_imperfection=1e-4, shape_degree=31)


@pytest.mark.parametrize("gamma", [271.0, 2333.0, 15163.0, 29160.0, 4 * 29160.0])
def test_the_critical_degree_holds_the_classical_buckling_band(gamma):
    # the pressure at which degree l buckles, p_l = (2/R)(kappa lambda/R^2 + A/lambda),
    # lambda = l (l + 1), is least at lambda = sqrt(gamma) where it is the classical p_c of
    # the theory module; the critical shape degree lies above the integer degree that buckles
    from shellbuckle import theory
    from shellbuckle.protocol.imperfection import buckling_degree, critical_shape_degree

    params = ShellParameters.from_gamma(gamma, nu=1 / 3)
    kappa, A, R = params.kappa, params.A, params.R
    lc = buckling_degree(gamma)
    lam = lc * (lc + 1)
    p_c = theory.classical_threshold(params).pressure
    assert 2 / R * (kappa * lam / R ** 2 + A / lam) == pytest.approx(p_c, rel=1e-12)
    l = np.arange(2, 80)
    p = 2 / R * (kappa * l * (l + 1) / R ** 2 + A / (l * (l + 1)))
    first = int(l[np.argmin(p)])
    assert math.floor(lc) <= first <= math.ceil(lc)
    assert first < critical_shape_degree(gamma) <= first + 2
