"""Why a step after buckling costs hundreds of iterations: the path of its minimization.

Run from the repository root:

    python benchmarks/bench_valley.py                           # 3594 and 10000 vertices
    python benchmarks/bench_valley.py --vertices 3594 10000 40000 --step 7

The paper's protocol (helfrich reading, gamma 2333 by default, the refinement study's smooth
imperfection: 0.00976 R rms, degrees 2-20, seed 0) is run to step ``--step - 1`` (the shell
buckles at step 4, dV/V = 0.076), then the first minimization of step ``--step`` (from the
jiggled start, by the protocol's own minimization) is made again, keeping every point where
Newton's method asks the protocol's fold test (``abandon``: after the relaxation and after
every Newton step short of convergence; the test never stops it here). Printed per mesh: the
points kept, the minimization's iterations (relaxation, quasi-Newton and Newton steps), how
far its end lies from its start
(largest vertex displacement, in mean edge lengths ``h`` of the mesh) and how far the dent's
axis turned (its angle times R, in ``h``); then, for points along the way, their energy above
the minimum ``E - E_min``, their distance to it (largest vertex displacement, in ``h``), and
``chord``: the highest energy on the straight line from the point to the minimum (positions
interpolated, the volume restored at 41 points), above ``E_min``, divided by ``E - E_min``.

A chord ratio far above 1 means the way to the minimum is not straight: the point lies in a
curved valley, which Newton's and quasi-Newton steps (straight steps from a local model)
follow by many short steps. The number of steps then grows with the length of the valley in
units of its width, i.e. with the distance the dent travels in mean edge lengths, which grows
as N^1/2 for a distance fixed in units of R. No timing is printed (``bench_scaling.py`` times
the same steps).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402

import numpy as np  # noqa: E402

from shellbuckle.mesh.random_sphere import random_sphere  # noqa: E402
from shellbuckle.params import ShellParameters  # noqa: E402
from shellbuckle.protocol import deflate as protocol_mod  # noqa: E402
from shellbuckle.protocol.deflate import Protocol  # noqa: E402
from shellbuckle.protocol.jiggle import step_rng  # noqa: E402
from shellbuckle.solve.linesearch import (RestoredPath, max_displacement,  # noqa: E402
                                          mean_edge_length)


def dent_axis(X: np.ndarray) -> np.ndarray:
    """The unit vector to the dent: the mean position weighted by the squared depth below the
    farthest vertex."""
    radius = np.linalg.norm(X, axis=1)
    w = (radius.max() - radius) ** 2
    c = (w[:, None] * X).sum(axis=0)
    return c / np.linalg.norm(c)


def chord_peak(ctx, X0: np.ndarray, X1: np.ndarray, V_target: float, points: int = 41) -> float:
    """The highest energy on the straight line from ``X0`` to ``X1``, the volume restored."""
    path = RestoredPath(ctx.energy, ctx.volume, X0, X1 - X0, V_target)
    return max(path(t)[0] for t in np.linspace(0.0, 1.0, points))


def probe(n: int, gamma: float, k: int, seed: int, smooth: float) -> list[str]:
    mesh = random_sphere(n, seed=seed)
    params = ShellParameters.from_gamma(gamma, nu=1.0 / 3.0, energy_convention="helfrich")
    protocol = Protocol.paper(seed=seed, smooth_jiggle=smooth, smooth_degree=20)
    ctx, state = protocol_mod.init(mesh, params, protocol, threads=1)
    for _ in range(k - 1):
        state, _ = protocol_mod.step(ctx, state)
    h = mean_edge_length(mesh.faces, mesh.X)
    V_target = ctx.V0 * (1.0 - protocol.schedule[k - 1])
    sigma = protocol.jiggle_sigma(mesh.X, state.X, mesh.topology.edges)
    start = protocol_mod._jiggled(ctx, state.X, sigma, step_rng(seed, k))
    kept, inner = [], protocol_mod.minimize

    def keeping(*args, abandon, abandon_thorough, **kwargs):
        def asking(test):
            def ask(X):  # the protocol's own test, after keeping the point
                kept.append(np.array(X))
                return test(X)
            return ask

        return inner(*args, abandon=asking(abandon), abandon_thorough=asking(abandon_thorough),
                     history=True, **kwargs)

    protocol_mod.minimize = keeping  # the protocol's first minimization of the step, as it is
    try:
        result = protocol_mod._minimize(ctx, ctx.energy, start, V_target, relaxed=state.X,
                                        relaxed_token=ctx.workspace.kept,
                                        certify_single=state.certify_single, jiggle=sigma)
    finally:
        protocol_mod.minimize = inner
    E_min, X_min = result.fun, result.x
    turned = np.arccos(np.clip(dent_axis(state.X) @ dent_axis(X_min), -1.0, 1.0)) * params.R
    kinds = [r["step"] for r in result.history]
    lines = [f"{mesh.n_vertices} vertices, step {k} (dV/V = {protocol.schedule[k - 1]:.3f}): "
             f"{result.message}; {len(kept)} points kept, {result.nit} iterations "
             f"({kinds.count('relax')} relaxation, {kinds.count('quasi-newton')} quasi-Newton); "
             f"end {max_displacement(X_min - state.X) / h:.1f} h from the step's start, "
             f"dent axis turned by {turned / h:.1f} h (h = {h:.4f} R)",
             f"  {'point':>11} {'E - E_min':>10} {'distance/h':>10} {'chord':>8}"]
    for j in sorted({round(x) for x in np.linspace(0, len(kept) - 1, 6)} if kept else ()):
        X = kept[j]
        gap = ctx.energy.value(X) - E_min
        if not gap > 0:
            continue
        peak = chord_peak(ctx, X, X_min, V_target)
        lines.append(f"  {j + 1:11d} {gap:10.2e} {max_displacement(X_min - X) / h:10.2f} "
                     f"{(peak - E_min) / gap:8.1f}")
    return lines


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--vertices", type=int, nargs="+", default=[3594, 10000])
    parser.add_argument("--gamma", type=float, default=2333.0)
    parser.add_argument("--step", type=int, default=5,
                        help="the step whose first minimization is followed (default 5, the "
                             "step after buckling at gamma 2333)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--smooth-jiggle", type=float, default=0.00976)
    args = parser.parse_args(argv)
    if args.step < 2:
        parser.error(f"--step must be >= 2, got {args.step}")
    for n in args.vertices:
        for line in probe(n, args.gamma, args.step, args.seed, args.smooth_jiggle):
            print(line, flush=True)


if __name__ == "__main__":
    main()
