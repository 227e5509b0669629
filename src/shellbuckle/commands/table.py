"""``shellbuckle table DIR [--columns a,b,c | --all] [--units reduced|si] [--csv]``: the
per-step table of a run (SPEC §7 columns).

Aligned text shows :data:`COMPACT` by default (the columns present; about 110 characters
wide), ``--csv`` every column by default (scripts read it); ``--columns`` picks stored columns
in the order given, ``--all`` every column. A value that does not exist (the inertia of step 0,
never computed) is ``-`` in the text and an empty cell in CSV. ``--units si`` prints the
dimensional columns of a run made from a material in J, Pa, m
(:func:`shellbuckle.store.table.table_in_units`).
"""

from __future__ import annotations

import sys

from ._checks import add_command, run_folder

#: The default columns of the aligned table, where present: the volume, the energy and its
#: split, the pressure, and whether the step is a certified minimum (iterations, converged,
#: inertia 0), then the shape and W once the run is analysed.
COMPACT = ("step", "dV_over_V", "E_over_kappa", "E_bend", "E_stretch", "pressure",
           "iterations", "converged", "inertia", "shape", "W")


def register(sub) -> None:
    parser = add_command(
        sub, "table", help="print the per-step table of a run",
        description="Print the per-step table of the run folder DIR, one row per finished "
                    "step. Aligned text shows by default " + ", ".join(COMPACT) + " (shape "
                    "and W after `shellbuckle analyze`); --csv prints every column by "
                    "default. The stored columns: step, target_dV_over_V, dV_over_V, E_total, "
                    "E_bend, E_stretch, E_over_kappa, E_before_c0_cycle, pressure, grad_norm, "
                    "iterations, inertia, min_distance, wall_s, then the analysis columns and "
                    "the other recorded values (self_intersecting, converged, c0, ...). A "
                    "value that does not exist (the inertia of step 0, not computed) is '-' "
                    "(empty in CSV).")
    parser.add_argument("dir", metavar="DIR", help="run folder")
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--columns", metavar="A,B,C",
                       help="the columns to print, comma-separated stored column names, in "
                            "this order (an unknown name is refused with the run's names)")
    which.add_argument("--all", action="store_true", help="print every column")
    parser.add_argument("--units", choices=("reduced", "si"), default="reduced",
                        help="reduced (default): energies in kappa, pressures in kappa/R^3, "
                             "lengths in R; si: energies in J, pressures in Pa, lengths in m, "
                             "for a run made from a material (--E --sigma --d --R, given in "
                             "Pa and m)")
    parser.add_argument("--csv", action="store_true",
                        help="print CSV (full precision) instead of aligned columns; every "
                             "column unless --columns")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    run = run_folder("DIR", args.dir, mesh=False)  # the table only: also of a lost mesh
    store = run.store
    from ..store.table import table_in_units

    params = run.params
    if args.units == "si" and not params.is_material:
        raise ValueError(f"--units si: the run {args.dir} has no material (--units si needs a "
                         "run made with --E --sigma --d --R)")
    table = store.table()
    columns = _columns(args, list(table.columns))
    table = table_in_units(table[columns], params, args.units)
    if args.units == "si":
        table = table.rename(columns=_si_label)
    if args.csv:  # CSV stays plain for parsers; run.json holds the parameters
        sys.stdout.write(table.to_csv(index=False, lineterminator="\n"))
        return 0
    _header(params, args.units)
    if table.empty:
        sys.stdout.write("  ".join(table.columns) + "\n(no finished step yet)\n")
    else:
        import pandas as pd

        shown = pd.DataFrame({c: [_cell(v) for v in table[c].astype(object)]
                              for c in table.columns})
        sys.stdout.write(shown.to_string(index=False) + "\n")
    return 0


def _columns(args, stored: list[str]) -> list[str]:
    """The columns to print: ``--columns`` (checked against ``stored``), ``--all``, or the
    default (every column for CSV, :data:`COMPACT` for text)."""
    if args.columns is None:
        if args.all or args.csv:
            return stored
        return [c for c in COMPACT if c in stored]
    names = [name.strip() for name in args.columns.split(",")]
    allowed = f"allowed: the run's columns {', '.join(stored)}"
    for name in names:
        if not name:
            raise ValueError(f"--columns {args.columns}: an empty name; {allowed}")
        if name not in stored:
            why = (" (the analysis columns appear after `shellbuckle analyze DIR`)"
                   if _analysis_column(name) else "")
            raise ValueError(f"--columns {args.columns}: no column {name!r} in this "
                             f"run{why}; {allowed}")
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        raise ValueError(f"--columns {args.columns}: {', '.join(twice)} named twice; "
                         f"{allowed}")
    return names


def _analysis_column(name: str) -> bool:
    from ..analysis.classify import RUN_COLUMNS

    return name in RUN_COLUMNS


def _si_label(column: str) -> str:
    """``E_bend [J]``: a dimensional column's name with its SI unit."""
    from ..params import UNITS
    from ..store.table import COLUMN_DIMENSIONS

    dimension = COLUMN_DIMENSIONS.get(column)
    return column if dimension is None else f"{column} [{UNITS[dimension][1]}]"


def _header(params, units: str) -> None:
    """Comment lines: ``# gamma = ..., nu = ..., energy convention ...``, the material when
    ``units`` is ``si``, and ``# units: ...``."""
    from ..params import convention_formula

    p = params
    lines = [f"gamma = {p.gamma:.6g}, nu = {p.nu:.4g}, energy convention {p.energy_convention} "
             f"({convention_formula(p.energy_convention)}"
             + (f"; the standard shell at gamma = {p.gamma_effective:.6g}"
                if p.energy_convention != "helfrich" else "") + ")"]
    if units == "si":
        lines += [f"material E = {p.E:.6g} Pa, sigma = {p.sigma:.4g}, d = {p.d:.6g} m, "
                  f"R = {p.R:.6g} m: kappa = E d^3/(12 (1 - sigma^2)) = {p.kappa:.6g} J",
                  "units: energies in J, pressures in Pa, lengths in m"]
    else:
        lines.append(f"units: energies in kappa = {p.kappa:.6g}, pressures in kappa/R^3, "
                     f"lengths in R = {p.R:.6g}")
    sys.stdout.write("".join(f"# {line}\n" for line in lines))


def _cell(v) -> str:
    import pandas as pd

    if v is None or v is pd.NA or (isinstance(v, float) and v != v):
        return "-"
    return f"{v:.6g}" if isinstance(v, float) else str(v)
