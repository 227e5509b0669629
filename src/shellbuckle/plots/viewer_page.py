"""The viewer page built from a run object: the part of :mod:`shellbuckle.plots.viewer` that
does not open run folders, so that the run object itself can show its page
(:meth:`shellbuckle.run.Run.view`) without an import circle (tests/test_import_graph.py).

:func:`page_of` makes the page's text (what the page shows: :mod:`shellbuckle.plots.viewer`);
:class:`ViewerPage` holds it, shows itself inline in Jupyter (an iframe whose ``srcdoc`` is
the page: nothing is served or fetched) and writes itself to a file.
"""

from __future__ import annotations

import base64
import html
import json
import logging
import math
import sys
from importlib import resources
from pathlib import Path

import numpy as np

from ..params import convention_formula

log = logging.getLogger(__name__)

__all__ = ["COLORS", "ViewerPage", "in_notebook", "page_of"]

COLORS = ("curvature", "strain", "bending")
"""Colourings of the surface: mean curvature, stretching and bending energy densities."""

# colour scales: anchors sampled from matplotlib's RdBu_r and viridis at 9 equally spaced points
_DIVERGING = ["#053061", "#2a71b2", "#6bacd1", "#c2ddec", "#f7f6f6", "#fbccb4", "#e48066",
              "#ba2832", "#67001f"]
_SEQUENTIAL = ["#440154", "#472d7b", "#3b528b", "#2c728e", "#21918c", "#28ae80", "#5ec962",
               "#addc30", "#fde725"]
_CLIP_PERCENTILE = 98.0  # colour ranges ignore the most extreme 2 % of the values

_TABLE_COLUMNS = {  # column -> header shown in the page
    "step": "step", "dV_over_V": "ΔV/V", "E_total": "E", "E_bend": "E_bend",
    "E_stretch": "E_stretch", "pressure": "p", "iterations": "iter",
    "min_distance": "min dist", "wall_s": "wall s", "shape": "shape", "n_dimples": "dimples",
    "corners": "corners", "W": "W"}


def _lut(anchors) -> np.ndarray:
    """256 x 3 uint8 colours interpolated linearly between hex ``anchors``."""
    rgb = np.array([[int(a[i:i + 2], 16) for i in (1, 3, 5)] for a in anchors], float)
    t = np.linspace(0.0, 1.0, len(anchors))
    u = np.linspace(0.0, 1.0, 256)
    return np.rint(np.stack([np.interp(u, t, rgb[:, c]) for c in range(3)], axis=1)).astype(np.uint8)


def _b64(array: np.ndarray, dtype: str) -> str:
    return base64.b64encode(np.ascontiguousarray(array, dtype=dtype).tobytes()).decode("ascii")


def _field_payload(values: np.ndarray, label: str, unit: str, on: str, diverging: bool) -> dict:
    """Quantize ``values (S, n)`` to uint8 indices of a colour scale over a robust range."""
    finite = values[np.isfinite(values)]
    if diverging:
        hi = float(np.percentile(np.abs(finite), _CLIP_PERCENTILE)) if finite.size else 1.0
        hi = hi if hi > 0 else 1.0
        lo = -hi
    else:
        lo = float(min(finite.min(), 0.0)) if finite.size else 0.0
        hi = float(np.percentile(finite, _CLIP_PERCENTILE)) if finite.size else 1.0
        hi = hi if hi > lo else lo + (abs(lo) or 1.0)
    index = np.rint((np.nan_to_num(values, nan=lo) - lo) / (hi - lo) * 255.0)
    return {"label": label, "unit": unit, "on": on, "lo": lo, "hi": hi,
            "clip_lo": bool(finite.size and finite.min() < lo),
            "clip_hi": bool(finite.size and finite.max() > hi),
            "lut": _b64(_lut(_DIVERGING if diverging else _SEQUENTIAL), "u1"),
            "data": _b64(np.clip(index, 0, 255), "u1")}


def _view_matrix(X0: np.ndarray, X_last: np.ndarray) -> list:
    """Row-major rotation that turns the mean direction of the largest displacement toward
    the viewer (+z), tilted by 35 degrees so that the rim of a dent shows in relief."""
    u = np.linalg.norm(X_last - X0, axis=1)
    d = (u[:, None] * X0).sum(axis=0)
    if not np.linalg.norm(d) > 1e-12 * max(u.sum(), 1e-300):
        d = np.array([0.3, 0.5, 0.8])
    d = d / np.linalg.norm(d)
    t = np.array([0.0, math.sin(math.radians(35.0)), math.cos(math.radians(35.0))])
    v, c = np.cross(d, t), float(d @ t)
    if np.linalg.norm(v) < 1e-12:
        R = np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    else:
        K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        R = np.eye(3) + K + K @ K / (1.0 + c)  # Rodrigues: R d = t
    return [float(x) for x in R.ravel()]


def _jsonable(value):
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    try:
        import pandas as pd

        if pd.isna(value):
            return None
    except (TypeError, ValueError):
        pass
    return str(value)


def _table_payload(table) -> dict:
    columns = [c for c in _TABLE_COLUMNS if c in table.columns]
    rows = [[_jsonable(v) for v in row] for row in table[columns].itertuples(index=False)]
    return {"columns": columns, "labels": {c: _TABLE_COLUMNS[c] for c in columns}, "rows": rows}


def _energy(run):
    """The run's own energy terms and ``c0`` (c = c1 + c2; the protocol's, ``2/R`` when it
    gave none), on its stress-free shape or the rest metrics it was started with: the terms of
    :class:`shellbuckle.export.RunFields`, built here from the run's values because the export
    module opens run folders and this one must not (tests/test_import_graph.py);
    tests/test_viewer.py checks that both give the same colours."""
    from ..energies.total import ShellEnergy
    from ..mesh.mesh import Mesh

    params, protocol = run.params, run.protocol
    c0 = 2.0 / params.R if protocol.c0 is None else float(protocol.c0)
    mesh = Mesh.from_arrays(np.asarray(run.store.X0, dtype=np.float64), run.faces)
    X0, profile = protocol.stress_free(mesh.X)
    energy = ShellEnergy.build(mesh, params, bending=protocol.bending, c0=c0, reference=X0,
                               form_factors=run.store.rest.get("form_factors"),
                               c0_profile=profile)
    return X0, energy, c0


def _payload(run, color: str, step: int = -1) -> dict:
    steps = list(run.steps)
    if not steps:
        raise ValueError(f"run {str(run.path)!r} has no finished step to show")
    start = steps.index(run.step(step))
    table = run.table.set_index("step", drop=False).loc[steps]
    X0, energy, c0 = _energy(run)
    kappa = float(run.params.kappa_helfrich)
    faces = np.asarray(run.faces)
    V, F = len(X0), len(faces)
    P = np.stack([np.asarray(run.positions(k), dtype=np.float64) for k in steps])  # (S, V, 3)
    H = np.stack([np.asarray(energy.bending.mean_curvature(X), dtype=np.float64) for X in P])
    bend = 0.5 * kappa * (2.0 * H - energy.bending.c0_vertices) ** 2  # per area, as RunFields
    strain = np.stack([np.asarray(energy.stretching.density(X), dtype=np.float64) for X in P])
    lo, hi = P.min(axis=(0, 1)), P.max(axis=(0, 1))
    span = np.where(hi - lo > 0, hi - lo, 1.0)
    hi = lo + span
    q = np.rint((P - lo) / span * 65535.0)
    center = 0.5 * (lo + hi)
    radius = float(np.linalg.norm(P - center, axis=2).max()) or 1.0
    params, protocol = run.params, run.protocol
    status, message = run.store.current_status()
    title = f"shellbuckle run {Path(run.path).name}"
    subtitle = (f"γ = {params.gamma:.6g}, ν = {params.nu:.4g}, κ = {params.kappa:.4g}, "
                f"R = {params.R:.4g}, c0 = {c0:.4g} (c = c1 + c2), "
                f"energy convention {params.energy_convention} "
                f"({convention_formula(params.energy_convention)}"
                + (f", γ_eff = {params.gamma_effective:.6g}), "
                   if params.energy_convention != "helfrich" else "), ") +
                f"bending {protocol.bending}, c0 cycle {'on' if protocol.c0_cycle else 'off'}, "
                f"{V} vertices, {F} faces · status {status}" + (f" ({message})" if message else ""))
    note = ("Colours use one range for all steps (the extreme 2 % of values are clipped). "
            "Curvature: vertex mean curvature H = (c1 + c2)/2 of the run's bending "
            "discretization. Strain: stretching energy per rest area of each triangle. "
            "Bending: κ_H/2 (2H − c0)² per area at each vertex, κ_H = "
            f"{params.kappa_helfrich:.4g} (the helfrich modulus of the energy convention).")
    return {
        "title": title, "subtitle": subtitle, "note": note,
        "n_vertices": V, "n_faces": F, "steps": steps, "start": start,
        "faces_dtype": "uint16" if V <= 65535 else "uint32",
        "faces": _b64(faces, "<u2" if V <= 65535 else "<u4"),
        "positions": _b64(q, "<u2"),
        "box": [float(x) for x in np.concatenate([lo, hi])],
        "center": [float(x) for x in center], "radius": radius,
        "view": _view_matrix(X0, P[-1]),
        "color": color, "frame_ms": 250,
        "fields": {
            "curvature": _field_payload(H, "mean curvature H", "1/R", "vertex", True),
            "strain": _field_payload(strain, "stretching energy density", "κ/R²", "face", False),
            "bending": _field_payload(bend, "bending energy density", "κ/R²", "vertex", False),
        },
        "table": _table_payload(table),
    }


def _template() -> str:
    return resources.files(__package__).joinpath("viewer.html").read_text(encoding="utf-8")


def page_of(run, color: str = "curvature", step: int = -1) -> str:
    """The viewer page of ``run`` (a :class:`~shellbuckle.run.Run`) as text, opening at step
    ``step`` (:meth:`~shellbuckle.run.Run.step`: negative counts from the last).

    ``color`` is the initial colouring, one of ``COLORS``; the page can switch between them.
    """
    if color not in COLORS:
        raise ValueError(f"color must be one of {', '.join(COLORS)}, got {color!r}")
    data = _payload(run, color, step)
    # JSON inside <script>: '<' escaped so that no '</script>' can end the element early
    text = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")
    page = _template()
    page = page.replace("__SHELLBUCKLE_TITLE__", html.escape(data["title"]), 1)
    return page.replace("__SHELLBUCKLE_DATA__", text, 1)


def in_notebook() -> bool:
    """Whether this code runs in a Jupyter kernel (an IPython shell with a kernel: Jupyter,
    JupyterLab, VS Code's notebooks), where a rich object is shown inline."""
    ipython = sys.modules.get("IPython")  # not imported: not in a kernel
    shell = ipython.get_ipython() if ipython is not None else None
    return getattr(shell, "kernel", None) is not None


class ViewerPage:
    """A viewer page: its text ``html``, the file ``path`` it was written to (or None) and the
    ``height`` in pixels of its inline frame.

    Jupyter shows it inline through ``_repr_html_``: an iframe whose ``srcdoc`` holds the page
    (sandboxed to run its scripts only), so nothing is served or fetched.
    """

    def __init__(self, html_text: str, path=None, height: int = 760):
        self.html = html_text
        self.path = None if path is None else Path(path)
        self.height = int(height)

    def iframe(self) -> str:
        """The HTML of an inline frame holding the page."""
        return (f'<div class="shellbuckle-view"><iframe '
                f'srcdoc="{html.escape(self.html, quote=True)}" '
                f'style="width: 100%; height: {self.height}px; border: 0;" '
                'sandbox="allow-scripts"></iframe></div>')

    def _repr_html_(self) -> str:
        return self.iframe()

    def write(self, path) -> Path:
        """Write the page to ``path`` (its folder must exist); return the path, also kept in
        :attr:`path`."""
        from ..store.names import refuse_store_file

        path = Path(path)
        refuse_store_file(path)
        if not path.parent.is_dir():
            raise FileNotFoundError(f"directory {str(path.parent)!r} does not exist")
        path.write_text(self.html, encoding="utf-8")
        log.info("viewer page written to %s (%.2f MB)", path, self.size / 1e6)
        self.path = path
        return path

    def open(self) -> bool:
        """Open :attr:`path` in the default web browser; whether one was found. ValueError
        when the page has not been written to a file."""
        import webbrowser

        if self.path is None:
            raise ValueError("the page has not been written to a file: call write(path) first")
        return bool(webbrowser.open(self.path.resolve().as_uri()))

    @property
    def size(self) -> int:
        """The page's size in bytes (UTF-8)."""
        return len(self.html.encode("utf-8"))

    def __repr__(self):
        where = "not written" if self.path is None else f"path={str(self.path)!r}"
        return f"ViewerPage({where}, {self.size / 1e6:.2f} MB)"
