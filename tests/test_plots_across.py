"""Figures across runs (paper Figs. 4, 5, 10): files written and valid, and the data drawn
equal to the collected runs, the fits and the paper's laws computed independently here."""

import json
import logging
import math
import struct

import numpy as np
import pytest

from shellbuckle.analysis.collect import collect_runs, deflation_runs, threshold_fits
from shellbuckle.analysis.fits import fit_power_law
from shellbuckle.plots.across import (DPI, plot_across_runs, plot_thresholds, plot_W_vs_dV,
                                      plot_W_vs_gamma)

from test_analysis_collect import SCRIPT, SCRIPT_W, tiny_runs  # noqa: F401 (fixture)

REFERENCE = {"protocol": {"gamma_range": [271, 29160]},
             "results": {"primary_buckling_fit": {"a": 2.8, "b": -0.55},
                         "secondary_buckling_fit": {"a": 850, "gamma_c": 850},
                         "wrinkle_average_window": [0.53, 0.76],
                         "experiments": {"wrinkles_observed": [4, 8]}}}


def lines(fig):
    return {line.get_gid(): line for ax in fig.axes for line in ax.get_lines() if line.get_gid()}


@pytest.fixture(scope="module")
def collected(tiny_runs):  # noqa: F811
    tables = {}
    df = collect_runs([tiny_runs["sweep"], tiny_runs["b"], tiny_runs["c"],
                       tiny_runs["scripted"]], tables=tables)
    return df, tables


def test_files_written_and_valid(tiny_runs, tmp_path):  # noqa: F811
    paths = plot_across_runs([tiny_runs["sweep"], tiny_runs["b"], tiny_runs["c"],
                              tiny_runs["scripted"]], tmp_path / "figs", reference=REFERENCE)
    assert len(paths) == 6 and all(p.exists() for p in paths)
    for p in paths:
        head = p.read_bytes()[:24]
        if p.suffix == ".png":
            assert head[:8] == b"\x89PNG\r\n\x1a\n"
            width, height = struct.unpack(">II", head[16:24])
            assert width >= 6 * DPI and height >= 4 * DPI   # >= 200 dpi at >= 6 x 4 inches
        else:
            assert p.suffix == ".pdf" and head[:5] == b"%PDF-"


def test_one_run_skips_the_fits_and_says_so(tiny_runs, tmp_path, caplog):  # noqa: F811
    with caplog.at_level(logging.INFO):
        paths = plot_across_runs(tiny_runs["c"], tmp_path, formats=("png",),
                                 reference=REFERENCE)
    assert sorted(p.name for p in paths) == ["fig04_W_vs_dV.png", "fig05_W_vs_gamma.png",
                                             "fig10_thresholds.png"]
    assert "not drawn" in caplog.text


def test_thresholds_figure_draws_the_runs_fits_and_paper(collected):
    df, _ = collected
    fits = threshold_fits(df)
    fig = plot_thresholds(df, fits, reference=REFERENCE)
    drawn = lines(fig)
    runs = deflation_runs(df)
    ok = np.isfinite(runs["primary_dV_over_V"].to_numpy(float))
    np.testing.assert_array_equal(drawn["primary"].get_xdata(), runs["gamma"].to_numpy(float)[ok])
    np.testing.assert_array_equal(drawn["primary"].get_ydata(),
                                  runs["primary_dV_over_V"].to_numpy(float)[ok])
    # the fit line equals an independent fit of the per-gamma means
    means = runs[ok].groupby("gamma")["primary_dV_over_V"].mean()
    independent = fit_power_law(means.index.to_numpy(float), means.to_numpy(float))
    x = np.asarray(drawn["fit_primary"].get_xdata(), float)
    np.testing.assert_allclose(drawn["fit_primary"].get_ydata(),
                               independent.prefactor * x ** independent.exponent, rtol=1e-10)
    x = np.asarray(drawn["paper_primary"].get_xdata(), float)
    np.testing.assert_allclose(drawn["paper_primary"].get_ydata(), 2.8 * x ** -0.55, rtol=1e-12)
    assert x.min() == pytest.approx(271) and x.max() == pytest.approx(29160)
    x = np.asarray(drawn["paper_secondary"].get_xdata(), float)
    np.testing.assert_allclose(drawn["paper_secondary"].get_ydata(), 850 / x, rtol=1e-12)
    assert list(drawn["paper_gamma_c"].get_xdata()) == [850]
    # theory: the classical threshold 6 (1 - nu)/sqrt(gamma) at nu = 1/3
    x = np.asarray(drawn["classical"].get_xdata(), float)
    np.testing.assert_allclose(drawn["classical"].get_ydata(), 4 / np.sqrt(x), rtol=1e-12)


def test_W_figures_draw_the_scripted_wrinkles(collected, tiny_runs):  # noqa: F811
    df, tables = collected
    fig = plot_W_vs_gamma(df, reference=REFERENCE)
    mean = lines(fig)["W_mean"]
    # only the scripted run (gamma = 1000) has wrinkled steps in the window
    assert list(mean.get_xdata()) == [1000.0]
    assert list(mean.get_ydata()) == pytest.approx([SCRIPT_W.mean()])
    bars = fig.axes[0].collections
    segments = [seg for c in bars if hasattr(c, "get_segments") for seg in c.get_segments()]
    assert any(abs(seg[1][1] - seg[0][1]) == pytest.approx(2 * SCRIPT_W.std())
               for seg in segments)
    fig = plot_W_vs_dV(df, tables, reference=REFERENCE)
    curve = lines(fig)["W_run:scripted"]
    wrinkled = [(dv, int(name[8:])) for name, dv, _ in SCRIPT if name.startswith("wrinkled")]
    assert list(curve.get_xdata()) == pytest.approx([dv for dv, _ in wrinkled])
    assert list(curve.get_ydata()) == [W for _, W in wrinkled]
    assert [k for k in lines(fig) if k.startswith("W_run:")] == ["W_run:scripted"]
    # the same curve when the tables are read again from the folders
    again = lines(plot_W_vs_dV(df, None, reference=REFERENCE))["W_run:scripted"]
    assert list(again.get_ydata()) == list(curve.get_ydata())


def test_paper_values_come_from_the_reference_file(collected, tmp_path):
    df, _ = collected
    changed = json.loads(json.dumps(REFERENCE))
    changed["results"]["primary_buckling_fit"].update(a=3.0, b=-0.5)
    path = tmp_path / "ref.json"
    path.write_text(json.dumps(changed))
    line = lines(plot_thresholds(df, {}, reference=path))["paper_primary"]
    x = np.asarray(line.get_xdata(), float)
    np.testing.assert_allclose(line.get_ydata(), 3.0 * x ** -0.5, rtol=1e-12)


def test_bad_formats(tiny_runs, tmp_path):  # noqa: F811
    with pytest.raises(ValueError, match="formats"):
        plot_across_runs(tiny_runs["c"], tmp_path, formats=("gif",), reference=REFERENCE)
    assert math.isfinite(DPI) and DPI >= 200
