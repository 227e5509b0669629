"""Newton's method for ``min E(x)`` subject to ``V(x) = V_target``, with saddle escape.

Problem and multiplier
----------------------
Lagrangian ``L = E - lam (V - V_target)``; at a solution ``grad E = lam grad V`` and
``lam = dE/dV``. Results report ``pressure = -lam`` (positive for a compressed shell; Surface
Evolver's body pressure is ``lam``, the opposite sign). At every iterate ``lam`` is the
least-squares multiplier ``(grad E . grad V) / |grad V|^2`` and ``r = grad E - lam grad V`` is
the projected gradient.

Newton step
-----------
The iterates are kept on the constraint surface (:func:`~.linesearch.restore_volume` after
every trial step), so the step solves the KKT system

    [[K + mu I, g], [g^T, 0]] [dx; dlam] = -[r; V - V_target],
    K = Hess E - lam Hess V,  g = grad V,

for a tangent step ``dx``; ``K`` restricted to the tangent space is the Hessian of the energy
on the constraint surface (Riemannian Hessian), so full steps converge quadratically.

Rigid motions
-------------
Translations and rotations leave ``E`` and ``V`` unchanged: ``K`` is exactly singular along
translations and, at equilibrium, along rotations. QDLDL factors without numerical pivoting,
eliminating the sparse block ``K`` first (AMD puts the dense row ``g`` last), so ``K`` itself
must not be singular. We fix the gauge by pinning six dofs (``dx = 0`` there), chosen by a
column-pivoted QR of the 6 rigid modes at the starting point so that no rigid motion leaves
them all unchanged. This is sparse, exact, and any rigid motion can be added to a step
without changing the energy, so it removes exactly the six null modes. Inertia counts are
therefore on the tangent space modulo rigid motions, like Surface Evolver's ``eigenneg``.

Negative curvature
------------------
By Sylvester's law, ``n_neg(KKT) = n_neg(K on the tangent space) + 1``. Each iteration first
factors with ``mu = 0``; that gives the inertia at the iterate. If the tangent Hessian is
indefinite (or singular), ``mu`` is increased (x100 first, then x8; it restarts from a third of
the last accepted shift, as in IPOPT, Wächter & Biegler, Math. Prog. 106, 25 (2006)) until the
inertia is right; the shifted step is a Levenberg–Marquardt / trust-region-like descent step.
The same shifted factorization then gives, by a few inverse-iteration steps, a direction
``d`` of most negative curvature of the tangent Hessian. Both the shifted step (backtracking)
and ``d`` (expanding/backtracking search, Moré & Sorensen, Math. Prog. 16, 1 (1979)) are
tried and the lower energy wins, so the method leaves a saddle even where the gradient
vanishes exactly (the perfectly symmetric shrunk sphere past its buckling threshold).

Convergence
-----------
Stop when ``|r| <= tol_grad |grad E| + atol_grad`` (``|grad E|`` is the size of the forces
present: at a constrained minimum they are the pressure forces ``lam grad V``; ``atol_grad``,
in energy per length, covers an unloaded shell), the last accepted step changed the energy by
at most ``tol_energy |E|``, and the tangent Hessian has no negative eigenvalue (inertia 0) when
``escape_saddles`` is on. Defaults: ``tol_grad = 1e-8``, ``atol_grad = 1e-10``,
``tol_energy = 1e-10``, ``max_iter = 100``. The volume constraint then holds to round-off
(``~1e-15`` relative).
"""

from __future__ import annotations

import logging
import time
from collections import defaultdict
from contextlib import contextmanager

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from .linear import SingularFactorError, make_solver
from .linesearch import (ENERGY_NOISE, RestoredPath, backtracking, check_problem,
                         curvature_search, mean_edge_length, projected_gradient, restore_volume)
from .result import MinimizeResult

log = logging.getLogger(__name__)


def rigid_modes(X: np.ndarray) -> np.ndarray:
    """The six infinitesimal rigid motions at ``X (V, 3)`` as columns of a ``(3V, 6)`` array:
    translations ``e_k`` and rotations ``e_k x (x - centroid)`` (vertex-major dofs)."""
    c = X - X.mean(axis=0)
    modes = np.zeros((len(X), 3, 6))
    for k in range(3):
        e = np.zeros(3)
        e[k] = 1.0
        modes[:, k, k] = 1.0
        modes[:, :, 3 + k] = np.cross(e, c)
    return modes.reshape(-1, 6)


def pinned_dofs(X: np.ndarray) -> np.ndarray:
    """Six dofs that fix the rigid-motion gauge: the first pivots of a column-pivoted QR of the
    transposed rigid modes, so that the rigid modes restricted to them are well conditioned."""
    piv = scipy.linalg.qr(rigid_modes(X).T, pivoting=True, mode="r")[1]
    return np.sort(piv[:6])


class KKTAssembler:
    """Reduced KKT matrix ``[[K_ff + mu I, g_f], [g_f^T, 0]]`` over the free dofs ``f``, full
    symmetric CSC storage with a pattern that stays fixed while the pattern of ``K`` does
    (so the linear solver reuses its symbolic analysis)."""

    def __init__(self, free: np.ndarray, n_dofs: int):
        self.free = np.asarray(free)
        self.n = len(self.free)
        self.new_index = np.full(n_dofs, -1, dtype=np.int64)
        self.new_index[self.free] = np.arange(self.n)
        self._K_indptr = self._K_indices = None

    def _analyse(self, K: sp.csr_matrix):
        """Pattern and slots. ``K`` is symmetric with sorted indices, so its CSR rows are its
        CSC columns; every column of the reduced KKT matrix is the kept part of a row of
        ``K`` followed by one entry of ``g`` (row ``n``), and the last column holds ``g`` and
        the zero corner. Missing diagonal entries of ``K`` (pruned zeros) are added."""
        n, n_dofs = self.n, K.shape[0]
        rows = np.repeat(np.arange(n_dofs), np.diff(K.indptr))
        a, b = self.new_index[rows], self.new_index[K.indices]
        self._keep = (a >= 0) & (b >= 0)
        a, b = a[self._keep], b[self._keep]
        diag = a == b
        if np.count_nonzero(diag) != n:  # add the missing diagonal entries: rebuild sorted
            a_all = np.concatenate([a, np.arange(n)])
            b_all = np.concatenate([b, np.arange(n)])
            unique, inverse = np.unique(a_all * n + b_all, return_inverse=True)
            self._slot_K_src = inverse[:len(a)]
            a, b = unique // n, unique % n
            diag_pos = inverse[len(a_all) - n:]
        else:
            self._slot_K_src = np.arange(len(a))
            diag_pos = np.flatnonzero(diag)
        counts = np.bincount(a, minlength=n) + 1
        self._indptr = np.zeros(n + 2, dtype=np.int32)
        np.cumsum(np.append(counts, n + 1), out=self._indptr[1:])
        self._nnz = int(self._indptr[-1])
        entry_slot = np.arange(len(a)) + a  # one g entry closes every earlier column
        self._slot_K = entry_slot[self._slot_K_src]
        self._slot_diag = entry_slot[diag_pos]
        self._slot_grow = self._indptr[1:n + 1] - 1
        self._slot_gcol = self._indptr[n] + np.arange(n + 1)
        self._indices = np.empty(self._nnz, dtype=np.int32)
        self._indices[entry_slot] = b
        self._indices[self._slot_grow] = n
        self._indices[self._slot_gcol] = np.arange(n + 1)
        self._K_indptr, self._K_indices = K.indptr.copy(), K.indices.copy()

    def build(self, K: sp.csr_matrix, g: np.ndarray, mu: float) -> sp.csc_matrix:
        if not (self._K_indptr is not None and len(K.indices) == len(self._K_indices)
                and np.array_equal(K.indptr, self._K_indptr)
                and np.array_equal(K.indices, self._K_indices)):
            self._analyse(K)
        gf = g.ravel()[self.free]
        data = np.zeros(self._nnz)
        data[self._slot_K] = K.data[self._keep]
        data[self._slot_diag] += mu
        data[self._slot_grow] = gf
        data[self._slot_gcol[:-1]] = gf
        return sp.csc_matrix((data, self._indices, self._indptr), shape=(self.n + 1, self.n + 1))


def _max_displacement(p: np.ndarray) -> float:
    return float(np.sqrt(np.einsum("ij,ij->i", p, p).max()))


class _Clock:
    def __init__(self):
        self.t = defaultdict(float)

    @contextmanager
    def __call__(self, key):
        t0 = time.perf_counter()
        yield
        self.t[key] += time.perf_counter() - t0


def newton(energy, volume, X0, V_target, *, tol_grad: float = 1e-8, atol_grad: float = 1e-10,
           tol_energy: float = 1e-10, max_iter: int = 100, solver=None,
           project_rigid: bool = True, escape_saddles: bool = True,
           compute_inertia: bool = True, max_step: float | None = None,
           inverse_iterations: int = 12, curvature_tol: float = 1e-8, seed: int = 0,
           history: bool = False) -> MinimizeResult:
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
    tol_grad, atol_grad, tol_energy, max_iter :
        Convergence criteria, see the module docstring.
    solver : None, "auto", "qdldl", "superlu", "pardiso" or a solver object
        The sparse symmetric-indefinite factorization (:mod:`.linear`; default "auto":
        PARDISO if Intel MKL loads, else QDLDL). Pass the same object to successive calls to
        keep its symbolic analysis.
    project_rigid : bool
        Pin six dofs to remove the rigid-motion null space (needed for energies invariant
        under rigid motions, i.e. all shell energies).
    escape_saddles : bool
        Shift and follow negative curvature, and refuse to stop at a saddle.
    compute_inertia : bool
        Factor at the final point to report the inertia (always done when escaping saddles).
    max_step : float, optional
        Largest vertex displacement of one step (default ``0.2 R_eq``, with ``R_eq`` the radius
        of the sphere of volume ``V_target``).
    inverse_iterations : int
        Inverse-iteration steps for the negative-curvature direction.
    curvature_tol : float
        Eigenvalues of the tangent Hessian above ``-curvature_tol * mean|diag K|`` are treated
        as zero (marginal) when deciding whether a converged point is a saddle.
    seed : int
        Seed of the inverse-iteration start vector (results are reproducible).
    history : bool
        Record one dict per iteration in ``result.history``.

    Returns
    -------
    MinimizeResult
    """
    clock = _Clock()
    t_start = time.perf_counter()
    X, V_target = check_problem(X0, V_target)
    linsolver = make_solver(solver)
    X, verr = restore_volume(volume, X, V_target)
    if not verr <= 1e-12:
        raise ValueError(f"cannot bring X0 to V_target={V_target!r} along the volume gradient "
                         f"(relative volume error {verr:.1e})")
    n_dofs = X.size
    free = (np.setdiff1d(np.arange(n_dofs), pinned_dofs(X)) if project_rigid
            else np.arange(n_dofs))
    kkt = KKTAssembler(free, n_dofs)
    if max_step is None:
        max_step = 0.2 * (3.0 * V_target / (4.0 * np.pi)) ** (1.0 / 3.0)
    edge = mean_edge_length(np.asarray(volume.faces), X)
    rng = np.random.default_rng(seed)

    def factor(K, g, mu):
        with clock("assembly"):
            A = kkt.build(K, g, mu)
        with clock("factorization"):
            try:
                linsolver.factor(A)
            except SingularFactorError:
                return False, None
        signs = linsolver.inertia()
        return True, None if signs is None else signs[1] - 1

    def solve(rhs_f, rhs_c=0.0):
        with clock("solve"):
            y = linsolver.solve(np.concatenate([rhs_f, [rhs_c]]))
        out = np.zeros(n_dofs)
        out[free] = y[:-1]
        return out.reshape(-1, 3)

    with clock("assembly"):
        E = energy.value(X)
    dE, mu_last, nit, records = None, 0.0, 0, []
    success, message, inertia = False, "", None
    for k in range(max_iter + 1):
        with clock("assembly"):
            gE, gV = energy.gradient(X), volume.gradient(X)
        lam, r = projected_gradient(gE, gV)
        r_norm = float(np.linalg.norm(r))
        grad_ok = r_norm <= tol_grad * float(np.linalg.norm(gE)) + atol_grad
        converged = grad_ok and (dE is None or abs(dE) <= tol_energy * abs(E))
        if converged and not (compute_inertia or escape_saddles):
            success, message = True, "converged"
            break
        with clock("assembly"):
            K = (energy.hessian(X) - lam * volume.hessian(X)).tocsr()
            K.sort_indices()
            diag_scale = float(np.abs(K.diagonal().ravel()[free]).mean()) or 1.0
        factored, inertia = factor(K, gV, 0.0)
        if converged and (not escape_saddles or inertia in (0, None)):
            success, message = True, "converged"
            break
        if k == max_iter:
            message = f"maximum number of iterations ({max_iter}) reached"
            break
        mu = 0.0
        if not factored or (escape_saddles and inertia is not None and inertia > 0):
            mu = max(mu_last / 3.0, 1e-8 * diag_scale) if mu_last > 0 else 1e-4 * diag_scale
            grow = 8.0 if mu_last > 0 else 100.0
            while True:
                ok, shifted_inertia = factor(K, gV, mu)
                if ok and shifted_inertia in (0, None):
                    break
                mu *= grow
                if mu > 1e12 * diag_scale:
                    break
            if mu > 1e12 * diag_scale:
                message = "could not make the tangent Hessian positive definite by a shift"
                break
            mu_last = mu
        verr_now = (volume.value(X) - V_target)
        s = solve(-r.ravel()[free], -verr_now)
        slope_s = float(np.einsum("ij,ij->", r, s))
        if not slope_s < 0:  # round-off at convergence, or unknown inertia: fall back to -r
            s = -r / diag_scale
            slope_s = -r_norm ** 2 / diag_scale

        d, curv_d = None, 0.0
        if escape_saddles and inertia is not None and inertia > 0:
            d, curv_d = _negative_curvature(solve, K, free, n_dofs, rng, inverse_iterations)
            if curv_d >= -curvature_tol * diag_scale:
                d = None
                if converged:
                    success = True
                    message = (f"converged; the tangent Hessian has {inertia} marginal negative "
                               f"eigenvalue(s) above -{curvature_tol:g} mean|diag K|")
                    break

        with clock("line_search"):
            step = _line_search(energy, volume, X, V_target, E, r, s, slope_s, d, curv_d,
                                max_step, edge, r_norm)
        if step is None:
            if grad_ok:
                success, message = True, "converged (no further decrease within round-off)"
            else:
                message = "line search failed to decrease the energy"
            break
        kind, alpha, E_new, X = step
        dE, E = E_new - E, E_new
        nit += 1
        log.debug("newton %3d  E=%.15g  |r|=%.3e  lam=%.9g  inertia=%s  mu=%.2e  %s alpha=%.3g",
                  k, E, r_norm, lam, inertia, mu, kind, alpha)
        if history:
            records.append(dict(iteration=k, energy=E, grad_norm=r_norm, lam=lam,
                                inertia=inertia, mu=mu, step=kind, alpha=alpha))

    clock.t["total"] = time.perf_counter() - t_start
    volume_error = abs(volume.value(X) - V_target) / V_target
    log.info("newton: %s after %d iterations, E=%.15g, |r|=%.3e, pressure=%.9g, inertia=%s",
             message, nit, E, r_norm, -lam, inertia)
    return MinimizeResult(x=X, fun=E, grad_norm=r_norm, nit=nit, success=success,
                          message=message, pressure=-lam, volume_error=volume_error,
                          inertia=inertia, method="newton",
                          history=records if history else None, timings=dict(clock.t))


def _negative_curvature(solve, K, free, n_dofs, rng, n_iter):
    """Direction of most negative curvature of the tangent Hessian by inverse iteration with
    the current (positive definite on the tangent space) shifted factorization.

    Returns ``(d (V, 3), d . K d)`` with ``d`` tangent and of unit maximum vertex displacement.
    """
    v = rng.standard_normal(len(free))
    d = None
    for _ in range(n_iter):
        d = solve(v)
        v = d.ravel()[free]
        v /= np.linalg.norm(v)
    d /= _max_displacement(d)
    curv = float(d.ravel() @ (K @ d.ravel()))
    return d, curv


def _line_search(energy, volume, X, V_target, E, r, s, slope_s, d, curv_d, max_step, edge,
                 r_norm):
    """Backtracking on the (shifted) Newton step and, if given, a curvature search along the
    negative-curvature direction ``d``; returns ``(kind, alpha, E, X)`` of the lower energy.

    When the predicted decrease ``-r.s`` is below the energy's evaluation noise
    (``ENERGY_NOISE |E|``), a full step is accepted if the energy stays within that noise and
    the projected gradient decreases (see :mod:`.linesearch`)."""
    candidates = []
    alpha0 = min(1.0, max_step / max(_max_displacement(s), np.finfo(float).tiny))
    noise = ENERGY_NOISE * abs(E)
    if d is None and -slope_s <= noise:
        E1, X1 = RestoredPath(energy, volume, X, s, V_target)(alpha0)
        if X1 is not None and E1 <= E + noise:
            r1 = projected_gradient(energy.gradient(X1), volume.gradient(X1))[1]
            if np.linalg.norm(r1) < r_norm:
                return "newton", alpha0, E1, X1
    found = backtracking(RestoredPath(energy, volume, X, s, V_target), E, slope_s, alpha0)
    if found is not None:
        candidates.append(("newton",) + found)
    if d is not None:
        slope_d = float(np.einsum("ij,ij->", r, d))
        if slope_d > 0 or (slope_d == 0 and d.ravel()[np.argmax(np.abs(d))] < 0):
            d, slope_d = -d, -slope_d
        length0 = max(alpha0 * _max_displacement(s), 0.5 * edge)
        found = curvature_search(RestoredPath(energy, volume, X, d, V_target), E, slope_d,
                                 curv_d, min(length0, max_step), max_alpha=max_step)
        if found is not None:
            candidates.append(("curvature",) + found)
    if not candidates:
        return None
    return min(candidates, key=lambda c: c[2])
