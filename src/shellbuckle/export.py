"""Export any stored step of a run to standard mesh formats and to Surface Evolver.

Formats (``FORMATS``): ``vtk`` and ``vtu`` (ParaView; positions, triangles, point and cell
data), ``ply`` (scalar point data), ``obj`` and ``stl`` (geometry only; STL stores float32
positions and one copy of each vertex per facet) through meshio, and ``fe``: a Surface Evolver
datafile with the run's own energy, which Surface Evolver 2.70 loads and can continue to
minimize.

Fields written with the mesh (where the format keeps them), all at the exported step ``X``:

- point data ``H`` (V,): discrete mean curvature ``H = (c1 + c2)/2`` of the run's own bending
  discretization (Jülicher's ``M_i/A_i`` or Evolver's ``star_perp`` ``h``), ``1/R`` on the
  initial sphere, negative where the surface is inverted; units ``1/R``;
- point data ``displacement`` (V, 3) ``X - X0`` from the initial sphere (PLY: three scalars
  ``displacement_x``, ``displacement_y``, ``displacement_z``); units ``R``;
- point data ``bending_energy_density`` (V,): ``kappa/2 (2 H - c0)^2``, bending energy per area
  at each vertex (the integrand of ``E_bend``); units ``kappa/R^2``;
- cell data ``stretching_energy_density`` (F,): membrane energy per rest area of each
  constant-strain triangle, ``A/(2(1+nu)) [Tr(e^2) + nu/(1-nu) (Tr e)^2]``; summed with the
  rest areas it gives the table's ``E_stretch``; units ``kappa/R^2``.

The ``.fe`` file (:func:`shellbuckle.mesh.evolver_io.write_evolver`) carries the run's moduli
(``linear_elastic`` modulus ``A``, ``poisson_ratio = nu``, ``star_perp_sq_mean_curvature``
modulus ``2 kappa``, ``h_zero = c0/2`` with the protocol's ``c0``, default ``2/R``), the rest
metrics ``form_factors`` of the initial sphere (or the run's own rest state when it was started
from a Surface Evolver file) and the body volume of the exported step as its target volume.
Its ``linear_elastic`` energy equals the table's ``E_stretch``; its bending energy equals the
table's ``E_bend`` for a run made with ``bending="evolver"`` (a Jülicher run reports a
different discretization of the same integral).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

__all__ = ["FORMATS", "RunFields", "export_step", "resolve_step", "default_export_path"]

#: format name -> file extension
FORMATS = {"vtk": ".vtk", "vtu": ".vtu", "ply": ".ply", "obj": ".obj", "stl": ".stl", "fe": ".fe"}
_POINT_DATA = {"vtk", "vtu", "ply"}
_CELL_DATA = {"vtk", "vtu"}


def _open(run):
    from .store.view import Run

    return Run.of(run)


def resolve_step(run, step) -> int:
    """The stored step number meant by ``step`` in ``run`` (a Run or a run folder):
    :meth:`shellbuckle.run.Run.step`, kept under this name for existing callers."""
    return _open(run).step(step)


@dataclass(frozen=True, eq=False)
class RunFields:
    """Surface fields of a run's conformations, with the run's own energy terms built once.

    ``X0 (V, 3)`` initial sphere, ``faces (F, 3)``, ``stretching``
    (:class:`~shellbuckle.energies.stretching.Stretching` with the run's rest state),
    ``bending`` (the run's bending term, Jülicher or Evolver ``star_perp``), ``kappa``,
    ``c0`` (convention ``c = c1 + c2``; the protocol's value, ``2/R`` when it gave none) and
    ``form_factors (F, 3)``: the rest metrics ``(s.s, s.t, t.t)`` of each face (``s = x1 - x0``,
    ``t = x2 - x0`` in the rest shape), i.e. of the initial sphere, or those the run was
    started with (a run from a Surface Evolver file).
    """

    X0: np.ndarray
    faces: np.ndarray
    form_factors: np.ndarray
    stretching: object
    bending: object
    kappa: float
    c0: float

    @classmethod
    def of(cls, run) -> "RunFields":
        """Build from a :class:`~shellbuckle.run.Run` (or a run folder path)."""
        from .energies.total import ShellEnergy
        from .mesh.mesh import Mesh

        run = _open(run)
        params, protocol = run.params, run.protocol
        c0 = 2.0 / params.R if protocol.c0 is None else float(protocol.c0)
        X0 = np.asarray(run.store.X0, dtype=np.float64)
        mesh = Mesh.from_arrays(X0, run.faces)
        form_factors = run.store.rest.get("form_factors")
        energy = ShellEnergy.build(mesh, params, bending=protocol.bending, c0=c0,
                                   form_factors=form_factors)
        if form_factors is None:
            s = X0[mesh.faces[:, 1]] - X0[mesh.faces[:, 0]]
            t = X0[mesh.faces[:, 2]] - X0[mesh.faces[:, 0]]
            form_factors = np.stack([(s * s).sum(1), (s * t).sum(1), (t * t).sum(1)], axis=1)
        return cls(X0=X0, faces=mesh.faces, form_factors=np.asarray(form_factors, np.float64),
                   stretching=energy.stretching,
                   bending=energy.bending, kappa=float(params.kappa_helfrich), c0=c0)

    def mean_curvature(self, X) -> np.ndarray:
        """Vertex mean curvature ``H = (c1 + c2)/2`` of the run's bending discretization, (V,)."""
        return np.asarray(self.bending.mean_curvature(X), dtype=np.float64)

    def bending_density(self, X, H=None) -> np.ndarray:
        """Bending energy per area at each vertex, ``kappa_H/2 (2 H - c0)^2`` (``kappa_H`` the
        helfrich modulus of the run's energy convention), shape (V,)."""
        H = self.mean_curvature(X) if H is None else H
        return 0.5 * self.kappa * (2.0 * H - self.c0) ** 2

    def stretching_density(self, X) -> np.ndarray:
        """Membrane energy per rest area of each face, shape (F,)."""
        return np.asarray(self.stretching.density(X), dtype=np.float64)

    def displacement(self, X) -> np.ndarray:
        """``X - X0``, displacement from the initial sphere, shape (V, 3)."""
        return np.asarray(X, dtype=np.float64) - self.X0


def _format_of(path: Path, fmt) -> tuple[Path, str]:
    allowed = ", ".join(FORMATS)
    ext = path.suffix.lower()
    if fmt is None:
        by_ext = {e: f for f, e in FORMATS.items()}
        if ext not in by_ext:
            raise ValueError(f"cannot tell the format of {str(path)!r} from its extension "
                             f"{ext or '(none)'!r}; give a format, one of: {allowed}")
        return path, by_ext[ext]
    fmt = str(fmt).lower().lstrip(".")
    if fmt not in FORMATS:
        raise ValueError(f"format {fmt!r} is not supported; allowed formats: {allowed}")
    if ext == "":
        return path.with_suffix(FORMATS[fmt]), fmt
    if ext != FORMATS[fmt]:
        raise ValueError(f"the extension {ext!r} of {str(path)!r} does not match the format "
                         f"{fmt!r} (expected {FORMATS[fmt]!r})")
    return path, fmt


def default_export_path(run, step: int, fmt: str) -> Path:
    """``<run folder name>_step<K>.<ext>`` in the current directory."""
    return Path(f"{Path(run.path).name}_step{int(step):03d}{FORMATS[fmt]}")


def export_step(run, step: int, path, fmt: str | None = None) -> Path:
    """Write step ``step`` of ``run`` (a Run or a run folder) to ``path``; return the path.

    ``fmt`` is one of ``FORMATS`` (``vtk vtu ply obj stl fe``); ``None`` takes it from the
    extension of ``path``, and a ``path`` without extension gets the format's. Point data
    (``H``, ``displacement``, ``bending_energy_density``) and cell data
    (``stretching_energy_density``) are written where the format keeps them (see the module
    docstring). Raises ``ValueError`` for a step that is not stored or an unknown format.
    """
    run = _open(run)
    path, fmt = _format_of(Path(path), fmt)
    step = resolve_step(run, step)
    if not path.parent.is_dir():
        raise FileNotFoundError(f"directory {str(path.parent)!r} does not exist")
    X = np.asarray(run.positions(step), dtype=np.float64)
    fields = RunFields.of(run)
    if fmt == "fe":
        return _export_evolver(run, step, X, fields, path)
    from .mesh.io import write_mesh
    from .mesh.mesh import Mesh

    mesh = Mesh.from_arrays(X, run.faces)
    point_data, cell_data = {}, {}
    if fmt in _POINT_DATA:
        H = fields.mean_curvature(X)
        point_data["H"] = H
        point_data["bending_energy_density"] = fields.bending_density(X, H)
        u = fields.displacement(X)
        if fmt == "ply":
            point_data.update({f"displacement_{c}": u[:, i] for i, c in enumerate("xyz")})
        else:
            point_data["displacement"] = u
    if fmt in _CELL_DATA:
        cell_data["stretching_energy_density"] = fields.stretching_density(X)
    write_mesh(path, mesh, point_data=point_data, cell_data=cell_data)
    log.info("step %d of %s written to %s", step, run.path, path)
    return path


def _export_evolver(run, step: int, X: np.ndarray, fields: RunFields, path: Path) -> Path:
    from .energies.volume import Volume
    from .mesh.evolver_io import write_evolver
    from .mesh.mesh import Mesh

    params = run.params
    mesh = Mesh.from_arrays(X, run.faces)
    volume = Volume(mesh.faces, mesh.n_vertices).value(X)
    record = run.store.record(step)
    title = (f"step {step} of run {Path(run.path).name}: dV/V = {record['dV_over_V']:.6g}, "
             f"gamma = {params.gamma:.6g}, nu = {params.nu:.6g}, c0 = {fields.c0:.6g}")
    if params.energy_convention != "helfrich":
        title += (f", energy convention {params.energy_convention} (kappa = {params.kappa:.6g}:"
                  f" the helfrich modulus below is {params.kappa_helfrich:.6g})")
    write_evolver(path, mesh, kappa=params.kappa_helfrich, c0=fields.c0, A=params.A, nu=params.nu,
                  form_factors=fields.form_factors, volume=volume, title=title)
    log.info("step %d of %s written to %s", step, run.path, path)
    return path
