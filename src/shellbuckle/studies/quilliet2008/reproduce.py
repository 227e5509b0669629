"""The paper's whole numerical study in one call: sweep, special runs, figures, report.

:func:`reproduce_paper` runs Quilliet et al. (EPJE 27, 13 (2008), §4) as a
:mod:`shellbuckle.sweep` (resumable, parallel on Dask) and then writes the figures and the
reproduction report from the run folders::

    from shellbuckle.studies.quilliet2008 import Study, reproduce_paper
    summary = reproduce_paper("repro")                      # the paper's scale
    summary = reproduce_paper("repro-quick", Study.quick()) # a couple of minutes on 2 cores

What is run (:class:`Study`), in ``OUT``:

- ``OUT/sweep/``: the deflations of the paper (its protocol: volume steps of 0.019 V0,
  jiggle, zero-curvature cycle, stop at self-intersection) at every gamma the paper names
  (:data:`PAPER_GAMMAS`, 271 to 29160), nu = 1/3, several seeds, on randomized meshes of
  3594 vertices (several mesh sizes for a mesh-convergence study);
- ``OUT/special/``: the runs the figures need and the sweep does not hold: Fig. 3, gamma = 743
  without (the "potato") and with the zero-curvature cycle, stopped at dV/V = 0.171, both
  quenched as a fixed-iteration Surface Evolver script (:func:`potato_quench`); for
  Fig. 11 a capsule at gamma = 743 and the wrinkled bowl of progressive deflation at
  gamma = 15163, both deflated to the stored volume nearest to the paper's dV/V = 0.645
  (0.646 = 34 steps). A run the sweep already has (same gamma, seed 0, mesh, protocol and
  far enough) is taken from it instead;
- ``OUT/paths/``: the path of Fig. 11, the capsule taken from gamma = 743 to 15163 at fixed
  volume in equal ratios (:func:`shellbuckle.run.continue_in_parameter`), compared with the
  bowl (:func:`shellbuckle.run.compare_paths`; paper: 1.42 times lower energy); and the
  re-inflation of §4.4 (the gamma = 2916 deflation from dV/V = 0.474 back to 0.209 in steps
  of -dv; the paper finds 3 and 4 wrinkles);
- ``OUT/figures/``: Figs. 3, 4, 5, 7, 9, 10 and 11 (:mod:`shellbuckle.plots.paper`,
  :mod:`shellbuckle.plots.across`), PNG and PDF;
- ``OUT/report.md``, ``OUT/report.html``: the reproduction report
  (:func:`shellbuckle.studies.quilliet2008.report.write_report`);
- ``OUT/reproduction.json``: what was run and produced, with wall times, the energy ratios of
  Figs. 3 and 11 and the per-mesh-size thresholds (``OUT/mesh_convergence.csv`` when several
  mesh sizes are run).

Running the same call again resumes: finished runs are skipped, unfinished ones continue from
their last step, and the figures and the report are rewritten.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path

from ...protocol.schedule import PAPER_DV
from ...util import plain

log = logging.getLogger(__name__)

PAPER_GAMMAS = (271.0, 583.0, 743.0, 933.0, 2333.0, 2916.0, 7465.0, 15163.0, 20995.0, 29160.0)
"""Every gamma the paper names for its simulations (§4.2-4.4, Figs. 3-11): 271 to 29160."""
PAPER_VERTICES = 3594
POTATO_GAMMA, POTATO_DV_OVER_V = 743.0, 0.171
"""Fig. 3: potato (no zero-curvature cycle) against capsule, gamma = 743, dV/V = 0.171."""


def potato_quench(n_vertices: int) -> dict:
    """Protocol options of the Fig. 3 pair: conjugate gradients with a fixed iteration budget
    per minimization (``n_vertices / 12``, at least 40). Minimized to convergence, our shells
    merge the paper's depressions without the cycle too; a quench keeps them, as the paper's
    Surface Evolver scripts did. The budget was checked on 1200 (80-100 iterations) and 3594
    (300) vertices: without the cycle 3-5 depressions persist past dV/V = 0.171, with it fewer
    remain, mostly one dent by 0.152-0.19 (tests/test_protocol.py, docs/protocol.md)."""
    return {"method": ("cg",), "max_iter": max(40, round(n_vertices / 12))}


REINFLATION_GAMMA, REINFLATION_FROM, REINFLATION_TO = 2916.0, 0.474, 0.209
"""Paper §4.4: re-inflation of the gamma = 2916 shell from dV/V = 0.474 to 0.209."""
SOLEIL_GAMMA, SOLEIL_DV_OVER_V = 15163.0, 0.645
"""Fig. 11: the conformation reached from a capsule at lower gamma, gamma = 15163, dV/V = 0.645."""
SOLEIL_FROM_GAMMA = 743.0
"""The lower gamma of the Fig. 11 path: a capsule until self-contact there (secondary
buckling only above gamma ~ 850, paper §4.4), so the path starts from a capsule at 0.645."""
FIG9_GAMMA = 2916.0
"""The gamma of the paper's Fig. 9 (energy against dV/V with the theory curves)."""
SUMMARY_JSON = "reproduction.json"


@dataclass(frozen=True)
class Study:
    """The scale of a reproduction.

    ``gammas`` (default :data:`PAPER_GAMMAS`), ``seeds`` (number of seeds, 0..seeds-1;
    default 3), ``vertices`` (randomized mesh sizes; several make a mesh-convergence study;
    default 3594), ``nu`` (1/3), ``dv`` (volume step, 0.019), ``until`` (last target dV/V,
    0.95: runs stop at self-contact before), ``special`` (the Fig. 3 and Fig. 11 runs),
    ``path_increments`` (gamma increments of the Fig. 11 path, 8), ``path_from_gamma`` (743),
    ``energy_convention`` (which bending energy kappa multiplies, :mod:`shellbuckle.params`:
    ``helfrich``, the default, ``paper`` or ``evolver-modulus``; every run of the study),
    ``special_seeds`` (the special runs of Figs. 3 and 11 and the re-inflation for seeds
    0..special_seeds-1; default 1, at most ``seeds``: the figures and the report use seed 0,
    the others give the seed scatter of those numbers in ``reproduction.json``).
    """

    gammas: tuple = PAPER_GAMMAS
    seeds: int = 3
    vertices: tuple = (PAPER_VERTICES,)
    nu: float = 1.0 / 3.0
    dv: float = PAPER_DV
    until: float = 0.95
    special: bool = True
    path_increments: int = 8
    path_from_gamma: float = SOLEIL_FROM_GAMMA
    energy_convention: str = "helfrich"
    special_seeds: int = 1

    def __post_init__(self):
        from ...params import check_convention

        check_convention(self.energy_convention)
        gammas = tuple(float(g) for g in _tuple(self.gammas))
        if not gammas or not all(math.isfinite(g) and g > 0 for g in gammas):
            raise ValueError(f"gammas must be numbers > 0, got {list(gammas)!r}")
        vertices = tuple(_tuple(self.vertices))
        if not vertices or not all(isinstance(n, int) and not isinstance(n, bool) and n >= 20
                                   for n in vertices):
            raise ValueError(f"vertices must be integers >= 20, got {list(vertices)!r}")
        if isinstance(self.seeds, bool) or not isinstance(self.seeds, int) or self.seeds < 1:
            raise ValueError(f"seeds (the number of seeds) must be an integer >= 1, got "
                             f"{self.seeds!r}")
        if not (0 < self.dv <= 0.5) or not (self.dv <= self.until < 0.99):
            raise ValueError(f"need 0 < dv <= 0.5 and dv <= until < 0.99, got dv = {self.dv!r}, "
                             f"until = {self.until!r}")
        if isinstance(self.path_increments, bool) or not isinstance(self.path_increments, int) \
                or self.path_increments < 1:
            raise ValueError(f"path_increments must be an integer >= 1, got "
                             f"{self.path_increments!r}")
        if isinstance(self.special_seeds, bool) or not isinstance(self.special_seeds, int) \
                or not 1 <= self.special_seeds <= self.seeds:
            raise ValueError(f"special_seeds must be an integer in [1, seeds = {self.seeds}], "
                             f"got {self.special_seeds!r}")
        if not self.path_from_gamma > 0:
            raise ValueError(f"path_from_gamma must be > 0, got {self.path_from_gamma!r}")
        object.__setattr__(self, "gammas", gammas)
        object.__setattr__(self, "vertices", vertices)

    @classmethod
    def quick(cls, **overrides) -> "Study":
        """A preset that runs in about two minutes on 2 cores: gamma 271, 2333 and 15163 (a
        capsule, a bowl that buckles twice, and the gamma of Fig. 11), one seed, 400 vertices,
        dV/V up to 0.4 (Fig. 11 at 0.399: on 400 vertices the bowl at gamma = 15163 touches
        itself near 0.47); the special runs of Figs. 3 and 11 at that scale."""
        values = dict(gammas=(271.0, 2333.0, 15163.0), seeds=1, vertices=(400,), until=0.4)
        return cls(**(values | overrides))

    def sweep_spec(self):
        """The :class:`~shellbuckle.sweep.SweepSpec` of the main deflations."""
        from ...sweep import SweepSpec

        return SweepSpec(gamma=self.gammas, nu=self.nu, seeds=tuple(range(self.seeds)),
                         vertices=self.vertices, dv=self.dv, until=self.until,
                         energy_convention=(self.energy_convention,))

    def steps_to(self, dV_over_V: float) -> int:
        """Volume steps to the stored dV/V nearest to ``dV_over_V``, at most to ``until``."""
        return max(1, min(round(dV_over_V / self.dv), math.floor(self.until / self.dv + 1e-9)))

    def to_dict(self) -> dict:
        return dataclasses.asdict(self) | {"gammas": list(self.gammas),
                                           "vertices": list(self.vertices)}


def _tuple(value) -> tuple:
    return (value,) if isinstance(value, (int, float)) else tuple(value)


# --------------------------------------------------------------------------- the runs

def _point_in(spec, **wanted) -> str | None:
    """Name of the point of ``spec`` with these parameters, if it has one."""
    for point in spec.points():
        if all(point.get(k) == v for k, v in wanted.items()):
            return point["name"]
    return None


def _role(role: str, seed: int) -> str:
    """The key of a special run: the role for seed 0 (as the figures use), else role@seed."""
    return role if seed == 0 else f"{role}@{seed}"


def _special_specs(study: Study, main, seed: int = 0) -> tuple[list, dict]:
    """Sweep specs of the special runs of ``seed`` that ``main`` lacks, and where each run is:
    ``{role: (folder kind, run name, step)}`` with folder kind ``sweep`` or ``special``
    (roles :func:`_role`)."""
    from ...sweep import SweepSpec

    v = study.vertices[0]
    specs, where = [], {}
    common = dict(nu=study.nu, seeds=(seed,), vertices=(v,), dv=study.dv,
                  energy_convention=(study.energy_convention,))

    def need(role, gamma, steps, c0_cycle=True, **protocol):
        role = _role(role, seed)
        name = _point_in(main, gamma=gamma, seed=seed, n_vertices=v, c0_cycle=c0_cycle) \
            if steps * study.dv <= study.until + 1e-12 and not protocol else None
        if name is not None:
            where[role] = ("sweep", name, steps)
            return
        spec = SweepSpec(gamma=(gamma,), until=(steps * study.dv,), c0_cycle=(c0_cycle,),
                         **common, **protocol)
        specs.append(spec)
        where[role] = ("special", spec.points()[0]["name"], steps)

    n_potato, n_soleil = study.steps_to(POTATO_DV_OVER_V), study.steps_to(SOLEIL_DV_OVER_V)
    need("fig11_capsule", study.path_from_gamma, n_soleil)
    need("fig11_bowl", SOLEIL_GAMMA, n_soleil)
    quench = potato_quench(v)
    need("fig3_capsule", POTATO_GAMMA, n_potato, **quench)
    need("fig3_potato", POTATO_GAMMA, n_potato, c0_cycle=False, **quench)
    return specs, where


def _sweeps(study: Study, out: Path, *, scheduler, workers, progress) -> dict:
    """Run the main sweep and the special runs on one Dask client; return the catalogues."""
    from ...sweep import check_scheduler, run_sweep, sweep_client

    check_scheduler(scheduler)
    main = study.sweep_spec()
    specials, where = [], {}
    for seed in range(study.special_seeds if study.special else 0):
        more, found = _special_specs(study, main, seed)
        specials += more
        where.update(found)
    import distributed  # noqa: F401  (its import sets the level of its loggers)

    # as run_sweep: Dask's INFO logs only when shellbuckle logs at INFO
    quiet = None if log.isEnabledFor(logging.INFO) else logging.getLogger("distributed")
    level = quiet.level if quiet is not None else None
    if quiet is not None:
        quiet.setLevel(logging.WARNING)
    catalogues = {}
    try:
        with sweep_client(scheduler, workers, [out / "sweep", out / "special"]) as client:
            log.info("main sweep: %d runs in %s", len(main), out / "sweep")
            catalogues["sweep"] = run_sweep(main, out / "sweep", scheduler=client,
                                            progress=progress)
            for spec in specials:
                catalogues["special"] = run_sweep(spec, out / "special", scheduler=client,
                                                  progress=progress)
    finally:
        if quiet is not None:
            quiet.setLevel(level)
    return {"catalogues": catalogues, "where": where}


def _run(out: Path, where: dict, role: str):
    """``(Run, step)`` of a special role, or ``(None, None)`` (logged) if it is not usable."""
    from ...run import Run

    if role not in where:
        return None, None
    kind, name, steps = where[role]
    folder = out / kind / name
    try:
        run = Run.open(folder)
    except ValueError as exc:
        log.warning("%s: run %s is not available (%s)", role, folder, exc)
        return None, None
    table = run.table
    target = steps * float(run.protocol.schedule[0])
    matches = table.index[(table["target_dV_over_V"] - target).abs() < 1e-9]
    if not len(matches):
        log.warning("%s: run %s stopped at dV/V = %.3f before %.3f (%s)", role, folder,
                    float(table["dV_over_V"].iloc[-1]), target, run.store.meta.get("message"))
        return None, None
    return run, int(table["step"].loc[matches[0]])


def _fig11_path(study: Study, out: Path, where: dict, progress: bool,
                seed: int = 0) -> dict | None:
    """The gamma path of Fig. 11 (for ``seed``) and its comparison with the bowl."""
    from ...run import compare_paths, continue_in_parameter

    capsule, k = _run(out, where, _role("fig11_capsule", seed))
    bowl, kb = _run(out, where, _role("fig11_bowl", seed))
    if capsule is None or bowl is None:
        log.warning("Fig. 11 path skipped: the capsule or the bowl run did not reach the volume")
        return None
    name = (f"g{study.path_from_gamma:g}_to_g{SOLEIL_GAMMA:g}_v{study.vertices[0]}_s{seed}_"
            f"step{k}")
    path = continue_in_parameter(capsule, k, out / "paths" / name, gamma=SOLEIL_GAMMA,
                                 increments=study.path_increments, progress=progress)
    if path.status != "finished":
        log.warning("Fig. 11 path %s: %s", path.path, path.store.meta.get("message"))
    result = compare_paths(path, -1, bowl, kb)
    result["paper_ratio"] = 1.42
    return result


def _reinflation(study: Study, out: Path, main_spec, progress: bool,
                 seed: int = 0) -> dict | None:
    """The paper's re-inflation (§4.4, Fig. 8): from a wrinkled (else polygonal) deflation at
    the stored step nearest dV/V = 0.474 — at gamma = 2916 if that run is wrinkled there, else
    at the study's gamma nearest to 2916 whose run is (the paper re-inflates a wrinkled
    state), else at the gamma nearest 2916 — volume steps of -dv back to 0.209; the shape and
    W at both ends."""
    from ...analysis import classify
    from ...run import Run, continue_from

    gammas = sorted({p["gamma"] for p in main_spec.points()},
                    key=lambda g: abs(math.log(g / REINFLATION_GAMMA)))
    candidates = []
    for gamma in gammas:
        name = _point_in(main_spec, gamma=gamma, seed=seed, n_vertices=study.vertices[0])
        try:
            run = Run.open(out / "sweep" / name)
        except ValueError as exc:
            log.warning("re-inflation: run %s not available (%s)", name, exc)
            continue
        table = run.table
        k = int(table["step"].iloc[(table["dV_over_V"] - REINFLATION_FROM).abs().argmin()])
        shape = classify(run.positions(k), run.faces).shape
        rank = {"wrinkled": 0, "polygonal": 1}.get(shape, 2)
        candidates.append((rank, len(candidates), gamma, name, run, k))
    if not candidates:
        return None
    _, _, gamma, name, parent, k = min(candidates)
    table = parent.table
    start = float(table["dV_over_V"].iloc[k])
    if start <= REINFLATION_TO + study.dv:
        log.warning("re-inflation skipped: the gamma = %g run stopped at dV/V = %.3f", gamma,
                    float(table["dV_over_V"].iloc[-1]))
        return None
    folder = out / "paths" / f"{name}_reinflate_from{k}"
    run = continue_from(parent, k, folder, dv=-study.dv, until=REINFLATION_TO,
                        progress=progress)
    ends = {}
    for label, (r, step) in {"from": (parent, k), "to": (run, run.steps[-1])}.items():
        c = classify(r.positions(step), r.faces)
        ends[label] = {"dV_over_V": float(r.table["dV_over_V"].iloc[step]), "shape": c.shape,
                       "W": int(c.W), "corners": int(c.corners),
                       "E_over_kappa": float(r.table["E_over_kappa"].iloc[step])}
    return {"gamma": gamma, "parent": str(parent.path), "path": str(run.path), **ends,
            "paper": "gamma 2916, 0.474 -> 0.209: a depression with 4-fold symmetry; "
                     "3 and 4 wrinkles on re-inflation"}


def _fig3_numbers(out: Path, where: dict, seed: int = 0) -> dict | None:
    from ...run import compare_paths

    potato, kp = _run(out, where, _role("fig3_potato", seed))
    capsule, kc = _run(out, where, _role("fig3_capsule", seed))
    if potato is None or capsule is None:
        return None
    result = compare_paths(capsule, kc, potato, kp)  # ratio = E_potato / E_capsule
    result["paper_ratio"] = 3.10
    result["paper_dimples"] = 17
    return result


# --------------------------------------------------------------------------- outputs

def _missing(what: str, exc: Exception, missing: list) -> None:
    log.warning("%s is not available (%s: %s); it is skipped", what, type(exc).__name__, exc)
    missing.append(f"{what}: {type(exc).__name__}: {exc}")


def _figures(study: Study, out: Path, where: dict, fig11: dict | None, formats,
             missing: list) -> list[Path]:
    from ...run import Run

    figures = out / "figures"
    written: list[Path] = []
    try:
        from ...plots.across import plot_across_runs
    except ImportError as exc:
        _missing("shellbuckle.plots.across.plot_across_runs (Figs. 4, 5, 10)", exc, missing)
    else:
        written += _attempt("Figs. 4, 5, 10", missing,
                            lambda: plot_across_runs([out / "sweep"], figures, formats))
    try:
        from ...plots import paper
    except ImportError as exc:
        _missing("shellbuckle.plots.paper (Figs. 3, 7, 9, 11)", exc, missing)
        return written
    main = study.sweep_spec()
    v = study.vertices[0]
    seed0 = [Run.open(out / "sweep" / p["name"]) for p in main.points()
             if p["seed"] == 0 and p["n_vertices"] == v and (out / "sweep" / p["name"]).exists()]
    jobs = {}
    if seed0:
        jobs["fig07_gallery"] = lambda: paper.fig7_gallery(seed0)
        g9 = min(study.gammas, key=lambda g: abs(math.log(g / FIG9_GAMMA)))
        runs9 = [Run.open(out / "sweep" / p["name"]) for p in main.points()
                 if p["gamma"] == g9 and p["n_vertices"] == v
                 and (out / "sweep" / p["name"]).exists()]
        jobs["fig09_energy"] = lambda: paper.fig9_energy(runs9)
    potato, kp = _run(out, where, "fig3_potato")
    capsule, kc = _run(out, where, "fig3_capsule")
    if potato is not None and capsule is not None:
        at = float(potato.table["dV_over_V"].iloc[kp])
        jobs["fig03_potato_capsule"] = lambda: paper.fig3_potato_capsule(potato, capsule, at=at)
    if fig11 is not None:
        jobs["fig11_paths"] = lambda: paper.fig11_paths(
            fig11["a"]["path"], fig11["b"]["path"], step_a=fig11["a"]["step"],
            step_b=fig11["b"]["step"])
    for stem, make in jobs.items():
        written += _attempt(stem, missing, lambda make=make, stem=stem: _save(
            paper, make(), figures / stem, formats))
    return written


def _save(paper, fig, stem: Path, formats) -> list[Path]:
    import matplotlib.pyplot as plt

    try:
        return paper.save(fig, stem, formats)
    finally:
        plt.close(fig)


def _attempt(what: str, missing: list, make) -> list[Path]:
    """``make()`` (a list of written files); a failure is logged and listed, not raised."""
    try:
        return [Path(p) for p in make()]
    except (ImportError, AttributeError) as exc:
        _missing(what, exc, missing)
    except Exception as exc:  # a figure must not lose the study: logged and listed
        log.error("%s failed: %s: %s", what, type(exc).__name__, exc, exc_info=True)
        missing.append(f"{what}: failed: {type(exc).__name__}: {exc}")
    return []


def _report(out: Path, missing: list) -> list[Path]:
    try:
        from .report import write_report
    except ImportError as exc:
        _missing("the reproduction report (write_report)", exc, missing)
        return []
    folders = [out / name for name in ("sweep", "special", "paths") if (out / name).is_dir()]
    written = []
    for fmt in ("md", "html"):
        written += _attempt(f"report ({fmt})", missing,
                            lambda fmt=fmt: [write_report(folders, out / f"report.{fmt}",
                                                          fmt=fmt)])
    return written


def _mesh_convergence(catalogue, out: Path) -> list[Path]:
    """Thresholds and W per (gamma, mesh size): ``OUT/mesh_convergence.csv``."""
    if catalogue is None or catalogue["n_vertices"].nunique() < 2:
        return []
    columns = ["primary_dV_over_V", "axisymmetry_loss_dV_over_V", "wrinkles_dV_over_V",
               "W_mean", "final_dV_over_V"]
    table = catalogue.groupby(["gamma", "n_vertices"])[columns].agg(["mean", "std", "count"])
    table.columns = [f"{a}_{b}" for a, b in table.columns]
    path = out / "mesh_convergence.csv"
    table.reset_index().to_csv(path, index=False)
    return [path]


# --------------------------------------------------------------------------- the study

def reproduce_paper(out, study: Study | None = None, *, workers: int | None = None,
                    scheduler=None, progress: bool = True,
                    formats=("png", "pdf")) -> dict:
    """Run the paper's study at the scale of ``study`` (default: the paper's) in ``out`` and
    write its figures and report (module docstring). Returns the summary written to
    ``out/reproduction.json``: the study, the run folders, the catalogue counts, the energy
    ratios of Fig. 3 (``fig3``) and Fig. 11 (``fig11``, :func:`shellbuckle.run.compare_paths`
    with the paper's ratio), the files written, what could not be produced (``missing``) and
    the wall times. ``workers``/``scheduler`` as in :func:`shellbuckle.sweep.run_sweep`.
    """
    from ...sweep import check_scheduler

    study = study or Study()
    if not isinstance(study, Study):
        raise ValueError(f"study must be a Study, got {type(study).__name__}")
    check_scheduler(scheduler)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    sweeps = _sweeps(study, out, scheduler=scheduler, workers=workers, progress=progress)
    t_runs = time.perf_counter() - t0
    where = sweeps["where"]
    fig11 = _fig11_path(study, out, where, progress) if study.special else None
    reinflation = (_reinflation(study, out, study.sweep_spec(), progress)
                   if study.special else None)
    more_seeds = range(1, study.special_seeds if study.special else 1)
    fig11_seeds = [fig11] + [_fig11_path(study, out, where, progress, s) for s in more_seeds]
    reinflation_seeds = [reinflation] + [_reinflation(study, out, study.sweep_spec(), progress, s)
                                         for s in more_seeds]
    t_path = time.perf_counter() - t0 - t_runs
    missing: list[str] = []
    written = _mesh_convergence(sweeps["catalogues"].get("sweep"), out)
    written += _figures(study, out, where, fig11, formats, missing)
    written += _report(out, missing)
    catalogues = sweeps["catalogues"]
    summary = {
        "study": study.to_dict(),
        "folders": {k: str(out / k) for k in ("sweep", "special", "paths")
                    if (out / k).is_dir()},
        "runs": {k: {"total": int(len(c)),
                     **{str(s): int(n) for s, n in c["status"].value_counts().items()}}
                 for k, c in catalogues.items()},
        "failed": [f"{k}/{name}" for k, c in catalogues.items()
                   for name in c.loc[c["status"] == "failed", "name"]],
        "special_runs": {role: f"{kind}/{name} step {steps}"
                         for role, (kind, name, steps) in where.items()},
        "fig3": _fig3_numbers(out, where) if study.special else None,
        "fig11": fig11,
        "reinflation": reinflation,
        "seeds_of_special_runs": {
            "fig3": [_fig3_numbers(out, where, s) for s in range(study.special_seeds)]
            if study.special else [],
            "fig11": fig11_seeds if study.special else [],
            "reinflation": reinflation_seeds if study.special else []},
        "written": [str(p) for p in written],
        "missing": missing,
        "wall_s": {"runs": t_runs, "fig11_path": t_path,
                   "outputs": time.perf_counter() - t0 - t_runs - t_path,
                   "total": time.perf_counter() - t0},
    }
    (out / SUMMARY_JSON).write_text(json.dumps(plain(summary), indent=1), encoding="utf-8")
    log.info("reproduction in %s: %.0f s", out, summary["wall_s"]["total"])
    return summary
