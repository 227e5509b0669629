"""A deflation of a Surface Evolver dump against Surface Evolver's own deflation of it.

The oracle is tests/fixtures/evolver/evolver_deflation.json, made by
make_deflation_fixture.sh with the real Surface Evolver 2.70: the gamma = 271 shell
gamma271.dmp (400 vertices) taken to the pre-buckling targets dV/V = 0.005 ... 0.02, each
minimized with Evolver's Newton steps (hessian) until the energy stops changing at 1e-15
relative, and its energies printed with %.17g. These tests never run Evolver.

`shellbuckle deflate --mesh gamma271.dmp` with no --bending bends with the file's
star_perp_sq_mean_curvature and lands on the same minima: E_total within 3e-13, E_stretch
within 2e-12 and E_bend (the small term) within 2e-10 relative of Evolver's, at volumes equal
to 1e-15. The Jülicher discretization (--bending juelicher) is off by 1.8e-3 to 9e-3 in E_total
and 24 to 44 % in E_bend (its E_stretch by only 4e-6 to 8e-5, so that term is not the contrast).
"""

import json
from pathlib import Path

import pytest

from shellbuckle.cli import main
from shellbuckle.run import Run

FIXTURES = Path(__file__).parent / "fixtures" / "evolver"
DUMP = FIXTURES / "gamma271.dmp"
EVOLVER = json.loads((FIXTURES / "evolver_deflation.json").read_text())
TARGETS = [t["dV_over_V"] for t in EVOLVER["targets"]]
ENERGIES = ("E_total", "E_stretch", "E_bend")


def _deflate(path, *extra) -> Run:
    """deflate --mesh gamma271.dmp through Evolver's targets, without jiggle."""
    schedule = ",".join(repr(x) for x in TARGETS)
    assert main(["deflate", "--mesh", str(DUMP), "--schedule", schedule, "--temperature", "0",
                 *extra, "--out", str(path), "--threads", "1", "--no-plot", "--quiet"]) == 0
    return Run.open(path)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("deflation")
    return {"default": _deflate(base / "default"),
            "juelicher": _deflate(base / "juelicher", "--bending", "juelicher")}


def _rows(run):
    """The stored steps by target dV/V, the start under 0."""
    table = run.table
    return {float(row.target_dV_over_V): row for row in table.itertuples()}


def test_the_fixture_is_a_converged_prebuckling_deflation():
    assert "2.70" in EVOLVER["evolver"]
    assert TARGETS == sorted(TARGETS) and len(TARGETS) == 4
    for printed in EVOLVER["targets"]:
        # Newton converged: the last step changed the energy at rounding level
        assert abs(printed["last_change"]) <= 1e-15 * printed["E_total"]
        # both terms large enough for a relative check to bite
        assert printed["E_stretch"] > 1e-2 and printed["E_bend"] > 1e-4
    # far before the classical buckling of gamma = 271 (dV/V = 0.2155, exact p-V relation)
    assert TARGETS[-1] < 0.1 * 0.2155


def test_the_run_reads_the_shell_of_the_dump(runs):
    run = runs["default"]
    assert run.protocol.bending == "evolver"
    assert run.protocol.temperature == 0 and run.protocol.jiggle is None
    assert run.params.gamma == pytest.approx(271.0, rel=1e-12)
    start = _rows(run)[0.0]
    for key in ENERGIES:
        assert getattr(start, key) == pytest.approx(EVOLVER["start"][key], rel=1e-12, abs=1e-20), key


@pytest.mark.parametrize("index", range(len(TARGETS)))
def test_deflate_follows_evolvers_prebuckling_energies(runs, index):
    printed = EVOLVER["targets"][index]
    row = _rows(runs["default"])[printed["dV_over_V"]]
    # the same volume: both sides measure V0 on the dump as loaded
    evolver_dv = 1.0 - printed["volume"] / EVOLVER["start"]["volume"]
    assert row.dV_over_V == pytest.approx(evolver_dv, abs=1e-12)
    for key in ENERGIES:
        assert getattr(row, key) == pytest.approx(printed[key], rel=1e-8, abs=0), key


def test_the_juelicher_discretization_does_not(runs):
    """The contrast: the other bending discretization misses Evolver's energies."""
    run = runs["juelicher"]
    assert run.protocol.bending == "juelicher"
    rows = _rows(run)
    for printed in EVOLVER["targets"]:
        row = rows[printed["dV_over_V"]]
        for key in ("E_total", "E_bend"):
            assert abs(getattr(row, key) / printed[key] - 1.0) > 1e-5, key
