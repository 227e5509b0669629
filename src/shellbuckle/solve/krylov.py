"""GMRES refinement of the solves made with a single-precision factorization.

A single-precision ``L D L^T`` of the KKT matrix ``A`` (:mod:`.pardiso`) solves ``A x = b``
with a relative error of about ``6e-8 cond(A)`` along its softest directions. The bending
stiffness makes ``cond(A)`` grow like ``h^-4`` with the mean edge ``h``, so on meshes of tens
of thousands of vertices that error nears one and a Newton step solved that way is far from
Newton's: after buckling a minimization then takes two to three times as many factorizations.
GMRES on the right-preconditioned system ``A M^-1 y = b``, ``x = M^-1 y``, with ``M^-1`` the
single-precision solve and ``A`` applied in double precision, removes the error in a few
iterations of one solve and one product with ``A`` each, which cost a small fraction of a
factorization (GMRES-based iterative refinement: Carson & Higham, SIAM J. Sci. Comput. 40,
A817 (2018); GMRES: Saad & Schultz, SIAM J. Sci. Stat. Comput. 7, 856 (1986), with Givens
rotations and modified Gram-Schmidt, Saad, *Iterative Methods for Sparse Linear Systems*, 2nd
ed., Algorithm 6.10).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.linalg
import scipy.sparse as sp


class Refined(NamedTuple):
    """A refined solve: the solution, its relative residual ``|b - A x| / |b|`` and the GMRES
    iterations taken."""

    x: np.ndarray
    residual: float
    iterations: int


def symmetric_matvec(upper: sp.csr_matrix):
    """``v -> A v`` for the symmetric matrix whose upper triangle is ``upper`` (CSR)."""
    lower = upper.T.tocsr()
    diagonal = upper.diagonal()
    return lambda v: upper @ v + lower @ v - diagonal * v


def gmres(matvec, precondition, b: np.ndarray, rtol: float, max_iter: int) -> Refined:
    """Solve ``A x = b`` (``matvec(v) = A v``) by GMRES right-preconditioned with
    ``precondition(v) ~ A^-1 v``, from ``x0 = precondition(b)``, without restarts: until
    ``|b - A x| <= rtol |b|`` or ``max_iter`` iterations. Every ``z_k = M^-1 v_k`` is kept and
    the correction is ``Z y`` (flexible GMRES, Saad, SIAM J. Sci. Comput. 14, 461 (1993)): a
    single-precision solve is linear only up to its rounding, which along the soft modes is of
    the order of the solution itself, so ``M^-1 (V y)`` would not be ``(M^-1 V) y``."""
    b = np.asarray(b, dtype=np.float64)
    b_norm = float(np.linalg.norm(b))
    x = precondition(b)
    if b_norm == 0.0:
        return Refined(x, 0.0, 0)
    r = b - matvec(x)
    beta = float(np.linalg.norm(r))
    if beta <= rtol * b_norm or max_iter == 0:
        return Refined(x, beta / b_norm, 0)
    V = np.empty((max_iter + 1, b.size))
    Z = np.empty((max_iter, b.size))
    H = np.zeros((max_iter + 1, max_iter))
    cs, sn = np.zeros(max_iter), np.zeros(max_iter)
    g = np.zeros(max_iter + 1)
    g[0] = beta
    V[0] = r / beta
    k = 0
    while k < max_iter:
        Z[k] = precondition(V[k])
        w = matvec(Z[k])
        for i in range(k + 1):
            H[i, k] = float(w @ V[i])
            w -= H[i, k] * V[i]
        H[k + 1, k] = float(np.linalg.norm(w))
        breakdown = H[k + 1, k] == 0.0  # the Krylov space holds the solution
        if not breakdown:
            V[k + 1] = w / H[k + 1, k]
        for i in range(k):  # the rotations so far, applied to the new column
            H[i, k], H[i + 1, k] = (cs[i] * H[i, k] + sn[i] * H[i + 1, k],
                                    -sn[i] * H[i, k] + cs[i] * H[i + 1, k])
        rho = float(np.hypot(H[k, k], H[k + 1, k]))
        cs[k], sn[k] = (H[k, k] / rho, H[k + 1, k] / rho) if rho > 0.0 else (1.0, 0.0)
        H[k, k], H[k + 1, k] = rho, 0.0
        g[k + 1], g[k] = -sn[k] * g[k], cs[k] * g[k]
        k += 1
        if abs(g[k]) <= rtol * b_norm or breakdown:
            break
    diagonal = np.diag(H[:k, :k])
    keep = k if np.all(diagonal != 0.0) else int(np.argmax(diagonal == 0.0))
    if keep:
        y = scipy.linalg.solve_triangular(H[:keep, :keep], g[:keep])
        x = x + y @ Z[:keep]
    return Refined(x, float(np.linalg.norm(b - matvec(x))) / b_norm, k)

