"""Where a run of the comparison's protocol spends its time: each minimization of each step.

Run from the repository root (one thread; PARDISO needs Intel MKL):

    python benchmarks/bench_minimizations.py                    # seeds 0-7, 3594 vertices
    python benchmarks/bench_minimizations.py --seeds 5 --vertices 642

The protocol is the one ``bench_evolver.py`` runs on shellbuckle's side (``random_sphere(N,
seed)``, gamma = 271, nu = 1/3, Surface Evolver's bending energy, 13 volume steps of 0.019 V0,
the c0 cycle, no jiggle, tolerance 1e-9). Each step minimizes three times: after the volume
step (``step``), at c0 = 0 (``flat``) and back at c0 = 2/R (``return``; it starts at the minimum
before the cycle when the straight path there is downhill, :func:`shellbuckle.protocol.deflate.
downhill_path`). The script wraps :func:`shellbuckle.solve.newton` to count the iterations and
process time of each call and prints, per mesh, the steps from the first one whose
``step`` minimization takes more than ``--long`` iterations (the buckling step), then the
totals over the meshes by kind of minimization, before and from the buckling step.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import shellbuckle.protocol.deflate as deflate_module  # noqa: E402
import shellbuckle.solve as solve_module  # noqa: E402
from bench_evolver import build_mesh, run_ours  # noqa: E402
from shellbuckle.params import ShellParameters  # noqa: E402

KINDS = ("step", "flat", "return")


class Recorder:
    """Wraps ``shellbuckle.solve.newton`` and ``downhill_path``: ``calls`` holds
    ``(iterations, cpu_s)`` of every minimization, ``direct`` the steps (from 0) whose downhill
    test held."""

    def __init__(self):
        self.calls, self.direct = [], set()
        self._newton, self._downhill = solve_module.newton, deflate_module.downhill_path

    def __enter__(self):
        def newton(*args, **kwargs):
            t = time.process_time()
            result = self._newton(*args, **kwargs)
            self.calls.append((result.nit, time.process_time() - t))
            return result

        def downhill_path(*args, **kwargs):
            answer = self._downhill(*args, **kwargs)
            if answer:  # asked after the step's first two minimizations
                self.direct.add((len(self.calls) - 2) // 3)
            return answer

        solve_module.newton, deflate_module.downhill_path = newton, downhill_path
        return self

    def __exit__(self, *exc):
        solve_module.newton, deflate_module.downhill_path = self._newton, self._downhill


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(8)))
    ap.add_argument("--vertices", type=int, default=3594)
    ap.add_argument("--steps", type=int, default=13)
    ap.add_argument("--long", type=int, default=60,
                    help="iterations of a step's first minimization that mark the buckling step")
    args = ap.parse_args(argv)
    if args.steps < 1 or args.vertices < 12:
        raise SystemExit(f"--steps must be >= 1 and --vertices >= 12, got {args.steps}, "
                         f"{args.vertices}")
    params = ShellParameters.from_gamma(271.0, nu=1.0 / 3.0)
    schedule = [0.019 * k for k in range(1, args.steps + 1)]
    with tempfile.TemporaryDirectory() as tmp:
        # compiled kernels and the solver's library loaded before anything is timed
        run_ours(build_mesh("random", 642, 0), params, [0.019], True, 1e-9, Path(tmp) / "warm")
        totals = {(phase, kind): [0, 0.0] for phase in ("before", "after") for kind in KINDS}
        run_cpu = 0.0
        print(f"{args.vertices} vertices, gamma = 271, {args.steps} steps of 0.019 V0, c0 cycle, "
              f"no jiggle; per minimization: iterations/CPU s (step, flat, return); "
              f"'direct': the return started at the minimum before the cycle")
        for seed in args.seeds:
            with Recorder() as rec:
                ours = run_ours(build_mesh("random", args.vertices, seed), params, schedule,
                                True, 1e-9, Path(tmp) / f"run{seed}")
            run_cpu += ours["total_cpu_s"]
            if len(rec.calls) != 3 * args.steps:
                raise SystemExit(f"seed {seed}: {len(rec.calls)} minimizations, expected "
                                 f"{3 * args.steps} (a step was jiggled again?)")
            buckled = next((k for k in range(args.steps) if rec.calls[3 * k][0] > args.long),
                           args.steps)
            cells = []
            for k in range(args.steps):
                trio = rec.calls[3 * k:3 * k + 3]
                phase = "before" if k < buckled else "after"
                for kind, (nit, cpu) in zip(KINDS, trio):
                    totals[phase, kind][0] += nit
                    totals[phase, kind][1] += cpu
                if k >= buckled:
                    direct = " direct" if k in rec.direct else ""
                    cells.append(f"{k + 1}: " + " ".join(f"{n}/{c:.2f}" for n, c in trio)
                                 + direct)
            print(f"seed {seed:3d}  run {ours['total_cpu_s']:6.2f} s  buckling step "
                  f"{buckled + 1}  " + " | ".join(cells), flush=True)
        print(f"\n{len(args.seeds)} runs, {run_cpu:.2f} s CPU; minimizations by kind:")
        print(f"{'':8s} {'kind':7s} {'iterations':>10s} {'CPU s':>8s} {'share':>6s}")
        for (phase, kind), (nit, cpu) in totals.items():
            print(f"{phase:8s} {kind:7s} {nit:10d} {cpu:8.2f} {100 * cpu / run_cpu:5.1f}%")


if __name__ == "__main__":
    main()
