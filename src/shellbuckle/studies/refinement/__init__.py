"""The mesh-refinement study: do the buckling thresholds, W and the energies converge as the
mesh is refined, and how far is the paper's mesh (3594 vertices) from the limit?

One sweep (:mod:`shellbuckle.sweep`) of deflations of the same shells on every mesh over
energy conventions x gamma x mesh sizes N x seeds: by default shells with a shape imperfection
of :data:`SHAPE_IN_D` of their effective thickness up to the classical buckling band
(:func:`~shellbuckle.protocol.imperfection.critical_shape_degree`) and no jiggle, so that
every mesh dents at the same material point; or spherical shells kicked by the smooth
imperfection (:mod:`shellbuckle.protocol.imperfection`, the same field on every mesh). Then, per
(convention, gamma, imperfection) and mesh size N:

- the primary threshold, the loss of axisymmetry and the wrinkle onset (dV/V, located by
  bisection where the runs have them, :mod:`shellbuckle.locate`), ``W_mean`` (wrinkles over the
  wrinkled steps with dV/V in [0.53, 0.76], i.e. near 0.645) as
  :func:`shellbuckle.analysis.collect.collect_runs` gives them;
- ``E/kappa`` at fixed dV/V (:data:`ENERGY_AT`), :func:`energy_at`: linear interpolation of the
  stored total energy between the two stored steps around that dV/V; the rim's largest
  harmonic at the same dV/V (:func:`rim_amplitude_at`), how far the dent is from
  axisymmetric, for shells whose dent is born non-axisymmetric; the dent axis's angle to the
  finest mesh's;

- with :func:`carry` (``shellbuckle refine --carry``), the step of each coarser mesh nearest
  dV/V = :data:`CARRY_AT` carried to the finest mesh of its seed and relaxed there
  (:func:`shellbuckle.studies.transfer.compare`): its wrinkle count there and its energy
  relative to the finest mesh's own step, i.e. whether a coarse mesh's W is a state of the
  shell or of its mesh; kept in ``carried.json`` in the study folder;

each averaged over seeds (mean, sample standard deviation with ``n - 1``, NaN for one seed),
and per quantity a value extrapolated to h -> 0 in the mean edge ``h = sqrt(8 pi / (sqrt(3)
(N - 2))) R`` (:func:`richardson`), with the discretization error of the paper's mesh relative
to it. :func:`run_study` runs the sweep and writes ``refinement.md``, ``refinement.csv`` and
``refinement.png`` (:func:`write_report`); :func:`report` rebuilds them from the runs.

The package, in the order of the data path: :mod:`.runs` (the study's defaults and what it
reads from one run), :mod:`.extrapolation` (Richardson in h), :mod:`.table` (the refinement
table), :mod:`.carried` (states carried to the finest mesh), :mod:`.output` (markdown, figure,
CSV) and :mod:`.study` (the sweep and its report); every public name of these modules is
importable from the package itself.

Reference for the protocol: Quilliet et al., Eur. Phys. J. E 27, 13 (2008), §4.1.
"""

from .runs import (GAMMAS, CONVENTIONS, PAPER_VERTICES, VERTICES, ENERGY_AT, PAPER_JIGGLE_SIGMA,
                   THRESHOLDS, BRANCH_END, RESOLUTIONS, IMPERFECT_BRANCH_END, SHAPE_IN_D, CARRY_AT,
                   energy_column, axis_column, angle_column, rim_column, CARRIED_W,
                   carried_columns, quantities, mean_edge, paper_equivalent_amplitude, energy_at,
                   rim_amplitude_at, material_dent_axis, step_near, dent_axis_at, branch_end,
                   branch_end_resolution, collect)
from .extrapolation import (ASSUMED_ORDER, MIN_ORDER, MAX_ORDER, Extrapolation, NOT_CONVERGED,
                            NO_VALUE, ONE_MESH, GAP, TO_FINEST, richardson)
from .table import (GROUP, COLUMNS, OWN_SEEDS, refinement_table)
from .carried import (CARRIED_JSON, CARRIED_VERSION, read_carried, run_identity, carry_pairs,
                      carry, with_carried)
from .output import (CSV, MARKDOWN, FIGURE, markdown, figure, write_report)
from .study import (study_spec, study_folders, run_study, report)

__all__ = ["GAMMAS", "CONVENTIONS", "PAPER_VERTICES", "VERTICES", "ENERGY_AT",
           "PAPER_JIGGLE_SIGMA", "THRESHOLDS", "BRANCH_END", "RESOLUTIONS", "IMPERFECT_BRANCH_END",
           "SHAPE_IN_D", "CARRY_AT", "energy_column", "axis_column", "angle_column", "rim_column",
           "CARRIED_W", "carried_columns", "quantities", "mean_edge", "paper_equivalent_amplitude",
           "energy_at", "rim_amplitude_at", "material_dent_axis", "step_near", "dent_axis_at",
           "branch_end", "branch_end_resolution", "collect", "ASSUMED_ORDER", "MIN_ORDER",
           "MAX_ORDER", "Extrapolation", "NOT_CONVERGED", "NO_VALUE", "ONE_MESH", "GAP",
           "TO_FINEST", "richardson", "GROUP", "COLUMNS", "OWN_SEEDS", "refinement_table",
           "CARRIED_JSON", "CARRIED_VERSION", "read_carried", "run_identity", "carry_pairs",
           "carry", "with_carried", "CSV", "MARKDOWN", "FIGURE", "markdown", "figure",
           "write_report", "study_spec", "study_folders", "run_study", "report"]
