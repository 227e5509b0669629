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
- point data ``displacement`` (V, 3) ``X - X0`` from the stress-free shape, the initial sphere
  unless the run has a shape imperfection (PLY: three scalars
  ``displacement_x``, ``displacement_y``, ``displacement_z``); units ``R``;
- point data ``bending_energy_density`` (V,): ``kappa/2 (2 H - c0_i)^2``, bending energy per area
  at each vertex (the integrand of ``E_bend``); units ``kappa/R^2``;
- cell data ``stretching_energy_density`` (F,): membrane energy per rest area of each
  constant-strain triangle, ``A/(2(1+nu)) [Tr(e^2) + nu/(1-nu) (Tr e)^2]``; summed with the
  rest areas it gives the table's ``E_stretch``; units ``kappa/R^2``.

The ``.fe`` file (:func:`shellbuckle.mesh.evolver_io.write_evolver`) carries the run's moduli
(``linear_elastic`` modulus ``A``, ``poisson_ratio = nu``, ``star_perp_sq_mean_curvature``
modulus ``2 kappa``, ``h_zero = c0/2`` with the protocol's ``c0``, default ``2/R``, a vertex
attribute for a shell with a shape imperfection), the rest metrics ``form_factors`` of the
stress-free shape (or the run's own rest state when it was started from a Surface Evolver
file) and the body volume of the exported step as its target volume.
Its ``linear_elastic`` energy equals the table's ``E_stretch``; its bending energy equals the
table's ``E_bend`` for a run made with ``bending="evolver"`` (a Jülicher run reports a
different discretization of the same integral).

A single-step ``vtu`` file also carries field data (one value each, :func:`field_data`): the
run's ``gamma``, ``nu``, ``kappa``, ``kappa_helfrich``, ``bending_factor`` (the energy
convention: the bending energy is the helfrich one with ``bending_factor * kappa``), ``A``,
``R``, ``c0`` and ``p_c`` (classical buckling pressure), and the step's ``step``,
``dV_over_V``, ``pressure`` (``kappa/R^3``), ``pressure_over_p_c``, ``E_over_kappa``,
``E_total``, ``E_bend`` and ``E_stretch`` (``kappa``), as in the run's table.

The whole run as one time series (:func:`export_series`, format ``xdmf``): an XDMF 3 file
(XML) with its heavy data in an HDF5 file beside it (same name, ``.h5``), which ParaView opens
as one time-dependent data set and :class:`meshio.xdmf.TimeSeriesReader` reads. See
:func:`export_series` for the layout.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .store.names import refuse_store_file

log = logging.getLogger(__name__)

__all__ = ["FORMATS", "SERIES_FORMATS", "RunFields", "export_step", "export_conformation",
           "export_series", "field_data", "run_metadata", "step_metadata", "resolve_step",
           "default_export_path", "default_series_path", "format_of"]

#: format name -> file extension
FORMATS = {"vtk": ".vtk", "vtu": ".vtu", "ply": ".ply", "obj": ".obj", "stl": ".stl", "fe": ".fe"}
#: format name -> file extension, of the formats holding every step of a run in one file
SERIES_FORMATS = {"xdmf": ".xdmf"}
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

    ``X0 (V, 3)`` the stress-free shape (the initial sphere, or the imperfect surface of a
    shape imperfection, :meth:`~shellbuckle.protocol.spec.Protocol.stress_free`),
    ``faces (F, 3)``, ``stretching``
    (:class:`~shellbuckle.energies.stretching.Stretching` with the run's rest state),
    ``bending`` (the run's bending term, Jülicher or Evolver ``star_perp``), ``kappa``,
    ``c0`` (convention ``c = c1 + c2``; the protocol's value, ``2/R`` when it gave none),
    ``c0_vertices (V,)`` the spontaneous curvature of each vertex where it varies (a shape
    imperfection; else None) and
    ``form_factors (F, 3)``: the rest metrics ``(s.s, s.t, t.t)`` of each face (``s = x1 - x0``,
    ``t = x2 - x0`` in the rest shape), i.e. of the stress-free shape, or those the run was
    started with (a run from a Surface Evolver file).
    """

    X0: np.ndarray
    faces: np.ndarray
    form_factors: np.ndarray
    stretching: object
    bending: object
    kappa: float
    c0: float
    c0_vertices: np.ndarray | None = None

    @classmethod
    def of(cls, run) -> "RunFields":
        """Build from a :class:`~shellbuckle.run.Run` (or a run folder path)."""
        from .energies.total import ShellEnergy
        from .mesh.mesh import Mesh

        run = _open(run)
        params, protocol = run.params, run.protocol
        c0 = 2.0 / params.R if protocol.c0 is None else float(protocol.c0)
        mesh = Mesh.from_arrays(np.asarray(run.store.X0, dtype=np.float64), run.faces)
        X0, profile = protocol.stress_free(mesh.X)
        form_factors = run.store.rest.get("form_factors")
        energy = ShellEnergy.build(mesh, params, bending=protocol.bending, c0=c0, reference=X0,
                                   form_factors=form_factors, c0_profile=profile)
        if form_factors is None:
            s = X0[mesh.faces[:, 1]] - X0[mesh.faces[:, 0]]
            t = X0[mesh.faces[:, 2]] - X0[mesh.faces[:, 0]]
            form_factors = np.stack([(s * s).sum(1), (s * t).sum(1), (t * t).sum(1)], axis=1)
        return cls(X0=X0, faces=mesh.faces, form_factors=np.asarray(form_factors, np.float64),
                   stretching=energy.stretching,
                   bending=energy.bending, kappa=float(params.kappa_helfrich), c0=c0,
                   c0_vertices=None if profile is None else energy.bending.c0_vertices)

    def mean_curvature(self, X) -> np.ndarray:
        """Vertex mean curvature ``H = (c1 + c2)/2`` of the run's bending discretization, (V,)."""
        return np.asarray(self.bending.mean_curvature(X), dtype=np.float64)

    def bending_density(self, X, H=None) -> np.ndarray:
        """Bending energy per area at each vertex, ``kappa_H/2 (2 H - c0)^2`` (``kappa_H`` the
        helfrich modulus of the run's energy convention), shape (V,)."""
        H = self.mean_curvature(X) if H is None else H
        c0 = self.c0 if self.c0_vertices is None else self.c0_vertices
        return 0.5 * self.kappa * (2.0 * H - c0) ** 2

    def stretching_density(self, X) -> np.ndarray:
        """Membrane energy per rest area of each face, shape (F,)."""
        return np.asarray(self.stretching.density(X), dtype=np.float64)

    def displacement(self, X) -> np.ndarray:
        """``X - X0``, displacement from the stress-free shape, shape (V, 3)."""
        return np.asarray(X, dtype=np.float64) - self.X0


def format_of(path: Path, fmt) -> tuple[Path, str]:
    """``(path, format)`` of an export: the format from the extension when ``fmt`` is None,
    else ``fmt`` with its extension added to a path without one (ValueError: an unknown
    format, or an extension that is not the format's)."""
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
    path, fmt = format_of(Path(path), fmt)
    step = resolve_step(run, step)
    record = run.store.record(step)
    path = _write(run, run.positions(step), path, fmt,
                  f"step {step} of run {Path(run.path).name}: dV/V = "
                  f"{record['dV_over_V']:.6g}", lambda: field_data(run, step))
    log.info("step %d of %s written to %s", step, run.path, path)
    return path


def export_conformation(run, X, path, fmt: str | None = None, *, values: dict | None = None,
                        what: str = "a conformation") -> Path:
    """Write positions ``X (V, 3)`` on the mesh of ``run`` (a state the run did not store,
    e.g. a step of another mesh carried to this one, :mod:`shellbuckle.studies.transfer`) to
    ``path``, with the fields of :func:`export_step` under the run's energy; a ``vtu`` file
    carries the run's parameters and ``values`` (numbers, e.g. ``dV_over_V`` and
    ``E_over_kappa``) as field data, an ``fe`` file says ``what`` in its title."""
    run = _open(run)
    path, fmt = format_of(Path(path), fmt)
    X = np.asarray(X, dtype=np.float64)
    if X.shape != (run.store.n_vertices, 3):
        raise ValueError(f"positions of shape {X.shape} are not a conformation of the "
                         f"{run.store.n_vertices}-vertex mesh of {str(run.path)!r}")
    return _write(run, X, path, fmt, f"{what} on the mesh of run {Path(run.path).name}",
                  lambda: _numeric_metadata(run) | (values or {}))


def _write(run, X: np.ndarray, path: Path, fmt: str, title: str, field_values) -> Path:
    """``X`` on the run's mesh in ``path`` (format ``fmt``), with the fields of the module
    docstring; ``field_values()`` gives a vtu file's field data, ``title`` heads an fe file."""
    if not path.parent.is_dir():
        raise FileNotFoundError(f"directory {str(path.parent)!r} does not exist")
    refuse_store_file(path)
    fields = RunFields.of(run)
    if fmt == "fe":
        return _export_evolver(run, X, fields, path, title)
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
    if fmt == "vtu":
        _add_vtu_field_data(path, field_values())
    return path


# ------------------------------------------------------------------------------ metadata
#: The step values every export carries, columns of the run's table.
STEP_COLUMNS = ("step", "dV_over_V", "pressure", "E_over_kappa", "E_total", "E_bend",
                "E_stretch")


def run_metadata(run) -> dict:
    """The run's parameters as plain values: ``gamma``, ``nu``, ``kappa``, ``energy_convention``
    (name), ``bending_factor`` ``f`` and ``kappa_helfrich = f kappa`` (the bending energy is
    ``1/2 kappa_helfrich (c1 + c2 - c0)^2``), ``A`` (2D Young modulus), ``R``, ``c0`` (the
    protocol's, ``2/R`` when it gave none) and ``p_c``, the classical buckling pressure
    :func:`shellbuckle.theory.classical_pressure` (``kappa/R^3``)."""
    from .theory import classical_pressure

    run = _open(run)
    params = run.params
    c0 = run.protocol.c0
    return {"gamma": float(params.gamma), "nu": float(params.nu), "kappa": float(params.kappa),
            "energy_convention": params.energy_convention,
            "bending_factor": float(params.bending_factor),
            "kappa_helfrich": float(params.kappa_helfrich), "A": float(params.A),
            "R": float(params.R), "c0": 2.0 / params.R if c0 is None else float(c0),
            "p_c": float(classical_pressure(params))}


def step_metadata(run, step: int, table=None, p_c: float | None = None) -> dict:
    """The values of stored step ``step`` in the run's table (:data:`STEP_COLUMNS`, and
    ``gamma``/``c0`` where the table has them: a parameter path), plus ``pressure_over_p_c``.
    ``table``, ``p_c``: the run's table and classical pressure, when the caller has them."""
    run = _open(run)
    table = run.table if table is None else table
    rows = table[table["step"] == step]
    if rows.empty:
        raise ValueError(f"step {step} is not in the table of run {str(run.path)!r}")
    row = rows.iloc[0]
    out = {c: row[c] for c in STEP_COLUMNS + ("gamma", "c0") if c in table.columns}
    out = {c: int(v) if c == "step" else float(v) for c, v in out.items()}
    p_c = run_metadata(run)["p_c"] if p_c is None else p_c
    out["pressure_over_p_c"] = out["pressure"] / p_c
    return out


def _numeric_metadata(run) -> dict:
    """:func:`run_metadata` without the convention's name (``bending_factor`` says it): the
    run's part of a vtu file's field data."""
    meta = run_metadata(run)
    meta.pop("energy_convention")
    return meta


def field_data(run, step: int, table=None) -> dict:
    """The numeric values a single-step export carries as field data: :func:`run_metadata`
    without the convention's name (``bending_factor`` says it) and :func:`step_metadata`."""
    meta = _numeric_metadata(run)
    return meta | step_metadata(run, step, table, meta["p_c"])


def _add_vtu_field_data(path: Path, values: dict) -> None:
    """Insert ``<FieldData>`` (one ascii Float64 or Int64 value per name) into a VTU file
    written by meshio, whose writer has no field data."""
    arrays = []
    for name, value in values.items():
        kind = "Int64" if isinstance(value, (int, np.integer)) else "Float64"
        text = str(int(value)) if kind == "Int64" else repr(float(value))
        arrays.append(f'<DataArray type="{kind}" Name="{name}" NumberOfTuples="1" '
                      f'format="ascii">{text}</DataArray>')
    block = ("<FieldData>\n" + "\n".join(arrays) + "\n</FieldData>\n").encode()
    data = path.read_bytes()
    tag = b"<UnstructuredGrid>"
    at = data.find(tag)
    if at < 0:
        raise ValueError(f"{str(path)!r} is not a VTU file as meshio writes it")
    at += len(tag)
    path.write_bytes(data[:at] + b"\n" + block + data[at:])


def _export_evolver(run, X: np.ndarray, fields: RunFields, path: Path, what: str) -> Path:
    from .energies.volume import Volume
    from .mesh.evolver_io import write_evolver
    from .mesh.mesh import Mesh

    params = run.params
    mesh = Mesh.from_arrays(X, run.faces)
    volume = Volume(mesh.faces, mesh.n_vertices).value(X)
    title = (f"{what}, gamma = {params.gamma:.6g}, nu = {params.nu:.6g}, "
             f"c0 = {fields.c0:.6g}")
    if params.energy_convention != "helfrich":
        title += (f", energy convention {params.energy_convention} (kappa = {params.kappa:.6g}:"
                  f" the helfrich modulus below is {params.kappa_helfrich:.6g})")
    c0 = fields.c0 if fields.c0_vertices is None else fields.c0_vertices
    write_evolver(path, mesh, kappa=params.kappa_helfrich, c0=c0, A=params.A, nu=params.nu,
                  form_factors=fields.form_factors, volume=volume, title=title)
    return path


# ------------------------------------------------------------------------------ time series
def default_series_path(run, fmt: str = "xdmf") -> Path:
    """``<run folder name>.<ext>`` in the current directory."""
    return Path(f"{Path(run.path).name}{SERIES_FORMATS[fmt]}")


def _info(parent, name: str, value) -> None:
    import xml.etree.ElementTree as ET

    text = repr(value) if isinstance(value, float) else str(value)
    ET.SubElement(parent, "Information", Name=name, Value=text)


def _data_item(parent, h5_name: str, dataset, shape, number_type: str = "Float") -> None:
    import xml.etree.ElementTree as ET

    item = ET.SubElement(parent, "DataItem", Dimensions=" ".join(str(n) for n in shape),
                         NumberType=number_type, Precision="8", Format="HDF")
    item.text = f"{h5_name}:{dataset}"


def export_series(run, path, fmt: str | None = None, steps=None) -> Path:
    """Write the stored steps of ``run`` (a Run or a run folder; ``steps``: a subset, default
    all) as one time series: an XDMF 3 file ``path`` and its HDF5 file ``path.with_suffix(".h5")``;
    return the XDMF path. ``fmt`` is ``"xdmf"`` or None (taken from the extension; a path
    without one gets ``.xdmf``).

    The time of each step is its **step number** (not dV/V, which stands still along a path
    in gamma or c0 and decreases on a re-inflation, while an XDMF time must increase). Layout:

    - HDF5: ``/mesh/faces (F, 3)`` int64 and ``/mesh/X0 (V, 3)`` (the initial sphere); for
      step ``k``, group ``/steps/<k, 6 digits>`` with ``X (V, 3)`` (positions, float64, the
      stored values exactly), ``displacement (V, 3)``, ``H (V,)``,
      ``bending_energy_density (V,)`` and ``stretching_energy_density (F,)`` (the fields of
      the VTU export, module docstring), and the step's values (:func:`step_metadata`) as
      attributes; the run's values (:func:`run_metadata`) as attributes of the root.
    - XDMF: a temporal collection of one uniform grid per step, each with its ``Time``, the
      shared triangles, the step's ``X`` as its geometry (ParaView shows the shape moving) and
      as a vector point field ``X`` (which meshio's reader returns, as it reads one geometry),
      the fields as ``Attribute`` elements, and the step's values as ``Information`` elements
      (``Name``, ``Value``); the run's values as ``Information`` elements of the ``Domain``.
    """
    import xml.etree.ElementTree as ET

    import h5py

    run = _open(run)
    path = Path(path)
    fmt = "xdmf" if fmt is None else str(fmt).lower().lstrip(".")
    if fmt not in SERIES_FORMATS:
        raise ValueError(f"format {fmt!r} is not a time-series format; allowed: "
                         f"{', '.join(SERIES_FORMATS)}")
    if path.suffix == "":
        path = path.with_suffix(SERIES_FORMATS[fmt])
    elif path.suffix.lower() != SERIES_FORMATS[fmt]:
        raise ValueError(f"the extension {path.suffix!r} of {str(path)!r} does not match the "
                         f"format {fmt!r} (expected {SERIES_FORMATS[fmt]!r})")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"directory {str(path.parent)!r} does not exist")
    h5_path = path.with_suffix(".h5")
    for target in (path, h5_path):
        if target.is_dir():
            raise ValueError(f"{str(target)!r} is a folder; the series needs a file there")
    if steps is not None and (isinstance(steps, (str, bytes)) or np.ndim(steps) != 1):
        raise TypeError(f"steps must be a list of step numbers, got {steps!r}")
    steps = run.steps if steps is None else [run.step(k) for k in steps]
    if not steps:
        raise ValueError(f"run {str(run.path)!r} has no finished step to export")
    if any(b <= a for a, b in zip(steps, steps[1:])):
        raise ValueError(f"steps {steps!r} (as resolved): a time series needs each step once, "
                         "in increasing order")
    refuse_store_file(path, [h5_path])
    fields = RunFields.of(run)
    faces = np.asarray(run.faces, dtype=np.int64)
    table = run.table
    meta = run_metadata(run)
    n_v, n_f = len(fields.X0), len(faces)

    root = ET.Element("Xdmf", Version="3.0")
    domain = ET.SubElement(root, "Domain")
    for name, value in meta.items():
        _info(domain, name, value)
    _info(domain, "run", Path(run.path).name)
    _info(domain, "time", "step number")
    series = ET.SubElement(domain, "Grid", Name=Path(run.path).name, GridType="Collection",
                           CollectionType="Temporal")
    with h5py.File(h5_path, "w") as h5:
        h5.attrs.update(meta)
        h5.attrs["run"] = str(run.path)
        h5["mesh/faces"] = faces
        h5["mesh/X0"] = fields.X0
        for step in steps:
            X = np.asarray(run.positions(step), dtype=np.float64)
            H = fields.mean_curvature(X)
            group = h5.create_group(f"steps/{step:06d}")
            data = {"X": X, "displacement": fields.displacement(X), "H": H,
                    "bending_energy_density": fields.bending_density(X, H),
                    "stretching_energy_density": fields.stretching_density(X)}
            for name, array in data.items():
                group[name] = array
            values = step_metadata(run, step, table, meta["p_c"])
            group.attrs.update(values)
            grid = ET.SubElement(series, "Grid", Name=f"step {step}", GridType="Uniform")
            ET.SubElement(grid, "Time", Value=str(step))
            for name, value in values.items():
                _info(grid, name, value)
            topology = ET.SubElement(grid, "Topology", TopologyType="Triangle",
                                     NumberOfElements=str(n_f))
            _data_item(topology, h5_path.name, "/mesh/faces", (n_f, 3), "Int")
            geometry = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
            _data_item(geometry, h5_path.name, f"{group.name}/X", (n_v, 3))
            for name, array in data.items():
                center = "Cell" if name == "stretching_energy_density" else "Node"
                attribute = ET.SubElement(grid, "Attribute", Name=name, Center=center,
                                          AttributeType="Vector" if array.ndim == 2
                                          else "Scalar")
                _data_item(attribute, h5_path.name, f"{group.name}/{name}", array.shape)
    ET.indent(root)
    ET.ElementTree(root).write(path, xml_declaration=True, encoding="utf-8")
    log.info("%d steps of %s written to %s and %s", len(steps), run.path, path, h5_path)
    return path
