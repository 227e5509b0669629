"""Energies of Surface Evolver files against the numbers Surface Evolver 2.70 printed.

The oracle is tests/fixtures/evolver/evolver_values.json, made by make_fixtures.sh with the real
Surface Evolver 2.70 (printf %.17g of total_energy, the quantity values, body volume and
total_area). These tests never run Evolver.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from shellbuckle.cli import main
from shellbuckle.energies.evolver import evolver_energy, evolver_terms
from shellbuckle.energies.evolver_bending import StarPerpBending
from shellbuckle.energies.stretching import Stretching
from shellbuckle.mesh import icosphere
from shellbuckle.mesh.evolver_io import read_evolver, write_evolver

FIXTURES = Path(__file__).parent / "fixtures" / "evolver"
EVOLVER = json.loads((FIXTURES / "evolver_values.json").read_text())
KEYS = ("E_stretch", "E_bend", "volume", "area")
CASES = sorted(EVOLVER["cases"])


def _compare(ours, printed, rtol):
    for key in KEYS:
        assert ours[key] == pytest.approx(printed[key], rel=rtol, abs=0), key
    # Evolver's total_energy also counts the facet surface tension
    assert ours["E_total"] + ours["E_tension"] == pytest.approx(printed["E_total"], rel=rtol, abs=0)
    assert ours["E_total"] == ours["E_stretch"] + ours["E_bend"]


@pytest.mark.parametrize("case", CASES)
def test_datafile_energies_match_evolver(case):
    _compare(evolver_energy(FIXTURES / f"{case}.fe"), EVOLVER["cases"][case]["fe"], 1e-10)


@pytest.mark.parametrize("case", CASES)
def test_dump_energies_match_evolver(case):
    ours = evolver_energy(FIXTURES / f"{case}.dmp")
    _compare(ours, EVOLVER["cases"][case]["dmp"], 1e-10)
    # the same numbers Evolver had in memory before dumping (the dump has 15 digits)
    _compare(ours, EVOLVER["cases"][case]["evolved"], 1e-10)


def test_fixture_cases_exercise_the_features():
    # every case has a non-negligible stretching and bending energy, so the relative checks bite
    for case in CASES:
        for stage in ("fe", "dmp"):
            values = EVOLVER["cases"][case][stage]
            assert values["E_stretch"] > 1e-2 and values["E_bend"] > 1e-2
    assert "2.70" in EVOLVER["evolver"]


def _perturbed_sphere():
    mesh = icosphere(4)
    rng = np.random.default_rng(11)
    return mesh, mesh.X * (1 + 0.04 * rng.uniform(-1, 1, (mesh.n_vertices, 1)))


def test_round_trip_write_read_gives_the_same_energies(tmp_path):
    mesh, X = _perturbed_sphere()
    kappa, c0, A, nu = 0.9, 2.0, 250.0, 0.3
    stretch = Stretching.from_reference(mesh.X, mesh.faces, mesh.n_vertices, A=A, nu=nu)
    bend = StarPerpBending(mesh.faces, mesh.n_vertices, kappa=kappa, c0=c0)
    x = mesh.X[mesh.faces]
    s, t = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    ff = np.stack([(s * s).sum(1), (s * t).sum(1), (t * t).sum(1)], axis=1)
    path = write_evolver(tmp_path / "shell.fe", mesh.with_positions(X), kappa=kappa, c0=c0, A=A, nu=nu,
                         form_factors=ff)
    result = evolver_energy(path)
    assert result["E_stretch"] == pytest.approx(stretch.value(X), rel=1e-12)
    assert result["E_bend"] == pytest.approx(bend.value(X), rel=1e-12)
    assert result["E_tension"] == 0.0
    terms = evolver_terms(path)
    assert len(terms["stretch"]) == 1 and len(terms["bend"]) == 1
    np.testing.assert_allclose(terms["bend"][0].gradient(X), bend.gradient(X), rtol=0,
                               atol=1e-12 * abs(bend.gradient(X)).max())


def test_reversed_facets_flip_h_zero(tmp_path):
    # The hand-made octahedron lists its facets inwards: Evolver's h is measured along them, so
    # the equivalent outward term has h_zero negated. Check against the bending term built on the
    # file's own inward facets (where h_zero keeps its sign).
    evf = read_evolver(FIXTURES / "octahedron_handmade.fe")
    assert (evf.facet_sign == -1).all()
    (q,) = evf.energy_quantities("star_perp_sq_mean_curvature")
    inward = StarPerpBending.from_evolver(evf.mesh.faces[:, [0, 2, 1]], evf.mesh.n_vertices,
                                          modulus=q.modulus, h_zero=evf.h_zero, vertices=q.vertices)
    assert evolver_energy(evf)["E_bend"] == pytest.approx(inward.value(evf.mesh.X), rel=1e-14)


def test_missing_form_factors_is_refused(tmp_path):
    text = (FIXTURES / "octahedron_handmade.fe").read_text()
    text = text.replace("define facet attribute form_factors real[3]\n", "")
    text = "\n".join(line.split(" form_factors")[0] if line[:1].isdigit() else line
                     for line in text.splitlines())
    path = tmp_path / "noff.fe"
    path.write_text(text)
    with pytest.raises(ValueError, match="needs the facet attribute form_factors"):
        evolver_energy(path)


def test_unset_form_factors_give_zero_stretching_like_evolver(tmp_path):
    # Evolver 2.70 returns 0 for a facet whose form_factors determinant is <= 0
    text = (FIXTURES / "octahedron_handmade.fe").read_text()
    text = text.replace("form_factors {2, 0.5, 1.5}", "")
    path = tmp_path / "unset.fe"
    path.write_text(text)
    full = evolver_energy(FIXTURES / "octahedron_handmade.fe")
    part = evolver_energy(path)
    assert 0 < part["E_stretch"] < full["E_stretch"]


def test_mixed_facet_orientation_is_refused_for_bending(tmp_path):
    text = (FIXTURES / "octahedron_handmade.fe").read_text()
    # reverse facet 1 and list it positive in the body: a consistent surface, mixed facets
    text = text.replace("1  5 -6 -1   poisson_ratio", "1  1 6 -5   poisson_ratio")
    text = text.replace("1 -1 -2 -3", "1 1 -2 -3")
    path = tmp_path / "mixed.fe"
    path.write_text(text)
    with pytest.raises(ValueError, match="opposite orientations"):
        evolver_energy(path)


def test_cli_json(capsys):
    path = FIXTURES / "dented.dmp"
    assert main(["evolver-energy", str(path), "--json"]) == 0
    out = capsys.readouterr().out
    data = json.loads(out)
    assert out.strip().count("\n") == 0
    assert set(data) == {"E_stretch", "E_bend", "E_total", "volume", "area"}
    printed = EVOLVER["cases"]["dented"]["dmp"]
    for key in KEYS:
        assert data[key] == pytest.approx(printed[key], rel=1e-10)


def test_cli_table(capsys):
    assert main(["evolver-energy", str(FIXTURES / "octahedron_handmade.fe")]) == 0
    out = capsys.readouterr().out
    for key in ("E_stretch", "E_bend", "E_total", "volume", "area", "read"):
        assert key in out


def test_cli_bad_file_exits_2(tmp_path, capsys):
    bad = tmp_path / "bad.fe"
    bad.write_text("vertices\n1 0 0\n")
    assert main(["evolver-energy", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "line 2" in err and "3 coordinates" in err and "Traceback" not in err
    assert main(["evolver-energy", str(tmp_path / "missing.fe")]) == 2
