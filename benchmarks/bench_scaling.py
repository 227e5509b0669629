"""How the cost of the paper's protocol grows with the mesh: time, factorizations, iterations and
peak memory per step, before and after buckling, from 3594 to 160k vertices.

Run from the repository root:

    python benchmarks/bench_scaling.py                                  # 3594 10000 40000, 6 steps
    python benchmarks/bench_scaling.py --vertices 3594 10000 40000 160000 --steps 4
    python benchmarks/bench_scaling.py --whole 3594 10000               # whole runs on the small ones
    python benchmarks/bench_scaling.py --option smooth_jiggle=0.002      # any Protocol field

Each mesh size runs in its own process (so that its peak resident memory is its own):
``random_sphere(n, seed)`` (not timed), one warm-up step on a 642-vertex icosphere (Numba's
compilation, not timed), then the paper's protocol (Quilliet et al. 2008, §4.1, as
``shellbuckle deflate`` runs it, without the run store) at ``--gamma`` (default 2333, which stays
a sphere for a few steps and then buckles) for ``--steps`` steps, or to self-contact for the
sizes named in ``--whole``. One thread unless ``--threads``.

Printed: one line per step with ``--per-step``; then per size the steps before buckling (before
the first pressure drop) and after, with the mean wall time per step, KKT factorizations per
step and minimizer iterations per step (Newton and quasi-Newton steps of the step's three
minimizations) in each part (the part after buckling includes the buckling step), the mean
``move`` of a step after the buckling step (the largest vertex displacement from the step's
start to its end, in mean edge lengths of the mesh: how far the dent travels over the mesh in
one step), the whole-run time where a whole run was made, the peak resident memory of the
process, and the growth exponent of the time per step before buckling between successive sizes
and over the whole range (a least-squares fit of log t = a + b log N).
The first lines name the machine and time a fixed piece of work on it
(``benchmarks/machine.py``); compare numbers only together with that line.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

DEFAULT_SIZES = (3594, 10000, 40000)


def _value(text: str):
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return {"true": True, "false": False, "none": None}.get(text.lower(), text)


def one_size(n: int, gamma: float, steps: int | None, seed: int, threads: int, options: dict,
             per_step: bool) -> dict:
    """The protocol on ``random_sphere(n, seed)``, in this process (``steps`` None: to
    self-contact)."""
    from shellbuckle.mesh import icosphere
    from shellbuckle.mesh.random_sphere import random_sphere
    from shellbuckle.params import ShellParameters
    from shellbuckle.protocol import deflate as protocol_mod
    from shellbuckle.protocol.deflate import Protocol
    from shellbuckle.solve.linear import CountingSolver
    from shellbuckle.solve.linesearch import max_displacement, mean_edge_length
    from shellbuckle.solve.workspace import Workspace

    params = ShellParameters.from_gamma(gamma, nu=1.0 / 3.0)
    until = 0.95 if steps is None else min(0.95, 0.019 * steps + 1e-9)
    protocol = Protocol.paper(until=until, seed=seed, **options)
    warm_ctx, warm = protocol_mod.init(icosphere(8), params, protocol, threads=threads)
    protocol_mod.step(warm_ctx, warm)
    t = time.perf_counter()
    mesh = random_sphere(n, seed=seed)
    build = time.perf_counter() - t
    t0 = time.perf_counter()
    ctx, state = protocol_mod.init(mesh, params, protocol, threads=threads)
    solver = CountingSolver(ctx.workspace.solver)
    ctx = dataclasses.replace(ctx, workspace=Workspace(solver))
    init = time.perf_counter() - t0
    edge = mean_edge_length(mesh.faces, mesh.X)
    rows = []
    while state.stopped is None:
        before, X_before = solver.n_factor, state.X
        state, record = protocol_mod.step(ctx, state)
        rows.append({"step": record["step"], "dV_over_V": record["dV_over_V"],
                     "pressure": record["pressure"], "wall_s": record["wall_s"],
                     "iterations": record["iterations"], "factorizations": solver.n_factor - before,
                     "move": max_displacement(state.X - X_before) / edge,
                     "converged": bool(record["converged"])})
        if per_step:
            r = rows[-1]
            print(f"    {n:>6} vertices step {r['step']:3d}  dV/V={r['dV_over_V']:.3f}  "
                  f"p={r['pressure']:.5g}  it={r['iterations']:4d}  fact={r['factorizations']:3d}  "
                  f"move={r['move']:.2f} edges  {r['wall_s']:.2f} s", file=sys.stderr, flush=True)
    total = time.perf_counter() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {"vertices": mesh.n_vertices, "gamma": gamma, "build_s": build, "init_s": init,
            "total_s": total, "whole": steps is None, "stopped": state.stopped,
            "peak_mb": peak_mb, "rows": rows}


def _parts(rows: list) -> tuple[list, list]:
    """The steps before the first pressure drop, and from it on."""
    p = [r["pressure"] for r in rows]
    drops = [i for i in range(1, len(p)) if p[i] < p[i - 1]]
    cut = drops[0] if drops else len(rows)
    return rows[:cut], rows[cut:]


def _mean(rows: list, key: str) -> float:
    return float(np.mean([r[key] for r in rows])) if rows else math.nan


def _fmt(x: float, spec: str) -> str:
    return format(x, spec) if math.isfinite(x) else "-".rjust(len(format(1.0, spec)))


def table(results: list) -> list[str]:
    lines = [f"{'vertices':>8} {'steps':>5} {'pre':>3} {'s/step pre':>10} {'s/step post':>11} "
             f"{'fact pre':>8} {'fact post':>9} {'it pre':>6} {'it post':>7} "
             f"{'move post':>9} {'whole s':>8} {'peak MB':>8} {'exponent':>8}"]
    previous = None
    for r in results:
        pre, post = _parts(r["rows"])
        t_pre = _mean(pre, "wall_s")
        exponent = math.nan
        if previous is not None and math.isfinite(t_pre) and math.isfinite(previous[1]):
            exponent = math.log(t_pre / previous[1]) / math.log(r["vertices"] / previous[0])
        lines.append(f"{r['vertices']:8d} {len(r['rows']):5d} {len(pre):3d} "
                     f"{_fmt(t_pre, '10.2f')} {_fmt(_mean(post, 'wall_s'), '11.2f')} "
                     f"{_fmt(_mean(pre, 'factorizations'), '8.1f')} "
                     f"{_fmt(_mean(post, 'factorizations'), '9.1f')} "
                     f"{_fmt(_mean(pre, 'iterations'), '6.0f')} "
                     f"{_fmt(_mean(post, 'iterations'), '7.0f')} "
                     f"{_fmt(_mean(post[1:], 'move'), '9.1f')} "
                     f"{_fmt(r['total_s'] if r['whole'] else math.nan, '8.1f')} "
                     f"{r['peak_mb']:8.0f} {_fmt(exponent, '8.2f')}")
        previous = (r["vertices"], t_pre)
    points = [(r["vertices"], _mean(_parts(r["rows"])[0], "wall_s")) for r in results]
    points = [(n, t) for n, t in points if math.isfinite(t)]
    if len(points) >= 2:
        b = np.polyfit(np.log([n for n, _ in points]), np.log([t for _, t in points]), 1)[0]
        lines.append(f"time per step before buckling grows as N^{b:.2f} from {points[0][0]} to "
                     f"{points[-1][0]} vertices (least squares over {len(points)} sizes)")
    return lines


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--vertices", type=int, nargs="+", default=list(DEFAULT_SIZES))
    parser.add_argument("--gamma", type=float, default=2333.0)
    parser.add_argument("--steps", type=int, default=6,
                        help="volume steps per size unless it is in --whole (default 6)")
    parser.add_argument("--whole", type=int, nargs="*", default=[],
                        help="sizes run to self-contact")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--option", action="append", default=[], metavar="NAME=VALUE",
                        help="a Protocol field, e.g. temperature=0.01 (repeatable)")
    parser.add_argument("--per-step", action="store_true", help="one line per step (stderr)")
    parser.add_argument("--json", help="also write the results to this JSON file")
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    options = dict(item.split("=", 1) for item in args.option)
    options = {k: _value(v) for k, v in options.items()}
    if args.one is not None:
        steps = None if args.one in args.whole else args.steps
        print(json.dumps(one_size(args.one, args.gamma, steps, args.seed, args.threads, options,
                                  args.per_step)))
        return
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from machine import describe, reference, reference_line

    print(f"{describe()}; {args.threads} thread(s); gamma = {args.gamma:g}; options {options}")
    print(reference_line(reference()), flush=True)
    results = []
    for n in sorted(args.vertices):
        command = [sys.executable, os.path.abspath(__file__), "--one", str(n),
                   "--gamma", str(args.gamma), "--steps", str(args.steps), "--seed", str(args.seed),
                   "--threads", str(args.threads), *sum((["--option", o] for o in args.option), []),
                   *(["--whole", *map(str, args.whole)] if args.whole else []),
                   *(["--per-step"] if args.per_step else [])]
        done = subprocess.run(command, check=True, stdout=subprocess.PIPE, text=True)
        r = json.loads(done.stdout.strip().splitlines()[-1])
        results.append(r)
        print(f"  {r['vertices']} vertices: {len(r['rows'])} steps in {r['total_s']:.1f} s "
              f"(init {r['init_s']:.1f} s; mesh built in {r['build_s']:.1f} s, not counted); "
              f"{r['stopped']}", flush=True)
    print()
    for line in table(results):
        print(line)
    print(f"load average at the end {os.getloadavg()[0]:.2f}; again {reference_line(reference())}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
