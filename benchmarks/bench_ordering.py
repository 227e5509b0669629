"""How the numbering of a randomized sphere's vertices changes the cost of the energy terms.

Run from the repository root (one thread):

    python benchmarks/bench_ordering.py                      # 3594, 10000, 40000 vertices
    python benchmarks/bench_ordering.py --vertices 40000 160000 --repeats 5

``random_sphere(N, seed)`` numbers its vertices in the order its random points were drawn, so
the vertices of one face lie far apart in memory. For each size this times, on the same
surface (2 % shrunk), the energy a deflation minimizes (stretching + Jülicher bending): one
value and gradient and one Hessian assembly, with the mesh's own numbering and with the
vertices renumbered by reverse Cuthill-McKee on the edge graph (scipy.sparse.csgraph), faces
sorted by their smallest vertex as ``random_sphere`` sorts them. It checks that the two give
the same energy to 1e-12 (relative) before timing. Best of ``--repeats`` runs, in ms, and the
ratio of the two numberings. The run store keeps each run's mesh as made, so a renumbering
would be a change of ``random_sphere`` (another mesh for a given seed), not of stored runs.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from scipy.sparse.csgraph import reverse_cuthill_mckee  # noqa: E402

from shellbuckle.energies.base import Sum  # noqa: E402
from shellbuckle.energies.bending import Bending  # noqa: E402
from shellbuckle.energies.stretching import Stretching  # noqa: E402
from shellbuckle.mesh.mesh import Mesh  # noqa: E402
from shellbuckle.mesh.random_sphere import random_sphere  # noqa: E402

from bench_energies import _best_ms  # noqa: E402  (run as benchmarks/bench_ordering.py)


def _renumbered(X: np.ndarray, faces: np.ndarray):
    """``X`` and ``faces`` with the vertices in reverse Cuthill-McKee order of the edge graph,
    the faces rotated to start at their smallest vertex and sorted."""
    n = len(X)
    rows = faces.ravel()
    cols = np.roll(faces, 1, axis=1).ravel()
    graph = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n)).tocsr()
    order = reverse_cuthill_mckee((graph + graph.T).tocsr(), symmetric_mode=True)
    new = np.empty(n, dtype=np.int64)
    new[order] = np.arange(n)
    F = new[faces]
    F = np.array([np.roll(f, -int(np.argmin(f))) for f in F])
    return X[order], F[np.lexsort(F.T[::-1])]


def _energy(X: np.ndarray, faces: np.ndarray):
    mesh = Mesh.from_arrays(X, faces)
    stretching = Stretching.from_reference(X, faces, len(X), A=1000.0, nu=1 / 3)
    return Sum([stretching, Bending.from_mesh(mesh)])


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vertices", type=int, nargs="+", default=[3594, 10000, 40000])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    print(f"{'vertices':>8} {'numbering':>14} {'E+grad ms':>10} {'Hessian ms':>11}")
    for n in args.vertices:
        mesh = random_sphere(n, 0)
        times = {}
        values = {}
        for label, (X, F) in (("as made", (mesh.X, mesh.faces)),
                              ("RCM", _renumbered(mesh.X, mesh.faces))):
            energy = _energy(X, F)
            Y = 0.98 * X
            values[label] = float(energy.value(Y))
            eg = _best_ms(lambda: (energy.value(Y), energy.gradient(Y)), args.repeats)
            hs = _best_ms(lambda: energy.hessian(Y), max(2, args.repeats // 2))
            times[label] = (eg, hs)
            print(f"{n:>8} {label:>14} {eg:>10.2f} {hs:>11.1f}", flush=True)
        same = abs(values["RCM"] - values["as made"]) <= 1e-12 * abs(values["as made"])
        ratio = [a / b for a, b in zip(times["as made"], times["RCM"])]
        print(f"{n:>8} {'ratio':>14} {ratio[0]:>10.2f} {ratio[1]:>11.2f}"
              f"   energies equal: {'yes' if same else 'NO'}")


if __name__ == "__main__":
    main()
