"""``shellbuckle continue DIR --step K``: a new run from a stored step, along a volume path or
a path in gamma or c0.

- Volume path, ``--dv/--until`` or ``--schedule`` (:func:`shellbuckle.run.continue_from`):
  deflate further or re-inflate (``--dv -0.019``) from step K, with the stored run's reference
  sphere, parameters and protocol; ``shellbuckle deflate --from DIR --step K`` is another
  spelling of it.
- Parameter path, ``--gamma [G0:]G1`` or ``--c0 [C0:]C1`` with ``--increments N``
  (:func:`shellbuckle.run.continue_in_parameter`): gamma in equal ratios or the spontaneous
  curvature c0 in equal differences at the fixed enclosed volume of step K, with the
  deflation protocol's jiggle, minimizer and c0 cycle at every increment;
  ``--then-deflate-to DV`` continues the end of the path in volume.

``--compare DIR2`` puts the last conformation next to a step of another run
(:func:`shellbuckle.run.compare_paths`), e.g. the paper's Fig. 11: a capsule taken from
gamma = 2333 to 15163 against the wrinkled bowl of progressive deflation at gamma = 15163.
Protocol options left out keep the stored run's values.
"""

from __future__ import annotations

from pathlib import Path

from ._checks import (RANGES, add_command, add_number, check_c0, check_mesh, check_steps,
                      check_value, floats, output_folder, run_folder, typed)
from ._options import (add_protocol_options, add_run_output_options, protocol_defaults,
                       protocol_values, stored_step)

#: Protocol options a continued run takes from the stored run unless given.
INHERITED = ("seed", "c0_cycle", "temperature", "jiggle", "method", "max_iter", "prerelax",
             "direct_return", "rescale_start")


def register(sub) -> None:
    parser = add_command(
        sub, "continue", help="continue from a stored step: in volume, or along a path in gamma "
                         "or c0 at fixed volume",
        description="Start a new run in --out from step K of the run in DIR, with its "
                    "reference sphere, parameters and protocol (options given replace them). "
                    "Either a volume path: --dv/--until or --schedule, e.g. --dv -0.019 "
                    "--until 0.2 re-inflates (`shellbuckle deflate --from DIR` is the same); "
                    "or a path in gamma (equal ratios) or in the spontaneous curvature c0 "
                    "(c = c1 + c2, equal differences) in N increments, minimizing at the "
                    "enclosed volume of step K at each one with the run's protocol (jiggle, "
                    "minimizer, zero-curvature cycle); each increment is one stored step. "
                    "Resumable: run the same command again. Example (the paper's Fig. 11): "
                    "shellbuckle continue runs/g2333 --step 34 --gamma 15163 --increments 8 "
                    "--out runs/g2333_to_15163 --compare runs/g15163")
    parser.add_argument("dir", metavar="DIR", help="run folder to start from")
    add_number(parser, "--step", "step", "the step of DIR to start from (default: the last; "
               "negative values count from the last)", default=-1)
    volume = parser.add_argument_group("a volume path (a negative --dv re-inflates)")
    add_protocol_options(volume, ("dv", "until", "schedule"), ranges={"dv": "dv_signed"})
    what = parser.add_argument_group("or a path in gamma or c0 at the volume of step K")
    exclusive = what.add_mutually_exclusive_group()
    exclusive.add_argument("--gamma", metavar="[G0:]G1 | G1,G2,..",
                           help="gamma to reach (G0, if given, must be the step's gamma), or "
                                "the list of values, one per increment")
    exclusive.add_argument("--c0", metavar="[C0:]C1 | C1,C2,..",
                           help="spontaneous curvature to reach (c = c1 + c2; the stress-free "
                                "sphere has 2/R), or the list of values")
    add_number(what, "--increments", "increments", "number of increments to the target "
               "(required with a target, 0 stores the start only)")
    add_number(what, "--then-deflate-to", "until", "continue the end of the path in volume up "
               "to dV/V = DV (steps of --dv; a smaller DV re-inflates)", metavar="DV")
    what.add_argument("--then-out", metavar="DIR2",
                      help="run folder of --then-deflate-to (default: OUT_deflated)")
    add_protocol_options(parser.add_argument_group("protocol (default: the run's)"), INHERITED,
                         inherited=True)
    then = parser.add_argument_group("afterwards")
    then.add_argument("--compare", metavar="RUN",
                      help="compare the last conformation with a step of the run folder RUN")
    add_number(then, "--compare-step", "step",
               "the step of --compare (default: the step whose dV/V is closest)")
    then.add_argument("--json", action="store_true", help="print the comparison as JSON")
    parser.add_argument("--out", required=True, metavar="OUT", help="run folder of the path")
    add_run_output_options(parser, plot="do not write the figures at the end of a volume path "
                           "or of --then-deflate-to (a path in gamma or c0 has none: dV/V "
                           "stays fixed along it)")
    parser.set_defaults(func=continue_run)


def continue_run(args) -> int:
    """``shellbuckle continue`` (and ``deflate --from``): a volume path or a parameter path
    from step ``args.step`` of the run in ``args.dir``, then the comparison if asked."""
    from ..run import Run
    from ._output import report_run

    parent = run_folder(getattr(args, "dir_option", "DIR"), args.dir)
    step = stored_step(parent, args.step)
    options = protocol_values(args, INHERITED)
    other = None
    if args.compare is not None:
        other = run_folder("--compare", args.compare)
        if args.compare_step is not None:
            stored_step(other, args.compare_step, "--compare-step")
    elif args.compare_step is not None:
        raise ValueError(f"--compare-step {args.compare_step}: goes with --compare RUN")
    output_folder("--out", args.out, run=True)
    if Path(args.out).resolve() == Path(parent.path).resolve():
        raise ValueError(f"--out {args.out}: is the run the path starts from; the path is a "
                         "new run in its own folder")
    if args.gamma is None and args.c0 is None:
        last = _volume_path(parent, step, args, options)
        report_run(last, plot=not args.no_plot)
    else:
        last = _parameter_path(parent, step, args, options)
    if other is not None:
        _compare(last, Run.open(args.compare), args.compare_step, args.json)
    return 0


def _volume_path(parent, step: int, args, options: dict):
    from ..protocol.schedule import steps_between
    from ..run import continue_from

    for flag in ("increments", "then_deflate_to", "then_out"):
        if getattr(args, flag) is not None:
            raise ValueError(f"--{flag.replace('_', '-')} goes with a path in --gamma or --c0; "
                             "a volume path ends at --until")
    schedule = floats("--schedule", args.schedule, "schedule") if args.schedule else None
    if schedule is not None:
        for name in ("dv", "until"):
            if getattr(args, name) is not None:
                raise ValueError(f"--{name} {typed(args, '--' + name, getattr(args, name))}: "
                                 "allowed: without --schedule, which lists the targets itself")
        check_steps("--schedule", args.schedule, len(schedule))
        return continue_from(parent, step, args.out, schedule=schedule,
                             progress=not args.quiet, **options)
    defaults = protocol_defaults()
    dv = defaults["dv"] if args.dv is None else args.dv
    until = defaults["until"] if args.until is None else args.until
    start = float(parent.table["dV_over_V"].iloc[step])
    if (until - start) * dv <= 0:
        raise ValueError(f"--until {typed(args, '--until', until)}: the path starts at "
                         f"dV/V = {start:.6g}; a step --dv {typed(args, '--dv', dv)} "
                         f"{'deflates' if dv > 0 else 're-inflates'}: allowed: --until "
                         f"{'above' if dv > 0 else 'below'} {start:.6g}")
    if not steps_between(start, until, dv):
        raise ValueError(f"--until {typed(args, '--until', until)}: the path starts at dV/V = "
                         f"{start:.6g}; allowed: at least one step --dv {typed(args, '--dv', dv)} "
                         "from it")
    check_steps("--dv", typed(args, "--dv", dv), abs(until - start) / abs(dv))
    return continue_from(parent, step, args.out,
                         dv=defaults["dv"] if args.dv is None else args.dv,
                         until=defaults["until"] if args.until is None else args.until,
                         progress=not args.quiet, **options)


def _parameter_path(parent, step: int, args, options: dict):
    from ..protocol.schedule import steps_between
    from ..run import continue_from, continue_in_parameter
    from ._output import report_run

    for flag in ("until", "schedule"):
        if getattr(args, flag) is not None:
            raise ValueError(f"--{flag} makes a volume path; a path in gamma or c0 goes on in "
                             "volume with --then-deflate-to")
    if args.dv is not None and args.then_deflate_to is None:
        raise ValueError("--dv with a path in gamma or c0 is the step of --then-deflate-to")
    params = parent.params_at(step)
    n_vertices = len(parent.store.X0)
    if args.gamma is not None:
        kind = {"gamma": _target("--gamma", args.gamma, params.gamma)}
    else:
        kind = {"c0": _target("--c0", args.c0, parent.c0_at(step))}
    value = next(iter(kind.values()))
    for target in value if isinstance(value, list) else [value]:
        if args.gamma is not None:
            check_value("--gamma", "gamma", target, args.gamma)
            check_mesh("--gamma", args.gamma, target, n_vertices,
                       gamma_effective=target / params.bending_factor,
                       mesh=f"the run in {args.dir}")
        else:
            check_value("--c0", "c0", target, args.c0)
            check_c0("--c0", args.c0, target, n_vertices, params.R)
    if isinstance(value, list):
        check_steps("--" + next(iter(kind)), args.gamma or args.c0, len(value))
    if isinstance(value, float) and args.increments is None:
        raise ValueError("a target value needs --increments N (e.g. --increments 8)")
    if isinstance(value, list) and args.increments is not None:
        raise ValueError("--increments goes with a target value, not with a list of values")
    then_out = None
    if args.then_deflate_to is not None:
        if args.then_out is not None and not args.then_out.strip():
            raise ValueError(f"--then-out {args.then_out!r}: an empty name; give a folder")
        then_out = Path(args.then_out) if args.then_out else Path(f"{Path(args.out)}_deflated")
        output_folder("--then-out", then_out, run=True)
        _then_out_free(then_out, Path(args.out), typed(args, "--then-out", then_out))
        start = float(parent.table["dV_over_V"].iloc[step])
        dv = abs(protocol_defaults()["dv"] if args.dv is None else args.dv)
        if not steps_between(start, args.then_deflate_to,
                             dv if args.then_deflate_to > start else -dv):
            raise ValueError(f"--then-deflate-to {typed(args, '--then-deflate-to')}: the path "
                             f"is at dV/V = {start:.6g}; allowed: {RANGES['until']}, at least "
                             f"one step --dv {dv:g} from it")
        check_steps("--then-deflate-to", typed(args, "--then-deflate-to"),
                    abs(args.then_deflate_to - start) / dv)
    elif args.then_out is not None:
        raise ValueError(f"--then-out {args.then_out}: goes with --then-deflate-to DV")
    run = continue_in_parameter(parent, step, args.out, increments=args.increments,
                                progress=not args.quiet, **kind, **options)
    report_run(run)
    if args.then_deflate_to is None:
        return run
    start = float(run.table["dV_over_V"].iloc[-1])
    dv = abs(protocol_defaults()["dv"] if args.dv is None else args.dv)
    last = continue_from(run, -1, then_out, dv=dv if args.then_deflate_to > start else -dv,
                         until=args.then_deflate_to, progress=not args.quiet)
    report_run(last, plot=not args.no_plot)
    return last


def _then_out_free(then_out: Path, out: Path, text) -> None:
    """``--then-out``: not the path's own folder, and a run there only the second part of this
    same command (a branch of the run in ``out``, resumed), checked before the first part
    runs."""
    from ..store.names import RUN_JSON
    from ..store.run import RunStore

    if then_out.resolve() == out.resolve():
        raise ValueError(f"--then-out {text}: is the --out folder of the path; the deflation "
                         "after it needs its own folder")
    if not (then_out / RUN_JSON).is_file():
        return
    try:
        parent = (RunStore.open(then_out).parent or {}).get("path")
    except (ValueError, OSError, AttributeError):  # damaged: another run in any case
        parent = None
    if parent is None or Path(parent).resolve() != out.resolve():
        raise ValueError(f"--then-out {text}: holds another run (not the deflation after the "
                         f"path in {out}); choose another folder")


def _target(option: str, text: str, start: float):
    """A target (float), or a list of values; ``A:B`` checks that ``A`` is the start."""
    try:
        if "," in text:
            return [float(x) for x in text.split(",") if x.strip()] or [float("nan")]
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


def _compare(run, other, other_step, as_json: bool) -> None:
    from ..run import compare_paths
    from ._output import print_json

    if other_step is None:
        target = float(run.table["dV_over_V"].iloc[-1])
        table = other.table
        other_step = int(table["step"].iloc[(table["dV_over_V"] - target).abs().argmin()])
    result = compare_paths(run, -1, other, other_step)
    if as_json:
        print_json(result, indent=1)
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
