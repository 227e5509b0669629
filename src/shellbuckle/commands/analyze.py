"""``shellbuckle analyze DIR [--json] [--quiet]``: classify every step, print the events."""

from __future__ import annotations

import os

from ._checks import add_command, run_folder, the_work


def register(sub) -> None:
    parser = add_command(
        sub, "analyze", help="classify every step of a run, store the analysis columns, print events",
        description="Classify the conformation of every finished step of the run folder DIR "
                    "and store the analysis columns (shape, n_dimples, corners, W, dent_depth, "
                    "dent_sagitta, rim_radius, rim_mode, rim_amplitude, concave_arcs, "
                    "asphericity, contact_distance) in DIR/analysis.json and the table; then "
                    "print the buckling events: primary buckling, loss of axisymmetry, "
                    "wrinkles and changes of the Hessian inertia, with dV/V. Works on a run "
                    "that is still being computed.")
    parser.add_argument("dir", metavar="DIR", help="run folder")
    parser.add_argument("--json", action="store_true",
                        help="print the events as one JSON object instead of text")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from ..analysis import analyze_run, events
    from ..analysis.events import PRESSURE_DROP
    found = run_folder("DIR", args.dir, params=False)  # the stored shapes only
    if not os.access(found.path, os.W_OK):
        raise ValueError(f"DIR {args.dir}: the run folder is not writable (the analysis is "
                         "stored in it)")
    if not found.steps:
        raise ValueError(f"run folder {args.dir!r} has no finished step yet")
    with the_work():
        table = analyze_run(found, progress=not args.quiet)
        found_events = events(found, table=table)
    if args.json:
        from ._output import print_json

        return print_json({"run": str(found.path), "steps": len(table),
                           "events": [vars(e) for e in found_events]})
    print(f"{found.path}: steps {int(table['step'].iloc[0])}-{int(table['step'].iloc[-1])} "
          f"analysed, up to dV/V = {table['dV_over_V'].iloc[-1]:.4f}")
    counts = table["shape"].value_counts()
    print("  shapes: " + ", ".join(f"{name} {n}" for name, n in counts.items()))
    if not found_events:
        print("  no event (the shell stayed a sphere)" if table["shape"].iloc[0] == "sphere"
              else "  no event (the run starts buckled, as a branch of another run does, and "
                   "its class does not change for good)")
    at_step = dict(zip(table["step"].astype(int), table["dV_over_V"].astype(float)))
    for e in found_events:
        note = "" if e.confirmed is None else ("  [confirmed]" if e.confirmed else "  [unconfirmed]")
        print(f"  {e.name:<17} step {e.step:>4}  dV/V = {at_step.get(e.step, e.dV_over_V):.4f}"
              f"  {e.description}{note}")
    if any(e.confirmed is not None for e in found_events):
        print(f"  [confirmed]: at the primary buckling the pressure is at least "
              f"{100 * PRESSURE_DROP:.0f} % below the sphere branch's at that volume, as after "
              "a buckling; [unconfirmed]: the shape changed without it")
    return 0
