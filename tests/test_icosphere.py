import numpy as np
import pytest

from shellbuckle.mesh import icosphere


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8, 13, 19])
def test_icosphere_is_a_closed_sphere(n):
    m = icosphere(n, R=2.0)
    t = m.topology
    assert m.n_vertices == 10 * n * n + 2
    assert t.euler_characteristic == 2
    np.testing.assert_allclose(np.linalg.norm(m.X, axis=1), 2.0)
    valence = t.valence()
    assert (valence == 5).sum() == 12 and ((valence == 5) | (valence == 6)).all()
    X, F = m.X, m.faces
    normals = np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]])
    assert ((normals * X[F].mean(axis=1)).sum(axis=1) > 0).all()  # outward


@pytest.mark.parametrize("bad", [0, -1, 2.5])
def test_icosphere_refuses_bad_level(bad):
    with pytest.raises(ValueError, match="integer >= 1"):
        icosphere(bad)
