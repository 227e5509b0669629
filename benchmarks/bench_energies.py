"""Time one energy+gradient evaluation and one Hessian assembly per energy term, single thread.

Run from the repository root:

    python benchmarks/bench_energies.py [--levels 16 32 63 126] [--repeats 7]

For icospheres of about 2.5k, 10k, 40k and 160k vertices it prints a plain table: vertices,
term, E+grad ms, Hessian ms and the ratio of each time to the same term's time at ~10k vertices
(linear cost means the ratio follows the vertex-count ratio 0.25, 1, 4, 16). Times are the best
of several repeats on a slightly perturbed, 2 % shrunk sphere. Targets (issue 2): E+grad at
10k vertices <= 1 ms and Hessian <= 10 ms on one core.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import importlib  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402

from shellbuckle.energies.area import Area  # noqa: E402
from shellbuckle.energies.base import Sum  # noqa: E402
from shellbuckle.energies.stretching import Stretching  # noqa: E402
from shellbuckle.energies.volume import Volume  # noqa: E402
from shellbuckle.mesh import icosphere  # noqa: E402


def _best_ms(fn, repeats: int) -> float:
    fn()  # warm-up
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return 1e3 * best


def _energy_and_gradient(term, X):
    if hasattr(term, "value_and_gradient"):
        return term.value_and_gradient(X)
    return term.value(X), term.gradient(X)


def _optional_term(module: str, name: str, mesh, notes: list[str]):
    """Build a term written elsewhere in the package if it can be imported, else note why not."""
    try:
        cls = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        notes.append(f"{module}.{name} skipped: not importable ({exc})")
        return None
    X, F, V = mesh.X, mesh.faces, mesh.n_vertices
    attempts = []
    if hasattr(cls, "from_mesh"):
        attempts.append(lambda: cls.from_mesh(mesh))
    if hasattr(cls, "from_reference"):
        attempts.append(lambda: cls.from_reference(X, F, V))
    attempts.append(lambda: cls(F, V))
    errors = []
    for build in attempts:
        try:
            return build()
        except Exception as exc:  # the other terms' constructors are not known here
            errors.append(f"{type(exc).__name__}: {exc}")
    notes.append(f"{module}.{name} skipped: could not construct ({'; '.join(errors)})")
    return None


def _terms(mesh, notes):
    X, F, V = mesh.X, mesh.faces, mesh.n_vertices
    terms = {
        "Stretching": Stretching.from_reference(X, F, V, A=1000.0, nu=1 / 3),
        "Volume": Volume(F, V),
        "Area": Area(F, V),
    }
    for module, name in (("shellbuckle.energies.bending", "Bending"),
                         ("shellbuckle.energies.evolver_bending", "StarPerpBending")):
        term = _optional_term(module, name, mesh, notes)
        if term is not None:
            terms[name] = term
    # the energy a deflation minimizes: stretching + one bending term (volume is a constraint)
    for bending, label in (("Bending", "Stretching+Bending"),
                           ("StarPerpBending", "Stretching+StarPerp")):
        if bending in terms:
            terms[label] = Sum([terms["Stretching"], terms[bending]])
    return terms


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", type=int, nargs="+", default=[16, 32, 63, 126],
                        help="icosphere subdivision levels (10 n^2 + 2 vertices)")
    parser.add_argument("--repeats", type=int, default=7, help="timed repeats per figure")
    args = parser.parse_args(argv)

    print(f"numpy {np.__version__}, scipy {scipy.__version__}, Python {platform.python_version()}, "
          f"{platform.processor() or platform.machine()}, 1 thread")
    rows, notes = [], []
    rng = np.random.default_rng(0)
    for n in args.levels:
        mesh = icosphere(n)
        h = 4.0 / np.sqrt(mesh.n_vertices)
        X = 0.98 * mesh.X + 0.01 * h * rng.standard_normal(mesh.X.shape)
        t = time.perf_counter()
        terms = _terms(mesh, notes)
        setup = time.perf_counter() - t
        repeats = max(2, args.repeats if mesh.n_vertices < 50_000 else args.repeats // 2)
        for name, term in terms.items():
            eg = _best_ms(lambda: _energy_and_gradient(term, X), repeats)
            hs = _best_ms(lambda: term.hessian(X), repeats)
            rows.append((mesh.n_vertices, name, eg, hs))
        print(f"  icosphere({n}): {mesh.n_vertices} vertices, {len(mesh.faces)} faces, "
              f"set-up of all terms {setup:.2f} s")
    ref_v = min({r[0] for r in rows}, key=lambda v: abs(v - 10_242))
    ref = {r[1]: r for r in rows if r[0] == ref_v}
    print(f"\nratios are to the same term at {ref_v} vertices")
    print(f"{'vertices':>9}  {'term':<21} {'E+grad ms':>10} {'Hessian ms':>11} "
          f"{'E+grad ratio':>12} {'Hess ratio':>10}")
    for v, name, eg, hs in rows:
        r = ref[name]
        print(f"{v:>9}  {name:<21} {eg:>10.3f} {hs:>11.2f} {eg / r[2]:>12.2f} {hs / r[3]:>10.2f}")
    for note in dict.fromkeys(notes):
        print("note:", note)


if __name__ == "__main__":
    main()
