"""The work around the factorizations of Newton's method, per call, on the paper's mesh.

Run from the repository root (one thread; PARDISO needs Intel MKL):

    python benchmarks/bench_newton_parts.py
    python benchmarks/bench_newton_parts.py --vertices 642 --repeat 50

For ``random_sphere(N, seed)`` shrunk by 2 % at gamma = 271 with Surface Evolver's bending
energy, it times the parts of a minimization that are not the factorization itself and, for
each one written more cheaply, the NumPy form it replaced, recomputed here, and whether the two
give the same bits:

- the KKT assembly (:class:`shellbuckle.solve.kkt.KKTAssembler`: each term scattered into
  the KKT data by one compiled pass, against NumPy's ``data[slot] += c * M.data[keep]``);
- the test that the six pinned dofs still fix the rigid motions (the six rows of the rigid
  modes it needs, against the whole ``(3V, 6)`` array) and the free dofs (a mask, against
  ``np.setdiff1d``), both at the start of every minimization, the first before every
  factorization;
- the mean edge length of the minimizers (one compiled pass over the face sides, against
  NumPy's ``norm``), four calls per volume step;
- PARDISO's analysis of the KKT pattern in single precision: with METIS, and with the ordering
  of an earlier analysis of the same pattern (what the double-precision solver of the same
  workspace now does; the factors are the same bits);
- PARDISO's factorizations and solves on one thread in its plain mode (the default there)
  against its reproducible mode (the default on several threads), for the three kinds of
  factorization Newton's method makes;

and, for scale, one energy value and gradient, one Hessian assembly, one single-precision
factorization and one solve. Times are medians of process time over ``--repeat`` calls.
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

from shellbuckle.energies.total import ShellEnergy  # noqa: E402
from shellbuckle.energies.volume import Volume  # noqa: E402
from shellbuckle.mesh.random_sphere import random_sphere  # noqa: E402
from shellbuckle.params import ShellParameters  # noqa: E402
from shellbuckle.solve import linear, pardiso  # noqa: E402
from shellbuckle.solve.linesearch import mean_edge_length  # noqa: E402
from shellbuckle.solve.gauge import fixes_gauge, pinned_dofs, rigid_modes  # noqa: E402
from shellbuckle.solve.kkt import KKTAssembler  # noqa: E402
from shellbuckle.solve.options import NewtonOptions  # noqa: E402
from shellbuckle.solve.recent import Recent  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import describe, median_ms, reference, reference_line  # noqa: E402  (machine.py)


def process_ms(f, repeat: int) -> float:
    """Median process time of ``f()`` in ms over ``repeat`` calls."""
    return median_ms(f, repeat, time.process_time)


def numpy_kkt_build(kkt, terms, g) -> np.ndarray:
    """The KKT data as NumPy's fancy indexing built it (the form before the compiled scatter)."""
    data = np.zeros(len(kkt._keys))
    for (M, coef), (_, _, keep, slot) in zip(terms, kkt._terms):
        data[slot] += coef * M.data[keep]
    data[kkt._slot_g] = g.ravel()[kkt.free]
    return data


def numpy_fixes_gauge(X, pinned) -> bool:
    """The gauge test with the whole ``(3V, 6)`` array of rigid modes."""
    modes = rigid_modes(X)
    cond = np.linalg.cond(modes[pinned])
    max_cond = NewtonOptions().gauge_max_cond
    return bool(cond <= max_cond or cond <= 2.0 * np.linalg.cond(modes[pinned_dofs(X)]))


def numpy_mean_edge_length(faces, X) -> float:
    d = X[np.roll(faces, -1, axis=1)] - X[faces]
    return float(np.linalg.norm(d, axis=-1).mean())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--vertices", type=int, default=3594)
    ap.add_argument("--seed", type=int, default=0, help="random_sphere seed")
    ap.add_argument("--repeat", type=int, default=30, help="timed calls per row")
    args = ap.parse_args(argv)
    if args.vertices < 12 or args.repeat < 1:
        raise SystemExit(f"need --vertices >= 12 and --repeat >= 1, got {args.vertices} and "
                         f"{args.repeat}")

    print(f"# {describe()}\n# {reference_line(reference())}", flush=True)
    mesh = random_sphere(args.vertices, seed=args.seed)
    params = ShellParameters.from_gamma(271.0, nu=1.0 / 3.0)
    energy = ShellEnergy.build(mesh, params, bending="evolver", c0=2.0 / params.R)
    volume = Volume(mesh.faces, mesh.n_vertices)
    X = 0.98 * mesh.X
    faces = np.asarray(mesh.faces)
    pinned = pinned_dofs(X)
    mask = np.ones(X.size, dtype=bool)
    mask[pinned] = False
    free = np.flatnonzero(mask)
    g = volume.gradient(X)
    terms = [(H, 1.0) for H in energy.hessian_terms(X)] + [(volume.hessian(X), -10.0)]
    kkt = KKTAssembler(free, X.size)
    kkt.build(terms, g)  # the pattern analysis, once per mesh

    def free_dofs():
        m = np.ones(X.size, dtype=bool)
        m[pinned] = False
        return np.flatnonzero(m)

    rows = [
        ("KKT assembly (terms scattered)", lambda: kkt.build(terms, g),
         lambda: numpy_kkt_build(kkt, terms, g), np.array_equal),
        ("gauge test (pinned dofs)", lambda: fixes_gauge(X, pinned),
         lambda: numpy_fixes_gauge(X, pinned), lambda a, b: a == b),
        ("free dofs", free_dofs,
         lambda: np.setdiff1d(np.arange(X.size), pinned), np.array_equal),
        ("mean edge length", lambda: mean_edge_length(faces, X),
         lambda: numpy_mean_edge_length(faces, X), lambda a, b: a == b),
        ("energy value and gradient", lambda: energy.value_and_gradient(X), None, None),
        ("Hessian terms (assembly)", lambda: energy.hessian_terms(X), None, None),
    ]
    print(f"{'per call':<34} {'now ms':>9} {'NumPy form ms':>14} {'same bits':>9}")
    for label, now, before, same in rows:
        t_now = process_ms(now, args.repeat)
        if before is None:
            print(f"{label:<34} {t_now:>9.3f} {'':>14} {'':>9}")
            continue
        t_before = process_ms(before, args.repeat)
        equal = "yes" if same(now(), before()) else "NO"
        print(f"{label:<34} {t_now:>9.3f} {t_before:>14.3f} {equal:>9}")

    if linear._load_mkl() is None:
        print("# PARDISO rows skipped: Intel MKL not installed")
        return 0
    data = kkt.build(terms, g)
    upper = kkt.matrix(data, 1e-3 * float(np.abs(kkt.diagonal(data)).mean()))
    b = np.random.default_rng(1).standard_normal(upper.shape[0])

    orderings = Recent(8)  # of the analyses below, by pattern

    def analyse(known: bool):
        if not known:
            orderings.clear()
        solver = pardiso.PardisoSolver(1, "single", refinement=0, orderings=orderings)
        solver._pattern, solver._n = upper, upper.shape[0]
        err = solver._analyse(np.ascontiguousarray(upper.data, dtype=np.float32))
        solver._release()
        if err:
            raise SystemExit(f"PARDISO analysis failed (error {err})")

    repeat = max(3, args.repeat // 5)
    t_metis = process_ms(lambda: analyse(False), repeat)
    t_known = process_ms(lambda: analyse(True), repeat)
    fresh = pardiso.PardisoSolver(1)
    reused = pardiso.PardisoSolver(1, orderings=fresh.orderings)
    fresh.factor(upper, upper=True)
    reused.factor(upper, upper=True)  # its analysis was given fresh's ordering
    same = np.array_equal(fresh.solve(b), reused.solve(b))
    print(f"{'PARDISO analysis, known ordering':<34} {t_known:>9.3f} {t_metis:>14.3f} "
          f"{'yes' if same else 'NO':>9}   (NumPy form: with METIS)")
    single = pardiso.PardisoSolver(1, "single", refinement=0)
    single.factor(upper, upper=True)
    t_factor = process_ms(lambda: single.factor(upper, upper=True), repeat)
    print(f"{'single-precision factorization':<34} {t_factor:>9.3f}")
    t_solve = process_ms(lambda: single.solve(b), args.repeat)
    print(f"{'single-precision solve':<34} {t_solve:>9.3f}")
    print(f"# {args.vertices} vertices, KKT matrix {upper.shape[0]} rows, {upper.nnz} entries in "
          f"its upper triangle; 'same bits': the two forms' results compared exactly")
    pardiso_modes(upper, b, repeat, args.repeat)
    return 0


def pardiso_modes(upper, b, repeat_factor: int, repeat_solve: int) -> None:
    """PARDISO on one thread in its plain mode (the default there) against its reproducible
    mode (``iparm[33] = 1``, the default on several threads), for the factorizations Newton's
    method makes: double precision with Bunch-Kaufman pivots, single precision with 1x1 pivots
    (steps, preconditioners, certificates) and with Bunch-Kaufman pivots."""
    kinds = [("double, Bunch-Kaufman", "double", False), ("single, 1x1", "single", True),
             ("single, Bunch-Kaufman", "single", False)]
    print(f"# PARDISO on one thread, ms: plain mode (now) against reproducible mode\n"
          f"{'factorization':<24} {'factor plain':>12} {'reproducible':>12} {'solve plain':>12} "
          f"{'reproducible':>12}")
    for label, precision, diagonal in kinds:
        row = []
        for reproducible in (False, True):
            solver = pardiso.PardisoSolver(1, precision, refinement=0, diagonal_pivoting=diagonal,
                                          reproducible=reproducible)
            solver.factor(upper, upper=True)
            row.append((process_ms(lambda: solver.factor(upper, upper=True), repeat_factor),
                        process_ms(lambda: solver.solve(b), repeat_solve)))
        (f0, s0), (f1, s1) = row
        print(f"{label:<24} {f0:>12.2f} {f1:>12.2f} {s0:>12.3f} {s1:>12.3f}")


if __name__ == "__main__":
    sys.exit(main())
