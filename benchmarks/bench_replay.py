"""The cost of the same work: every step of one stored trajectory, replayed from its stored start.

Run from the repository root:

    python benchmarks/bench_replay.py                        # gamma 271, 2333, 20995; 3594 vertices
    python benchmarks/bench_replay.py --gamma 2333 --every 4 # every 4th step only (quicker)
    python benchmarks/bench_replay.py --gamma 2333 --steps   # one line per step
    python benchmarks/bench_replay.py --every 4 --option memory=32   # Newton's options changed

Why: after buckling a trajectory depends on the code down to round-off, so two versions of the
solver run different trajectories (another dent, another stop) and a whole run
(``bench_deflation.py``) measures their speed only to a factor 1.5-2. Here the work is fixed:
a trajectory of the paper's protocol (dV = 0.019 V0, jiggle, Newton, c0 cycle, to
self-contact) is made once and stored in ``--states DIR`` (``g{gamma}_v{N}_s{seed}.npz``: the
conformation after every step, its energy, and the shellbuckle commit that made it; made by
the current code when missing), and every step ``k`` is then run again by the protocol's
``step`` from the stored conformation ``k - 1``, with the same jiggle. Keep the file to
compare two versions of the code on the same work.

Printed per gamma (one thread, mesh and trajectory construction not counted): steps
replayed; CPU and wall seconds of the replays; CPU seconds per step; minimizer iterations, KKT
factorizations (single and double precision) and linear solves per step; and ``same``, the
fraction of steps whose replay ends at the stored minimum (energy within 1e-9 relative; after
buckling a replay by another code may end at another pinning site of the dent); and ``dE
mean``, the mean of ``(E_replay - E_stored) / |E_stored|`` over the steps (in units of
1e-3): where a variant ends at other minima, whether they lie systematically higher or lower
(the wrinkled regime has many nearly degenerate ones).

``--option KEY=VALUE`` (repeatable) sets a field of
:class:`shellbuckle.solve.options.NewtonOptions` (``memory``, ``max_quasi``, ``relax_tol``, ...;
the value is a Python literal) for every minimization of the replays, to measure a setting on
the same work before changing its default. The trajectory itself is always made with the
defaults.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import ast  # noqa: E402
import contextlib  # noqa: E402
import dataclasses  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from shellbuckle.mesh.random_sphere import random_sphere  # noqa: E402
from shellbuckle.params import ShellParameters  # noqa: E402
from shellbuckle.protocol import deflate as protocol_mod  # noqa: E402
from shellbuckle.protocol.deflate import Protocol, State  # noqa: E402
from shellbuckle.solve.linear import CountingSolver  # noqa: E402
from shellbuckle.solve.options import NewtonOptions  # noqa: E402
from shellbuckle.solve.workspace import Workspace  # noqa: E402
from shellbuckle.store.run import source_commit  # noqa: E402

from machine import describe, reference, reference_line  # noqa: E402  (benchmarks/machine.py)

PAPER_GAMMAS = (271.0, 2333.0, 20995.0)


def _context(mesh, gamma: float, seed: int):
    protocol = Protocol.paper(seed=seed)
    ctx, state = protocol_mod.init(mesh, ShellParameters.from_gamma(gamma, nu=1.0 / 3.0),
                                   protocol, threads=1)
    workspace = Workspace(CountingSolver(ctx.workspace.solver))
    return dataclasses.replace(ctx, workspace=workspace), state


def trajectory(path: Path, mesh, gamma: float, seed: int) -> dict:
    """The stored trajectory at ``path``, made (by a whole run to self-contact) if missing."""
    if path.exists():
        with np.load(path) as data:
            return {k: data[k] for k in data.files}
    print(f"  making the trajectory {path} (a whole run) ...", flush=True)
    ctx, state = _context(mesh, gamma, seed)
    X, E = [state.X], [ctx.energy.value(state.X)]
    while state.stopped is None:
        state, record = protocol_mod.step(ctx, state)
        X.append(state.X)
        E.append(record["E_total"])
    out = dict(X=np.array(X), E=np.array(E), gamma=gamma, seed=seed,
               commit=str(source_commit() or "unknown"))
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **out)
    return out


def parse_options(items) -> dict:
    """``["memory=32", ...]`` as fields of :class:`NewtonOptions`, checked against them (a
    misspelt name is refused, not ignored)."""
    allowed = [f.name for f in dataclasses.fields(NewtonOptions)]
    options = {}
    for item in items or ():
        key, sep, text = item.partition("=")
        if not sep or key not in allowed:
            raise ValueError(f"--option {item!r}: expected KEY=VALUE with KEY one of "
                             f"{', '.join(allowed)}")
        try:
            options[key] = ast.literal_eval(text)
        except (ValueError, SyntaxError):
            raise ValueError(f"--option {item!r}: the value {text!r} is not a Python literal "
                             "(a number, True/False, None, a string in quotes)") from None
    return options


@contextlib.contextmanager
def newton_options(options: dict):
    """Within it, every minimization of the protocol gets ``options`` (fields of
    :class:`NewtonOptions`, as keywords of Newton's method) on top of its own."""
    inner = protocol_mod.minimize

    def minimize(*args, **kwargs):
        return inner(*args, **{**kwargs, **options})

    protocol_mod.minimize = minimize
    try:
        yield
    finally:
        protocol_mod.minimize = inner


def replay(mesh, traj: dict, every: int, per_step: bool) -> dict:
    ctx, _ = _context(mesh, float(traj["gamma"]), int(traj["seed"]))
    counts = ctx.workspace.solver.counts
    steps = range(1, len(traj["X"]), every)
    wall = cpu = 0.0
    its, same, rel = [], [], []
    certify_single = True  # the choice the last replayed step leaves, as in a run
    for k in steps:
        t, c = time.perf_counter(), time.process_time()
        before = dict(counts)
        start = State(step=k - 1, X=traj["X"][k - 1], certify_single=certify_single)
        after, record = protocol_mod.step(ctx, start)
        certify_single = after.certify_single
        dc, dt = time.process_time() - c, time.perf_counter() - t
        wall, cpu = wall + dt, cpu + dc
        its.append(record["iterations"])
        same.append(abs(record["E_total"] - traj["E"][k]) <= 1e-9 * abs(traj["E"][k]))
        rel.append((record["E_total"] - traj["E"][k]) / abs(traj["E"][k]))
        if per_step:
            d = {key: counts[key] - before[key] for key in counts}
            print(f"    step {k:3d}  E={record['E_total']:.12g}  stored {traj['E'][k]:.12g}  "
                  f"it={record['iterations']:4d}  fact={d['double']}+{d['single']}  "
                  f"solves={d['solve']:4d}  {dc:.2f} s CPU", flush=True)
    n = len(steps)
    return dict(gamma=float(traj["gamma"]), steps=n, cpu=cpu, wall=wall, per_step=cpu / n,
                it=np.mean(its), double=counts["double"] / n, single=counts["single"] / n,
                solves=counts["solve"] / n, same=np.mean(same), dE=np.mean(rel),
                commit=str(traj["commit"]))


HEADER = (f"{'gamma':>7} {'steps':>5} {'cpu s':>7} {'wall s':>7} {'s/step':>6} {'it':>6} "
          f"{'fact d':>6} {'fact s':>6} {'solves':>6} {'same':>5} {'dE mean':>8}  "
          "trajectory made by")


def _row(r: dict) -> str:
    return (f"{r['gamma']:7g} {r['steps']:5d} {r['cpu']:7.1f} {r['wall']:7.1f} "
            f"{r['per_step']:6.2f} {r['it']:6.1f} {r['double']:6.1f} {r['single']:6.1f} "
            f"{r['solves']:6.1f} {r['same']:5.2f} {1e3 * r['dE']:+8.3f}  {r['commit'][:12]}")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--gamma", type=float, nargs="+", default=list(PAPER_GAMMAS))
    parser.add_argument("--vertices", type=int, default=3594)
    parser.add_argument("--seed", type=int, default=0, help="mesh and jiggle seed (default 0)")
    parser.add_argument("--states", type=Path, default=Path("benchmarks/trajectories"),
                        help="folder of the stored trajectories (default benchmarks/trajectories)")
    parser.add_argument("--every", type=int, default=1, help="replay every k-th step only")
    parser.add_argument("--steps", action="store_true", help="print one line per step")
    parser.add_argument("--option", action="append", metavar="KEY=VALUE",
                        help="a keyword argument of Newton's method for the replays "
                             "(repeatable; e.g. memory=32)")
    args = parser.parse_args(argv)
    if args.every < 1:
        parser.error(f"--every must be >= 1, got {args.every}")
    try:
        options = parse_options(args.option)
    except ValueError as exc:
        parser.error(str(exc))
    print(f"{describe()}; one thread, shellbuckle {source_commit() or 'unknown'}")
    print(reference_line(reference()), flush=True)
    if options:
        print("Newton's options for the replays: "
              + ", ".join(f"{k}={v!r}" for k, v in options.items()))
    mesh = random_sphere(args.vertices, seed=args.seed)
    rows = []
    for gamma in args.gamma:
        path = args.states / f"g{gamma:g}_v{args.vertices}_s{args.seed}.npz"
        traj = trajectory(path, mesh, gamma, args.seed)
        with newton_options(options):
            rows.append(replay(mesh, traj, args.every, args.steps))
        print(f"  gamma={gamma:g}: {rows[-1]['steps']} steps replayed", flush=True)
    print()
    print(HEADER)
    for r in rows:
        print(_row(r))
    print(f"load average at the end {os.getloadavg()[0]:.2f}; again {reference_line(reference())}")


if __name__ == "__main__":
    main()
