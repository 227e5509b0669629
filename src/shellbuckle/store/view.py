"""A stored run read through the package's types: :class:`Run`.

:class:`~shellbuckle.store.run.RunStore` reads and writes a run folder in plain values;
:class:`Run` gives them as :class:`~shellbuckle.params.ShellParameters`,
:class:`~shellbuckle.protocol.spec.Protocol`, a table and meshes, and resolves step indices
(:meth:`Run.step`). It lives here, below the run-level analysis and the run drivers of
:mod:`shellbuckle.run` (which re-exports it), so that both can open a run folder. Its own
:meth:`Run.classify`, :meth:`Run.plot`, :meth:`Run.pv` and :meth:`Run.view` import, when
called, modules that do not import this one (the classifier, which opens run folders through
the plain :class:`~shellbuckle.store.run.RunStore`; the figures and
:mod:`shellbuckle.plots.viewer_page`, which take the run object they are given), so no import
circle closes (tests/test_import_graph.py).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..mesh.mesh import Mesh
from ..params import ShellParameters
from ..protocol.spec import Protocol
from .layout import RUN_JSON
from .repair import _how_to_replace_run_json
from .run import RunStore, _span


def described(store: RunStore, part: str | None = None):
    """What ``run.json`` of ``store`` describes: ``part`` ``"params"`` (the
    :class:`ShellParameters`), ``"protocol"`` (the :class:`Protocol`), or both as a tuple
    (None); ValueError naming ``run.json`` and what to do when they cannot be read."""
    build = {"params": ShellParameters.from_dict, "protocol": Protocol.from_dict}
    parts = [part] if part is not None else list(build)
    try:
        found = [build[name](getattr(store, name)) for name in parts]
    except (ValueError, TypeError, KeyError, AttributeError) as exc:
        what = "parameters" if parts == ["params"] else (
            "protocol" if parts == ["protocol"] else "parameters or protocol")
        raise ValueError(f"{store.path / RUN_JSON}: its {what} cannot be read "
                         f"({type(exc).__name__}: {exc}); "
                         + _how_to_replace_run_json(store.path)) from None
    return found[0] if part is not None else tuple(found)


class Run:
    """A stored run: parameters, protocol, per-step table and conformations.

    ``table`` is a pandas DataFrame with the SPEC §7 columns; ``positions(k)`` the vertex
    positions of step ``k``; ``mesh(k)`` a :class:`~shellbuckle.mesh.Mesh` of step ``k``;
    ``step(k)`` the stored step that index ``k`` means (negative counts from the last).
    A damaged step file is left out of ``steps`` and ``table`` and named in ``damaged``
    (:attr:`RunStore.damaged <shellbuckle.store.run.RunStore.damaged>`); the others read.
    """

    def __init__(self, store: RunStore):
        self.store = store

    @classmethod
    def open(cls, path) -> "Run":
        return cls(RunStore.open(path))

    @classmethod
    def of(cls, run_or_path) -> "Run":
        """``run_or_path`` itself if it is a :class:`Run`, else the run in that folder."""
        if isinstance(run_or_path, cls):
            return run_or_path
        if isinstance(run_or_path, (str, bytes, os.PathLike)):
            return cls.open(run_or_path)
        raise ValueError(f"expected a Run or a run folder, got {type(run_or_path).__name__}")

    @property
    def path(self) -> Path:
        return self.store.path

    @property
    def params(self) -> ShellParameters:
        return described(self.store, "params")

    @property
    def protocol(self) -> Protocol:
        return described(self.store, "protocol")

    @property
    def table(self):
        return self.store.table()

    @property
    def steps(self) -> list[int]:
        """The good finished steps (a damaged step file is left out: :attr:`damaged`)."""
        return self.store.steps

    @property
    def damaged(self) -> dict[int, str]:
        """Damaged steps, ``{step: what is wrong}`` naming the file (empty for a whole run);
        they are left out of :attr:`steps` and :attr:`table`."""
        return self.store.damaged

    @property
    def faces(self) -> np.ndarray:
        return self.store.faces

    def step(self, k: int = -1) -> int:
        """The stored step meant by ``k``: a finished step, or a negative index counted from
        the last (-1 is the last). ValueError naming the allowed steps otherwise."""
        steps = self.store.steps
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
            raise ValueError(f"a step must be an integer, got {k!r}")
        if not steps:
            raise ValueError(f"run {str(self.path)!r} has no finished step yet")
        if k < 0 and -len(steps) <= k:
            return steps[k]
        if k not in steps:
            damaged = self.store.damaged
            if k in damaged:
                raise ValueError(f"step {k} of run {str(self.path)!r} is damaged: {damaged[k]}; "
                                 f"allowed steps: {_span(steps)} (or -1 .. -{len(steps)} "
                                 "counted from the last)")
            raise ValueError(f"step {k} is not a finished step of run {str(self.path)!r}; "
                             f"allowed steps: {_span(steps)} (or -1 .. "
                             f"-{len(steps)} counted from the last)")
        return int(k)

    def params_at(self, k: int = -1) -> ShellParameters:
        """The parameters in force at step ``k``: :attr:`params`, with the step's own gamma
        along a gamma path (the ``gamma`` column of its table)."""
        params = self.params
        gamma = self.store.record(self.step(k)).get("gamma")
        if gamma is None or gamma == params.gamma:
            return params
        return params.with_gamma(gamma)

    def c0_at(self, k: int = -1) -> float:
        """The spontaneous curvature (c = c1 + c2) in force at step ``k``."""
        c0 = self.store.record(self.step(k)).get("c0")
        if c0 is not None:
            return float(c0)
        c0 = self.protocol.c0
        return 2.0 / self.params.R if c0 is None else float(c0)

    def positions(self, k: int = -1) -> np.ndarray:
        """Vertex positions ``(V, 3)`` of step ``k`` (:meth:`step`)."""
        return self.store.positions(self.step(k))

    def mesh(self, k: int = -1) -> Mesh:
        return Mesh.from_arrays(self.positions(k), self.store.faces)

    # ------------------------------------------------------- analysis and figures
    # imported inside the methods: the figures load matplotlib, and the modules they use do
    # not import this one (tests/test_import_graph.py)

    def classify(self, k: int = -1):
        """The classification of step ``k`` (:meth:`step`: negative counts from the last):
        a :class:`~shellbuckle.analysis.classify.Classification` with ``shape``, ``n_dimples``,
        ``corners``, ``W``, the dent's depth and ``dent_axis``, the rim and its spectrum and
        the descriptors, the same as ``shellbuckle classify DIR --step K`` prints. Nothing
        is written.

        The stored analysis (``analysis.json``, :func:`~shellbuckle.analysis.analyze_run`)
        holds only the table's columns, without the dent axis, the rim spectrum or the
        descriptors, so the step is classified from its positions (0.1 s at 3594 vertices);
        where that analysis is current its columns are the same numbers
        (tests/test_run_object.py).
        """
        from ..analysis.classify import classify

        return classify(self.positions(k), self.faces)

    def view(self, k: int = -1, color: str = "curvature", path=None, *,
             inline: bool | None = None, open_browser: bool = True, height: int = 760):
        """The interactive viewer of ``shellbuckle view`` (every stored step, a slider, the
        table and curves), opening at step ``k``; ``color``: ``curvature``, ``strain`` or
        ``bending`` (:mod:`shellbuckle.plots.viewer`).

        Returns a :class:`~shellbuckle.plots.viewer_page.ViewerPage`. In Jupyter (``inline``
        None: when running in a Jupyter kernel) the notebook shows it inline, an iframe
        holding the whole page (nothing served or fetched), and nothing is written unless
        ``path`` is given. Elsewhere (or ``inline=False``) the page is written to ``path``
        (default ``DIR/view.html``, as the command), opened in the web browser unless
        ``open_browser`` is False, and its file is the result's ``path``.
        """
        from ..plots.viewer_page import ViewerPage, in_notebook, page_of

        page = ViewerPage(page_of(self, color, k), height=height)
        inline = in_notebook() if inline is None else bool(inline)
        if path is not None or not inline:
            page.write(self.path / "view.html" if path is None else path)
        if not inline and open_browser:
            page.open()
        return page

    def plot(self, path=None, step: int = -1, *, units: str = "reduced"):
        """The run figure ``shellbuckle deflate`` draws at the end (E/kappa with its bending
        and stretching parts and p/p_c against dV/V with the theory, the class of every step,
        the located events, the conformation of ``step`` in 3D):
        :func:`shellbuckle.plots.run.plot_deflation`; ``units="si"`` for a run made from a
        material (J, Pa, m). Saved to ``path`` when given (PNG, or PDF by the suffix); returns
        the matplotlib Figure."""
        from ..plots.run import plot_deflation

        return plot_deflation(self, path=path, step=step, units=units)

    def pv(self, path=None, branches: bool = True, *, units: str = "reduced"):
        """p/p_c (or Pa, ``units="si"``) against dV/V of this run and, with ``branches``, of
        the runs started from it beside it (re-inflations, other paths), arrows along each path
        (:func:`shellbuckle.plots.pv.plot_pv`, :func:`~shellbuckle.plots.pv.family`). Saved to
        ``path`` when given; returns the matplotlib Figure."""
        from ..plots.pv import family, plot_pv

        return plot_pv(family(self) if branches else [self], path, units=units)

    @property
    def status(self) -> str:
        """The run's status: run.json's (running, paused, finished, failed, interrupted),
        except ``"interrupted"`` for a run whose run.json says running while no process
        writes it: it was stopped outright, and resuming continues it
        (:meth:`~shellbuckle.store.run.RunStore.current_status`)."""
        return self.store.current_status()[0]

    @property
    def message(self) -> str | None:
        """What the run's status says (why it stopped, failed or was interrupted), or None."""
        return self.store.current_status()[1]

    def __repr__(self):
        return f"Run({str(self.path)!r}, status={self.status!r}, steps={len(self.steps)})"
