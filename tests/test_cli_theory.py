import json
import math
import re
import subprocess
import sys

import pytest

from shellbuckle import theory as T
from shellbuckle.cli import main
from shellbuckle.params import ShellParameters
from shellbuckle.run import MAIN_JOB_GAMMA

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def test_theory_with_no_options_writes_the_default_png(tmp_path):
    # the README's main job: the installed entry point, no options, from any folder
    proc = subprocess.run([sys.executable, "-c", "import sys; from shellbuckle.cli import main; "
                           "sys.exit(main(['theory']))"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    png = tmp_path / "shellbuckle_theory.png"
    assert png.read_bytes()[:8] == PNG_SIGNATURE and png.stat().st_size > 10_000
    # printed d/R at the default gamma (every command's: the main job's), nu = 1/3 is
    # sqrt(8/gamma) (reference conventions)
    d = float(re.search(r"d/R = ([0-9.]+)", proc.stdout).group(1))
    assert math.isclose(d, math.sqrt(8 / MAIN_JOB_GAMMA), rel_tol=1e-3)
    assert "crossing" in proc.stdout and "classical" in proc.stdout
    assert "Traceback" not in proc.stderr


def test_json_numbers_are_the_physics(tmp_path, capsys):
    out = tmp_path / "fig.png"
    assert main(["theory", "--gamma", "743", "--nu", "0.25", "--out", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    p = ShellParameters.from_gamma(743, nu=0.25)
    xc = info["crossing_dV_over_V"]
    assert math.isclose(T.U_sphere(xc, p), T.U_axisym_of_dV(xc, p), rel_tol=1e-9)
    assert math.isclose(info["classical_dV_over_V"], 6 * 0.75 / math.sqrt(743), rel_tol=1e-12)
    assert math.isclose(info["classical_pressure"], 4 * math.sqrt(743), rel_tol=1e-12)
    assert out.read_bytes()[:8] == PNG_SIGNATURE


def test_pdf_output_also_writes_png(tmp_path, capsys):
    out = tmp_path / "fig.pdf"
    assert main(["theory", "--gamma", "20995", "--out", str(out)]) == 0
    assert out.read_bytes()[:5] == b"%PDF-"
    assert out.with_suffix(".png").read_bytes()[:8] == PNG_SIGNATURE


def test_thick_shell_without_crossing_still_plots(tmp_path, capsys):
    out = tmp_path / "thick.png"
    assert main(["theory", "--gamma", "10", "--out", str(out)]) == 0
    assert "none" in capsys.readouterr().out
    assert out.stat().st_size > 10_000


@pytest.mark.parametrize("argv, words", [
    (["--gamma", "-1"], ["--gamma -1", "[1, 1e11]"]),
    (["--gamma", "nan"], ["--gamma nan", "finite"]),
    (["--nu", "1.5"], ["--nu 1.5", "(-1, 0.5)"]),
    (["--nu", "0.6"], ["--nu 0.6", "(-1, 0.5)", "d/R"]),
])
def test_bad_values_exit_2_with_a_message(tmp_path, capsys, argv, words):
    out = tmp_path / "never.png"
    assert main(["theory", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "error" in err and "Traceback" not in err
    for word in words:
        assert word in err
    assert not out.exists()


def test_bad_gamma_through_the_entry_point(tmp_path):
    proc = subprocess.run([sys.executable, "-c", "import sys; from shellbuckle.cli import main; "
                           "sys.exit(main(['theory', '--gamma', '-1']))"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "gamma" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "shellbuckle_theory.png").exists()


def test_missing_output_folder_exits_2(tmp_path, capsys):
    assert main(["theory", "--out", str(tmp_path / "missing" / "f.png")]) == 2
    assert "missing" in capsys.readouterr().err


def test_nu_above_one_third_warns_on_stderr(tmp_path, capsys):
    assert main(["theory", "--nu", "0.4", "--out", str(tmp_path / "f.png")]) == 0
    assert "warning" in capsys.readouterr().err
