"""The linearized KKT system of one Newton minimization: assembly, factorization, directions.

:class:`KKTSystem` holds, for one minimization of ``E`` at ``V = V_target``, the gauge (the
pinned dofs, :mod:`.gauge`), the Hessian of the Lagrangian ``K = Hess E - lam Hess V`` at the
last assembled point (kept as its terms, :mod:`.kkt`) and the factorization in use (a
:class:`~.workspace.Factorization` token). From them it gives

- the inertia of the tangent Hessian: by Sylvester's law of inertia the KKT matrix has
  ``n_neg(Z^T K Z) + 1`` negative eigenvalues, ``Z`` a basis of the tangent space (Gould,
  Math. Prog. 32, 90 (1985)), so every ``L D L^T`` factorization tells whether ``K + mu I`` is
  positive definite there (:meth:`KKTSystem.factor`);
- the Newton step ``s`` of the shifted system and the curvature ``s.K s / s.s`` of the
  unshifted one along it (:meth:`KKTSystem.step`);
- L-BFGS steps whose initial inverse Hessian is the tangent KKT solve with the current
  factorization (Nocedal & Wright, *Numerical Optimization*, 2nd ed., Algorithm 7.4;
  :meth:`KKTSystem.quasi_newton_step`);
- a direction of most negative curvature by inverse iteration with a shifted, positive
  definite factorization (Golub & Van Loan, *Matrix Computations*, 4th ed., §8.2.2;
  :meth:`KKTSystem.negative_curvature`);
- Newton steps from a single-precision factorization refined by GMRES in double precision
  (:mod:`.krylov`, ``refine_iterations``), so that on large meshes, where the single-precision
  solve loses most of its digits along the soft modes, they stay Newton steps
  (:meth:`KKTSystem.step`);
- a single-precision certificate: inertia 0 of a single-precision factorization of the KKT
  matrix with ``K`` shifted down by ``sigma``, whose computed factors are those of
  ``K - sigma I + E`` with a backward error ``|E|`` of the order of the single-precision
  round-off times ``|K|`` (for small growth; Higham, *Accuracy and Stability of Numerical
  Algorithms*, 2nd ed., ch. 11), shows ``K`` positive definite on the tangent space while
  ``|E| < sigma`` (:meth:`KKTSystem.certify_single`).

Every direction is taken without its rigid-motion part (:func:`~.gauge.remove_rigid`).
"""

from __future__ import annotations

import time
from collections import defaultdict
from contextlib import contextmanager

import numpy as np

from .gauge import fixes_gauge, free_dofs, pinned_dofs, remove_rigid
from .krylov import gmres, symmetric_matvec
from .linesearch import max_displacement, projected_gradient
from .workspace import weak


class LastGradient:
    """``energy`` whose values come with the gradient (``value_and_gradient``), the last of
    which is kept: the point a line search accepts is evaluated once instead of twice (value,
    then gradient). Other attributes are the energy's."""

    def __init__(self, energy):
        self.energy = energy
        self._fused = energy.value_and_gradient
        self._X = self._X_copy = self._g = None

    def value(self, X) -> float:
        E, self._g = self._fused(X)
        self._X, self._X_copy = X, np.array(X, copy=True)
        return E

    def gradient(self, X) -> np.ndarray:
        if X is self._X and np.array_equal(X, self._X_copy):
            return self._g
        return self.energy.gradient(X)

    def __getattr__(self, name):
        return getattr(self.energy, name)


def gradient_floor(energy, volume, X, r, seed: int = 0, samples: int = 2) -> float:
    """The round-off floor of the projected gradient ``r`` at ``X``: the smallest, over
    ``samples`` random sign patterns drawn from ``seed``, of ``|r(X + d) - r|`` with ``d`` a
    change of every coordinate by one unit in the last place (``np.spacing``). It is
    ``|K d|`` to a few per cent (the energy's own round-off is smaller), and the same at the
    same ``X`` whatever was computed before."""
    rng = np.random.default_rng(seed)
    floor = np.inf
    for _ in range(samples):
        Xd = X + np.where(rng.random(X.shape) < 0.5, -1.0, 1.0) * np.spacing(X)
        _, rd = projected_gradient(energy.gradient(Xd), volume.gradient(Xd))
        floor = min(floor, float(np.linalg.norm(rd - r)))
    return floor


def with_last_gradient(energy):
    """``energy`` as a :class:`LastGradient` where it has ``value_and_gradient``."""
    return LastGradient(energy) if hasattr(energy, "value_and_gradient") else energy


class Clock:
    """Wall time spent per part (``clock("solve")`` as a context), summed in :attr:`t`."""

    def __init__(self):
        self.t = defaultdict(float)

    @contextmanager
    def __call__(self, key):
        t0 = time.perf_counter()
        yield
        self.t[key] += time.perf_counter() - t0


class KKTSystem:
    """Assembly, factorization and solves of one Newton minimization of ``energy`` at
    ``volume = V_target``, in ``workspace`` (:class:`~.workspace.Workspace`), with
    ``options`` (:class:`~.options.NewtonOptions`): the gauge is pinned at ``X`` with the
    dofs ``pinned`` where they fix it (else :func:`~.gauge.pinned_dofs` there); ``rng``
    draws the start vectors of the inverse iteration."""

    def __init__(self, energy, volume, V_target, workspace, X, options, pinned, rng):
        self.energy, self.volume, self.V_target = energy, volume, V_target
        self.workspace, self.options, self.rng = workspace, options, rng
        self.linsolver = workspace.solver
        self.n_dofs = X.size
        self.pinned = None
        self.free = np.arange(self.n_dofs)
        if options.project_rigid:
            self.set_gauge(X, pinned)
        else:
            self.kkt = workspace.assembler(self.free, self.n_dofs)
        self.clock = Clock()
        self.diag_scale = 1.0
        self._terms = self._data = self._X_assembled = None
        self.raw_energy = energy.energy if isinstance(energy, LastGradient) else energy
        self.token = None  # the factorization the solves use (made here, or a warm start's)

    def set_gauge(self, X, pinned=None) -> bool:
        """Pin ``pinned`` (or, if those do not fix the rigid motions at ``X``, the dofs of
        :func:`~.gauge.pinned_dofs` at ``X``); whether the gauge changed."""
        if pinned is None or not fixes_gauge(X, pinned, self.options.gauge_max_cond):
            pinned = pinned_dofs(X)
        pinned = np.sort(np.asarray(pinned))
        if self.pinned is not None and np.array_equal(pinned, self.pinned):
            return False
        self.pinned = pinned
        self.free = free_dofs(self.n_dofs, pinned)
        self.kkt = self.workspace.assembler(self.free, self.n_dofs)
        return True

    def gauge_lost(self, X) -> bool:
        """Whether the pinned dofs no longer fix the rigid motions at ``X`` (some rigid motion
        leaves all of them unchanged: ``K`` on the free dofs is then singular, and the residual
        on the pinned dofs cannot be removed)."""
        return self.pinned is not None and not fixes_gauge(X, self.pinned,
                                                           self.options.gauge_max_cond)

    def value(self, X) -> float:
        with self.clock("assembly"):
            return self.energy.value(X)

    def gradients(self, X):
        """``(lam, r, grad E, grad V)`` at ``X``, ``lam`` the least-squares multiplier and ``r``
        the projected gradient (:func:`~.linesearch.projected_gradient`)."""
        with self.clock("assembly"):
            gE, gV = self.energy.gradient(X), self.volume.gradient(X)
        lam, r = projected_gradient(gE, gV)
        return lam, r, gE, gV

    def gradient_floor(self, X, r) -> float:
        """The round-off floor of ``r`` at ``X`` (:func:`gradient_floor`, the options' seed)."""
        with self.clock("assembly"):
            return gradient_floor(self.raw_energy, self.volume, X, r, self.options.seed)

    def assemble(self, X, lam, gV):
        """Hessian of the Lagrangian ``K = Hess E - lam Hess V`` (kept as its two terms)."""
        with self.clock("assembly"):
            terms = getattr(self.energy, "hessian_terms", None)
            HE = terms(X) if terms is not None else [self.energy.hessian(X)]
            self._terms = [(H, 1.0) for H in HE] + [(self.volume.hessian(X), -lam)]
            self._data = self.kkt.build(self._terms, gV)
            self.diag_scale = float(np.abs(self.kkt.diagonal(self._data)).mean()) or 1.0
            self._X_assembled = np.array(X, copy=True)

    def K_times(self, v: np.ndarray) -> np.ndarray:
        v = v.ravel()
        return sum(c * (M @ v) for M, c in self._terms)

    def factor(self, mu: float, approximate: bool = False):
        """Factor the KKT matrix with shift ``mu``: ``(ok, n_neg of the tangent Hessian)``.
        ``approximate``: in single precision where the solver offers it (see :mod:`.linear`),
        for a preconditioner, a step far from a minimum or a certificate with a margin."""
        A = self.kkt.matrix(self._data, mu)
        approximate = approximate and self.workspace.approximate_ok
        with self.clock("factorization"):
            token, ok = self.workspace.factor(A, self.kkt, self.pinned, approximate)
        self.token = token
        if not ok:
            return False, None
        signs = self.linsolver.inertia()
        inertia = None if signs is None else signs[1] - 1
        token.X, token.V_target = self._X_assembled, self.V_target
        token.energy = weak(self.raw_energy)
        token.mu, token.inertia = mu, inertia
        token.certificate = not approximate and mu == 0.0 and inertia == 0
        return True, inertia

    def certify_single(self) -> bool:
        """Whether one single-precision factorization of the KKT matrix with the tangent
        Hessian shifted down by ``certify_shift mean|diag K|`` has inertia 0, which shows the
        tangent Hessian positive definite (module docstring); the solver then holds that
        factorization. False at once where the solver has no single precision."""
        if not self.workspace.factors_single:
            return False
        ok, inertia = self.factor(-self.options.certify_shift * self.diag_scale,
                                  approximate=True)
        self.token.certificate = bool(ok and inertia == 0)
        return self.token.certificate

    def solve(self, rhs_f, rhs_c=0.0, refine: bool = False) -> np.ndarray:
        """The KKT solve with the current factorization for the right-hand side ``(rhs_f,
        rhs_c)`` (free dofs, constraint), as positions ``(V, 3)`` (zero on the pinned dofs).
        ``refine``: where the factorization is single precision, GMRES with it as
        preconditioner and the matrix of that factorization (its shift included) in double
        precision, to ``refine_rtol`` within ``refine_iterations`` iterations (:mod:`.krylov`)."""
        b = np.concatenate([rhs_f, [rhs_c]])
        token, o = self.token, self.options
        if refine and token is not None and token.approximate and o.refine_iterations:
            with self.clock("refine"):
                matvec = symmetric_matvec(self.kkt.matrix(self._data, token.mu))
                y = gmres(matvec, self.linsolver.solve, b, o.refine_rtol,
                          o.refine_iterations).x
        else:
            with self.clock("solve"):
                y = self.linsolver.solve(b)
        out = np.zeros(self.n_dofs)
        out[self.free] = y[:-1]
        return out.reshape(-1, 3)

    def without_rigid(self, X, p) -> np.ndarray:
        """``p`` minus its least-squares component along the rigid motions at ``X`` (when the
        gauge is pinned; :func:`~.gauge.remove_rigid`)."""
        return p if self.pinned is None else remove_rigid(X, p)

    def step(self, X, r, verr):
        """Newton step ``s`` from the current factorization (rigid part removed), its slope
        ``r.s``, the curvature ``s.K s / s.s`` of the unshifted tangent Hessian along it, and
        whether ``s`` is the solve's step: where the solve gives no descent (round-off at
        convergence) ``s = -r / mean|diag K|`` instead. A single-precision factorization's solve
        is refined in double precision (:meth:`solve`)."""
        s = self.without_rigid(X, self.solve(-r.ravel()[self.free], -verr, refine=True))
        slope = float(np.einsum("ij,ij->", r, s))
        solved = slope < 0
        if not solved:
            s = -r / self.diag_scale
            slope = -float(np.einsum("ij,ij->", r, r)) / self.diag_scale
        ss = float(np.einsum("ij,ij->", s, s))
        curv = float(s.ravel() @ self.K_times(s)) / ss if ss > 0 else 0.0
        return s, slope, curv, solved

    def quasi_newton_step(self, X, r, pairs, verr, scale: float = 1.0):
        """L-BFGS step ``p = -H r`` whose initial inverse Hessian ``H0`` is the current
        factorization (the tangent KKT solve) times ``scale`` and whose pairs are the steps
        taken since (a :class:`~.lbfgs.SecantPairs`, or ``None``: none); ``(p, r.p)``, or
        ``None`` if ``p`` is not a descent direction."""

        def H0(q):
            z = self.solve(q[self.free], -verr).ravel()
            if scale != 1.0:
                z *= scale
            return z

        z = H0(-r.ravel()) if pairs is None else pairs.apply(-r, H0)
        p = self.without_rigid(X, z.reshape(-1, 3))
        slope = float(np.einsum("ij,ij->", r, p))
        return (p, slope) if slope < 0 else None

    def negative_curvature(self, X, n_iter: int):
        """Direction of most negative curvature of the tangent Hessian by ``n_iter`` steps of
        inverse iteration with the current (shifted, positive definite on the tangent space)
        factorization: ``(d (V, 3), d . K d)`` with ``d`` tangent, without rigid motion and of
        unit maximum vertex displacement."""
        v = self.rng.standard_normal(len(self.free))
        d = None
        for _ in range(n_iter):
            d = self.solve(v)
            v = d.ravel()[self.free]
            v /= np.linalg.norm(v)
        d = self.without_rigid(X, d)
        d /= max_displacement(d)
        return d, float(d.ravel() @ self.K_times(d))

