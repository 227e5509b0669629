"""Command-line interface: a thin layer over the Python API.

Each sub-command parses its options, calls the API and reports. A ``ValueError`` (bad input)
becomes its message on stderr and exit code 2; any other failure during the work exits 1.
"""

from __future__ import annotations

import argparse
import logging
import sys


def _build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="shellbuckle",
        description="Buckling of thin elastic spherical shells under volume loss.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for register in [*_COMMANDS, *_command_modules()]:
        register(sub)
    return parser


def _command_modules():
    """``register`` of every module in ``shellbuckle.commands`` (one sub-command each)."""
    import importlib
    import pkgutil

    from shellbuckle import commands

    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda i: i.name):
        yield importlib.import_module(f"shellbuckle.commands.{info.name}").register


def _register_table(sub) -> None:
    """``shellbuckle table DIR [--csv]``: the per-step table of a run (SPEC §7 columns)."""
    parser = sub.add_parser(
        "table", help="print the per-step table of a run",
        description="Print the per-step table of the run folder DIR: one row per finished "
                    "step, columns step, target_dV_over_V, dV_over_V, E_total, E_bend, "
                    "E_stretch, E_over_kappa, E_before_c0_cycle, pressure, grad_norm, "
                    "iterations, inertia, min_distance, wall_s, then analysis columns.")
    parser.add_argument("dir", metavar="DIR", help="run folder")
    parser.add_argument("--csv", action="store_true",
                        help="print CSV (full precision) instead of aligned columns")

    def run(args) -> int:
        import pandas as pd

        from .store import RunStore

        store = RunStore.open(args.dir)
        table = store.table()
        if not args.csv:  # CSV stays plain for parsers; run.json holds the parameters
            from .params import ShellParameters, convention_formula

            try:
                p = ShellParameters.from_dict(store.params)
            except (ValueError, TypeError):
                p = None
            if p is not None:
                sys.stdout.write(
                    f"# gamma = {p.gamma:.6g}, nu = {p.nu:.4g}, kappa = {p.kappa:.6g}, energy "
                    f"convention {p.energy_convention} ({convention_formula(p.energy_convention)}"
                    + (f"; the standard shell at gamma = {p.gamma_effective:.6g}"
                       if p.energy_convention != "helfrich" else "")
                    + "); energies in units of kappa\n")
        if args.csv:
            sys.stdout.write(table.to_csv(index=False, lineterminator="\n"))
        elif table.empty:
            sys.stdout.write("  ".join(table.columns) + "\n(no finished step yet)\n")
        else:
            def cell(v) -> str:
                if v is None or v is pd.NA or (isinstance(v, float) and v != v):
                    return "-"
                return f"{v:.6g}" if isinstance(v, float) else str(v)
            shown = pd.DataFrame({c: [cell(v) for v in table[c].astype(object)]
                                  for c in table.columns})
            sys.stdout.write(shown.to_string(index=False) + "\n")
        return 0

    parser.set_defaults(func=run)


def _register_theory(sub) -> None:
    """``shellbuckle theory [--gamma G] [--nu NU] [--out PATH] [--json]``: paper §3 theory."""
    parser = sub.add_parser(
        "theory", help="plot the paper's theory curves and print the buckling estimates",
        description="Plot U_sphere (small strain and exact), U_axisym and the crossing of "
                    "Quilliet et al. (2008) section 3 against dV/V, write the figure, and print "
                    "d/R, the crossing U_sphere = U_axisym and the classical threshold. "
                    "Energies in units of kappa, pressures in kappa/R^3.")
    parser.add_argument("--gamma", type=float, default=2333.0,
                        help="Foppl-von Karman number A R^2/kappa, > 0 (default 2333)")
    parser.add_argument("--nu", type=float, default=1.0 / 3.0,
                        help="2D Poisson ratio in (-1, 1/2) (default 1/3, incompressible)")
    parser.add_argument("--out", default="shellbuckle_theory.png",
                        help="figure file, .png or .pdf (default shellbuckle_theory.png)")
    parser.add_argument("--json", action="store_true",
                        help="print the numbers as one JSON object")
    _add_convention_option(parser, default="helfrich")

    def run(args) -> int:
        import json
        import warnings
        from pathlib import Path

        from .params import ShellParameters
        from .plots.theory import plot_theory
        from .theory import summary

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            params = ShellParameters.from_gamma(args.gamma, nu=args.nu,
                                                energy_convention=args.energy_convention)
        for w in caught:
            print(f"shellbuckle theory: warning: {w.message}", file=sys.stderr)
        out = Path(args.out)
        if not out.parent.is_dir():
            raise FileNotFoundError(f"--out: directory {str(out.parent)!r} does not exist")
        plot_theory(params, path=out)
        info = summary(params)
        if args.json:
            print(json.dumps({**info, "figure": str(out)}))
            return 0
        print(params.describe().splitlines()[0])
        if params.energy_convention != "helfrich":
            print(params.describe().splitlines()[-1])
        xc = info["crossing_dV_over_V"]
        if xc is None:
            print("crossing U_sphere = U_axisym: none (U_axisym > U_sphere for all dV/V)")
        else:
            pref = info["crossing_asymptotic_dV_over_V"] * params.gamma_effective ** 0.6
            print(f"crossing U_sphere = U_axisym: dV/V = {xc:.4g} "
                  f"(exact Green-Lagrange sphere: {info['crossing_dV_over_V_exact_sphere']:.4g}; "
                  f"thin-shell law {pref:.4g} gamma^(-3/5) = "
                  f"{info['crossing_asymptotic_dV_over_V']:.4g})")
        g = "gamma" if params.energy_convention == "helfrich" else "gamma_effective"
        k = "kappa" if params.energy_convention == "helfrich" else "f kappa"
        print(f"classical threshold: p_c = 4 sqrt({k} A)/R^2 = "
              f"{info['classical_pressure']:.4g} kappa/R^3, dV/V = 6(1-nu)/sqrt({g}) = "
              f"{info['classical_dV_over_V']:.4g} "
              f"(exact pressure-volume relation: {info['classical_dV_over_V_exact']:.4g})")
        print(f"figure: {out}")
        return 0

    parser.set_defaults(func=run)


def _register_evolver_energy(sub) -> None:
    """``shellbuckle evolver-energy FILE [--json]``: energies of a Surface Evolver file."""
    parser = sub.add_parser(
        "evolver-energy", help="energies, volume and area of a Surface Evolver datafile or dump",
        description="Read a Surface Evolver datafile (.fe) or dump (.dmp) and print the "
                    "stretching (linear_elastic), bending (star_perp_sq_mean_curvature) and total "
                    "energies, the enclosed volume and the area of its configuration, computed "
                    "with the file's own moduli, h_zero, poisson_ratio and form_factors. The "
                    "file's 'read' section of commands is never executed.")
    parser.add_argument("file", metavar="FILE", help="Surface Evolver datafile or dump")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object with E_stretch, E_bend, E_total, volume, area")

    def run(args) -> int:
        import json

        import numpy as np

        from .energies.evolver import evolver_energy
        from .mesh.evolver_io import read_evolver

        evf = read_evolver(args.file)
        result = evolver_energy(evf)
        if args.json:
            keys = ("E_stretch", "E_bend", "E_total", "volume", "area")
            print(json.dumps({k: result[k] for k in keys}))
            return 0
        mesh = evf.mesh
        print(f"{args.file}: {mesh.n_vertices} vertices, {len(mesh.faces)} facets")
        for q in evf.quantities:
            print(f"  quantity {q.name} {q.kind} method {q.method} modulus {q.modulus:.17g}"
                  + ("" if q.is_global else " (applied to some elements)"))
        if evf.h_zero is not None:
            h0 = np.asarray(evf.h_zero)
            print("  h_zero " + (f"{float(h0):.17g}" if h0.ndim == 0
                                 else f"per vertex, {h0.min():.6g} .. {h0.max():.6g}"))
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

    parser.set_defaults(func=run)


def _add_material_options(parser) -> None:
    group = parser.add_argument_group("shell parameters (either gamma and nu, or a 3D material)")
    group.add_argument("--gamma", type=float,
                       help="Foppl-von Karman number A R^2/kappa (default 15163: wrinkles)")
    group.add_argument("--nu", type=float, help="2D Poisson ratio (default 1/3)")
    group.add_argument("--E", type=float, help="3D Young modulus of the material")
    group.add_argument("--sigma", type=float, help="3D Poisson ratio of the material, in (-1, 0.5]")
    group.add_argument("--d", type=float, help="shell thickness")
    group.add_argument("--R", type=float, help="shell radius (with --E --sigma --d)")
    _add_convention_option(group)


def _add_convention_option(parser, default=None) -> None:
    from .params import CONVENTION_HELP, ENERGY_CONVENTIONS

    parser.add_argument("--energy-convention", choices=list(ENERGY_CONVENTIONS),
                        default=default, metavar="{" + ",".join(ENERGY_CONVENTIONS) + "}",
                        help=CONVENTION_HELP)


def _params_from_args(args, fallback=None):
    from .params import DEFAULT_CONVENTION, ShellParameters
    from .run import MAIN_JOB_GAMMA

    material = [args.E, args.sigma, args.d, args.R]
    convention = getattr(args, "energy_convention", None) or DEFAULT_CONVENTION
    if any(v is not None for v in material):
        if any(v is None for v in material):
            raise ValueError("a material needs all of --E, --sigma, --d and --R")
        if args.gamma is not None or args.nu is not None:
            raise ValueError("give either --gamma/--nu or the material --E --sigma --d --R, not both")
        return ShellParameters.from_material(args.E, args.sigma, args.d, args.R,
                                             energy_convention=convention)
    if fallback is not None and args.gamma is None and args.nu is None:
        return fallback
    default_gamma = fallback.gamma if fallback else MAIN_JOB_GAMMA
    gamma = args.gamma if args.gamma is not None else default_gamma
    nu = args.nu if args.nu is not None else (fallback.nu if fallback else 1.0 / 3.0)
    return ShellParameters.from_gamma(gamma, nu=nu, energy_convention=convention)


def _register_deflate(sub) -> None:
    """``shellbuckle deflate``: the paper's deflation protocol, stored step by step."""
    from .protocol.deflate import DEFAULT_MAX_ITER

    parser = sub.add_parser(
        "deflate", help="deflate a shell with the paper's protocol (the main job)",
        description="Stepwise deflation at fixed enclosed volume (Quilliet et al. 2008, §4.1): "
                    "at each volume step jiggle, minimize, and run the zero-spontaneous-"
                    "curvature cycle; stop at self-intersection. Every finished step is stored "
                    "in --out; an interrupted run continues with `shellbuckle resume DIR`. "
                    "With no options: gamma = 15163, nu = 1/3 on a randomized 3594-vertex mesh "
                    "(a capsule that turns polygonal, then wrinkles).")
    _add_material_options(parser)
    mesh = parser.add_argument_group("mesh (default: randomized sphere, 3594 vertices)")
    mesh.add_argument("--vertices", type=int, help="vertices of the randomized sphere mesh")
    mesh.add_argument("--icosphere", type=int, metavar="N",
                      help="icosahedral sphere with edges divided in N (10 N^2 + 2 vertices)")
    mesh.add_argument("--mesh", metavar="FILE",
                      help="start from a mesh file (.fe/.dmp bring their own moduli, h_zero, "
                           "poisson_ratio and form_factors; or any meshio format)")
    proto = parser.add_argument_group("protocol")
    proto.add_argument("--seed", type=int, default=0, help="random seed (mesh and jiggle), default 0")
    proto.add_argument("--dv", type=float, default=0.019, help="volume step / V0 (default 0.019)")
    proto.add_argument("--until", type=float, default=0.95,
                       help="last target dV/V (default 0.95; the run stops earlier at self-contact)")
    proto.add_argument("--schedule", type=str,
                       help="comma-separated list of target dV/V values instead of --dv/--until")
    proto.add_argument("--pressures", type=str,
                       help="pressure control: comma-separated external overpressures "
                            "(units kappa/R^3), one per step, instead of a volume schedule")
    proto.add_argument("--no-c0-cycle", action="store_true",
                       help="skip the zero-spontaneous-curvature cycle (gives 'potato' shapes)")
    proto.add_argument("--temperature", type=float,
                       help="jiggle temperature on Surface Evolver's scale: displacements of std "
                            "0.28 T times the size of the initial surface (default 0.05, as "
                            "Surface Evolver: 0.028 R)")
    proto.add_argument("--jiggle", type=float,
                       help="jiggle amplitude as a fraction of the mean edge length, instead of "
                            "--temperature")
    proto.add_argument("--bending", choices=["juelicher", "evolver"], default=None,
                       help="bending discretization (default juelicher; with a Surface Evolver "
                            "--mesh file that bends with star_perp_sq_mean_curvature, evolver: "
                            "the file's own energy)")
    proto.add_argument("--method", choices=["newton", "alternate", "cg", "gd"], default="newton",
                       help="minimizer (default newton)")
    proto.add_argument("--max-iter", type=int, default=DEFAULT_MAX_ITER,
                       help="Newton steps (factorizations) of each minimization at most, or "
                            f"iterations with --method cg/gd (default {DEFAULT_MAX_ITER}; a small "
                            "budget with --method cg quenches as a fixed Surface Evolver script)")
    proto.add_argument("--c0", type=float, help="spontaneous curvature c = c1 + c2 (default 2/R)")
    proto.add_argument("--no-prerelax", action="store_true",
                       help="start each Newton minimization at once, without the relaxation "
                            "preconditioned by the step's starting state (slower; for comparisons)")
    proto.add_argument("--no-direct-return", action="store_true",
                       help="after the zero-curvature cycle always minimize from the flat "
                            "minimum, never from the minimum before the cycle (slower; for "
                            "comparisons)")
    branch = parser.add_argument_group("continue from a stored step (re-inflation, other paths)")
    branch.add_argument("--from", dest="from_run", metavar="DIR",
                        help="start from a step of the run in DIR (its reference sphere, "
                             "parameters and protocol options are kept; give --dv/--until or "
                             "--schedule, e.g. --dv -0.019 to re-inflate)")
    branch.add_argument("--step", type=int, default=-1,
                        help="the step of --from to start from (default: the last)")
    parser.add_argument("--out", help="run folder (default runs/gamma..._nu..._seed..._TIME)")
    _add_threads_option(parser)
    parser.add_argument("--no-plot", action="store_true", help="do not write the figure at the end")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=_cmd_deflate)


def _add_threads_option(parser) -> None:
    parser.add_argument("--threads", type=int,
                        help="threads of the sparse factorization (default: the cores this "
                             "process may use, or MKL_NUM_THREADS); one thread runs PARDISO's "
                             "faster plain mode, several its reproducible mode (the same bits "
                             "on any number); a run keeps its mode when resumed")


def _cmd_deflate(args) -> int:
    from .mesh import icosphere
    from .mesh.random_sphere import random_sphere
    from .run import deflate, params_for_mesh, shell_from_file

    from .protocol.deflate import Protocol
    from .solve.linear import check_threads

    if args.threads is not None:
        check_threads(args.threads)
    if args.from_run is not None:
        return _cmd_continue(args)
    choices = [x is not None for x in (args.vertices, args.icosphere, args.mesh)]
    if sum(choices) > 1:
        raise ValueError("give only one of --vertices, --icosphere and --mesh")
    schedule = None
    if args.schedule:
        try:
            schedule = [float(x) for x in args.schedule.split(",") if x.strip()]
        except ValueError:
            raise ValueError(f"--schedule must be comma-separated numbers, got {args.schedule!r}") from None
    pressures = None
    if args.pressures:
        if schedule is not None:
            raise ValueError("give either --schedule or --pressures, not both")
        try:
            pressures = [float(x) for x in args.pressures.split(",") if x.strip()]
        except ValueError:
            raise ValueError(f"--pressures must be comma-separated numbers, got {args.pressures!r}") from None
    # refuse bad protocol options before any mesh is built
    options = dict(c0_cycle=not args.no_c0_cycle, jiggle=args.jiggle,
                   temperature=args.temperature, seed=args.seed, bending=args.bending or "juelicher",
                   method=args.method, max_iter=args.max_iter, c0=args.c0,
                   prerelax=not args.no_prerelax, direct_return=not args.no_direct_return)
    if pressures is not None:
        Protocol(schedule=tuple(pressures), control="pressure", **options)
    elif schedule is None:
        Protocol.paper(dv=args.dv, until=args.until, **options)
    else:
        Protocol(schedule=tuple(schedule), **options)
    from_file = {}
    if args.mesh is not None:
        mesh, from_file = shell_from_file(args.mesh)
        if args.E is not None:
            params = _params_from_args(args)
        else:
            params = params_for_mesh(mesh, from_file, args.gamma, args.nu,
                                     energy_convention=args.energy_convention)
    else:
        params = _params_from_args(args)
        if args.icosphere is not None:
            mesh = icosphere(args.icosphere, R=params.R)
        else:
            mesh = random_sphere(3594 if args.vertices is None else args.vertices,
                                 seed=args.seed, R=params.R)
    c0 = args.c0 if args.c0 is not None else from_file.get("c0")
    bending = args.bending or from_file.get("bending", "juelicher")
    run = deflate(mesh, params, dv=args.dv, until=args.until, schedule=schedule,
                  c0_cycle=not args.no_c0_cycle, jiggle=args.jiggle,
                  temperature=args.temperature, seed=args.seed,
                  bending=bending, method=args.method, max_iter=args.max_iter, c0=c0,
                  prerelax=not args.no_prerelax, direct_return=not args.no_direct_return,
                  out=args.out,
                  progress=not args.quiet, form_factors=from_file.get("form_factors"),
                  pressures=pressures, threads=args.threads)
    return _report_run(run, plot=not args.no_plot)


def _cmd_continue(args) -> int:
    from .run import Run, continue_from

    if args.out is None:
        raise ValueError("--from needs --out: the new run gets its own folder")
    for name in ("gamma", "nu", "E", "sigma", "d", "R", "vertices", "icosphere", "mesh",
                 "energy_convention"):
        if getattr(args, name) is not None:
            option = name.replace("_", "-")
            raise ValueError(f"--{option} cannot be combined with --from: the run continues "
                             "with the stored mesh and parameters")
    parent = Run.open(args.from_run)
    steps = parent.steps
    if not steps:
        raise ValueError(f"{args.from_run} has no finished step to continue from")
    step = args.step if args.step >= 0 else steps[args.step] if -len(steps) <= args.step else None
    if step not in steps:
        raise ValueError(f"--step {args.step} is not a finished step of {args.from_run}; allowed: "
                         f"0..{steps[-1]} (or -1 .. -{len(steps)} counted from the last)")
    schedule = ([float(x) for x in args.schedule.split(",") if x.strip()]
                if args.schedule else None)
    run = continue_from(parent, step, args.out, schedule=schedule,
                        dv=None if schedule else args.dv, until=None if schedule else args.until,
                        progress=not args.quiet, c0_cycle=not args.no_c0_cycle,
                        jiggle=args.jiggle, temperature=args.temperature, seed=args.seed)
    return _report_run(run, plot=not args.no_plot)


def _report_run(run, plot: bool) -> int:
    table = run.table
    last = table.iloc[-1]
    print(f"run folder: {run.path}")
    print(f"status: {run.status} ({run.store.meta.get('message')})")
    print(f"steps: {int(last['step'])}, dV/V = {last['dV_over_V']:.4f}, "
          f"E/kappa = {last['E_over_kappa']:.6g}, pressure = {last['pressure']:.6g}")
    if plot:
        from .plots.run import plot_deflation

        path = run.path / "deflation.png"
        plot_deflation(run, path=path)
        print(f"figure: {path}")
    return 0


def _register_resume(sub) -> None:
    """``shellbuckle resume DIR``: continue an interrupted run from its last finished step."""
    parser = sub.add_parser("resume", help="continue a stored run from its last finished step",
                            description="Continue the run in DIR from its last finished step; "
                                        "the result is the same as an uninterrupted run.")
    parser.add_argument("dir", metavar="DIR", help="run folder")
    _add_threads_option(parser)
    parser.add_argument("--no-plot", action="store_true", help="do not write the figure at the end")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=_cmd_resume)


def _cmd_resume(args) -> int:
    from .run import resume

    return _report_run(resume(args.dir, progress=not args.quiet, threads=args.threads),
                       plot=not args.no_plot)



def _register_view(sub) -> None:
    """``shellbuckle view DIR [--out FILE.html] [--color C]``: interactive page of a run."""
    parser = sub.add_parser(
        "view", help="write a self-contained interactive HTML page of a run",
        description="Write one self-contained HTML file (no network access needed to open it) "
                    "showing the surface of every stored step of the run folder DIR: a step "
                    "slider and play button, drag to rotate, wheel to zoom, a colour legend, "
                    "the per-step table and the energies and pressure against dV/V. Colours: "
                    "curvature (vertex mean curvature H, 1/R), strain (stretching energy per "
                    "rest area of each triangle, kappa/R^2) or bending (bending energy per "
                    "area, kappa/R^2); the page can switch between them.")
    parser.add_argument("dir", metavar="DIR", help="run folder")
    parser.add_argument("--out", metavar="FILE.html",
                        help="page to write (default DIR/view.html)")
    parser.add_argument("--color", default="curvature",
                        help="initial colouring: curvature (default), strain or bending")

    def run(args) -> int:
        from pathlib import Path

        from .plots.viewer import COLORS, write_html
        from .run import Run

        if args.color not in COLORS:
            raise ValueError(f"--color must be one of {', '.join(COLORS)}, got {args.color!r}")
        run = Run.open(args.dir)
        out = Path(args.out) if args.out else run.path / "view.html"
        path = write_html(run, out, color=args.color)
        print(f"{path} ({path.stat().st_size / 1e6:.2f} MB, {len(run.steps)} steps)")
        return 0

    parser.set_defaults(func=run)


def _register_export(sub) -> None:
    """``shellbuckle export DIR --step K --format FMT [--out PATH]``: one step to a mesh file."""
    parser = sub.add_parser(
        "export", help="export one step of a run to VTK, VTU, PLY, OBJ, STL or Surface Evolver",
        description="Write step K of the run folder DIR as a mesh file: vtk or vtu (ParaView; "
                    "point data H, displacement from the initial sphere and bending energy "
                    "density, cell data stretching energy density), ply (scalar point data), "
                    "obj, stl (geometry only), or fe: a Surface Evolver datafile with the run's "
                    "moduli, c0, the initial sphere's rest metrics (form_factors) and the step's "
                    "volume as the body's target, which Surface Evolver loads and can continue "
                    "from with the same energy.")
    parser.add_argument("dir", metavar="DIR", help="run folder")
    parser.add_argument("--step", required=True, type=int, metavar="K",
                        help="stored step number (negative counts from the last: -1 is the last)")
    parser.add_argument("--format", required=True, metavar="FMT", dest="fmt",
                        help="one of vtk, vtu, ply, obj, stl, fe")
    parser.add_argument("--out", metavar="PATH",
                        help="file to write (default <run folder name>_step<K>.<FMT> here)")

    def run(args) -> int:
        from .export import FORMATS, default_export_path, export_step, resolve_step
        from .run import Run

        fmt = args.fmt.lower().lstrip(".")
        if fmt not in FORMATS:
            raise ValueError(f"--format {args.fmt!r} is not supported; allowed: {', '.join(FORMATS)}")
        run = Run.open(args.dir)
        step = resolve_step(run, args.step)
        out = args.out if args.out else default_export_path(run, step, fmt)
        path = export_step(run, step, out, fmt=fmt)
        print(f"step {step} of {run.path} written to {path}")
        return 0

    parser.set_defaults(func=run)


def _register_classify(sub) -> None:
    """``shellbuckle classify FILE [--step K] [--json]``: the class of one conformation."""
    parser = sub.add_parser(
        "classify", help="classify one conformation: sphere, dimples, capsule, polygonal, wrinkled",
        description="Classify the conformation in FILE, a closed triangulated surface in any "
                    "supported mesh format (.fe/.dmp Surface Evolver, or a meshio format: "
                    ".vtk .vtu .xdmf .msh .ply .obj .off .stl .mesh .inp), or a step of a run "
                    "folder (FILE = DIR, with --step K; default the last step). Prints the shape "
                    "(sphere, dimples, capsule, polygonal, wrinkled, other), the number of "
                    "dimples, corners and wrinkles W, the dent's depth, sagitta and axis, the "
                    "rim radius and its strongest Fourier modes. Lengths in the file's units.")
    parser.add_argument("file", metavar="FILE", help="mesh file, or run folder with --step")
    parser.add_argument("--step", type=int, metavar="K",
                        help="step of a run folder (negative counts from the last; default -1)")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object (with all the descriptors)")

    def run(args) -> int:
        import json
        from pathlib import Path

        from .analysis import classify

        path = Path(args.file)
        if path.is_dir():
            from .run import Run

            found = Run.open(path)
            steps = found.steps
            if not steps:
                raise ValueError(f"run folder {str(path)!r} has no finished step yet")
            k = -1 if args.step is None else args.step
            if not -len(steps) <= k < (steps[-1] + 1 if k >= 0 else 0) or (k >= 0 and k not in steps):
                raise ValueError(f"--step {k} is not a stored step of {path} (steps "
                                 f"{steps[0]}..{steps[-1]}, or -1 for the last)")
            step = steps[k] if k < 0 else k
            X, faces, source = found.positions(step), found.faces, f"{path} step {step}"
        else:
            if args.step is not None:
                raise ValueError("--step applies to a run folder, not to a mesh file")
            if not path.exists():
                raise ValueError(f"mesh file {str(path)!r} does not exist")
            from .mesh.io import read_mesh

            mesh = read_mesh(path)
            X, faces, source = mesh.X, mesh.faces, str(path)
        c = classify(X, faces)
        if args.json:
            out = {"source": source, **c.as_dict()}
            print(json.dumps(_json_safe(out)))
            return 0
        print(f"{source}: {len(X)} vertices")
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
        return 0

    parser.set_defaults(func=run)


def _json_safe(value):
    """``value`` with non-finite floats replaced by None (strict JSON)."""
    import math

    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _register_analyze(sub) -> None:
    """``shellbuckle analyze DIR [--json] [--quiet]``: classify every step, print the events."""
    parser = sub.add_parser(
        "analyze", help="classify every step of a run, store the analysis columns, print events",
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

    def run(args) -> int:
        import json

        from .analysis import analyze_run, events
        from .run import Run

        found = Run.open(args.dir)
        if not found.steps:
            raise ValueError(f"run folder {args.dir!r} has no finished step yet")
        table = analyze_run(found, progress=not args.quiet)
        found_events = events(found, table=table)
        if args.json:
            print(json.dumps(_json_safe({"run": str(found.path), "steps": len(table),
                                         "events": [vars(e) for e in found_events]})))
            return 0
        print(f"{found.path}: {len(table)} steps analysed, up to dV/V = "
              f"{table['dV_over_V'].iloc[-1]:.4f}")
        counts = table["shape"].value_counts()
        print("  shapes: " + ", ".join(f"{name} {n}" for name, n in counts.items()))
        if not found_events:
            print("  no event (the shell stayed a sphere)")
        for e in found_events:
            note = "" if e.confirmed is None else ("  [confirmed]" if e.confirmed else "  [unconfirmed]")
            print(f"  {e.name:<17} step {e.step:>4}  dV/V = {e.dV_over_V:.4f}  {e.description}{note}")
        return 0

    parser.set_defaults(func=run)


def _register_sweep(sub) -> None:
    """``shellbuckle sweep [--config FILE.toml] [--gamma G,..] ... --out DIR``: runs on Dask."""
    parser = sub.add_parser(
        "sweep", help="run a grid of deflations in parallel on Dask, resumable, with a catalogue",
        description="Run every combination of the given values (gamma x nu x mesh x seeds x "
                    "protocol options) as one deflation, each in its own run folder in DIR named "
                    "from its parameters (e.g. g2333_nu0.333_v3594_s0), on a local Dask cluster "
                    "of single-threaded workers (default: one per core) or on the Dask scheduler "
                    "at ADDR. DIR/catalogue.csv (one row per run: parameters, status, steps, "
                    "final dV/V, stop reason, thresholds, W, wall time) is rewritten as runs "
                    "finish. Running the same command again skips finished runs, resumes "
                    "unfinished ones from their last step and retries failed ones. Lists are "
                    "comma-separated; integer lists also take ranges (0-4). Values on the "
                    "command line replace those of --config.")
    parser.add_argument("--config", metavar="FILE.toml", help="sweep file (see examples/sweep.toml)")
    parser.add_argument("--gamma", metavar="G,..", help="Foppl-von Karman numbers, > 0 (default 2333)")
    parser.add_argument("--nu", metavar="NU,..", help="2D Poisson ratios in (-1, 1) (default 1/3)")
    parser.add_argument("--seeds", metavar="S,..", help="seeds of mesh and jiggle, >= 0 (default 0)")
    parser.add_argument("--vertices", metavar="N,..",
                        help="randomized spheres with N vertices (default 3594 unless --icosphere)")
    parser.add_argument("--icosphere", metavar="N,..",
                        help="icosahedral spheres of level N (10 N^2 + 2 vertices)")
    parser.add_argument("--dv", metavar="DV,..", help="volume steps / V0 in (0, 0.5] (default 0.019)")
    parser.add_argument("--until", metavar="U,..", help="last target dV/V in (0, 0.99) (default 0.95)")
    parser.add_argument("--temperature", metavar="T,..",
                        help="jiggle temperatures (Surface Evolver's scale) in [0, 1] (default 0.05)")
    parser.add_argument("--jiggle", metavar="J,..",
                        help="jiggle amplitudes in [0, 0.5] of the mean edge length, instead of "
                             "--temperature")
    parser.add_argument("--bending", metavar="B,..", help="bending models: juelicher, evolver")
    parser.add_argument("--method", metavar="M,..", help="minimizers: newton, alternate, cg, gd")
    parser.add_argument("--energy-convention", metavar="C,..",
                        help="energy conventions: helfrich (default), paper, evolver-modulus "
                             "(see shellbuckle deflate --help)")
    parser.add_argument("--no-c0-cycle", action="store_true",
                        help="no zero-spontaneous-curvature cycle (the paper's potato shapes)")
    parser.add_argument("--workers", metavar="N", help="local worker processes (default: cores)")
    parser.add_argument("--scheduler", metavar="ADDR",
                        help="address of a running Dask scheduler (e.g. tcp://host:8786)")
    parser.add_argument("--no-analysis", action="store_true",
                        help="do not classify the steps of finished runs (no thresholds or W)")
    parser.add_argument("--no-retry", action="store_true", help="do not rerun failed runs")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--out", required=True, metavar="DIR", help="sweep folder")

    def values(option: str, text: str, kind) -> list:
        """Comma-separated values of ``kind``; integers also as inclusive ranges ``a-b``."""
        out = []
        for item in (part.strip() for part in text.split(",")):
            try:
                if kind is str:
                    if not item:
                        raise ValueError
                    out.append(item)
                elif kind is int and "-" in item[1:]:
                    low, high = (int(x) for x in item.split("-", 1))
                    if high < low:
                        raise ValueError
                    out.extend(range(low, high + 1))
                else:
                    out.append(kind(item))
            except ValueError:
                what = {int: "an integer (or a range a-b)", float: "a number"}.get(kind, "a name")
                raise ValueError(f"{option}: {item!r} is not {what}") from None
        return out

    def run(args) -> int:
        from pathlib import Path

        from .sweep import SweepSpec, check_scheduler, run_sweep

        kinds = {"gamma": float, "nu": float, "seeds": int, "vertices": int, "icosphere": int,
                 "dv": float, "until": float, "jiggle": float, "temperature": float,
                 "bending": str, "method": str, "energy_convention": str}
        given = {name: values(f"--{name.replace('_', '-')}", getattr(args, name), kind)
                 for name, kind in kinds.items() if getattr(args, name) is not None}
        if args.no_c0_cycle:
            given["c0_cycle"] = False
        workers = None if args.workers is None else values("--workers", args.workers, int)
        if workers is not None and (len(workers) != 1 or workers[0] < 1):
            raise ValueError(f"--workers: {args.workers!r} must be one integer >= 1")
        workers = workers[0] if workers else None
        if workers is not None and args.scheduler is not None:
            raise ValueError("--workers applies to the local cluster; a --scheduler has its "
                             "own workers")
        check_scheduler(args.scheduler)
        spec = (SweepSpec.from_toml(args.config, **given) if args.config
                else SweepSpec.from_dict(given))
        catalogue = run_sweep(spec, args.out, scheduler=args.scheduler, workers=workers,
                              progress=not args.quiet, analyze=not args.no_analysis,
                              retry_failed=not args.no_retry)
        counts = catalogue["status"].value_counts()
        print(f"sweep {args.out}: {len(catalogue)} runs; "
              + ", ".join(f"{status} {n}" for status, n in counts.items()))
        print(f"catalogue: {Path(args.out) / 'catalogue.csv'}")
        failed = catalogue[catalogue["status"] == "failed"]
        for _, row in failed.iterrows():
            print(f"  failed: {row['name']}: {row['message']}", file=sys.stderr)
        return 1 if len(failed) else 0

    parser.set_defaults(func=run)


# Each entry adds one sub-command: register(subparsers) -> sets ``func`` via set_defaults.
_COMMANDS: list = [_register_deflate, _register_resume, _register_table, _register_theory, _register_evolver_energy, _register_view, _register_export, _register_classify, _register_analyze, _register_sweep]


def main(argv=None) -> int:
    parser = _build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as exc:
        print(f"shellbuckle {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"shellbuckle {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a failure during the work, not bad input
        logging.getLogger("shellbuckle").debug("failure", exc_info=True)
        print(f"shellbuckle {args.command}: failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
