"""Energies of a Surface Evolver datafile or dump, computed with the file's own quantities.

Each ``energy`` quantity of the file becomes an energy term of this package:

- method ``linear_elastic`` -> :class:`~shellbuckle.energies.stretching.Stretching` built from
  the facet attributes ``form_factors`` (rest metric) and ``poisson_ratio``, with the
  quantity's ``modulus`` as the 2D Young modulus ``A``. Facets whose ``form_factors`` have a
  non-positive determinant (for instance never set, all zero) get zero energy, as in Evolver
  2.70 (``method4.c``: ``if (det <= 0) return 0``); that is logged.
- method ``star_perp_sq_mean_curvature`` ->
  :class:`~shellbuckle.energies.evolver_bending.StarPerpBending` with ``kappa = modulus / 2``
  and ``c0 = 2 h_zero`` (``h_zero`` from the vertex attribute, else the parameter, else 0).
  Evolver measures the curvature along each facet's own orientation; where the mesh faces were
  reversed to point out of the body (``facet_sign = -1``), ``h_zero`` changes sign.

Method instances applied to some elements only (non-global quantities) act on those elements.
Other energies (facet surface tension, other methods, gravity) are not included in ``E_total``;
the facet surface-tension energy Evolver adds by default (tension 1 unless a facet sets
``tension``/``density``) is reported separately as ``E_tension``, so Evolver's
``total_energy`` is ``E_total + E_tension`` when the file has no other energy.

Reference: Surface Evolver 2.70 manual, named methods ``linear_elastic`` and
``star_perp_sq_mean_curvature``; sources ``method4.c`` and ``sqcurve3.c``.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ..mesh.evolver_io import EvolverFile, read_evolver
from .evolver_bending import StarPerpBending
from .stretching import Stretching
from .volume import Volume

log = logging.getLogger(__name__)

__all__ = ["evolver_energy", "evolver_terms"]


def _as_file(source) -> EvolverFile:
    if isinstance(source, EvolverFile):
        return source
    return read_evolver(Path(source))


def _stretching_terms(evf: EvolverFile) -> list:
    mesh = evf.mesh
    terms = []
    for q in evf.energy_quantities("linear_elastic"):
        where = f"{evf.path}: quantity {q.name!r} (linear_elastic)"
        if evf.form_factors is None or evf.poisson_ratio is None:
            missing = "form_factors real[3]" if evf.form_factors is None else "poisson_ratio real"
            raise ValueError(f"{where} needs the facet attribute {missing}, which the file does not "
                             "define (Surface Evolver 2.70 refuses such a file too)")
        if q.modulus == 0.0:
            continue
        if not q.modulus > 0.0:
            raise ValueError(f"{where}: modulus must be positive (2D Young modulus), got {q.modulus!r}")
        facets = np.arange(len(mesh.faces)) if q.facets is None else q.facets
        ff = evf.form_factors[facets]
        det = ff[:, 0] * ff[:, 2] - ff[:, 1] ** 2
        if (det <= 0).any():
            log.warning("%s: %d facets have form_factors with det <= 0 (e.g. not set); like Surface "
                        "Evolver 2.70 they get zero stretching energy", where, int((det <= 0).sum()))
            facets, ff = facets[det > 0], ff[det > 0]
        nu = evf.poisson_ratio[facets]
        for value in np.unique(nu):  # Stretching has one Poisson ratio: one term per value
            sel = nu == value
            terms.append(Stretching.from_form_factors(mesh.faces[facets[sel]], mesh.n_vertices,
                                                      ff[sel], A=q.modulus, nu=float(value)))
    return terms


def _vertex_orientation(evf: EvolverFile) -> np.ndarray:
    """+1/-1 per vertex: whether Evolver's facets around it have the mesh orientation.

    Raises if the facets around a vertex disagree (Evolver's sign of ``h`` there would depend on
    its internal facet order)."""
    V = evf.mesh.n_vertices
    idx = evf.mesh.faces.ravel()
    sign = np.repeat(evf.facet_sign, 3)
    n_neg = np.bincount(idx, weights=(sign < 0), minlength=V)
    n_all = np.bincount(idx, minlength=V)
    mixed = (n_neg > 0) & (n_neg < n_all)
    if mixed.any():
        v = int(np.flatnonzero(mixed)[0])
        raise ValueError(f"{evf.path}: the facets around vertex {evf.vertex_ids[v]} have opposite "
                         "orientations; star_perp_sq_mean_curvature's sign of h there is not "
                         "defined by the file (orient the facets consistently)")
    return np.where(n_neg > 0, -1.0, 1.0)


def _bending_terms(evf: EvolverFile) -> list:
    mesh = evf.mesh
    quantities = [q for q in evf.energy_quantities("star_perp_sq_mean_curvature") if q.modulus != 0.0]
    if not quantities:
        return []
    h_zero = np.zeros(mesh.n_vertices) if evf.h_zero is None else \
        np.broadcast_to(np.asarray(evf.h_zero, dtype=np.float64), (mesh.n_vertices,))
    h_zero = h_zero * _vertex_orientation(evf)
    return [StarPerpBending.from_evolver(mesh.faces, mesh.n_vertices, modulus=q.modulus,
                                         h_zero=h_zero, vertices=q.vertices) for q in quantities]


def evolver_terms(source) -> dict:
    """Energy terms of a Surface Evolver file (path or :class:`EvolverFile`).

    Returns ``{"stretch": [Stretching, ...], "bend": [StarPerpBending, ...]}``, each term acting
    on ``evf.mesh.X`` (sum them with :class:`~shellbuckle.energies.base.Sum`).
    """
    evf = _as_file(source)
    return {"stretch": _stretching_terms(evf), "bend": _bending_terms(evf)}


def evolver_energy(source) -> dict:
    """Energies, volume and area of the configuration in a Surface Evolver datafile or dump.

    ``source`` is a path or an :class:`~shellbuckle.mesh.evolver_io.EvolverFile`. Returns a
    dict of floats:

    - ``E_stretch``: sum of the ``linear_elastic`` energy quantities;
    - ``E_bend``: sum of the ``star_perp_sq_mean_curvature`` energy quantities;
    - ``E_total = E_stretch + E_bend``;
    - ``volume``: enclosed volume of the outward-oriented surface (Evolver's body volume);
    - ``area``: total facet area (Evolver's ``total_area``);
    - ``E_tension``: facet surface tension times area, which Evolver also counts in its
      ``total_energy`` (zero for files written by :func:`write_evolver`); not in ``E_total``.

    Energies are in the file's units (its moduli). Raises ``ValueError`` for an unreadable or
    unsupported file.
    """
    evf = _as_file(source)
    terms = evolver_terms(evf)
    X = evf.mesh.X
    x = X[evf.mesh.faces]
    face_area = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
    E_stretch = float(sum(t.value(X) for t in terms["stretch"]))
    E_bend = float(sum(t.value(X) for t in terms["bend"]))
    for note in evf.skipped:
        if "not computed" in note:
            log.warning("%s: %s", evf.path, note)
    return {"E_stretch": E_stretch, "E_bend": E_bend, "E_total": E_stretch + E_bend,
            "volume": Volume(evf.mesh.faces, evf.mesh.n_vertices).value(X),
            "area": float(face_area.sum()),
            "E_tension": float(np.dot(evf.facet_tension, face_area))}
