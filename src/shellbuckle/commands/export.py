"""``shellbuckle export DIR --step K --format FMT [--out PATH]``: one step as a mesh file."""

from __future__ import annotations

from ._checks import add_command, add_number, output_file, run_folder
from ._options import stored_step


def register(sub) -> None:
    parser = add_command(
        sub, "export", help="export one step of a run to VTK, VTU, PLY, OBJ, STL or Surface Evolver",
        description="Write step K of the run folder DIR as a mesh file: vtk or vtu (ParaView; "
                    "point data H, displacement from the initial sphere and bending energy "
                    "density, cell data stretching energy density), ply (scalar point data), "
                    "obj, stl (geometry only), or fe: a Surface Evolver datafile with the run's "
                    "moduli, c0, the initial sphere's rest metrics (form_factors) and the step's "
                    "volume as the body's target, which Surface Evolver loads and can continue "
                    "from with the same energy.")
    parser.add_argument("dir", metavar="DIR", help="run folder")
    add_number(parser, "--step", "step", "stored step number (negative counts from the last: "
               "-1 is the last)", required=True, metavar="K")
    parser.add_argument("--format", required=True, metavar="FMT", dest="fmt",
                        help="one of vtk, vtu, ply, obj, stl, fe")
    parser.add_argument("--out", metavar="PATH",
                        help="file to write (default <run folder name>_step<K>.<FMT> here)")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from ..export import FORMATS, default_export_path, export_step

    fmt = args.fmt.lower().lstrip(".")
    if fmt not in FORMATS:
        raise ValueError(f"--format {args.fmt!r} is not supported; allowed: {', '.join(FORMATS)}")
    run = run_folder("DIR", args.dir)
    step = stored_step(run, args.step)
    out = args.out if args.out else default_export_path(run, step, fmt)
    output_file("--out", out)
    path = export_step(run, step, out, fmt=fmt)
    print(f"step {step} of {run.path} written to {path}")
    return 0
