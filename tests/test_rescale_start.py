"""The scaled start of a volume step (``Protocol.rescale_start``, ``--rescale-start``).

Oracles: a volume scales as the cube of a uniform scaling (exactly); before buckling the
minimum of a step does not depend on where its minimization starts (the same energies and
shapes as the protocol's own start, to the minimizer's tolerance); the stored protocol of a
run made without the option is what it was before the option existed (its identity).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from shellbuckle.cli import main
from shellbuckle.energies.volume import Volume
from shellbuckle.mesh import random_sphere
from shellbuckle.params import ShellParameters
from shellbuckle.protocol.deflate import scaled_to_volume
from shellbuckle.protocol.spec import Protocol
from shellbuckle.run import deflate


def test_the_scaled_start_has_the_step_volume_and_the_same_shape():
    mesh = random_sphere(400, seed=3)
    rng = np.random.default_rng(0)
    X = mesh.X * (1.0 + 0.05 * rng.standard_normal((mesh.n_vertices, 1))) + [0.3, -0.1, 0.2]
    volume = Volume(mesh.faces, mesh.n_vertices)
    target = 0.93 * volume.value(X)
    Y = scaled_to_volume(volume, X, target)
    assert volume.value(Y) == pytest.approx(target, rel=1e-13)
    c = X.mean(axis=0)
    f = (0.93) ** (1.0 / 3.0)
    np.testing.assert_allclose(Y - c, f * (X - c), rtol=0, atol=1e-14)


def test_before_buckling_the_scaled_start_ends_at_the_same_minima(tmp_path):
    mesh = random_sphere(1000, seed=1)
    params = ShellParameters.from_gamma(271, 1 / 3)
    common = dict(bending="evolver", jiggle=0.0, until=0.076, locate=False)
    plain = deflate(mesh, params, out=tmp_path / "plain", **common).table
    run = deflate(mesh, params, out=tmp_path / "scaled", rescale_start=True, **common)
    assert run.protocol.rescale_start
    scaled = run.table
    assert len(plain) == len(scaled) == 5
    np.testing.assert_allclose(scaled["E_total"], plain["E_total"], rtol=1e-10, atol=0)
    np.testing.assert_allclose(scaled["pressure"], plain["pressure"], rtol=1e-8, atol=0)
    assert (plain["inertia"].iloc[1:] == 0).all() and (scaled["inertia"].iloc[1:] == 0).all()


def test_a_run_without_the_option_stores_the_protocol_it_stored_before():
    # a run folder made before the option existed keeps its identity (it resumes as the
    # same run), and a run made with it says so
    protocol = Protocol(schedule=(0.019, 0.038))
    assert "rescale_start" not in protocol.to_dict()
    assert Protocol.from_dict(protocol.to_dict()) == protocol
    scaled = Protocol(schedule=(0.019, 0.038), rescale_start=True)
    assert scaled.to_dict()["rescale_start"] is True
    assert Protocol.from_dict(scaled.to_dict()) == scaled
    with pytest.raises(TypeError, match="rescale_start"):
        Protocol(schedule=(0.019,), rescale_start="yes")


def test_the_command_line_stores_the_option(tmp_path):
    out = tmp_path / "r"
    assert main(["deflate", "--icosphere", "6", "--gamma", "271", "--until", "0.02",
                 "--rescale-start", "--no-plot", "--no-locate", "--quiet",
                 "--out", str(out)]) == 0
    assert json.loads((out / "run.json").read_text())["protocol"]["rescale_start"] is True


def test_a_sweep_with_the_scaled_start_names_and_stores_it(tmp_path):
    from shellbuckle.sweep import SweepSpec, run_name, run_point

    plain = SweepSpec(gamma=271, icosphere=4, until=0.04)
    scaled = SweepSpec(gamma=271, icosphere=4, until=0.04, rescale_start=True)
    assert "rescale_start" not in plain.to_dict()  # sweeps made before keep their record
    assert SweepSpec.from_dict(scaled.to_dict()) == scaled
    (p0,), (p1,) = plain.points(), scaled.points()
    assert "rescale_start" not in p0 and p1["rescale_start"] is True
    assert run_name(p1) == run_name(p0) + "_rs"
    with pytest.raises(ValueError, match="rescale_start"):
        SweepSpec(gamma=271, rescale_start="yes")
    result = run_point(p1, tmp_path, analyze=False)
    assert result["outcome"] == "finished"
    meta = json.loads((tmp_path / p1["name"] / "run.json").read_text())
    assert meta["protocol"]["rescale_start"] is True


def test_the_sweep_command_passes_the_option(tmp_path):
    out = tmp_path / "s"
    assert main(["sweep", "--gamma", "271", "--icosphere", "4", "--until", "0.04",
                 "--rescale-start", "--workers", "1", "--quiet", "--no-analysis",
                 "--out", str(out)]) == 0
    (folder,) = [p for p in out.iterdir() if p.name.endswith("_rs")]
    assert json.loads((folder / "run.json").read_text())["protocol"]["rescale_start"] is True
