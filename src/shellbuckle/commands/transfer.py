"""``shellbuckle transfer SOURCE TARGET [--step K] [--out FILE]``: a step of one mesh carried to
another mesh of the same shell and relaxed there (:mod:`shellbuckle.studies.transfer`)."""

from __future__ import annotations

import math

from ._checks import add_command, add_number, output_file, run_folder, the_work
from ._options import add_threads_option, stored_step


def register(sub) -> None:
    parser = add_command(
        sub, "transfer", help="carry a step of one mesh to another mesh of the same shell, "
                              "relax it there and compare it with that mesh's own step",
        description="Interpolate step K of the run SOURCE at the material points of the run "
                    "TARGET's mesh (the same shell: parameters, c0 and shape imperfection), "
                    "minimize it there at the same dV/V with TARGET's energy (no jiggle, no "
                    "zero-curvature cycle), and print the energy and class (shape, W) of the "
                    "source's step, of the carried start and minimum, and of TARGET's own step "
                    "at the same dV/V, with the carried minimum's energy relative to it. A "
                    "state of the shell relaxes to the same class at the target's energy; a "
                    "state of the source's mesh only relaxes to another class, or lies above "
                    "(docs/mesh-convergence.md). Nothing is written to either run. Exit "
                    "status 1 if a carried state does not relax to a certified minimum (which "
                    "needs TARGET's minimizer to be Newton's method, the default).")
    parser.add_argument("source", metavar="SOURCE", help="run folder of the step to carry")
    parser.add_argument("target", metavar="TARGET", help="run folder of the mesh to carry it to")
    add_number(parser, "--step", "step", "step of SOURCE (negative counts from the last; "
               "default -1)", metavar="K", default=-1)
    parser.add_argument("--both-ways", action="store_true",
                        help="also carry TARGET's step at the same dV/V to SOURCE's mesh")
    parser.add_argument("--out", metavar="FILE",
                        help="write the carried minimum (on TARGET's mesh) as a mesh file, as "
                             "shellbuckle export does (vtk, vtu, ply, obj, stl, fe by the "
                             "extension)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    add_threads_option(parser)
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    from ..export import FORMATS

    source, target = run_folder("SOURCE", args.source), run_folder("TARGET", args.target)
    if args.out is not None:
        output_file("--out", args.out, tuple(FORMATS.values()))
    k = stored_step(source, args.step)
    from ..studies.transfer import check_same_shell, compare, own_step

    try:
        check_same_shell(source, target)
    except ValueError as exc:
        raise ValueError(f"TARGET {args.target}: {exc}") from None
    back = None
    if args.both_ways:
        dv = float(source.store.record(k)["dV_over_V"])
        back = own_step(target, dv)
        if back is None:
            raise ValueError(f"--both-ways: TARGET {args.target} has no step at dV/V = "
                             f"{dv:.6g} (step {k} of SOURCE) to carry back")
    with the_work():
        results = [compare(source, k, target, threads=args.threads)]
        if back is not None:
            results.append(compare(target, back, source, threads=args.threads))
        if args.out is not None:
            from ..export import export_conformation

            first = results[0]
            export_conformation(target, first.transferred.X, args.out,
                                values={"dV_over_V": first.dV_over_V,
                                        "E_over_kappa": first.carried.E_over_kappa},
                                what=f"step {k} of run {source.path} carried")
    if args.json:
        from ._output import print_json

        print_json([r.as_dict() for r in results] if back is not None
                   else results[0].as_dict())
    else:
        for r in results:
            _print(r)
        if args.out is not None:
            print(f"carried minimum written to {args.out}")
    return 0 if all(r.certified for r in results) else 1


def _print(r) -> None:
    print(f"{r.source_path} carried to the mesh of {r.target_path}, at dV/V = "
          f"{r.dV_over_V:.6g}:")
    rows = [(r.source.what, r.source), ("carried, start", None), (r.carried.what, r.carried)]
    if r.own is not None:
        rows.append((r.own.what, r.own))
    width = max(len(what) for what, _ in rows)
    print(f"  {'':{width}}  {'E/kappa':>14}  {'shape':<10} {'W':>3}")
    for what, s in rows:
        if s is None:
            print(f"  {what:{width}}  {r.start_E_over_kappa:14.8g}")
        else:
            print(f"  {what:{width}}  {s.E_over_kappa:14.8g}  {s.shape:<10} {s.W:>3}")
    status = "a certified minimum" if r.certified else \
        f"NOT a certified minimum ({r.transferred.result.message})"
    print(f"  the carried state relaxed to {status}")
    if r.own is None:
        print("  the target run has no step at this dV/V")
    elif math.isfinite(r.relative):
        same = "the same class" if (r.carried.shape, r.carried.W) == (r.own.shape, r.own.W) \
            else "another class"
        print(f"  carried minimum - target's own: {100 * r.relative:+.4f} % of its energy, "
              f"{same}")
    print()
