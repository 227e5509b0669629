"""Pool the results of ``bench_evolver.py`` on several meshes (or jiggle seeds) into one table.

After buckling, which dent forms, where, and how far it slides before it settles depends on
round-off-level details of each code's path, so the time either code takes for the steps after
buckling is a random variable of the mesh (Surface Evolver's own buckling step took 18 to 93 s
on four meshes of the same size). One mesh's time ratio is one draw; this script reports the
ratio per mesh and pooled (total Evolver CPU time over total shellbuckle CPU time).

Run from the repository root, for example:

    for s in 0 1 2 3; do
        python benchmarks/bench_evolver.py --vertices 3594 --steps 13 --c0-cycle --seed $s \\
            --json benchmarks/results/evolver_3594_seed$s.json
    done
    python benchmarks/evolver_seeds.py benchmarks/results/evolver_3594_seed*.json

For each file: the mesh seed, the step at which each code's pressure first fell (primary
buckling; ``-`` if it did not), the CPU time of each side over the steps
before that step and from it on, the whole-process CPU times (Evolver's process includes
reading the datafile; ours is the ``deflate`` call, set-up included, the mean of the runs of
``--ours-runs``), their ratio, the machine's reference step, and the CPU time of each run of
ours (one before and one after Evolver's by default). Files written with ``--to-tolerance``
also give Evolver's time to shellbuckle's tolerance (``bench_evolver.time_to_tolerance``), per
file, before and after buckling, and pooled, with the relaxes that never passed the test; their
whole-process time leaves out the time Evolver spent recording its iterates.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
from pathlib import Path


def _buckling_step(rows, side: str) -> int | None:
    """First step whose pressure is below the previous step's, on one side (primary
    buckling, as in bench_deflation.py)."""
    for previous, row in zip(rows, rows[1:]):
        if row[f"p_{side}"] < previous[f"p_{side}"]:
            return row["step"]
    return None


def summarize(path: Path) -> dict:
    data = json.loads(path.read_text())
    rows = data["steps"]
    buckled = [s for s in (_buckling_step(rows, "SE"), _buckling_step(rows, "ours")) if s]
    split = min(buckled) if buckled else len(rows) + 1
    before = [r for r in rows if r["step"] < split]
    after = [r for r in rows if r["step"] >= split]
    tol = data.get("to_tolerance")
    excluded = tol["excluded_s"] if tol else 0.0
    return {
        "tol_SE": tol["process_cpu_s"] if tol else None,
        "tol_before_SE": sum(r["cpu_SE_tol"] for r in before) if tol else None,
        "tol_after_SE": sum(r["cpu_SE_tol"] for r in after) if tol else None,
        "tol_missed": tol["missed"] if tol else [],
        "file": path.name, "seed": data.get("seed"), "jiggle_seed": data.get("jiggle_seed"),
        "steps": len(rows), "buckle_SE": _buckling_step(rows, "SE"),
        "buckle_ours": _buckling_step(rows, "ours"),
        "before_SE": sum(r["cpu_SE"] for r in before), "before_ours": sum(r["cpu_ours"] for r in before),
        "after_SE": sum(r["cpu_SE"] for r in after), "after_ours": sum(r["cpu_ours"] for r in after),
        "cpu_SE": data["evolver_process_cpu_s"] - excluded, "cpu_ours": data["ours_total_cpu_s"],
        "step_ms": (data.get("reference_workload_ms") or {}).get("step_ms", math.nan),
        "runs_ours": data.get("ours_runs_cpu_s") or [data["ours_total_cpu_s"]],
    }


def pooled(rows, total: str, before: str, after: str) -> str:
    """The pooled CPU ratio of ``rows`` with Evolver's time taken from the keys ``total``
    (whole run), ``before`` and ``after`` (the steps before buckling and from it on), the
    range and median of the per-run ratios, and the ratios before and after buckling."""
    total_se, total_us = sum(r[total] for r in rows), sum(r["cpu_ours"] for r in rows)
    ratios = [r[total] / r["cpu_ours"] for r in rows]
    ratio_before = sum(r[before] for r in rows) / sum(r["before_ours"] for r in rows)
    after_us = sum(r["after_ours"] for r in rows)
    ratio_after = sum(r[after] for r in rows) / after_us if after_us else math.nan
    return (f"pooled CPU ratio {total_se / total_us:.1f} (Evolver {total_se:.1f} s, shellbuckle "
            f"{total_us:.2f} s); per run {min(ratios):.1f} to {max(ratios):.1f}, median "
            f"{statistics.median(ratios):.1f}; before buckling {ratio_before:.1f}, from the "
            f"buckling step on {ratio_after:.1f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="+", type=Path, help="JSON files written by bench_evolver.py --json")
    args = ap.parse_args(argv)
    missing = [str(f) for f in args.files if not f.is_file()]
    if missing:
        raise SystemExit(f"no such file: {', '.join(missing)}")
    rows = [summarize(f) for f in args.files]
    print(f"{'file':<34} {'seed':>4} {'buckle SE/us':>12} {'before SE':>9} {'before us':>9} "
          f"{'after SE':>8} {'after us':>8} {'cpu SE':>7} {'cpu us':>6} {'ratio':>6} "
          f"{'ref step ms':>11} {'runs us':>11}")
    for r in rows:
        buckle = f"{r['buckle_SE'] or '-'}/{r['buckle_ours'] or '-'}"
        print(f"{r['file']:<34} {r['seed']!s:>4} {buckle:>12} {r['before_SE']:>9.1f} "
              f"{r['before_ours']:>9.2f} {r['after_SE']:>8.1f} {r['after_ours']:>8.2f} "
              f"{r['cpu_SE']:>7.1f} {r['cpu_ours']:>6.2f} {r['cpu_SE'] / r['cpu_ours']:>6.1f} "
              f"{r['step_ms']:>11.0f} {'/'.join(f'{t:.2f}' for t in r['runs_ours']):>11}")
    print(f"# {len(rows)} runs: " + pooled(rows, "cpu_SE", "before_SE", "after_SE"))
    tol = [r for r in rows if r["tol_SE"] is not None]
    if tol:
        # Evolver's time to shellbuckle's tolerance (bench_evolver.py --to-tolerance)
        print(f"{'file':<34} {'tol before SE':>13} {'tol after SE':>12} {'tol cpu SE':>10} "
              f"{'ratio':>6}  relaxes that never passed (step.relax)")
        for r in tol:
            print(f"{r['file']:<34} {r['tol_before_SE']:>13.1f} {r['tol_after_SE']:>12.1f} "
                  f"{r['tol_SE']:>10.1f} {r['tol_SE'] / r['cpu_ours']:>6.1f}  "
                  f"{', '.join(r['tol_missed']) or '-'}")
        print(f"# to shellbuckle's tolerance, {len(tol)} runs: "
              + pooled(tol, "tol_SE", "tol_before_SE", "tol_after_SE"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
