"""Krylov solves against PARDISO's factorization for the Newton system of a stored step.

For each step ``k`` of a finished run, at its stored minimum ``X_k``: the Hessian ``K = Hess E
- lam Hess V`` (``lam`` the least-squares multiplier of ``grad E = lam grad V``, the stored
pressure with its sign changed), shifted by ``mu = --shift x mean|diag K|``, and the right-hand
side of the start of step ``k``: step ``k - 1``'s minimum rescaled about its centroid to step
``k``'s volume, ``b = -P r`` with ``r`` its projected gradient. Each method solves that system
once, on one thread, timed in CPU seconds (``time.process_time``):

- ``PARDISO double``: the project's :class:`~shellbuckle.solve.pardiso.PardisoSolver` (plain
  mode) on the KKT matrix ``[[K_ff + mu I, g], [g^T, 0]]`` over the free dofs
  (:class:`~shellbuckle.solve.kkt.KKTAssembler`, six dofs pinned by
  :func:`~shellbuckle.solve.gauge.pinned_dofs`): the numeric factorization (best of 3, the
  analysis reused) and one solve.
- ``PARDISO single + FGMRES``: its single-precision twin (``approximate=True``) refined by the
  project's flexible GMRES (:func:`shellbuckle.solve.krylov.gmres`, the KKT matrix applied in
  double precision) to each tolerance.
- Projected PCG on ``P (K + mu I) P x = P b``, ``P = I - Q Q^T`` with ``Q`` an orthonormal basis
  of ``grad V`` and the six rigid modes at ``X_k`` (the constraint and the gauge by projection,
  Gould, Hribar & Nocedal, SIAM J. Sci. Comput. 23, 1376 (2001)), preconditioner ``z = P M^-1
  r`` and the flexible (Polak-Ribiere) ``beta = max(0, z.(r - r_old)) / r_old.z_old`` (Golub
  & Ye, SIAM J. Sci. Comput. 21, 1305 (1999); Notay, SIAM J. Sci. Comput. 22, 1444 (2000)):
  a single-precision solve is linear only up to its rounding. ``M^-1`` is one V-cycle of pyamg's
  smoothed aggregation (Vanek, Mandel & Brezina, Computing 56, 179 (1996); Bell, Olson &
  Schroder, J. Open Source Softw. 7, 4142 (2022)) on the 3x3 vertex blocks of ``K + mu I``
  with ``B`` the six rigid modes: ``AMG rigid th.1 emin`` with the symmetric strength
  threshold 0.1 and energy-minimizing prolongation (Olson, Schroder & Tuminaro, SIAM J. Sci.
  Comput. 33, 966 (2011)), the best setting of the scratch study; ``AMG rigid`` without the two
  (NumPy's global random generator seeded with 0 before each set-up: pyamg's spectral-radius
  estimates start from random vectors, which moves the iterations by one or two otherwise).
- ``held k-1 single``: the same PCG with ``M^-1`` the single-precision factorization of step
  ``k - 1``'s KKT matrix at its own minimum (``mu = 0``), as if held from the last step.

    python benchmarks/bench_krylov.py RUN --steps 20,34
    python benchmarks/bench_krylov.py RUN --steps 34 --shift 1e-4 --tol 1e-6 1e-10 --max-cpu 60

pyamg is needed by this benchmark only (``pip install pyamg``). Prints one row per step and
method: the set-up (factorization or AMG hierarchy) CPU s, then for each tolerance the
iterations and CPU s to reach it (``>N``: not reached within ``--max-cpu`` s or 2000
iterations), and the final relative residual ``|P (b - (K + mu I) x)| / |P b|`` (the rigid part
of a pinned solution removed). For ``mu > 0`` the pinned KKT system is not the projected one
(the shift is as small as the softest modes), so the factorization rows' residual is O(1) there.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

from shellbuckle.protocol.deflate import scaled_to_volume  # noqa: E402
from shellbuckle.protocol.stored import stored_context  # noqa: E402
from shellbuckle.solve.gauge import free_dofs, pinned_dofs, remove_rigid, rigid_modes  # noqa: E402
from shellbuckle.solve.kkt import KKTAssembler  # noqa: E402
from shellbuckle.solve.krylov import gmres, symmetric_matvec  # noqa: E402
from shellbuckle.solve.linesearch import projected_gradient  # noqa: E402
from shellbuckle.solve.pardiso import PardisoSolver  # noqa: E402
from shellbuckle.store.view import Run  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import describe  # noqa: E402  (machine.py)

cpu = time.process_time
MAX_ITER = 2000
EMIN = ("energy", {"krylov": "cg", "maxiter": 4, "degree": 1})


def timed(f):
    t = cpu()
    out = f()
    return cpu() - t, out


class Tangent:
    """The Newton system of a stored minimum ``X``: ``A = K + mu I`` (``mu = shift x
    mean|diag K|``), the pinned KKT matrix's upper triangle ``U`` and the projection ``P``."""

    def __init__(self, ctx, X, shift: float):
        gE, gV = ctx.energy.gradient(X), ctx.volume.gradient(X)
        lam, _ = projected_gradient(gE, gV)
        HE = ctx.energy.hessian_terms(X)
        HV = ctx.volume.hessian(X)
        K = (sum(HE[1:], HE[0]) - lam * HV).tocsr()
        self.X, self.n, self.nnz, self.V = X, K.shape[0], K.nnz, float(ctx.volume.value(X))
        self.mu = shift * float(np.abs(K.diagonal()).mean())
        self.A = (K + self.mu * sp.identity(self.n, format="csr")).tocsr()
        self.R = rigid_modes(X)
        self.Q = np.linalg.qr(np.column_stack([gV.ravel(), self.R]))[0]
        self.free = free_dofs(self.n, pinned_dofs(X))
        kkt = KKTAssembler(self.free, self.n)
        self.U = kkt.matrix(kkt.build([(H, 1.0) for H in HE] + [(HV, -lam)], gV), self.mu)

    def P(self, v):
        return v - self.Q @ (self.Q.T @ v)

    def kkt_rhs(self, b):
        return np.concatenate([b[self.free], [0.0]])

    def embed(self, y):
        x = np.zeros(self.n)
        x[self.free] = y[:-1]
        return x

    def residual(self, b, x):
        """``|P (b - A x)| / |P b|`` with the rigid part of ``x`` removed."""
        x = remove_rigid(self.X, x.reshape(-1, 3)).ravel()
        return float(np.linalg.norm(self.P(b - self.A @ x)) / np.linalg.norm(self.P(b)))


def real_rhs(run, ctx, t: Tangent, k: int):
    """``-P r`` at step ``k - 1``'s minimum rescaled about its centroid to step ``k``'s volume."""
    X = scaled_to_volume(ctx.volume, run.positions(k - 1), t.V)
    _, r = projected_gradient(ctx.energy.gradient(X), ctx.volume.gradient(X))
    return t.P(-r.ravel())


def ppcg(t: Tangent, precondition, b, tols, max_cpu):
    """Projected flexible PCG from ``x = 0`` (module docstring): ``{tol: (iterations, CPU s)}``
    at the first iteration whose recursive relative residual is below ``tol`` (``">N"`` if not
    reached), and the final true relative residual."""
    t0 = cpu()
    b = t.P(b)
    b_norm = np.linalg.norm(b)
    x, r = np.zeros_like(b), b.copy()
    z = t.P(precondition(r))
    p, rz = z.copy(), r @ z
    hit, todo, it = {}, sorted(tols, reverse=True), 0
    while todo and it < MAX_ITER and cpu() - t0 <= max_cpu:
        Ap = t.P(t.A @ p)
        pAp = p @ Ap
        if not pAp > 0:
            break
        alpha = rz / pAp
        x += alpha * p
        r_old = r.copy()
        r -= alpha * Ap
        it += 1
        rel = np.linalg.norm(r) / b_norm
        while todo and rel <= todo[0]:
            hit[todo.pop(0)] = (it, cpu() - t0)
        if not todo:
            break
        z = t.P(precondition(r))
        rz_new = r @ z
        if not rz_new > 0:
            break
        p = z + (max(0.0, z @ (r - r_old)) / rz) * p
        rz = rz_new
    spent = cpu() - t0
    hit.update({tol: (f">{it}", f">{spent:.0f}") for tol in todo})
    return hit, float(np.linalg.norm(b - t.P(t.A @ x)) / b_norm)


def factored(U, approximate: bool):
    """A one-thread plain-mode PARDISO factorization of ``U`` and the CPU s of its numeric
    factorization (best of 3, the analysis reused)."""
    s = PardisoSolver(n_threads=1, precision="double", reproducible=False)
    s.factor(U, upper=True, approximate=approximate)
    return s, min(timed(lambda: s.factor(U, upper=True, approximate=approximate))[0]
                  for _ in range(3))


def row(k, method, setup, tols, hit, res):
    """One printed row; ``hit``: ``{tol: (iterations, CPU s or ">N")}``, ``-`` where missing."""
    cells = ""
    for tol in tols:
        its, spent = hit.get(tol, ("-", "-"))
        cells += f" {its!s:>6} {spent if isinstance(spent, str) else f'{spent:.3f}':>7}"
    setup = setup if isinstance(setup, str) else f"{setup:.3f}"
    print(f"{k:>4} {method:<24} {setup:>8}{cells} {res:>9.1e}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", help="a finished deflation run folder")
    parser.add_argument("--steps", default="20,34", help="comma-separated steps (>= 1)")
    parser.add_argument("--shift", type=float, default=0.0,
                        help="mu in units of mean|diag K| (default 0)")
    parser.add_argument("--tol", nargs="+", type=float, default=[1e-6, 1e-10],
                        help="relative residual tolerances")
    parser.add_argument("--max-cpu", type=float, default=100.0,
                        help="CPU s cap of each Krylov solve")
    args = parser.parse_args()
    try:
        import pyamg
    except ImportError:
        parser.exit(2, "bench_krylov.py needs pyamg: pip install pyamg\n")
    try:
        steps = [int(v) for v in args.steps.split(",")]
    except ValueError:
        steps = [0]
    if min(steps) < 1:
        parser.error(f"--steps {args.steps}: comma-separated integers >= 1 (a step and the "
                     f"one before it)")
    tols = sorted(args.tol, reverse=True)
    run = Run.of(args.run)
    ctx = stored_context(run, threads=1)
    print(f"# {describe()}\n# {run.store.path}; pyamg {pyamg.__version__}; shift "
          f"{args.shift:g} mean|diag K|; cap {args.max_cpu:g} CPU s, {MAX_ITER} iterations")
    print(f"{'step':>4} {'method':<24} {'setup s':>8}"
          + "".join(f" {f'its {tol:g}':>6} {'cpu s':>7}" for tol in tols) + f" {'rel. res':>9}")
    for k in steps:
        t = Tangent(ctx, run.positions(k), args.shift)
        b = real_rhs(run, ctx, t, k)
        kb = t.kkt_rhs(b)
        print(f"# step {k}: n = {t.n}, nnz(K) = {t.nnz}, mu = {t.mu:.4g}", flush=True)

        s, setup = factored(t.U, approximate=False)
        solve, y = min((timed(lambda: s.solve(kb)) for _ in range(3)), key=lambda ty: ty[0])
        res = t.residual(b, t.embed(y))
        row(k, "PARDISO double", setup, tols, {tol: (1, solve) for tol in tols if res <= tol},
            res)
        s, setup = factored(t.U, approximate=True)
        kkt_matvec, hit = symmetric_matvec(t.U), {}
        for tol in tols:
            spent, refined = timed(lambda: gmres(kkt_matvec, s.solve, kb, tol, 50))
            hit[tol] = (refined.iterations, spent)
        row(k, "PARDISO single + FGMRES", setup, tols, hit, t.residual(b, t.embed(refined.x)))
        s = None  # the factors freed

        for name, options in (("AMG rigid th.1 emin",
                               dict(strength=("symmetric", {"theta": 0.1}), smooth=EMIN)),
                              ("AMG rigid", {})):
            np.random.seed(0)  # pyamg's spectral radius estimates start from np.random.rand
            setup, ml = timed(lambda: pyamg.smoothed_aggregation_solver(
                t.A.tobsr(blocksize=(3, 3)), B=t.R, **options))
            hit, res = ppcg(t, ml.aspreconditioner(cycle="V"), b, tols, args.max_cpu)
            row(k, f"PCG, {name}", setup, tols, hit, res)
            del ml

        prev = Tangent(ctx, run.positions(k - 1), 0.0)
        s = PardisoSolver(n_threads=1, precision="double", reproducible=False)
        s.factor(prev.U, upper=True, approximate=True)
        hit, res = ppcg(t, lambda v: prev.embed(s.solve(prev.kkt_rhs(v))), b, tols, args.max_cpu)
        row(k, f"PCG, held {k - 1} single", "held", tols, hit, res)
        s = prev = None


if __name__ == "__main__":
    main()
