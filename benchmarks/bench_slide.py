"""What the iterations of a step after buckling buy: the slide of the dent.

Run from the repository root, on a stored run folder:

    shellbuckle deflate --gamma 2333 --energy-convention helfrich --vertices 10000 \
        --smooth-jiggle 0.00976 --smooth-degree 20 --no-locate --no-plot --threads 1 --out h10k
    python benchmarks/bench_slide.py h10k                      # every step after buckling
    python benchmarks/bench_slide.py h10k --replay 17,20       # and two steps made again

First table, one line per stored step after the primary buckling: the minimizer's iterations
(the table's, all minimizations of the step), the class of the shape (the steps are
classified, and the analysis stored as ``shellbuckle analyze`` does, where the run has none),
and how far the dent's axis turned since the step before (degrees, and the arc it swept at
radius R in mean edge lengths ``h``; the axis of the material points: the vertices' reference
directions weighted by how far each lies inside the median radius, squared). The dent's
position on a sphere is a symmetry of the continuous shell (a rotation of the dent against the
material costs no energy); on a mesh it is pinned weakly, and a step in which it slides to
another pinning site costs several times a step in which it stays.

Second table, for each ``--replay`` step (made again by the protocol's own step from the
stored step before, with its jiggle, one thread; the result equals the stored one to the
printed energy): per minimization of the step, in order, with its c0 (from the jiggled start;
with the c0 cycle, its zero-curvature stage and the return): its iterations, after how many
accepted steps (relaxation, quasi-Newton and Newton) it came within ``1e-5`` and ``1e-7`` of
its final energy (relative), the turn of the dent's axis from its start to its end (in ``h``),
and for every minimization after the first at the first one's c0 how far it ended from where
the first did (the largest vertex distance, in ``h``, and the energy difference). Then where
the first minimization moves the shell: the rms and largest vertex displacement (in ``h``),
the share of the squared displacement in bands of the material angle from the dent axis, how
far the dent's rim advanced and its depth grew (in ``h``, :func:`shellbuckle.analysis.classify`),
and the turn about the dent axis that best maps the moving start vertices onto the end
surface (0: the wrinkle pattern does not turn). No timing is printed (``bench_scaling.py``
times steps).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402

import numpy as np  # noqa: E402

from shellbuckle.analysis.classify import analyze_run, classify, is_current  # noqa: E402
from shellbuckle.locate import StepFromStored  # noqa: E402
from shellbuckle.protocol import deflate as protocol_mod  # noqa: E402
from shellbuckle.run import Run  # noqa: E402
from shellbuckle.solve.linesearch import max_displacement, mean_edge_length  # noqa: E402
from shellbuckle.studies.refinement import material_dent_axis  # noqa: E402


def dent_axis(X0: np.ndarray, X: np.ndarray) -> np.ndarray:
    """The unit vector to the dent in the material (the refinement study's measure)."""
    return material_dent_axis(X0, X)


def turn(a: np.ndarray, b: np.ndarray) -> float:
    """The angle between two unit vectors, in radians."""
    return float(np.arccos(np.clip(a @ b, -1.0, 1.0)))


def slides(run: Run, h: float) -> list[str]:
    """The first table: every stored step after the primary buckling."""
    table = run.table.set_index("step")
    analysis = run.store.analysis()
    missing = [k for k in run.steps if not is_current(analysis.get(k))]
    if missing:  # a run made with --no-locate and never analysed
        analyze_run(run, steps=missing)
        analysis = run.store.analysis()
    shapes = {int(k): str(a["shape"]) for k, a in analysis.items()}
    buckled = next((k for k in table.index if shapes.get(k, "sphere") != "sphere"), None)
    if buckled is None:
        return ["the run stays a sphere: no dent to follow"]
    lines = [f"{'step':>5} {'dV/V':>7} {'iterations':>10} {'shape':>10} {'turn deg':>9} "
             f"{'turn h':>7}"]
    X0, radius = run.store.X0, float(run.params.R)
    previous = dent_axis(X0, run.positions(buckled))
    quiet, moved = [], []
    for k in table.index[table.index > buckled]:
        axis = dent_axis(X0, run.positions(k))
        angle = turn(previous, axis)
        previous = axis
        iterations = int(table.loc[k, "iterations"])
        arc = angle * radius / h  # the arc swept at radius R, in mean edges
        (moved if arc >= 1.0 else quiet).append(iterations)
        lines.append(f"{k:5d} {table.loc[k, 'dV_over_V']:7.3f} {iterations:10d} "
                     f"{shapes.get(k, '?'):>10} {np.degrees(angle):9.2f} {arc:7.2f}")
    for name, group in (("dent stays (turn < 1 h)", quiet), ("dent slides (turn >= 1 h)", moved)):
        if group:
            lines.append(f"{name}: {len(group)} steps, {np.mean(group):.0f} iterations per step "
                         f"({sum(group)} in all)")
    return lines


#: Bands of the material angle from the dent axis, degrees.
BANDS = (0, 30, 60, 90, 180)


def where(run: Run, start: np.ndarray, end: np.ndarray, h: float) -> list[str]:
    """Where a minimization from ``start`` to ``end`` moves the shell (module docstring)."""
    from scipy.spatial import cKDTree

    from shellbuckle.protocol.imperfection import reference_directions

    move = np.linalg.norm(end - start, axis=1)
    if not (move > 0.1 * h).any():
        return [f"  the first minimization moves no vertex by more than 0.1 h (at most "
                f"{move.max() / h:.2g} h)"]
    a, b = classify(start, run.faces), classify(end, run.faces)
    axis = dent_axis(run.store.X0, end)
    angle = np.degrees(np.arccos(np.clip(reference_directions(run.store.X0) @ axis, -1, 1)))
    share = np.histogram(angle, bins=BANDS, weights=move ** 2)[0] / (move ** 2).sum()
    bands = ", ".join(f"{lo}-{hi} deg {100 * f:.0f} %"
                      for lo, hi, f in zip(BANDS[:-1], BANDS[1:], share))
    lines = [f"  the first minimization moves vertices by {np.sqrt((move ** 2).mean()) / h:.2f} h "
             f"rms, {move.max() / h:.2f} h at most; squared displacement by angle from the "
             f"dent axis: {bands}"]
    if np.isfinite([a.rim_radius, b.rim_radius, a.dent_depth, b.dent_depth]).all():
        lines.append(f"  rim radius {a.rim_radius:.4f} -> {b.rim_radius:.4f} "
                     f"({(b.rim_radius - a.rim_radius) / h:+.2f} h), dent depth "
                     f"{a.dent_depth:.4f} -> {b.dent_depth:.4f} "
                     f"({(b.dent_depth - a.dent_depth) / h:+.2f} h)")
    moving = move > 0.1 * h
    centre, tree = end.mean(axis=0), cKDTree(end)
    space_axis = np.asarray(b.dent_axis if b.dent_axis is not None else axis, dtype=float)
    K = np.cross(np.eye(3), space_axis / np.linalg.norm(space_axis))  # K @ v = axis x v
    turns = np.radians(np.arange(-10.0, 10.01, 0.5))
    gaps = [tree.query((start[moving] - centre) @ (np.eye(3) + np.sin(t) * K
                                                   + (1 - np.cos(t)) * K @ K).T + centre)[0].mean()
            for t in turns]
    best = np.degrees(turns[int(np.argmin(gaps))])
    lines.append(f"  best turn about the dent axis {best:+.1f} deg (moving vertices' mean gap to "
                 f"the end surface {min(gaps) / h:.3f} h; unturned {gaps[len(turns) // 2] / h:.3f}"
                 " h)")
    return lines


def replay(run: Run, k: int, h: float) -> list[str]:
    """The second table for step ``k``: each minimization of the step made again."""
    results = []
    inner = protocol_mod.minimize

    def keeping(*args, **kwargs):  # the protocol's minimization, with its history kept
        kwargs["history"] = True
        result = inner(*args, **kwargs)
        results.append((args[0], args[2], result))
        return result

    protocol_mod.minimize = keeping
    try:
        step_to = StepFromStored(run, k)
        state, record = step_to(float(run.protocol.schedule[k - 1]))
    finally:
        protocol_mod.minimize = inner
    stored = float(run.store.record(k)["E_total"])
    X0 = run.store.X0
    lines = [f"step {k}: E {record['E_total']:.12g} (stored {stored:.12g}), "
             f"{record['iterations']} iterations, {classify(state.X, run.faces).shape}"]
    first = results[0][2]
    first_energy, radius = first.fun, float(run.params.R)
    for i, (energy, start, result) in enumerate(results):
        E = np.array([r["energy"] for r in result.history or []] + [result.fun])
        within = [int(np.argmax(np.abs(E - result.fun) <= rel * abs(result.fun)))
                  for rel in (1e-5, 1e-7)]
        c0 = getattr(energy, "c0", float("nan"))
        line = (f"  c0 = {c0:<5g} {result.nit:5d} iterations, within 1e-5 after {within[0]:4d}, "
                f"1e-7 after {within[1]:4d}; axis turned "
                f"{turn(dent_axis(X0, start), dent_axis(X0, result.x)) * radius / h:5.2f} h")
        if i > 0 and c0 == getattr(results[0][0], "c0", None):
            line += (f"; ends {max_displacement(result.x - first.x) / h:.1e} h from the first "
                     f"minimum, energy {(result.fun - first_energy) / abs(first_energy):+.1e} "
                     f"relative")
        lines.append(line)
    return lines + where(run, results[0][1], first.x, h)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", help="a stored deflation run folder")
    parser.add_argument("--replay", default="", help="comma-separated steps to make again")
    args = parser.parse_args(argv)
    run = Run.of(args.run)
    h = mean_edge_length(run.faces, run.store.X0)  # in the run's units of length
    print(f"{run.path}: {len(run.store.X0)} vertices, mean edge h = "
          f"{h / float(run.params.R):.4f} R")
    for line in slides(run, h):
        print(line)
    for k in (int(s) for s in args.replay.split(",") if s.strip()):
        for line in replay(run, k, h):
            print(line)


if __name__ == "__main__":
    main()
