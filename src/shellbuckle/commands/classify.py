"""``shellbuckle classify FILE [--step K] [--json]``: the class of one conformation."""

from __future__ import annotations

from ._checks import add_command, add_number, input_file, run_folder, the_work
from ._options import stored_step


def register(sub) -> None:
    parser = add_command(
        sub, "classify", help="classify one conformation: sphere, dimples, capsule, polygonal, wrinkled",
        description="Classify the conformation in FILE, a closed triangulated surface in any "
                    "supported mesh format (.fe/.dmp Surface Evolver, or a meshio format: "
                    ".vtk .vtu .xdmf .msh .ply .obj .off .stl .mesh .inp), or a step of a run "
                    "folder (FILE = DIR, with --step K; default the last step). Prints the shape "
                    "(sphere, dimples, capsule, polygonal, wrinkled, other), the number of "
                    "dimples, corners and wrinkles W, the dent's depth, sagitta and axis, the "
                    "rim radius and its strongest Fourier modes. Lengths in the file's units.")
    parser.add_argument("file", metavar="FILE", help="mesh file, or run folder with --step")
    add_number(parser, "--step", "step", "step of a run folder (negative counts from the last; "
               "default -1)", metavar="K")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object (with all the descriptors)")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from ..analysis import classify

    X, faces, source = _conformation(args.file, args.step)
    with the_work():
        c = classify(X, faces)
    if args.json:
        from ._output import print_json

        return print_json({"source": source, **c.as_dict()})
    _print(source, len(X), c)
    return 0


def _conformation(name: str, step):
    """Positions, faces and a label of step ``step`` of a run folder, or of a mesh file."""
    from pathlib import Path

    path = Path(name)
    if path.is_dir():
        run = run_folder("FILE", path)
        k = stored_step(run, -1 if step is None else step)
        return run.positions(k), run.faces, f"{path} step {k}"
    if step is not None:
        raise ValueError("--step applies to a run folder, not to a mesh file")
    input_file("FILE", path)
    from ..mesh.io import read_mesh

    mesh = read_mesh(path)
    return mesh.X, mesh.faces, str(path)


def _print(source: str, n_vertices: int, c) -> None:
    print(f"{source}: {n_vertices} vertices")
    print(f"  shape       {c.shape}")
    print(f"  n_dimples   {c.n_dimples}")
    print(f"  corners     {c.corners}")
    print(f"  W           {c.W}")
    if not getattr(c, "count_resolved", True):
        print("  count       not resolved: the rim's corners are closer than the mesh "
              "resolves (docs/analysis.md, Resolution)")
    if c.dent_axis is not None:
        axis = ", ".join(f"{v:+.4f}" for v in c.dent_axis)
        print(f"  dent depth  {c.dent_depth:.6g}   (indentation along the axis; sagitta below "
              f"the crest {c.dent_sagitta:.6g})")
        print(f"  dent axis   ({axis})   (unit, pointing out of the dent)")
    if c.rim_spectrum is not None:
        top = sorted(range(2, len(c.rim_spectrum) + 1), key=lambda m: -c.rim_spectrum[m - 1])[:3]
        modes = ", ".join(f"m={m}: {c.rim_spectrum[m - 1]:.4f}" for m in top)
        print(f"  rim radius  {c.rim_radius:.6g}   (outline of the depression; strongest modes "
              f"{modes}; axisymmetric below {c.axisymmetry_threshold:.4f})")
        print(f"  crest radius {c.crest_radius:.6g}   (the ridge around the dent)")
    print(f"  asphericity {c.asphericity:.6g}")
    if c.contact_distance == c.contact_distance:
        print(f"  self-contact distance {c.contact_distance:.6g}")
