"""Figures of one run: energy and pressure along the path with the theory, and 3D views.

All figures use matplotlib's Agg backend (no display needed) and are saved as PNG, or PDF when
the path ends in ``.pdf``.
"""

from __future__ import annotations

import numpy as np

from .. import theory


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def render_surface(ax, X, faces, values=None, *, cmap="coolwarm", elev=20.0, azim=-60.0,
                   axis=None, vlim=None, label=None):
    """Draw a triangulated surface on a 3D axis, faces coloured by per-vertex ``values``.

    The view is fixed and documented: the camera looks from elevation ``elev`` and azimuth
    ``azim`` (degrees, matplotlib's convention) after the shape is rotated so that ``axis``
    (e.g. the dent axis) points along +z; with ``axis=None`` the shape is drawn as stored.
    ``vlim`` is the symmetric colour limit (default: the 98th percentile of ``|values|``).
    """
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    plt = _pyplot()
    X = np.asarray(X, float) - np.asarray(X, float).mean(axis=0)
    if axis is not None:
        X = X @ _rotation_to_z(np.asarray(axis, float)).T
    tri = X[faces]
    shade = None
    if values is not None:
        face_values = np.asarray(values, float)[faces].mean(axis=1)
        lim = vlim if vlim is not None else float(np.percentile(np.abs(face_values), 98)) or 1.0
        norm = plt.Normalize(-lim, lim)
        colors = plt.get_cmap(cmap)(norm(face_values))
        shade = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    else:
        colors = (0.75, 0.78, 0.85, 1.0)
    collection = Poly3DCollection(tri, facecolors=colors, edgecolors=(0, 0, 0, 0.08),
                                  linewidths=0.2)
    ax.add_collection3d(collection)
    r = np.abs(X).max()
    ax.set(xlim=(-r, r), ylim=(-r, r), zlim=(-r, r))
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=elev, azim=azim)
    ax.set_axis_off()
    if shade is not None and label:
        plt.colorbar(shade, ax=ax, shrink=0.6, pad=0.02, label=label)
    return collection


def _rotation_to_z(axis):
    """Rotation matrix taking the unit vector along ``axis`` to +z (Rodrigues)."""
    a = axis / np.linalg.norm(axis)
    z = np.array([0.0, 0.0, 1.0])
    v, c = np.cross(a, z), float(a @ z)
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def view_axis(X, faces):
    """The direction to look from at a conformation: out of its dent (the classifier's
    ``dent_axis``), or None without a dent. In a deep bowl the negative-curvature vertices lie
    past the centre, so their mean position would look at the back of the shell. Computed from
    the descriptors (the rim's axis, else the largest dent's), as the classifier does, without
    importing it: the classifier opens runs, and :meth:`shellbuckle.run.Run.plot` draws this."""
    from ..analysis.descriptors import ShapeAnalyzer

    X = np.asarray(X, dtype=np.float64)
    d = ShapeAnalyzer(faces, n_vertices=len(X)).describe(X)
    axis = d.rim.axis if d.rim is not None else (d.dents[0].axis if d.dents else None)
    return None if axis is None else np.asarray(axis, float)


def plot_run(table, params, X, faces, curvature=None, *, path=None, title=None, axis=None):
    """Three panels: E/kappa vs dV/V with U_sphere and U_axisym; pressure vs dV/V with the
    shrunk-sphere pressure and the classical threshold p_c; the last conformation in 3D,
    coloured by ``curvature`` (per-vertex mean curvature H, or None).

    ``table`` is a run's per-step DataFrame (columns ``dV_over_V``, ``E_over_kappa``,
    ``pressure``); ``params`` a :class:`~shellbuckle.params.ShellParameters`; ``axis``: the
    direction the 3D view looks from (:func:`view_axis`; None: the shape as stored).
    """
    plt = _pyplot()
    fig = plt.figure(figsize=(13.5, 4.2), constrained_layout=True)
    ax_e = fig.add_subplot(1, 3, 1)
    ax_p = fig.add_subplot(1, 3, 2)
    ax_s = fig.add_subplot(1, 3, 3, projection="3d")
    x = np.asarray(table["dV_over_V"], float)
    xmax = max(float(np.nanmax(x)) if len(x) else 0.0, 0.05) * 1.05
    grid = np.linspace(0.0, min(xmax, 0.999), 400)
    kappa = params.kappa
    ax_e.plot(grid, theory.U_sphere_exact(grid, params) / kappa, "--", color="0.4",
              label=r"$U_{sphere}$ (exact, uniform shrink)")
    ax_e.plot(grid[1:], theory.U_axisym_of_dV(grid[1:], params) / kappa, ":", color="C3",
              label=r"$U_{axisym}$ (inverted cap)")
    ax_e.plot(x, np.asarray(table["E_over_kappa"], float), "o-", ms=3, color="C0",
              label="simulation")
    ax_e.set(xlabel=r"$\Delta V/V$", ylabel=r"$E/\kappa$", xlim=(0, xmax),
             ylim=(0, 1.15 * max(float(np.nanmax(table["E_over_kappa"])), 1.0)))
    ax_e.legend(frameon=False, fontsize=8)
    threshold = theory.classical_threshold(params)
    p_scale = threshold.pressure
    ax_p.plot(grid, theory.pressure_sphere_exact(grid, params) / p_scale, "--", color="0.4",
              label="uniformly shrunk sphere")
    ax_p.axhline(1.0, color="C3", lw=0.8,
                 label=r"classical $p_c=4\sqrt{\kappa A}/R^2$" if params.bending_factor == 1
                 else rf"classical $p_c=4\sqrt{{{params.bending_factor:g}\kappa A}}/R^2$")
    ax_p.plot(x, np.asarray(table["pressure"], float) / p_scale, "o-", ms=3, color="C0",
              label="simulation")
    ax_p.set(xlabel=r"$\Delta V/V$", ylabel=r"pressure $p/p_c$", xlim=(0, xmax))
    top = float(np.nanmax(np.abs(np.asarray(table["pressure"], float)))) / p_scale
    ax_p.set_ylim(min(0.0, float(np.nanmin(table["pressure"])) / p_scale * 1.1),
                  max(1.3, 1.1 * top))
    ax_p.legend(frameon=False, fontsize=8)
    render_surface(ax_s, X, faces, curvature, axis=axis, elev=35.0,
                   label=r"mean curvature $H$" if curvature is not None else None)
    last = table.iloc[-1]
    ax_s.set_title(rf"step {int(last['step'])}, $\Delta V/V$ = {float(last['dV_over_V']):.3f}",
                   fontsize=9)
    fig.suptitle(title or rf"$\gamma$ = {params.gamma:g}, $\nu$ = {params.nu:.3g}"
                 + params.convention_note.replace("gamma_eff", r"$\gamma_{eff}$"), fontsize=11)
    if path is not None:
        fig.savefig(path, dpi=150)
        plt.close(fig)
    return fig


def plot_deflation(run, path=None, step: int = -1):
    """The run figure (:func:`plot_run`) of a stored :class:`~shellbuckle.run.Run`, with the
    conformation of ``step`` (default: the last) coloured by Jülicher's mean curvature."""
    from ..energies.bending import Bending
    from ..mesh.topology import Topology

    X = run.positions(step)
    faces = run.faces
    H = Bending.from_mesh(Topology.from_faces(faces, len(X))).mean_curvature(X)
    table = run.table
    table = table[table["step"] <= run.step(step)]
    return plot_run(table, run.params, X, faces, H, path=path, axis=view_axis(X, faces))
