"""Time the shape analysis of one conformation (what ``analyze``, ``locate`` and every report do
for each stored step), single thread.

Run from the repository root:

    python benchmarks/bench_analysis.py [--levels 19 32 63 126] [--repeats 3]

For icospheres of about 3.6k, 10k, 40k and 160k vertices (``icosphere(n)``, 10 n^2 + 2
vertices) it prints a plain table, one row per mesh and shape:

- ``capsule``: the cap above 60 degrees from the pole mirrored through its plane (an
  axisymmetric dent);
- ``five-fold``: the same dent with a five-fold rim, the cap's edge at
  ``alpha = 60 deg (1 + 0.15 Re(w^5))``, ``w = (x + i y) / (R sin 60 deg)`` (at the rim about
  ``60 deg (1 + 0.15 cos 5 phi)``, fading towards the axis as ``rho^5`` so that the surface is
  smooth there): a wrinkled bowl with W = 5, which the classifier frames and counts.

Columns: the geometry (areas, normals, Jülicher curvature and its smoothing), the whole
``ShapeAnalyzer.describe`` + ``classify_descriptors`` (best of ``--repeats``), the same per
1000 vertices, and both again with the previous method (each smoothing step by a sparse LU
factorization, the rim's envelope by testing every ray against every segment), with the ratio.
The shape found (class and W) is printed to show both methods agree.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import contextlib  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from shellbuckle.analysis import descriptors, wrinkles  # noqa: E402
from shellbuckle.analysis.classify import classify_descriptors  # noqa: E402
from shellbuckle.analysis.descriptors import ShapeAnalyzer  # noqa: E402
from shellbuckle.mesh import icosphere  # noqa: E402

ALPHA = np.radians(60.0)


def dented(X: np.ndarray, m: int = 0, eps: float = 0.0) -> np.ndarray:
    """The cap of half-angle ``ALPHA (1 + eps Re(w^m))``, ``w = (x + i y) / (R sin ALPHA)``,
    around +z, each vertex reflected along z through the height of that cap's edge (``m = 0``:
    a spherical cap inverted). ``Re(w^m)`` is a polynomial in x and y, so the reflected floor
    is smooth at the axis (an azimuthal ``cos(m phi)`` would give it ``m`` ridges there)."""
    R = np.linalg.norm(X, axis=1).max()
    z = X[:, 2] / R
    w = (X[:, 0] + 1j * X[:, 1]) / (R * np.sin(ALPHA))
    c = np.cos(ALPHA * (1.0 + eps * (w ** m).real))
    out = X.copy()
    out[:, 2] -= 2.0 * R * np.clip(z - c, 0.0, None)
    return out


@contextlib.contextmanager
def previous_method():
    """Smoothing by sparse LU (the conjugate gradients allowed no iteration) and the dense
    envelope, as the analysis did before."""
    maxiter, envelope = descriptors.SMOOTHING_MAXITER, wrinkles._envelope
    descriptors.SMOOTHING_MAXITER, wrinkles._envelope = 0, wrinkles._envelope_dense
    try:
        yield
    finally:
        descriptors.SMOOTHING_MAXITER, wrinkles._envelope = maxiter, envelope


def best(fn, repeats: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=int, nargs="+", default=[19, 32, 63, 126])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    print(f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, "
          f"NumPy {np.__version__}; one thread")
    head = (f"{'vertices':>8} {'shape':>9} {'geometry ms':>12} {'analysis ms':>12} "
            f"{'ms/1k vert':>10} {'before: geometry':>16} {'analysis':>9} {'ratio':>6}  result")
    print(head)
    for level in args.levels:
        mesh = icosphere(level)
        analyzer = ShapeAnalyzer(mesh.faces, n_vertices=len(mesh.X))
        for name, X in (("capsule", dented(mesh.X)), ("five-fold", dented(mesh.X, 5, 0.15))):
            def analyse(X=X):
                return classify_descriptors(analyzer.describe(X))

            analyse()  # compile and warm up
            t_geom, _ = best(lambda X=X: analyzer.geometry(X), args.repeats)
            t_all, c = best(analyse, args.repeats)
            with previous_method():
                t_geom0, _ = best(lambda X=X: analyzer.geometry(X), args.repeats)
                t_all0, c0 = best(analyse, args.repeats)
            same = (c.shape, c.W) == (c0.shape, c0.W)
            print(f"{len(mesh.X):>8} {name:>9} {1e3 * t_geom:>12.1f} {1e3 * t_all:>12.1f} "
                  f"{1e6 * t_all / len(mesh.X):>10.2f} {1e3 * t_geom0:>16.1f} "
                  f"{1e3 * t_all0:>9.1f} {t_all0 / t_all:>6.1f}  {c.shape}, W = {c.W}"
                  + ("" if same else f" (before: {c0.shape}, W = {c0.W})"))


if __name__ == "__main__":
    main()
