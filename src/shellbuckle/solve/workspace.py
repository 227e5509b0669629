"""The factorization workspace that successive Newton minimizations on one mesh share.

A :class:`Workspace` is owned by whoever runs the minimizations (a deflation run makes one in
:func:`shellbuckle.protocol.deflate.init`) and is passed to each of them explicitly
(``newton(..., workspace=ws)``). It holds

- the linear solver (:mod:`.linear`), with its symbolic analyses, the fill-reducing orderings
  of the patterns it has analysed and the numeric factorizations it holds;
- the KKT assemblers (:class:`~.kkt.KKTAssembler`) of the last few gauges, so that neither an
  assembler nor the solver analyses a pattern again from one minimization to the next;
- :attr:`Workspace.last`, the token of the last factorization given to the solver, and
  :attr:`Workspace.kept`, one token that a caller keeps for a later minimization.

Nothing else in :mod:`shellbuckle.solve` persists between calls: two workspaces made alike
and given the same calls take the same numerical path.

A :class:`Factorization` token says what a factorization of the KKT matrix is (gauge,
precision, point, energy, volume target, shift, inertia) and whether it shows the tangent
Hessian positive definite. A later minimization may reuse the factorization the solver still
holds as the initial inverse Hessian of its first quasi-Newton steps (Nocedal & Wright,
*Numerical Optimization*, 2nd ed., §7.2: any positive definite ``H0`` serves) and, where it
certifies a minimum of the same energy at the same volume, as the certificate of that minimum
(:mod:`.newton`, "Warm start"). :meth:`Workspace.holds` decides whether the solver still holds
it: PARDISO keeps the last two factorizations of a pattern in each precision (``held`` and
``activate``), another solver only its last one. A token refers to its workspace, assembler
and energy weakly, so a kept result keeps none of them alive.
"""

from __future__ import annotations

import weakref

import numpy as np

from .kkt import KKTAssembler
from .linear import SingularFactorError, accepts, make_solver
from .recent import Recent


def weak(obj):
    """A weak reference to ``obj`` (a strong one, as a callable, if it takes none)."""
    try:
        return weakref.ref(obj)
    except TypeError:
        return lambda: obj


class Factorization:
    """What a linear solver holds after a factorization by Newton's method: the workspace and
    KKT assembler (free dofs and pattern), weakly referenced, the pinned dofs of that gauge,
    whether the factorization was approximate (single precision, a preconditioner only), the
    solver's handle of it (``solver.held()``, where the solver keeps more than one), and what
    it certifies: the point, energy (weakly), volume target, shift and inertia."""

    __slots__ = ("workspace", "kkt", "pinned", "approximate", "handle", "X", "energy",
                 "V_target", "mu", "inertia", "certificate")

    def __init__(self, workspace, kkt, pinned, approximate: bool):
        self.workspace, self.kkt, self.approximate = weak(workspace), weak(kkt), approximate
        self.pinned = pinned
        self.handle = self.X = self.energy = self.V_target = self.mu = self.inertia = None
        self.certificate = False  # it shows the tangent Hessian at X positive definite

    def definite_for(self, energy) -> bool:
        """Whether this factorization of the KKT matrix of ``energy`` at the point ``self.X``
        (the matrix does not depend on the volume target) shows the tangent Hessian there
        positive definite: an unshifted double-precision one with inertia 0, or a
        single-precision certificate (:mod:`.newton`, "Single-precision certificates")."""
        return self.certificate and self.energy is not None and self.energy() is energy

    def certifies(self, energy, V_target) -> bool:
        """Whether it is :meth:`definite_for` ``energy`` at ``V_target``: it certifies a minimum
        there."""
        return self.definite_for(energy) and self.V_target == V_target


class Workspace:
    """The linear solver, KKT assemblers and held factorizations of a run's minimizations.

    ``solver``: ``None`` or ``"auto"`` (PARDISO if Intel MKL loads, else QDLDL), a backend
    name or a solver object (:func:`~.linear.make_solver`, with ``threads`` and
    ``reproducible``). A solver serves one workspace: factored through another one, this
    workspace no longer knows what it holds.
    """

    ASSEMBLERS = 4
    """KKT assemblers kept, most recently used first (one per gauge)."""

    def __init__(self, solver=None, *, threads: int | None = None,
                 reproducible: bool | None = None):
        self.solver = make_solver(solver, threads=threads, reproducible=reproducible)
        self.approximate_ok = accepts(self.solver.factor, "approximate")
        # a certificate needs the margin of a shift only where the approximate factorization
        # is in single precision; elsewhere it would save nothing
        self.factors_single = self.approximate_ok and bool(
            getattr(self.solver, "single_precision", False))
        self._assemblers = Recent(self.ASSEMBLERS)
        self.last: Factorization | None = None
        """The token of the last factorization given to :attr:`solver`."""
        self.kept: Factorization | None = None
        """A token a caller keeps for a later minimization (the deflation protocol: the one its
        last step ended with, for the smooth start of the next step). A cache: without it the
        minimization factors the same matrix again, with the same bits."""

    def assembler(self, free: np.ndarray, n_dofs: int) -> KKTAssembler:
        """The :class:`~.kkt.KKTAssembler` for these free dofs, made once and reused while it
        is among the last :attr:`ASSEMBLERS` used."""
        key = (int(n_dofs), np.asarray(free).tobytes())
        kkt = self._assemblers.get(key) or KKTAssembler(free, n_dofs)
        self._assemblers.put(key, kkt)
        return kkt

    def factor(self, A, kkt: KKTAssembler, pinned, approximate: bool):
        """Factor ``A`` (the upper triangle from ``kkt``; ``approximate``: in single precision
        where the solver offers it). Returns ``(token, ok)``: the token, now :attr:`last`, is
        filled in by the caller; ``ok`` is False when the solver found a zero or non-finite
        pivot, and the token then stays approximate with no handle (never a warm start)."""
        token = self.last = Factorization(self, kkt, pinned, True)
        try:
            if approximate:
                self.solver.factor(A, upper=True, approximate=True)
            else:
                self.solver.factor(A, upper=True)
        except SingularFactorError:
            return token, False
        held = getattr(self.solver, "held", None)
        token.approximate, token.handle = approximate, None if held is None else held()
        return token, True

    def holds(self, token, kkt: KKTAssembler) -> bool:
        """Whether the solver can solve with ``token``'s factorization now, for the gauge of
        ``kkt``, in double precision or as a certificate: a solver that keeps several
        factorizations (``activate``) is switched to it if it still holds it; another one must
        not have factored anything since."""
        if not (isinstance(token, Factorization) and (not token.approximate or token.certificate)
                and token.workspace() is self and token.kkt() is kkt):
            return False
        activate = getattr(self.solver, "activate", None)
        if activate is not None and token.handle is not None:
            return bool(activate(token.handle))
        return self.last is token
