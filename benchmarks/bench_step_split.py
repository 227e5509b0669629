"""Where the iterations of a stored step go: the protocol's step ``k`` of a stored deflation
made again from its stored step ``k - 1`` (:class:`shellbuckle.locate.StepFromStored`, which
gives the stored bits), with the iterations, CPU time and energy of each of its
minimizations (from the jiggled start; at c0 = 0, the cycle's waypoint; back at c0), and with
another number of quasi-Newton steps per factorization (``--max-quasi``).

    python benchmarks/bench_step_split.py RUN --steps 20,30,35,40 [--max-quasi 0 10 20 50]

Prints one line per step and setting, and the total CPU time per setting. A setting other
than the run's own may end a step after buckling in another minimum (its energy differs
from the stored one): the path after buckling depends on the minimizer's steps.
"""

from __future__ import annotations

import argparse
import time

import shellbuckle.protocol.deflate as protocol
from shellbuckle.locate import StepFromStored


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", help="a finished deflation run folder")
    parser.add_argument("--steps", default="20,30", help="comma-separated steps (>= 1)")
    parser.add_argument("--max-quasi", nargs="*", type=int, default=[None],
                        help="quasi-Newton steps per factorization (default: the run's own)")
    args = parser.parse_args()
    steps = [int(k) for k in args.steps.split(",")]
    minimize, calls = protocol.minimize, []
    print(f"{'max_quasi':>9} {'step':>4} {'iterations':>10} {'stored':>6} {'cpu s':>6} "
          f"{'E / stored - 1':>14}  minimizations (iterations, cpu s, E)")
    for quasi in args.max_quasi:
        def counted(*a, **k):
            if quasi is not None:
                k["max_quasi"] = quasi
            t = time.process_time()
            result = minimize(*a, **k)
            calls.append((result.nit, round(time.process_time() - t, 1), float(result.fun)))
            return result

        protocol.minimize = counted
        total = 0.0
        for k in steps:
            calls.clear()
            step = StepFromStored(args.run, k)
            stored = step.run.store.record(k)
            t = time.process_time()
            _, record = step(stored["target_dV_over_V"])
            cpu = time.process_time() - t
            total += cpu
            label = "run's" if quasi is None else str(quasi)
            print(f"{label:>9} {k:>4} {record['iterations']:>10} {stored['iterations']:>6} "
                  f"{cpu:>6.1f} {record['E_total'] / stored['E_total'] - 1:>14.2e}  {calls}",
                  flush=True)
        print(f"{'':>9} total CPU {total:.1f} s")
    protocol.minimize = minimize


if __name__ == "__main__":
    main()
