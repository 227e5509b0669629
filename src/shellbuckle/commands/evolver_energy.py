"""``shellbuckle evolver-energy FILE [--json]``: the energies of a Surface Evolver file."""

from __future__ import annotations

from ._checks import add_command, input_file


def register(sub) -> None:
    parser = add_command(
        sub, "evolver-energy", help="energies, volume and area of a Surface Evolver datafile or dump",
        description="Read a Surface Evolver datafile (.fe) or dump (.dmp) and print the "
                    "stretching (linear_elastic), bending (star_perp_sq_mean_curvature) and total "
                    "energies, the enclosed volume and the area of its configuration, computed "
                    "with the file's own moduli, h_zero, poisson_ratio and form_factors. The "
                    "file's 'read' section of commands is never executed.")
    parser.add_argument("file", metavar="FILE", help="Surface Evolver datafile or dump")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object with E_stretch, E_bend, E_total, volume, area")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    import json

    from ..energies.evolver import evolver_energy
    from ..mesh.evolver_io import read_evolver

    evf = read_evolver(input_file("FILE", args.file))
    result = evolver_energy(evf)
    if args.json:
        keys = ("E_stretch", "E_bend", "E_total", "volume", "area")
        print(json.dumps({k: result[k] for k in keys}))
        return 0
    _print_file(args.file, evf)
    rows = [("E_stretch", "linear_elastic"), ("E_bend", "star_perp_sq_mean_curvature"),
            ("E_total", "E_stretch + E_bend"), ("volume", "enclosed volume"),
            ("area", "total facet area")]
    for key, note in rows:
        print(f"  {key:<10} {result[key]:>24.17g}   {note}")
    if result["E_tension"]:
        print(f"  (facet surface tension energy {result['E_tension']:.17g} is not in E_total; "
              "Evolver's total_energy includes it)")
    for note in evf.skipped:
        print(f"  skipped: {note}")
    return 0


def _print_file(name, evf) -> None:
    """The file's mesh size, energy quantities and h_zero."""
    import numpy as np

    mesh = evf.mesh
    print(f"{name}: {mesh.n_vertices} vertices, {len(mesh.faces)} facets")
    for q in evf.quantities:
        print(f"  quantity {q.name} {q.kind} method {q.method} modulus {q.modulus:.17g}"
              + ("" if q.is_global else " (applied to some elements)"))
    if evf.h_zero is not None:
        h0 = np.asarray(evf.h_zero)
        print("  h_zero " + (f"{float(h0):.17g}" if h0.ndim == 0
                             else f"per vertex, {h0.min():.6g} .. {h0.max():.6g}"))
