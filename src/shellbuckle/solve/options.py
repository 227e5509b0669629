"""The options of Newton's method at fixed volume, one frozen value (:class:`NewtonOptions`).

Every number that steers :func:`~.newton.newton` is a field here, with the value the method
was tuned with as its default (the measurements behind each default are in
``benchmarks/README.md``, "Newton's method: the measurements behind its defaults"). A run that
wants other values builds another value, ``dataclasses.replace(NewtonOptions(), max_quasi=0)``
or ``NewtonOptions(max_quasi=0)``; nothing is read from module globals, so two minimizations
with equal options and equal inputs take the same path.
"""

from __future__ import annotations

import dataclasses
import numbers
from dataclasses import dataclass

import numpy as np

_INTEGERS = ("max_iter", "inverse_iterations", "refine_iterations", "max_quasi", "memory", "seed",
             "jam_steps", "single_jam_steps", "relax_rough_full", "relax_window", "relax_memory",
             "relax_ask_steps")
_FLAGS = ("project_rigid", "escape_saddles", "compute_inertia", "certify", "certify_single",
          "single_precision_steps", "history", "relax_scaling", "smooth_start")


@dataclass(frozen=True)
class NewtonOptions:
    """Options of :func:`~.newton.newton` (defaults: the tuned values).

    Convergence (:mod:`.newton`, "Convergence")
        ``tol_grad``, ``atol_grad``: stop when ``|r| <= tol_grad |grad E| + atol_grad``;
        ``tol_energy``: and the last step changed the energy by at most ``tol_energy |E|``;
        ``tol_step``: or the unshifted double-precision Newton step moves no vertex by more
        than ``tol_step`` times the largest vertex distance from the origin (the gradient's
        round-off floor, :mod:`.newton` "Convergence"; 0: no step test);
        ``tol_floor``: or ``|r|`` is at most ``tol_floor`` times the gradient's measured
        round-off floor, the change of ``r`` under a change of every coordinate by one unit
        in the last place (:mod:`.newton` "Convergence"; 0: no floor test);
        ``max_iter``: Newton steps (factorizations of ``K``) at most, the quasi-Newton and
        relaxation steps not counted (the relaxation takes at most ``max_iter // 2``).
    What is shown at the end
        ``project_rigid``: pin six dofs to remove the rigid motions (:mod:`.gauge`);
        ``escape_saddles``: shift and follow negative curvature, never stop at a saddle;
        ``compute_inertia``: report the inertia at the final point; ``certify``: stop only
        where a factorization shows inertia 0 (``False``: the gradient and energy tests
        alone, inertia ``None``, :mod:`.newton` "Uncertified minima"); ``inertia_step``: a
        point within this many mean edge lengths (largest vertex displacement) of the last
        unshifted factorization keeps its inertia (0 refactors at every converged point);
        ``curvature_tol``: tangent eigenvalues above ``-curvature_tol mean|diag K|`` are
        marginal.
    Precision (:mod:`.newton`, "Single-precision steps" and "Single-precision certificates")
        ``single_precision_steps``: factor the Newton steps of an unconverged point in single
        precision where the solver offers it (with ``escape_saddles`` only);
        ``certify_single``: try the certificate first in single precision with the tangent
        Hessian shifted down by ``certify_shift mean|diag K|``; ``single_jam_steps``: Newton
        steps without progress after which the rest of a minimization factors in double
        precision; ``refine_iterations``, ``refine_rtol``: the Newton step of a
        single-precision factorization is refined by at most that many GMRES iterations to
        that relative residual of the double-precision KKT system (0: not refined;
        :mod:`.krylov`).
    Steps
        ``max_step``: largest vertex displacement of one step (``None``: ``0.2 R_eq``, the
        radius of the sphere of the target volume); ``inverse_iterations``: steps of the
        inverse iteration for a negative-curvature direction; ``seed``: its start vector
        (and the sign patterns of the gradient's round-off floor);
        ``max_quasi``, ``memory``: quasi-Newton steps per factorization and their secant
        pairs (``max_quasi = 0``: plain Newton); ``quasi_min_alpha``: a quasi-Newton step cut
        below this fraction of its length ends the reuse of a factorization; ``jam_steps``:
        Newton steps without progress after which a minimization stops as stalled;
        ``gauge_max_cond``: largest condition number of the rigid modes on the pinned dofs
        for which a gauge is kept (:func:`.gauge.fixes_gauge`); ``history``: one record per
        accepted step in ``result.history``.
    Relaxation (:mod:`.relax`)
        ``relax_shift``, ``relax_rough_shift``: shifts of the preconditioner after and during
        the rough stage, relative to ``mean|diag K|`` (a rough shift not above
        ``relax_shift`` skips that stage); ``relax_rough_full``: consecutive full steps that
        end the rough stage; ``relax_rough_max_move``, ``relax_rough_min_move``: the rough
        stage runs only for a start between these many mean edge lengths (rms) from the
        relaxed state, and a start closer than the minimum is not relaxed at all (a smooth
        start) where ``smooth_start`` is on (off: it is relaxed, without the rough stage;
        the protocol turns it off for a start with an imperfection); ``relax_tol``,
        ``relax_window``: the relaxation stops when the energy falls by less than
        ``relax_tol |E|`` over ``relax_window`` steps; ``relax_memory``: its secant
        pairs; ``relax_scaling``: scale its initial inverse Hessian by the line searches'
        estimate after the rough stage; ``relax_ask_steps``, ``relax_ask_alpha``: after that
        many consecutive steps cut below that fraction of their length, ``abandon`` is asked.
    """

    tol_grad: float = 1e-8
    atol_grad: float = 1e-10
    tol_energy: float = 1e-10
    tol_step: float = 1e-15
    tol_floor: float = 1.0
    max_iter: int = 100
    project_rigid: bool = True
    escape_saddles: bool = True
    compute_inertia: bool = True
    certify: bool = True
    inertia_step: float = 1e-4
    curvature_tol: float = 1e-8
    single_precision_steps: bool = True
    certify_single: bool = True
    certify_shift: float = 1e-6
    single_jam_steps: int = 3
    refine_iterations: int = 20
    refine_rtol: float = 1e-8
    max_step: float | None = None
    inverse_iterations: int = 12
    seed: int = 0
    max_quasi: int = 50
    memory: int = 16
    quasi_min_alpha: float = 0.05
    jam_steps: int = 10
    gauge_max_cond: float = 10.0
    history: bool = False
    relax_shift: float = 1e-3
    relax_rough_shift: float = 1.0
    relax_rough_full: int = 3
    relax_rough_max_move: float = 1.5
    relax_rough_min_move: float = 0.3
    smooth_start: bool = True
    relax_tol: float = 1e-5
    relax_window: int = 5
    relax_memory: int = 20
    relax_scaling: bool = True
    relax_ask_steps: int = 5
    relax_ask_alpha: float = 1e-3

    def __post_init__(self):
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name in _FLAGS:
                ok = isinstance(value, (bool, np.bool_))
                allowed = "True or False"
            elif f.name in _INTEGERS:
                ok = isinstance(value, numbers.Integral) and not isinstance(value, bool) \
                    and value >= 0
                allowed = "an integer >= 0"
            elif f.name == "max_step":
                ok = value is None or (isinstance(value, numbers.Real) and 0 < value < np.inf)
                allowed = "a positive number or None"
            else:
                ok = isinstance(value, numbers.Real) and not isinstance(value, bool) \
                    and 0 <= value < np.inf
                allowed = "a finite number >= 0"
            if not ok:
                raise ValueError(f"Newton option {f.name} must be {allowed}, got {value!r}")

    def replace(self, **changes) -> "NewtonOptions":
        """These options with ``changes`` (field names; a ``ValueError`` names any other)."""
        unknown = sorted(set(changes) - {f.name for f in dataclasses.fields(self)})
        if unknown:
            names = ", ".join(f.name for f in dataclasses.fields(self))
            raise ValueError(f"unknown Newton option(s) {unknown}; the options are the fields "
                             f"of NewtonOptions: {names}")
        return dataclasses.replace(self, **changes) if changes else self
