"""Classification of a conformation: sphere, dimples, capsule, polygonal, wrinkled, other.

The classes follow Quilliet et al. (EPJE 27, 13 (2008), §4.2-4.4), decided from the
descriptors of :mod:`.descriptors` and :mod:`.wrinkles`. The *rim* here is the outline of the
depression (the zero line of the smoothed mean curvature around the dent), the curve on which
the paper reads its secondary thresholds:

``sphere``
    no dent (no inverted-curvature region larger than the noise size).
``dimples``
    two or more separate dents, ``n_dimples`` of them: the paper's "potato" shapes obtained
    without the zero-spontaneous-curvature cycle.
``capsule``
    one dent whose rim is axisymmetric: every Fourier mode ``m >= 2`` of the rim radius has a
    relative amplitude below the axisymmetry threshold (below).
``polygonal``
    one dent whose rim lost axisymmetry (some mode ``m >= 2`` above the threshold) with
    ``corners`` apices (prominent maxima of the rim radius), the rim not concave between them.
``wrinkled``
    a polygonal rim that is concave between successive apices (dips inside the chord joining
    them, :mod:`.wrinkles`) on at least ``WRINKLED_FRACTION`` of its arcs (and at least two):
    ``W`` wrinkles, ``W = corners``.
``other``
    one dent whose rim cannot be traced around its axis, a non-axisymmetric rim with fewer
    than two apices, or one whose apices cannot be counted at the mesh's resolution
    (``count_resolved`` False: :attr:`.wrinkles.Curve.count_resolved`), so that no wrong
    number is reported.

The axisymmetry threshold is ``max(AXISYMMETRY_THRESHOLD, AXISYMMETRY_EDGES h / rim_radius)``
with ``h`` the mean edge length: the rim is located to a fraction of an edge, so the noise
floor of the mode amplitudes scales as ``h / rim_radius``. Calibration (docs/analysis.md): over
inverted caps in random orientations on icosahedral and random meshes of 642 and 3594
vertices the largest ``amplitude * rim_radius / h`` is 0.029, over the capsule steps of real
runs 0.066.
``corners`` and ``W`` are 0 where they do not apply (``W`` counts wrinkles only on wrinkled
rims, as the paper's Fig. 4 does).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from ..util import json_safe
from . import wrinkles
from .descriptors import Descriptors, ShapeAnalyzer

SHAPES = ("sphere", "dimples", "capsule", "polygonal", "wrinkled", "other")

#: A rim is axisymmetric when all its modes m >= 2 have relative amplitudes below
#: max(AXISYMMETRY_THRESHOLD, AXISYMMETRY_EDGES * h / rim_radius).
AXISYMMETRY_THRESHOLD = 0.01
AXISYMMETRY_EDGES = 0.15
#: A non-axisymmetric rim is wrinkled when at least this fraction of its arcs between
#: successive apices (and at least two arcs) are concave (:data:`wrinkles.CONCAVITY`).
WRINKLED_FRACTION = 0.5


@dataclass(frozen=True, eq=False)
class Classification:
    """The class of a conformation and the numbers behind it.

    ``shape`` (one of :data:`SHAPES`), ``n_dimples``, ``corners``, ``W``; the dent's
    ``dent_depth`` (indentation), ``dent_sagitta``, ``dent_axis (3,)`` (unit, out of the dent;
    ``None`` without a dent); the rim, i.e. the outline of the depression
    (:mod:`.wrinkles`): ``rim_radius``, ``rim_spectrum (N_MODES,)`` (relative amplitudes of the
    modes ``m = 1..N_MODES``), ``dominant_mode`` and ``dominant_amplitude`` (largest mode
    ``m >= 2``), ``axisymmetry_threshold`` used, ``concave_arcs``, ``count_resolved`` (False
    when the rim has apices that cannot be counted at the mesh's resolution, the shape is then
    ``other``); ``crest_radius`` (the ridge, the geometric rim); ``asphericity``,
    ``contact_distance``; and all ``descriptors``.
    """

    shape: str
    n_dimples: int
    corners: int
    W: int
    dent_depth: float
    dent_sagitta: float
    dent_axis: tuple | None
    rim_radius: float
    crest_radius: float
    rim_spectrum: tuple | None
    dominant_mode: int
    dominant_amplitude: float
    axisymmetry_threshold: float
    concave_arcs: int
    count_resolved: bool
    asphericity: float
    contact_distance: float
    descriptors: Descriptors = field(repr=False)

    def columns(self) -> dict:
        """Flat scalar values for the per-step table (``shape``, ``n_dimples``, ``corners``,
        ``W`` and the dent and rim numbers)."""
        return {"shape": self.shape, "n_dimples": self.n_dimples, "corners": self.corners,
                "W": self.W, "dent_depth": self.dent_depth, "dent_sagitta": self.dent_sagitta,
                "rim_radius": self.rim_radius, "crest_radius": self.crest_radius,
                "rim_mode": self.dominant_mode,
                "rim_amplitude": self.dominant_amplitude, "concave_arcs": self.concave_arcs,
                "asphericity": self.asphericity, "contact_distance": self.contact_distance}

    def as_dict(self) -> dict:
        """JSON-able summary (vectors as lists), with the full descriptors under
        ``descriptors``."""
        out = self.columns()
        out["dent_axis"] = None if self.dent_axis is None else list(self.dent_axis)
        out["rim_spectrum"] = None if self.rim_spectrum is None else list(self.rim_spectrum)
        out["axisymmetry_threshold"] = self.axisymmetry_threshold
        out["count_resolved"] = self.count_resolved
        out["descriptors"] = self.descriptors.as_dict()
        return out


def axisymmetry_threshold(curve: wrinkles.Curve, mean_edge: float) -> float:
    """Relative mode amplitude above which ``curve`` is not axisymmetric (module docstring)."""
    return max(AXISYMMETRY_THRESHOLD, AXISYMMETRY_EDGES * mean_edge / curve.radius)


def classify_descriptors(d: Descriptors) -> Classification:
    """Classify a conformation from its :class:`~.descriptors.Descriptors` (ValueError for a
    surface enclosing no positive volume: faces pointing inward, which turn every dent into
    a bump, or a shape no deflation reaches)."""
    volume = d.geometry.volume
    if not volume > 0:
        raise ValueError(f"the surface encloses a non-positive volume {volume!r}: a shell's "
                         "faces point outward (reverse them: faces[:, ::-1])")
    rim = d.rim
    outline = rim.outline if rim is not None else None
    n = d.n_dimples
    corners = W = 0
    threshold = math.nan
    resolved = True
    if n == 0:
        shape = "sphere"
    elif n >= 2:
        shape = "dimples"
    elif rim is None:
        shape = "other"
    else:
        threshold = axisymmetry_threshold(outline, d.geometry.mean_edge)
        if outline.dominant_amplitude < threshold:
            shape = "capsule"
        elif outline.n_apices < 2 or not outline.count_resolved:
            shape, resolved = "other", outline.count_resolved
        else:
            corners = outline.n_apices
            concave = outline.n_concave
            if concave >= 2 and concave >= WRINKLED_FRACTION * outline.n_apices:
                shape, W = "wrinkled", corners
            else:
                shape = "polygonal"
    main = d.dents[0] if d.dents else None
    axis = rim.axis if rim is not None else (main.axis if main is not None else None)
    return Classification(
        shape=shape, n_dimples=n, corners=corners, W=W, dent_depth=d.dent_depth,
        dent_sagitta=d.dent_sagitta,
        dent_axis=None if axis is None else tuple(float(v) for v in axis),
        rim_radius=outline.radius if rim is not None else math.nan,
        crest_radius=rim.crest.radius if rim is not None else math.nan,
        rim_spectrum=None if rim is None else tuple(float(v) for v in outline.spectrum),
        dominant_mode=outline.dominant_mode if rim is not None else 0,
        dominant_amplitude=outline.dominant_amplitude if rim is not None else math.nan,
        axisymmetry_threshold=threshold,
        concave_arcs=outline.n_concave if rim is not None else 0,
        count_resolved=resolved,
        asphericity=d.asphericity, contact_distance=d.contact_distance, descriptors=d)


def classify(X, faces) -> Classification:
    """Classify one conformation: positions ``X (V, 3)`` on the closed, outward-oriented
    triangulation ``faces (F, 3)``. To classify many conformations of one mesh, build a
    :class:`~.descriptors.ShapeAnalyzer` once and call :func:`classify_descriptors` on
    ``analyzer.describe(X)``."""
    X = np.asarray(X, dtype=np.float64)
    return classify_descriptors(ShapeAnalyzer(faces, n_vertices=len(X)).describe(X))


# ---------------------------------------------------------------------- runs

#: Version of the classification, stored with every analysed step (``analysis_version``):
#: analysis stored by another version is stale and computed again
#: (:func:`is_current`). 1: stored without the column; 2: rim counts by the dip of each arc
#: inside its chord, counts below the mesh's resolution refused (``count_resolved``).
#: 3: the far sheet of a dent's wall is not a dimple (:meth:`.descriptors.ShapeAnalyzer.far_sheet`).
ANALYSIS_VERSION = 3


def is_current(stored: dict | None) -> bool:
    """Whether one step's stored analysis was made by this version of the classifier."""
    return bool(stored) and "shape" in stored and \
        stored.get("analysis_version") == ANALYSIS_VERSION


#: Analysis columns written by :func:`analyze_run` (the first four are SPEC §7's).
RUN_COLUMNS = ("shape", "n_dimples", "corners", "W", "dent_depth", "dent_sagitta",
               "rim_radius", "crest_radius", "rim_mode", "rim_amplitude", "concave_arcs",
               "asphericity", "contact_distance")


def _store(run_or_path):
    """The :class:`~shellbuckle.store.run.RunStore` of a :class:`shellbuckle.run.Run` (its
    ``store``), a RunStore itself, or that of a run folder.

    Run-level analysis needs only the stored arrays, so it reads the folder through the plain
    store, not through :class:`~shellbuckle.store.view.Run`: the run object can then classify
    its own steps (:meth:`shellbuckle.run.Run.classify`) without an import circle
    (tests/test_import_graph.py).
    """
    from ..store.run import RunStore

    if isinstance(run_or_path, RunStore):
        return run_or_path
    if isinstance(getattr(run_or_path, "store", None), RunStore):
        return run_or_path.store
    if isinstance(run_or_path, (str, bytes, os.PathLike)):
        return RunStore.open(run_or_path)
    raise ValueError(f"expected a Run or a run folder, got {type(run_or_path).__name__}")


def _stored_step(store, k) -> int:
    """Step ``k`` of ``store``, a negative ``k`` counted from the last finished step
    (ValueError for a ``k`` that is no integer or no finished step)."""
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
        raise ValueError(f"steps must be integers (step numbers, or negative counted from the "
                         f"last), got {k!r}")
    steps = store.steps
    if -len(steps) <= k < 0:
        return steps[k]
    if k not in steps:
        raise ValueError(f"step {k} is not a finished step of run {store.path} (finished: "
                         f"{len(steps)} steps, {steps[0] if steps else '-'}..."
                         f"{steps[-1] if steps else '-'})")
    return int(k)


def classify_run(run_or_path, steps=None, progress: bool = False) -> dict:
    """Classify the conformations of a stored run without writing anything.

    ``run_or_path``: a :class:`shellbuckle.run.Run` or a run folder. ``steps``: the steps to
    classify (default all finished steps). Returns ``{step: Classification}``.
    """
    store = _store(run_or_path)
    steps = list(store.steps) if steps is None else list(steps)
    stored = {k: _stored_step(store, k) for k in steps}  # each checked before any work
    analyzer = ShapeAnalyzer(store.faces, n_vertices=len(store.X0))
    iterator = steps
    if progress:
        from tqdm.auto import tqdm

        iterator = tqdm(steps, unit="step", desc="analysis", dynamic_ncols=True)
    return {k: classify_descriptors(analyzer.describe(store.positions(stored[k])))
            for k in iterator}


def analyze_run(run_or_path, steps=None, progress: bool = False):
    """Classify every step of a run and store the analysis columns in it.

    Writes :data:`RUN_COLUMNS` for each step with
    :meth:`shellbuckle.store.RunStore.update_analysis` (atomic, allowed while the run is still
    being computed; non-finite numbers are stored as null) and returns the run's table (a
    pandas DataFrame) with the columns filled in. ``steps`` restricts the work to some steps
    (default: all finished steps, refreshing earlier results).
    """
    store = _store(run_or_path)
    results = classify_run(store, steps=steps, progress=progress)
    store.update_analysis({_stored_step(store, k): {**json_safe(c.columns()),
                                                    "analysis_version": ANALYSIS_VERSION}
                           for k, c in results.items()})
    return store.table()


def table_with_shapes(run, table=None):
    """``table`` (default: the run's) with the analysis columns ``shape``, ``W`` and
    ``corners`` of every step: the stored ones, the missing steps classified without writing
    (:func:`analyze_run` stores them). ``run``: a Run, its RunStore or a folder."""
    if table is None:
        table = _store(run).table()
    if "shape" not in table.columns or table["shape"].isna().any():
        missing = (list(table["step"]) if "shape" not in table.columns
                   else list(table.loc[table["shape"].isna(), "step"]))
        results = classify_run(run, steps=missing)
        table = table.copy()
        if "shape" not in table.columns:
            table["shape"] = None
            table["W"] = 0
            table["corners"] = 0
        for k, c in results.items():
            row = table.index[table["step"] == k]
            table.loc[row, "shape"] = c.shape
            table.loc[row, "W"] = c.W
            table.loc[row, "corners"] = c.corners
    return table
