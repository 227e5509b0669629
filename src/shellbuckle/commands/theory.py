"""``shellbuckle theory [--gamma G] [--nu NU] [--out PATH] [--json]``: the paper's §3 theory."""

from __future__ import annotations

import sys

from ._checks import add_command, output_file
from ._options import add_shell_options


def register(sub) -> None:
    parser = add_command(
        sub, "theory", help="plot the paper's theory curves and print the buckling estimates",
        description="Plot U_sphere (small strain and exact), U_axisym and the crossing of "
                    "Quilliet et al. (2008) section 3 against dV/V, write the figure, and print "
                    "d/R, the crossing U_sphere = U_axisym and the classical threshold. "
                    "Energies in units of kappa, pressures in kappa/R^3.")
    add_shell_options(parser, material=False, defaults=True, convention_default="helfrich")
    parser.add_argument("--out", default="shellbuckle_theory.png",
                        help="figure file, .png or .pdf, in an existing folder (default "
                             "shellbuckle_theory.png)")
    parser.add_argument("--json", action="store_true",
                        help="print the numbers as one JSON object")
    parser.set_defaults(func=_cmd)


def _cmd(args) -> int:
    import json
    import warnings
    from ..params import ShellParameters
    from ..plots.theory import plot_theory
    from ..theory import summary

    out = output_file("--out", args.out, suffixes=(".png", ".pdf"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        params = ShellParameters.from_gamma(args.gamma, nu=args.nu,
                                            energy_convention=args.energy_convention)
    for w in caught:
        print(f"shellbuckle theory: warning: {w.message}", file=sys.stderr)
    plot_theory(params, path=out)
    info = summary(params)
    if args.json:
        print(json.dumps({**info, "figure": str(out)}))
        return 0
    _print(params, info)
    print(f"figure: {out}")
    return 0


def _print(params, info: dict) -> None:
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
