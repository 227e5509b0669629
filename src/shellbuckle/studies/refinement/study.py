"""The study itself: its sweep (:func:`study_spec`, :func:`run_study`) and its report from
the finished runs (:func:`report`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from .carried import carry, read_carried, with_carried
from .output import write_report
from .runs import (CONVENTIONS, ENERGY_AT, GAMMAS, SHAPE_IN_D, VERTICES, collect,
                   paper_equivalent_amplitude, quantities)
from .table import GROUP, refinement_table

if TYPE_CHECKING:  # pandas is imported where a table is made: not to build the command line
    import pandas as pd


def study_spec(gammas=GAMMAS, conventions=CONVENTIONS, vertices=VERTICES, seeds=(0,), *,
               smooth_jiggle: float | None = None, smooth_degree: int | None = None,
               shape_imperfection: float | None = None,
               shape_imperfection_d: float | None = None, shape_degree=None,
               until: float = 0.95):
    """The study's :class:`~shellbuckle.sweep.SweepSpec`: the paper's protocol (dv = 0.019,
    the c0 cycle, Newton) on shells with a shape imperfection, by default
    :data:`SHAPE_IN_D` of each shell's effective thickness up to its
    :func:`~shellbuckle.protocol.imperfection.critical_shape_degree` (``shape_imperfection``
    gives it in units of R instead, ``shape_degree`` a degree; an amplitude 0 means spherical
    shells), with the smooth imperfection (jiggle) of rms ``smooth_jiggle`` R up to degree
    ``smooth_degree`` (default :data:`~shellbuckle.protocol.imperfection.DEFAULT_DEGREE`);
    the default jiggle is none on imperfect shells (the shape breaks the symmetry, the same
    way on every mesh) and :func:`paper_equivalent_amplitude` on spherical ones."""
    from ...protocol.imperfection import CRITICAL, DEFAULT_DEGREE
    from ...sweep import SweepSpec

    if shape_imperfection is not None and shape_imperfection_d is not None:
        raise ValueError("give either shape_imperfection (units of R) or shape_imperfection_d "
                         "(units of d), not both")
    if shape_imperfection is None and shape_imperfection_d is None:
        shape_imperfection_d = SHAPE_IN_D
    spherical = shape_imperfection == 0 or shape_imperfection_d == 0
    if spherical:  # the runs of a study without shape imperfection
        if shape_degree is not None:
            raise ValueError(f"shape_degree = {shape_degree}: needs a shape imperfection (its "
                             "amplitude is 0: spherical shells)")
        shape = {}
    else:
        shape = {"shape_degree": CRITICAL if shape_degree is None else shape_degree}
        if shape_imperfection is not None:
            shape["shape_imperfection"] = shape_imperfection
        else:
            shape["shape_imperfection_d"] = shape_imperfection_d
    if smooth_jiggle is None and not spherical:  # the shape breaks the symmetry: no jiggle
        if smooth_degree is not None:
            raise ValueError(f"smooth_degree = {smooth_degree}: needs smooth_jiggle (imperfect "
                             "shells have no jiggle by default)")
        smooth_jiggle, degree = 0.0, None
    else:  # an explicit jiggle keeps its degree (and the run names of earlier studies)
        degree = DEFAULT_DEGREE if smooth_degree is None else smooth_degree
        if smooth_jiggle is None:
            smooth_jiggle = round(paper_equivalent_amplitude(degree), 5)
    return SweepSpec(gamma=list(gammas), energy_convention=list(conventions),
                     vertices=list(vertices), seeds=list(seeds), until=until,
                     smooth_jiggle=smooth_jiggle, smooth_degree=degree, **shape)


def study_folders(out, spec) -> list[Path]:
    """The run folders of the sweep ``spec`` (:func:`study_spec`) that exist in ``out``."""
    return [f for f in (Path(out) / p["name"] for p in spec.points()) if f.exists()]


def run_study(out, gammas=GAMMAS, conventions=CONVENTIONS, vertices=VERTICES, seeds=(0,), *,
              smooth_jiggle: float | None = None, smooth_degree: int | None = None,
              shape_imperfection: float | None = None,
              shape_imperfection_d: float | None = None, shape_degree=None,
              until: float = 0.95, workers: int | None = None, scheduler=None,
              progress: bool = True, energy_at_values=ENERGY_AT,
              carry_states: bool = False) -> pd.DataFrame:
    """Run (or resume) the study's sweep in ``out`` (:func:`study_spec`, runs that are
    finished are skipped), with ``carry_states`` carry each coarse mesh's state near
    :data:`CARRY_AT` to the finest mesh (:func:`carry`, on ``workers`` local processes, by
    default one per core; only to the spec's finest mesh), then write its report
    (:func:`write_report`) from the runs of this spec (also where the carry failed, whose
    error is raised after it); returns the refinement table."""
    from ...sweep import default_workers, run_sweep

    spec = study_spec(gammas, conventions, vertices, seeds, smooth_jiggle=smooth_jiggle,
                      smooth_degree=smooth_degree, shape_imperfection=shape_imperfection,
                      shape_imperfection_d=shape_imperfection_d, shape_degree=shape_degree,
                      until=until)
    if carry_states:
        read_carried(out, strict=True)  # a damaged record: refused before hours of runs
    run_sweep(spec, out, scheduler=scheduler, workers=workers, progress=progress)
    folders = study_folders(out, spec)
    failure = None
    if carry_states:
        try:
            carry(out, folders, workers=workers or default_workers(), progress=progress,
                  finest_vertices=max(vertices))
        except Exception as exc:  # the runs' report is written all the same, then it is raised
            failure = exc
    try:
        table = report(out, folders, energy_at_values=energy_at_values)
    finally:  # the carry's failure, not one of the report that follows it
        if failure is not None:
            raise failure
    return table


def report(out, paths=None, *, energy_at_values=ENERGY_AT) -> pd.DataFrame:
    """Build the refinement table of the finished runs in ``paths`` (default: every run of the
    sweep folder ``out``) and write it in ``out`` (:func:`write_report`); returns it."""
    import pandas as pd

    paths = [out] if paths is None else list(paths)
    runs = collect(paths, energy_at_values) if paths else pd.DataFrame(
        columns=[*GROUP, "n_vertices", *quantities(energy_at_values)])
    runs = with_carried(runs, read_carried(out), out)
    table = refinement_table(runs, energy_at_values)
    write_report(table, out, n_runs=len(runs))
    return table
