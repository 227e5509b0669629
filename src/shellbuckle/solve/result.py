"""The result of a minimization at fixed enclosed volume, modeled on SciPy's ``OptimizeResult``.

Sign convention for the pressure
--------------------------------
At a constrained minimum of ``E`` at volume ``V = V_target`` the gradients are parallel,
``grad E = lam grad V``, and the Lagrange multiplier is ``lam = dE/dV`` along the path of
minima. We report ``pressure = -lam = -dE/dV``: the external overpressure that holds the shell
at that volume. It is positive when the shell is compressed (the energy rises as the volume
shrinks). Surface Evolver's body ``pressure`` is ``lam`` itself, the opposite sign.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, eq=False)
class MinimizeResult:
    """Outcome of a constrained minimization.

    Attributes
    ----------
    x : (V, 3) float array
        Final vertex positions; they satisfy the volume constraint to round-off.
    fun : float
        Energy ``E(x)``.
    grad_norm : float
        Euclidean norm of the projected gradient ``grad E - lam grad V`` (all 3V components),
        with ``lam = (grad E . grad V) / |grad V|^2`` the least-squares multiplier.
    nit : int
        Number of accepted iterations (Newton steps, or CG/gradient steps).
    success : bool
        Whether the convergence criteria were met.
    message : str
        Why the iteration stopped.
    pressure : float
        ``-lam`` (see the module docstring for the sign; Surface Evolver reports ``lam``).
    volume_error : float
        ``|V(x) - V_target| / |V_target|``.
    inertia : int or None
        Number of negative eigenvalues of the Hessian of the Lagrangian
        ``Hess E - lam Hess V`` restricted to the tangent space of the constraint, rigid
        motions removed (Surface Evolver's ``eigenneg``); ``None`` when not computed.
    method : str
        ``"newton"``, ``"cg"``, ``"gd"`` or ``"alternate"``.
    history : list of dict or None
        One record per iteration when requested (energy, gradient norm, step length, ...).
    timings : dict
        Wall time in seconds spent in the main parts (``assembly``, ``factorization``,
        ``solve``, ``line_search``, ``total``).
    factorization : object or None
        Newton's method only: a token for the factorization its linear solver holds at the
        end (of the tangent KKT matrix at a point of the last iterations), which the next
        minimization on the same mesh and gauge may use to start (``newton(...,
        warm_start=result.factorization)``); ``None`` if there is none.
    certificate : str or None
        Newton's method only: the factorization that showed the reported inertia 0,
        ``"double"`` (unshifted, double precision) or ``"single"`` (single precision with the
        tangent Hessian shifted down, :mod:`.newton`, "Single-precision certificates");
        ``None`` where no inertia 0 was shown.
    """

    x: np.ndarray
    fun: float
    grad_norm: float
    nit: int
    success: bool
    message: str
    pressure: float
    volume_error: float
    inertia: int | None
    method: str
    history: list | None = None
    timings: dict = field(default_factory=dict)
    factorization: object | None = field(default=None, repr=False)
    certificate: str | None = None

    @property
    def lam(self) -> float:
        """The Lagrange multiplier ``dE/dV`` (Surface Evolver's body pressure)."""
        return -self.pressure

    def __repr__(self) -> str:
        inertia = "n/a" if self.inertia is None else self.inertia
        return (f"MinimizeResult(method={self.method!r}, success={self.success}, fun={self.fun:.12g}, "
                f"grad_norm={self.grad_norm:.3e}, nit={self.nit}, pressure={self.pressure:.9g}, "
                f"volume_error={self.volume_error:.1e}, inertia={inertia}, message={self.message!r})")
