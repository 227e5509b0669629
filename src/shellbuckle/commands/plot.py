"""``shellbuckle plot DIR... [--out DIR] [--format png,pdf] [--at DV] [--units reduced|si]
[--potato DIR --capsule DIR] [--pair DIR DIR]``: the paper's figures that the given runs allow.

For each run: the run figure (energy and pressure vs dV/V, the last conformation in 3D;
:func:`shellbuckle.plots.run.plot_deflation`), Fig. 9 (E/kappa vs dV/V with the theory), the
gallery of its conformations (:mod:`shellbuckle.plots.paper`) and its pressure-volume figure
with the branches started from it (:func:`shellbuckle.plots.pv.plot_pv`); these are drawn in
``--units`` (reduced, or SI for runs made from a material). With several runs: Fig. 7 (conformations at dV/V = 0.854),
Fig. 9 of all runs together and the across-run Figs. 4, 5 and 10
(:func:`shellbuckle.plots.across.plot_across_runs`). ``--potato``/``--capsule``: Fig. 3;
``--pair``: Fig. 11. Prints the files written, one per line. Nothing is written in the runs.
"""

from __future__ import annotations

import logging
from pathlib import Path

from ._checks import add_command, add_number, input_file, output_folder, run_folder, the_work

log = logging.getLogger(__name__)


def register(sub) -> None:
    parser = add_command(
        sub, "plot", help="write the paper's figures (Figs. 3, 4, 5, 7, 9, 10, 11, galleries) from run folders",
        description="Write the figures the runs DIR... allow, as PNG (300 dpi) and PDF: for "
                    "each run, the run figure (energy and pressure vs dV/V with the theory, the "
                    "last conformation in 3D), Fig. 9 (E/kappa vs dV/V with U_sphere, U_axisym, "
                    "the primary buckling and the crossing), the gallery of its conformations "
                    "and the pressure-volume figure (p/p_c vs dV/V) of the run and its "
                    "branches, in --units; with "
                    "several runs, Fig. 7 (one conformation per run at dV/V = 0.854 or the "
                    "nearest stored step), Fig. 9 of all the runs and the across-run Figs. 4, 5 "
                    "and 10; with --potato/--capsule, Fig. 3; with --pair, Fig. 11. "
                    "Conformations are seen along their dent axis and coloured by mean "
                    "curvature (docs/figures.md). Prints the files written.")
    parser.add_argument("dirs", nargs="*", metavar="DIR", help="run folder")
    parser.add_argument("--out", default="figures",
                        help="output folder, new or existing, in an existing folder (default: "
                             "figures)")
    parser.add_argument("--format", dest="formats", default="png,pdf",
                        help="comma-separated formats among png, pdf, svg (default png,pdf)")
    add_number(parser, "--dpi", "dpi", "resolution of the PNG files of Figs. 3, 7, 9, 11 and "
               "the galleries, dots per inch (default 300; Figs. 4, 5, 10 keep their own)",
               default=300)
    add_number(parser, "--at", "at", "dV/V of Fig. 7 (default 0.854, the paper's); when given, "
               "also of Figs. 3 and 11 (defaults: the paper's 0.171 for Fig. 3, the largest dV/V "
               "both runs reached for Fig. 11)", default=None, metavar="DV")
    add_number(parser, "--every", "every", "the per-run gallery shows every K-th step and the "
               "last (default: at most 8 panels)", default=None, metavar="K")
    parser.add_argument("--potato", metavar="DIR",
                        help="run without the zero-curvature cycle, for Fig. 3 (with --capsule)")
    parser.add_argument("--capsule", metavar="DIR",
                        help="run with the zero-curvature cycle, for Fig. 3 (with --potato)")
    parser.add_argument("--pair", nargs=2, metavar=("DIR_A", "DIR_B"),
                        help="two runs at the same gamma reaching one dV/V by different paths, "
                             "for Fig. 11")
    parser.add_argument("--units", choices=("reduced", "si"), default="reduced",
                        help="units of the per-run figures and of Fig. 9: reduced (default: "
                             "E/kappa, p/p_c, lengths in R) or si (energies in J, pressures in "
                             "Pa, lengths in m and curvatures in 1/m), for runs made from a "
                             "material (deflate --E --sigma --d --R, given in Pa and m); "
                             "Figs. 3, 4, 5, 7, 10 and 11 compare shells in reduced units")
    parser.add_argument("--reference", default=None, metavar="FILE",
                        help="the paper's reference JSON (default: found beside the package, "
                             "or $SHELLBUCKLE_REFERENCE); without it the figures show ours only")
    parser.set_defaults(func=_cmd)


def _formats(text: str) -> tuple:
    from ..plots.paper import FORMATS

    formats = tuple(f.strip().lower() for f in text.split(",") if f.strip())
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise ValueError(f"--format {text!r}: formats must be among {', '.join(FORMATS)}")
    return formats


def _run(path, option: str = "DIR"):
    run = run_folder(option, path)
    if not run.steps:
        raise ValueError(f"{option} {path}: holds a run with no finished step yet")
    return run


def _stems(runs) -> list[str]:
    """One file stem per run: its folder name, made unique with a suffix when names repeat."""
    stems, seen = [], {}
    for run in runs:
        name = Path(run.path).name
        seen[name] = seen.get(name, 0) + 1
        stems.append(name if seen[name] == 1 else f"{name}_{seen[name]}")
    return stems


def _check_materials(runs) -> None:
    """--units si: every run must be made from a material (one line saying which is not)."""
    for run in runs:
        if not run.params.is_material:
            raise ValueError(f"--units si: the run {run.path} has no material (it was made "
                             "from gamma alone; SI units need a run made with --E --sigma "
                             "--d --R)")


def _cmd(args) -> int:
    from ..plots import paper
    from ..plots.pv import family, plot_pv
    from ..plots.run import plot_deflation

    formats = _formats(args.formats)
    if (args.potato is None) != (args.capsule is None):
        raise ValueError("--potato and --capsule go together (Fig. 3 compares the two runs)")
    if not args.dirs and args.potato is None and args.pair is None:
        raise ValueError("nothing to plot: give run folders DIR..., --potato/--capsule or "
                         "--pair")
    runs = [_run(d) for d in args.dirs]
    if args.units == "si":
        _check_materials(runs)
    potato = ((_run(args.potato, "--potato"), _run(args.capsule, "--capsule"))
              if args.potato is not None else None)
    pair = tuple(_run(d, "--pair") for d in args.pair) if args.pair is not None else None
    if args.reference is not None:
        input_file("--reference", args.reference)
    reference = paper.load_reference(args.reference, required=False)
    out = output_folder("--out", args.out)
    written: list[Path] = []

    def save(fig, stem):
        written.extend(paper.save(fig, out / stem, formats, dpi=args.dpi))
        if getattr(fig.canvas, "manager", None) is not None:  # a pyplot figure (run figure)
            import matplotlib.pyplot as plt

            plt.close(fig)

    with the_work():  # a ValueError of the figures is a failure, the input was accepted
        units = args.units
        for run, stem in zip(runs, _stems(runs)):
            save(plot_deflation(run, units=units), f"{stem}_run")
            save(paper.fig9_energy([run], units=units), f"{stem}_fig09_energy")
            save(paper.run_gallery(run, every=args.every, units=units), f"{stem}_gallery")
            # p vs dV/V, with the run's branches beside it
            save(plot_pv(family(run), units=units), f"{stem}_pv")
        if len(runs) > 1:
            at = paper.GALLERY_DV_OVER_V if args.at is None else args.at
            save(paper.fig7_gallery(runs, at=at, reference=reference), "fig07_gallery")
            save(paper.fig9_energy(runs, units=units), "fig09_energy")
            written.extend(_across([Path(r.path) for r in runs], out, formats, reference))
        if potato is not None:
            save(paper.fig3_potato_capsule(*potato, at=args.at, reference=reference),
                 "fig03_potato_capsule")
        if pair is not None:
            save(paper.fig11_paths(*pair, at=args.at, reference=reference), "fig11_paths")
    for path in written:
        print(path)
    return 0


def _across(paths, out: Path, formats, reference) -> list[Path]:
    """Figs. 4, 5 and 10 by :func:`shellbuckle.plots.across.plot_across_runs` (skipped, with a
    warning, when that module is not available)."""
    try:
        from ..plots.across import plot_across_runs
    except ImportError as exc:
        log.warning("across-run figures (Figs. 4, 5, 10) skipped: %s", exc)
        return []
    return [Path(p) for p in plot_across_runs(paths, out, formats, reference=reference)]
