"""The smooth imperfection: one field on the sphere whatever the mesh, with the requested
spectrum and amplitude, reproducible by seed, resumable in a run, and relaxed without the
rough stage made for per-vertex noise."""

import json

import numpy as np
import pytest
import scipy.special

from shellbuckle.mesh import icosphere
from shellbuckle.mesh.random_sphere import random_sphere
from shellbuckle.params import ShellParameters
from shellbuckle.protocol import deflate as P
from shellbuckle.protocol.deflate import Protocol
from shellbuckle.protocol.imperfection import (evaluate, harmonic_index, n_harmonics,
                                               power_per_degree, random_coefficients,
                                               reference_directions, reference_sphere,
                                               smooth_displacement, smooth_jiggle,
                                               vertex_normals)
from shellbuckle.protocol.jiggle import jiggle, step_rng
from shellbuckle.solve import minimize
from shellbuckle.solve.gauge import remove_rigid
from shellbuckle.solve.relax import move
from shellbuckle.solve.system import KKTSystem
from shellbuckle.studies.transfer import material_interpolation


@pytest.fixture(scope="module")
def meshes():
    return {n: random_sphere(n, seed=n) for n in (1000, 2000, 6000)}


def vertex_areas(X, faces):
    corners = X[faces]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                         corners[:, 2] - corners[:, 0]), axis=1)
    return np.bincount(faces.ravel(), np.repeat(area / 3.0, 3), minlength=len(X))


def normal_displacement(mesh, amplitude, degree, rng, X=None):
    """The scalar normal displacement of the smooth imperfection at each vertex."""
    X = mesh.X if X is None else X
    d = smooth_displacement(X, mesh.faces, reference_directions(mesh.X), amplitude, degree, rng)
    return np.einsum("ij,ij->i", d, vertex_normals(X, mesh.faces))


def interpolate(mesh, values, points):
    """Barycentric interpolation of vertex ``values`` of a sphere mesh at unit ``points``, in
    the face that the ray to each point crosses (the refinement study's transfer)."""
    return material_interpolation(mesh.X, mesh.faces, values, points)


def real_harmonics_scipy(directions, degree):
    """The real 4 pi-normalized harmonics (no Condon-Shortley phase) from SciPy's complex
    orthonormal ones, an implementation independent of the module's recursion:
    Y_l0 = sqrt(4 pi) Y_l^0, Y_lm = sqrt(8 pi) (-1)^m Re Y_l^m, Y_l,-m = sqrt(8 pi) (-1)^m
    Im Y_l^m (m > 0)."""
    theta = np.arccos(np.clip(directions[:, 2], -1, 1))
    phi = np.arctan2(directions[:, 1], directions[:, 0])
    out = np.empty((len(directions), n_harmonics(degree)))
    for l in range(degree + 1):
        for m in range(l + 1):
            if hasattr(scipy.special, "sph_harm_y"):  # SciPy >= 1.15
                Y = scipy.special.sph_harm_y(l, m, theta, phi)
            else:
                Y = scipy.special.sph_harm(m, l, phi, theta)
            if m == 0:
                out[:, harmonic_index(l, 0)] = np.sqrt(4 * np.pi) * Y.real
            else:
                out[:, harmonic_index(l, m)] = np.sqrt(8 * np.pi) * (-1) ** m * Y.real
                out[:, harmonic_index(l, -m)] = np.sqrt(8 * np.pi) * (-1) ** m * Y.imag
    return out


# --------------------------------------------------------------------------- the same field

def test_the_same_field_on_two_meshes_of_the_same_sphere(meshes):
    # generated on a 2000- and a 6000-vertex randomized sphere (other seeds, other vertices)
    # from the same stream, the normal displacements agree where one mesh's vertices sample
    # the other's interpolant, to the interpolation error of the finer mesh
    degree, amplitude = 10, 0.01
    coarse, fine = meshes[2000], meshes[6000]
    u_coarse = normal_displacement(coarse, amplitude, degree, step_rng(3, 1))
    u_fine = normal_displacement(fine, amplitude, degree, step_rng(3, 1))
    at_coarse = interpolate(fine, u_fine, reference_directions(coarse.X))
    error = np.sqrt(np.mean((at_coarse - u_coarse) ** 2))
    assert error < 0.02 * amplitude
    # Surface Evolver's white noise of the same rms along the normals is another field on
    # each mesh: interpolated, it does not agree at all
    rng = step_rng(3, 1)
    noise_fine = amplitude * rng.standard_normal(len(fine.X))
    noise_coarse = amplitude * rng.standard_normal(len(coarse.X))
    noise_error = np.sqrt(np.mean((interpolate(fine, noise_fine, reference_directions(coarse.X))
                                   - noise_coarse) ** 2))
    assert noise_error > amplitude


def test_the_interpolation_error_falls_as_the_square_of_the_edge(meshes):
    # the discrepancy is the discretization's: interpolated from 2000 and from 6000 vertices
    # onto the vertices of a third mesh, it falls as h^2 (h ~ N^(-1/2): by 6000/2000 = 3)
    degree, amplitude = 10, 0.01
    target = reference_directions(meshes[1000].X)
    exact = amplitude * evaluate(random_coefficients(degree, step_rng(3, 1)), target)
    errors = []
    for n in (2000, 6000):
        u = normal_displacement(meshes[n], amplitude, degree, step_rng(3, 1))
        errors.append(np.sqrt(np.mean((interpolate(meshes[n], u, target) - exact) ** 2)))
    assert errors[0] / errors[1] == pytest.approx(3.0, rel=0.3)


def test_a_material_point_moves_by_the_same_amount_at_any_deformation(meshes):
    # the field is evaluated at the reference directions, applied along the current normals
    mesh = meshes[2000]
    X = mesh.X * np.array([1.3, 0.9, 0.7]) + np.array([0.2, -0.1, 0.05])
    d = smooth_displacement(X, mesh.faces, reference_directions(mesh.X), 0.02, 8,
                            step_rng(1, 4))
    n = vertex_normals(X, mesh.faces)
    u_ref = normal_displacement(mesh, 0.02, 8, step_rng(1, 4))
    np.testing.assert_allclose(np.einsum("ij,ij->i", d, n), u_ref, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.cross(d, n), 0.0, atol=1e-15)  # along the normal
    # the reference sphere's centre and radius, from positions off the origin
    centre, radius = reference_sphere(2.5 * mesh.X + np.array([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(centre, [1.0, 2.0, 3.0], atol=1e-12)
    assert radius == pytest.approx(2.5, rel=1e-12)


def test_vertex_normals_of_a_sphere_are_radial(meshes):
    X = meshes[6000].X
    n = vertex_normals(X, meshes[6000].faces)
    radial = X / np.linalg.norm(X, axis=1)[:, None]
    assert np.max(np.linalg.norm(n - radial, axis=1)) < 0.01  # O(h^2), h = 0.05 R


# --------------------------------------------------------------------------- spectrum, amplitude

@pytest.mark.parametrize("degree", [2, 5, 12])
def test_least_squares_fit_recovers_the_coefficients_and_nothing_outside_2_to_L(meshes,
                                                                              degree):
    a = random_coefficients(degree, step_rng(11, degree))
    directions = reference_directions(meshes[6000].X)
    f = evaluate(a, directions)
    # fitted with SciPy's harmonics up to L + 2: degrees 0, 1, L+1, L+2 must come out empty
    fitted, *_ = np.linalg.lstsq(real_harmonics_scipy(directions, degree + 2), f, rcond=None)
    expected = np.zeros(n_harmonics(degree + 2))
    expected[:n_harmonics(degree)] = a
    np.testing.assert_allclose(fitted, expected, atol=1e-10)
    assert np.all(a[:4] == 0)
    # a flat spectrum: every degree 2..L carries the same power, 1/(L - 1), which sums to 1
    power = power_per_degree(a)
    np.testing.assert_allclose(power[2:], 1.0 / (degree - 1), rtol=1e-12)
    assert power[0] == power[1] == 0


def test_the_harmonics_are_4pi_normalized_real_harmonics():
    # (1/4 pi) int Y_lm Y_l'm' = delta: Gauss-Legendre in cos(theta) x trapezoid in phi, exact
    # for these degrees
    degree = 6
    t, w = np.polynomial.legendre.leggauss(degree + 2)
    phi = np.linspace(0, 2 * np.pi, 2 * degree + 3, endpoint=False)
    T, P = np.meshgrid(t, phi, indexing="ij")
    s = np.sqrt(1 - T ** 2)
    directions = np.column_stack([(s * np.cos(P)).ravel(), (s * np.sin(P)).ravel(), T.ravel()])
    weights = (w[:, None] * np.full_like(P, 2 * np.pi / len(phi))).ravel()
    Y = np.column_stack([evaluate(np.eye(n_harmonics(degree))[i], directions)
                         for i in range(n_harmonics(degree))])
    gram = (Y * weights[:, None]).T @ Y / (4 * np.pi)
    np.testing.assert_allclose(gram, np.eye(n_harmonics(degree)), atol=1e-12)


@pytest.mark.parametrize("amplitude, degree", [(0.01, 8), (0.003, 20)])
def test_the_rms_normal_displacement_over_the_sphere_is_the_amplitude(meshes, amplitude,
                                                                      degree):
    mesh = meshes[6000]
    u = normal_displacement(mesh, amplitude, degree, step_rng(2, 7))
    area = vertex_areas(mesh.X, mesh.faces)
    rms = np.sqrt(np.sum(area * u ** 2) / np.sum(area))
    assert rms == pytest.approx(amplitude, rel=0.01)
    # in a run, amplitude = smooth_jiggle R
    p = Protocol(schedule=(0.1,), smooth_jiggle=0.02)
    assert p.jiggle_sigma(3.0 * mesh.X, mesh.X, mesh.topology.edges) == pytest.approx(0.06)


# --------------------------------------------------------------------------- seeds

def test_reproducible_by_seed_and_step_different_otherwise(meshes):
    mesh = meshes[1000]
    directions = reference_directions(mesh.X)

    def draw(seed, k):
        return smooth_jiggle(mesh.X, mesh.faces, directions, 0.01, 10, step_rng(seed, k))

    a = draw(5, 3)
    assert np.array_equal(a, draw(5, 3))
    for other in (draw(5, 4), draw(6, 3)):
        # different fields: their difference is as large as the fields themselves
        assert np.sqrt(np.mean(np.sum((other - a) ** 2, axis=1))) > 0.005
    assert np.array_equal(smooth_jiggle(mesh.X, mesh.faces, directions, 0.0, 10,
                                        step_rng(5, 3)), mesh.X)
    rng = step_rng(5, 3)
    smooth_jiggle(mesh.X, mesh.faces, directions, 0.0, 10, rng)  # zero draws nothing
    assert np.array_equal(rng.standard_normal(4), step_rng(5, 3).standard_normal(4))
    assert not np.array_equal(jiggle(mesh.X, 0.01, step_rng(5, 3)), a)


# --------------------------------------------------------------------------- in a run

GAMMA = 271.0
SMOOTH = {"schedule": (0.03, 0.06, 0.09, 0.12), "smooth_jiggle": 0.005, "smooth_degree": 8,
          "seed": 5}


def _smooth_run(out, mesh, max_steps=None):
    """A run of the smooth protocol, created in ``out`` and driven by ``resume`` (PARDISO's
    plain mode on one thread, as ``deflate(..., threads=1)``)."""
    from shellbuckle.run import SOLVER_MODE, resume
    from shellbuckle.store.run import RunStore

    params = ShellParameters.from_gamma(GAMMA, nu=1 / 3)
    store = RunStore.create(out, params=params.to_dict(), protocol=Protocol(**SMOOTH).to_dict(),
                            X0=mesh.X, faces=mesh.faces, extra_meta={SOLVER_MODE: "plain"})
    store.close()
    return resume(out, max_steps=max_steps, threads=1, locate=False)


def test_a_smooth_run_stores_its_option_and_resumes_bit_for_bit(tmp_path):
    mesh = random_sphere(600, seed=2)
    full = _smooth_run(tmp_path / "full", mesh)
    assert full.status == "finished" and full.steps == [0, 1, 2, 3, 4]
    protocol = json.loads((tmp_path / "full" / "run.json").read_text())["protocol"]
    assert protocol["smooth_jiggle"] == 0.005 and protocol["smooth_degree"] == 8
    assert protocol["temperature"] is None and protocol["jiggle"] is None
    assert Protocol.from_dict(protocol) == Protocol(**SMOOTH)
    table = full.table
    assert table["converged"].iloc[1:].all()
    # the record's jiggle_sigma is the field's rms, smooth_jiggle R (R = 1)
    np.testing.assert_allclose(table["jiggle_sigma"].iloc[1:], 0.005, rtol=1e-12)
    # paused after 2 steps, then resumed: the same bits as the uninterrupted run
    part = _smooth_run(tmp_path / "part", mesh, max_steps=2)
    assert part.status == "paused" and part.steps == [0, 1, 2]
    from shellbuckle.run import resume

    done = resume(tmp_path / "part", threads=1, locate=False)
    assert done.steps == full.steps
    for k in full.steps:
        np.testing.assert_array_equal(done.positions(k), full.positions(k))


def test_deflate_command_runs_the_smooth_imperfection(tmp_path, monkeypatch):
    from shellbuckle.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["deflate", "--gamma", "271", "--vertices", "600", "--smooth-jiggle-d", "0.03",
                 "--smooth-degree", "8", "--dv", "0.03", "--until", "0.06", "--threads", "1",
                 "--no-plot", "--quiet", "--out", "r"]) == 0
    protocol = json.loads((tmp_path / "r" / "run.json").read_text())["protocol"]
    d_over_R = ShellParameters.from_gamma(271.0).d_over_R
    assert protocol["smooth_jiggle"] == pytest.approx(0.03 * d_over_R, rel=1e-12)
    assert protocol["smooth_degree"] == 8 and protocol["temperature"] is None
    # the catalogue of runs names the imperfection a run was made with
    from shellbuckle.analysis.collect import collect_runs

    row = collect_runs(tmp_path / "r").iloc[0]
    assert row["smooth_jiggle"] == protocol["smooth_jiggle"] and row["smooth_degree"] == 8
    assert row["temperature"] != row["temperature"]  # NaN: no per-vertex jiggle


def test_a_smooth_imperfection_is_relaxed_without_the_rough_stage(monkeypatch):
    # oracle: the same minimization from the same smooth start with the relaxation's rough
    # stage (the solver's default, made for per-vertex noise) ends at the same minimum, with
    # at least one factorization more
    factored = []
    original = KKTSystem.factor

    def counting(self, mu, approximate=False):
        factored.append(mu)
        return original(self, mu, approximate)

    monkeypatch.setattr(KKTSystem, "factor", counting)
    params = ShellParameters.from_gamma(2333, nu=1 / 3)
    protocol = Protocol.paper(until=0.1, seed=0, smooth_jiggle=0.03, smooth_degree=12)
    ctx, state = P.init(icosphere(16), params, protocol, threads=1)
    X = P._jiggled(ctx, state.X, protocol.smooth_jiggle, step_rng(0, 1))
    V = ctx.V0 * (1.0 - protocol.schedule[0])
    assert 0.3 < move(ctx.volume, X, state.X) < 1.5  # a start the rough stage would take
    counts, results = [], []
    for rough in (None, 1.0):
        factored.clear()
        if rough is None:
            res = P._minimize(ctx, ctx.energy, X, V, relaxed=state.X,
                              jiggle=protocol.smooth_jiggle)
        else:
            res = minimize(ctx.energy, ctx.volume, X, V, tol=protocol.tol, workspace=ctx.workspace,
                           pinned=ctx.pinned, precondition_at=state.X, relax_rough_shift=rough)
        counts.append(len(factored))
        results.append(res)
    smooth, rough = results
    assert smooth.success and rough.success and smooth.inertia == rough.inertia == 0
    assert smooth.fun == pytest.approx(rough.fun, rel=1e-10)
    # the same shape (the two paths may end moved rigidly against each other)
    assert np.abs(remove_rigid(rough.x, smooth.x - rough.x)).max() <= 1e-8
    assert counts[0] < counts[1]


def _spy_on_minimize(monkeypatch, **extra) -> list:
    """The keyword arguments of every minimization the protocol starts from now on (run with
    ``extra`` added), in a list."""
    seen, inner = [], P.minimize

    def spy(*args, **kwargs):
        seen.append(kwargs)
        return inner(*args, **kwargs, **extra)

    monkeypatch.setattr(P, "minimize", spy)
    return seen


def test_an_imperfection_smaller_than_the_smooth_start_distance_is_still_relaxed(monkeypatch):
    # a start closer than relax_rough_min_move edges to the last minimum takes quasi-Newton
    # steps on the unshifted Hessian there, unless it carries an imperfection: then every
    # mesh relaxes it the same way, however small it is in edge lengths. Oracles: the
    # protocol's minimization is, to the bit, the explicit relaxation without a smooth start,
    # and the smooth start reaches the same (unique, spherical) minimum by the other path
    params = ShellParameters.from_gamma(2333, nu=1 / 3)
    protocol = Protocol.paper(until=0.1, seed=0, smooth_jiggle=0.005, smooth_degree=12)
    ctx, state = P.init(icosphere(16), params, protocol, threads=1)
    X = P._jiggled(ctx, state.X, protocol.smooth_jiggle, step_rng(0, 1))
    V = ctx.V0 * (1.0 - protocol.schedule[0])
    assert move(ctx.volume, X, state.X) < 0.3  # below the smooth-start distance
    seen = _spy_on_minimize(monkeypatch, history=True)
    step = P._minimize(ctx, ctx.energy, X, V, relaxed=state.X, jiggle=protocol.smooth_jiggle)
    assert seen[-1]["smooth_start"] is False
    P._minimize(ctx, ctx.energy, X, V, relaxed=state.X, jiggle=0.0)  # no imperfection
    assert "smooth_start" not in seen[-1]
    monkeypatch.undo()
    common = dict(tol=protocol.tol, workspace=ctx.workspace, pinned=ctx.pinned,
                  precondition_at=state.X, relax_rough_shift=0.0, history=True)
    relaxed = minimize(ctx.energy, ctx.volume, X, V, smooth_start=False, **common)
    smooth = minimize(ctx.energy, ctx.volume, X, V, **common)
    assert step.history[0]["step"] == "relax" and smooth.history[0]["step"] != "relax"
    assert np.array_equal(step.x, relaxed.x) and step.nit == relaxed.nit
    assert relaxed.success and smooth.success and relaxed.inertia == smooth.inertia == 0
    assert relaxed.fun == pytest.approx(smooth.fun, rel=1e-10)
    assert np.abs(remove_rigid(smooth.x, relaxed.x - smooth.x)).max() <= 1e-8


@pytest.mark.parametrize("temperature, stored_before, relaxed", [
    (0.01, False, True),   # a jiggle of 0.07 mean edges: relaxed all the same
    (0.0, False, False),   # no jiggle: the smooth start on the last minimum's Hessian
    (0.01, True, False),   # a run stored before the option keeps the path it was made with
])
def test_the_step_relaxes_a_jiggled_start_when_its_protocol_says_so(monkeypatch, temperature,
                                                                    stored_before, relaxed):
    protocol = Protocol.paper(until=0.019, seed=0, temperature=temperature)
    if stored_before:
        data = protocol.to_dict()
        del data["relax_imperfection"]
        protocol = Protocol.from_dict(data)
        assert protocol.relax_imperfection is False
    ctx, state = P.init(icosphere(8), ShellParameters.from_gamma(271, nu=1 / 3), protocol,
                        threads=1)
    seen = _spy_on_minimize(monkeypatch)
    state, record = P.step(ctx, state)
    assert record["converged"]
    assert (seen[0].get("smooth_start") is False) == relaxed
    assert all("smooth_start" not in kwargs for kwargs in seen[1:])  # the c0 cycle


def test_no_jiggle_asks_no_mesh_to_resolve_a_degree(tmp_path):
    # --smooth-jiggle 0 is no field: a 600-vertex mesh (which resolves L <= 10) runs with
    # the default degree 20
    from shellbuckle.cli import main

    assert main(["deflate", "--gamma", "271", "--vertices", "600", "--smooth-jiggle", "0",
                 "--until", "0.019", "--threads", "1", "--no-plot", "--no-locate", "--quiet",
                 "--out", str(tmp_path / "r")]) == 0
    protocol = json.loads((tmp_path / "r" / "run.json").read_text())["protocol"]
    assert protocol["smooth_jiggle"] == 0.0
