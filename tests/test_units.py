"""Physical units of a run's results (shellbuckle.params.unit_scale, to_si, to_reduced;
shellbuckle.store.table.table_in_units).

Oracles: the paper's conversions, written out here (Quilliet et al. 2008, section 3):
kappa = E d^3 / (12 (1 - sigma^2)), energies are E/kappa times kappa, pressures p R^3/kappa times
kappa/R^3, lengths x/R times R; and scale invariance: the same shell (gamma, nu) deflated in
reduced units and as a material of size R gives the same reduced results.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from shellbuckle.mesh import icosphere
from shellbuckle.mesh.mesh import Mesh
from shellbuckle.params import ShellParameters, to_reduced, to_si, unit_scale
from shellbuckle.run import deflate
from shellbuckle.store.table import table_in_units

MATERIALS = [(2e6, 0.5, 1e-5, 1e-4), (3.5e9, 0.3, 2e-7, 1e-5), (1.0, 0.0, 0.05, 1.0)]


def _kappa(E, sigma, d):
    return E * d ** 3 / (12.0 * (1.0 - sigma ** 2))


@pytest.mark.parametrize("E, sigma, d, R", MATERIALS)
def test_the_reduced_units_of_a_material_are_the_papers(E, sigma, d, R):
    params = ShellParameters.from_material(E=E, sigma=sigma, d=d, R=R)
    kappa = _kappa(E, sigma, d)
    expected = {"energy": kappa, "pressure": kappa / R ** 3, "length": R, "curvature": 1 / R,
                "force": kappa / R}
    for dimension, value in expected.items():
        assert unit_scale(params, dimension) == pytest.approx(value, rel=1e-14)
    reduced = np.array([0.0, 1.5, 8 * math.pi, -3.25])
    assert to_si(reduced, "energy", params) == pytest.approx(reduced * kappa, rel=1e-14)
    assert to_si(2.0, "pressure", params) == pytest.approx(2.0 * kappa / R ** 3, rel=1e-14)
    assert to_si(0.5, "length", params) == pytest.approx(0.5 * R, rel=1e-14)
    for dimension in expected:
        back = to_reduced(to_si(reduced, dimension, params), dimension, params)
        np.testing.assert_allclose(back, reduced, rtol=1e-15)


def test_si_needs_a_material_and_dimensions_are_named():
    params = ShellParameters.from_gamma(2333.0)
    with pytest.raises(ValueError, match="no material"):
        to_si(1.0, "energy", params)
    with pytest.raises(ValueError, match="dimension must be one of energy"):
        unit_scale(params, "temperature")
    # a shell given by gamma: its reduced units are its own (kappa = R = 1 by default)
    assert all(unit_scale(params, d) == 1.0 for d in ("energy", "pressure", "length"))


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """The same shell (gamma = 800, nu = 1/3: d/R = 0.1) deflated by one pre-buckling step in
    reduced units and as a material of radius 0.1 mm (92 vertices, ~1 s)."""
    root = tmp_path_factory.mktemp("units")
    material = ShellParameters.from_material(E=2e6, sigma=0.5, d=1e-5, R=1e-4)
    reduced = ShellParameters.from_gamma(material.gamma, nu=material.nu)
    mesh = icosphere(3)
    sized = Mesh.from_arrays(mesh.X * material.R, mesh.faces)
    a = deflate(mesh, reduced, dv=0.04, until=0.04, seed=1, out=root / "g", locate=False,
                threads=1)
    b = deflate(sized, material, dv=0.04, until=0.04, seed=1, out=root / "m", locate=False,
                threads=1)
    return a, b


COLUMNS = {"E_total": "energy", "E_bend": "energy", "E_stretch": "energy", "pressure": "pressure",
           "min_distance": "length", "c0": "curvature"}


def test_a_material_run_in_si_is_the_reduced_run_times_the_papers_units(pair):
    a, b = pair
    E, sigma, d, R = 2e6, 0.5, 1e-5, 1e-4
    kappa = _kappa(E, sigma, d)
    scale = {"energy": kappa, "pressure": kappa / R ** 3, "length": R, "curvature": 1 / R}
    reduced = table_in_units(a.table, a.params, "reduced")
    si = table_in_units(b.table, b.params, "si")
    assert si["pressure"].iloc[1] > 0 and si["E_stretch"].iloc[1] > 0  # a compressed shell
    for column, dimension in COLUMNS.items():
        np.testing.assert_allclose(si[column].to_numpy(float),
                                   reduced[column].to_numpy(float) * scale[dimension],
                                   rtol=1e-6, atol=1e-30, err_msg=column)
    # and the material run read in reduced units is the reduced run (scale invariance)
    back = table_in_units(b.table, b.params, "reduced")
    for column in COLUMNS:
        np.testing.assert_allclose(back[column].to_numpy(float),
                                   reduced[column].to_numpy(float), rtol=1e-6, atol=1e-20,
                                   err_msg=column)
    # E/kappa has no dimension: the same in both unit systems, and the energy in kappa
    assert back["E_over_kappa"].tolist() == si["E_over_kappa"].tolist()
    np.testing.assert_allclose(back["E_over_kappa"], back["E_total"], rtol=1e-12)


def test_reduced_units_of_a_gamma_run_are_its_stored_values_to_the_bit(pair):
    a, _ = pair
    table = a.table
    reduced = table_in_units(table, a.params, "reduced")
    for column in COLUMNS:
        assert reduced[column].to_numpy(float).tobytes() == table[column].to_numpy(float).tobytes()
    with pytest.raises(ValueError, match="no material"):
        table_in_units(table, a.params, "si")


def test_a_colloid_in_si_units_buckles_as_the_same_shell_in_reduced_units(tmp_path):
    """A 20 nm shell 2 nm thick (kappa ~ 1e-19 J, the paper's colloids) deflated in SI units
    through its buckling: every step the reduced shell's, E/kappa to 1e-9. The gradient test's
    absolute part is a force in the shell's units (kappa / R); a fixed 1e-10 N exceeds this
    shell's forces and ended its minimizations after a few steps, 60 % above the minimum."""
    material = ShellParameters.from_material(E=1e8, sigma=0.5, d=2e-9, R=2e-8)
    reduced = ShellParameters.from_gamma(material.gamma, nu=material.nu)
    assert material.kappa < 1e-18 and material.gamma == pytest.approx(800.0)
    a = deflate(icosphere(4), reduced, until=0.1, out=tmp_path / "g", locate=False, threads=1)
    b = deflate(icosphere(4, R=material.R), material, until=0.1, out=tmp_path / "m",
                locate=False, threads=1)
    assert a.table["converged"].all() and b.table["converged"].all()
    assert a.table["E_over_kappa"].iloc[-1] > 10.0  # past the buckling (about 6 for a sphere)
    np.testing.assert_allclose(b.table["E_over_kappa"].to_numpy(float),
                               a.table["E_over_kappa"].to_numpy(float), rtol=1e-9, atol=0)
    # before the buckling the minimizations take the same steps (the rounding of the two
    # unit systems differs, so the buckling step may take another path to the same minimum)
    assert b.table["iterations"].tolist()[:4] == a.table["iterations"].tolist()[:4]


def test_a_colloid_under_pressure_in_si_units_is_the_reduced_shell(tmp_path):
    """Pressures are in the shell's own units (Pa for a material): 50 kappa/R^3, below the
    classical buckling pressure, is accepted in Pa and shrinks the shell as the reduced run's
    50 does."""
    material = ShellParameters.from_material(E=1e8, sigma=0.5, d=2e-9, R=2e-8)
    reduced = ShellParameters.from_gamma(material.gamma, nu=material.nu)
    unit = material.kappa / material.R ** 3
    a = deflate(icosphere(4), reduced, pressures=[50.0], out=tmp_path / "g", locate=False,
                threads=1)
    b = deflate(icosphere(4, R=material.R), material, pressures=[50.0 * unit],
                out=tmp_path / "m", locate=False, threads=1)
    assert a.table["dV_over_V"].iloc[-1] > 0.01
    np.testing.assert_allclose(b.table["dV_over_V"].to_numpy(float),
                               a.table["dV_over_V"].to_numpy(float), rtol=1e-9, atol=1e-15)
    with pytest.raises(ValueError, match="allowed overpressures"):  # above p_c in Pa
        deflate(icosphere(4, R=material.R), material, pressures=[200.0 * unit],
                out=tmp_path / "x", locate=False, threads=1)
    assert not (tmp_path / "x").exists()


def test_the_command_line_takes_a_materials_pressures_in_pascal(tmp_path):
    """`--pressures` of a shell given by --E --sigma --d --R are in Pa: 50 kappa/R^3 in Pa is
    accepted (it was refused against bounds in kappa/R^3) and gives the reduced shell's
    volume; 2.3e6 Pa, above p_c = 1.26e6 Pa, is refused naming the option."""
    from shellbuckle.cli import main

    material = ShellParameters.from_material(E=1e8, sigma=0.5, d=2e-9, R=2e-8)
    pascal = 50.0 * material.kappa / material.R ** 3
    shell = ["deflate", "--E", "1e8", "--sigma", "0.5", "--d", "2e-9", "--R", "2e-8",
             "--icosphere", "4", "--no-plot", "--no-locate", "--quiet", "--threads", "1"]
    assert main([*shell, "--pressures", repr(pascal), "--out", str(tmp_path / "m")]) == 0
    reduced = deflate(icosphere(4), ShellParameters.from_gamma(material.gamma, nu=material.nu),
                      pressures=[50.0], out=tmp_path / "g", locate=False, threads=1)
    from shellbuckle.run import Run

    assert Run.open(tmp_path / "m").table["dV_over_V"].iloc[-1] == pytest.approx(
        reduced.table["dV_over_V"].iloc[-1], rel=1e-9)
    assert main([*shell, "--pressures", "2.3e6", "--out", str(tmp_path / "x")]) == 2
    assert not (tmp_path / "x").exists()


def test_a_material_runs_printed_pressures_are_in_kappa_over_R3_as_their_label_says(tmp_path,
                                                                                  capsys):
    """The last step's pressure and the located events' pressures of a run made from a
    material equal the reduced table's (``table``, κ/R³), and the last step's in Pa equals
    the SI table's: the stored values are in Pa, and were printed as if they were κ/R³."""
    import re

    from shellbuckle.cli import main
    from shellbuckle.run import Run
    from shellbuckle.store.located import read_located
    from shellbuckle.store.table import table_in_units

    out = tmp_path / "rubber"
    assert main(["deflate", "--E", "1e6", "--sigma", "0.5", "--d", "1e-5", "--R", "1e-4",
                 "--vertices", "200", "--dv", "0.05", "--until", "0.15", "--quiet", "--no-plot",
                 "--threads", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    run = Run.open(out)
    reduced = table_in_units(run.table, run.params, "reduced")["pressure"].iloc[-1]
    si = run.table["pressure"].iloc[-1]
    assert reduced < 1e3 < si  # the two units differ by kappa/R^3 = 111 Pa here
    found = re.search(r"pressure = (\S+) kappa/R\^3 \((\S+) Pa\)", printed)
    assert found, printed
    assert float(found[1]) == pytest.approx(reduced, rel=1e-5)
    assert float(found[2]) == pytest.approx(si, rel=1e-5)
    event = read_located(out)["primary_buckling"]  # stored in Pa; printed in kappa/R^3
    unit = run.params.kappa / run.params.R ** 3
    shown = re.search(r"p (\S+) -> (\S+),", printed)
    assert float(shown[1]) == pytest.approx(event["old"]["pressure"] / unit, rel=1e-4)
    assert float(shown[2]) == pytest.approx(event["new"]["pressure"] / unit, rel=1e-4)
