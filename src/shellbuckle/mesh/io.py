"""Reading and writing triangulated surfaces in standard mesh formats.

Formats go through meshio (https://github.com/nschloemer/meshio), chosen by the file
extension; Surface Evolver datafiles and dumps (``.fe``, ``.dmp``) go through
:mod:`shellbuckle.mesh.evolver_io`. Only triangle cells are accepted. A mesh that is read is
validated with :func:`~shellbuckle.mesh.checks.validate_surface` (closed, oriented outward,
manifold, genus 0), so the error names the first offending vertex, edge or face.

Precision: VTK, VTU, XDMF, PLY, Gmsh, Medit and Abaqus files keep float64 positions exactly;
OBJ and OFF are written with Python's shortest round-trip float repr, also exact; STL stores
float32 and one copy of every vertex per facet, so positions come back rounded to float32 and
vertices are merged (exact duplicates) on reading, renumbered in order of first appearance.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .checks import validate_surface
from .mesh import Mesh

#: extension -> (meshio file_format, what is kept besides positions and triangles)
MESHIO_FORMATS = {
    ".vtk": ("vtk", "point and cell data"),
    ".vtu": ("vtu", "point and cell data"),
    ".xdmf": ("xdmf", "point and cell data"),
    ".msh": ("gmsh", "point and cell data (Gmsh 4.1)"),
    ".ply": ("ply", "scalar point data"),
    ".obj": ("obj", "no data"),
    ".off": ("off", "no data"),
    ".stl": ("stl", "no data; float32 positions"),
    ".mesh": ("medit", "no data"),
    ".inp": ("abaqus", "no data"),
}
EVOLVER_FORMATS = (".fe", ".dmp")
_POINT_DATA = {".vtk", ".vtu", ".xdmf", ".msh", ".ply"}
_CELL_DATA = {".vtk", ".vtu", ".xdmf", ".msh"}


def _allowed() -> str:
    return ", ".join(list(MESHIO_FORMATS) + list(EVOLVER_FORMATS))


def _extension(path: Path) -> str:
    ext = path.suffix.lower()
    if ext not in MESHIO_FORMATS and ext not in EVOLVER_FORMATS:
        raise ValueError(f"unsupported mesh file extension {ext or '(none)'!r} for {str(path)!r}; "
                         f"allowed: {_allowed()}")
    return ext


def read_mesh(path) -> Mesh:
    """Read a closed triangulated surface from ``path``; the format follows the extension.

    Allowed extensions: ``.vtk .vtu .xdmf .msh (Gmsh) .ply .obj .off .stl .mesh (Medit)
    .inp (Abaqus)`` through meshio, and ``.fe``/``.dmp`` (Surface Evolver). Raises
    ``ValueError`` for another extension, for cells other than triangles or non-3D points,
    and :class:`~shellbuckle.mesh.topology.MeshError` (a ``ValueError``) when the surface is
    not closed, manifold, outward oriented and of genus 0. STL vertices are merged.
    """
    path = Path(path)
    ext = _extension(path)
    if ext in EVOLVER_FORMATS:
        from .evolver_io import read_evolver  # imported here: optional at import time
        return read_evolver(path).mesh
    if not path.is_file():
        raise FileNotFoundError(f"mesh file {str(path)!r} does not exist")
    import contextlib
    import io

    import meshio

    said = io.StringIO()
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(said), \
                contextlib.redirect_stderr(said):
            # meshio probes an ASCII STL as binary first, which can overflow harmlessly
            warnings.simplefilter("ignore", RuntimeWarning)
            m = meshio.read(path, file_format=MESHIO_FORMATS[ext][0])
    except SystemExit:  # some of meshio's readers print their reason and exit
        why = " ".join(said.getvalue().split()) or "no reason given"
        raise ValueError(f"{str(path)!r} cannot be read as {ext} ({why})") from None
    except (ValueError, KeyError, IndexError, EOFError, OSError, meshio.ReadError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise ValueError(f"{str(path)!r} cannot be read as {ext} "
                         f"({type(exc).__name__}: {exc})") from None
    other = sorted({block.type for block in m.cells if block.type != "triangle"})
    if other:
        raise ValueError(f"{str(path)!r} contains {', '.join(other)} cells; only triangle cells "
                         "(a triangulated surface) are supported")
    if not m.cells:
        raise ValueError(f"{str(path)!r} contains no triangle cells")
    points = np.asarray(m.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"{str(path)!r} has points of shape {points.shape}; 3D points are required")
    faces = np.concatenate([np.asarray(b.data, dtype=np.int64) for b in m.cells])
    if ext == ".stl":
        points, faces = merge_duplicate_vertices(points, faces)
    validate_surface(points, faces)
    return Mesh.from_arrays(points, faces)


def write_mesh(path, mesh: Mesh, point_data: dict | None = None,
               cell_data: dict | None = None) -> Path:
    """Write ``mesh`` to ``path`` in the format given by its extension; return the path.

    ``point_data`` maps names to arrays of shape ``(V, ...)`` (one entry per vertex),
    ``cell_data`` to arrays ``(F, ...)`` (one per face). Point data is kept by .vtk, .vtu,
    .xdmf, .msh and (scalars only) .ply; cell data by .vtk, .vtu, .xdmf and .msh. Asking
    another format to store data raises ``ValueError`` rather than dropping it. ``.fe`` is
    written by :func:`shellbuckle.mesh.evolver_io.write_evolver`.
    """
    path = Path(path)
    ext = _extension(path)
    point_data = _check_data("point_data", point_data, mesh.n_vertices, ext, _POINT_DATA)
    cell_data = _check_data("cell_data", cell_data, len(mesh.faces), ext, _CELL_DATA)
    if ext in EVOLVER_FORMATS:
        if point_data or cell_data:
            raise ValueError("Surface Evolver files do not take point_data/cell_data here; "
                             "write .vtu or .vtk to keep data")
        from .evolver_io import write_evolver  # imported here: optional at import time
        write_evolver(path, mesh)
        return path
    if ext == ".ply":
        bad = [k for k, v in point_data.items() if v.ndim != 1]
        if bad:
            raise ValueError(f"PLY stores scalar point data only; {bad[0]!r} has shape "
                             f"{point_data[bad[0]].shape}; use .vtu or .vtk for vector data")
    import meshio

    # PLY has no 64-bit integers (meshio would convert them and print a warning of its own)
    index = np.int32 if ext == ".ply" else np.int64
    out = meshio.Mesh(np.asarray(mesh.X, dtype=np.float64),
                      [("triangle", np.asarray(mesh.faces, dtype=index))],
                      point_data=point_data,
                      cell_data={k: [v] for k, v in cell_data.items()})
    kwargs = {"binary": True} if ext == ".stl" else {}
    meshio.write(path, out, file_format=MESHIO_FORMATS[ext][0], **kwargs)
    return path


def _check_data(name: str, data, n: int, ext: str, supported: set) -> dict:
    if not data:
        return {}
    if ext not in supported:
        raise ValueError(f"{ext} files cannot store {name}; formats that can: "
                         f"{', '.join(sorted(supported))}")
    out = {}
    for key, value in data.items():
        value = np.asarray(value)
        if value.ndim == 0 or len(value) != n:
            raise ValueError(f"{name}[{key!r}] must have length {n} along its first axis, "
                             f"got shape {value.shape}")
        out[str(key)] = value
    return out


def merge_duplicate_vertices(points: np.ndarray, faces: np.ndarray):
    """Merge vertices with identical coordinates; keep them in order of first appearance.

    Returns ``(points (V', 3), faces (F, 3))`` with faces renumbered.
    """
    _, first, inverse = np.unique(points, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    order = np.argsort(first)                  # unique rows in order of first appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return points[first[order]], rank[inverse][faces]
