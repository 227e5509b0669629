"""Newton's method for ``min E(x)`` subject to ``V(x) = V_target``, with saddle escape.

This module is the driver; the parts are :mod:`.gauge` (rigid motions), :mod:`.kkt` (the KKT
matrix), :mod:`.system` (factorizations and directions), :mod:`.workspace` (what successive
minimizations share), :mod:`.damping` (shift and line searches), :mod:`.relax` (the
relaxation before Newton's method) and :mod:`.options` (every tuning value). The measurements
behind the defaults are in ``benchmarks/README.md``.

Problem and multiplier
----------------------
Lagrangian ``L = E - lam (V - V_target)``; at a solution ``grad E = lam grad V`` and
``lam = dE/dV``. Results report ``pressure = -lam`` (positive for a compressed shell; Surface
Evolver's body pressure is ``lam``). At every iterate ``lam`` is the least-squares multiplier
``(grad E . grad V) / |grad V|^2`` and ``r = grad E - lam grad V`` the projected gradient.

Newton step
-----------
The iterates stay on the constraint surface (:func:`~.linesearch.restore_volume` after every
trial step), so a step solves the KKT system of :mod:`.kkt` for a tangent ``dx``; ``K``
restricted to the tangent space is the Riemannian Hessian of the energy on the constraint
surface, so full steps converge quadratically (Absil, Mahony & Sepulchre, *Optimization
Algorithms on Matrix Manifolds* (2008), §6.2). Six pinned dofs fix the rigid motions
(:mod:`.gauge`); every factorization gives the inertia of the tangent Hessian
(:mod:`.system`). Where that is indefinite, or a step overshoots along soft modes, the
Levenberg–Marquardt shift of :mod:`.damping` damps the step; at a stationary point with
negative curvature, or where a shifted step fails, a direction of negative curvature is
searched beside it (Moré & Sorensen, Math. Prog. 16, 1 (1979)). While ``mu > 0`` the unshifted
matrix is not factored; it is factored again when ``mu`` drops to 0, when the gradient has
converged, and at the last iteration, so the reported inertia is that of the unshifted tangent
Hessian.

Quasi-Newton steps between factorizations
-----------------------------------------
After each Newton step up to ``max_quasi`` L-BFGS steps reuse its factorization as initial
inverse Hessian, with the secant pairs ``(x_{i+1} - x_i, r_{i+1} - r_i)`` of the steps since
(Nocedal & Wright, *Numerical Optimization*, 2nd ed., §7.2). The matrix is factored again when
a quasi-Newton step is cut below ``quasi_min_alpha`` of its length or fails, after
``max_quasi`` steps, or when the steps stall: over three steps the projected gradient has not
fallen by 10 % and the energy has fallen by less than 0.3 times the fall of the Newton step
(:func:`stalled`; in a curved post-buckling valley the gradient does not fall from step to step
while the energy falls as much per quasi-Newton step as per Newton step).

Preconditioned relaxation
-------------------------
Given a relaxed state near the start (``precondition_at``: the state before a jiggle), the
minimization first relaxes by L-BFGS preconditioned with the shifted Hessian there
(:mod:`.relax`), then Newton's method converges.

Smooth starts
-------------
A start closer than ``relax_rough_min_move`` mean edge lengths (rms) to ``precondition_at`` is
not relaxed: its first steps are quasi-Newton steps on the unshifted Hessian at
``precondition_at`` (:func:`~.relax.exact_preconditioner`). With ``smooth_start=False`` it is
relaxed all the same: near an instability the unshifted Hessian has a soft mode, and its
quasi-Newton steps amplify a start's small component along it into a long step that can carry
the shell over a barrier the relaxation (a shifted, gradient-flow-like descent) stays behind.

Single-precision steps
----------------------
The Newton steps of a point whose gradient has not converged (and their shift search) are
factored in single precision where the solver offers it (``single_precision_steps``, with
``escape_saddles``): inexact Newton steps (relative error about ``1e-7`` times the condition
number along the soft modes) that the line search and the following quasi-Newton steps
correct (Dembo, Eisenstat & Steihaug, SIAM J. Numer. Anal. 19, 400 (1982)). Their inertia only
chooses the shift, never certifies a minimum. After ``single_jam_steps`` Newton steps without
progress (:func:`jammed`) the rest of the minimization factors in double precision.

Single-precision certificates
-----------------------------
With ``certify_single`` the inertia 0 at a converged point is first sought with one
single-precision factorization of the KKT matrix whose tangent Hessian is shifted down by
``certify_shift mean|diag K|`` (:meth:`~.system.KKTSystem.certify_single`); where it shows a
negative eigenvalue, the unshifted double-precision factorization decides, and the
minimization does not try again. A reported inertia other than 0 therefore always comes from a
double-precision factorization; ``result.certificate`` says which one showed inertia 0.

Warm start
----------
A minimization that starts where another one on the same mesh ended, at other parameters (the
protocol's zero-spontaneous-curvature cycle), can take its first steps with the factorization
the workspace's solver still holds (``warm_start=result.factorization``, or a list of such
tokens: the first the workspace holds is used), quasi-Newton steps on it instead of the
relaxation and a first Newton step; it keeps the token's gauge while that fixes the rigid
motions (:mod:`.workspace`). A token that certifies a minimum of the same energy at the same
volume counts as the last unshifted factorization (see "Convergence").

Convergence
-----------
Stop when ``|r| <= tol_grad |grad E| + atol_grad`` (``|grad E|`` is the size of the forces
present, at a constrained minimum the pressure forces), the last accepted step changed the
energy by at most ``tol_energy |E|``, and, when ``escape_saddles`` is on, the tangent Hessian
has no negative eigenvalue. That inertia is the last unshifted factorization's when the point
has moved since by at most ``inertia_step`` mean edge lengths, else the matrix is factored at
the point. The volume constraint then holds to round-off (``~1e-15`` relative).

The gradient test has a floor: the coordinates are known to one unit in the last place, and
a displacement that small changes the gradient by about that unit times the stiffest
eigenvalue of ``K`` (bending at the mesh scale, ``~ kappa / h^2``), summed over all dofs.
That floor grows with the number of vertices while ``|grad E|`` falls, so on fine meshes it
lies above ``tol_grad |grad E|`` (the protocol's ``tol_grad = 1e-9`` is reached down to the
floor at about 40k vertices). Hence two more tests, each of which, with the energy test,
converges as the gradient test does (the inertia is then asked as there):

- the floor test: ``|r| <= tol_floor rho``, with ``rho`` the floor measured at the point,
  the change of ``r`` when every coordinate changes by one unit in the last place (seeded
  random signs, the smaller of two patterns: :meth:`~.system.KKTSystem.gradient_floor`).
  Rounding the exact minimum to the nearest representable point leaves ``|r|`` about
  ``0.29 rho`` (the rms of a uniform rounding error of half a unit), so with ``tol_floor =
  1`` a point passes when its gradient is no larger than the change one unit in the last
  place makes: its gradient cannot tell it from a rounded minimum. The message is
  :data:`AT_FLOOR`.
- the step test (Dennis & Schnabel, *Numerical Methods for Unconstrained Optimization*,
  SIAM 1996, §7.2): a point whose exact Newton step (unshifted, double precision) moves no
  vertex by more than ``tol_step`` times the largest vertex distance from the origin, after
  a step that changed the energy by at most ``tol_energy |E|``, is the minimum to the
  precision of its coordinates, with the message :data:`AT_RESOLUTION` (its inertia is that
  factorization's where inertia is asked for). The default ``1e-15`` is four to nine units
  in the last place of coordinates of order one. A step the solve could not give (no
  descent: ``-r`` scaled, :meth:`~.system.KKTSystem.step`) is not tested; the test is tried
  at the last allowed Newton step too. After buckling, the exact step along the soft modes
  of a point at the floor can exceed ``tol_step``, so on fine meshes the floor test is the
  one that ends those minimizations.

Uncertified minima
------------------
With ``certify=False`` the minimization stops on the gradient and energy tests alone (inertia
``None``): no factorization is made only to show inertia 0. Saddles are still escaped on the
way, since every factorization's inertia sets the shift. The protocol uses it for a waypoint
minimum that is neither reported nor kept.

``max_iter`` bounds the Newton steps, i.e. the factorizations of ``K``; the quasi-Newton and
relaxation steps are not counted against it. ``nit`` counts every accepted step.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .damping import damping_after, damping_next, factor_positive, newton_search
from .gauge import fixes_gauge
from .lbfgs import SecantPairs
from .linesearch import (check_problem, max_displacement, mean_edge_length,
                         quasi_newton_search, restore_volume)
from .listen import accepted
from .options import NewtonOptions
from .relax import exact_preconditioner, relax, smooth_start
from .result import MinimizeResult
from .system import KKTSystem, with_last_gradient
from .workspace import Factorization, Workspace

log = logging.getLogger(__name__)

ABANDONED = "abandoned"
"""Start of the message of a minimization stopped by its ``abandon`` test."""

AT_RESOLUTION = "converged (the Newton step is below the resolution of the coordinates)"
"""Message of a minimization that ended on the step test ("Convergence")."""

AT_FLOOR = "converged (the projected gradient is at its round-off floor)"
"""Message of a minimization that ended on the floor test ("Convergence")."""



class Step(NamedTuple):
    """An accepted step: ``kind`` (``"newton"``, ``"quasi-newton"``, ``"curvature"``), length
    ``alpha``, the energy ``E`` and point ``X`` reached, and the model ratio ``rho``."""

    kind: str
    alpha: float
    E: float
    X: np.ndarray
    rho: float


class Factored(NamedTuple):
    """The last factorization of ``K`` in a minimization: its point, shift, inertia of the
    unshifted tangent Hessian (``None`` if not shown) and precision."""

    X: np.ndarray
    mu: float
    inertia: int | None
    precision: str


@dataclass(frozen=True, eq=False)
class Minimization:
    """What stays fixed during one minimization: its system (:class:`~.system.KKTSystem`),
    the (gradient-caching) energy, volume and target, options, step cap, mean edge length of
    the start, whether inertia 0 must be shown, and the ``abandon`` tests."""

    system: KKTSystem
    energy: object
    volume: object
    V_target: float
    options: NewtonOptions
    max_step: float
    edge: float
    want_inertia: bool
    abandon: object = None
    thorough: object = None


@dataclass(eq=False)
class NewtonState:
    """Where one minimization is: the iterate, its gradients, the shift, the factorization in
    use, the quasi-Newton memory, the progress trails and, once it ends, the outcome
    (``message`` is ``None`` while it runs)."""

    X: np.ndarray
    E: float
    pairs: SecantPairs
    nit: int = 0  # accepted steps, the relaxation's included
    records: list = field(default_factory=list)
    k: int = 0  # Newton steps (factorizations of K); the quasi-Newton steps are not counted
    dE: float | None = None  # energy change of the last accepted step
    mu: float = 0.0  # Levenberg-Marquardt shift
    lam: float = np.nan
    r: np.ndarray | None = None
    gV: np.ndarray | None = None
    r_norm: float = np.nan
    grad_ok: bool = False
    converged: bool = False
    evaluated: bool = False  # lam, r, gV are those at X
    assembled: bool = False  # K is assembled at X
    fact: Factored | None = None
    inertia: int | None = None
    retries: int = 0  # failed line searches at this point
    n_quasi: int = 0  # quasi-Newton steps on the current factorization
    quasi_ok: bool = False
    previous: tuple | None = None  # (X, r) before the last step, for its secant pair
    r_history: list = field(default_factory=list)  # (|r|, E) since the last factorization
    trail: list = field(default_factory=list)  # (E, |r|) after each Newton step
    single_ok: bool = True  # single-precision Newton steps allowed
    certify_single: bool = True  # a single-precision certificate still to try
    ask: object = None  # the abandon test to ask at the next unconverged point
    success: bool = False
    message: str | None = None
    certificate: str | None = None
    floor: float | None = None  # the gradient's round-off floor, last measured
    at_floor: bool = False  # the gradient test holds by the floor test


def newton(energy, volume, X0, V_target, options: NewtonOptions | None = None, *,
           workspace: Workspace | None = None, solver=None, pinned=None,
           precondition_at: np.ndarray | None = None, precondition_token=None,
           warm_start=None, abandon=None, abandon_thorough=None,
           **overrides) -> MinimizeResult:
    """Minimize ``energy`` over positions ``X (V, 3)`` at enclosed ``volume(X) = V_target``.

    Parameters
    ----------
    energy : Energy
        ``value``, ``gradient (V, 3)`` and true ``hessian (3V, 3V)`` (see energies/base.py).
    volume : Volume
        The constraint (``value``, ``gradient``, ``hessian``; ``faces`` for the mesh size).
    X0 : (V, 3) array
        Start; first moved along ``grad V`` onto the constraint surface.
    V_target : float
        Enclosed volume to hold.
    options : NewtonOptions, optional
        Tolerances and tuning (:class:`~.options.NewtonOptions`; default its defaults).
        ``overrides`` (keywords named as its fields, e.g. ``max_iter=50``) replace fields.
    workspace : Workspace, optional
        Linear solver, KKT assemblers and held factorizations shared with other
        minimizations on the same mesh (:class:`~.workspace.Workspace`); warm starts and
        ``precondition_token`` need the workspace they were made in. Default: a new one with
        ``solver`` (``None``, ``"auto"``, ``"qdldl"``, ``"superlu"``, ``"pardiso"`` or a solver
        object, :func:`~.linear.make_solver`); give at most one of the two.
    pinned : (6,) int array, optional
        The dofs that fix the rigid-motion gauge (default :func:`~.gauge.pinned_dofs` at the
        start); used while they fix it (:func:`~.gauge.fixes_gauge`). A caller that minimizes
        the same mesh many times passes one set so that the KKT pattern stays the same.
    precondition_at : (V, 3) array, optional
        A relaxed state near the start: the minimization first relaxes preconditioned with
        the Hessian there, or takes a smooth start (:mod:`.relax`).
    precondition_token : Factorization, optional
        ``result.factorization`` of the minimization that ended at ``precondition_at``: a
        smooth start uses it where the workspace still holds it, made at exactly that point.
    warm_start : Factorization or list of them, optional
        ``result.factorization`` of the minimization that ended at ``X0`` (same workspace,
        other parameters): the first steps reuse it and the relaxation is skipped ("Warm
        start"). Ignored where the workspace's solver no longer holds it.
    abandon : callable, optional
        ``abandon(X) -> str or None``, asked after the relaxation (and at its cut steps) and
        after every Newton step at an unconverged point: a reason stops the minimization
        (``success = False``, message ``"abandoned: <reason>"``).
    abandon_thorough : callable, optional
        A costlier test asked instead of ``abandon`` after the relaxation and after a Newton
        step that ends ``single_jam_steps`` steps without progress (default ``abandon``).

    Returns
    -------
    MinimizeResult
        With ``factorization``: a token of the factorization the workspace holds at the end.
    """
    t_start = time.perf_counter()
    if options is not None and not isinstance(options, NewtonOptions):
        raise ValueError(f"options must be a NewtonOptions, got {options!r}")
    options = (options or NewtonOptions()).replace(**overrides)
    energy = with_last_gradient(energy)
    X, V_target = check_problem(X0, V_target)
    X, verr = restore_volume(volume, X, V_target)
    if not verr <= 1e-12:
        raise ValueError(f"cannot bring X0 to V_target={V_target!r} along the volume gradient "
                         f"(relative volume error {verr:.1e})")
    max_step = options.max_step
    if max_step is None:
        max_step = 0.2 * (3.0 * V_target / (4.0 * np.pi)) ** (1.0 / 3.0)
    tokens = [t for t in (warm_start if isinstance(warm_start, (list, tuple)) else [warm_start])
              if isinstance(t, Factorization)]
    if (options.project_rigid and tokens and tokens[0].pinned is not None
            and fixes_gauge(X, tokens[0].pinned, options.gauge_max_cond)):
        pinned = tokens[0].pinned  # the gauge of the held factorization, while it holds
    system = KKTSystem(energy, volume, V_target, _workspace(workspace, solver), X, options,
                       pinned, np.random.default_rng(options.seed))
    m = Minimization(system, energy, volume, V_target, options, max_step,
                     edge=mean_edge_length(np.asarray(volume.faces), X),
                     want_inertia=options.certify and (options.compute_inertia
                                                       or options.escape_saddles),
                     abandon=abandon, thorough=abandon_thorough or abandon)
    state = _start(m, X, precondition_at, precondition_token, tokens)
    while state.message is None:
        _iterate(m, state)
    return _result(m, state, t_start)


def _workspace(workspace, solver) -> Workspace:
    if workspace is None:
        return Workspace(solver)
    if not isinstance(workspace, Workspace):
        raise ValueError(f"workspace must be a Workspace, got {workspace!r}")
    if solver is not None:
        raise ValueError(f"give either a workspace or a solver, not both (the workspace has its "
                         f"solver); got solver={solver!r}")
    return workspace


def _start(m: Minimization, X, precondition_at, precondition_token, tokens) -> NewtonState:
    """The state at the start: a held factorization (warm start, smooth start) to begin with
    quasi-Newton steps, else the relaxation from ``X`` (if ``precondition_at``)."""
    o, system = m.options, m.system
    E = system.value(X)
    single_ok = o.single_precision_steps and o.escape_saddles
    certify_single = o.certify_single and single_ok
    system.token = next((t for t in tokens if system.workspace.holds(t, system.kkt)), None)
    warm = system.token is not None
    if (precondition_at is not None and not warm and o.smooth_start
            and smooth_start(m.volume, X, precondition_at, o.relax_rough_min_move)):
        system.token = exact_preconditioner(system, precondition_at, precondition_token,
                                            certify_single)
        warm = system.token is not None
    nit, records = 0, []
    if precondition_at is not None and not warm:
        X, E, nit, records = relax(system, X, E, precondition_at, o, m.max_step, m.abandon)
    fact = None
    if warm and system.token.certifies(system.raw_energy, m.V_target):
        # a minimum of this energy, certified by the held factorization
        fact = Factored(system.token.X, 0.0, 0, "single" if system.token.approximate else "double")
    # the test to ask at the next point that has not converged: the thorough one after the
    # relaxation, the cheap one after every Newton step
    ask = m.thorough if precondition_at is not None and not warm else None
    return NewtonState(X=X, E=E, pairs=SecantPairs(X.size, o.memory), nit=nit, records=records,
                       fact=fact, quasi_ok=warm, single_ok=single_ok,
                       certify_single=certify_single, ask=ask)


def _iterate(m: Minimization, st: NewtonState) -> None:
    """One iteration: the gradients at a new point (and the tests there), then a quasi-Newton
    step on the held factorization where it serves, else a Newton step."""
    if not st.evaluated:
        _evaluate(m, st)
        if st.message is not None:
            return
    step = _quasi_newton(m, st)
    if step is None:
        step = _newton_step(m, st)
        if step is None:  # a retry at the same point, or the end
            return
    _accept(m, st, step)


def _evaluate(m: Minimization, st: NewtonState) -> None:
    """Gradients, convergence and the pending ``abandon`` test at a new point."""
    o = m.options
    st.lam, st.r, gE, st.gV = m.system.gradients(st.X)
    st.r_norm = float(np.linalg.norm(st.r))
    st.at_floor = False
    st.grad_ok = (st.r_norm <= o.tol_grad * float(np.linalg.norm(gE)) + o.atol_grad
                  or _at_floor(m, st))
    st.converged = st.grad_ok and (st.dE is None or abs(st.dE) <= o.tol_energy * abs(st.E))
    if st.previous is not None:
        st.pairs.add(st.X - st.previous[0], st.r - st.previous[1])
    st.r_history.append((st.r_norm, st.E))
    st.evaluated = True
    if st.converged and (not m.want_inertia or _certified(st.fact, st.X, o.inertia_step * m.edge)):
        st.success, st.message = True, _converged(st)
        st.inertia = 0 if m.want_inertia else None
        st.certificate = st.fact.precision if m.want_inertia else None
        return
    reason = st.ask(st.X) if st.ask is not None and not st.converged else None
    st.ask = None
    if reason:
        st.message = f"{ABANDONED}: {reason}"


def _quasi_newton(m: Minimization, st: NewtonState) -> Step | None:
    """A quasi-Newton step on the current factorization, or ``None`` where none serves (then
    the matrix is factored again)."""
    o = m.options
    if not (st.retries == 0 and st.quasi_ok and not st.converged and st.n_quasi < o.max_quasi
            and st.k < o.max_iter and not stalled(st.r_history)):
        return None
    quasi = m.system.quasi_newton_step(st.X, st.r, st.pairs, m.volume.value(st.X) - m.V_target)
    if quasi is None:
        return None
    p, slope_p = quasi
    with m.system.clock("line_search"):
        found = quasi_newton_search(m.energy, m.volume, st.X, m.V_target, st.E, st.r_norm, p,
                                    slope_p, m.max_step)
    if found is None:
        st.quasi_ok = False
        return None
    alpha, E_new, X_new = found
    st.quasi_ok = alpha >= o.quasi_min_alpha
    st.n_quasi += 1
    return Step("quasi-newton", alpha, E_new, X_new, np.nan)


def _newton_step(m: Minimization, st: NewtonState) -> Step | None:
    """Factor at the point, test convergence, and search the (damped) Newton step and, at a
    saddle, a negative-curvature direction; ``None`` for a retry or the end."""
    indefinite = _factor(m, st)
    if indefinite is None:
        return None
    o, system = m.options, m.system
    if st.converged and (not o.escape_saddles or st.inertia == 0 or not indefinite):
        st.success, st.message = True, _converged(st)
        st.certificate = st.fact.precision if st.mu == 0.0 and st.inertia == 0 else None
        return None
    s, slope_s, curv_s, solved = system.step(st.X, st.r, m.volume.value(st.X) - m.V_target)
    if solved and _at_resolution(m, st, s, indefinite):
        return None
    if st.k == o.max_iter:
        st.message = f"maximum number of Newton iterations ({o.max_iter}) reached"
        return None
    d, curv_d = _negative_curvature(m, st, indefinite)
    if st.message is not None:
        return None
    with system.clock("line_search"):
        found = newton_search(m.energy, m.volume, st.X, m.V_target, st.E, st.r, s, slope_s,
                              curv_s, d, curv_d, m.max_step, m.edge, st.r_norm,
                              extend=st.mu > 0.0)
    if found is None:
        _search_failed(st, curv_s)
        return None
    step = Step(*found)
    st.mu = damping_next(st.mu, curv_s, step.kind, step.alpha, step.rho)
    st.k += 1
    st.ask = m.abandon
    st.trail.append((step.E, st.r_norm))
    return None if _stuck(m, st, step) else step


def _factor(m: Minimization, st: NewtonState) -> bool | None:
    """Assemble ``K`` at the point (once; pinning other dofs where the gauge is lost) and
    factor it: a single-precision certificate where one is due, else with the smallest
    working shift (:func:`~.damping.factor_positive`). Whether the tangent Hessian is known to
    be indefinite; ``None`` if no shift works (the end)."""
    o, system = m.options, m.system
    if system.gauge_lost(st.X):
        log.info("newton: the pinned dofs no longer fix the rigid motions; pinning others")
        system.set_gauge(st.X)
        st.fact, st.assembled = None, False
    if not st.assembled:
        system.assemble(st.X, st.lam, st.gV)
        st.assembled = True
        if st.grad_ok or st.k == o.max_iter:  # Newton's step, and the inertia at the point
            st.mu = 0.0
    # far from convergence a single-precision factorization serves the step (and the shift
    # search); the inertia that certifies a minimum is always double precision
    single = st.single_ok and not st.grad_ok and st.k < o.max_iter and st.retries == 0
    precision = "double"
    if st.grad_ok and st.mu == 0.0 and m.want_inertia and st.single_ok and st.certify_single:
        st.certify_single = False  # one try per minimization
        if system.certify_single():
            precision = "single"
    if precision == "single":
        shift = (0.0, 0, False)  # positive definite: inertia 0, as unshifted
    else:
        shift = factor_positive(system, st.mu, o.escape_saddles, approximate=single)
    if shift is None:
        st.message = "could not make the tangent Hessian positive definite by a shift"
        return None
    st.mu, st.inertia, indefinite = shift
    st.fact, st.n_quasi, st.quasi_ok = Factored(st.X, st.mu, st.inertia, precision), 0, True
    st.floor = None  # measured again at the next point
    st.pairs.clear()
    st.r_history = [(st.r_norm, st.E)]
    return indefinite


def _at_floor(m: Minimization, st: NewtonState) -> bool:
    """The floor test of "Convergence": whether ``|r|`` at the point is at most ``tol_floor``
    times the gradient's round-off floor there. The floor is measured at the first point that
    fails the gradient test after the start and after each factorization, and at every point
    whose ``|r|`` is below ``tol_floor`` times the last measured floor (it changes little
    along a minimization), so the test costs two gradients per factorization."""
    o = m.options
    if not o.tol_floor or (st.floor is not None and st.r_norm > o.tol_floor * st.floor):
        return False
    st.floor = m.system.gradient_floor(st.X, st.r)
    st.at_floor = st.r_norm <= o.tol_floor * st.floor
    return st.at_floor


def _converged(st: NewtonState) -> str:
    """The message of a minimization that converged on the gradient or the floor test."""
    return AT_FLOOR if st.at_floor else "converged"


def _at_resolution(m: Minimization, st: NewtonState, s: np.ndarray, indefinite: bool) -> bool:
    """The step test of "Convergence": whether the Newton step ``s`` of a point that fails the
    gradient test moves no vertex by more than ``tol_step`` times the largest vertex distance
    from the origin (the point is then the minimum to the precision of its coordinates, and
    the minimization ends there, converged). It counts for an unshifted double-precision
    factorization showing no negative eigenvalue (with ``escape_saddles``) after a step that
    changed the energy by at most ``tol_energy`` relative; such a step of a single-precision
    factorization makes the following factorizations double precision."""
    o = m.options
    if st.grad_ok or not o.tol_step or st.mu != 0.0:
        return False
    step = max_displacement(s)
    if step > o.tol_step * max_displacement(st.X):
        return False
    if m.system.token.approximate:
        st.single_ok = False
        return False
    if o.escape_saddles and indefinite:
        return False
    if st.dE is not None and abs(st.dE) > o.tol_energy * abs(st.E):
        return False
    log.debug("newton: the Newton step (%.3e) is below the resolution of the coordinates at "
              "|r| = %.3e", step, st.r_norm)
    st.converged = True
    st.success, st.message = True, AT_RESOLUTION
    if not m.want_inertia:
        st.inertia = None
    st.certificate = st.fact.precision if st.inertia == 0 else None
    return True


def _negative_curvature(m: Minimization, st: NewtonState, indefinite: bool):
    """``(d, d.K d)``, a direction of negative curvature to search beside the Newton step at a
    stationary saddle or after a failed search, or ``(None, curvature)`` where there is none
    beyond ``curvature_tol`` (at a converged point: the end, a marginal minimum)."""
    o = m.options
    if not (o.escape_saddles and indefinite and (st.grad_ok or st.retries)):
        return None, 0.0
    d, curv_d = m.system.negative_curvature(st.X, o.inverse_iterations)
    if curv_d >= -o.curvature_tol * m.system.diag_scale:
        if st.converged:
            st.success = True
            st.message = (f"converged; the tangent Hessian has {st.inertia} marginal negative "
                          f"eigenvalue(s) above -{o.curvature_tol:g} mean|diag K|")
        return None, curv_d
    return d, curv_d


def _search_failed(st: NewtonState, curv_s: float) -> None:
    """No decrease along the step: converged within round-off, or a retry at the same point
    with stronger damping (three at most), or the end."""
    if st.grad_ok:
        st.success, st.message = True, "converged (no further decrease within round-off)"
    elif st.retries < 3:  # same point and Hessian, stronger damping
        st.retries, st.k = st.retries + 1, st.k + 1
        st.mu = damping_after(st.mu, curv_s, 1.0 / 16.0)
    else:
        st.message = "line search failed to decrease the energy"


def _stuck(m: Minimization, st: NewtonState, step: Step) -> bool:
    """After a Newton step: end the single-precision steps where they jam (asking the
    thorough ``abandon`` test there) and stop a minimization that has stalled; whether it
    stopped (at the step's point)."""
    o, stop = m.options, None
    if jammed(st.trail, o.tol_energy, o.single_jam_steps):
        st.single_ok = False  # inexact steps along the softest modes
        reason = m.thorough(step.X) if m.thorough is not None and not st.grad_ok else None
        stop = f"{ABANDONED}: {reason}" if reason else None
    if stop is None and not st.grad_ok and jammed(st.trail, o.tol_energy, o.jam_steps):
        stop = (f"stalled: {o.jam_steps} Newton steps lowered the energy by less than "
                f"{o.tol_energy:g} relative and the gradient by less than half")
    if stop is None:
        return False
    st.X, st.E = step.X, step.E
    st.lam, st.r, _, st.gV = m.system.gradients(st.X)
    st.r_norm = float(np.linalg.norm(st.r))
    st.message = stop
    st.nit += 1
    accepted(st.E, st.r_norm)
    return True


def _accept(m: Minimization, st: NewtonState, step: Step) -> None:
    log.debug("newton %3d  E=%.15g  |r|=%.3e  lam=%.9g  inertia=%s  mu=%.2e  %s alpha=%.3g "
              "rho=%.3g", st.nit, step.E, st.r_norm, st.lam, st.inertia, st.mu, step.kind,
              step.alpha, step.rho)
    if m.options.history:
        st.records.append(dict(iteration=st.nit, energy=step.E, grad_norm=st.r_norm,
                               lam=st.lam, inertia=st.inertia, mu=st.mu, step=step.kind,
                               alpha=step.alpha, rho=step.rho))
    st.previous = (st.X, st.r) if step.kind != "curvature" else None
    st.dE, st.E, st.X, st.retries = step.E - st.E, step.E, step.X, 0
    st.evaluated = st.assembled = False
    st.nit += 1
    accepted(st.E, st.r_norm)


def _result(m: Minimization, st: NewtonState, t_start: float) -> MinimizeResult:
    system = m.system
    system.clock.t["total"] = time.perf_counter() - t_start
    volume_error = abs(m.volume.value(st.X) - m.V_target) / m.V_target
    log.info("newton: %s after %d iterations, E=%.15g, |r|=%.3e, pressure=%.9g, inertia=%s",
             st.message, st.nit, st.E, st.r_norm, -st.lam, st.inertia)
    held = system.token if system.workspace.holds(system.token, system.kkt) else None
    return MinimizeResult(x=st.X, fun=st.E, grad_norm=st.r_norm, nit=st.nit,
                          success=st.success, message=st.message, pressure=-st.lam,
                          volume_error=volume_error, inertia=st.inertia, method="newton",
                          history=st.records if m.options.history else None,
                          timings=dict(system.clock.t), factorization=held,
                          certificate=st.certificate)


def _certified(fact: Factored | None, X: np.ndarray, max_move: float) -> bool:
    """Whether the inertia 0 of the last factorization (unshifted, or a single-precision
    certificate, at ``fact.X``) holds at ``X``: the points differ by at most ``max_move`` per
    vertex."""
    return (fact is not None and fact.mu == 0.0 and fact.inertia == 0
            and max_displacement(X - fact.X) <= max_move)


def jammed(trail: list, tol_energy: float, steps: int) -> bool:
    """Over the last ``steps`` Newton steps (``trail``: ``(E, |r|)`` after each) the energy
    fell by at most ``tol_energy`` relative and the projected gradient by less than half: the
    iterate is stuck far from stationarity (e.g. on a triangle folded by a jiggle), and more
    Newton steps only cost factorizations."""
    if len(trail) <= steps:
        return False
    (E_old, r_old), (E_new, r_new) = trail[-1 - steps], trail[-1]
    return E_old - E_new <= tol_energy * abs(E_new) and r_new > 0.5 * r_old


def stalled(history: list, window: int = 3, ratio: float = 0.9, progress: float = 0.3) -> bool:
    """Whether the quasi-Newton steps since the last factorization have stalled: over the last
    ``window`` steps the projected gradient has not fallen by ``ratio`` and the energy has
    fallen by less than ``progress`` times the fall of the step taken with the factorization.
    ``history``: ``(|r|, E)`` at the factorization and after every step since."""
    if len(history) <= window:
        return False
    (r_old, E_old), (r_new, E_new) = history[-1 - window], history[-1]
    if r_new <= ratio * r_old:
        return False
    return E_old - E_new <= progress * (history[0][1] - history[1][1])
