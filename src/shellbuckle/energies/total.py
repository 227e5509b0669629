"""The shell's elastic energy: membrane stretching plus bending, built from parameters.

``ShellEnergy`` is itself an energy term (value / gradient / Hessian) and keeps its two parts
so that runs can report ``E_stretch`` and ``E_bend`` separately. Units: lengths in R, energies
in the units of kappa (kappa = 1 unless a material is given); ``A = gamma kappa / R^2``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .bending import Bending
from .kinds import BENDING_KINDS
from .stretching import Stretching


def make_bending(kind: str, mesh, kappa: float, c0: float, c0_profile=None):
    """Bending term of kind ``"juelicher"`` (default) or ``"evolver"``; ``c0_profile (V,)``
    multiplies ``c0`` vertex by vertex (:class:`.bending.Bending`)."""
    if kind == "juelicher":
        return Bending.from_mesh(mesh, kappa=kappa, c0=c0, c0_profile=c0_profile)
    if kind == "evolver":
        from .evolver_bending import StarPerpBending

        return StarPerpBending(mesh.faces, mesh.n_vertices, kappa=kappa, c0=c0,
                               c0_profile=c0_profile)
    raise ValueError(f"bending must be one of {', '.join(BENDING_KINDS)}, got {kind!r}")


def with_c0(bending, c0: float):
    """The bending term with spontaneous curvature ``c0`` (convention c = c1 + c2)."""
    if hasattr(bending, "with_c0"):
        return bending.with_c0(c0)
    return dataclasses.replace(bending, c0=c0)


@dataclass(frozen=True, eq=False)
class ShellEnergy:
    """``E = E_stretch + E_bend`` (Quilliet et al. 2008, eq. 1, Gaussian term omitted)."""

    stretching: Stretching
    bending: object

    @classmethod
    def build(cls, mesh, params, *, bending: str = "juelicher", c0: float | None = None,
              reference=None, form_factors=None, c0_profile=None) -> "ShellEnergy":
        """Energy of ``mesh`` for :class:`~shellbuckle.params.ShellParameters` ``params``.

        The stretching rest state is ``form_factors (F, 3)`` (Surface Evolver's rest metrics)
        if given, else the shape of ``reference`` (positions, default ``mesh.X``: the
        stress-free initial sphere); ``c0`` defaults to ``2/R`` (stress-free sphere), times
        ``c0_profile (V,)`` vertex by vertex if given (a stress-free shape that is not a
        sphere, :func:`~shellbuckle.protocol.imperfection.stress_free_shape`). The
        bending term has the modulus ``params.kappa_helfrich`` of the parameters' energy
        convention (``params.kappa`` under the default helfrich convention).
        """
        t = mesh.topology
        c0 = 2.0 / params.R if c0 is None else float(c0)
        if form_factors is not None:
            stretching = Stretching.from_form_factors(t.faces, t.n_vertices, form_factors,
                                                      params.A, params.nu)
        else:
            X0 = mesh.X if reference is None else np.asarray(reference, float)
            stretching = Stretching.from_reference(X0, t.faces, t.n_vertices, params.A, params.nu)
        return cls(stretching, make_bending(bending, mesh, params.kappa_helfrich, c0,
                                            c0_profile))

    @property
    def c0(self) -> float:
        return self.bending.c0

    def with_c0(self, c0: float) -> "ShellEnergy":
        return ShellEnergy(self.stretching, with_c0(self.bending, c0))

    def parts(self, X) -> dict:
        """``{"E_stretch": ..., "E_bend": ...}`` at positions ``X``."""
        return {"E_stretch": self.stretching.value(X), "E_bend": self.bending.value(X)}

    def value(self, X) -> float:
        return float(self.stretching.value(X) + self.bending.value(X))

    def gradient(self, X) -> np.ndarray:
        return self.stretching.gradient(X) + self.bending.gradient(X)

    def value_and_gradient(self, X) -> tuple[float, np.ndarray]:
        """``(value(X), gradient(X))`` from one pass over the mesh per term (the same numbers
        as the two separate calls)."""
        (Es, gs), (Eb, gb) = (_value_and_gradient(t, X) for t in (self.stretching, self.bending))
        return float(Es + Eb), gs + gb

    def hessian(self, X) -> sp.csr_matrix:
        stretching, bending = self.hessian_terms(X)
        return (stretching + bending).tocsr()

    def hessian_terms(self, X) -> list:
        """The Hessian as the list of its terms (stretching, bending), each a CSR matrix whose
        pattern does not depend on ``X``. Their sum is :meth:`hessian`, whose pattern can lose
        entries that happen to cancel exactly (e.g. on the reference sphere); Newton's method
        scatters the terms separately so that its KKT pattern, and with it the linear solver's
        ordering and round-off, never depend on the values."""
        return [self.stretching.hessian(X), self.bending.hessian(X)]


def _value_and_gradient(term, X):
    fused = getattr(term, "value_and_gradient", None)
    return fused(X) if fused is not None else (term.value(X), term.gradient(X))
