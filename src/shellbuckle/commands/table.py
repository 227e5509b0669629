"""``shellbuckle table DIR [--csv]``: the per-step table of a run (SPEC §7 columns)."""

from __future__ import annotations

import sys

from ._checks import add_command, run_folder


def register(sub) -> None:
    parser = add_command(
        sub, "table", help="print the per-step table of a run",
        description="Print the per-step table of the run folder DIR: one row per finished "
                    "step, columns step, target_dV_over_V, dV_over_V, E_total, E_bend, "
                    "E_stretch, E_over_kappa, E_before_c0_cycle, pressure, grad_norm, "
                    "iterations, inertia, min_distance, wall_s, then analysis columns.")
    parser.add_argument("dir", metavar="DIR", help="run folder")
    parser.add_argument("--csv", action="store_true",
                        help="print CSV (full precision) instead of aligned columns")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    store = run_folder("DIR", args.dir).store
    table = store.table()
    if args.csv:  # CSV stays plain for parsers; run.json holds the parameters
        sys.stdout.write(table.to_csv(index=False, lineterminator="\n"))
        return 0
    _header(store)
    if table.empty:
        sys.stdout.write("  ".join(table.columns) + "\n(no finished step yet)\n")
    else:
        import pandas as pd

        shown = pd.DataFrame({c: [_cell(v) for v in table[c].astype(object)]
                              for c in table.columns})
        sys.stdout.write(shown.to_string(index=False) + "\n")
    return 0


def _header(store) -> None:
    """``# gamma = ..., nu = ..., kappa = ..., energy convention ...``, when run.json says."""
    from ..params import ShellParameters, convention_formula

    try:
        p = ShellParameters.from_dict(store.params)
    except (ValueError, TypeError):
        return
    sys.stdout.write(
        f"# gamma = {p.gamma:.6g}, nu = {p.nu:.4g}, kappa = {p.kappa:.6g}, energy "
        f"convention {p.energy_convention} ({convention_formula(p.energy_convention)}"
        + (f"; the standard shell at gamma = {p.gamma_effective:.6g}"
           if p.energy_convention != "helfrich" else "")
        + "); energies in units of kappa\n")


def _cell(v) -> str:
    import pandas as pd

    if v is None or v is pd.NA or (isinstance(v, float) and v != v):
        return "-"
    return f"{v:.6g}" if isinstance(v, float) else str(v)
