"""The lowest eigenvalues of the Hessian of an energy at fixed volume (the constrained Hessian).

At a conformation ``X`` where the energy is stationary at fixed volume, ``grad E = lam grad V``,
stability is decided by the Hessian of the Lagrangian ``K = Hess E - lam Hess V`` on the
tangent space of the constraint, ``{dx : grad V . dx = 0}``, with the rigid-motion gauge fixed
by the pinned dofs (:mod:`.gauge`): the conformation is a strict minimum when its lowest
eigenvalue is positive, and a fold or bifurcation of the equilibrium branch is where that
eigenvalue goes through zero (Nocedal & Wright, *Numerical Optimization*, 2nd ed., §12.5;
Thompson & Hunt, *A General Theory of Elastic Stability*, 1973).

The eigenvalues are found by Lanczos iteration (ARPACK through :func:`scipy.sparse.linalg.eigsh`)
in shift-invert form: for a shift ``s`` below the spectrum, the operator

    T x = first block of [[K - s I, g], [g^T, 0]]^-1 [x; 0]

is symmetric on the tangent space and has the eigenvalues ``1 / (lambda_i - s)``, so the
lowest ``lambda_i`` are its largest and best separated. The saddle-point matrix is factored
once by the package's symmetric-indefinite solver (:mod:`.linear`), assembled as Newton's
method assembles it (:class:`~.kkt.KKTAssembler`). The eigenvalues are those of the restriction
to the free dofs in the Euclidean metric of the positions; their signs (the inertia) do not
depend on that choice, their sizes do.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from .gauge import free_dofs
from .kkt import KKTAssembler
from .linear import make_solver

#: The shift below the spectrum, relative to the largest diagonal entry of ``K``.
RELATIVE_SHIFT = 1e-7


def multiplier(energy, volume, X: np.ndarray, free: np.ndarray) -> float:
    """The least-squares Lagrange multiplier ``lam`` of ``grad E = lam grad V`` on the free
    dofs (``-lam`` is the pressure)."""
    gE = energy.gradient(X).ravel()[free]
    gV = volume.gradient(X).ravel()[free]
    return float(gE @ gV / (gV @ gV))


def lowest_eigenvalues(energy, volume, X: np.ndarray, pinned, k: int = 1, *,
                       solver=None, tol: float = 1e-8) -> np.ndarray:
    """The ``k`` lowest eigenvalues (ascending) of the constrained Hessian at ``X`` (module
    docstring). ``pinned``: the gauge's dofs (:func:`~.gauge.pinned_dofs`); ``solver``: a
    linear solver or backend name (default :func:`~.linear.make_solver`)."""
    X = np.asarray(X, dtype=float)
    n_dofs = X.size
    free = free_dofs(n_dofs, pinned)
    lam = multiplier(energy, volume, X, free)
    terms = getattr(energy, "hessian_terms", None)
    hessians = terms(X) if terms is not None else [energy.hessian(X)]
    assembler = KKTAssembler(free, n_dofs)
    data = assembler.build([(H, 1.0) for H in hessians] + [(volume.hessian(X), -lam)],
                           volume.gradient(X))
    scale = float(np.max(np.abs(assembler.diagonal(data))))
    shift = -RELATIVE_SHIFT * scale
    solver = make_solver(solver)
    solver.factor(assembler.matrix(data, mu=-shift), upper=True)
    n = len(free)

    def apply(x):
        return solver.solve(np.concatenate([np.ravel(x), [0.0]]))[:n]

    T = spla.LinearOperator((n, n), matvec=apply, dtype=float)
    start = np.random.default_rng(0).standard_normal(n)
    theta = spla.eigsh(T, k=min(k, n - 2), which="LM", v0=apply(start), tol=tol,
                       return_eigenvectors=False)
    return np.sort(shift + 1.0 / theta)
