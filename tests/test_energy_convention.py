"""The energy conventions (shellbuckle.params): which bending energy kappa multiplies.

Oracles: the paper's eq. (1) read literally, 1/2 kappa (H - H0)^2 with H = (c1 + c2)/2 and
H0 = 1/R, is 1/4 of the standard 1/2 kappa (c1 + c2 - c0)^2 (since c1 + c2 = 2H and
c0 = 2 H0); Surface Evolver's modulus reading kappa (H - H0)^2 is 1/2 of it. The factors 1/4
and 1/2 below are written from that algebra, not read from the code. A shell under a
convention is then the standard shell at kappa f with the same A: the same minimizers as the
standard shell at gamma / f, with energies in units of kappa scaled by 1/f.
"""

import json

import numpy as np
import pytest

from shellbuckle import theory
from shellbuckle.cli import main
from shellbuckle.energies.evolver import evolver_energy
from shellbuckle.energies.total import ShellEnergy
from shellbuckle.export import export_step
from shellbuckle.mesh import random_sphere
from shellbuckle.mesh.evolver_io import read_evolver
from shellbuckle.mesh.mesh import Mesh
from shellbuckle.params import ShellParameters
from shellbuckle.run import Run, deflate, params_for_mesh, resume, shell_from_file

FACTOR = {"paper": 1.0 / 4.0, "evolver-modulus": 1.0 / 2.0}
GAMMA, NU = 600.0, 1.0 / 3.0


def _perturbed(n=300, seed=5, scale=0.03):
    mesh = random_sphere(n, seed=seed)
    rng = np.random.default_rng(seed)
    return mesh, mesh.X + scale * rng.normal(size=mesh.X.shape)


def _close(a, b, rtol=1e-12):
    a, b = np.asarray(a, float), np.asarray(b, float)
    assert np.max(np.abs(a - b)) <= rtol * np.max(np.abs(b))


@pytest.mark.parametrize("bending", ["juelicher", "evolver"])
@pytest.mark.parametrize("convention", ["paper", "evolver-modulus"])
def test_energy_gradient_and_hessian_equal_the_standard_energy_at_scaled_kappa(bending,
                                                                             convention):
    mesh, X = _perturbed()
    f = FACTOR[convention]
    ours = ShellEnergy.build(mesh, ShellParameters.from_gamma(GAMMA, NU, energy_convention=convention),
                             bending=bending)
    # the standard energy with bending modulus f kappa and the same A = gamma kappa / R^2
    standard = ShellEnergy.build(mesh, ShellParameters.from_gamma(GAMMA / f, NU, kappa=f),
                                 bending=bending)
    unit = ShellEnergy.build(mesh, ShellParameters.from_gamma(GAMMA, NU), bending=bending)
    assert ours.bending.value(X) == pytest.approx(f * unit.bending.value(X), rel=1e-12)
    assert ours.stretching.value(X) == pytest.approx(unit.stretching.value(X), rel=1e-14)
    assert ours.value(X) == pytest.approx(standard.value(X), rel=1e-12)
    _close(ours.gradient(X), standard.gradient(X))
    _close(ours.hessian(X).toarray(), standard.hessian(X).toarray())


def test_paper_bending_energy_is_half_kappa_mean_curvature_deviation_squared():
    """Under paper, E_bend = sum_i 1/2 kappa (H_i - 1/R)^2 A_i with the discretization's vertex
    mean curvature H_i = (c1 + c2)/2 and vertex area A_i (Jülicher), on a perturbed mesh."""
    mesh, X = _perturbed()
    kappa = 2.5
    params = ShellParameters.from_gamma(GAMMA, NU, kappa=kappa, energy_convention="paper")
    bending = ShellEnergy.build(mesh, params).bending
    H, area = np.asarray(bending.mean_curvature(X)), np.asarray(bending.vertex_areas(X))
    expected = np.sum(0.5 * kappa * (H - 1.0 / params.R) ** 2 * area)
    assert bending.value(X) == pytest.approx(expected, rel=1e-12)


def test_deflation_under_paper_is_the_standard_deflation_at_four_gamma(tmp_path):
    """Same shapes, and E/kappa and pressure/kappa times 4, through primary buckling."""
    mesh = random_sphere(400, seed=3)
    a = deflate(mesh, ShellParameters.from_gamma(GAMMA, energy_convention="paper"),
                until=0.114, seed=3, out=tmp_path / "paper", threads=1)
    b = deflate(mesh, ShellParameters.from_gamma(4 * GAMMA), until=0.114, seed=3,
                out=tmp_path / "helfrich", threads=1)
    ta, tb = a.table, b.table
    assert list(ta["step"]) == list(tb["step"]) and len(ta) == 7
    np.testing.assert_allclose(4 * ta["E_over_kappa"], tb["E_over_kappa"], rtol=1e-9)
    np.testing.assert_allclose(4 * ta["pressure"], tb["pressure"], rtol=1e-6, atol=1e-9)
    for k in a.steps:
        np.testing.assert_allclose(a.positions(k), b.positions(k), atol=1e-5)
    # it buckled on the way (the pressure drops), so the invariance covers the buckled branch
    p = tb["pressure"].to_numpy()
    assert (p[2:] < 0.8 * p[1:-1]).any()


def test_the_convention_is_stored_and_kept_by_resume(tmp_path):
    mesh = random_sphere(200, seed=1)
    params = ShellParameters.from_gamma(GAMMA, energy_convention="evolver-modulus")
    whole = deflate(mesh, params, until=0.076, seed=1, out=tmp_path / "whole", threads=1)
    part = deflate(mesh, params, until=0.076, seed=1, out=tmp_path / "part", threads=1,
                   max_steps=2)
    assert part.params == params and len(part.steps) == 3  # steps 0, 1, 2: interrupted
    stored = json.loads((tmp_path / "part" / "run.json").read_text())
    assert stored["params"]["energy_convention"] == "evolver-modulus"
    assert stored["params"]["gamma_effective"] == pytest.approx(2 * GAMMA)
    resumed = resume(tmp_path / "part", threads=1)
    assert Run.open(resumed.path).params == params
    np.testing.assert_array_equal(resumed.table["E_total"], whole.table["E_total"])


def test_run_json_without_a_convention_reads_as_helfrich():
    data = ShellParameters.from_gamma(GAMMA).to_dict()
    del data["energy_convention"], data["gamma_effective"]
    assert ShellParameters.from_dict(data).energy_convention == "helfrich"
    with pytest.raises(ValueError, match="helfrich, paper, evolver-modulus, got 'quarter'"):
        ShellParameters.from_dict(data | {"energy_convention": "quarter"})
    with pytest.raises(ValueError, match="gamma_effective"):
        ShellParameters.from_dict(ShellParameters.from_gamma(GAMMA, energy_convention="paper")
                                  .to_dict() | {"gamma_effective": GAMMA})


@pytest.mark.parametrize("convention", ["paper", "evolver-modulus"])
def test_theory_under_a_convention_is_the_standard_theory_at_gamma_over_f(convention):
    f = FACTOR[convention]
    for gamma in (271.0, 2916.0, 29160.0):
        ours = ShellParameters.from_gamma(gamma, NU, energy_convention=convention)
        std = ShellParameters.from_gamma(gamma / f, NU)
        x = np.linspace(0.01, 0.9, 9)
        # energies in units of kappa: ours = f * standard's (whose kappa unit is f times ours)
        _close(theory.U_axisym_of_dV(x, ours) / ours.kappa, f * theory.U_axisym_of_dV(x, std))
        _close(theory.U_sphere(x, ours), f * theory.U_sphere(x, std))
        assert theory.crossing(ours) == pytest.approx(theory.crossing(std), rel=1e-12)
        ct, cs = theory.classical_threshold(ours), theory.classical_threshold(std)
        assert ct.dV_over_V == pytest.approx(6 * (1 - NU) / np.sqrt(gamma / f), rel=1e-14)
        assert ct.dV_over_V_exact == pytest.approx(cs.dV_over_V_exact, rel=1e-12)
        assert ct.pressure == pytest.approx(f * cs.pressure, rel=1e-12)
        assert ours.d_over_R_effective == pytest.approx(ours.d_over_R * np.sqrt(f), rel=1e-12)


def test_material_under_paper_behaves_as_half_the_thickness():
    E, sigma, d, R = 2.0e6, 0.5, 0.04, 1.0
    paper = ShellParameters.from_material(E, sigma, d, R, energy_convention="paper")
    assert paper.kappa == pytest.approx(E * d ** 3 / (12 * (1 - sigma ** 2)))
    assert paper.gamma_effective == pytest.approx(
        ShellParameters.from_material(E, sigma, d / 2, R).gamma, rel=1e-12)
    assert paper.d_over_R_effective == pytest.approx(d / 2 / R, rel=1e-12)


@pytest.mark.parametrize("convention", ["helfrich", "paper", "evolver-modulus"])
def test_an_exported_fe_carries_the_energy_and_reads_back_under_its_convention(tmp_path,
                                                                            convention):
    run = deflate(random_sphere(150, seed=2),
                  ShellParameters.from_gamma(GAMMA, energy_convention=convention),
                  schedule=[0.02], bending="evolver", out=tmp_path / "run", threads=1)
    path = export_step(run, 1, tmp_path / "s1.fe")
    row = run.table.iloc[-1]
    energies = evolver_energy(read_evolver(path))
    assert energies["E_bend"] == pytest.approx(row["E_bend"], rel=1e-10)
    mesh, found = shell_from_file(path)
    X0 = Mesh.from_arrays(run.store.X0, run.faces)
    back = params_for_mesh(X0, found, energy_convention=convention)
    assert back.kappa == pytest.approx(1.0, rel=1e-12)  # the kappa the run was given
    assert back.A == pytest.approx(GAMMA, rel=1e-12)  # A = gamma kappa / R^2 with R = 1


def test_cli_refuses_an_unknown_convention_naming_it_and_the_choices(tmp_path, capsys):
    for argv in (["deflate", "--energy-convention", "quarter", "--out", str(tmp_path / "r")],
                 ["theory", "--energy-convention", "quarter"],
                 ["reproduce-paper", "--energy-convention", "quarter", "--out",
                  str(tmp_path / "s")],
                 ["sweep", "--energy-convention", "quarter", "--out", str(tmp_path / "w")]):
        with pytest.raises(SystemExit) as exit_info:
            code = main(argv)
            raise SystemExit(code)
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert "quarter" in err and "energy" in err and "paper" in err
    assert not any(tmp_path.iterdir())


def test_cli_theory_under_paper_prints_the_standard_numbers_at_four_gamma(tmp_path, capsys):
    out = tmp_path / "t.png"
    assert main(["theory", "--gamma", "2916", "--energy-convention", "paper", "--json",
                 "--out", str(out)]) == 0
    paper = json.loads(capsys.readouterr().out)
    assert main(["theory", "--gamma", str(4 * 2916), "--json", "--out", str(out)]) == 0
    std = json.loads(capsys.readouterr().out)
    assert paper["gamma_effective"] == 4 * 2916 and paper["energy_convention"] == "paper"
    assert paper["classical_dV_over_V"] == pytest.approx(4.0 / np.sqrt(4 * 2916), rel=1e-14)
    for key in ("crossing_dV_over_V", "classical_dV_over_V_exact", "d_over_R_effective"):
        assert paper[key] == pytest.approx(std[key], rel=1e-12)
