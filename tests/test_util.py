"""The small helpers written once: timestamps, plain JSON values, the mean edge length."""

import datetime as dt
import json
import math

import numpy as np
import pytest

from shellbuckle.mesh import icosphere, random_sphere
from shellbuckle.util import json_safe, now, plain


def test_now_is_utc_iso_to_the_second():
    stamp = dt.datetime.fromisoformat(now())
    assert stamp.utcoffset() == dt.timedelta(0) and stamp.microsecond == 0
    assert abs((dt.datetime.now(dt.timezone.utc) - stamp).total_seconds()) < 5


def test_plain_and_json_safe_give_json_values():
    value = {1: (np.float64(0.5), np.int64(3), np.bool_(True)), "x": [math.nan, -math.inf],
             "a": np.array(2.0)}
    kept = plain(value)
    assert kept["1"] == [0.5, 3, True] and type(kept["1"][1]) is int
    assert type(kept["1"][2]) is bool and kept["a"] == 2.0
    assert math.isnan(kept["x"][0]) and kept["x"][1] == -math.inf
    strict = json_safe(value)
    assert strict["x"] == [None, None]
    assert json.loads(json.dumps(strict, allow_nan=False)) == strict


@pytest.mark.parametrize("mesh", [icosphere(3), random_sphere(300, seed=2)],
                         ids=["icosphere", "random"])
def test_mean_edge_length_is_the_edges_mean_and_the_face_sides_mean(mesh):
    """Each edge once; on a closed surface every edge is the side of two faces, so the mean
    over face sides (the solver's measure) is the same number up to rounding."""
    from shellbuckle.protocol.jiggle import mean_edge_length
    from shellbuckle.solve.linesearch import mean_edge_length as face_sides_mean

    X = mesh.X + np.random.default_rng(0).normal(scale=0.01, size=mesh.X.shape)
    edges = mesh.topology.edges
    value = mesh.topology.mean_edge_length(X)
    direct = np.mean([np.linalg.norm(X[i] - X[j]) for i, j in edges])
    assert value == pytest.approx(direct, rel=1e-14)
    assert value == mean_edge_length(X, edges)          # the jiggle's, bit for bit
    assert value == pytest.approx(face_sides_mean(mesh.faces, X), rel=1e-12)
    assert mesh.topology.mean_edge_length(2.0 * X) == pytest.approx(2.0 * value, rel=1e-14)
