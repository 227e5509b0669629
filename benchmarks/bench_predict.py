"""Two predictors of a volume step's start, measured on stored runs: the step ``k`` of a run
made again from its stored step ``k - 1`` (:class:`shellbuckle.locate.StepFromStored`, the
stored bits) as the protocol makes it, then from a predicted start.

- ``--coarse RUN``: a coarse-grid prediction from a run of the same shell on a coarser mesh.
  The fine minimum ``x`` at the last volume is sampled at the coarse mesh's material points
  (``y0``, linear interpolation in the fine reference triangles,
  :func:`shellbuckle.studies.transfer.material_interpolation`) and relaxed there at its own
  volume (the anchor ``ya``: the coarse mesh's discretization error taken out); the coarse
  problem is then minimized from ``ya`` at the volume changed by the step's fraction, and its
  displacement, interpolated to the fine material points, is added to ``x``. With ``--tilt``
  the anchor is the coarse problem of the full approximation scheme instead (Brandt, Math.
  Comp. 31, 333 (1977); Briggs, Henson & McCormick, *A Multigrid Tutorial*, 2nd ed., ch. 6):
  ``y0`` itself, made stationary by the linear term ``-tau . y``, ``tau = grad E_c(y0) - p
  grad V_c(y0)`` (``p`` fitted by least squares).
- ``--rescale``: the last minimum scaled uniformly about its centroid to the new volume
  (:func:`shellbuckle.protocol.deflate.scaled_to_volume`, the protocol's ``rescale_start``).
  The protocol's own start is the last minimum moved along the volume gradient to the new
  volume, which is proportional to each vertex's area: on a randomized mesh its radial move
  is as uneven as the vertex areas.
- ``--substeps m``: continuation in smaller volume steps: ``m - 1`` minimizations at evenly
  spaced volumes between the two steps' (uncertified, each from the last), then the protocol's
  step from there.

    python benchmarks/bench_predict.py RUN --steps 20,30 --coarse COARSE_RUN
    python benchmarks/bench_predict.py RUN --steps 20,30 --substeps 2 4

Prints, per step and start: the predictor's iterations and CPU time, the step's iterations
(its first minimization, and the whole step with its c0 cycle) and CPU time, its energy
against the stored one, and how far the predicted start is from the stored end and from the
step's start (rms and largest vertex distance, in mean edges ``h``). After buckling the path
depends on the start: another start may end in another minimum.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

import shellbuckle.protocol.deflate as protocol
from shellbuckle.locate import StepFromStored
from shellbuckle.protocol.imperfection import reference_directions
from shellbuckle.protocol.jiggle import mean_edge_length
from shellbuckle.protocol.stored import stored_context
from shellbuckle.store.view import Run
from shellbuckle.studies.transfer import material_interpolation


@dataclasses.dataclass(frozen=True)
class Tilted:
    """``energy(X) - tau . X``: the same Hessian, a constant added to the gradient."""

    energy: object
    tau: np.ndarray

    def value(self, X):
        return float(self.energy.value(X) - np.vdot(self.tau, X))

    def gradient(self, X):
        return self.energy.gradient(X) - self.tau

    def value_and_gradient(self, X):
        E, g = self.energy.value_and_gradient(X)
        return float(E - np.vdot(self.tau, X)), g - self.tau

    def hessian(self, X):
        return self.energy.hessian(X)

    def hessian_terms(self, X):
        return self.energy.hessian_terms(X)


def coarse_start(fine: Run, coarse_ctx, X, dv_from: float, dv_to: float, tilt: bool):
    """The fine start predicted on the coarse mesh: ``(start, iterations)``."""
    coarse_X0 = coarse_ctx.mesh.X
    y0 = material_interpolation(fine.store.X0, fine.store.faces, X,
                                reference_directions(coarse_X0))
    V = coarse_ctx.volume.value(y0)
    if tilt:
        g = coarse_ctx.energy.gradient(y0)
        n = coarse_ctx.volume.gradient(y0)
        energy = Tilted(coarse_ctx.energy, g - float(np.vdot(g, n) / np.vdot(n, n)) * n)
        anchor, nit = y0, 0
    else:
        energy = coarse_ctx.energy
        relaxed = protocol._minimize(coarse_ctx, energy, y0, V)
        anchor, nit = relaxed.x, relaxed.nit
    result = protocol._minimize(coarse_ctx, energy, anchor, V * (1.0 - dv_to) / (1.0 - dv_from))
    D = material_interpolation(coarse_X0, coarse_ctx.mesh.faces, result.x - anchor,
                               reference_directions(fine.store.X0))
    return X + D, nit + result.nit


def substep_start(ctx, X, dv_from: float, dv_to: float, m: int):
    """The start after ``m - 1`` uncertified minimizations at volumes between the two steps':
    ``(start, iterations)``."""
    token, nit = ctx.workspace.kept, 0
    for j in range(1, m):
        V = ctx.V0 * (1.0 - (dv_from + (dv_to - dv_from) * j / m))
        result = protocol._minimize(ctx, ctx.energy, X, V, relaxed=X, relaxed_token=token,
                                    certify=False)
        X, token, nit = result.x, result.factorization, nit + result.nit
    ctx.workspace.kept = token
    return X, nit


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", help="a finished deflation run folder")
    parser.add_argument("--steps", default="20,30", help="comma-separated steps (>= 1)")
    parser.add_argument("--coarse", help="a run of the same shell on a coarser mesh")
    parser.add_argument("--tilt", action="store_true",
                        help="the coarse problem of the full approximation scheme")
    parser.add_argument("--substeps", nargs="*", type=int, default=[],
                        help="numbers of smaller volume steps (>= 2)")
    parser.add_argument("--rescale", action="store_true",
                        help="the last minimum scaled uniformly to the new volume")
    parser.add_argument("--no-plain", action="store_true",
                        help="skip the step made from the protocol's own start")
    args = parser.parse_args()
    run = Run.of(args.run)
    coarse_ctx = stored_context(Run.of(args.coarse), 1) if args.coarse else None
    minimize, calls = protocol.minimize, []

    def counted(*a, **k):
        result = minimize(*a, **k)
        calls.append(result.nit)
        return result

    protocol.minimize = counted
    print(f"{'step':>4} {'start':>10} {'pred it':>7} {'first it':>8} {'step it':>7} "
          f"{'cpu s':>6} {'E / stored - 1':>14} {'start to end / h':>17} "
          f"{'start moved / h':>16}", flush=True)
    for k in [int(s) for s in args.steps.split(",")]:
        step = StepFromStored(run, k)
        h = mean_edge_length(run.store.X0, step.ctx.mesh.topology.edges)
        X_prev, record_prev = step.start
        stored, end = run.store.record(k), run.positions(k)
        dv_from, dv_to = float(record_prev["dV_over_V"]), float(stored["target_dV_over_V"])
        starts = [] if args.no_plain else [("plain", None)]
        starts += [("coarse", None)] if coarse_ctx is not None else []
        starts += [("rescale", None)] if args.rescale else []
        starts += [(f"{m} substeps", m) for m in args.substeps]
        for name, m in starts:
            t = time.process_time()
            if name == "plain":
                X, nit = X_prev, 0
            elif name == "coarse":
                X, nit = coarse_start(run, coarse_ctx, X_prev, dv_from, dv_to, args.tilt)
            elif name == "rescale":
                X = protocol.scaled_to_volume(step.ctx.volume, X_prev,
                                              step.ctx.V0 * (1.0 - dv_to))
                nit = 0
            else:
                X, nit = substep_start(step.ctx, X_prev, dv_from, dv_to, m)
            calls.clear()
            _, record = step(dv_to, start=(X, record_prev))
            cpu = time.process_time() - t
            first = calls[0] if calls else 0
            to_end, moved = (np.linalg.norm(a - b, axis=1) / h for a, b in ((X, end),
                                                                            (X, X_prev)))
            print(f"{k:>4} {name:>10} {nit:>7} {first:>8} {record['iterations']:>7} "
                  f"{cpu:>6.1f} {record['E_total'] / stored['E_total'] - 1:>14.2e} "
                  f"{np.sqrt(np.mean(to_end ** 2)):>8.2f} {to_end.max():>8.2f} "
                  f"{np.sqrt(np.mean(moved ** 2)):>7.2f} {moved.max():>8.2f}", flush=True)
    protocol.minimize = minimize


if __name__ == "__main__":
    main()
