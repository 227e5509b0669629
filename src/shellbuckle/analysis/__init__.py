"""Automatic analysis of conformations and runs (SPEC §4; Quilliet et al. 2008, §4.2-4.4).

- :func:`describe` (X, faces) -> dict of shape descriptors (:mod:`.descriptors`: asphericity,
  dents, dent axis and depth, rim curve and its Fourier spectrum, self-contact distance);
- :func:`classify` (X, faces) -> :class:`Classification` (``sphere``, ``dimples``,
  ``capsule``, ``polygonal``, ``wrinkled``, ``other``; ``n_dimples``, ``corners``, ``W``);
- :func:`analyze_run` (run or folder): classifies every step and stores the analysis columns;
- :func:`events` (run or folder): primary buckling, loss of axisymmetry, wrinkles, inertia
  changes, each with its dV/V; :func:`thresholds` the first three as a dict.

The named thresholds and their calibration are documented in ``docs/analysis.md``.
"""

from .classify import (RUN_COLUMNS, SHAPES, Classification, analyze_run, classify,
                       classify_descriptors, classify_run)
from .descriptors import Descriptors, ShapeAnalyzer, describe
from .events import Event, events, thresholds
from .fits import (PowerLawFit, critical_gamma, crossover, fit_power_law, gamma_at,
                   wrinkle_average)

#: The names of :mod:`.collect`, which loads pandas: loaded when one is asked for, so that a
#: run's progress bar (descriptors and classification) does not load pandas.
_COLLECT = ("collect_runs", "threshold_fits", "wrinkles_by_gamma")

__all__ = ["RUN_COLUMNS", "SHAPES", "Classification", "Descriptors", "Event", "ShapeAnalyzer",
           "analyze_run", "classify", "classify_descriptors", "classify_run", "describe",
           "events", "thresholds", "PowerLawFit", "critical_gamma", "crossover",
           "fit_power_law", "gamma_at", "wrinkle_average", *_COLLECT]


def __getattr__(name):
    if name in _COLLECT:
        from . import collect

        return getattr(collect, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
