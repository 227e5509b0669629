"""Minimizers at fixed enclosed volume: Newton (sparse LDL^T, saddle escape), nonlinear
conjugate gradient and gradient descent, all returning a :class:`MinimizeResult` whose
``pressure = -lam = -dE/dV`` (Surface Evolver's body pressure is ``lam``)."""

from __future__ import annotations

import dataclasses

from .cg import conjugate_gradient, gradient_descent
from .linear import QDLDLSolver, SingularFactorError, SuperLUSolver, make_solver
from .linesearch import projected_gradient, restore_volume
from .listen import listening
from .newton import newton
from .options import NewtonOptions
from .result import MinimizeResult
from .workspace import Workspace

__all__ = ["MinimizeResult", "NewtonOptions", "QDLDLSolver", "SingularFactorError",
           "SuperLUSolver", "Workspace", "conjugate_gradient", "gradient_descent",
           "listening", "make_solver", "minimize", "newton", "projected_gradient",
           "restore_volume"]

METHODS = ("newton", "cg", "gd", "alternate")


def minimize(energy, volume, X0, V_target, method: str = "newton", *, tol: float | None = None,
             cg_iter: int = 20, cg_options: dict | None = None, **options) -> MinimizeResult:
    """Minimize ``energy`` at ``volume(X) = V_target`` from ``X0 (V, 3)``.

    ``method``: ``"newton"`` (:func:`newton`), ``"cg"`` (:func:`conjugate_gradient`), ``"gd"``
    (:func:`gradient_descent`), or ``"alternate"``: ``cg_iter`` conjugate-gradient iterations
    (options ``cg_options``) to relax cheaply, then Newton to convergence (the paper
    alternated Surface Evolver's gradient and Hessian steps). ``options`` go to the chosen
    method (to Newton for ``"alternate"``: its inputs, ``options=`` a
    :class:`~.options.NewtonOptions`, ``workspace=``, or fields of it as keywords); ``tol`` is
    a shorthand for ``tol_grad``.
    """
    if tol is not None:
        options["tol_grad"] = tol
    if method == "newton":
        return newton(energy, volume, X0, V_target, **options)
    if method == "cg":
        return conjugate_gradient(energy, volume, X0, V_target, **options)
    if method == "gd":
        return gradient_descent(energy, volume, X0, V_target, **options)
    if method == "alternate":
        relax = conjugate_gradient(energy, volume, X0, V_target, max_iter=cg_iter,
                                   **(cg_options or {}))
        result = newton(energy, volume, relax.x, V_target, **options)
        timings = dict(result.timings)
        timings["cg"] = relax.timings.get("total", 0.0)
        timings["total"] = timings.get("total", 0.0) + timings["cg"]
        history = None
        if result.history is not None or relax.history is not None:
            history = (relax.history or []) + (result.history or [])
        return dataclasses.replace(result, nit=relax.nit + result.nit, method="alternate",
                                   history=history, timings=timings)
    raise ValueError(f"unknown method {method!r}; choose one of {METHODS}")
