"""Time the self-contact check done at every volume step of a deflation, single thread.

Run from the repository root:

    python benchmarks/bench_contact.py [--levels 19 32 63 126] [--repeats 7]

For icospheres of about 3.6k, 10k, 40k and 160k vertices (``icosphere(n)``, 10 n^2 + 2
vertices) and the randomized 3594-vertex sphere it prints a plain table, one row per shape:

- ``sphere``: the undeformed mesh (the state of most steps: no contact anywhere);
- ``capsule``: the cap above z = 0.3 mirrored through that plane, the paper's axisymmetric
  dent (U_axisym shape, no contact);
- ``through``: the capsule with its inverted cap pushed further down by a smooth Gaussian
  bump, 0.7 exp(-(x^2 + y^2) / 0.25), so that its pole crosses the opposite side (the state
  at which a deflation stops; edges stay within about 1.5 times their length).

Columns: checker construction (once per topology: k-ring and face-star key sets), the whole
``ContactChecker.check(X)`` (best of ``--repeats``), its intersection and distance parts, the
check time per 1000 vertices (constant for linear cost), the number of intersecting face pairs
and the minimum non-adjacent distance in mean edge lengths. Target (issue 3): well under one
Newton iteration, a few ms at 3.6k vertices, linear growth.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

from shellbuckle.mesh import icosphere, random_sphere  # noqa: E402
from shellbuckle.mesh.contact import ContactChecker  # noqa: E402


def _best_ms(fn, repeats: int, clock=time.perf_counter) -> float:
    fn()  # warm-up
    best = np.inf
    for _ in range(repeats):
        t = clock()
        fn()
        best = min(best, clock() - t)
    return 1e3 * best


def mirrored_cap(X: np.ndarray, c: float) -> np.ndarray:
    """Mirror the vertices above the plane z = c through it (an inverted spherical cap)."""
    X = X.copy()
    cap = X[:, 2] > c
    X[cap, 2] = 2 * c - X[cap, 2]
    return X


def pushed_through(X: np.ndarray, c: float = 0.3, depth: float = 0.7) -> np.ndarray:
    """The capsule ``mirrored_cap(X, c)`` with its inverted cap pushed down by a Gaussian bump
    of height ``depth``: the pole goes from 2c - 1 to 2c - 1 - depth < -1, through the south cap."""
    cap = X[:, 2] > c
    X = mirrored_cap(X, c)
    X[cap, 2] -= depth * np.exp(-(X[cap, 0] ** 2 + X[cap, 1] ** 2) / 0.25)
    return X


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--levels", type=int, nargs="+", default=[19, 32, 63, 126],
                    help="icosphere levels n (10 n^2 + 2 vertices)")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--no-random", action="store_true", help="skip the randomized 3594 mesh")
    args = ap.parse_args(argv)
    print(f"python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
          f"{platform.machine()}, load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cpus (times are best of {args.repeats})")
    meshes = [(f"icosphere({n})", icosphere(n)) for n in args.levels]
    if not args.no_random:
        meshes.insert(1, ("random_sphere(3594)", random_sphere(3594, seed=1)))
    header = (f"{'mesh':>20} {'shape':>8} {'V':>7} {'build ms':>9} {'check ms':>9} "
              f"{'inter ms':>9} {'dist ms':>8} {'ms/1kV':>7} {'cpu ms':>7} {'pairs':>6} {'d_min/h':>8}")
    print(header)
    print("-" * len(header))
    for name, mesh in meshes:
        t = time.perf_counter()
        checker = ContactChecker(mesh.topology)
        build = 1e3 * (time.perf_counter() - t)
        edges = mesh.topology.edges
        for shape, X in [("sphere", mesh.X), ("capsule", mirrored_cap(mesh.X, 0.3)),
                         ("through", pushed_through(mesh.X))]:
            h = float(np.linalg.norm(X[edges[:, 0]] - X[edges[:, 1]], axis=1).mean())
            full = _best_ms(lambda: checker.check(X), args.repeats)
            inter = _best_ms(lambda: checker.intersecting_pairs(X), args.repeats)
            dist = _best_ms(lambda: checker._distances(
                X, cKDTree(X, balanced_tree=False, compact_nodes=False), h), args.repeats)
            cpu = _best_ms(lambda: checker.check(X), args.repeats, time.process_time)
            result = checker.check(X)
            V = mesh.n_vertices
            print(f"{name:>20} {shape:>8} {V:>7} {build:>9.1f} {full:>9.2f} {inter:>9.2f} "
                  f"{dist:>8.2f} {full / (V / 1000):>7.2f} {cpu:>7.1f} {result.n_pairs:>6} "
                  f"{result.min_distance / h:>8.3f}")
            build = float("nan")


if __name__ == "__main__":
    main()
