"""Figure of the paper's theory (section 3): energies of the shrunk sphere and of the capsule.

Drawn with matplotlib's object API on a :class:`~matplotlib.figure.Figure` (Agg canvas), so no
display and no global pyplot state are needed.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .. import theory
from ..params import ShellParameters
from .render import place_legend

__all__ = ["plot_theory"]

log = logging.getLogger(__name__)

_STYLE = {
    "sphere": dict(color="#1f4e9c", lw=1.8, ls="-"),
    "sphere_exact": dict(color="#6a9bd8", lw=1.4, ls="-."),
    "axisym": dict(color="#c23b22", lw=1.8, ls="--"),
    "asymptotic": dict(color="0.45", lw=1.0, ls=":"),
    "crossing": dict(color="black", lw=0.9, ls="-"),
    "classical": dict(color="#2e8b57", lw=1.1, ls=(0, (4, 2, 1, 2))),
}


def _marks(ax, info: dict) -> None:
    """Vertical lines at the energy crossing and at the classical threshold."""
    xc = info["crossing_dV_over_V"]
    if xc is not None:
        ax.axvline(xc, **_STYLE["crossing"], alpha=0.6, zorder=1)
        ax.plot([xc], [info["crossing_energy"]], "o", ms=5, mfc="white", mec="black", zorder=5,
                label=r"$U_\mathrm{sphere}=U_\mathrm{axisym}$: "
                      rf"$\Delta V/V={xc:.3g}$")
    xt = info["classical_dV_over_V"]
    if xt <= 1:
        ax.axvline(xt, **_STYLE["classical"], zorder=1,
                   label=r"classical $p_c=4\sqrt{\kappa A}/R^2$: "
                         rf"$\Delta V/V\approx 6(1-\nu)/\sqrt{{\gamma}}={xt:.3g}$")


def _curves(ax, params: ShellParameters, x: np.ndarray, asymptotic: bool) -> None:
    kappa = params.kappa
    x_axi = x[x < 1.0]
    ax.plot(x, theory.U_sphere(x, params) / kappa, **_STYLE["sphere"],
            label=r"$U_\mathrm{sphere}$ (eq. Usphere, small strain)")
    ax.plot(x, theory.U_sphere_exact(x, params) / kappa, **_STYLE["sphere_exact"],
            label=r"$U_\mathrm{sphere}$, exact Green–Lagrange")
    ax.plot(x_axi, theory.U_axisym_of_dV(x_axi, params) / kappa, **_STYLE["axisym"],
            label=r"$U_\mathrm{axisym}$ (eq. Ucapsule)")
    if asymptotic:
        ax.plot(x_axi, theory.U_axisym_asymptotic_of_dV(x_axi, params) / kappa,
                **_STYLE["asymptotic"],
                label=r"$U_\mathrm{axisym}\propto\gamma^{-3/4}(\Delta V/V)^{3/4}$ (thin limit)")


def _overview(ax, params: ShellParameters, info: dict) -> None:
    """Linear dV/V on [0, 1], logarithmic energy: the whole deflation."""
    x = np.linspace(0.0, 1.0, 1201)[1:]
    x = x[x < 1.0 - 1e-4]
    _curves(ax, params, x, asymptotic=False)
    _marks(ax, info)
    u_axi = theory.U_axisym_of_dV(x, params) / params.kappa
    top = 3.0 * float(theory.U_sphere_exact(1.0, params)) / params.kappa
    ax.set_yscale("log")
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(0.3 * float(u_axi.min()), top)
    ax.annotate(r"eq. Ucapsule diverges as $\Delta V/V\to 1$ ($\alpha\to\pi/2$)",
                xy=(0.98, 0.03), xycoords="axes fraction", ha="right", va="bottom",
                fontsize="x-small", color="0.35")
    ax.set_xlabel(r"relative volume loss $\Delta V/V$")
    ax.set_ylabel(r"elastic energy $U/\kappa$")
    ax.grid(True, which="major", alpha=0.25)


def _zoom(ax, params: ShellParameters, info: dict) -> None:
    """Log-log around the crossing, with the paper's thin-shell asymptotic capsule energy."""
    centre = info["crossing_dV_over_V"] or info["crossing_asymptotic_dV_over_V"] or 0.1
    lo = max(min(centre / 30.0, info["classical_dV_over_V"] / 30.0), 1e-12)
    x = np.geomspace(lo, 0.999, 600)
    _curves(ax, params, x, asymptotic=True)
    _marks(ax, info)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(lo, 1.0)
    u = theory.U_sphere(x, params) / params.kappa
    u_axi = theory.U_axisym_of_dV(x, params) / params.kappa
    ax.set_ylim(0.3 * min(u.min(), u_axi.min()), 3.0 * float(theory.U_sphere_exact(0.999, params))
                / params.kappa)
    ax.set_xlabel(r"relative volume loss $\Delta V/V$")
    ax.set_ylabel(r"elastic energy $U/\kappa$")
    ax.grid(True, which="major", alpha=0.25)


def _title(params: ShellParameters) -> str:
    return (rf"$\gamma={params.gamma:.6g}$, $\nu={params.nu:.3g}$, "
            rf"$d/R={params.d_over_R:.3g}$")


def plot_theory(params: ShellParameters, path=None, ax=None) -> Figure:
    """Energies of paper section 3 against the relative volume loss ``dV/V``.

    Plots, in units of ``kappa`` (E/kappa): ``U_sphere`` (eq. Usphere), the exact
    Green-Lagrange energy of the uniformly shrunk sphere and ``U_axisym`` (eq. Ucapsule with
    eq. deltaV_vs_alpha), and marks the crossing ``U_sphere = U_axisym`` and the classical
    threshold ``dV/V = 6 (1 - nu)/sqrt(gamma)`` (``p_c = 4 sqrt(kappa A)/R^2``).

    Without ``ax``: a two-panel figure, (a) linear dV/V on [0, 1] with logarithmic energy,
    (b) log-log around the crossing with the paper's thin-shell asymptotic form, and one
    legend for both below them (the curves and the vertical marks fill every corner of the
    panels). With ``ax``: panel (a) only, drawn into ``ax``, its legend framed where it covers
    the fewest points of the curves (:func:`~shellbuckle.plots.render.place_legend`; the
    caller's figure may leave no room beside the axes). ``path``: the figure is saved there in the format of
    its suffix (``.png``; a ``.pdf`` path also gets a PNG of the same name). Returns the
    Figure. ``ValueError`` when d/R is undefined (nu >= 1/2).
    """
    info = theory.summary(params)
    if info["d_over_R"] is None:
        params.d_over_R  # raises the ValueError that names nu and its range
    info["crossing_energy"] = (None if info["crossing_dV_over_V"] is None else
                               theory.U_sphere(info["crossing_dV_over_V"], params)
                               / params.kappa)
    if ax is None:
        fig = Figure(figsize=(11.0, 5.4))  # fixed margins: constrained layout costs seconds
        ax_overview, ax_zoom = fig.subplots(1, 2)
        fig.subplots_adjust(left=0.065, right=0.98, bottom=0.27, top=0.885, wspace=0.2)
        _overview(ax_overview, params, info)
        _zoom(ax_zoom, params, info)
        ax_overview.set_title("(a) whole deflation", loc="left", fontsize="medium")
        ax_zoom.set_title("(b) log-log, with the thin-shell limit", loc="left",
                          fontsize="medium")
        fig.legend(*ax_zoom.get_legend_handles_labels(), loc="lower center", ncol=3,
                   bbox_to_anchor=(0.5, 0.005), fontsize="small", frameon=False)
        fig.suptitle("Shrunk sphere vs. inverted cap (Quilliet et al. 2008, §3): "
                     + _title(params))
    else:
        fig = ax.figure
        _overview(ax, params, info)
        ax.set_title(_title(params))
    if info["crossing_dV_over_V"] is None:
        log.info("no U_sphere = U_axisym crossing at gamma = %g", params.gamma)
        (ax or fig.axes[0]).annotate(
            r"no crossing: $U_\mathrm{axisym}>U_\mathrm{sphere}$ for all $\Delta V/V$",
            xy=(0.02, 0.97), xycoords="axes fraction", ha="left", va="top", fontsize="small")
    if ax is not None:  # last: where it covers the fewest curves (a frame fades what is under)
        place_legend(ax, outside=False, fontsize="small", framealpha=0.9)
    if path is not None:
        path = Path(path)
        fig.savefig(path, dpi=200)
        if path.suffix.lower() == ".pdf":
            fig.savefig(path.with_suffix(".png"), dpi=200)
        log.info("theory figure written to %s", path)
    return fig
