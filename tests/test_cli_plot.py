"""``shellbuckle plot``: the files it writes and prints, and bad input refused with exit code 2."""

import logging
import sys

import numpy as np
import pytest

from shellbuckle.cli import main
from shellbuckle.mesh import icosphere
from shellbuckle.params import ShellParameters
from shellbuckle.plots import paper
from shellbuckle.run import deflate

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two tiny real deflations (162 vertices, 3 steps): with and without the c0 cycle."""
    base = tmp_path_factory.mktemp("cli_plot_runs")
    params = ShellParameters.from_gamma(743.0, nu=1.0 / 3.0)
    cycle = deflate(icosphere(4), params, dv=0.06, until=0.12, out=base / "cycle", seed=0)
    plain = deflate(icosphere(4), params, dv=0.06, until=0.12, out=base / "plain", seed=0,
                    c0_cycle=False)
    return cycle.path, plain.path


def _printed(capsys):
    return [line for line in capsys.readouterr().out.splitlines() if line.strip()]


def _valid(path):
    data = path.read_bytes()
    if path.suffix == ".png":
        return data[:8] == PNG and len(data) > 10_000
    if path.suffix == ".pdf":
        return data[:5] == b"%PDF-" and data.rstrip().endswith(b"%%EOF")
    return False


def test_one_run_gives_its_energy_figure_and_gallery(runs, tmp_path, capsys):
    cycle, _ = runs
    out = tmp_path / "figs"
    assert main(["plot", str(cycle), "--out", str(out), "--dpi", "120"]) == 0
    printed = _printed(capsys)
    expected = {f"cycle_{name}.{fmt}" for name in ("run", "fig09_energy", "gallery", "pv")
                for fmt in ("png", "pdf")}
    assert {p.name for p in out.iterdir()} == expected
    assert sorted(printed) == sorted(str(out / name) for name in expected)
    assert all(_valid(out / name) for name in expected)
    # the PNG's width (header bytes 16-20) is the figure's width at --dpi
    width = int.from_bytes((out / "cycle_fig09_energy.png").read_bytes()[16:20], "big")
    assert width == round(paper.fig9_energy(cycle).get_figwidth() * 120)


def test_several_runs_pairs_and_formats(runs, tmp_path, capsys, monkeypatch):
    cycle, plain = runs
    seen = {}
    original = paper.fig7_gallery

    def fig7(runs_, **kw):
        seen["at"] = kw["at"]
        return original(runs_, **kw)

    monkeypatch.setattr(paper, "fig7_gallery", fig7)
    out = tmp_path / "figs"
    code = main(["plot", str(cycle), str(plain), "--out", str(out), "--format", "png",
                 "--at", "0.1", "--potato", str(plain), "--capsule", str(cycle),
                 "--pair", str(plain), str(cycle)])
    assert code == 0
    printed = _printed(capsys)
    names = {p.name for p in out.iterdir()}
    assert sorted(printed) == sorted(str(out / n) for n in names)  # all written, all printed
    assert all(n.endswith(".png") for n in names)
    assert {"cycle_run.png", "cycle_fig09_energy.png", "cycle_gallery.png", "cycle_pv.png",
            "plain_run.png", "plain_fig09_energy.png", "plain_gallery.png", "plain_pv.png",
            "fig07_gallery.png", "fig09_energy.png",
            "fig03_potato_capsule.png", "fig11_paths.png"} <= names
    assert len(names) > 10  # and the across-run figures (plots.across)
    assert all(_valid(out / n) for n in names)
    assert seen["at"] == 0.1


def test_across_run_figures_are_skipped_when_unavailable(runs, tmp_path, capsys, monkeypatch,
                                                         caplog):
    monkeypatch.setitem(sys.modules, "shellbuckle.plots.across", None)  # import fails
    out = tmp_path / "figs"
    with caplog.at_level(logging.WARNING):
        assert main(["plot", *map(str, runs), "--out", str(out), "--format", "pdf"]) == 0
    assert "across-run figures" in caplog.text
    names = {p.name for p in out.iterdir()}
    assert names == {"cycle_run.pdf", "cycle_fig09_energy.pdf", "cycle_gallery.pdf",
                     "cycle_pv.pdf", "plain_run.pdf", "plain_fig09_energy.pdf",
                     "plain_gallery.pdf", "plain_pv.pdf", "fig07_gallery.pdf",
                     "fig09_energy.pdf"}
    assert len(_printed(capsys)) == 10


def test_a_run_named_twice_gets_distinct_files(runs, tmp_path, capsys):
    cycle, _ = runs
    out = tmp_path / "figs"
    assert main(["plot", str(cycle), str(cycle), "--out", str(out), "--format", "png"]) == 0
    names = {p.name for p in out.iterdir()}
    assert {"cycle_gallery.png", "cycle_2_gallery.png"} <= names


@pytest.mark.parametrize("extra, message", [
    (["--at", "1.5"], "1.5"),
    (["--at", "-0.2"], "-0.2"),
    (["--at", "nan"], "nan"),
    (["--format", "png,gif"], "gif"),
    (["--potato", "X"], "--capsule"),
    (["--dpi", "10"], "10"),
    (["--units", "si"], "no material"),
])
def test_bad_options_exit_2_naming_the_value(runs, tmp_path, capsys, extra, message):
    extra = [str(runs[0]) if e == "X" else e for e in extra]
    assert main(["plot", str(runs[0]), "--out", str(tmp_path / "f"), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "f").exists()  # refused before any work


def test_bad_folders_exit_2(tmp_path, capsys):
    missing = tmp_path / "nope"
    assert main(["plot", str(missing), "--out", str(tmp_path / "f")]) == 2
    assert str(missing) in capsys.readouterr().err
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["plot", str(empty), "--out", str(tmp_path / "f")]) == 2
    assert str(empty) in capsys.readouterr().err
    assert main(["plot", "--out", str(tmp_path / "f")]) == 2
    assert "nothing to plot" in capsys.readouterr().err


def test_units_si_draws_a_material_run_in_joules_pascals_and_metres(tmp_path, capsys,
                                                                    monkeypatch):
    """A shell of radius 0.1 mm (E = 2 MPa, sigma = 0.5, d = 10 um; 92 vertices, 2 steps):
    its per-run figures in SI, their axes in J, Pa and 1/m; the same command on a shell given
    by gamma alone exits 2 with one line saying why, before writing anything."""
    from matplotlib.figure import Figure

    from shellbuckle.mesh.mesh import Mesh
    from shellbuckle.plots import run as run_figure

    E, sigma, d, R = 2e6, 0.5, 1e-5, 1e-4
    params = ShellParameters.from_material(E=E, sigma=sigma, d=d, R=R)
    mesh = icosphere(3)
    run = deflate(Mesh.from_arrays(mesh.X * R, mesh.faces), params, dv=0.04, until=0.08,
                  out=tmp_path / "shell", seed=1, locate=False, threads=1)
    drawn = {}
    original = run_figure.plot_run

    def spy(*args, **kwargs):
        drawn["fig"] = original(*args, **kwargs)
        return drawn["fig"]

    monkeypatch.setattr(run_figure, "plot_run", spy)
    assert main(["plot", str(run.path), "--units", "si", "--format", "png", "--dpi", "50",
                 "--out", str(tmp_path / "figs")]) == 0
    names = {p.name for p in (tmp_path / "figs").iterdir()}
    assert names == {f"shell_{n}.png" for n in ("run", "fig09_energy", "gallery", "pv")}
    fig = drawn["fig"]
    assert isinstance(fig, Figure)
    kappa = E * d ** 3 / (12 * (1 - sigma ** 2))
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert "(J)" in labels[0] and "(Pa)" in labels[1] and any("1/m" in t for t in labels)
    energy = next(ln for ln in fig.axes[0].get_lines() if ln.get_gid() == "simulation")
    np.testing.assert_allclose(energy.get_ydata(), run.table["E_over_kappa"] * kappa,
                               rtol=1e-12)
    capsys.readouterr()
    gamma_run = deflate(icosphere(3), ShellParameters.from_gamma(params.gamma), dv=0.04,
                        until=0.04, out=tmp_path / "reduced", seed=1, locate=False, threads=1)
    assert main(["plot", str(gamma_run.path), "--units", "si",
                 "--out", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no material" in err[0] and str(gamma_run.path) in err[0]
    assert not (tmp_path / "none").exists()
