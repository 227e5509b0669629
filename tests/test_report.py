"""The reproduction report: every reference key listed, our numbers equal to fits computed
independently here from each run's own thresholds, the paper's inconsistent captions found
from gamma = 8 (R/d)^2, one-file HTML, and bad input through the CLI (exit 2)."""

import json
import math

import numpy as np
import pytest

from shellbuckle.analysis import thresholds
from shellbuckle.analysis.collect import load_reference
from shellbuckle.analysis.fits import fit_power_law
from shellbuckle.cli import main
from shellbuckle.report import fmt_number, write_report
from shellbuckle.run import Run

from test_analysis_collect import tiny_runs  # noqa: F401 (fixture)


@pytest.fixture(scope="module")
def reference():
    try:
        return load_reference()
    except ValueError:
        pytest.skip("reference/quilliet2008.json not found next to the repository")


def keys(value, prefix=""):
    """Every leaf key of a JSON value, written as in the report (a.b[0].c)."""
    if isinstance(value, dict):
        return [k for name, v in value.items()
                for k in keys(v, f"{prefix}.{name}" if prefix else name)]
    if isinstance(value, list) and any(isinstance(v, (dict, list)) for v in value):
        return [k for i, v in enumerate(value) for k in keys(v, f"{prefix}[{i}]")]
    return [prefix]


def runs_of(tiny):
    return [tiny["sweep"], tiny["b"], tiny["c"], tiny["scripted"]]


@pytest.fixture(scope="module")
def markdown(tiny_runs, reference, tmp_path_factory):  # noqa: F811
    out = tmp_path_factory.mktemp("report") / "report.md"
    assert write_report(runs_of(tiny_runs), out, "md", reference=reference,
                        figures=False) == out
    return out.read_text()


def row_of(text, key):
    line = next(ln for ln in text.splitlines() if ln.startswith(f"| {key} |"))
    return [c.strip() for c in line.strip("|").split(" | ")]


def test_every_reference_key_is_listed(markdown, reference):
    listed = {ln.split(" | ")[0][2:] for ln in markdown.splitlines() if ln.startswith("| ")}
    missing = [k for k in keys(reference) if k not in listed]
    assert not missing
    # what the runs cannot reach is said so
    assert "not reachable" in row_of(markdown, "results.potato_vs_capsule.potato_dimples")[5]
    assert "not reachable" in row_of(markdown, "results.soleil.statement")[5]


def test_fit_numbers_equal_independent_fits(markdown, tiny_runs):  # noqa: F811
    by_gamma = {}
    for path in runs_of(tiny_runs)[1:] + [tiny_runs["a"]]:
        run = Run.open(path)
        gamma = run.store.params["gamma"]
        by_gamma.setdefault(gamma, []).append(thresholds(run))
    gammas = sorted(by_gamma)
    primary = [(g, np.mean([t["primary_buckling"] for t in by_gamma[g]])) for g in gammas]
    primary = [(g, v) for g, v in primary if math.isfinite(v)]
    fit = fit_power_law(*zip(*primary))
    a = row_of(markdown, "results.primary_buckling_fit.a")
    b = row_of(markdown, "results.primary_buckling_fit.b")
    assert a[2].split(" ± ")[0] == f"{fit.prefactor:.4g}"
    assert a[2].split(" ± ")[1] == f"{fit.prefactor_err:.4g}"
    assert b[2].split(" ± ")[0] == f"{fit.exponent:.4g}"
    assert a[3] == f"{fit.prefactor - 2.8:.4g}"
    assert a[4] == f"{100 * (fit.prefactor - 2.8) / 2.8:+.1f} %"
    # secondary: both secondary thresholds, exponent -1 -> a = geometric mean of dV/V * gamma
    points = [(g, np.mean(v)) for g in gammas for name in ("axisymmetry_loss", "wrinkles")
              for v in [[t[name] for t in by_gamma[g]]] if all(map(math.isfinite, v))]
    a_sec = math.exp(np.mean([math.log(v * g) for g, v in points]))
    assert row_of(markdown, "results.secondary_buckling_fit.a")[2].split(" ± ")[0] == \
        f"{a_sec:.4g}"
    assert row_of(markdown, "results.secondary_buckling_fit.gamma_c")[2].split(" ± ")[0] == \
        f"{a_sec:.4g}"                                           # a/gamma = 1 at gamma = a


def test_inconsistent_captions_are_stated(markdown, reference):
    for entry in reference["gamma_to_d_over_R_in_captions"]:
        formula = math.sqrt(8.0 / entry["gamma"])                # gamma = 8 (R/d)^2, nu = 1/3
        printed_ok = abs(formula - entry["d_over_R"]) <= 0.5 * 10 ** -(
            len(repr(entry["d_over_R"]).split(".")[1])) + 1e-12
        line = f"gamma = {entry['gamma']} is printed with d/R = {entry['d_over_R']}"
        assert (line in markdown) == (not printed_ok)
        if not printed_ok:
            assert f"{formula:.4f}" in markdown
    assert sum(f"gamma = {g} is printed" in markdown for g in (743, 2916)) == 2


def test_provenance_lists_every_run(markdown, tiny_runs):  # noqa: F811
    for path in runs_of(tiny_runs)[1:] + [tiny_runs["a"]]:
        meta = Run.open(path).store.meta
        assert f"| {path.name} |" in markdown
        assert meta["mesh"]["sha256"][:12] in markdown
        assert f"shellbuckle {meta['versions']['shellbuckle']}" in markdown


def test_html_is_one_file_with_the_figures(tiny_runs, reference, tmp_path):  # noqa: F811
    out = write_report([tiny_runs["c"], tiny_runs["b"]], tmp_path / "r.html", "html",
                       reference=reference)
    text = out.read_text()
    assert text.startswith("<!DOCTYPE html>") and text.count("data:image/png;base64,") == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.html"]


def test_cli_writes_and_refuses_bad_input(tiny_runs, reference, tmp_path, capsys):  # noqa: F811
    ref = tmp_path / "ref.json"
    ref.write_text(json.dumps(reference))
    out = tmp_path / "rep.md"
    assert main(["report", str(tiny_runs["c"]), "--out", str(out), "--reference", str(ref),
                 "--no-figures"]) == 0
    assert out.exists() and fmt_number(3000.0) in out.read_text()
    assert main(["report", str(tmp_path / "missing"), "--reference", str(ref)]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["report", str(tiny_runs["c"]), "--reference", str(tmp_path / "no.json")]) == 2
    assert "--reference" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["report", str(tiny_runs["c"]), "--format", "pdf"])
    assert exc.value.code == 2
    with pytest.raises(ValueError, match="format"):
        write_report(tiny_runs["c"], tmp_path / "x.txt", "txt", reference=reference)
