"""The jiggle: Surface Evolver's displacement scale, the edge-length scale, seeding, options."""

import numpy as np
import pytest

from shellbuckle.mesh.icosphere import icosphere
from shellbuckle.mesh.random_sphere import random_sphere
from shellbuckle.protocol.deflate import Protocol
from shellbuckle.protocol.jiggle import (EVOLVER_JIGGLE_SCALE, evolver_sigma, jiggle,
                                         mean_edge_length, overall_size, step_rng)


def test_evolver_scale_follows_its_source():
    # iterate.c: gaussian() * temperature * max_len * overall_size; gaussian() is
    # (sum of 5 uniforms in [0, 1) - 2.5) / 5 * sqrt(12/5), of variance 5/12 / 25 * 12/5 = 1/25
    g_std = np.sqrt(5 / 12) / 5 * np.sqrt(12 / 5)
    assert EVOLVER_JIGGLE_SCALE == pytest.approx(g_std * 1.4, rel=1e-12)


@pytest.mark.parametrize("R", [1.0, 2.5])
def test_evolver_sigma_is_mesh_independent_and_proportional_to_size(R):
    coarse, fine = icosphere(3, R=R), random_sphere(2000, seed=1, R=R)
    # the bounding box of an inscribed mesh: 2R up to its sagitta (icosphere(3) misses the poles)
    assert overall_size(coarse.X) == pytest.approx(2 * R, rel=3e-2)
    assert overall_size(fine.X) == pytest.approx(2 * R, rel=3e-3)
    # Surface Evolver 2.70 measured: std 0.0279 R at its default temperature 0.05
    assert evolver_sigma(0.05, fine.X) == pytest.approx(0.028 * R, rel=4e-3)
    assert evolver_sigma(0.1, coarse.X) == pytest.approx(2 * evolver_sigma(0.05, coarse.X))


def test_displacements_have_the_requested_std_and_zero_mean():
    m = random_sphere(3000, seed=0)
    rng = step_rng(7, 3)
    d = jiggle(m.X, 0.02, rng) - m.X
    n = d.size
    assert d.std() == pytest.approx(0.02, rel=4 / np.sqrt(n))  # ~4 standard errors
    assert abs(d.mean()) < 4 * 0.02 / np.sqrt(n)
    by_edge = Protocol(schedule=(0.1,), jiggle=0.1).jiggle_sigma(m.X, m.X, m.topology.edges)
    e = jiggle(m.X, by_edge, step_rng(7, 3)) - m.X
    assert e.std() == pytest.approx(0.1 * mean_edge_length(m.X, m.topology.edges), rel=4 / np.sqrt(n))


def test_same_seed_and_step_give_the_same_jiggle_and_zero_draws_nothing():
    m = icosphere(2)
    a = jiggle(m.X, 0.01, step_rng(1, 5))
    b = jiggle(m.X, 0.01, step_rng(1, 5))
    c = jiggle(m.X, 0.01, step_rng(1, 6))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.array_equal(jiggle(m.X, 0.0, step_rng(1, 5)), m.X)


def test_protocol_jiggle_options():
    m = icosphere(3)
    default = Protocol(schedule=(0.1,))
    assert default.temperature == 0.05 and default.jiggle is None
    assert default.jiggle_sigma(m.X, m.X, m.topology.edges) == pytest.approx(0.028, rel=3e-2)
    by_edge = Protocol(schedule=(0.1,), jiggle=0.2)
    assert by_edge.temperature is None
    assert by_edge.jiggle_sigma(m.X, m.X, m.topology.edges) == pytest.approx(
        0.2 * mean_edge_length(m.X, m.topology.edges))
    with pytest.raises(ValueError, match="not both"):
        Protocol(schedule=(0.1,), jiggle=0.1, temperature=0.05)
    with pytest.raises(ValueError, match="temperature"):
        Protocol(schedule=(0.1,), temperature=-0.1)
    # a protocol stored before the temperature option existed keeps its edge-length jiggle
    old = default.to_dict()
    old.pop("temperature")
    old.pop("jiggle")
    assert Protocol.from_dict(old).jiggle == 0.01
    assert Protocol.from_dict(default.to_dict()) == default
    # ... and, stored before the preconditioned relaxation, resumes without it
    old.pop("prerelax")
    assert default.prerelax and not Protocol.from_dict(old).prerelax
    # ... and, stored before the direct return of the c0 cycle, resumes without it
    old.pop("direct_return")
    assert default.direct_return and not Protocol.from_dict(old).direct_return


def _first_step_with_first_minimization_changed(monkeypatch, **changes):
    """Step 1 of a small deflation (icosphere 3, gamma 271, c0 cycle, seed 4) whose first
    minimization returns its result with the fields ``changes``; ``(mesh, params, protocol,
    state, record, calls)`` with the keyword arguments of every minimization in ``calls``."""
    import dataclasses

    import shellbuckle.protocol.deflate as deflate
    from shellbuckle.params import ShellParameters

    mesh = icosphere(3)
    params = ShellParameters.from_gamma(271.0, nu=1.0 / 3.0)
    protocol = Protocol(schedule=(0.019,), c0_cycle=True, seed=4)
    ctx, state = deflate.init(mesh, params, protocol)
    minimize, calls = deflate._minimize, []

    def first_changed(*args, **kwargs):
        result = minimize(*args, **kwargs)
        calls.append(kwargs)
        return dataclasses.replace(result, **changes) if len(calls) == 1 else result

    monkeypatch.setattr(deflate, "_minimize", first_changed)
    state, record = deflate.step(ctx, state)
    monkeypatch.setattr(deflate, "_minimize", minimize)
    return mesh, params, protocol, state, record, calls


def test_a_step_that_does_not_converge_is_jiggled_again_with_half_the_amplitude(monkeypatch):
    from shellbuckle.protocol.deflate import _minimize as minimize
    from shellbuckle.protocol.deflate import init

    # the first minimization ends unconverged and tangled
    mesh, params, protocol, state, record, calls = \
        _first_step_with_first_minimization_changed(monkeypatch, success=False, fun=1e6)
    sigma0 = protocol.jiggle_sigma(mesh.X, mesh.X, mesh.topology.edges)
    assert record["jiggle_attempts"] == 2 and record["converged"]
    assert record["jiggle_sigma"] == pytest.approx(sigma0 / 2)
    assert len(calls) == 4  # the failed attempt skips the c0 cycle; the retry runs it
    # the retry starts again from the step's start, not from the failed attempt
    again = Protocol(schedule=(0.019,), c0_cycle=True, seed=4)
    ctx2, s2 = init(mesh, params, again)
    rng = np.random.default_rng([4, 1, 1])
    X = jiggle(s2.X, sigma0 / 2, rng)
    V = ctx2.V0 * (1 - 0.019)
    r = minimize(ctx2, ctx2.energy, X, V, relaxed=s2.X, jiggle=sigma0 / 2)
    r = minimize(ctx2, ctx2.energy.with_c0(0.0), r.x, V, relaxed=r.x)
    r = minimize(ctx2, ctx2.energy, r.x, V, relaxed=r.x)
    assert np.allclose(r.x, state.X, atol=1e-12)


def test_a_stalled_minimization_goes_through_the_c0_cycle(monkeypatch):
    # a minimization that stops without converging, neither on a fold nor tangled (it stalled
    # on soft modes: gamma = 20995, dV/V = 0.608, residual 6e-5), is the step's last attempt;
    # the cycle then starts from it and converges the step, as the paper's protocol cycles
    # after every minimization (before, the step ended unconverged there, without the cycle)
    *_, record, calls = _first_step_with_first_minimization_changed(  # at its own (low)
        monkeypatch, success=False, message="stalled: (a test)")  # energy: not tangled
    # the minimization, then the two of the cycle (which start from the previous ones)
    assert [c.get("warm") is None for c in calls] == [True, False, False]
    assert record["jiggle_attempts"] == 1 and record["converged"] and record["inertia"] == 0


def test_an_unconverged_step_that_intersects_itself_is_jiggled_again(monkeypatch):
    # not a minimum, so its self-intersection (here: one vertex pushed through the far side of
    # the shell) must not end the run as a contact; a converged one does
    import dataclasses

    import shellbuckle.protocol.deflate as deflate
    from shellbuckle.params import ShellParameters

    mesh = icosphere(6)
    ctx, state = deflate.init(mesh, ShellParameters.from_gamma(271.0, nu=1.0 / 3.0),
                              Protocol(schedule=(0.019,), c0_cycle=False, seed=4))
    minimize, calls = deflate._minimize, []
    spiked = mesh.X.copy()
    spiked[0] = -1.5 * mesh.X[0]
    assert ctx.contact.check(spiked).intersects
    assert not deflate.only_local(ctx.contact, ctx.contact.check(spiked), rings=ctx.fold_rings)

    def first_crosses(*args, converged=False, **kwargs):
        result = minimize(*args, **kwargs)
        calls.append(result.success)
        if len(calls) == 1:  # at a low energy, so not "tangled"
            return dataclasses.replace(result, x=spiked, success=converged)
        return result

    monkeypatch.setattr(deflate, "_minimize", first_crosses)
    _, record = deflate.step(ctx, state)
    assert record["jiggle_attempts"] == 2 and record["converged"]
    assert not record["self_intersecting"]
    calls.clear()
    monkeypatch.setattr(deflate, "_minimize",
                        lambda *a, **k: first_crosses(*a, converged=True, **k))
    stopped, record = deflate.step(ctx, state)
    assert record["jiggle_attempts"] == 1 and record["self_intersecting"] and stopped.stopped


def test_a_step_that_merely_crawls_is_not_jiggled_again(monkeypatch):
    # unconverged but at a sensible energy (a soft mode, not a tangle): no retry
    import dataclasses

    import shellbuckle.protocol.deflate as deflate
    from shellbuckle.params import ShellParameters

    mesh = icosphere(3)
    ctx, state = deflate.init(mesh, ShellParameters.from_gamma(271.0, nu=1.0 / 3.0),
                              Protocol(schedule=(0.019,), c0_cycle=False, seed=4))
    minimize = deflate._minimize
    monkeypatch.setattr(deflate, "_minimize", lambda *a, **k: dataclasses.replace(
        minimize(*a, **k), success=False))
    _, record = deflate.step(ctx, state)
    assert record["jiggle_attempts"] == 1 and not record["converged"]


def test_a_fold_is_told_from_a_contact_of_distant_faces():
    # the classification behind re-jiggling a fold: intersecting faces within FOLD_RINGS rings
    # are a fold of the mesh; a pair from opposite sides of the shell is a contact that ends
    # the run
    from types import SimpleNamespace

    from shellbuckle.mesh.contact import ContactChecker
    from shellbuckle.protocol.deflate import FOLD_RINGS, only_local

    mesh = icosphere(12)
    faces = np.asarray(mesh.faces)
    checker = ContactChecker(mesh.topology)
    # graph distances between faces by a plain breadth-first search over the edges
    neighbours = [set() for _ in range(mesh.n_vertices)]
    for a, b in mesh.topology.edges:
        neighbours[a].add(b)
        neighbours[b].add(a)
    depth = {int(v): 0 for v in faces[0]}
    frontier = set(depth)
    for d in range(1, FOLD_RINGS + 2):
        frontier = {u for v in frontier for u in neighbours[v]} - set(depth)
        depth.update({u: d for u in frontier})
    expected = np.array([min(depth.get(int(v), np.inf) for v in f) for f in faces])
    expected[expected > FOLD_RINGS] = np.inf
    got = checker.face_distance(np.zeros(len(faces), int), np.arange(len(faces)), FOLD_RINGS)
    assert np.array_equal(got, expected)
    assert 0 < np.isfinite(expected).sum() < len(faces) // 4

    def contact(pairs):
        pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
        return SimpleNamespace(intersects=len(pairs) > 0, pairs=pairs)

    edge_ring = np.flatnonzero(expected == FOLD_RINGS)[0]
    outside = np.flatnonzero(~np.isfinite(expected))
    centres = mesh.X[faces].mean(axis=1)
    far = outside[np.argmax(np.linalg.norm(centres[outside] - centres[0], axis=1))]
    assert only_local(checker, contact([(0, edge_ring)]), rings=FOLD_RINGS)
    assert not only_local(checker, contact([(0, outside[0])]), rings=FOLD_RINGS)
    assert not only_local(checker, contact([(0, far)]), rings=FOLD_RINGS)
    # any distant pair
    assert not only_local(checker, contact([(0, edge_ring), (0, far)]), rings=FOLD_RINGS)
    assert not only_local(checker, contact([]), rings=FOLD_RINGS)


def test_a_fold_is_a_length_of_the_shell_on_every_mesh():
    # invariance: two faces 0.2 R apart on the sphere are a fold, two faces 0.6 R apart a
    # contact, on a mesh of the paper's size and on one 11 times finer, whose edges count the
    # same lengths with three times as many rings
    from types import SimpleNamespace

    from shellbuckle.energies.volume import Volume
    from shellbuckle.mesh.contact import ContactChecker
    from shellbuckle.protocol.deflate import FOLD_RINGS, fold_rings, only_local

    rings = {}
    for n, frequency in ((3612, 19), (39692, 63)):
        mesh = icosphere(frequency)
        faces = np.asarray(mesh.faces)
        V0 = Volume(mesh.faces, mesh.n_vertices).value(mesh.X)
        rings[n] = fold_rings(mesh.X, mesh.topology.edges, V0)
        checker = ContactChecker(mesh.topology)
        centres = mesh.X[faces].mean(axis=1)
        centres /= np.linalg.norm(centres, axis=1)[:, None]
        arc = np.arccos(np.clip(centres @ centres[0], -1.0, 1.0))  # distance on the sphere
        for length, local in ((0.2, True), (0.6, False)):
            g = int(np.argmin(np.abs(arc - length)))
            contact = SimpleNamespace(intersects=True, pairs=np.array([[0, g]]))
            assert only_local(checker, contact, rings=rings[n]) == local, (n, length)
            if n > 3612 and local:  # the coarse mesh's ring count would call it a contact
                assert not only_local(checker, contact, rings=FOLD_RINGS)
    assert rings[3612] == FOLD_RINGS
    assert rings[39692] == pytest.approx(FOLD_RINGS * np.sqrt(39692 / 3612), abs=1)


def test_two_faces_folded_onto_each_other_are_found():
    # oracle: geometry. Moving the far vertex l of a hinge (i, j, k, l) onto k puts the face
    # (j, i, l) on (i, j, k): outward normals opposite, dihedral angle 180 degrees. Rotating l
    # about the edge by 1 degree from there is no longer flat.
    from scipy.spatial.transform import Rotation

    from shellbuckle.protocol.deflate import FLAT_FOLD_TOL, folded_flat

    mesh = icosphere(3)
    hinges = mesh.topology.hinges
    assert folded_flat(mesh.X, hinges) is None
    h = 17
    i, j, k, l = hinges[h]
    X = mesh.X.copy()
    X[l] = X[k]
    reason = folded_flat(X, hinges)
    assert reason is not None and f"edge {i}-{j}" in reason and "180.000 degrees" in reason
    axis = (X[j] - X[i]) / np.linalg.norm(X[j] - X[i])
    for angle, flat in ((np.degrees(FLAT_FOLD_TOL) / 2, True), (1.0, False)):
        Y = X.copy()
        Y[l] = X[i] + Rotation.from_rotvec(np.radians(angle) * axis).apply(X[k] - X[i])
        assert (folded_flat(Y, hinges) is not None) == flat


def test_a_minimization_abandoned_on_a_fold_is_jiggled_again(monkeypatch):
    # a minimization stopped by the fold test counts as tangled whatever its energy
    import dataclasses

    import shellbuckle.protocol.deflate as deflate
    from shellbuckle.params import ShellParameters
    from shellbuckle.solve.newton import ABANDONED

    mesh = icosphere(3)
    ctx, state = deflate.init(mesh, ShellParameters.from_gamma(271.0, nu=1.0 / 3.0),
                              Protocol(schedule=(0.019,), seed=4))
    minimize, calls = deflate._minimize, []

    def first_abandoned(*args, **kwargs):
        result = minimize(*args, **kwargs)
        calls.append(result)
        if len(calls) == 1:
            return dataclasses.replace(result, success=False, message=f"{ABANDONED}: a fold")
        return result

    monkeypatch.setattr(deflate, "_minimize", first_abandoned)
    _, record = deflate.step(ctx, state)
    assert record["jiggle_attempts"] == 2 and record["converged"] and len(calls) == 4


def _vertex_pushed_through_a_nearby_face(mesh, lift=0.2):
    """``mesh.X`` with vertex 0 moved just outside a face two rings away: its star then passes
    through the surface there (a fold of the mesh, as a jiggle can leave)."""
    X, F = mesh.X.copy(), np.asarray(mesh.faces)
    edge = np.linalg.norm(X[F[:, 0]] - X[F[:, 1]], axis=1).mean()
    ring = set(F[(F == 0).any(axis=1)].ravel())
    ring2 = set(F[[bool(set(f) & ring) for f in F]].ravel())
    f = next(i for i, face in enumerate(F) if not set(face) & ring and len(set(face) & ring2) >= 2)
    c = X[F[f]].mean(axis=0)
    X[0] = c + lift * edge * c / np.linalg.norm(c)
    return X


def test_a_local_self_intersection_is_a_fold_and_a_distant_one_is_not():
    # oracle: the exact triangle-triangle test (the surface crosses itself near vertex 0 only)
    # and the distance on the mesh of the crossing faces
    from shellbuckle.mesh.contact import ContactChecker
    from shellbuckle.protocol.deflate import FOLD_RINGS, folded_locally

    mesh = icosphere(6)
    checker = ContactChecker(mesh.topology)
    assert folded_locally(checker, mesh.X, rings=FOLD_RINGS) is None
    folded = _vertex_pushed_through_a_nearby_face(mesh)
    pairs, n = checker.intersecting_pairs(folded)
    assert n > 0 and (checker.face_distance(pairs[:, 0], pairs[:, 1], FOLD_RINGS) <= 2).all()
    reason = folded_locally(checker, folded, rings=FOLD_RINGS)
    assert reason is not None and f"faces {pairs[0, 0]} and {pairs[0, 1]} intersect" in reason
    spiked = mesh.X.copy()
    spiked[0] = -1.5 * mesh.X[0]  # through the far side of the shell: a contact, not a fold
    assert checker.intersecting_pairs(spiked)[1] > 0
    assert folded_locally(checker, spiked, rings=FOLD_RINGS) is None


def test_a_stalled_minimization_left_in_a_fold_is_jiggled_again_without_the_cycle(monkeypatch):
    # the same stalled first minimization as in the test above, but ending where the surface
    # passes through itself locally: jiggled again at once, the cycle only after the retry
    mesh = icosphere(3)
    folded = _vertex_pushed_through_a_nearby_face(mesh)
    *_, record, calls = _first_step_with_first_minimization_changed(
        monkeypatch, success=False, message="stalled: (a test)", x=folded)
    assert record["jiggle_attempts"] == 2 and record["converged"] and record["inertia"] == 0
    assert len(calls) == 4  # the stalled attempt, then the retry's minimization and cycle
    assert [c.get("warm") is None for c in calls] == [True, True, False, False]
