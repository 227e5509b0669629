"""Sweep throughput on a local Dask cluster: runs per hour on 1 worker and on 2 workers.

Run from the repository root:

    python benchmarks/bench_sweep.py [--runs 8] [--icosphere 6] [--until 0.3] [--workers 1 2]

Each worker count sweeps ``--runs`` runs of the same cost (gamma = 2333, nu = 1/3, the same
icosahedral mesh, the same schedule; only the seed of the jiggle differs) into a fresh folder
with :func:`shellbuckle.sweep.run_sweep`, analysis included, exactly as ``shellbuckle sweep``
does. Columns:

- ``wall s``: from the call to the returned catalogue, including the start and stop of the
  local cluster (``startup s``, measured separately on an empty task);
- ``runs/h``: runs / wall x 3600; ``speedup``: wall(1 worker) / wall (the table is printed at
  the end, in the order of ``--workers``); ``efficiency``: speedup / workers;
- ``task s/run``: mean wall time of one task on its worker (mesh, setup, steps, writing,
  analysis); ``cpu s/run``: mean CPU time of one task (the work itself, independent of how
  the cores are shared); ``cpu/wall``: CPU time of the worker processes during the tasks
  over their wall time (1 when each worker has a core to itself, less when other jobs share
  the cores);
  ``steps s/run``: mean of the per-step wall times stored in the runs;
- ``load``: the 1-minute load average of the machine before and after (other jobs included).
"""

from __future__ import annotations

import argparse
import platform
import sys
import shutil
import tempfile
import time
from pathlib import Path


def _load() -> float:
    try:
        return float(Path("/proc/loadavg").read_text().split()[0])
    except OSError:  # pragma: no cover - not Linux
        return float("nan")


def _startup(workers: int) -> float:
    from distributed import Client, LocalCluster

    from shellbuckle.sweep import WORKER_ENV

    t = time.perf_counter()
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           dashboard_address=None, env=dict(WORKER_ENV))
    client = Client(cluster)
    client.submit(int, 1).result()
    client.close()
    cluster.close()
    return time.perf_counter() - t


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=8, help="runs per sweep (default 8)")
    parser.add_argument("--icosphere", type=int, default=6, help="mesh level (default 6: 362 "
                        "vertices)")
    parser.add_argument("--until", type=float, default=0.3, help="last target dV/V (default 0.3)")
    parser.add_argument("--gamma", type=float, default=2333.0)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--keep", metavar="DIR", help="keep the sweep folders in DIR")
    args = parser.parse_args(argv)

    import dask
    import numpy as np

    from shellbuckle.protocol.schedule import PAPER_DV, linear_schedule
    from shellbuckle.sweep import SweepSpec, default_workers, run_sweep

    spec = SweepSpec(gamma=args.gamma, icosphere=args.icosphere, until=args.until,
                     seeds=list(range(args.runs)))
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    steps = len(linear_schedule(PAPER_DV, args.until))
    print(f"{args.runs} runs: gamma = {args.gamma:g}, icosphere({args.icosphere}) = "
          f"{10 * args.icosphere ** 2 + 2} vertices, {steps} steps of dV/V = {PAPER_DV} each")
    print(f"machine: {platform.machine()}, {default_workers()} cores, {platform.python_version()}, "
          f"dask {dask.__version__}, numpy {np.__version__}")
    header = (f"{'workers':>7} {'runs':>5} {'wall s':>8} {'startup s':>9} {'runs/h':>8} "
              f"{'speedup':>8} {'efficiency':>10} {'task s/run':>10} {'cpu s/run':>9} "
              f"{'cpu/wall':>8} {'steps s/run':>11} "
              f"{'load':>11}")
    results = []
    for w in args.workers:
        startup = _startup(w)
        out = root / f"workers{w}"
        shutil.rmtree(out, ignore_errors=True)
        load0 = _load()
        t = time.perf_counter()
        catalogue = run_sweep(spec, out, workers=w, progress=False)
        wall = time.perf_counter() - t
        load1 = _load()
        finished = int((catalogue["status"] == "finished").sum())
        if finished != args.runs:
            raise SystemExit(f"only {finished} of {args.runs} runs finished in {out}")
        results.append((w, wall, startup, catalogue, load0, load1))
        print(f"  {w} worker(s): {wall:.1f} s", file=sys.stderr, flush=True)
    # speedup relative to the fewest workers, scaled to one worker (exact when that is 1)
    w0, wall0 = min((r[0], r[1]) for r in results)
    print(header)
    for w, wall, startup, catalogue, load0, load1 in results:
        speedup = w0 * wall0 / wall
        print(f"{w:>7d} {args.runs:>5d} {wall:>8.1f} {startup:>9.1f} "
              f"{args.runs / wall * 3600:>8.0f} {speedup:>8.2f} {speedup / w:>10.2f} "
              f"{catalogue['task_wall_s'].mean():>10.2f} {catalogue['task_cpu_s'].mean():>9.2f} "
              f"{catalogue['task_cpu_s'].sum() / catalogue['task_wall_s'].sum():>8.2f} "
              f"{catalogue['wall_s'].mean():>11.2f} "
              f"{load0:>5.1f}->{load1:<5.1f}")
    if not args.keep:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
