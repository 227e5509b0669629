"""The round-off floor of the projected gradient on stored steps, beside the gradient test.

Run from the repository root, on run folders (a run of each mesh size to compare):

    python benchmarks/bench_floor.py RUN [RUN ...] [--steps 1,2,5,10,20,30,40]

For each step of each run, at its stored positions and with its run's energy (convention,
spontaneous curvature, parameters): the projected gradient ``|r|`` (``r = grad E - lam grad V``,
``lam`` the least-squares multiplier), the protocol's gradient test ``tol |grad E| +
atol_grad`` (``tol`` from the run's protocol, Newton's ``atol_grad``), the round-off floor
``rho`` of :func:`shellbuckle.solve.system.gradient_floor` (the change of ``r`` when every
coordinate changes by one unit in the last place, the smaller over two seeded sign patterns)
and ``|r| / rho``. Rounding an exact minimum to the nearest representable point leaves ``|r|``
about ``0.29 rho``; a minimization that reaches the floor stops there by the floor test
(``shellbuckle.solve.newton``, "Convergence"). Then the floor over the runs, with its growth
exponent in the number of vertices. No timing is printed.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402

import numpy as np  # noqa: E402


def measure(path: str, steps: list[int] | None) -> list[dict]:
    """One row per step of the run in ``path`` (every stored step after step 0 by default)."""
    from shellbuckle.protocol.stored import stored_context
    from shellbuckle.solve.options import NewtonOptions
    from shellbuckle.solve.linesearch import projected_gradient
    from shellbuckle.solve.system import gradient_floor
    from shellbuckle.store.view import Run

    run = Run.open(path)
    ctx = stored_context(run, threads=1)
    store = run.store
    chosen = [k for k in store.steps if k > 0] if steps is None else \
        [k for k in steps if k in store.steps]
    rows = []
    for k in chosen:
        record = store.record(k)
        X = store.positions(k)
        c0 = record.get("c0", ctx.c0)
        energy = ctx.energy if c0 == ctx.c0 else ctx.energy.with_c0(c0)
        gE, gV = energy.gradient(X), ctx.volume.gradient(X)
        _, r = projected_gradient(gE, gV)
        rho = gradient_floor(energy, ctx.volume, X, r)
        r_norm = float(np.linalg.norm(r))
        rows.append(dict(run=os.path.basename(os.path.normpath(path)), n=len(X), step=k,
                         dV=record["dV_over_V"], converged=record.get("converged"),
                         r=r_norm, test=ctx.protocol.tol * float(np.linalg.norm(gE))
                         + NewtonOptions().atol_grad,
                         floor=rho, ratio=r_norm / rho))
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", metavar="RUN", help="run folders")
    parser.add_argument("--steps", default=None,
                        help="comma-separated steps (default: every stored step)")
    args = parser.parse_args(argv)
    steps = [int(s) for s in args.steps.split(",")] if args.steps else None
    rows = [row for path in args.runs for row in measure(path, steps)]
    print(f"{'vertices':>8} {'step':>4} {'dV/V':>6} {'converged':>9} {'|r|':>9} "
          f"{'test':>9} {'floor':>9} {'|r|/floor':>9}")
    for row in rows:
        print(f"{row['n']:8d} {row['step']:4d} {row['dV']:6.3f} {str(row['converged']):>9} "
              f"{row['r']:9.2e} {row['test']:9.2e} {row['floor']:9.2e} {row['ratio']:9.2f}")
    sizes = sorted({row["n"] for row in rows})
    if len(sizes) > 1:
        floor = [np.median([row["floor"] for row in rows if row["n"] == n]) for n in sizes]
        slope = np.polyfit(np.log(sizes), np.log(floor), 1)[0]
        print("\nmedian floor: " + ", ".join(f"{n}: {f:.2e}" for n, f in zip(sizes, floor))
              + f"; grows as N^{slope:.2f}")


if __name__ == "__main__":
    main()
