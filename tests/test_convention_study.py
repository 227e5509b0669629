"""reproduce-paper --compare-conventions (shellbuckle.convention_study) at a tiny scale.

Oracle: a study under ``paper`` at gamma is the standard (helfrich) study at 4 gamma, so its
measured thresholds are the same numbers at gammas four times smaller: the fitted exponent is
the same and the prefactor is the standard one times 4^b (a power law a (4 gamma)^b).
"""

import math

import pytest

from shellbuckle import convention_study as cs
from shellbuckle.cli import main
from shellbuckle.reproduce import Study, reproduce_paper

SMALL = dict(seeds=1, vertices=(200,), until=0.2, special=False)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    base = tmp_path_factory.mktemp("readings")
    reproduce_paper(base / "paper", Study(gammas=(500.0, 1000.0), energy_convention="paper",
                                          **SMALL), workers=1, progress=False, formats=("png",))
    reproduce_paper(base / "helfrich", Study(gammas=(2000.0, 4000.0), **SMALL), workers=1,
                    progress=False, formats=("png",))
    return cs.measure(base / "paper"), cs.measure(base / "helfrich")


def test_paper_at_gamma_measures_as_helfrich_at_four_gamma(pair):
    paper, helfrich = pair
    assert paper["convention"] == "paper" and helfrich["convention"] == "helfrich"
    a_p, b_p = paper["metrics"]["primary_a"].value, paper["metrics"]["primary_b"].value
    a_h, b_h = helfrich["metrics"]["primary_a"].value, helfrich["metrics"]["primary_b"].value
    assert math.isfinite(a_p) and b_p == pytest.approx(b_h, rel=1e-9)
    assert a_p == pytest.approx(a_h * 4.0 ** b_h, rel=1e-9)


def test_values_the_runs_cannot_reach_are_not_scored(pair):
    paper, _ = pair
    metrics = paper["metrics"]
    assert set(metrics) == set(cs.CRITERIA)
    # no run at gamma = 2916, 15163 or 20995, none to dV/V = 0.854, no special runs
    for key in ("fig9", "hysteresis", "W_bowl", "fig3_ratio", "fig11_ratio", "reinflation",
                "gallery_20995", "self_contact"):
        assert metrics[key].agrees is None, key
    assert paper["scored"] == sum(m.agrees is not None for m in metrics.values())
    assert paper["score"] == sum(bool(m.agrees) for m in metrics.values())


def test_the_verdict_needs_a_lead_of_two_points_and_half_the_values():
    def result(name, score, scored=18):
        return {"convention": name, "score": score, "scored": scored}
    assert cs.verdict({"a": result("a", 12), "b": result("b", 11)}).startswith("undecided")
    assert cs.verdict({"a": result("a", 12), "b": result("b", 10)}).startswith(
        "a reproduces the paper best")
    assert "no reading reproduces" in cs.verdict({"a": result("a", 7), "b": result("b", 2)})


def test_every_criterion_is_stated_in_the_table(pair, tmp_path):
    paper, helfrich = pair
    text = cs.markdown({"helfrich": helfrich, "paper": paper})
    for rule in cs.CRITERIA.values():
        assert rule in text
    rows = [line for line in text.splitlines() if line.startswith("| ")]
    # a Markdown table: every row has the same number of cells
    assert len({line.count(" | ") for line in rows}) == 1


def test_compare_conventions_refuses_a_convention_with_the_flag(tmp_path, capsys):
    code = main(["reproduce-paper", "--compare-conventions", "--energy-convention", "paper",
                 "--out", str(tmp_path / "x")])
    assert code == 2 and "--energy-convention" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_the_report_states_the_reading_of_every_run(pair, tmp_path):
    from pathlib import Path

    from shellbuckle.report import write_report

    paper, helfrich = pair
    out = write_report([Path(paper["folder"]) / "sweep", Path(helfrich["folder"]) / "sweep"],
                       tmp_path / "report.md", figures=False)
    text = out.read_text(encoding="utf-8")
    assert "paper (1/2 kappa (H - H0)^2, the standard shell at 4 gamma): 2 run(s)" in text
    assert "helfrich (1/2 kappa (c1 + c2 - c0)^2): 2 run(s)" in text
    provenance = text[text.index("Provenance"):]
    assert provenance.count("| paper |") == 2 and provenance.count("| helfrich |") == 2


def test_each_sensitivity_variant_changes_one_thing_from_the_base():
    from dataclasses import fields

    base, *variants = cs.sensitivity_specs(("helfrich", "paper"), 2, with_base=True)
    assert base.energy_convention == ("helfrich", "paper") and base.seeds == (0, 1)
    assert len(variants) == len(cs.VARIANTS) - 1
    for spec, (name, change) in zip(variants, list(cs.VARIANTS.items())[1:]):
        differ = {f.name for f in fields(base) if getattr(spec, f.name) != getattr(base, f.name)}
        assert differ == set(change), name
        point = spec.points()[0]
        assert cs._variant_of(point | {"temperature": point["temperature"]}) == name


def test_the_sensitivity_table_counts_finished_runs_only():
    import pandas as pd

    def row(seed, status, primary):
        return {"gamma": 2333.0, "energy_convention": "paper", "n_vertices": 3594,
                "method": "newton", "bending": "juelicher", "temperature": 0.01, "seed": seed,
                "status": status, "primary_dV_over_V": primary,
                "axisymmetry_loss_dV_over_V": 0.3, "wrinkles_dV_over_V": float("nan"),
                "W_mean": 5.0, "stop_dV_over_V": 0.8}

    frame = pd.DataFrame([row(0, "finished", 0.02), row(1, "finished", 0.04),
                          row(2, "running", 0.9)])
    table = cs.sensitivity_table([frame])
    assert len(table) == 1
    r = table.iloc[0]
    assert r["variant"] == "jiggle T 0.01" and r["runs"] == 2
    assert r["primary_dV_over_V_mean"] == pytest.approx(0.03)
    assert r["primary_dV_over_V_std"] == pytest.approx(math.sqrt(2) * 0.01)
    assert r["wrinkles_dV_over_V_n"] == 0
    text = cs.sensitivity_markdown(table)
    assert "primary buckling" in text and "none (0/2)" in text
