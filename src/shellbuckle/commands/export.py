"""``shellbuckle export DIR --step K --format FMT [--out PATH]``: one step as a mesh file;
``shellbuckle export DIR --format xdmf [--out PATH]``: every stored step as one time series."""

from __future__ import annotations

from pathlib import Path

from ._checks import add_command, add_number, output_file, run_folder, the_work
from ._options import stored_step


def register(sub) -> None:
    parser = add_command(
        sub, "export", help="export one step of a run to VTK, VTU, PLY, OBJ, STL or Surface "
                            "Evolver, or the whole run to XDMF",
        description="Write step K of the run folder DIR as a mesh file: vtk or vtu (ParaView; "
                    "point data H, displacement from the initial sphere and bending energy "
                    "density, cell data stretching energy density; vtu also the run's "
                    "parameters and the step's dV/V, pressure and energies as field data), ply "
                    "(scalar point data), obj, stl (geometry only), or fe: a Surface Evolver "
                    "datafile with the run's moduli, c0, the initial sphere's rest metrics "
                    "(form_factors) and the step's volume as the body's target, which Surface "
                    "Evolver loads and can continue from with the same energy. --format xdmf "
                    "(no --step) writes every stored step as one time series, an XDMF file and "
                    "its HDF5 data (.h5 beside it) that ParaView opens and meshio's "
                    "TimeSeriesReader reads: the time is the step number, each step with its "
                    "positions, the vtu fields and its table values.")
    parser.add_argument("dir", metavar="DIR", help="run folder")
    add_number(parser, "--step", "step", "stored step number (negative counts from the last: "
               "-1 is the last); required except with --format xdmf", metavar="K")
    parser.add_argument("--format", required=True, metavar="FMT", dest="fmt",
                        help="one of vtk, vtu, ply, obj, stl, fe (one step) or xdmf (every step)")
    parser.add_argument("--out", metavar="PATH",
                        help="file to write (default <run folder name>_step<K>.<FMT> here, or "
                             "<run folder name>.xdmf and .h5 for xdmf)")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from ..export import (FORMATS, SERIES_FORMATS, default_export_path, export_step,
                          format_of)

    fmt = args.fmt.lower().lstrip(".")
    if fmt not in FORMATS and fmt not in SERIES_FORMATS:
        raise ValueError(f"--format {args.fmt!r} is not supported; allowed: "
                         f"{', '.join(list(FORMATS) + list(SERIES_FORMATS))}")
    if fmt in SERIES_FORMATS:
        return _series(args, fmt)
    if args.step is None:
        raise ValueError(f"--step is required with --format {fmt} (one step per file; "
                         "--format xdmf writes every step)")
    run = run_folder("DIR", args.dir)
    step = stored_step(run, args.step)
    out = args.out if args.out else default_export_path(run, step, fmt)
    output_file("--out", out)
    try:  # the extension of --out: the export's own rule, before the work
        format_of(Path(out), fmt)
    except ValueError as exc:
        raise ValueError(f"--out {out}: {exc}") from None
    with the_work():
        path = export_step(run, step, out, fmt=fmt)
    print(f"step {step} of {run.path} written to {path}")
    return 0


def _series(args, fmt: str) -> int:
    from ..export import SERIES_FORMATS, default_series_path, export_series

    if args.step is not None:
        raise ValueError(f"--step {args.step}: not used with --format {fmt}, which writes "
                         "every stored step")
    run = run_folder("DIR", args.dir)
    if not run.steps:
        raise ValueError(f"DIR {args.dir}: holds a run with no finished step yet")
    out = args.out if args.out else default_series_path(run, fmt)
    output_file("--out", out, suffixes=(SERIES_FORMATS[fmt],), beside=(".h5",))
    with the_work():
        path = export_series(run, out, fmt=fmt)
    print(f"{len(run.steps)} steps of {run.path} written to {path} and "
          f"{path.with_suffix('.h5')}")
    return 0
