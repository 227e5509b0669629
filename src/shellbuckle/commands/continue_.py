"""``shellbuckle continue DIR --step K --gamma [G0:]G1 --increments N``: a path in gamma or c0.

Follows a path in the Foppl-von Karman number gamma (equal ratios) or in the spontaneous
curvature c0 (equal differences) at the fixed enclosed volume of step K of the run in DIR,
with the deflation protocol's jiggle, minimizer and c0 cycle at every increment
(:func:`shellbuckle.run.continue_in_parameter`). ``--then-deflate-to DV`` continues the end of
the path in volume (:func:`shellbuckle.run.continue_from`); ``--compare DIR2`` puts the last
conformation next to a step of another run (:func:`shellbuckle.run.compare_paths`), e.g. the
paper's Fig. 11: a capsule taken from gamma = 2333 to 15163 against the wrinkled bowl of
progressive deflation at gamma = 15163.
"""

from __future__ import annotations

import json
from pathlib import Path


def register(sub) -> None:
    parser = sub.add_parser(
        "continue", help="follow a path in gamma or c0 at fixed volume from a stored step",
        description="Start from step K of the run in DIR and change gamma (in equal ratios) or "
                    "the spontaneous curvature c0 (c = c1 + c2, in equal differences) in N "
                    "increments, minimizing at the enclosed volume of step K at each one with "
                    "the run's protocol (jiggle, minimizer, zero-curvature cycle). Each "
                    "increment is one stored step of a new run in --out (resumable: run the "
                    "same command again). Example (the paper's Fig. 11): "
                    "shellbuckle continue runs/g2333 --step 34 --gamma 15163 --increments 8 "
                    "--out runs/g2333_to_15163 --compare runs/g15163")
    parser.add_argument("dir", metavar="DIR", help="run folder to start from")
    parser.add_argument("--step", type=int, default=-1,
                        help="the step of DIR to start from (default: the last; negative "
                             "values count from the last)")
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--gamma", metavar="[G0:]G1 | G1,G2,..",
                      help="gamma to reach (G0, if given, must be the step's gamma), or the "
                           "list of values, one per increment")
    what.add_argument("--c0", metavar="[C0:]C1 | C1,C2,..",
                      help="spontaneous curvature to reach (c = c1 + c2; the stress-free "
                           "sphere has 2/R), or the list of values")
    parser.add_argument("--increments", type=int,
                        help="number of increments to the target (required with a target, "
                             "0 stores the start only)")
    proto = parser.add_argument_group("protocol (default: the run's)")
    proto.add_argument("--no-c0-cycle", action="store_true",
                       help="skip the zero-spontaneous-curvature cycle at each increment")
    proto.add_argument("--temperature", type=float,
                       help="jiggle temperature on Surface Evolver's scale (std 0.28 T x size)")
    proto.add_argument("--jiggle", type=float,
                       help="jiggle amplitude as a fraction of the mean edge length")
    proto.add_argument("--seed", type=int, help="seed of the jiggle (default: the run's)")
    proto.add_argument("--method", choices=["newton", "alternate", "cg", "gd"],
                       help="minimizer (default: the run's)")
    then = parser.add_argument_group("afterwards")
    then.add_argument("--then-deflate-to", type=float, metavar="DV",
                      help="continue the end of the path in volume up to dV/V = DV (steps of "
                           "--dv; a smaller DV re-inflates)")
    then.add_argument("--dv", type=float, default=0.019,
                      help="volume step of --then-deflate-to (default 0.019)")
    then.add_argument("--then-out", metavar="DIR2",
                      help="run folder of --then-deflate-to (default: OUT_deflated)")
    then.add_argument("--compare", metavar="RUN",
                      help="compare the last conformation with a step of the run folder RUN")
    then.add_argument("--compare-step", type=int,
                      help="the step of --compare (default: the step whose dV/V is closest)")
    then.add_argument("--json", action="store_true", help="print the comparison as JSON")
    parser.add_argument("--out", required=True, metavar="OUT", help="run folder of the path")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=_cmd)


def _values(option: str, text: str, start: float):
    """A target (float), or a list of values; ``A:B`` checks that ``A`` is the start."""
    try:
        if "," in text:
            return [float(x) for x in text.split(",") if x.strip()]
        if ":" in text:
            first, last = (float(x) for x in text.split(":", 1))
            if abs(first - start) > 1e-6 * max(abs(start), 1.0):
                raise ValueError(f"{option} {text}: the path starts at the step's value "
                                 f"{start:.10g}, not {first:.10g}; give {option} "
                                 f"{start:.10g}:{last:g} or just {last:g}")
            return last
        return float(text)
    except ValueError as exc:
        if "starts at" in str(exc):
            raise
        raise ValueError(f"{option} must be a number, START:END or a comma-separated list of "
                         f"numbers, got {text!r}") from None


def _cmd(args) -> int:
    from ..run import Run, continue_from, continue_in_parameter

    parent = Run.open(args.dir)
    step = parent.step(args.step)
    options = {"c0_cycle": False} if args.no_c0_cycle else {}
    for name in ("temperature", "jiggle", "seed", "method"):
        if getattr(args, name) is not None:
            options[name] = getattr(args, name)
    if args.gamma is not None:
        value = _values("--gamma", args.gamma, parent.params_at(step).gamma)
        kind = {"gamma": value}
    else:
        value = _values("--c0", args.c0, parent.c0_at(step))
        kind = {"c0": value}
    increments = args.increments
    if isinstance(value, float) and increments is None:
        raise ValueError("a target value needs --increments N (e.g. --increments 8)")
    if isinstance(value, list) and increments is not None:
        raise ValueError("--increments goes with a target value, not with a list of values")
    run = continue_in_parameter(parent, step, args.out, increments=increments,
                                progress=not args.quiet, **kind, **options)
    _summary(run)
    last = run
    if args.then_deflate_to is not None:
        start = float(run.table["dV_over_V"].iloc[-1])
        dv = abs(args.dv) if args.then_deflate_to > start else -abs(args.dv)
        out = Path(args.then_out) if args.then_out else Path(f"{Path(args.out)}_deflated")
        last = continue_from(run, -1, out, dv=dv, until=args.then_deflate_to,
                             progress=not args.quiet)
        _summary(last)
    if args.compare is not None:
        _compare(last, Run.open(args.compare), args.compare_step, args.json)
    return 0


def _summary(run) -> None:
    table = run.table
    row = table.iloc[-1]
    gamma = run.params_at(-1).gamma
    print(f"run folder: {run.path}")
    print(f"status: {run.status} ({run.store.meta.get('message')})")
    print(f"steps: {int(row['step'])}, gamma = {gamma:.6g}, c0 = {run.c0_at(-1):.6g}, "
          f"dV/V = {row['dV_over_V']:.4f}, E/kappa = {row['E_over_kappa']:.6g}")


def _compare(run, other, other_step, as_json: bool) -> None:
    from ..cli import _json_safe
    from ..run import compare_paths

    if other_step is None:
        target = float(run.table["dV_over_V"].iloc[-1])
        table = other.table
        other_step = int(table["step"].iloc[(table["dV_over_V"] - target).abs().argmin()])
    result = compare_paths(run, -1, other, other_step)
    if as_json:
        print(json.dumps(_json_safe(result), indent=1))
        return
    for key in ("a", "b"):
        side = result[key]
        print(f"{key}: {side['path']} step {side['step']}: gamma = {side['gamma']:.6g}, "
              f"dV/V = {side['dV_over_V']:.4f}, E/kappa = {side['E_over_kappa']:.6g} "
              f"(bend {side['E_bend']:.6g}, stretch {side['E_stretch']:.6g}), "
              f"shape {side['shape']}, W = {side['W']}")
    print(f"E_b / E_a = {result['ratio']:.4f}"
          + ("" if result["same_parameters"] else
             "  (not the same parameters: " + "; ".join(result["differences"]) + ")"))
