"""Wall time of whole deflation runs with the paper's protocol, single thread by default.

Run from the repository root:

    python benchmarks/bench_deflation.py                     # gamma 271, 2333, 20995; 3594 vertices
    python benchmarks/bench_deflation.py --gamma 2333 --until 0.1 --steps   # quick, per-step rows
    python benchmarks/bench_deflation.py --gamma --large     # only the ~40k-vertex run
    python benchmarks/bench_deflation.py --gamma 2333 --threads 2   # PARDISO on two threads
    python benchmarks/bench_deflation.py --gamma 20995 --seeds 0 1 2  # three jiggle seeds

For each gamma (nu = 1/3) it runs the paper's protocol (Quilliet et al. 2008, §4.1: steps of
dV = 0.019 V0, jiggle, Newton at fixed volume, the c0 -> 0 -> 2/R cycle, stop at the first
self-intersection or at ``--until``) on ``random_sphere(vertices, seed)`` and prints one row:
number of steps; total wall time and CPU time of the process (the wall time is inflated when
other jobs share the machine, the CPU time much less); wall time per step; minimizer
iterations per step (Newton and quasi-Newton steps of the three minimizations of a step
summed; mean and max over steps) and KKT factorizations per step (mean); dV/V at primary
buckling (the first step whose pressure is lower than the previous step's) and dV/V of the
last step; and where the time went (assembly of energies and KKT matrices, factorizations,
solves, line searches). ``--large`` adds a run on a ~40k-vertex mesh with a few steps
(``--large-until``) to show how the cost per step grows. Mesh construction is not counted
(it is reported separately); the run is the protocol's ``init`` + ``step`` loop as
``shellbuckle deflate`` drives it, without the run store (which adds one small HDF5 write per
step). Everything runs on one thread (the issue's measure) unless ``--threads N`` gives the
sparse factorization N threads (the results are the same bits; NumPy's BLAS stays on one).

After buckling, where the shell goes (which dent, which wrinkle pattern, how far it deflates
before its walls touch) depends on the jiggle, so the time of a whole run is a random variable.
``--seeds S ...`` runs every gamma once per jiggle seed on the same mesh
(``random_sphere(vertices, --seed)``) and ends with one line per gamma: the smallest, median
and largest total wall time and number of steps, and how many runs took at most 60 s.

The first lines name the machine and time a fixed piece of the deflation's work on it
(``benchmarks/machine.py``: an energy gradient, a Hessian, PARDISO factorizations and solves);
the last line times it again. The same run's wall time differs by up to 1.5 times between
days on machines of one kind; compare runs by those figures as well as by their own.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402

import numpy as np  # noqa: E402

from shellbuckle.mesh.random_sphere import random_sphere  # noqa: E402
from shellbuckle.params import ShellParameters  # noqa: E402
from shellbuckle.protocol import deflate as protocol_mod  # noqa: E402
from shellbuckle.protocol.deflate import Protocol  # noqa: E402
from shellbuckle.solve.linear import CountingSolver  # noqa: E402
from shellbuckle.solve.workspace import Workspace  # noqa: E402

from machine import describe, reference, reference_line  # noqa: E402  (benchmarks/machine.py)

PAPER_GAMMAS = (271.0, 2333.0, 20995.0)
TIMING_KEYS = ("assembly", "factorization", "solve", "line_search")


class _Recorder:
    """Wraps the protocol's minimizer call to collect the iteration counts and timings."""

    def __init__(self):
        self.inner = protocol_mod._minimize
        self.timings = defaultdict(float)
        self.n_min = 0
        self.nit = []

    def __call__(self, ctx, energy, X, V_target, *args, **kwargs):
        result = self.inner(ctx, energy, X, V_target, *args, **kwargs)
        self.n_min += 1
        self.nit.append(result.nit)
        for key, value in (result.timings or {}).items():
            self.timings[key] += value
        return result


def _threads_text(threads: int) -> str:
    if threads == 1:
        return "one thread"
    return f"sparse factorization on {threads} threads (the rest on one)"


TARGET_S = 60.0
"""The issue's target for one whole run (wall seconds, one core)."""


def run_one(mesh, gamma: float, *, dv: float, until: float, seed: int, per_step: bool,
            jiggle: float | None = None, prerelax: bool = True, direct_return: bool = True,
            threads: int = 1) -> dict:
    """One whole run; ``seed`` is the jiggle's seed (the mesh is given)."""
    params = ShellParameters.from_gamma(gamma, nu=1.0 / 3.0)
    protocol = Protocol.paper(dv=dv, until=until, seed=seed, jiggle=jiggle, prerelax=prerelax,
                              direct_return=direct_return)
    recorder = _Recorder()
    protocol_mod._minimize = recorder
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        ctx, state = protocol_mod.init(mesh, params, protocol, threads=threads)
        ctx = dataclasses.replace(ctx, workspace=Workspace(CountingSolver(ctx.workspace.solver)))
        t_init = time.perf_counter() - t0
        records = []
        while state.stopped is None:
            state, record = protocol_mod.step(ctx, state)
            records.append(record)
            if per_step:
                print(f"    step {record['step']:3d}  dV/V={record['dV_over_V']:.4f}  "
                      f"E={record['E_total']:.10g}  p={record['pressure']:.8g}  "
                      f"it={record['iterations']:3d}  inertia={record['inertia']}  "
                      f"conv={record['converged']}  {record['wall_s']:.2f} s", flush=True)
        total, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        protocol_mod._minimize = recorder.inner
    pressures = np.array([r["pressure"] for r in records])
    drops = np.flatnonzero(np.diff(pressures) < 0)
    its = np.array([r["iterations"] for r in records])
    return dict(gamma=gamma, seed=seed, vertices=mesh.n_vertices, steps=len(records),
                total=total, cpu=cpu,
                init=t_init, factor=ctx.workspace.solver.n_factor / len(records),
                per_step=(total - t_init) / len(records), it_mean=its.mean(),
                it_max=its.max(),
                buckle=records[drops[0] + 1]["dV_over_V"] if len(drops) else float("nan"),
                last=records[-1]["dV_over_V"], stopped=state.stopped,
                unconverged=sum(not r["converged"] for r in records),
                timings={k: recorder.timings.get(k, 0.0) for k in TIMING_KEYS})


HEADER = (f"{'gamma':>7} {'seed':>4} {'vertices':>8} {'steps':>5} {'total s':>8} {'cpu s':>7} "
          f"{'s/step':>7} "
          f"{'it mean':>7} {'it max':>6} {'fact':>5} {'dV/V buckle':>11} {'dV/V stop':>9} "
          f"{'unconv':>6}  assembly/factor/solve/linesearch s")


def _row(r: dict) -> str:
    t = r["timings"]
    split = "/".join(f"{t[k]:.1f}" for k in TIMING_KEYS)
    return (f"{r['gamma']:7g} {r['seed']:4d} {r['vertices']:8d} {r['steps']:5d} "
            f"{r['total']:8.1f} {r['cpu']:7.1f} "
            f"{r['per_step']:7.2f} {r['it_mean']:7.1f} {r['it_max']:6d} {r['factor']:5.1f} "
            f"{r['buckle']:11.3f} "
            f"{r['last']:9.3f} {r['unconverged']:6d}  {split}")


def seed_summary(rows: list) -> list:
    """One line per (gamma, vertices) run with more than one seed: the spread of the whole-run
    wall time and of the number of steps, and the runs within ``TARGET_S``."""
    groups = defaultdict(list)
    for r in rows:
        groups[(r["gamma"], r["vertices"])].append(r)
    lines = []
    for (gamma, n), group in groups.items():
        if len(group) < 2:
            continue
        total = np.array([r["total"] for r in group])
        steps = np.array([r["steps"] for r in group])
        lines.append(f"gamma={gamma:g}, {n} vertices, {len(group)} seeds: total wall s "
                     f"min/median/max {total.min():.1f}/{np.median(total):.1f}/{total.max():.1f}"
                     f", steps {steps.min()}/{np.median(steps):g}/{steps.max()}, "
                     f"{int(np.sum(total <= TARGET_S))} of {len(group)} within {TARGET_S:g} s")
    return lines


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--gamma", type=float, nargs="*", default=list(PAPER_GAMMAS),
                        help="gammas of the 3594-vertex runs (default 271 2333 20995; none: skip)")
    parser.add_argument("--vertices", type=int, default=3594, help="mesh size (default 3594)")
    parser.add_argument("--until", type=float, default=0.95,
                        help="last target dV/V (default 0.95: run to self-contact)")
    parser.add_argument("--dv", type=float, default=0.019, help="volume step / V0 (default 0.019)")
    parser.add_argument("--seed", type=int, default=0, help="mesh and jiggle seed (default 0)")
    parser.add_argument("--seeds", type=int, nargs="+",
                        help="jiggle seeds: one run per seed and gamma on the --seed mesh")
    parser.add_argument("--no-prerelax", action="store_true",
                        help="Newton from the jiggled state at once, without the preconditioned "
                             "relaxation (the solver before it existed)")
    parser.add_argument("--no-direct-return", action="store_true",
                        help="after the c0 cycle always minimize from the flat minimum (the "
                             "protocol before its direct return existed)")
    parser.add_argument("--jiggle", type=float,
                        help="jiggle as a fraction of the mean edge length instead of the "
                             "protocol's default (Surface Evolver's temperature 0.05)")
    parser.add_argument("--steps", action="store_true", help="print one line per step")
    parser.add_argument("--threads", type=int, default=1,
                        help="threads of the sparse factorization (default 1)")
    parser.add_argument("--large", action="store_true", help="add the ~40k-vertex run")
    parser.add_argument("--large-vertices", type=int, default=40000)
    parser.add_argument("--large-gamma", type=float, default=2333.0)
    parser.add_argument("--large-until", type=float, default=0.057,
                        help="last target dV/V of the large run (default 0.057: 3 steps)")
    args = parser.parse_args(argv)

    print(f"{describe()}; {_threads_text(args.threads)}")
    print(reference_line(reference()), flush=True)
    seeds = args.seeds or [args.seed]
    jobs = [(args.vertices, g, args.until, s) for g in args.gamma for s in seeds]
    if args.large:
        jobs.append((args.large_vertices, args.large_gamma, args.large_until, args.seed))
    meshes = {}
    rows = []
    for n, gamma, until, seed in jobs:
        if n not in meshes:
            t = time.perf_counter()
            meshes[n] = random_sphere(n, seed=args.seed)
            print(f"random_sphere({n}, seed={args.seed}) built in {time.perf_counter() - t:.1f} s "
                  "(not counted)", flush=True)
        r = run_one(meshes[n], gamma, dv=args.dv, until=until, seed=seed,
                    per_step=args.steps, jiggle=args.jiggle, prerelax=not args.no_prerelax,
                    direct_return=not args.no_direct_return, threads=args.threads)
        rows.append(r)
        print(f"  gamma={gamma:g}, {n} vertices, seed {seed}: {r['stopped']}; "
              f"{r['total']:.1f} s wall, "
              f"{r['cpu']:.1f} s CPU (init {r['init']:.1f} s)", flush=True)
    print()
    print(HEADER)
    for r in rows:
        print(_row(r))
    for line in seed_summary(rows):
        print(line)
    print(f"load average at the end {os.getloadavg()[0]:.2f}; again {reference_line(reference())}")


if __name__ == "__main__":
    main()
