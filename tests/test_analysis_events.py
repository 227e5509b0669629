"""Buckling events along runs: a run store of synthetic conformations with known events, and a
real gamma = 271 deflation."""

import json

import numpy as np
import pytest

from shellbuckle import theory
from shellbuckle.analysis import analyze_run, events, thresholds
from shellbuckle.analysis.events import PERSISTENCE, PRESSURE_DROP
from shellbuckle.params import ShellParameters
from shellbuckle.store import RunStore

from test_analysis_classify import deflated_271, polygonal_profile, wrinkle_profile
from test_analysis_shapes import inverted_cap, mesh, modulated_cap

ALPHA = np.radians(45)

# (conformation, pressure, inertia) per step; the expected events are written beside
SCRIPT = [
    ("sphere", 0.0, 0),
    ("sphere", 10.0, 0),
    ("sphere", 20.0, 0),
    ("cap40", 8.0, 1),     # primary buckling: pressure drops by 60 %; inertia 0 -> 1
    ("cap50", 7.5, 0),     # inertia 1 -> 0
    ("poly4", 7.4, 0),     # a single polygonal step: not persistent, no event
    ("cap55", 7.3, 0),
    ("poly4", 7.2, 0),     # loss of axisymmetry (holds for steps 7 and 8)
    ("poly4", 7.1, 0),
    ("wrinkled5", 7.0, 0),  # wrinkled once only: no wrinkle event yet
    ("poly4", 6.9, 0),
    ("wrinkled6", 6.8, 0),  # appearance of wrinkles (holds until the end)
    ("wrinkled6", 6.7, 0),
]
EXPECTED_SHAPES = ["sphere"] * 3 + ["capsule", "capsule", "polygonal", "capsule", "polygonal",
                                    "polygonal", "wrinkled", "polygonal", "wrinkled", "wrinkled"]


def _conformation(name, X0, k):
    if name == "sphere":
        return X0 * (1 - 0.005 * k)
    if name.startswith("cap"):
        return inverted_cap(X0, np.radians(float(name[3:])), (0.2, 0.1, 1.0))
    if name.startswith("poly"):
        return modulated_cap(X0, ALPHA, polygonal_profile(int(name[4:])), (0.2, 0.1, 1.0), 0.3)
    return modulated_cap(X0, ALPHA, wrinkle_profile(int(name[8:])), (0.2, 0.1, 1.0), 0.3)


@pytest.fixture(scope="module")
def scripted(tmp_path_factory):
    m = mesh("random")
    path = tmp_path_factory.mktemp("events") / "scripted"
    with RunStore.create(path, params={"gamma": 1000.0}, protocol={"dv": 0.02}, X0=m.X,
                         faces=m.faces) as store:
        for k, (name, p, inertia) in enumerate(SCRIPT):
            store.append_step(k, _conformation(name, m.X, k),
                              {"dV_over_V": 0.02 * k, "pressure": p, "inertia": inertia,
                               "E_stretch": 1.0, "E_bend": 1.0})
    return path


def test_analyze_run_stores_the_classes(scripted):
    table = analyze_run(scripted)
    assert table["shape"].tolist() == EXPECTED_SHAPES
    assert table["W"].tolist() == [5 if s == "wrinkled" else 0 for s in EXPECTED_SHAPES[:11]] + [6, 6]
    stored = json.loads((scripted / "analysis.json").read_text())
    assert [stored[str(k)]["shape"] for k in range(len(SCRIPT))] == EXPECTED_SHAPES
    # the table on disk has the columns too, readable without shellbuckle
    import pandas as pd

    assert pd.read_csv(scripted / "table.csv")["shape"].tolist() == EXPECTED_SHAPES


def test_events_of_the_scripted_run(scripted):
    assert PERSISTENCE == 2 and PRESSURE_DROP <= 0.6  # the script is written for these
    found = [(e.name, e.step) for e in events(scripted)]
    assert found == [("primary_buckling", 3), ("inertia_change", 3), ("inertia_change", 4),
                     ("axisymmetry_loss", 7), ("wrinkles", 11)]
    primary = events(scripted)[0]
    assert primary.confirmed is True and primary.dV_over_V == pytest.approx(0.06)
    assert thresholds(scripted) == pytest.approx(
        {"primary_buckling": 0.06, "axisymmetry_loss": 0.14, "wrinkles": 0.22})


def test_events_classify_unanalysed_runs_without_writing(tmp_path):
    m = mesh("icosphere")
    with RunStore.create(tmp_path / "r", params={"gamma": 1.0}, protocol={}, X0=m.X,
                         faces=m.faces) as store:
        store.append_step(0, m.X, {"dV_over_V": 0.0, "pressure": 5.0})
        store.append_step(1, inverted_cap(m.X, np.radians(50)), {"dV_over_V": 0.1,
                                                                   "pressure": 4.5})
    found = events(tmp_path / "r")
    # the pressure fell by 10 % only: the shape changed, but the snap-through is not confirmed
    assert [(e.name, e.step, e.confirmed) for e in found] == [("primary_buckling", 1, False)]
    assert not (tmp_path / "r" / "analysis.json").exists()


def test_gamma_271_primary_buckling_between_crossing_and_classical(tmp_path_factory):
    run = deflated_271(tmp_path_factory)
    found = events(run)
    names = [e.name for e in found]
    assert "axisymmetry_loss" not in names and "wrinkles" not in names  # a capsule (paper §4.3)
    primary = found[names.index("primary_buckling")]
    assert primary.confirmed
    params = ShellParameters.from_gamma(271.0, nu=1 / 3)
    dv = run.protocol.schedule[1] - run.protocol.schedule[0]
    assert theory.crossing(params) < primary.dV_over_V
    assert primary.dV_over_V <= theory.classical_threshold(params).dV_over_V_exact + dv
    p = run.table["pressure"].to_numpy()
    assert p[primary.step] < (1 - PRESSURE_DROP) * p[primary.step - 1]
