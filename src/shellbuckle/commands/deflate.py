"""``shellbuckle deflate``: the paper's deflation protocol, stored step by step (the main job).

``deflate --from DIR --step K`` is kept as another spelling of ``shellbuckle continue DIR
--step K`` along a volume path: it calls the same code (:func:`.continue_.continue_run`).
"""

from __future__ import annotations

from ._checks import (RANGES, add_command, add_number, allowed, check_c0,
                      check_mesh, check_pressures, check_smooth_degree, check_steps, check_value,
                      floats, input_file, output_folder, typed)
from .locate import add_locate_options, locate_arguments
from ._options import (add_protocol_options, add_run_output_options, add_shell_options,
                       add_threads_option, default_gamma, params_from_args, protocol_defaults,
                       protocol_values)

#: The protocol options of a deflation (Protocol fields, and dv, until, schedule, pressures,
#: smooth_jiggle_d).
PROTOCOL = ("seed", "dv", "until", "schedule", "pressures", "c0_cycle", "temperature", "jiggle",
            "smooth_jiggle", "smooth_jiggle_d", "smooth_degree", "shape_imperfection",
            "shape_imperfection_d", "shape_degree", "bending", "method",
            "max_iter", "c0", "prerelax", "direct_return", "rescale_start")
#: The options of the smooth imperfection, which replaces the per-vertex jiggle.
SMOOTH = ("smooth_jiggle", "smooth_jiggle_d", "smooth_degree")
#: The options of the shape imperfection (the stress-free shape of a new shell).
SHAPE = ("shape_imperfection", "shape_imperfection_d", "shape_degree")
#: Options given in units of the thickness, stored in units of R under the other name.
IN_D = {"smooth_jiggle_d": "smooth_jiggle", "shape_imperfection_d": "shape_imperfection"}
#: Options of a new shell or mesh, which a continued run takes from the stored one.
NEW_SHELL = ("gamma", "nu", "E", "sigma", "d", "R", "energy_convention", "vertices",
             "icosphere", "mesh", "pressures", "bending", "c0")
#: Vertices of the default mesh: the paper's randomized sphere.
DEFAULT_VERTICES = 3594


def register(sub) -> None:
    parser = add_command(
        sub, "deflate", help="deflate a shell with the paper's protocol (the main job)",
        description="Stepwise deflation at fixed enclosed volume (Quilliet et al. 2008, §4.1): "
                    "at each volume step jiggle, minimize, and run the zero-spontaneous-"
                    "curvature cycle; stop at self-intersection. Every finished step is stored "
                    "in --out; an interrupted run continues with `shellbuckle resume DIR`. "
                    f"With no options: gamma = {default_gamma():g}, nu = 1/3 on a randomized "
                    f"{DEFAULT_VERTICES}-vertex mesh (a capsule that turns polygonal, then "
                    "wrinkles).")
    add_shell_options(parser)
    mesh = parser.add_argument_group(f"mesh (default: randomized sphere, {DEFAULT_VERTICES} "
                                     "vertices)")
    add_number(mesh, "--vertices", "vertices", "vertices of the randomized sphere mesh")
    add_number(mesh, "--icosphere", "icosphere", "icosahedral sphere with edges divided in N "
               "(10 N^2 + 2 vertices)", metavar="N")
    mesh.add_argument("--mesh", metavar="FILE",
                      help="start from a mesh file (.fe/.dmp bring their own moduli, h_zero, "
                           "poisson_ratio and form_factors; or any meshio format)")
    add_protocol_options(parser.add_argument_group("protocol"), PROTOCOL,
                         ranges={"dv": "dv_signed"})
    branch = parser.add_argument_group(
        "continue from a stored step (another spelling of `shellbuckle continue DIR --step K` "
        "along a volume path)")
    branch.add_argument("--from", dest="from_run", metavar="DIR",
                        help="start from a step of the run in DIR (its reference sphere, "
                             "parameters and protocol options are kept unless given; give "
                             "--dv/--until or --schedule, e.g. --dv -0.019 to re-inflate)")
    add_number(branch, "--step", "step", "the step of --from to start from (default: the last)",
               default=-1)
    parser.add_argument("--out", help="run folder (default runs/gamma..._nu..._seed..._TIME)")
    add_threads_option(parser)
    add_run_output_options(parser)
    add_locate_options(parser)
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    if args.from_run is not None:
        from .continue_ import continue_run

        for name in SMOOTH + SHAPE:
            if getattr(args, name) is not None:
                flag = "--" + name.replace("_", "-")
                kept = "jiggle" if name in SMOOTH else "shell"
                raise ValueError(f"{flag} {typed(args, flag, getattr(args, name))}: allowed: "
                                 f"without --from (a continued run keeps the stored run's "
                                 f"{kept})")
        return continue_run(_as_continue(args))
    options = _protocol(args)
    located = locate_arguments(args)
    if args.out is not None:
        output_folder("--out", args.out, run=True)
    mesh, params, from_file = _shell(args, options.get("seed", protocol_defaults()["seed"]),
                                     options)
    options.setdefault("bending", from_file.get("bending"))
    options.setdefault("c0", from_file.get("c0"))
    options = {k: v for k, v in options.items() if v is not None and k not in IN_D}
    from ..run import deflate

    run = deflate(mesh, params, out=args.out, progress=not args.quiet,
                  form_factors=from_file.get("form_factors"), threads=args.threads, **located,
                  **options)
    from ._output import report_run

    return report_run(run, plot=not args.no_plot)


def _protocol(args) -> dict:
    """The protocol options given, checked (a Protocol is built) before any mesh is."""
    from ..protocol.spec import Protocol

    choices = [x is not None for x in (args.vertices, args.icosphere, args.mesh)]
    if sum(choices) > 1:
        raise ValueError("give only one of --vertices, --icosphere and --mesh")
    options = protocol_values(args, PROTOCOL)
    for name in ("schedule", "pressures"):
        if name in options:
            options[name] = floats(f"--{name}", options[name], name)
            check_steps(f"--{name}", options[name] and args.__dict__[name],
                        len(options[name]))
    if options.get("schedule") is not None and options.get("pressures") is not None:
        raise ValueError("give either --schedule or --pressures, not both")
    listed = "--schedule" if options.get("schedule") is not None else (
        "--pressures" if options.get("pressures") is not None else None)
    for name in ("dv", "until"):
        if listed and name in options:
            raise ValueError(f"--{name} {typed(args, '--' + name, options[name])}: allowed: "
                             f"without {listed}, which lists the targets itself")
    _check_smooth_options(args, options)
    if args.mesh is not None and (options.get("shape_imperfection")
                                  or options.get("shape_imperfection_d")):
        flag = "--shape-imperfection" + ("-d" if "shape_imperfection_d" in options else "")
        raise ValueError(f"{flag} {typed(args, flag)}: allowed: on a randomized or icosahedral "
                         f"sphere (--vertices, --icosphere), not on a --mesh file, whose "
                         f"vertices would be moved onto a sphere ({args.mesh})")
    from ..protocol.imperfection import CRITICAL, critical_shape_degree

    if options.get("shape_degree") == CRITICAL:
        L = critical_shape_degree(params_from_args(args).gamma_effective)
        options["shape_degree"] = check_value("--shape-degree", "shape_degree", L,
                                              f"{CRITICAL} (gives L = {L})")
    defaults = protocol_defaults()
    dv, until = options.get("dv", defaults["dv"]), options.get("until", defaults["until"])
    if dv <= 0:
        raise ValueError(f"--dv {typed(args, '--dv', dv)}: a new deflation needs a step > 0; "
                         f"{RANGES['dv'].explained()} (a negative step re-inflates a stored run: "
                         "--from DIR)")
    if until < dv:
        raise ValueError(f"--until {typed(args, '--until', until)}: allowed: at least the step "
                         f"--dv {typed(args, '--dv', dv)} and below 0.99")
    check_steps("--dv", typed(args, "--dv", dv), until / dv)
    fields = {k: v for k, v in options.items() if k not in ("dv", "until", "schedule",
                                                           "pressures", *IN_D)}
    for name, field in IN_D.items():
        if name in options:  # its value in units of R needs the shell: _check_smooth
            fields[field] = 0.0
    if fields.get("shape_imperfection"):  # its curvature is checked with the option's name
        fields["shape_imperfection"] = 0.0
    if options.get("pressures") is not None:
        Protocol(schedule=tuple(options["pressures"]), control="pressure", **fields)
    elif options.get("schedule") is not None:
        Protocol(schedule=tuple(options["schedule"]), **fields)
    else:
        Protocol.paper(**{k: options[k] for k in ("dv", "until") if k in options}, **fields)
    return options


def _check_smooth_options(args, options: dict) -> None:
    """The smooth imperfection (``--smooth-jiggle`` or ``--smooth-jiggle-d``, and
    ``--smooth-degree``) replaces the per-vertex jiggle: one amplitude, without
    ``--temperature`` or ``--jiggle`` (which are not given together either); the shape
    imperfection likewise takes one amplitude; a degree only with an amplitude."""
    if "jiggle" in options and "temperature" in options:
        raise ValueError(f"--jiggle {typed(args, '--jiggle', options['jiggle'])}: allowed: "
                         "without --temperature (two scales of the same per-vertex jiggle: "
                         "give one)")
    for kind, amplitude in (("smooth", "smooth_jiggle"), ("shape", "shape_imperfection")):
        flag, degree = "--" + amplitude.replace("_", "-"), f"--{kind}-degree"
        given = [name for name in (amplitude, amplitude + "_d") if name in options]
        if len(given) == 2:
            raise ValueError(f"{flag}-d {typed(args, flag + '-d')}: give either {flag} (units "
                             f"of R) or {flag}-d (units of the thickness d), not both")
        if given and kind == "smooth":
            used = "--" + given[0].replace("_", "-")
            for other in ("temperature", "jiggle"):
                if other in options:
                    raise ValueError(f"{used} {typed(args, used, options[given[0]])}: allowed: "
                                     f"without --{other} (the smooth imperfection replaces "
                                     "Surface Evolver's per-vertex jiggle)")
        elif not given and f"{kind}_degree" in options:
            raise ValueError(f"{degree} {typed(args, degree)}: allowed: only with {flag} or "
                             f"{flag}-d (the highest degree of the {kind} imperfection)")


def _shell(args, seed: int, options: dict):
    """The starting mesh, the shell parameters and what a mesh file says about the shell,
    checked (the mesh resolves the elastic length, c0 and the pressures) before any folder
    is made; the randomized or icosahedral mesh is built after the checks."""
    if args.mesh is not None:
        from ..run import params_for_mesh, shell_from_file

        input_file("--mesh", args.mesh)
        try:
            mesh, from_file = shell_from_file(args.mesh)
        except ValueError as exc:  # what the file holds, named with the option
            raise ValueError(f"--mesh {args.mesh}: {exc}") from None
        if args.E is not None:
            params = params_from_args(args)
        else:
            params = params_for_mesh(mesh, from_file, args.gamma, args.nu,
                                     energy_convention=args.energy_convention)
        n = len(mesh.X)
        if n < RANGES["vertices"].low:
            raise ValueError(f"--mesh {args.mesh}: {n} vertices; "
                             f"allowed: {RANGES['vertices'].explained()}")
        from ..run import check_mesh_fits

        try:  # outward faces, a valid rest metric, the radius of the shell given
            check_mesh_fits(mesh, params, from_file.get("form_factors"))
        except ValueError as exc:
            raise ValueError(f"--mesh {args.mesh}: {exc}") from None
        _check_shell(args, params, n, f"--mesh {args.mesh}", options)
        return mesh, params, from_file
    params = params_from_args(args)
    if args.icosphere is not None:
        n, what = 10 * args.icosphere ** 2 + 2, f"--icosphere {typed(args, '--icosphere')}"
    else:
        vertices = DEFAULT_VERTICES if args.vertices is None else args.vertices
        n, what = vertices, f"--vertices {typed(args, '--vertices', vertices)}"
    _check_shell(args, params, n, what, options)
    from ..mesh import icosphere
    from ..mesh.random_sphere import random_sphere

    if args.icosphere is not None:
        return icosphere(args.icosphere, R=params.R), params, {}
    return random_sphere(n, seed=seed, R=params.R), params, {}


def _check_shell(args, params, n: int, mesh: str, options: dict) -> None:
    """The mesh of ``n`` vertices resolves gamma and the smooth imperfection's degree; c0 and
    the pressures suit the shell. An amplitude in units of the thickness
    (``--smooth-jiggle-d``) becomes ``options["smooth_jiggle"]``, in units of R."""
    if args.gamma is not None:
        option, text = "--gamma", typed(args, "--gamma", args.gamma)
    elif args.d is not None:
        option, text = "--d", typed(args, "--d", args.d)
    else:
        option, text = mesh.split(" ", 1) if " " in mesh else (mesh, "")
    check_mesh(option, text, params.gamma, n, gamma_effective=params.gamma_effective,
               mesh=mesh if option != mesh.split(" ", 1)[0] else "it")
    if options.get("c0") is not None:
        check_c0("--c0", typed(args, "--c0", options["c0"]), options["c0"], n, params.R)
    if options.get("pressures") is not None:
        texts = [t.strip() for t in args.pressures.split(",") if t.strip()]
        check_pressures("--pressures", texts, options["pressures"], params)
    _check_smooth(args, params, n, mesh, options)


def _check_smooth(args, params, n: int, mesh: str, options: dict) -> None:
    """The smooth and shape imperfections: amplitudes in units of the thickness converted to
    units of R and checked, and the mesh resolving their degree."""
    from ..protocol.imperfection import DEFAULT_DEGREE, check_shape

    for kind, amplitude in (("smooth", "smooth_jiggle"), ("shape", "shape_imperfection")):
        in_d = amplitude + "_d"
        flag_d = "--" + in_d.replace("_", "-")
        if options.get(in_d) is not None:
            d = params.d_over_R_effective  # the thickness the mechanics sees
            value = options[in_d] * d
            if RANGES[amplitude].problem(value):
                raise ValueError(f"{flag_d} {typed(args, flag_d)}: gives an rms amplitude of "
                                 f"{value:.4g} R at the effective d/R = {d:.4g}; "
                                 f"{allowed(amplitude)}")
            options[amplitude] = value
        if not options.get(amplitude):  # none, or 0: no field for the mesh to resolve
            continue
        degree = kind + "_degree"
        if options.get(degree) is not None:
            option = "--" + degree.replace("_", "-")
        else:
            option = flag_d if options.get(in_d) is not None \
                else "--" + amplitude.replace("_", "-")
        check_smooth_degree(option, typed(args, option), options.get(degree) or DEFAULT_DEGREE,
                            n, mesh=mesh, kind=kind)
        if kind == "shape" and options[amplitude]:
            flag = flag_d if options.get(in_d) is not None else "--shape-imperfection"
            try:
                check_shape(options[amplitude], options.get(degree) or DEFAULT_DEGREE,
                            options.get("seed", protocol_defaults()["seed"]))
            except ValueError as exc:
                raise ValueError(f"{flag} {typed(args, flag)}: {exc}") from None


def _as_continue(args):
    """The ``continue`` arguments that ``deflate --from DIR`` stands for (a volume path)."""
    import argparse

    for name in NEW_SHELL:
        if getattr(args, name) is not None:
            flag = "--" + name.replace("_", "-")
            raise ValueError(f"{flag} {typed(args, flag, getattr(args, name))}: cannot be "
                             "combined with --from: the run continues with the stored mesh, "
                             "parameters and energy")
    if args.out is None:
        raise ValueError(f"--from {typed(args, '--from', args.from_run)}: needs --out: the "
                         "new run gets its own folder")
    given = {name: getattr(args, name) for name in vars(args)}
    return argparse.Namespace(**given | {
        "dir": args.from_run, "dir_option": "--from", "gamma": None, "c0": None, "increments": None,
        "then_deflate_to": None, "then_out": None, "compare": None, "compare_step": None,
        "json": False})
