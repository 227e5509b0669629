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
them all unchanged (or given by the caller: the deflation protocol passes one set for the
whole run, so that the KKT pattern and the solver's symbolic analysis change only when they
must). A given set is kept only while the rigid modes on it are conditioned to
``GAUGE_MAX_COND`` (10; a fresh choice gives 2-3), at the start and before every
factorization; otherwise the dofs are chosen again at the current point, a function of the
point alone, so a resumed run repeats the same choices. This is
sparse, exact, and any rigid motion can be added to a step without changing the energy, so it
removes exactly the six null modes. Inertia counts are therefore on the tangent space modulo
rigid motions, like Surface Evolver's ``eigenneg``. Every step (Newton, quasi-Newton,
negative curvature) is taken without its rigid-motion part (least squares at the current
point): the pinned step carries whatever infinitesimal rotation makes the pinned dofs vanish,
and over many steps the shell would rotate (26 degrees within one minimization at gamma = 271,
dV/V = 0.6) until the pinned dofs hardly fix the rotations any more (a nearly singular ``K``:
marginal negative eigenvalues and an iteration that stalls with the energy converged).

Shift (Levenberg–Marquardt) and negative curvature
--------------------------------------------------
By Sylvester's law, ``n_neg(KKT) = n_neg(K on the tangent space) + 1``, so every
factorization tells whether ``K + mu I`` is positive definite on the tangent space. The shift
``mu`` plays two roles. (1) If the tangent Hessian is indefinite (or singular), ``mu`` is
raised (x4, from ``1e-4 mean|diag K|`` or from the current shift) until the inertia is right;
the shifted step is a descent step. (2) After buckling the shell has a few very soft modes
(the position of a dent on the sphere is pinned only by the mesh: tangent eigenvalues
``~1e-6`` of ``mean|diag K|``, 30 times below the next ones) along which the energy is far
from quadratic, and undamped Newton steps overshoot. ``mu`` is therefore adapted as in a
trust-region / Levenberg–Marquardt method by the ratio ``rho`` of the actual to the predicted
decrease (quadratic model with the unshifted ``K``): divided by 4 after a good step
(``rho > 0.75``, or a full step whose predicted decrease is below the energy's evaluation
noise, near a minimum), and set after a step cut to ``alpha`` by the line search (or
stretched to ``alpha > 1``: a damped step whose model was good is doubled while the energy
falls) to the shift that would have given that length along the step's direction; a shift
below ``1e-3`` of the curvature along the step is dropped. While ``mu > 0`` the unshifted
matrix is not factored (no wasted factorization per iteration); it is factored again when
``mu`` drops to 0, when the gradient has converged, and at the last iteration, so the
reported inertia is always that of the unshifted tangent Hessian.

At a stationary point with negative curvature (a saddle, e.g. the perfectly symmetric shrunk
sphere past its buckling threshold) or when a shifted step fails, a few inverse-iteration
steps with the shifted factorization give a direction ``d`` of most negative curvature; it is
searched (expanding/backtracking, Moré & Sorensen, Math. Prog. 16, 1 (1979)) beside the
shifted step and the lower energy wins, so the method leaves a saddle even where the gradient
vanishes exactly.

Quasi-Newton steps between factorizations
-----------------------------------------
A factorization costs about 15 gradient evaluations (3594 vertices: ~0.1 s against ~7 ms
for a solve). After each Newton step, up to ``max_quasi`` L-BFGS steps reuse it: the initial
inverse Hessian is the tangent KKT solve with the current factorization (exact where it was
factored) and the secant pairs ``(x_{i+1} - x_i, r_{i+1} - r_i)`` of the steps since correct
it (Nocedal & Wright, *Numerical Optimization*, 2nd ed., §7.2). The matrix is factored again
(a Newton step) when a quasi-Newton step is cut below ``QUASI_MIN_ALPHA`` (5 %) of its length
or fails, after ``max_quasi`` steps, or when the steps stall: over three steps the projected
gradient has not fallen by 10 % and the energy has fallen by less than 0.3 times the fall of
the Newton step (:func:`_stalled`). In the soft post-buckling valleys this takes about three
times fewer factorizations for about 1.5 times more steps. There, while a dent slides to its
new pinning site, the projected gradient does not fall from step to step but every
quasi-Newton step lowers the energy about as much as a Newton step; a test on the gradient
alone, or on a step cut to half, used to end the reuse after two or three steps (γ = 2333,
step 13 of the protocol: 46 factorizations in the first minimization, 22-26 with these tests,
the same minimum to ten digits). For the same reason ``max_quasi`` is 50 and ``memory`` 16
(they were 10 and 8, then 30 and 16): in a slide the tenth quasi-Newton step still lowers the
energy as much as the first, and a factorization (with its assembly) costs about seven steps.
Replays of the protocol (``benchmarks/bench_replay.py --every 4``), 10 and 8 against 30 and 16:
25-30 % fewer single-precision factorizations for 4-16 % more steps, every step at gamma = 271
and 2333 at the stored minimum. 30 against 50: at gamma = 271, where a dent crawls for
100-300 steps to its pinning site after buckling and the limit ends most reuses, whole runs
of the comparison's protocol (c0 cycle, no jiggle, 13 steps) took 2-3.5 % less CPU time on
28 meshes (seeds 1-14: 72.4, 72.4, 71.9 against 75.0-75.7 s in all; seeds 15-28: 72.4, 73.0
against 73.5, 76.2 s); at gamma = 2333 and 20995 (replays, ``--every 4``) the limit is
rarely reached: the same factorizations, 1-2 % more steps. 100 was no better than 50 (seeds
1-14: 74.4 s; seeds 15-28: 73.0 s).

Preconditioned relaxation
-------------------------
A jiggle on Surface Evolver's scale (0.44 mean edge lengths on the paper's mesh) leaves the
shell about 1e4 times its elastic energy above the minimum, with hundreds of negative
eigenvalues of the Hessian; started there, the shifted Newton method spends ~40 iterations and
~50 factorizations (every shift search on a strongly indefinite matrix factors several times)
removing that roughness. The roughness is the stiff part of the perturbation, which the
Hessian of the relaxed state the jiggle started from describes well. Given that state
(``precondition_at``), the minimization first takes L-BFGS steps whose initial inverse Hessian
is the tangent KKT solve with ``K(X_ref) + mu I``, ``mu = 1e-3 mean|diag K|``: one
factorization serves every step, and the shift keeps the soft modes (those along which a dent
forms or slides, eigenvalues ~1e-6 of the scale) from dominating the steps, so that they relax
as in a gradient flow instead of being undone. When the energy falls by less than ``1e-5``
relative over five steps, Newton's method takes over and converges as described above. On the
paper's mesh (gamma = 2333, steps 2, 6 and 10 of the protocol, from the same states) the first
minimization of a step then takes 3-8 factorizations instead of 30-60 and 2-3 s instead of
6-9 s, and ends at the same minimum (energies equal to ten digits).

The relaxation starts in a rough stage with a larger shift (``relax_rough_shift``, at first
``1e-1 mean|diag K|``, now ``mean|diag K|`` itself, see below), and factors again with ``1e-3``
once three consecutive steps were taken in full (or the energy test above holds). Right after
the jiggle the forces are huge (``|r|`` ~ 1e5-1e6 on the paper's mesh) and their small
components along the soft modes, divided by the small shift, made the first directions 10-60
mean edge lengths long at the median vertex; the line search cut them to a few percent (the
largest vertex move at the 0.2 R step cap), so the stiff roughness of the jiggle, which wants
the full step, fell by only a few percent per step. In the wrinkled regime (gamma = 20995)
every one of the 100 relaxation steps allowed was cut to 1-14 % and Newton's method started
about 15 kappa above the minimum with ~20 negative eigenvalues. With the larger shift the soft
components are damped at first, the steps are taken in full after 5-20 of them, and the
relaxation goes on with the small shift from a smooth shell. Replaying stored trajectories
(``benchmarks/bench_replay.py --every 3``): gamma = 20995 33 % less CPU time, 2333 8 %, 271
unchanged, one more single-precision factorization per minimization. In the wrinkled regime the
minimum reached is then another one of the many nearly degenerate wrinkle patterns (energies
within 0.2 % of the stored ones, above or below); at gamma = 2333 every replayed step ends at
the stored minimum. The stage is skipped when the start lies more than 1.5 mean edge lengths
(rms over the vertices) from the relaxed state (``RELAX_ROUGH_MAX_MOVE``): the protocol's
jiggle is 0.76 edge lengths rms per vertex on the paper's mesh but 2.5 on a 40k-vertex mesh
(the same absolute amplitude), and there the rough stage's local full steps locked the tangled
triangles in: every one of three steps folded (and was jiggled again), against none of two
without the stage; capping its steps at 0.5 or 1 edge length did not help.
A start closer than 0.3 mean edge lengths (rms) to the relaxed state
(``RELAX_ROUGH_MIN_MOVE``), without a jiggle or with a small one, has nothing rough to remove:
it is not relaxed at all ("Smooth starts"); the relaxation runs without its rough stage only
where the exact Hessian at the relaxed state is not positive definite.

With the rough shift ``1e-1 mean|diag K|`` the first 20-30 steps after the jiggle were still
capped at ``max_step`` (gamma = 271, step 3: the direction moved the median vertex by 1-3
mean edge lengths and the farthest by 20-80, against a jiggle of 0.76 rms, and every step
was scaled to 2-20 % of its length): the Hessian of the relaxed state underestimates the
stiffness of the stretched, jiggled mesh (Green-Lagrange strains stiffen), so shifted by a
tenth of its diagonal it still made the steps 5-20 times too long. With the diagonal itself
as shift the first steps are taken at 10-80 % of their length and the roughness is gone
after 10-15 steps instead of about 30 (271, step 3: from 4500 times the minimum's energy to
twice it in 20 steps instead of 37). Replays of every second step
(``benchmarks/bench_replay.py --every 2 --option relax_rough_shift=...``, 1e-1 against 1):
gamma = 271 161 -> 134 iterations and 9.1 -> 8.6 single-precision factorizations per step,
10 % less CPU time; 20995 253 -> 217 and 10.4 -> 8.9, 14 % less; 2333 the same within 2 %
(121 -> 117 iterations, 6.7 -> 6.9 factorizations). At 271 and 2333 every replayed step but
one (of 20 and of 24) ends at the stored minimum, those two 1.4e-4 relative above it; at
20995 most end at other wrinkle patterns, on average 1e-3 relative below the stored energies
(with 0.5: 2e-4 above, 9 % less CPU time).

After the rough stage the shifted Hessian of the relaxed state is still too soft along the
directions the steps take, by a factor that changes slowly: at gamma = 20995 (step 5 of the
protocol; every fourth step from the 11th looked at, 23 in all) each step after the rough stage
raised the energy when taken in full, and the line search's interpolation cut it to 0.1-0.4 of
its length, where the quadratic model held (two energy evaluations per step). The initial
inverse Hessian of those steps is therefore scaled (``relax_scaling``), as L-BFGS scales its
``H0`` (Nocedal & Wright §7.2), by ``tau``: after each step ``tau`` is multiplied by the
minimizer of the parabola through the energy, the slope and the accepted point along the step
(clipped to [0.1, 2], ``tau`` within [1e-3, 1]; :func:`_rescaled`). The steps are then taken in
full (one evaluation) with about the same decrease. Replays of every second step
(``benchmarks/bench_replay.py --every 2 --option relax_scaling=False``, on trajectories made
with it off): CPU time 9 % lower at gamma = 20995 (199.6 -> 193.9 iterations, 8.5 -> 8.1
single-precision factorizations per step), 4 % lower at 2333 and 4 % higher at 271 (8.0 -> 8.3
factorizations), all steps at 271 and 2333 at the stored minima; whole runs at 20995 (three
seeds) spent 25 % less time in line searches. The quasi-Newton steps between Newton steps are
not scaled: their ``H0`` is the Hessian at the point, and scaled in the same way they took more
factorizations (20995: 8.1 -> 10.2 per step).

Single-precision steps
----------------------
The Newton steps of a point whose gradient has not converged (and the shift search there)
are factored in single precision where the solver offers it (``single_precision_steps``, with
``escape_saddles``: its round-off breaks the symmetry of a saddle, as a jiggle does;
PARDISO, without iterative refinement: its solves are half as costly, ~3 against ~6 ms on
the paper's mesh, and its factorization about 1.5 times cheaper). Such a step is an inexact
Newton step (relative error about ``1e-7`` times the condition number along the soft
modes), which the line search and the following quasi-Newton steps correct; its inertia is
used only to choose the shift, never reported nor used to certify a minimum: the convergence
test still needs a certificate near the final point (one more factorization per minimization,
where the last Newton step used to certify it): an unshifted double-precision factorization,
or a single-precision one with a margin (below). After three Newton steps
without progress (:func:`_jammed` over ``SINGLE_JAM_STEPS``) the rest of the minimization
factors in double precision: on a 40k-vertex mesh the softest modes are softer, relative to
the scale of the matrix, than on the paper's mesh, and a sliding dent stalled with
single-precision steps (gamma = 2333, third volume step: ten Newton steps without progress,
not converged). Replays as above: 10 %
(gamma = 271 and 2333) and 7 % (20995) less CPU time with the same iterations; every replayed
step at gamma = 271 and 2333 ends at the stored minimum.

Single-precision certificates
-----------------------------
Where the solver factors approximate matrices in single precision (PARDISO) and
``certify_single`` is on, the certificate at a converged point is tried first with one
single-precision factorization of the KKT matrix whose tangent Hessian is shifted *down*,
``K - sigma I`` with ``sigma = CERTIFY_SHIFT mean|diag K|`` (``1e-6``). The computed factors
are those of ``K - sigma I + E`` with a backward error ``|E|`` of the order of the
single-precision round-off times ``|K|``; inertia 0 shows ``K + E > sigma I``, so ``K`` is
positive definite as long as ``|E| < sigma``. Measured on the paper's mesh (gamma = 271, the
bending energy of Surface Evolver, the 13 minima of the protocol to dV/V = 0.247, bisection on
the shift to 40 bits): the smallest tangent eigenvalue seen by the single-precision
factorizations lies 1.4e-8 to 2.3e-8 ``mean|diag K|`` above the one seen in double precision, 40
to 70 times below ``sigma``; before buckling that eigenvalue is ``4e-6`` to
``1.5e-5 mean|diag K|``, after it ``1e-8`` to ``8e-8``. That was with Bunch–Kaufman pivots in
PARDISO's reproducible mode. The certificate now pivots on the diagonal (1x1) as the other
single-precision factorizations do (:mod:`.linear`), on one thread in PARDISO's plain mode:
measured again the same way (minima of random_sphere(3594, seed) for seeds 1 and 2, 26 in all),
the 1x1 factorizations see the smallest eigenvalue 0.85e-8 to 2.5e-8 above double precision (40
to 120 times below ``sigma``; Bunch–Kaufman 2.0e-8 to 3.6e-8), and none had to be made again
with Bunch–Kaufman pivots; such a factorization costs 31-35 against 50-54 ms. Where the
single-precision factorization shows a negative eigenvalue (a saddle, a soft post-buckling
valley, or a stiff shell on a fine mesh, whose smallest eigenvalue scales as ``1 / (gamma N)``),
the unshifted double-precision factorization decides, as without this option, and the
minimization does not try again. A reported inertia other than 0 therefore always comes from a
double-precision factorization.

The certificate's factorization is then the one the solver holds: the next minimizations
start from it (warm starts, smooth starts), and its solves cost half as much (1.2 against
3.3 ms on the paper's mesh, one thread; its factorization 37 against 55 ms). Before
buckling a volume step of the protocol without a jiggle (the comparison with Surface
Evolver) then costs 0.11-0.13 s instead of 0.15-0.19 s, the same minima to the last
printed digit. The protocol tries it while the last step's minimum was certified so
(:data:`shellbuckle.protocol.deflate.SINGLE_CERTIFICATE`). ``result.certificate`` says which
factorization showed the inertia 0.

Warm start
----------
A minimization that starts where another one on the same mesh ended, at slightly different
parameters (the protocol's zero-spontaneous-curvature cycle: ``c0 -> 0`` from a minimum at
``c0 = 2/R``, then back), can take its first steps with the factorization the linear solver
still holds from the previous minimization (``warm_start=result.factorization``, the
certification of its minimum): quasi-Newton steps whose initial inverse Hessian is that
factorization, as after a Newton step, instead of the preconditioned relaxation (which factors
once) and a first Newton step (which factors again). The token is valid while the solver
still holds that factorization (PARDISO keeps the last two in double precision, see
:mod:`.linear`, ``held``/``activate``; another solver only until it factors anything
else), and the minimization keeps the token's gauge while it fixes the rigid motions at the
start (so the KKT pattern is the same); else it is ignored. ``warm_start`` may be a list of
tokens: the first valid one is used. Replaying the same steps of stored trajectories of the
paper's protocol (``benchmarks/bench_replay.py``, every second step) costs 13-20 % less CPU
time (gamma = 271, 2333, 20995) and every step ends at the same minimum.

A token certifies what its factorization showed: an unshifted double-precision
factorization with inertia 0 at a point ``X1`` of the same energy object and volume target
(:meth:`_Factorization.certifies`) counts as the last unshifted factorization of the
minimization (the rule of "Convergence": a final point within ``inertia_step`` of ``X1``
needs no new factorization). The protocol's return from ``c0 = 0`` to ``2/R`` starts with
the factorization at the minimum before the cycle (the c0 = 0 stage between them is not
certified, "Uncertified minima", so it is usually the solver's last double-precision one):
where the shell returns to that minimum it is the Hessian at the destination and certifies
it. Measured on replays (every 4th step): 0.3-0.8 fewer double-precision factorizations per
step at gamma = 271 and 20995, none at 2333 (there the tails of the minimization move the
shell by more than ``inertia_step`` along its soft modes); before buckling the return costs
two quasi-Newton steps and no factorization.

Smooth starts
-------------
A start closer than ``RELAX_ROUGH_MIN_MOVE`` (0.3) mean edge lengths (rms) to
``precondition_at`` has no roughness to relax: the protocol without a jiggle (as in the
comparison with Surface Evolver), where a volume step moves the vertices by about 0.1 edge
lengths. Its first steps are quasi-Newton steps whose initial inverse Hessian is the
unshifted Hessian of the Lagrangian at ``precondition_at`` (a minimum of the previous volume
step, positive definite on the tangent space), factored in double precision: the
factorization that certified that minimum when the linear solver still holds it and it was
made at exactly that point (``precondition_token``; the protocol passes the last step's),
else the same matrix factored again, which gives the same bits, so a run resumed from its
store repeats the uninterrupted run exactly. Where that matrix is not positive definite the
relaxation runs as for a rough start. Before buckling a volume step then costs one
factorization, the certification of its minimum, instead of three (the relaxation's, a first
Newton step's and the certification): on the paper's mesh with Surface Evolver's bending
energy and the c0 cycle (``benchmarks/bench_evolver.py``) 0.18-0.19 s per step instead of
0.27 s, 8-10 quasi-Newton steps to the new minimum.

Convergence
-----------
Stop when ``|r| <= tol_grad |grad E| + atol_grad`` (``|grad E|`` is the size of the forces
present: at a constrained minimum they are the pressure forces ``lam grad V``; ``atol_grad``,
in energy per length, covers an unloaded shell), the last accepted step changed the energy by
at most ``tol_energy |E|``, and the tangent Hessian has no negative eigenvalue (inertia 0) when
``escape_saddles`` is on. The inertia is that of the last unshifted factorization when the
point has moved since by at most ``inertia_step`` (``1e-4``) mean edge lengths (a converging
Newton or quasi-Newton tail moves by far less; the soft eigenvalues change by ~1e-7 of
``mean|diag K|`` over such a distance), else the matrix is factored at the point. Defaults:
``tol_grad = 1e-8``, ``atol_grad = 1e-10``, ``tol_energy = 1e-10``, ``max_iter = 100``. The
volume constraint then holds to round-off (``~1e-15`` relative).

Uncertified minima
------------------
With ``certify=False`` the minimization stops on the gradient and energy tests alone: no
double-precision factorization is made only to show inertia 0 at the final point (reported as
``None``). Saddles are still escaped on the way, since every factorization's inertia (single
precision included) sets the shift, and a quasi-Newton or shifted Newton iteration from a
generic start does not converge to a saddle. The deflation protocol uses it for the c0 = 0
stage of its cycle: that minimum is a waypoint, neither reported nor kept, and the return to
c0 = 2/R is certified as usual. It saves one double-precision factorization (~85 ms on the
paper's mesh, one thread) per volume step, of about twelve.

``max_iter`` bounds the Newton steps, i.e. the factorizations of ``K`` (the costly part);
the quasi-Newton steps that reuse a factorization (at most ``max_quasi`` per Newton step) and
the relaxation's steps are not counted against it. ``nit`` counts every accepted step.
"""

from __future__ import annotations

import logging
import time
import weakref
from collections import defaultdict
from contextlib import contextmanager

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from numba import njit

from ..energies.kernels import add_scaled_at
from .lbfgs import SecantPairs
from .linear import SingularFactorError, accepts, make_solver
from .linesearch import (ENERGY_NOISE, RestoredPath, backtracking, check_problem,
                         curvature_search, mean_edge_length, parabola_minimizer,
                         projected_gradient, restore_volume)
from .recent import Recent
from .result import MinimizeResult

log = logging.getLogger(__name__)

RELAX_SHIFT = 1e-3
"""Shift of the preconditioner of the relaxation, relative to ``mean|diag K|``."""
RELAX_ROUGH_SHIFT = 1.0
"""Shift of the relaxation's first (rough) stage, relative to ``mean|diag K|`` (module
docstring, "Preconditioned relaxation"; it was 1e-1)."""
RELAX_ROUGH_FULL = 3
"""Consecutive full steps after which the rough stage of the relaxation ends."""
RELAX_ROUGH_MAX_MOVE = 1.5
"""The rough stage is skipped when the start lies farther from the relaxed state than this
many mean edge lengths (root mean square over the vertices): a perturbation larger than the
edges tangles the mesh, and the rough stage's local steps lock the tangles in."""
RELAX_ROUGH_MIN_MOVE = 0.3
"""A start closer to the relaxed state than this many mean edge lengths (rms) has no roughness
to remove (no jiggle, or a small one; the protocol's jiggle moves the vertices by 0.76 edge
lengths rms, a volume step of 0.019 V0 by 0.1): no relaxation at all, quasi-Newton steps on
the exact Hessian at the relaxed state (module docstring, "Smooth starts")."""
RELAX_TOL = 1e-5
"""The relaxation hands over to Newton's method when the energy falls by less than this,
relative, over ``RELAX_WINDOW`` steps."""
RELAX_WINDOW = 5
RELAX_MEMORY = 20
"""Secant pairs kept by the relaxation's L-BFGS."""
RELAX_ASK_ALPHA = 1e-3
RELAX_ASK_STEPS = 5
"""After ``RELAX_ASK_STEPS`` consecutive relaxation steps cut below ``RELAX_ASK_ALPHA`` of
their length, ``abandon`` is asked (and again after every further such step): a triangle folded
onto its neighbour by the jiggle stops the steps (gamma = 271, step 21: every step after the
36th was cut below 1e-3, and the relaxation went on to its 55th before Newton's method asked).
Not after one such step: on a 40k-vertex mesh (gamma = 2333, step 2) a hinge reached 179.993
degrees at one cut step, and the relaxation went on, unfolded it and converged."""
JAM_STEPS = 10
"""Newton steps without progress after which a minimization stops as stalled (:func:`_jammed`)."""
SINGLE_JAM_STEPS = 3
"""Newton steps without progress after which the single-precision steps end for the rest of a
minimization (module docstring, "Single-precision steps")."""
QUASI_MIN_ALPHA = 0.05
"""A quasi-Newton step cut below this fraction of its length ends the reuse of a factorization."""
GAUGE_MAX_COND = 10.0
"""Largest condition number of the six rigid modes on the pinned dofs for which a gauge is kept
(:func:`pinned_dofs` gives 2-3 on a sphere or a dented shell); above it the dofs are chosen
again at the current point. On a deep capsule (gamma = 271, dV/V = 0.4) the run's pins had
drifted to 24-374 and Newton's method crawled: the residual left on the free dofs had a
component along the rigid motions that the pinned dofs amplify (99.999 % of the residual sat on
them), 1035 iterations and 200 factorizations without converging; with pins chosen again at
the point, 29 Newton iterations to a minimum 8e-5 kappa lower."""
CERTIFY_SHIFT = 1e-6
"""Shift of a single-precision certificate, relative to ``mean|diag K|`` (module docstring,
"Single-precision certificates")."""
ABANDONED = "abandoned"
"""Start of the message of a minimization stopped by its ``abandon`` test."""


def _ref(obj):
    """A weak reference to ``obj`` (a strong one, as a callable, if it takes none)."""
    try:
        return weakref.ref(obj)
    except TypeError:
        return lambda: obj


class _Factorization:
    """What a linear solver holds after a factorization by :class:`_Newton` (see "Warm
    start"): the solver and the KKT assembler (free dofs and pattern), weakly referenced so
    that a token keeps neither alive, the pinned dofs of that gauge, whether the
    factorization was approximate (single precision, a preconditioner only), the solver's
    handle of it (``solver.held()``, where the solver keeps more than one), and what it
    certifies: the point, energy (weakly), volume target, shift and inertia."""

    __slots__ = ("solver", "kkt", "pinned", "approximate", "handle", "X", "energy",
                 "V_target", "mu", "inertia", "certificate")

    def __init__(self, solver, kkt, pinned, approximate: bool):
        self.solver, self.kkt, self.approximate = _ref(solver), _ref(kkt), approximate
        self.pinned = pinned
        self.handle = self.X = self.energy = self.V_target = self.mu = self.inertia = None
        self.certificate = False  # it shows the tangent Hessian at X positive definite

    def definite_for(self, energy) -> bool:
        """Whether this factorization of the KKT matrix of ``energy`` at the point ``self.X``
        (the matrix does not depend on the volume target) shows the tangent Hessian there
        positive definite: an unshifted double-precision one with inertia 0, or a
        single-precision certificate (module docstring, "Single-precision certificates")."""
        return self.certificate and self.energy is not None and self.energy() is energy

    def certifies(self, energy, V_target) -> bool:
        """Whether it is :meth:`definite_for` ``energy`` at ``V_target``: it certifies a minimum
        there."""
        return self.definite_for(energy) and self.V_target == V_target


_HELD = Recent(8)
"""``id(solver) -> _Factorization``: the last factorization each recent solver was given by
Newton's method (a token whose solver has died no longer matches any solver)."""


def _hold(token: _Factorization) -> None:
    _HELD.put(id(token.solver()), token)


def _warm_ok(token, nt) -> bool:
    """Whether ``nt``'s solver can solve with ``token`` (a ``result.factorization``) now,
    for the same gauge, in double precision: a solver that keeps several factorizations
    (``activate``) is switched to it if it still holds it; another one must not have factored
    anything since."""
    if not (isinstance(token, _Factorization) and (not token.approximate or token.certificate)
            and token.solver() is nt.linsolver and token.kkt() is nt.kkt):
        return False
    activate = getattr(nt.linsolver, "activate", None)
    if activate is not None and token.handle is not None:
        return bool(activate(token.handle))
    return _HELD.peek(id(nt.linsolver)) is token


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


def remove_rigid(X: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``p (V, 3)`` minus its least-squares component along the rigid motions at ``X``.

    The translations and the rotations about the centroid are orthogonal to each other, so the
    projection is closed-form: the translation is the mean ``t`` of ``p`` and the rotation
    ``w`` solves ``I w = sum_i c_i x p_i`` with the inertia tensor
    ``I = sum_i (|c_i|^2 1 - c_i c_i^T)`` of the centred positions ``c``; the result is
    ``p - t - w x c``, the same as the least-squares solve with :func:`rigid_modes`. Compiled
    (:func:`_remove_rigid`): three passes over the vertices, 0.02 ms on the paper's mesh
    against 0.13-0.3 ms for the same sums as NumPy matrix products, once per step of the
    minimizer."""
    return _remove_rigid(np.ascontiguousarray(X, dtype=np.float64),
                         np.ascontiguousarray(p, dtype=np.float64))


@njit(cache=True, nogil=True)
def _remove_rigid(X, p):
    """:func:`remove_rigid`: sums in vertex order, the 3x3 system by its adjugate."""
    n = X.shape[0]
    m0 = m1 = m2 = t0 = t1 = t2 = 0.0
    for i in range(n):
        m0, m1, m2 = m0 + X[i, 0], m1 + X[i, 1], m2 + X[i, 2]
        t0, t1, t2 = t0 + p[i, 0], t1 + p[i, 1], t2 + p[i, 2]
    m0, m1, m2, t0, t1, t2 = m0 / n, m1 / n, m2 / n, t0 / n, t1 / n, t2 / n
    s00 = s01 = s02 = s11 = s12 = s22 = b0 = b1 = b2 = 0.0  # sum c c^T, sum c x p
    for i in range(n):
        c0, c1, c2 = X[i, 0] - m0, X[i, 1] - m1, X[i, 2] - m2
        s00, s01, s02 = s00 + c0 * c0, s01 + c0 * c1, s02 + c0 * c2
        s11, s12, s22 = s11 + c1 * c1, s12 + c1 * c2, s22 + c2 * c2
        b0 += c1 * p[i, 2] - c2 * p[i, 1]
        b1 += c2 * p[i, 0] - c0 * p[i, 2]
        b2 += c0 * p[i, 1] - c1 * p[i, 0]
    # the inertia tensor I = tr(S) 1 - S and the adjugate of I (symmetric)
    a00, a11, a22, a01, a02, a12 = s11 + s22, s00 + s22, s00 + s11, -s01, -s02, -s12
    i00, i01, i02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
    i11, i12, i22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
    det = a00 * i00 + a01 * i01 + a02 * i02
    w0 = (i00 * b0 + i01 * b1 + i02 * b2) / det
    w1 = (i01 * b0 + i11 * b1 + i12 * b2) / det
    w2 = (i02 * b0 + i12 * b1 + i22 * b2) / det
    out = np.empty_like(p)
    for i in range(n):
        c0, c1, c2 = X[i, 0] - m0, X[i, 1] - m1, X[i, 2] - m2
        out[i, 0] = p[i, 0] - t0 - (w1 * c2 - w2 * c1)
        out[i, 1] = p[i, 1] - t1 - (w2 * c0 - w0 * c2)
        out[i, 2] = p[i, 2] - t2 - (w0 * c1 - w1 * c0)
    return out


def pinned_dofs(X: np.ndarray) -> np.ndarray:
    """Six dofs that fix the rigid-motion gauge: the first pivots of a column-pivoted QR of the
    transposed rigid modes, so that the rigid modes restricted to them are well conditioned."""
    piv = scipy.linalg.qr(rigid_modes(X).T, pivoting=True, mode="r")[1]
    return np.sort(piv[:6])


def _fixes_gauge(X: np.ndarray, pinned) -> bool:
    """Whether the dofs ``pinned`` fix the rigid-motion gauge at ``X``: six distinct valid
    dofs on which the rigid modes are conditioned to :data:`GAUGE_MAX_COND`, or to twice the
    condition of the best choice at ``X`` (:func:`pinned_dofs`; above 10 only on very
    elongated shapes)."""
    pinned = np.asarray(pinned)
    if pinned.shape != (6,) or len(np.unique(pinned)) != 6 or pinned.min() < 0 \
            or pinned.max() >= X.size:
        return False
    cond = np.linalg.cond(_rigid_rows(X, pinned))
    return bool(cond <= GAUGE_MAX_COND
                or cond <= 2.0 * np.linalg.cond(_rigid_rows(X, pinned_dofs(X))))


def _rigid_rows(X: np.ndarray, dofs: np.ndarray) -> np.ndarray:
    """The rows ``dofs`` of :func:`rigid_modes` at ``X`` (the same numbers), without the
    ``(3V, 6)`` array."""
    dofs = np.asarray(dofs)
    rows, coordinate = np.arange(len(dofs)), dofs % 3
    c = X[dofs // 3] - X.mean(axis=0)
    out = np.zeros((len(dofs), 6))
    out[rows, coordinate] = 1.0
    for k in range(3):
        e = np.zeros(3)
        e[k] = 1.0
        out[:, 3 + k] = np.cross(e, c)[rows, coordinate]
    return out


def _sorted_unique(a: np.ndarray) -> np.ndarray:
    """``np.unique(a)`` for integer keys, by a sort: the KKT pattern's keys come nearly sorted
    (row by row), and a sort then takes ~4 ms on the paper's mesh where ``np.unique``'s hash
    table takes ~150 ms."""
    a = np.sort(a)
    keep = np.empty(a.size, dtype=bool)
    keep[:1] = True
    np.not_equal(a[1:], a[:-1], out=keep[1:])
    return a[keep]


def _contains(sorted_keys: np.ndarray, keys: np.ndarray) -> bool:
    """Whether every one of ``keys`` is in ``sorted_keys`` (sorted, unique)."""
    if not keys.size:
        return True
    if not sorted_keys.size:
        return False
    at = np.minimum(np.searchsorted(sorted_keys, keys), sorted_keys.size - 1)
    return bool(np.array_equal(sorted_keys[at], keys))


class KKTAssembler:
    """Upper triangle of the reduced KKT matrix ``[[sum_t c_t M_t + mu I, g], [g^T, 0]]`` over
    the free dofs ``f``, from symmetric sparse terms ``M_t`` (the energy and volume Hessians).

    The result is a CSR matrix (sorted indices, int32) whose pattern stays fixed while the
    patterns of the terms do, so the linear solver reuses its symbolic analysis. The map from
    every stored entry of every term to its slot in the result is computed once per pattern;
    an assembly is then one scatter per term (no sparse sums, transposes or sorting).
    """

    def __init__(self, free: np.ndarray, n_dofs: int):
        self.free = np.asarray(free)
        self.n = len(self.free)
        self.n_dofs = int(n_dofs)
        self.new_index = np.full(n_dofs, -1, dtype=np.int64)
        self.new_index[self.free] = np.arange(self.n)
        self._keys = None
        self._terms: list = []

    def _term_keys(self, M: sp.csr_matrix):
        """Positions of the kept (free, upper) entries of ``M`` and their pattern keys."""
        rows = np.repeat(np.arange(self.n_dofs), np.diff(M.indptr))
        a, b = self.new_index[rows], self.new_index[M.indices]
        keep = np.flatnonzero((a >= 0) & (a <= b))
        return keep, a[keep] * (self.n + 1) + b[keep]

    def _analyse(self, mats):
        n = self.n
        found = [self._term_keys(M) for M in mats]
        if self._keys is None or not all(_contains(self._keys, keys) for _, keys in found):
            ar = np.arange(n + 1, dtype=np.int64)
            fixed = [ar[:n] * (n + 1) + ar[:n], ar * (n + 1) + n]  # diagonal; g column, corner
            self._keys = _sorted_unique(np.concatenate(fixed + [keys for _, keys in found]))
            rows = self._keys // (n + 1)
            self._indices = (self._keys % (n + 1)).astype(np.int32)
            self._indptr = np.zeros(n + 2, dtype=np.int32)
            np.cumsum(np.bincount(rows, minlength=n + 1), out=self._indptr[1:])
            self._slot_diag = np.searchsorted(self._keys, ar[:n] * (n + 1) + ar[:n])
            self._slot_g = np.searchsorted(self._keys, ar[:n] * (n + 1) + n)
        self._terms = [(M.indptr.copy(), M.indices.copy(), keep,
                        np.searchsorted(self._keys, keys)) for M, (keep, keys) in zip(mats, found)]

    def _same_patterns(self, mats) -> bool:
        return len(mats) == len(self._terms) and all(
            len(M.indices) == len(t[1]) and np.array_equal(M.indptr, t[0])
            and np.array_equal(M.indices, t[1]) for M, t in zip(mats, self._terms))

    def build(self, terms, g: np.ndarray) -> np.ndarray:
        """Data array of the unshifted matrix. ``terms``: list of ``(M (3V, 3V) csr,
        coefficient)``; ``g (V, 3)`` the constraint gradient."""
        mats = [M if sp.issparse(M) and M.format == "csr" else sp.csr_matrix(M) for M, _ in terms]
        for M in mats:
            if not M.has_canonical_format:  # one slot per stored entry is assumed below
                M.sum_duplicates()
        if not self._same_patterns(mats):
            self._analyse(mats)
        data = np.zeros(len(self._keys))
        for M, (coef, (_, _, keep, slot)) in zip(mats, zip([c for _, c in terms], self._terms)):
            add_scaled_at(data, slot, np.ascontiguousarray(M.data, dtype=np.float64), keep,
                          float(coef))
        data[self._slot_g] = g.ravel()[self.free]
        return data

    def diagonal(self, data: np.ndarray) -> np.ndarray:
        """The diagonal of ``K_ff`` in a data array from :meth:`build`."""
        return data[self._slot_diag]

    def matrix(self, data: np.ndarray, mu: float = 0.0) -> sp.csr_matrix:
        """The upper-triangular CSR matrix of ``data`` with ``mu`` added to ``K_ff``'s diagonal."""
        if mu != 0.0:
            data = data.copy()
            data[self._slot_diag] += mu
        return sp.csr_matrix((data, self._indices, self._indptr), shape=(self.n + 1, self.n + 1))


_KKT_CACHE = Recent(4)


def kkt_assembler(free: np.ndarray, n_dofs: int) -> KKTAssembler:
    """A :class:`KKTAssembler` for these free dofs, shared by successive minimizations (the
    protocol's three per volume step) so that neither it nor the linear solver redoes its
    pattern analysis; a few recent ones are kept."""
    key = (int(n_dofs), np.asarray(free).tobytes())
    kkt = _KKT_CACHE.get(key) or KKTAssembler(free, n_dofs)
    _KKT_CACHE.put(key, kkt)
    return kkt


def _max_displacement(p: np.ndarray) -> float:
    return float(np.sqrt(np.einsum("ij,ij->i", p, p).max()))


class _LastGradient:
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


def _with_last_gradient(energy):
    return _LastGradient(energy) if hasattr(energy, "value_and_gradient") else energy


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
           inverse_iterations: int = 12, curvature_tol: float = 1e-8,
           inertia_step: float = 1e-4, max_quasi: int = 50, memory: int = 16, pinned=None,
           seed: int = 0, history: bool = False, precondition_at: np.ndarray | None = None,
           relax_shift: float = RELAX_SHIFT, relax_tol: float = RELAX_TOL,
           relax_rough_shift: float = RELAX_ROUGH_SHIFT, single_precision_steps: bool = True,
           abandon=None, abandon_thorough=None, warm_start=None,
           certify: bool = True, relax_scaling: bool = True,
           precondition_token=None, certify_single: bool = True) -> MinimizeResult:
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
        Convergence criteria, see the module docstring (``max_iter`` counts Newton steps,
        not the quasi-Newton steps between them).
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
        Report the inertia at the final point (always done when escaping saddles).
    max_step : float, optional
        Largest vertex displacement of one step (default ``0.2 R_eq``, with ``R_eq`` the radius
        of the sphere of volume ``V_target``).
    inverse_iterations : int
        Inverse-iteration steps for the negative-curvature direction.
    curvature_tol : float
        Eigenvalues of the tangent Hessian above ``-curvature_tol * mean|diag K|`` are treated
        as zero (marginal) when deciding whether a converged point is a saddle.
    inertia_step : float
        A final full Newton step no larger than ``inertia_step`` times the mean edge length
        (largest vertex displacement) keeps the inertia of the factorization it came from;
        see the module docstring. 0 refactors at every converged point.
    max_quasi, memory : int
        At most ``max_quasi`` quasi-Newton steps reuse one factorization, with the last
        ``memory`` secant pairs (see the module docstring); ``max_quasi = 0`` is plain
        Newton (one factorization per step).
    pinned : (6,) int array, optional
        The dofs that fix the rigid-motion gauge (default: :func:`pinned_dofs` at the start).
        A caller that minimizes the same mesh many times passes one set (e.g. chosen on the
        reference mesh) so that the KKT pattern, and the linear solver's symbolic analysis,
        stay the same from call to call; it is used if the rigid modes restricted to it have a
        condition number below 1e3 at the start, else a new set is chosen.
    seed : int
        Seed of the inverse-iteration start vector (results are reproducible).
    history : bool
        Record one dict per iteration in ``result.history``.
    precondition_at : (V, 3) array, optional
        A relaxed state near the start (the state before a jiggle, or the minimum at the
        previous parameters): the minimization first relaxes by L-BFGS preconditioned with
        the Hessian there, shifted by ``relax_shift mean|diag K|``, until the energy falls by
        less than ``relax_tol |E|`` over five steps (at most ``max_iter // 2`` steps, counted
        in ``nit`` but not against Newton's ``max_iter``); Newton's method then converges.
        See the module docstring ("Preconditioned relaxation").
    relax_shift, relax_tol : float
        Shift of the preconditioner and stopping test of that relaxation.
    relax_rough_shift : float
        Shift of the relaxation's first stage (module docstring, "Preconditioned
        relaxation"), relative to ``mean|diag K|``; a value not above ``relax_shift`` skips
        that stage, as does a start farther than ``RELAX_ROUGH_MAX_MOVE`` (1.5) or closer
        than ``RELAX_ROUGH_MIN_MOVE`` (0.3) mean edge lengths (rms) from
        ``precondition_at``.
    relax_scaling : bool
        Scale the initial inverse Hessian of the relaxation's steps after its rough stage (or
        from the start, without one) by the line searches' estimate of how much too soft it
        is (module docstring, "Preconditioned relaxation").
    single_precision_steps : bool
        Factor the Newton steps of an unconverged point in single precision where the solver
        offers it (module docstring, "Single-precision steps"); the inertia at a converged
        point always comes from a double-precision factorization. Only with
        ``escape_saddles`` (round-off of single precision moves an iterate off a saddle that
        a search for any stationary point should reach).
    abandon : callable, optional
        ``abandon(X) -> str or None``, asked after the relaxation and after every Newton step
        at a point that has not converged: a reason stops the minimization there
        (``success = False``, message ``"abandoned: <reason>"``). The deflation protocol
        gives up at once on a triangle folded onto its neighbour, where the energy is not
        differentiable and no minimizer makes progress (it jiggles again instead).
    abandon_thorough : callable, optional
        Like ``abandon`` (default: ``abandon``), a test that may cost more, asked in its place
        at two kinds of points only, where the shell is smooth unless it is tangled: after the
        relaxation, and after every Newton step that ends ``SINGLE_JAM_STEPS`` Newton steps
        without progress (:func:`_jammed`). The protocol also looks there for a surface that
        passes through itself near a vertex the jiggle pushed through a face (~7 ms on the
        paper's mesh). Not during the relaxation: a freshly jiggled surface passes through
        itself in many places (80 pairs of faces at the protocol's amplitude on the paper's
        mesh) that the relaxation removes.
    warm_start : object, optional
        ``result.factorization`` of the minimization that ended at ``X0`` (same mesh, solver
        and gauge, other parameters): the first steps reuse the factorization the solver still
        holds, and the relaxation of ``precondition_at`` is skipped (module docstring, "Warm
        start"). Ignored when the solver has been given another matrix since.
    precondition_token : object, optional
        ``result.factorization`` of the minimization that ended at ``precondition_at`` (the
        previous volume step's): for a smooth start (closer than ``RELAX_ROUGH_MIN_MOVE`` mean
        edge lengths, rms, to ``precondition_at``) whose solver still holds that
        factorization, made at exactly ``precondition_at``, it serves the first quasi-Newton
        steps; without it the same matrix is factored (module docstring, "Smooth starts").
    certify : bool
        With ``escape_saddles`` or ``compute_inertia``, stop only where a factorization shows
        inertia 0 (module docstring, "Convergence").
        ``False``: stop on the gradient and energy tests alone and report the inertia as
        ``None``; saddles are still escaped on the way (every factorization's inertia sets
        the shift). For an intermediate minimum that nobody reports (the protocol's c0 = 0
        stage, module docstring "Uncertified minima"), it saves the last factorization.
    certify_single : bool
        Try the certificate first in single precision, with a margin (module docstring,
        "Single-precision certificates"); only with ``single_precision_steps`` and
        ``escape_saddles``, and only on a solver that factors approximate matrices in single
        precision. At most once per minimization (and for the refactored ``precondition_at``
        of a smooth start).

    Returns
    -------
    MinimizeResult
    """
    t_start = time.perf_counter()
    energy = _with_last_gradient(energy)
    X, V_target = check_problem(X0, V_target)
    X, verr = restore_volume(volume, X, V_target)
    if not verr <= 1e-12:
        raise ValueError(f"cannot bring X0 to V_target={V_target!r} along the volume gradient "
                         f"(relative volume error {verr:.1e})")
    if max_step is None:
        max_step = 0.2 * (3.0 * V_target / (4.0 * np.pi)) ** (1.0 / 3.0)
    tokens = [t for t in (warm_start if isinstance(warm_start, (list, tuple)) else [warm_start])
              if isinstance(t, _Factorization)]
    if (project_rigid and tokens and tokens[0].pinned is not None
            and _fixes_gauge(X, tokens[0].pinned)):
        pinned = tokens[0].pinned  # the gauge of the held factorization, while it holds
    nt = _Newton(energy, volume, V_target, make_solver(solver), X, project_rigid, pinned,
                 np.random.default_rng(seed))
    edge = mean_edge_length(np.asarray(volume.faces), X)
    want_inertia = certify and (compute_inertia or escape_saddles)
    E = nt.value(X)
    dE, mu, nit, records = None, 0.0, 0, []
    thorough = abandon_thorough or abandon  # the costlier test, asked where it pays
    single_ok = single_precision_steps and escape_saddles  # (module docstring)
    certify_single = certify_single and single_ok
    nt.token = next((t for t in tokens if _warm_ok(t, nt)), None)
    warm = nt.token is not None
    if precondition_at is not None and not warm and _smooth_start(volume, X, precondition_at):
        nt.token = _exact_preconditioner(nt, precondition_at, precondition_token, certify_single)
        warm = nt.token is not None
    if precondition_at is not None and not warm:
        X, E, nit, records = _relax(nt, X, E, precondition_at, (relax_rough_shift, relax_shift),
                                    relax_tol, max_iter // 2, max_step, tol_grad, atol_grad,
                                    history, abandon, relax_scaling)
    success, message, inertia, retries, certificate = False, "", None, 0, None
    fact = None  # (X, mu, inertia at mu = 0 or None, precision) of the current factorization
    if warm and nt.token.certifies(nt.raw_energy, V_target):
        # a minimum of this energy, certified by the held factorization
        fact = (nt.token.X, 0.0, 0, "single" if nt.token.approximate else "double")
    # with a warm start the held factorization serves the first quasi-Newton steps
    pairs, n_quasi, quasi_ok, previous, r_history = SecantPairs(X.size, memory), 0, warm, None, []
    need_gradient, hessian_fresh = True, False
    k = 0  # Newton steps (factorizations of K) so far; the quasi-Newton steps are not counted
    newton_trail = []  # (E, |r|) after each Newton step
    # the test to ask at the next point that has not converged: the thorough one after the
    # relaxation, the cheap one after every Newton step
    ask = thorough if precondition_at is not None and not warm else None
    while True:
        if need_gradient:
            lam, r, gE, gV = nt.gradients(X)
            r_norm = float(np.linalg.norm(r))
            grad_ok = r_norm <= tol_grad * float(np.linalg.norm(gE)) + atol_grad
            converged = grad_ok and (dE is None or abs(dE) <= tol_energy * abs(E))
            if previous is not None:
                pairs.add(X - previous[0], r - previous[1])
            r_history.append((r_norm, E))
            need_gradient = False
            if converged and (not want_inertia or _certified(fact, X, inertia_step * edge)):
                success, message = True, "converged"
                inertia = 0 if want_inertia else None
                certificate = fact[3] if want_inertia else None
                break
            reason = ask(X) if ask is not None and not converged else None
            ask = None
            if reason:
                message = f"{ABANDONED}: {reason}"
                break
        quasi = None
        if (retries == 0 and quasi_ok and not converged and n_quasi < max_quasi
                and k < max_iter and not _stalled(r_history)):
            quasi = nt.quasi_newton_step(X, r, pairs, volume.value(X) - V_target)
        if quasi is not None:
            p, slope_p = quasi
            with nt.clock("line_search"):
                found = _quasi_search(energy, volume, X, V_target, E, r_norm, p, slope_p, max_step)
            if found is None:
                quasi_ok = False
                continue
            alpha, E_new, X_new = found
            kind, rho = "quasi-newton", np.nan
            quasi_ok = alpha >= QUASI_MIN_ALPHA
            n_quasi += 1
        else:
            if nt.gauge_lost(X):
                log.info("newton: the pinned dofs no longer fix the rigid motions; pinning others")
                nt.set_gauge(X)
                fact, hessian_fresh = None, False
            if not hessian_fresh:
                nt.assemble(X, lam, gV)
                hessian_fresh = True
                if grad_ok or k == max_iter:  # Newton's step, and the inertia at the point
                    mu = 0.0
            # far from convergence a single-precision factorization serves the step (and the
            # shift search); the inertia that certifies a minimum is always double precision
            single = single_ok and not grad_ok and k < max_iter and retries == 0
            precision = "double"
            if grad_ok and mu == 0.0 and want_inertia and single_ok and certify_single:
                certify_single = False  # one try per minimization
                if nt.certify_single():
                    precision = "single"
            if precision == "single":
                shift = (0.0, 0, False)  # positive definite: inertia 0, as unshifted
            else:
                shift = nt.factor_positive(mu, escape_saddles, approximate=single)
            if shift is None:
                message = "could not make the tangent Hessian positive definite by a shift"
                break
            mu, inertia, indefinite = shift
            fact, n_quasi, quasi_ok = (X, mu, inertia, precision), 0, True
            pairs.clear()
            r_history = [(r_norm, E)]
            if converged and (not escape_saddles or inertia == 0 or not indefinite):
                success, message = True, "converged"
                certificate = precision if mu == 0.0 and inertia == 0 else None
                break
            if k == max_iter:
                message = f"maximum number of Newton iterations ({max_iter}) reached"
                break
            s, slope_s, curv_s = nt.step(X, r, volume.value(X) - V_target)
            d, curv_d = None, 0.0
            if escape_saddles and indefinite and (grad_ok or retries):
                d, curv_d = nt.negative_curvature(X, inverse_iterations)
                if curv_d >= -curvature_tol * nt.diag_scale:
                    d = None
                    if converged:
                        success = True
                        message = (f"converged; the tangent Hessian has {inertia} marginal "
                                   f"negative eigenvalue(s) above -{curvature_tol:g} mean|diag K|")
                        break
            with nt.clock("line_search"):
                found = _line_search(energy, volume, X, V_target, E, r, s, slope_s, curv_s, d,
                                     curv_d, max_step, edge, r_norm, extend=mu > 0.0)
            if found is None:
                if grad_ok:
                    success, message = True, "converged (no further decrease within round-off)"
                    break
                if retries < 3:  # same point and Hessian, stronger damping
                    retries, k = retries + 1, k + 1
                    mu = _damping_after(mu, curv_s, 1.0 / 16.0)
                    continue
                message = "line search failed to decrease the energy"
                break
            kind, alpha, E_new, X_new, rho = found
            mu = _damping_next(mu, curv_s, kind, alpha, rho)
            k += 1
            ask = abandon
            newton_trail.append((E_new, r_norm))
            stop = None
            if _jammed(newton_trail, tol_energy, SINGLE_JAM_STEPS):
                single_ok = False  # inexact steps along the softest modes
                reason = thorough(X_new) if thorough is not None and not grad_ok else None
                stop = f"{ABANDONED}: {reason}" if reason else None
            if stop is None and not grad_ok and _jammed(newton_trail, tol_energy):
                stop = (f"stalled: {JAM_STEPS} Newton steps lowered the energy by less than "
                        f"{tol_energy:g} relative and the gradient by less than half")
            if stop is not None:
                X, E = X_new, E_new
                lam, r, gE, gV = nt.gradients(X)
                r_norm = float(np.linalg.norm(r))
                message = stop
                nit += 1
                break
        log.debug("newton %3d  E=%.15g  |r|=%.3e  lam=%.9g  inertia=%s  mu=%.2e  %s alpha=%.3g "
                  "rho=%.3g", nit, E_new, r_norm, lam, inertia, mu, kind, alpha, rho)
        if history:
            records.append(dict(iteration=nit, energy=E_new, grad_norm=r_norm, lam=lam,
                                inertia=inertia, mu=mu, step=kind, alpha=alpha, rho=rho))
        previous = (X, r) if kind != "curvature" else None
        dE, E, X, retries = E_new - E, E_new, X_new, 0
        need_gradient, hessian_fresh = True, False
        nit += 1

    nt.clock.t["total"] = time.perf_counter() - t_start
    volume_error = abs(volume.value(X) - V_target) / V_target
    log.info("newton: %s after %d iterations, E=%.15g, |r|=%.3e, pressure=%.9g, inertia=%s",
             message, nit, E, r_norm, -lam, inertia)
    held = nt.token if _warm_ok(nt.token, nt) else None
    return MinimizeResult(x=X, fun=E, grad_norm=r_norm, nit=nit, success=success,
                          message=message, pressure=-lam, volume_error=volume_error,
                          inertia=inertia, method="newton",
                          history=records if history else None, timings=dict(nt.clock.t),
                          factorization=held, certificate=certificate)


def _relax(nt, X, E, X_ref, shifts, tol, max_it, max_step, tol_grad, atol_grad, history,
           abandon=None, scaling=False):
    """Preconditioned relaxation (see the module docstring): L-BFGS steps whose initial
    inverse Hessian is the KKT solve with the Hessian at ``X_ref`` shifted by
    ``shift mean|diag K|`` (raised x4 until positive definite on the tangent space), from
    ``X`` until the energy falls by at most ``tol |E|`` over ``RELAX_WINDOW`` steps, the
    projected gradient has converged, a step fails, or ``max_it`` steps. ``shifts = (rough,
    shift)``: with ``rough > shift`` the steps first use that larger shift, until
    ``RELAX_ROUGH_FULL`` consecutive steps are taken in full or the energy test above holds;
    the matrix is then factored again with ``shift`` (the secant pairs are kept: they describe
    the energy, not the preconditioner). No rough stage when ``X`` lies farther than
    ``RELAX_ROUGH_MAX_MOVE`` or closer than ``RELAX_ROUGH_MIN_MOVE`` mean edge lengths (rms)
    from ``X_ref``. After
    ``RELAX_ASK_STEPS`` consecutive steps cut below ``RELAX_ASK_ALPHA`` of their length,
    ``abandon(X)`` is asked, and a reason ends the relaxation (Newton's method then asks
    again and stops).
    Returns ``(X, E, steps, history records)``."""
    energy, volume, V_target = nt.energy, nt.volume, nt.V_target
    rough, shift = shifts
    move = _move(volume, X, X_ref)
    rough = (rough if rough > shift and RELAX_ROUGH_MIN_MOVE <= move <= RELAX_ROUGH_MAX_MOVE
             else None)
    lam, r, gE, gV = nt.gradients(X_ref)
    nt.assemble(X_ref, lam, gV)
    if nt.factor_positive((rough or shift) * nt.diag_scale, escape_saddles=True,
                          approximate=True) is None:
        return X, E, 0, []
    pairs, previous, energies, records = SecantPairs(X.size, RELAX_MEMORY), None, [E], []
    n, full, cut, tau = 0, 0, 0, 1.0
    while n < max_it:
        if rough is not None and full >= RELAX_ROUGH_FULL:
            rough, energies = None, [E]
            if nt.factor_positive(shift * nt.diag_scale, escape_saddles=True,
                                  approximate=True) is None:
                break
        lam, r, gE, gV = nt.gradients(X)
        r_norm = float(np.linalg.norm(r))
        if r_norm <= tol_grad * float(np.linalg.norm(gE)) + atol_grad:
            break
        if previous is not None:
            pairs.add(X - previous[0], r - previous[1])
        verr = volume.value(X) - V_target
        quasi = (nt.quasi_newton_step(X, r, pairs, verr, tau)
                 or nt.quasi_newton_step(X, r, None, verr, tau))
        if quasi is None:
            break
        with nt.clock("line_search"):
            found = _quasi_search(energy, volume, X, V_target, E, r_norm, *quasi, max_step)
        if found is None:
            break
        alpha, E_new, X_new = found
        full = full + 1 if alpha == 1.0 else 0
        # a cut step is judged against the unscaled step's length (the abandon test below)
        cut = cut + 1 if alpha * tau < RELAX_ASK_ALPHA else 0
        if scaling and rough is None:
            tau = _rescaled(tau, E, E_new, quasi[1], alpha)
        previous, X, E = (X, r), X_new, E_new
        n += 1
        energies.append(E)
        if history:
            records.append(dict(iteration=n - 1, energy=E, grad_norm=r_norm, lam=lam,
                                inertia=None, mu=np.nan, step="relax", alpha=alpha, rho=np.nan))
        if abandon is not None and cut >= RELAX_ASK_STEPS and abandon(X):
            break
        if len(energies) > RELAX_WINDOW and energies[-1 - RELAX_WINDOW] - E <= tol * abs(E):
            if rough is None:
                break
            full = RELAX_ROUGH_FULL  # the rough stage has done what it can
    log.debug("preconditioned relaxation: %d steps, E=%.15g", n, E)
    return X, E, n, records


def _move(volume, X: np.ndarray, X_ref: np.ndarray) -> float:
    """How far ``X`` lies from ``X_ref``: the root mean square over the vertices of their
    displacements, in mean edge lengths of ``X_ref``."""
    move = float(np.sqrt(np.mean(np.sum((X - X_ref) ** 2, axis=1))))
    return move / mean_edge_length(np.asarray(volume.faces), X_ref)


def _smooth_start(volume, X: np.ndarray, X_ref: np.ndarray) -> bool:
    """Whether ``X`` lies closer to ``X_ref`` than ``RELAX_ROUGH_MIN_MOVE`` (:func:`_move`): no
    jiggle, or a small one; such a start is not relaxed at all."""
    return _move(volume, X, X_ref) < RELAX_ROUGH_MIN_MOVE


def _exact_preconditioner(nt, X_ref: np.ndarray, token, single: bool = False):
    """The factorization that certifies the Hessian of the Lagrangian at ``X_ref`` positive
    definite on the tangent space, for the first quasi-Newton steps of a smooth start (module
    docstring, "Smooth starts"): ``token`` if the solver still holds it and it was made at
    exactly ``X_ref`` with this energy, else a new one (``single``: a single-precision
    certificate where it holds, else unshifted in double precision; the same matrix as the
    minimization that ended at ``X_ref`` factored with the same choice gives the same bits);
    ``None`` where that matrix has a negative direction."""
    if (isinstance(token, _Factorization) and token.definite_for(nt.raw_energy)
            and token.X is not None and np.array_equal(token.X, X_ref) and _warm_ok(token, nt)):
        return token
    lam, _, _, gV = nt.gradients(X_ref)
    nt.assemble(X_ref, lam, gV)
    if single and nt.certify_single():
        return nt.token
    ok, inertia = nt.factor(0.0)
    return nt.token if ok and inertia == 0 else None


def _certified(fact, X: np.ndarray, max_displacement: float) -> bool:
    """Whether the inertia 0 of the last factorization (unshifted, or a single-precision
    certificate, at ``fact[0]``) holds at ``X``: the points differ by at most
    ``max_displacement`` per vertex."""
    return (fact is not None and fact[1] == 0.0 and fact[2] == 0
            and _max_displacement(X - fact[0]) <= max_displacement)


def _jammed(trail: list, tol_energy: float, steps: int = JAM_STEPS) -> bool:
    """Over the last ``steps`` Newton steps the energy fell by at most ``tol_energy``
    relative and the projected gradient by less than half: the iterate is stuck far from
    stationarity (e.g. on a triangle folded by the jiggle, where the shift grows without bound
    and the line search takes steps of 1e-7), and more Newton steps only cost factorizations."""
    if len(trail) <= steps:
        return False
    (E_old, r_old), (E_new, r_new) = trail[-1 - steps], trail[-1]
    return E_old - E_new <= tol_energy * abs(E_new) and r_new > 0.5 * r_old


def _stalled(history: list, window: int = 3, ratio: float = 0.9, progress: float = 0.3) -> bool:
    """Whether the quasi-Newton steps since the last factorization have stalled: over the last
    ``window`` steps the projected gradient has not fallen by ``ratio`` and the energy has
    fallen by less than ``progress`` times the fall of the step taken with the factorization.
    ``history``: ``(|r|, E)`` at the factorization and after every step since.

    In a curved post-buckling valley the gradient does not fall from step to step while the
    energy falls steadily, as much per quasi-Newton step as per Newton step; those steps go on
    (a factorization costs about ten of them)."""
    if len(history) <= window:
        return False
    (r_old, E_old), (r_new, E_new) = history[-1 - window], history[-1]
    if r_new <= ratio * r_old:
        return False
    return E_old - E_new <= progress * (history[0][1] - history[1][1])


def _quasi_search(energy, volume, X, V_target, E, r_norm, p, slope, max_step):
    """Armijo backtracking along a quasi-Newton step ``p``; below the energy noise, the full
    step is taken if the energy stays within the noise and the projected gradient falls."""
    alpha0 = min(1.0, max_step / max(_max_displacement(p), np.finfo(float).tiny))
    path = RestoredPath(energy, volume, X, p, V_target)
    noise = ENERGY_NOISE * abs(E)
    if -slope > noise:
        return backtracking(path, E, slope, alpha0)
    E1, X1 = path(alpha0)
    if X1 is not None and E1 <= E + noise:
        if np.linalg.norm(projected_gradient(energy.gradient(X1), volume.gradient(X1))[1]) < r_norm:
            return alpha0, E1, X1
    return None


def _rescaled(tau: float, E: float, E_new: float, slope: float, alpha: float) -> float:
    """The next scale of an L-BFGS initial inverse Hessian: ``tau`` times the minimizer
    (clipped to [0.1, 2]; ``2 alpha`` where it is not convex) of the parabola through
    ``(0, E)`` with slope ``slope`` and the accepted point ``(alpha, E_new)`` of the step it
    gave (:func:`~.linesearch.parabola_minimizer`), within [1e-3, 1]."""
    best = parabola_minimizer(alpha, E_new, E, slope)
    if best is None:
        best = 2.0 * alpha
    return float(np.clip(tau * min(max(best, 0.1), 2.0), 1e-3, 1.0))


def _damping_next(mu: float, curv_s: float, kind: str, alpha: float, rho: float) -> float:
    """Levenberg–Marquardt shift for the next iteration from the step just accepted.

    ``rho`` is the ratio of the actual to the predicted decrease of the full step (Moré,
    Lecture Notes in Math. 630, 105 (1978); Nocedal & Wright §4.1, §10.3). A step cut by the
    line search to ``alpha < 1``, or stretched to ``alpha > 1`` (a damped step whose model
    was good, see :func:`_line_search`), sets the shift that would have given that length
    along the step's own direction; otherwise a good model (``rho > 0.75``) divides the shift
    by 4 and a poor one (``rho < 0.25``) doubles the step's shifted curvature. A shift below
    ``1e-3`` times the curvature along the step is dropped (pure Newton). A full step whose
    predicted decrease is below the energy's noise (``rho`` NaN: near a minimum, where the
    model is good) divides the shift by 4 too; left there, the shift kept the tail of a
    minimization converging linearly.
    """
    if kind != "newton":
        return mu
    if not np.isfinite(rho):
        if alpha != 1.0:
            return mu
        rho = 1.0
    if alpha != 1.0:
        mu = _damping_after(mu, curv_s, alpha)
    elif rho > 0.75:
        mu = mu / 4.0
    elif rho < 0.25:
        mu = _damping_after(mu, curv_s, 0.5)
    return 0.0 if mu <= 1e-3 * max(curv_s, 0.0) else mu


def _damping_after(mu: float, curv_s: float, factor: float) -> float:
    """The shift that scales a step along its own direction by ``factor``: with
    ``q = s.K s / s.s`` the curvature along the step (computed with shift ``mu``),
    ``(q + mu) / (q + mu') = factor``. A shortening (``factor < 1``) at least doubles it."""
    target = max(curv_s + mu, 0.0) / factor - curv_s
    if factor < 1.0:
        return float(max(target, 2.0 * mu, np.finfo(float).tiny))
    return float(max(target, 0.0))


class _Newton:
    """Assembly, factorization and solves of one Newton minimization."""

    def __init__(self, energy, volume, V_target, linsolver, X, project_rigid, pinned, rng):
        self.energy, self.volume, self.V_target = energy, volume, V_target
        self.linsolver, self.rng = linsolver, rng
        self.n_dofs = X.size
        self.pinned = None
        self.free = np.arange(self.n_dofs)
        if project_rigid:
            self.set_gauge(X, pinned)
        else:
            self.kkt = kkt_assembler(self.free, self.n_dofs)
        self._approximate_ok = accepts(linsolver.factor, "approximate")
        # a certificate needs the margin of a shift only where the approximate factorization
        # is in single precision; elsewhere it would save nothing
        self._factors_single = self._approximate_ok and bool(
            getattr(linsolver, "single_precision", False))
        self.clock = _Clock()
        self.diag_scale = 1.0
        self._terms = self._data = self._X_assembled = None
        self.raw_energy = energy.energy if isinstance(energy, _LastGradient) else energy
        self.token = None  # the factorization the solves use (made here, or a warm start's)

    def set_gauge(self, X, pinned=None) -> bool:
        """Pin ``pinned`` (or, if those do not fix the rigid motions at ``X``, the dofs of
        :func:`pinned_dofs` at ``X``); whether the gauge changed."""
        if pinned is None or not _fixes_gauge(X, pinned):
            pinned = pinned_dofs(X)
        pinned = np.sort(np.asarray(pinned))
        if self.pinned is not None and np.array_equal(pinned, self.pinned):
            return False
        self.pinned = pinned
        free = np.ones(self.n_dofs, dtype=bool)
        free[pinned] = False
        self.free = np.flatnonzero(free)
        self.kkt = kkt_assembler(self.free, self.n_dofs)
        return True

    def gauge_lost(self, X) -> bool:
        """Whether the pinned dofs no longer fix the rigid motions at ``X`` (the shell moved
        so that some rigid motion leaves all of them unchanged: ``K`` on the free dofs is then
        singular, and the residual on the pinned dofs cannot be removed)."""
        return self.pinned is not None and not _fixes_gauge(X, self.pinned)

    def value(self, X) -> float:
        with self.clock("assembly"):
            return self.energy.value(X)

    def gradients(self, X):
        with self.clock("assembly"):
            gE, gV = self.energy.gradient(X), self.volume.gradient(X)
        lam, r = projected_gradient(gE, gV)
        return lam, r, gE, gV

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
        for a preconditioner or a certificate with a margin (:meth:`certify_single`)."""
        A = self.kkt.matrix(self._data, mu)
        approximate = approximate and self._approximate_ok
        # a failed factorization leaves nothing usable: mark it approximate (never warm)
        token = self.token = _Factorization(self.linsolver, self.kkt, self.pinned, True)
        _hold(token)
        with self.clock("factorization"):
            try:
                if approximate:
                    self.linsolver.factor(A, upper=True, approximate=True)
                else:
                    self.linsolver.factor(A, upper=True)
            except SingularFactorError:
                return False, None
        signs = self.linsolver.inertia()
        inertia = None if signs is None else signs[1] - 1
        held = getattr(self.linsolver, "held", None)
        token.approximate, token.handle = approximate, None if held is None else held()
        token.X, token.V_target = self._X_assembled, self.V_target
        token.energy = _ref(self.raw_energy)
        token.mu, token.inertia = mu, inertia
        token.certificate = not approximate and mu == 0.0 and inertia == 0
        return True, inertia

    def certify_single(self) -> bool:
        """Whether one single-precision factorization of the KKT matrix with the tangent
        Hessian shifted down by ``CERTIFY_SHIFT mean|diag K|`` has inertia 0, which shows the
        tangent Hessian positive definite (module docstring, "Single-precision
        certificates"); the solver then holds that factorization."""
        if not self._factors_single:
            return False
        ok, inertia = self.factor(-CERTIFY_SHIFT * self.diag_scale, approximate=True)
        self.token.certificate = bool(ok and inertia == 0)
        return self.token.certificate

    def factor_positive(self, mu: float, escape_saddles: bool, approximate: bool = False):
        """Factor with shift ``mu``; if the tangent Hessian plus shift is not positive
        definite (and saddles are escaped), raise the shift (x4) until it is.

        Returns ``(mu, inertia, indefinite)``: ``inertia`` is the number of negative
        eigenvalues of the tangent Hessian when ``mu = 0`` was factored in double precision
        (else ``None``: an ``approximate`` factorization's inertia only guides the shift, it is
        never reported nor used to certify a minimum) and ``indefinite`` whether the tangent
        Hessian is known to have one; ``None`` if no shift up to ``1e12 mean|diag K|`` works."""
        ok, inertia = self.factor(mu, approximate)
        if mu > 0.0:
            inertia0, indefinite = None, not (ok and inertia in (0, None))
        else:
            inertia0, indefinite = inertia, bool(ok and inertia is not None and inertia > 0)
        if approximate:
            inertia0 = None
        if ok and (not escape_saddles or inertia in (0, None)):
            return mu, inertia0, indefinite
        mu = 4.0 * mu if mu > 0.0 else 1e-4 * self.diag_scale
        while mu <= 1e12 * self.diag_scale:
            ok, inertia = self.factor(mu, approximate)
            if ok and (not escape_saddles or inertia in (0, None)):
                return mu, inertia0, indefinite
            mu *= 4.0
        return None

    def solve(self, rhs_f, rhs_c=0.0) -> np.ndarray:
        with self.clock("solve"):
            y = self.linsolver.solve(np.concatenate([rhs_f, [rhs_c]]))
        out = np.zeros(self.n_dofs)
        out[self.free] = y[:-1]
        return out.reshape(-1, 3)

    def without_rigid(self, X, p) -> np.ndarray:
        """``p`` minus its least-squares component along the rigid motions at ``X`` (when the
        gauge is pinned). A step solved with pinned dofs carries whatever rotation makes those
        dofs vanish; removing it changes neither ``r.p`` (``r`` is orthogonal to rigid motions)
        nor the linearized constraint, and keeps the shell from rotating step after step
        (gamma = 271, dV/V = 0.6: 26 degrees within one minimization), which would leave the
        pinned dofs a poor gauge (a nearly singular ``K``, marginal negative eigenvalues and a
        stalled iteration)."""
        return p if self.pinned is None else remove_rigid(X, p)

    def step(self, X, r, verr):
        """Newton step ``s`` from the current factorization (rigid part removed), its slope
        ``r.s`` and the curvature ``s.K s / s.s`` of the unshifted tangent Hessian along it."""
        s = self.without_rigid(X, self.solve(-r.ravel()[self.free], -verr))
        slope = float(np.einsum("ij,ij->", r, s))
        if not slope < 0:  # round-off at convergence, or unknown inertia: fall back to -r
            s = -r / self.diag_scale
            slope = -float(np.einsum("ij,ij->", r, r)) / self.diag_scale
        ss = float(np.einsum("ij,ij->", s, s))
        curv = float(s.ravel() @ self.K_times(s)) / ss if ss > 0 else 0.0
        return s, slope, curv

    def quasi_newton_step(self, X, r, pairs, verr, scale: float = 1.0):
        """L-BFGS step ``p = -H r`` (Nocedal & Wright, Algorithm 7.4) whose initial inverse
        Hessian ``H0`` is the current factorization (the tangent KKT solve, exact at the point
        where it was factored) times ``scale`` (the relaxation's self-scaling) and whose pairs
        are the steps taken since (a :class:`~.lbfgs.SecantPairs`, or ``None``: none);
        ``(p, r.p)``, or ``None`` if ``p`` is not a descent direction."""

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
        """Direction of most negative curvature of the tangent Hessian by inverse iteration
        with the current (positive definite on the tangent space) shifted factorization.

        Returns ``(d (V, 3), d . K d)`` with ``d`` tangent and of unit maximum vertex
        displacement."""
        v = self.rng.standard_normal(len(self.free))
        d = None
        for _ in range(n_iter):
            d = self.solve(v)
            v = d.ravel()[self.free]
            v /= np.linalg.norm(v)
        d = self.without_rigid(X, d)
        d /= _max_displacement(d)
        return d, float(d.ravel() @ self.K_times(d))


def _line_search(energy, volume, X, V_target, E, r, s, slope_s, curv_s, d, curv_d, max_step,
                 edge, r_norm, extend=False):
    """Backtracking on the (shifted) Newton step and, if given, a curvature search along the
    negative-curvature direction ``d``; returns ``(kind, alpha, E, X, rho)`` of the lower
    energy, ``rho`` the ratio of the actual to the predicted decrease (quadratic model
    ``alpha r.s + alpha^2/2 s.K s``) of the Newton step at the accepted ``alpha``.

    With ``extend`` (a damped step), a full step whose decrease is at least 0.9 of the
    prediction is doubled while the energy keeps falling (at most three times, within
    ``max_step``): in a soft valley the damped direction is right and only its length is
    too short, and the length found sets the next shift.

    When the predicted decrease ``-r.s`` is below the energy's evaluation noise
    (``ENERGY_NOISE |E|``), a full step is accepted if the energy stays within that noise and
    the projected gradient decreases (see :mod:`.linesearch`)."""
    candidates = []
    alpha0 = min(1.0, max_step / max(_max_displacement(s), np.finfo(float).tiny))
    noise = ENERGY_NOISE * abs(E)
    ss = float(np.einsum("ij,ij->", s, s))

    def ratio(alpha, E1):
        predicted = -(alpha * slope_s + 0.5 * alpha * alpha * curv_s * ss)
        return (E - E1) / predicted if predicted > noise else np.nan

    if d is None and -slope_s <= noise:
        E1, X1 = RestoredPath(energy, volume, X, s, V_target)(alpha0)
        if X1 is not None and E1 <= E + noise:
            r1 = projected_gradient(energy.gradient(X1), volume.gradient(X1))[1]
            if np.linalg.norm(r1) < r_norm:
                return "newton", alpha0, E1, X1, np.nan
    path = RestoredPath(energy, volume, X, s, V_target)
    found = backtracking(path, E, slope_s, alpha0)
    if found is not None:
        alpha, E1, X1 = found
        rho = ratio(alpha, E1)
        if extend and alpha == 1.0 and rho > 0.9:
            for _ in range(3):
                if 2.0 * alpha * _max_displacement(s) > max_step:
                    break
                E2, X2 = path(2.0 * alpha)
                if X2 is None or not E2 < E1 or E2 > E + 1e-4 * 2.0 * alpha * slope_s:
                    break
                alpha, E1, X1 = 2.0 * alpha, E2, X2
        candidates.append(("newton", alpha, E1, X1, rho))
    if d is not None:
        slope_d = float(np.einsum("ij,ij->", r, d))
        if slope_d > 0 or (slope_d == 0 and d.ravel()[np.argmax(np.abs(d))] < 0):
            d, slope_d = -d, -slope_d
        length0 = max(alpha0 * _max_displacement(s), 0.5 * edge)
        found = curvature_search(RestoredPath(energy, volume, X, d, V_target), E, slope_d,
                                 curv_d, min(length0, max_step), max_alpha=max_step)
        if found is not None:
            candidates.append(("curvature",) + found + (np.nan,))
    if not candidates:
        return None
    return min(candidates, key=lambda c: c[2])
