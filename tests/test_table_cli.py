"""``shellbuckle table``: the columns shown, missing values, units and the refusals.

Oracles: the records written into hand-made run folders (their values and column names), the
compact default as documented (docs/guide.md: step, dV_over_V, E_over_kappa, E_bend,
E_stretch, pressure, iterations, converged, inertia, then shape and W once analysed; at most 120
characters), the paper's conversions for SI (kappa = E d^3/(12 (1 - sigma^2)), pressures in
kappa/R^3), and docs/errors.md for bad input (exit code 2, one line naming the option, the
value as typed and what is allowed, nothing written).
"""

from __future__ import annotations

import io
import math
from contextlib import redirect_stderr, redirect_stdout

import numpy as np
import pandas as pd
import pytest

from shellbuckle import cli
from shellbuckle.analysis import events
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.protocol import deflate as protocol_mod
from shellbuckle.store import RunStore

DOCUMENTED_DEFAULT = ["step", "dV_over_V", "E_over_kappa", "E_bend", "E_stretch", "pressure",
                      "iterations", "converged", "inertia"]
MATERIAL = dict(E=2e6, sigma=0.5, d=1e-5, R=1e-4)
PROTOCOL = {"dv": 0.019, "until": 0.3, "seed": 7}


def _record(k, scale_E=1.0, scale_p=1.0, scale_x=1.0, inertia=0):
    return {"target_dV_over_V": 0.019 * k, "dV_over_V": 0.019 * k + 1e-13,
            "E_total": (1.0 / 3.0 + k) * scale_E, "E_bend": math.pi * scale_E,
            "E_stretch": (1.0 / 3.0 + k - math.pi) * scale_E,
            "E_over_kappa": 1.0 / 3.0 + k, "E_before_c0_cycle": (0.5 + k) * scale_E,
            "pressure": (40.0 - k) * scale_p, "grad_norm": 3e-11, "iterations": 12 + k,
            "inertia": inertia, "min_distance": 0.123456789012345678 * scale_x,
            "wall_s": 0.5, "self_intersecting": False, "converged": True,
            "c0": 2.0 / scale_x, "jiggle_sigma": 0.01 * scale_x}


def _folder(path, params, scales=(1.0, 1.0, 1.0), analysed=True, n=4):
    """A run folder of ``n`` steps written by hand; step 0 stores inertia -1, the placeholder
    of runs made before missing values were stored as missing."""
    rng = np.random.default_rng(0)
    X0 = rng.normal(size=(12, 3))
    faces = rng.integers(0, 12, size=(20, 3))
    with RunStore.create(path, params=params.to_dict(), protocol=PROTOCOL, X0=X0,
                         faces=faces) as store:
        for k in range(n):
            store.append_step(k, X0, _record(k, *scales, inertia=-1 if k == 0 else k % 2))
        if analysed:
            store.update_analysis({k: {"shape": ["sphere", "capsule", "polygonal",
                                                 "wrinkled"][k % 4], "W": 5 if k == 3 else 0,
                                       "n_dimples": 1, "corners": 0} for k in range(n)})
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("tables")
    material = ShellParameters.from_material(**MATERIAL)
    kappa, R = material.kappa, material.R
    return {"gamma": _folder(root / "g", ShellParameters.from_gamma(271.0)),
            "plain": _folder(root / "p", ShellParameters.from_gamma(271.0), analysed=False),
            "material": _folder(root / "m", material, scales=(kappa, kappa / R ** 3, R)),
            "root": root}


def _cli(argv):
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        try:
            code = cli.main(argv)
        except SystemExit as exc:  # argparse's own errors
            code = exc.code
    return code, out.getvalue(), err.getvalue()


def _text_columns(out):
    body = [line for line in out.splitlines() if not line.startswith("#")]
    return body[0].split(), body[1:]


# --------------------------------------------------------------------------- columns

def test_the_default_is_compact_and_fits_in_120_characters(runs):
    code, out, err = _cli(["table", str(runs["gamma"])])
    assert code == 0 and err == ""
    header, rows = _text_columns(out)
    assert header == DOCUMENTED_DEFAULT + ["shape", "W"]
    assert len(rows) == 4 and rows[3].split()[-2:] == ["wrinkled", "5"]
    assert max(len(line) for line in out.splitlines()) <= 120
    code, out, _ = _cli(["table", str(runs["plain"])])  # not analysed: no shape, no W
    assert code == 0 and _text_columns(out)[0] == DOCUMENTED_DEFAULT


def test_columns_in_the_order_given_and_all(runs):
    code, out, _ = _cli(["table", str(runs["gamma"]), "--columns", "W,dV_over_V, step,c0"])
    assert code == 0
    header, rows = _text_columns(out)
    assert header == ["W", "dV_over_V", "step", "c0"]
    assert rows[2].split() == ["0", "0.038", "2", "2"]
    stored = list(RunStore.open(runs["gamma"]).table().columns)
    code, out, _ = _cli(["table", str(runs["gamma"]), "--all"])
    assert code == 0 and _text_columns(out)[0] == stored
    assert {"target_dV_over_V", "grad_norm", "wall_s", "jiggle_sigma"} <= set(stored)


def test_csv_prints_every_column_at_full_precision_and_honours_columns(runs):
    code, out, _ = _cli(["table", str(runs["gamma"]), "--csv"])
    assert code == 0 and not out.startswith("#")
    parsed = pd.read_csv(io.StringIO(out))
    assert list(parsed.columns) == list(RunStore.open(runs["gamma"]).table().columns)
    assert parsed["min_distance"].tolist() == [0.123456789012345678] * 4
    assert parsed["E_total"].tolist() == [1.0 / 3.0 + k for k in range(4)]
    code, out, _ = _cli(["table", str(runs["gamma"]), "--csv", "--columns", "E_bend,step"])
    assert out.splitlines()[0] == "E_bend,step"
    assert pd.read_csv(io.StringIO(out))["E_bend"].tolist() == [math.pi] * 4


# --------------------------------------------------------------------------- missing values

def test_a_stored_inertia_of_minus_one_reads_as_missing(runs):
    store = RunStore.open(runs["gamma"])
    assert store.record(0)["inertia"] == -1  # the step file keeps what was written
    table = store.table()
    assert table["inertia"].dtype == "Int64"
    assert table["inertia"].isna().tolist() == [True, False, False, False]
    assert table["inertia"].iloc[1:].tolist() == [1, 0, 1]
    code, out, _ = _cli(["table", str(runs["gamma"]), "--csv", "--columns", "step,inertia"])
    assert out.splitlines()[1:] == ["0,", "1,1", "2,0", "3,1"]
    csv = pd.read_csv(runs["gamma"] / "table.csv")  # the convenience copy, too
    assert csv["inertia"].isna().tolist() == [True, False, False, False]
    code, out, _ = _cli(["table", str(runs["gamma"]), "--columns", "step,inertia"])
    assert [line.split() for line in _text_columns(out)[1]][0] == ["0", "-"]


def test_a_new_step_0_stores_no_inertia():
    """measure() of a state no minimizer produced: the inertia was not computed."""
    params = ShellParameters.from_gamma(271.0)
    mesh = icosphere(2)
    ctx, state = protocol_mod.init(mesh, params, protocol_mod.Protocol(schedule=[0.05]),
                                   threads=1)
    record = protocol_mod.measure(ctx, state.X, 0.0)
    assert record["inertia"] is None


def test_inertia_changes_skip_the_steps_where_it_was_not_computed(runs):
    """inertia: -1 (not computed), 1, 0, 1: the changes are at steps 2 and 3, none at 1."""
    found = [(e.name, e.step) for e in events(runs["gamma"], located=False)
             if e.name == "inertia_change"]
    assert found == [("inertia_change", 2), ("inertia_change", 3)]


# --------------------------------------------------------------------------- units

def test_si_units_of_a_material_run(runs):
    E, sigma, d, R = MATERIAL.values()
    kappa = E * d ** 3 / (12.0 * (1.0 - sigma ** 2))  # the paper's conversion
    code, out, _ = _cli(["table", str(runs["material"]), "--csv", "--units", "si",
                         "--columns", "E_total,pressure,min_distance,E_over_kappa,step"])
    assert code == 0
    si = pd.read_csv(io.StringIO(out))
    assert list(si.columns) == ["E_total [J]", "pressure [Pa]", "min_distance [m]",
                                "E_over_kappa", "step"]
    k = si["step"].to_numpy()
    np.testing.assert_allclose(si["E_total [J]"], (1 / 3 + k) * kappa, rtol=1e-14)
    np.testing.assert_allclose(si["pressure [Pa]"], (40.0 - k) * kappa / R ** 3, rtol=1e-14)
    np.testing.assert_allclose(si["min_distance [m]"], 0.123456789012345678 * R, rtol=1e-14)
    np.testing.assert_allclose(si["E_over_kappa"], 1 / 3 + k, rtol=1e-15)
    code, out, _ = _cli(["table", str(runs["material"]), "--csv",
                         "--columns", "E_total,pressure,min_distance,c0"])
    reduced = pd.read_csv(io.StringIO(out))  # the default: reduced units
    np.testing.assert_allclose(reduced["E_total"], 1 / 3 + k, rtol=1e-14)
    np.testing.assert_allclose(reduced["pressure"], 40.0 - k, rtol=1e-14)
    np.testing.assert_allclose(reduced["min_distance"], 0.123456789012345678, rtol=1e-14)
    np.testing.assert_allclose(reduced["c0"], 2.0, rtol=1e-14)  # 2/R on the sphere
    code, out, _ = _cli(["table", str(runs["material"]), "--units", "si"])
    comments = [line for line in out.splitlines() if line.startswith("#")]
    assert "energies in J, pressures in Pa, lengths in m" in comments[-1]
    assert "E_bend [J]" in out and "pressure [Pa]" in out


# --------------------------------------------------------------------------- refusals

BAD = [
    (["--columns", "bogus"], "--columns", "bogus"),
    (["--columns", "step,bogus"], "--columns", "step,bogus"),
    (["--columns", "step,,W"], "--columns", "step,,W"),
    (["--columns", "step,step"], "--columns", "step,step"),
    (["--columns", ""], "--columns", "allowed"),
    (["--columns", "E_total", "--all"], "--all", "--columns"),
    (["--units", "SI"], "--units", "SI"),
    (["--units", "si"], "--units si", "--E --sigma --d --R"),
]


@pytest.mark.parametrize("extra, option, value", BAD)
def test_bad_input_is_refused_in_one_line_before_any_work(runs, extra, option, value):
    before = sorted(p.relative_to(runs["root"]) for p in runs["root"].rglob("*"))
    code, out, err = _cli(["table", str(runs["gamma"]), *extra])
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("shellbuckle table: error: ")
    assert option in lines[0] and value in lines[0], lines[0]
    if extra[0] == "--columns" and len(extra) == 2:
        assert "allowed" in lines[0] and "dV_over_V" in lines[0] and "E_over_kappa" in lines[0]
    assert sorted(p.relative_to(runs["root"]) for p in runs["root"].rglob("*")) == before


def test_an_analysis_column_of_a_run_not_analysed_says_how_to_get_it(runs):
    code, _, err = _cli(["table", str(runs["plain"]), "--columns", "step,shape"])
    assert code == 2 and "shellbuckle analyze" in err and "'shape'" in err
