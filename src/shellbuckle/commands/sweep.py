"""``shellbuckle sweep [--config FILE.toml] [--gamma G,..] ... --out DIR``: runs on Dask."""

from __future__ import annotations

import sys

from ._checks import (RANGES, add_command, allowed, as_option, check_mesh,
                      check_smooth_degree, check_value, input_file, scheduler_address,
                      sweep_folder, the_work)
from ._options import (add_protocol_options, add_shell_options, default_gamma, shape_degrees,
                       values)

#: The protocol axes of a sweep (SweepSpec fields), as comma-separated lists.
PROTOCOL = ("seed", "dv", "until", "temperature", "jiggle", "bending", "method")
#: Each list option's kind; the names are SweepSpec's fields.
KINDS = {"gamma": float, "nu": float, "seeds": int, "vertices": int, "icosphere": int,
         "dv": float, "until": float, "jiggle": float, "temperature": float, "bending": str,
         "method": str, "energy_convention": str, "smooth_jiggle": float, "smooth_degree": int,
         "shape_imperfection": float, "shape_imperfection_d": float, "shape_degree": str}
#: The range (a name of ``_checks.RANGES``) of each numeric axis.
SPANS = {"gamma": "gamma", "nu": "nu", "seeds": "seed", "vertices": "vertices",
         "icosphere": "icosphere", "dv": "dv", "until": "until_deflated", "jiggle": "jiggle",
         "temperature": "temperature", "smooth_jiggle": "smooth_jiggle",
         "smooth_degree": "smooth_degree", "shape_imperfection": "shape_imperfection",
         "shape_imperfection_d": "shape_imperfection_d", "shape_degree": "shape_degree"}
#: Runs of one sweep at most.
MAX_RUNS = 10_000


def register(sub) -> None:
    parser = add_command(
        sub, "sweep", help="run a grid of deflations in parallel on Dask, resumable, with a catalogue",
        description="Run every combination of the given values (gamma x nu x mesh x seeds x "
                    "protocol options) as one deflation, each in its own run folder in DIR named "
                    "from its parameters (e.g. g2333_nu0.333_v3594_s0), on a local Dask cluster "
                    "of single-threaded workers (default: one per core) or on the Dask scheduler "
                    "at ADDR. DIR/catalogue.csv (one row per run: parameters, status, steps, "
                    "final dV/V, stop reason, thresholds, W, wall time) is rewritten as runs "
                    "finish. Running the same command again skips finished runs, resumes "
                    "unfinished ones from their last step and retries failed ones. Lists are "
                    "comma-separated; integer lists also take ranges (0-4). Values on the "
                    "command line replace those of --config; what neither gives takes the "
                    "defaults of `shellbuckle deflate`.")
    parser.add_argument("--config", metavar="FILE.toml", help="sweep file (see examples/sweep.toml)")
    add_shell_options(parser, material=False, listed=True)
    parser.add_argument("--vertices", metavar="N,..",
                        help="randomized spheres with N vertices (default 3594 unless --icosphere); "
                             + allowed("vertices"))
    parser.add_argument("--icosphere", metavar="N,..",
                        help="icosahedral spheres of level N (10 N^2 + 2 vertices); "
                             + allowed("icosphere"))
    add_protocol_options(parser, PROTOCOL, listed=True, flags={"seed": "--seeds"},
                         ranges={name: SPANS[name] for name in PROTOCOL if name in SPANS})
    add_protocol_options(parser, ("c0_cycle",))
    parser.add_argument("--smooth-jiggle", metavar="A,..",
                        help="comma-separated list of: rms amplitudes (units of R) of the smooth "
                             "imperfection that replaces the per-vertex jiggle, the same field "
                             "on any mesh (docs/mesh-convergence.md); "
                             + allowed("smooth_jiggle"))
    parser.add_argument("--smooth-degree", metavar="L,..",
                        help="comma-separated list of: highest degrees L of the smooth "
                             "imperfection (default 20); every mesh must resolve it with 4 "
                             "mean edges per wavelength 2 pi R/L; " + allowed("smooth_degree"))
    parser.add_argument("--shape-imperfection", metavar="A,..",
                        help="comma-separated list of: rms amplitudes (units of R) of the "
                             "shells' shape imperfection, their stress-free shape moved "
                             "radially by a seeded field, the same shell on every mesh of a "
                             "seed; " + allowed("shape_imperfection"))
    parser.add_argument("--shape-imperfection-d", metavar="B,..",
                        help="comma-separated list of: the same rms amplitudes in units of each "
                             "shell's effective thickness, converted per gamma and "
                             "convention, instead of "
                             "--shape-imperfection; " + allowed("shape_imperfection_d"))
    parser.add_argument("--shape-degree", metavar="L,..",
                        help="comma-separated list of: highest degrees L of the shape "
                             "imperfection (default 20), or 'critical': per shell ceil(l_c) + 1 "
                             "with l_c (l_c + 1) = sqrt(gamma_eff), the classical buckling band; "
                             "every mesh must resolve it; " + allowed("shape_degree"))
    parser.add_argument("--workers", metavar="N", help="local worker processes (default: "
                        "cores); " + allowed("workers"))
    parser.add_argument("--scheduler", metavar="ADDR",
                        help="address of a running Dask scheduler (e.g. tcp://host:8786)")
    parser.add_argument("--no-analysis", action="store_true",
                        help="do not classify the steps of finished runs (no thresholds or W)")
    parser.add_argument("--no-retry", action="store_true", help="do not rerun failed runs")
    parser.add_argument("--rescale-start", action="store_true",
                        help="every run starts each volume step from the last minimum scaled "
                             "uniformly to the new volume (faster before buckling on fine "
                             "meshes; runs named ..._rs; see deflate --rescale-start)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="sweep folder: new (in an existing folder), empty, or a previous "
                             "sweep to resume")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from pathlib import Path

    from ..sweep import SweepSpec, run_sweep

    given = {name: values(_flag(name), getattr(args, name), kind, SPANS.get(name, ""))
             for name, kind in KINDS.items()
             if getattr(args, name) is not None and name != "shape_degree"}
    if args.shape_degree is not None:
        given["shape_degree"] = shape_degrees(args.shape_degree)
    if args.no_c0_cycle:
        given["c0_cycle"] = False
    if args.rescale_start:
        given["rescale_start"] = True
    workers = _workers(args)
    scheduler_address("--scheduler", args.scheduler)
    defaults = {"gamma": [default_gamma()]}  # the one default gamma of the command line
    if args.config:
        input_file("--config", args.config)
    if args.shape_imperfection is not None and args.shape_imperfection_d is not None:
        raise ValueError(f"--shape-imperfection-d {args.shape_imperfection_d}: give either "
                         "--shape-imperfection (units of R) or --shape-imperfection-d (units of "
                         "d)")
    try:
        spec = (SweepSpec.from_toml(args.config, defaults=defaults, **given) if args.config
                else SweepSpec.from_dict(defaults | given))
    except ValueError as exc:  # named with the option as typed where the value was typed
        raise ValueError(as_option(str(exc), {name: (_flag(name), getattr(args, name))
                                              for name in given if name in KINDS})) from None
    _check(spec, given, args.config, args.gamma)
    sweep_folder("--out", args.out, spec)
    with the_work():
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


def _workers(args) -> int | None:
    """``--workers N`` (one integer >= 1, for the local cluster only), or None."""
    if args.workers is None:
        return None
    workers = values("--workers", args.workers, int)
    if len(workers) != 1:
        raise ValueError(f"--workers {args.workers}: allowed: one {RANGES['workers']}")
    check_value("--workers", "workers", workers[0], args.workers)
    if args.scheduler is not None:
        raise ValueError("--workers applies to the local cluster; a --scheduler has its "
                         "own workers")
    return workers[0]


def _flag(name: str) -> str:
    return f"--{name.replace('_', '-')}"


def _check(spec, given: dict, config, gamma_text=None) -> None:
    """Every value of the sweep in its range (values from --config too), at most
    :data:`MAX_RUNS` runs, and every mesh resolving every gamma."""
    from ..params import bending_factor

    for name, span in SPANS.items():
        where = _flag(name) if name in given or not config else f"--config {config}: {name}"
        for value in getattr(spec, name, None) or ():
            if value is not None and not isinstance(value, str):  # "critical": per shell
                check_value(where, span, value)
    if len(spec) > MAX_RUNS:
        raise ValueError(f"--out: the sweep has {len(spec)} runs; allowed: at most {MAX_RUNS}")
    meshes = [(n, f"--vertices {n}") for n in spec.vertices or ()]
    meshes += [(10 * n ** 2 + 2, f"--icosphere {n}") for n in spec.icosphere or ()]
    if not meshes:
        meshes = [(3594, "the default 3594-vertex mesh")]
    factor = min(bending_factor(c) for c in spec.energy_convention)
    gamma = max(spec.gamma)
    n, mesh = min(meshes)
    check_mesh("--gamma", gamma_text or f"{gamma:g}", gamma, n, gamma_effective=gamma / factor, mesh=mesh)
    from ..protocol.imperfection import DEFAULT_DEGREE

    points = spec.points()
    for kind, amplitude in (("smooth", "smooth_jiggle"), ("shape", "shape_imperfection")):
        field = [p for p in points if p.get(amplitude)]  # 0: no field to resolve
        if not field:
            continue
        degree = max(DEFAULT_DEGREE if p[f"{kind}_degree"] is None else p[f"{kind}_degree"]
                     for p in field)
        if None not in getattr(spec, f"{kind}_degree"):
            option = f"--{kind}-degree"
            text = ",".join(map(str, getattr(spec, f"{kind}_degree")))
        else:
            flag = amplitude + ("_d" if kind == "shape" and any(
                b is not None for b in spec.shape_imperfection_d) else "")
            option = "--" + flag.replace("_", "-")
            text = ",".join(f"{a:g}" for a in getattr(spec, flag) if a is not None)
        check_smooth_degree(option, text, degree, n, mesh=mesh, kind=kind)
