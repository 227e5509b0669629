"""Surface Evolver 2.70 and shellbuckle on the same ``.fe`` mesh, moduli, rest state and protocol.

Run from the repository root (Surface Evolver as ``evolver`` on the PATH, Debian/Ubuntu package
``evolver-nox``, or ``--evolver PATH``):

    python benchmarks/bench_evolver.py --vertices 642 --steps 5
    python benchmarks/bench_evolver.py --vertices 3594 --steps 13          # across buckling
    python benchmarks/bench_evolver.py --mesh icosphere --vertices 642 --c0-cycle --steps 3
    python benchmarks/bench_evolver.py --schedule 0.171 0.19 0.209 0.228   # jump near buckling

What it does:

1. builds the mesh (``random_sphere(N, seed)``, the paper's randomized isotropic sphere, or an
   icosphere with ``N = 10 n^2 + 2``) and writes it with ``write_evolver``: rest state = the
   initial sphere (``form_factors``), ``A = gamma kappa / R^2``, ``kappa = 1``, ``c0 = 2/R``
   (Evolver ``h_zero = 1/R``), Poisson ratio ``nu``;
2. runs Surface Evolver on that file, non-interactively (``evolver -x -f CMD FILE``, stdin
   closed). Three vertices pin the rigid motions (``pin_rigid_motions``), as shellbuckle's
   Newton pins six degrees of freedom. For each step ``k`` it sets
   ``body[1].target := V0 (1 - dV/V_k)`` and minimizes with the procedure ``relax`` (see
   ``EVOLVER_RELAX``): one ``g`` step (Lagrange multiplier, projection onto the new volume),
   then Newton steps with ``hessian_normal off`` (all three degrees of freedom of every
   vertex, as the stretching energy needs): ``hessian_seek`` (Newton direction plus a line
   search) until it takes full steps where the Hessian is positive definite, then plain
   ``hessian``, until ``1 + --confirm`` Newton steps in a row change the energy by at most
   ``--etol`` relative; at a stationary point with ``eigenneg > 0`` (the symmetric branch
   past buckling) ``saddle`` steps down along the lowest eigenvector and Newton resumes.
   With ``--c0-cycle``: ``h_zero := 0``, relax, ``h_zero := 1/R``, relax (the paper's
   cycle). No jiggle by default; ``--temperature T`` adds the protocol's jiggle (Surface
   Evolver's scale, the displacements shellbuckle draws for its first attempt at each step,
   written into the command file) before each step's minimization, outside the timed part.
   CPU time per step is Evolver's ``clock`` around the step, wall time is ``date`` before and
   after it;
3. runs ``shellbuckle.run.deflate`` on the same mesh with ``bending="evolver"`` (the same
   discrete energy as Evolver's ``star_perp_sq_mean_curvature``), the same schedule,
   the same jiggle (none by default), the same c0-cycle setting, Newton with its default
   convergence test (relative projected gradient ``--tol``, energy change 1e-10, inertia 0),
   and, where a jiggle folds the mesh, its protocol's new jiggle at half the amplitude (which
   Evolver's side does not have); with ``--rescale`` both sides start each step from the
   shell scaled uniformly to its volume (ours: ``rescale_start``). CPU time per step
   is the process time between the run's per-step log records (step 1 includes the run's
   set-up), wall time is the table's ``wall_s``. Our side runs ``--ours-runs`` times (default
   2), alternately before and after Evolver's run, each in a fresh process that first does
   what this one does before it (the mesh, its volume and rest form factors: Numba's one-time
   start, about 0.2 s, is not in the timed call); its times are their mean, so that a drift of
   the machine's speed during Evolver's minutes-long run cancels (the reference workload is
   measured before and after);
4. checks both final conformations of every step with shellbuckle's energy (total energy,
   relative projected-gradient residual ``|grad E - lam grad V| / |grad E|``), aligns them
   (rotation + translation, Kabsch) and reports the largest vertex distance between them,
   and prints one table side by side plus the CPU and wall-time ratios (Evolver / ours).

Sign convention: shellbuckle reports ``pressure = -dE/dV`` (positive for a deflated shell);
Evolver's ``body[1].pressure`` is the Lagrange multiplier ``+dE/dV``. The table prints
``-body[1].pressure`` in the column ``p_SE`` so that both columns use shellbuckle's sign.

Before buckling both codes minimize the same function from the same state, so they reach
the same minimum (energies to ~1e-13 relative, shapes to round-off). Where the buckled and
the spherical states are both local minima (between the energy crossing and the classical
threshold), and past the threshold, the minimum each code reaches depends on its path (line
searches, how it leaves the unstable symmetric branch), so different local minima are
possible; the ``dx`` column and the shape table (``shellbuckle.analysis.classify``: class,
dents, dent depth, rim radius, angle between the two dent axes) show it.
Current numbers: ``docs/surface-evolver.md``; every measurement and its reading:
``benchmarks/results/evolver_comparison_history.md``.

**Time to the same tolerance** (``--to-tolerance``, with ``--confirm 1``). The two codes stop
on different tests: shellbuckle on its relative projected-gradient residual (``--tol``, 1e-9),
Evolver on the energy change of its Newton steps (``--etol``). Before buckling Evolver's test
stops at residuals of 1e-11 to 1e-13 (on 14 meshes of 3594 vertices, at exactly the first
Newton iterate within shellbuckle's tolerance), after it can stop early (residuals up to 1e-4,
where the dent still creeps). With ``--to-tolerance`` Evolver records every
iterate of ``relax`` (energy, ``eigenneg``, CPU time, positions; the recording itself is left
out of its times), and :func:`time_to_tolerance` finds in each relax the first Newton iterate
that passes shellbuckle's own test (residual, energy change 1e-10, no negative eigenvalue)
computed by shellbuckle on Evolver's conformation: Evolver's time to that iterate is its time to
the same tolerance; a relax that never passes keeps its whole time (in Evolver's favour). The
table then also prints that time's ratio per step and in total.

``--json FILE`` writes everything measured (both sides' per-step records, timings, versions).
``--keep DIR`` keeps the datafile, the generated command file, Evolver's output and both
sides' positions in DIR (by default they live in a temporary folder that is removed).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import logging  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
import platform  # noqa: E402
import re  # noqa: E402
import resource  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import shellbuckle  # noqa: E402
from shellbuckle.energies.total import ShellEnergy  # noqa: E402
from shellbuckle.energies.volume import Volume  # noqa: E402
from shellbuckle.mesh import icosphere, random_sphere  # noqa: E402
from shellbuckle.mesh.evolver_io import write_evolver  # noqa: E402
from shellbuckle.params import ShellParameters  # noqa: E402
from shellbuckle.protocol.jiggle import evolver_sigma, jiggle, step_rng  # noqa: E402
from shellbuckle.run import deflate  # noqa: E402
from shellbuckle.solve.linesearch import projected_gradient  # noqa: E402
from shellbuckle.store.run import source_commit  # noqa: E402

from machine import describe, reference, reference_line  # noqa: E402  (benchmarks/machine.py)

EVOLVER_RELAX = r"""
// relax(etol, confirm, maxit): minimize the energy at the current target volume.
// One g step (Lagrange multiplier, projection onto the target volume), then Newton steps on
// all vertex degrees of freedom (hessian_normal off): hessian_seek (Newton direction plus a
// line search) until a seek takes a full step (scale within 10 % of 1) from a point where
// the factored Hessian is positive definite (eigenneg = 0) and changes the energy by at most
// 1e-6 relative, then plain hessian steps (back to hessian_seek if one raises the energy).
// Plain Newton steps taken earlier (a full seek step alone is not enough) can throw the shell
// far away near buckling: at 3594 vertices, gamma = 271, dV/V = 0.19 they ended at 9 times
// the energy after 300 steps.
// Converged after 1 + confirm consecutive plain Newton steps that each change the energy by
// at most etol relative, with eigenneg = 0. (The energy change cannot see a relative
// gradient residual below ~1e-8; confirm = 1 takes the residual to round-off.)
// At a stationary point with eigenneg > 0, saddle moves down along the lowest eigenvector;
// if that lowers the energy by less than etol relative (a zero mode), the point is accepted.
procedure relax(real etol, integer confirm, integer maxit)
{
  local e_old, de, polish, e_sad, small;
  SBX_BEGIN
  g 1;
  SBX_SNAP(0)
  relax_g := relax_g + 1;
  polish := 0;
  small := 0;
  relax_ok := 0;
  relax_local := 0;
  while relax_local < maxit do {
    e_old := total_energy;
    if polish then hessian else hessian_seek;
    SBX_SNAP(2 - polish)
    relax_newton := relax_newton + 1;
    relax_local := relax_local + 1;
    de := e_old - total_energy;
    if polish then {
      if abs(de) <= etol*abs(total_energy) then {
        small := small + 1;
        if eigenneg == 0 then {
          if small > confirm then { relax_ok := 1; break };
        } else {
          e_sad := total_energy;
          saddle;
          SBX_SNAP(3)
          relax_saddles := relax_saddles + 1;
          relax_local := relax_local + 1;
          small := 0;
          polish := 0;
          if e_sad - total_energy <= etol*abs(total_energy) then { relax_ok := 1; break };
        };
      } else {
        small := 0;
        if de < 0 then polish := 0;
      };
    } else {
      if last_hessian_scale == 0 or abs(de) <= etol*abs(total_energy) then {
        if eigenneg > 0 then {
          e_sad := total_energy;
          saddle;
          SBX_SNAP(3)
          relax_saddles := relax_saddles + 1;
          relax_local := relax_local + 1;
          if e_sad - total_energy <= etol*abs(total_energy) then polish := 1;
        } else polish := 1;
      } else if last_hessian_scale > 0.9 and last_hessian_scale < 1.1 and eigenneg == 0
                and abs(de) <= 1e-6*abs(total_energy) then polish := 1;
    };
  };
  SBX_END
}
"""

EVOLVER_SNAPSHOT = r"""
// sbx_snap(kind): after each iteration of relax (0 g, 1 hessian, 2 hessian_seek, 3 saddle),
// print its energy, eigenneg and CPU time since the step began, and write the positions to
// snap_<n>.txt; the time this takes is left out of the step's time (sbx_excl).
procedure sbx_snap(integer kind)
{
  local t_in;
  t_in := clock;
  sbx_n := sbx_n + 1;
  printf "SBX_SNAP %d %d %d %d %.17g %.6f %d\n", sbx_n, sbx_step, sbx_relax, kind, total_energy,
         t_in - sbx_t0 - sbx_excl, eigenneg;
  { foreach vertex do printf "%d %.17g %.17g %.17g\n", id, x, y, z }
    >>> sprintf "snap_%d.txt", sbx_n;
  sbx_excl := sbx_excl + (clock - t_in);
}
"""

TRACE_MARKERS = {
    "SBX_BEGIN": ('sbx_relax := sbx_relax + 1;\n  printf "SBX_RELAX %d %d %.6f\\n", sbx_step, '
                  "sbx_relax, clock - sbx_t0 - sbx_excl;"),
    "SBX_END": ('printf "SBX_RELAX_END %d %d %.6f\\n", sbx_step, sbx_relax, '
                "clock - sbx_t0 - sbx_excl;"),
}


def relax_procedure(trace: bool) -> str:
    """:data:`EVOLVER_RELAX` with its tracing markers filled in (``trace``: every iteration
    recorded by ``sbx_snap``, relax start and end times printed) or removed."""
    lines = []
    for line in EVOLVER_RELAX.splitlines():
        marker = line.strip()
        if marker in TRACE_MARKERS or marker.startswith("SBX_SNAP("):
            if trace:
                indent = line[:len(line) - len(line.lstrip())]
                text = (TRACE_MARKERS[marker] if marker in TRACE_MARKERS
                        else "sbx_snap" + marker[len("SBX_SNAP"):] + ";")
                lines.append(indent + text)
            continue
        lines.append(line)
    return "\n".join(lines)


STEP_FIELDS = ("step", "target", "E_total", "E_stretch", "E_bend", "volume", "body_pressure",
               "E_before_c0_cycle", "newton", "saddles", "g", "eigenneg", "converged", "cpu_s")


def build_mesh(kind: str, n_vertices: int, seed: int):
    if kind == "icosphere":
        n = int(round(math.sqrt((n_vertices - 2) / 10.0)))
        if n < 1 or 10 * n * n + 2 != n_vertices:
            raise SystemExit(f"--mesh icosphere needs --vertices = 10 n^2 + 2 (12, 42, 92, 162, "
                             f"252, 362, 492, 642, ...), got {n_vertices}")
        return icosphere(n)
    return random_sphere(n_vertices, seed=seed)


def rest_form_factors(X: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Evolver's ``form_factors (s11, s12, s22)`` of the rest shape ``X`` in face vertex order."""
    x = X[faces]
    e1, e2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    return np.stack([(e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)], axis=1)


def pin_rigid_motions(fe: Path, X: np.ndarray) -> tuple[int, int, int]:
    """Remove the six rigid motions from Evolver's problem, as shellbuckle's Newton does.

    With ``hessian_normal off`` Evolver's Hessian is singular along translations and
    rotations; away from equilibrium the rotational directions come out slightly negative
    (``Hessian not positive definite. Index: 3``) and at a minimum ``eigenneg`` counts them
    at random, which makes ``saddle`` chase zero modes. Pinning a gauge does not change the
    minimum energy (it is invariant under rigid motions): vertex ``a`` is ``fixed``, vertex
    ``b`` (the farthest from ``a``) moves on the line through ``a`` and ``b`` (constraints 1
    and 2), vertex ``c`` (the farthest from that line) in the plane through ``a``, ``b``,
    ``c`` (constraint 2). The planes are ``nonwall`` constraints: the star curvature methods
    would otherwise treat them as mirror planes (they only act on incomplete stars anyway).
    Returns the 0-based ``(a, b, c)``.
    """
    a = int(np.argmax(X[:, 2]))
    b = int(np.argmax(np.linalg.norm(X - X[a], axis=1)))
    u = (X[b] - X[a]) / np.linalg.norm(X[b] - X[a])
    off = (X - X[a]) - np.outer((X - X[a]) @ u, u)
    c = int(np.argmax(np.linalg.norm(off, axis=1)))
    n1 = off[c] / np.linalg.norm(off[c])  # both planes contain the line ab
    n2 = np.cross(u, n1)                   # this one also contains c
    text = fe.read_text().splitlines()
    at = text.index("vertices")
    decl = []
    for k, n in enumerate((n1, n2), start=1):
        decl += [f"constraint {k} nonwall",
                 f"formula: ({float(n[0])!r})*x + ({float(n[1])!r})*y + ({float(n[2])!r})*z = "
                 f"{float(n @ X[a])!r}", ""]
    for v, extra in ((a, " fixed"), (b, " constraint 1 2"), (c, " constraint 2")):
        line = text[at + 1 + v]
        if not line.startswith(f"{v + 1} "):
            raise RuntimeError(f"unexpected vertex line {line!r} in {fe}")
        text[at + 1 + v] = line + extra
    fe.write_text("\n".join(text[:at] + decl + text[at:]) + "\n")
    return a, b, c


def evolver_commands(schedule, V0: float, h_zero: float, c0_cycle: bool, etol: float,
                     confirm: int, maxit: int, hessian_normal: bool = False,
                     jiggles=None, fixed: int | None = None, trace: bool = False,
                     rescale: bool = False) -> str:
    """The Evolver command file: the relax procedure and one block per volume step.

    ``hessian_normal=True`` keeps Evolver's default ``hessian_normal on`` (Newton steps only
    along the vertex normals), which cannot relax the in-plane stretching: shown for reference.
    ``jiggles``: per step a ``(V, 3)`` displacement added to every vertex but the ``fixed``
    one (0-based) before the step's minimization, outside the timed part (the protocol's
    jiggle with shellbuckle's random numbers, :func:`jiggle_displacements`).
    ``trace``: record every iteration of ``relax`` (:data:`EVOLVER_SNAPSHOT`) for
    :func:`time_to_tolerance`; the recording is left out of the steps' times.
    ``rescale``: before each step's minimization (inside its time) the shell is scaled
    uniformly about the ``fixed`` vertex to the step's volume, so that Evolver's projection
    onto the new volume (along the volume gradient, proportional to each vertex's area) has
    nothing left to do: on a randomized mesh that projection makes the radial displacement
    as uneven as the vertex areas, a strain that grows as the edges shrink (at 10000 vertices
    the first step's projection alone raises the energy from 0.09 to 38.5, the minimum being
    0.21). The scaling keeps the pinned gauge (the line and the plane pass through the fixed
    vertex). Not the paper's protocol; a start in Evolver's favour.
    """
    if rescale and fixed is None:
        raise ValueError("rescale needs the fixed vertex")
    lines = ["// Generated by benchmarks/bench_evolver.py",
             "relax_newton := 0", "relax_saddles := 0", "relax_g := 0", "relax_ok := 0",
             "relax_local := 0", "sbx_n := 0", "sbx_step := 0", "sbx_relax := 0",
             "sbx_excl := 0", "sbx_t0 := clock"]
    if trace:
        lines.append(EVOLVER_SNAPSHOT)
    lines += [relax_procedure(trace), "quiet on",
             f"hessian_normal {'on' if hessian_normal else 'off'}", f"V0 := {V0!r}"]
    fmt = " ".join(["%d", "%.17g"] + ["%.17g"] * 6 + ["%d"] * 5 + ["%.6f"])
    for k, target in enumerate(schedule, start=1):
        if jiggles is not None:
            lines.append(f"// step {k}: the jiggle")
            for v, d in enumerate(jiggles[k - 1]):
                if v != fixed:
                    lines += [f"vertex[{v + 1}].{axis} := vertex[{v + 1}].{axis} + {float(c)!r}"
                              for axis, c in zip("xyz", d)]
        lines += [
            f"// step {k}: dV/V = {target!r}",
            'system "date +SBX_WALL_START_%s.%N"',
            "relax_newton := 0", "relax_saddles := 0", "relax_g := 0",
            f"sbx_step := {k}", "sbx_relax := 0", "sbx_excl := 0",
            "sbx_t0 := clock",
        ]
        if rescale:
            a = f"vertex[{fixed + 1}]"
            lines += [f"sbx_f := (V0 * (1 - {target!r}) / body[1].volume)^(1/3)",
                      f"sbx_ax := {a}.x", f"sbx_ay := {a}.y", f"sbx_az := {a}.z",
                      "set vertex x sbx_ax + sbx_f * (x - sbx_ax)",
                      "set vertex y sbx_ay + sbx_f * (y - sbx_ay)",
                      "set vertex z sbx_az + sbx_f * (z - sbx_az)", "recalc"]
        lines += [
            f"body[1].target := V0 * (1 - {target!r})",
            f"relax({etol!r}, {confirm}, {maxit})",
            "sbx_ok := relax_ok",
            "sbx_before := total_energy",
        ]
        if c0_cycle:
            lines += ["h_zero := 0", "recalc", f"relax({etol!r}, {confirm}, {maxit})",
                      "sbx_ok := sbx_ok * relax_ok",
                      f"h_zero := {h_zero!r}", "recalc", f"relax({etol!r}, {confirm}, {maxit})",
                      "sbx_ok := sbx_ok * relax_ok"]
        lines += [
            "sbx_cpu := clock - sbx_t0 - sbx_excl",
            f'printf "SBX_EXCL {k} %.6f\\n", sbx_excl',
            'system "date +SBX_WALL_END_%s.%N"',
            f'printf "SBX_STEP {fmt}\\n", {k}, {target!r}, total_energy, stretching.value, '
            "bending.value, body[1].volume, body[1].pressure, sbx_before, relax_newton, "
            "relax_saddles, relax_g, eigenneg, sbx_ok, sbx_cpu",
            f'{{ foreach vertex do printf "%d %.17g %.17g %.17g\\n", id, x, y, z }} >>> '
            f'"evolver_step{k}.txt"',
        ]
    lines += ["quit", ""]
    return "\n".join(lines)


def jiggle_displacements(X0: np.ndarray, temperature: float, seed: int, n_steps: int):
    """The displacements the protocol's jiggle adds at steps ``1 .. n_steps`` (first attempt):
    Surface Evolver's scale at ``temperature`` on the initial mesh ``X0``, the protocol's random
    stream of each step (:mod:`shellbuckle.protocol.jiggle`)."""
    sigma = evolver_sigma(temperature, X0)
    return [jiggle(np.zeros_like(X0), sigma, step_rng(seed, k)) for k in range(1, n_steps + 1)]


def run_evolver(evolver: str, workdir: Path, fe: Path, cmd: Path, timeout: float) -> dict:
    """Run Evolver, parse its per-step lines; positions are read from the files it wrote."""
    log_path = workdir / "evolver.log"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    with open(log_path, "w") as log_file:
        proc = subprocess.run([evolver, "-x", "-f", cmd.name, fe.name], cwd=workdir,
                              stdin=subprocess.DEVNULL, stdout=log_file,
                              stderr=subprocess.STDOUT, timeout=timeout)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    text = log_path.read_text(errors="replace")
    steps, starts, ends = [], [], []
    excluded, relaxes = {}, {}  # per step: the recording's CPU time; (step, relax): its record
    for line in text.splitlines():
        if line.startswith("SBX_SNAP "):
            n, step, relax, kind, energy, t, neg = line.split()[1:8]
            relaxes[(int(step), int(relax))]["snaps"].append(
                {"n": int(n), "kind": int(kind), "E": float(energy), "t": float(t),
                 "eigenneg": int(neg)})
        elif line.startswith("SBX_RELAX "):
            step, relax, t = line.split()[1:4]
            relaxes[(int(step), int(relax))] = {"relax": int(relax), "t_start": float(t),
                                                "t_end": math.nan, "snaps": []}
        elif line.startswith("SBX_RELAX_END "):
            step, relax, t = line.split()[1:4]
            relaxes[(int(step), int(relax))]["t_end"] = float(t)
        elif line.startswith("SBX_EXCL "):
            step, t = line.split()[1:3]
            excluded[int(step)] = float(t)
        elif line.startswith("SBX_STEP "):
            values = line.split()[1:]
            steps.append({name: (int(v) if name in ("step", "newton", "saddles", "g", "eigenneg",
                                                     "converged") else float(v))
                          for name, v in zip(STEP_FIELDS, values)})
        elif line.startswith("SBX_WALL_START_"):
            starts.append(float(line[len("SBX_WALL_START_"):]))
        elif line.startswith("SBX_WALL_END_"):
            ends.append(float(line[len("SBX_WALL_END_"):]))
    if proc.returncode != 0 or not steps:
        tail = "\n".join(text.splitlines()[-30:])
        raise RuntimeError(f"Surface Evolver exited with code {proc.returncode} after "
                           f"{len(steps)} steps; last output:\n{tail}")
    for rec, t_start, t_end in zip(steps, starts, ends):
        rec["wall_s"] = t_end - t_start
        rec["X"] = read_positions(workdir / f"evolver_step{rec['step']}.txt")
        rec["excluded_s"] = excluded.get(rec["step"], 0.0)
        rec["relaxes"] = [relaxes[key] for key in sorted(relaxes) if key[0] == rec["step"]]
    version = subprocess.run([evolver, "-V"], stdin=subprocess.DEVNULL, capture_output=True,
                             text=True).stdout.splitlines()
    return {"steps": steps, "process_wall_s": wall,
            "process_cpu_s": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
            "version": version[0].strip() if version else "unknown",
            "warnings": len(re.findall(r"Hessian not positive definite", text))}


def read_positions(path: Path) -> np.ndarray:
    """Positions ``(V, 3)`` from a file of ``id x y z`` lines that Evolver wrote (a step's end
    state or an ``sbx_snap`` snapshot), in the order of Evolver's vertex ids."""
    data = np.array(path.read_text().split(), dtype=float).reshape(-1, 4)
    X = np.empty((len(data), 3))
    X[data[:, 0].astype(int) - 1] = data[:, 1:]
    return X


def time_to_tolerance(step: dict, energies: list, volume: Volume, workdir: Path, tol: float,
                      atol: float = 1e-10, etol: float = 1e-10) -> dict:
    """Evolver's CPU time to shellbuckle's convergence test in one step, from its trace.

    In each ``relax`` of the step (``energies[i]``: shellbuckle's energy of the i-th, with
    its ``c0``), the first Newton iterate (``hessian`` or ``hessian_seek``) that passes the
    test shellbuckle's Newton stops on: relative projected-gradient residual
    ``|grad E - lam grad V| <= tol |grad E| + atol``, energy change of that iteration at most
    ``etol |E|``, and no negative eigenvalue (``eigenneg = 0`` of the Hessian Evolver factored
    for it). The time Evolver spends after that iterate in the same relax (polishing further,
    confirming its own energy test) is not needed for that tolerance and is taken off the
    step's time; a relax that never passes (it stopped on its own test first) keeps its whole
    time. Returns ``cpu_s`` (the step's time to tolerance), ``over_s`` (the time taken off) and
    per relax the iterate that passed (``hit``, its number in the relax, 0 the ``g`` step; or
    ``None``), its residual, the number of iterates, the relax's start and end times and its
    ``trace``: per iterate ``[kind (0 g, 1 hessian, 2 hessian_seek, 3 saddle), energy, CPU time
    since the step began, eigenneg]``."""
    out, over = [], 0.0
    for relax, energy in zip(step["relaxes"], energies):
        hit, residual, previous = None, math.nan, None
        for i, snap in enumerate(relax["snaps"]):
            small = previous is not None and abs(snap["E"] - previous) <= etol * abs(snap["E"])
            previous = snap["E"]
            if snap["kind"] not in (1, 2) or snap["eigenneg"] != 0 or not small:
                continue
            X = read_positions(workdir / f"snap_{snap['n']}.txt")
            gE = energy.gradient(X)
            _, r = projected_gradient(gE, volume.gradient(X))
            r_norm, g_norm = float(np.linalg.norm(r)), float(np.linalg.norm(gE))
            if r_norm <= tol * g_norm + atol:
                hit, residual = i, r_norm / g_norm
                over += relax["t_end"] - snap["t"]
                break
        out.append({"relax": relax["relax"], "hit": hit, "residual": residual,
                    "iterates": len(relax["snaps"]), "t_start": relax["t_start"],
                    "t_end": relax["t_end"],
                    "trace": [[x["kind"], x["E"], x["t"], x["eigenneg"]] for x in relax["snaps"]]})
    return {"cpu_s": step["cpu_s"] - over, "over_s": over, "relaxes": out}


class _StepClock(logging.Handler):
    """Process CPU time at each per-step record of :func:`shellbuckle.run.deflate`."""

    def __init__(self):
        super().__init__(logging.INFO)
        self.marks = []

    def emit(self, record):
        if record.name == "shellbuckle.run" and record.msg.startswith("step "):
            self.marks.append((int(record.args[0]), time.process_time()))


def run_ours(mesh, params, schedule, c0_cycle: bool, tol: float, out: Path,
             temperature: float = 0.0, seed: int = 0, rescale: bool = False) -> dict:
    clock = _StepClock()
    run_logger = logging.getLogger("shellbuckle.run")
    old_level = run_logger.level
    run_logger.setLevel(logging.INFO)
    run_logger.addHandler(clock)
    try:
        cpu0, wall0 = time.process_time(), time.perf_counter()
        run = deflate(mesh, params, schedule=list(schedule), c0_cycle=c0_cycle,
                      temperature=temperature, seed=seed, bending="evolver", tol=tol,
                      stop_at_contact=False, out=out, rescale_start=rescale)
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    finally:
        run_logger.removeHandler(clock)
        run_logger.setLevel(old_level)
    table = run.table
    marks = dict(clock.marks)
    steps, previous = [], cpu0
    for k in range(1, len(schedule) + 1):
        row = table.loc[table["step"] == k].iloc[0]
        rec = {name: row[name].item() if hasattr(row[name], "item") else row[name]
               for name in ("step", "target_dV_over_V", "dV_over_V", "E_total", "E_stretch",
                            "E_bend", "E_before_c0_cycle", "pressure", "grad_norm",
                            "iterations", "inertia", "converged", "wall_s")}
        rec["cpu_s"] = marks.get(k, math.nan) - previous
        previous = marks.get(k, math.nan)
        rec["X"] = run.positions(k)
        steps.append(rec)
    return {"steps": steps, "total_cpu_s": cpu, "total_wall_s": wall}


def _ours_in_child(mesh_kind: str, vertices: int, mesh_seed: int, gamma: float, nu: float,
                   schedule, c0_cycle: bool, tol: float, out: str, temperature: float,
                   jiggle_seed: int, rescale: bool = False) -> dict:
    """:func:`run_ours` in a fresh process (``multiprocessing`` spawn), after the same work the
    benchmark's own process does before it (the mesh, its volume and rest form factors, which
    also start Numba), so that every run of our side starts from the same state."""
    mesh = build_mesh(mesh_kind, vertices, mesh_seed)
    Volume(mesh.faces, mesh.n_vertices).value(mesh.X)
    rest_form_factors(mesh.X, mesh.faces)
    return run_ours(mesh, ShellParameters.from_gamma(gamma, nu=nu), schedule, c0_cycle, tol,
                    Path(out), temperature, jiggle_seed, rescale)


def mean_of_runs(runs: list[dict]) -> dict:
    """One result from several runs of our side on the same problem: the first run's records
    (the runs are deterministic; a run whose energies differ is refused) with the CPU and wall
    times averaged per step and in total, and each run's totals in ``runs_cpu_s``."""
    first = runs[0]
    for other in runs[1:]:
        if [s["E_total"] for s in other["steps"]] != [s["E_total"] for s in first["steps"]]:
            raise SystemExit("two runs of shellbuckle on the same problem ended at different "
                             "energies; their times are not comparable")
    steps = []
    for k, step in enumerate(first["steps"]):
        row = dict(step)
        row["cpu_s"] = float(np.mean([r["steps"][k]["cpu_s"] for r in runs]))
        row["wall_s"] = float(np.mean([r["steps"][k]["wall_s"] for r in runs]))
        row["cpu_s_runs"] = [r["steps"][k]["cpu_s"] for r in runs]
        steps.append(row)
    return {"steps": steps, "total_cpu_s": float(np.mean([r["total_cpu_s"] for r in runs])),
            "total_wall_s": float(np.mean([r["total_wall_s"] for r in runs])),
            "runs_cpu_s": [r["total_cpu_s"] for r in runs]}


def kabsch(A: np.ndarray, B: np.ndarray) -> tuple[float, np.ndarray]:
    """Best rotation ``R`` (``A @ R ~ B`` after centring, Kabsch) and the largest vertex
    distance between the aligned ``A`` and ``B``."""
    a, b = A - A.mean(0), B - B.mean(0)
    U, _, Vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(U @ Vt))
    R = U @ np.diag([1.0, 1.0, d]) @ Vt
    return float(np.linalg.norm(a @ R - b, axis=1).max()), R


def check(energy: ShellEnergy, volume: Volume, X: np.ndarray) -> dict:
    """Our energy, relative projected-gradient residual and volume at positions ``X``."""
    gE = energy.gradient(X)
    _, r = projected_gradient(gE, volume.gradient(X))
    return {"E": energy.value(X), "residual": float(np.linalg.norm(r) / np.linalg.norm(gE)),
            "V": volume.value(X)}


def source_version() -> str:
    """shellbuckle's version and, in a git checkout, its commit (``+dirty`` if src/ differs)."""
    commit = source_commit()
    return f"{shellbuckle.__version__} (git {commit})" if commit else shellbuckle.__version__


def shape_rows(faces, se_steps, our_steps) -> list[dict] | None:
    """Shape class, dents, dent depth and the angle between the two dent axes (after the
    rigid alignment of the two conformations), per step (``shellbuckle.analysis.classify``);
    ``None`` if that module cannot be imported."""
    try:
        from shellbuckle.analysis.classify import classify
    except ImportError as exc:
        print(f"# shapes not classified: {exc}")
        return None
    rows = []
    for e, o in zip(se_steps, our_steps):
        ce, co = classify(e["X"], faces), classify(o["X"], faces)
        R = kabsch(e["X"], o["X"])[1]
        rotation = math.degrees(math.acos(float(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))
        angle = math.nan
        if ce.dent_axis is not None and co.dent_axis is not None:
            cos = float(np.clip(np.dot(np.asarray(ce.dent_axis) @ R, co.dent_axis), -1.0, 1.0))
            angle = math.degrees(math.acos(cos))
        rows.append({"step": o["step"], "shape_SE": ce.shape, "shape_ours": co.shape,
                     "dents_SE": ce.n_dimples, "dents_ours": co.n_dimples,
                     "depth_SE": ce.dent_depth, "depth_ours": co.dent_depth,
                     "rim_SE": ce.rim_radius, "rim_ours": co.rim_radius,
                     "axis_angle_deg": angle, "rigid_rotation_deg": rotation})
    return rows


def _finite_or_none(value):
    """JSON-safe copy: non-finite floats become ``null``."""
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vertices", type=int, default=642)
    ap.add_argument("--mesh", choices=("random", "icosphere"), default="random",
                    help="random_sphere (the paper's randomized mesh) or icosphere")
    ap.add_argument("--seed", type=int, default=0, help="random_sphere seed")
    ap.add_argument("--gamma", type=float, default=271.0)
    ap.add_argument("--nu", type=float, default=1.0 / 3.0)
    ap.add_argument("--dv", type=float, default=0.019, help="volume step dV/V0")
    ap.add_argument("--steps", type=int, default=5, help="number of volume steps of --dv")
    ap.add_argument("--schedule", type=float, nargs="+",
                    help="target dV/V of each step (instead of --dv/--steps)")
    ap.add_argument("--c0-cycle", action="store_true",
                    help="the paper's c0 -> 0 -> 2/R cycle at each step, on both sides")
    ap.add_argument("--temperature", type=float, default=0.0,
                    help="the protocol's jiggle at this Surface Evolver temperature (0.05 is the "
                         "paper's) on both sides, with the same random displacements; default 0: "
                         "no jiggle")
    ap.add_argument("--jiggle-seed", type=int, default=0, help="seed of the jiggle")
    ap.add_argument("--tol", type=float, default=1e-9,
                    help="shellbuckle's relative projected-gradient tolerance (protocol default)")
    ap.add_argument("--etol", type=float, default=1e-10,
                    help="Evolver: stop when a Newton step changes the energy by <= etol |E|")
    ap.add_argument("--confirm", type=int, default=0,
                    help="Evolver: extra plain Newton steps after the energy test is met (0: "
                         "residuals comparable to shellbuckle's tolerance; 1: near round-off)")
    ap.add_argument("--maxit", type=int, default=300, help="Evolver: Newton/saddle steps per relax")
    ap.add_argument("--to-tolerance", action="store_true",
                    help="also measure Evolver's CPU time to shellbuckle's convergence test: every "
                         "iterate of Evolver's relax is recorded (outside its timed part) and "
                         "tested with shellbuckle's residual, and the time Evolver spends after "
                         "the first iterate that passes is not counted (time_to_tolerance); use "
                         "with --confirm 1, so that Evolver goes on where its energy test stops "
                         "early")
    ap.add_argument("--hessian-normal", action="store_true",
                    help="Evolver: keep its default hessian_normal on (normal motion only; for "
                         "reference, it cannot relax in-plane stretching)")
    ap.add_argument("--no-pin", action="store_true",
                    help="Evolver: do not pin the rigid motions (see pin_rigid_motions)")
    ap.add_argument("--rescale", action="store_true",
                    help="both sides start each step from the shell scaled uniformly to its "
                         "volume (Evolver: see evolver_commands; ours: --rescale-start)")
    ap.add_argument("--evolver", default="evolver")
    ap.add_argument("--timeout", type=float, default=6 * 3600.0, help="Evolver time limit (s)")
    ap.add_argument("--ours-runs", type=int, default=2,
                    help="runs of shellbuckle, each in a fresh process, alternately before and "
                         "after Surface Evolver's (the first before); its times are their mean "
                         "(default 2: the machine's drift during Evolver's run cancels)")
    ap.add_argument("--json", type=Path, help="write all measurements to this JSON file")
    ap.add_argument("--keep", type=Path, help="keep the working files in this folder")
    args = ap.parse_args(argv)
    if args.rescale and args.no_pin:
        ap.error("--rescale scales about the pinned vertex; it cannot go with --no-pin")
    if args.ours_runs < 1:
        raise SystemExit(f"--ours-runs must be at least 1, got {args.ours_runs}")

    evolver = shutil.which(args.evolver)
    if evolver is None:
        raise SystemExit(f"Surface Evolver not found as {args.evolver!r} (Debian/Ubuntu: "
                         "apt-get install evolver-nox; or give --evolver PATH)")
    if args.schedule is not None:
        schedule = [float(s) for s in args.schedule]
    else:
        schedule = [args.dv * k for k in range(1, args.steps + 1)]
    if not all(0.0 < s < 1.0 for s in schedule):
        raise SystemExit(f"every target dV/V must be in (0, 1), got {schedule}")

    params = ShellParameters.from_gamma(args.gamma, nu=args.nu)
    c0 = 2.0 / params.R
    t = time.perf_counter()
    mesh = build_mesh(args.mesh, args.vertices, args.seed)
    t_mesh = time.perf_counter() - t
    volume = Volume(mesh.faces, mesh.n_vertices)
    V0 = volume.value(mesh.X)
    ff = rest_form_factors(mesh.X, mesh.faces)

    workdir = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench_evolver_"))
    workdir.mkdir(parents=True, exist_ok=True)
    try:
        fe = write_evolver(workdir / "shell.fe", mesh, kappa=params.kappa, c0=c0, A=params.A,
                           nu=params.nu, form_factors=ff, volume=V0,
                           title=f"bench_evolver: {args.mesh} {mesh.n_vertices} vertices, "
                                 f"gamma = {args.gamma:g}, nu = {args.nu:.6g}")
        pinned = None if args.no_pin else pin_rigid_motions(fe, mesh.X)
        cmd = workdir / "protocol.cmd"
        jiggles = (jiggle_displacements(mesh.X, args.temperature, args.jiggle_seed, len(schedule))
                   if args.temperature > 0 else None)
        cmd.write_text(evolver_commands(schedule, V0, 0.5 * c0, args.c0_cycle, args.etol,
                                        args.confirm, args.maxit, args.hessian_normal,
                                        jiggles, None if pinned is None else pinned[0],
                                        trace=args.to_tolerance, rescale=args.rescale))
        print(f"# mesh: {args.mesh}, {mesh.n_vertices} vertices, {len(mesh.faces)} faces "
              f"(built in {t_mesh:.1f} s); gamma = {args.gamma:g}, nu = {args.nu:.6g}, kappa = 1, "
              f"c0 = 2/R; {len(schedule)} steps, c0 cycle {'on' if args.c0_cycle else 'off'}, "
              + (f"jiggle at temperature {args.temperature:g} (seed {args.jiggle_seed})"
                 if args.temperature > 0 else "no jiggle"), flush=True)
        machine, ref = describe(), reference()
        print(f"# {machine}\n# {reference_line(ref)}", flush=True)
        print("# Evolver rigid-motion gauge: " + ("none (--no-pin)" if pinned is None else
              "vertex {} fixed, {} on a line, {} in a plane (Evolver ids)".format(
                  *(v + 1 for v in pinned))), flush=True)
        spawn = multiprocessing.get_context("spawn")
        runs = []

        def ours_run():
            child = (args.mesh, args.vertices, args.seed, args.gamma, args.nu, schedule,
                     args.c0_cycle, args.tol, str(workdir / f"run{len(runs)}"),
                     args.temperature, args.jiggle_seed, args.rescale)
            with spawn.Pool(1) as pool:
                runs.append(pool.apply(_ours_in_child, child))
            print(f"# shellbuckle run {len(runs)}: {runs[-1]['total_wall_s']:.1f} s wall, "
                  f"{runs[-1]['total_cpu_s']:.2f} s CPU (whole deflate call)", flush=True)

        for _ in range((args.ours_runs + 1) // 2):
            ours_run()
        se = run_evolver(evolver, workdir, fe, cmd, args.timeout)
        print(f"# Surface Evolver done: {se['process_wall_s']:.1f} s wall, "
              f"{se['process_cpu_s']:.1f} s CPU (whole process)", flush=True)
        tolerance = None
        if args.to_tolerance:
            by_c0 = {c: ShellEnergy.build(mesh, params, bending="evolver", c0=c, form_factors=ff)
                     for c in (c0, 0.0)}
            energies = [by_c0[c0], by_c0[0.0], by_c0[c0]] if args.c0_cycle else [by_c0[c0]]
            tolerance = [time_to_tolerance(e, energies, volume, workdir, args.tol)
                         for e in se["steps"]]
            if not args.keep:  # ~250 kB each at 3594 vertices, hundreds per run
                for snapshot in workdir.glob("snap_*.txt"):
                    snapshot.unlink()
        for _ in range(args.ours_runs // 2):
            ours_run()
        ours = mean_of_runs(runs)
        ref_after = reference()
        print(f"# after: {reference_line(ref_after)}", flush=True)
    finally:
        if not args.keep:
            shutil.rmtree(workdir, ignore_errors=True)

    energy = ShellEnergy.build(mesh, params, bending="evolver", c0=c0, form_factors=ff)
    rows = []
    for e, o in zip(se["steps"], ours["steps"]):
        ce, co = check(energy, volume, e["X"]), check(energy, volume, o["X"])
        rows.append({
            "step": o["step"], "target": o["target_dV_over_V"],
            "dV_SE": 1.0 - e["volume"] / V0, "dV_ours": o["dV_over_V"],
            "Es_SE": e["E_stretch"], "Es_ours": o["E_stretch"],
            "Eb_SE": e["E_bend"], "Eb_ours": o["E_bend"],
            "E_SE": e["E_total"], "E_ours": o["E_total"],
            "rel_dE": (e["E_total"] - o["E_total"]) / abs(o["E_total"]),
            "p_SE": -e["body_pressure"], "p_ours": o["pressure"],
            "it_SE": e["newton"] + e["saddles"] + e["g"], "saddles_SE": e["saddles"],
            "it_ours": o["iterations"], "neg_SE": e["eigenneg"], "neg_ours": o["inertia"],
            "res_SE": ce["residual"], "res_ours": co["residual"],
            "E_SE_by_ours": ce["E"], "dx": kabsch(e["X"], o["X"])[0],
            "cpu_SE": e["cpu_s"], "cpu_ours": o["cpu_s"], "cpu_ours_runs": o["cpu_s_runs"],
            "wall_SE": e["wall_s"], "wall_ours": o["wall_s"],
            "converged_SE": bool(e["converged"]), "converged_ours": bool(o["converged"]),
        })
        if tolerance is not None:
            t = tolerance[len(rows) - 1]
            rows[-1].update({"cpu_SE_tol": t["cpu_s"], "over_SE": t["over_s"],
                             "excluded_SE": e["excluded_s"], "relaxes_SE": t["relaxes"]})

    header = (f"{'step':>4} {'dV/V':>6} {'E_stretch SE':>13} {'E_stretch ours':>14} "
              f"{'E_bend SE':>12} {'E_bend ours':>12} {'E_total SE':>19} {'E_total ours':>19} "
              f"{'rel.diff':>9} {'p SE':>10} {'p ours':>10} {'dx':>8} {'res SE':>8} "
              f"{'res ours':>8} {'it SE':>5} {'it us':>5} {'neg':>5} {'cpu SE':>7} "
              f"{'cpu us':>7} {'ratio':>6} {'wall SE':>7} {'wall us':>7}")
    print(header)
    for r in rows:
        ratio = r["cpu_SE"] / r["cpu_ours"] if r["cpu_ours"] > 0 else math.nan
        print(f"{r['step']:>4d} {r['dV_ours']:>6.3f} {r['Es_SE']:>13.8g} {r['Es_ours']:>14.8g} "
              f"{r['Eb_SE']:>12.7g} {r['Eb_ours']:>12.7g} {r['E_SE']:>19.15g} {r['E_ours']:>19.15g} "
              f"{r['rel_dE']:>9.1e} {r['p_SE']:>10.6g} {r['p_ours']:>10.6g} {r['dx']:>8.1e} "
              f"{r['res_SE']:>8.1e} {r['res_ours']:>8.1e} {r['it_SE']:>5d} {r['it_ours']:>5d} "
              f"{r['neg_SE']:>2d}/{r['neg_ours']:<2d} {r['cpu_SE']:>7.2f} {r['cpu_ours']:>7.2f} "
              f"{ratio:>6.2f} {r['wall_SE']:>7.2f} {r['wall_ours']:>7.2f}")
    shapes = shape_rows(mesh.faces, se["steps"], ours["steps"])
    if shapes:
        print("# shapes (shellbuckle.analysis.classify); axes deg = angle between the dent axes "
              "after rigid alignment; rot deg = rotation that aligns Evolver's conformation on ours")
        print(f"{'step':>4} {'shape SE':>10} {'shape ours':>10} {'dents':>5} {'depth SE':>9} "
              f"{'depth ours':>10} {'rim SE':>7} {'rim ours':>8} {'axes deg':>8} {'rot deg':>7}")
        def num(value, width, digits):
            return f"{'-':>{width}}" if not np.isfinite(value) else f"{value:>{width}.{digits}f}"

        for s in shapes:
            print(f"{s['step']:>4d} {s['shape_SE']:>10} {s['shape_ours']:>10} "
                  f"{s['dents_SE']:>2d}/{s['dents_ours']:<2d} {num(s['depth_SE'], 9, 4)} "
                  f"{num(s['depth_ours'], 10, 4)} {num(s['rim_SE'], 7, 4)} "
                  f"{num(s['rim_ours'], 8, 4)} {num(s['axis_angle_deg'], 8, 1)} "
                  f"{num(s['rigid_rotation_deg'], 7, 2)}")
    failed = [f"{r['step']} ({', '.join(side for side in ('SE', 'ours') if not r['converged_' + side])})"
              for r in rows if not (r["converged_SE"] and r["converged_ours"])]
    if failed:
        print("# NOT CONVERGED at step " + "; ".join(failed))
    model = max(abs(r["E_SE_by_ours"] - r["E_SE"]) / abs(r["E_SE"]) for r in rows)
    print(f"# same model: shellbuckle's energy of Evolver's conformations differs from Evolver's "
          f"total_energy by at most {model:.1e} relative")
    cpu_se = sum(r["cpu_SE"] for r in rows)
    cpu_us = sum(r["cpu_ours"] for r in rows)
    wall_se = sum(r["wall_SE"] for r in rows)
    wall_us = sum(r["wall_ours"] for r in rows)
    print(f"# totals over the steps: CPU Evolver {cpu_se:.2f} s, ours {cpu_us:.2f} s "
          f"(ratio {cpu_se / cpu_us:.2f}); wall Evolver {wall_se:.2f} s, ours {wall_us:.2f} s "
          f"(ratio {wall_se / wall_us:.2f})")
    tol_totals = None
    if tolerance is not None:
        excluded = sum(r["excluded_SE"] for r in rows)
        over = sum(r["over_SE"] for r in rows)
        tol_se = sum(r["cpu_SE_tol"] for r in rows)
        missed = [f"{r['step']}.{x['relax']}" for r in rows for x in r["relaxes_SE"]
                  if x["hit"] is None]
        tol_totals = {"excluded_s": excluded, "over_s": over, "cpu_steps_s": tol_se,
                      "process_cpu_s": se["process_cpu_s"] - excluded - over, "missed": missed}
        print(f"# to shellbuckle's tolerance (relative residual {args.tol:g}, energy change 1e-10, "
              f"eigenneg 0): Evolver {tol_se:.2f} s over the steps ({over:.2f} s after the first "
              f"iterate that passed taken off; {excluded:.2f} s of recording left out), ours "
              f"{cpu_us:.2f} s: ratio {tol_se / cpu_us:.2f}; whole process "
              f"{tol_totals['process_cpu_s']:.1f} s; per step "
              + " ".join(f"{r['step']}:{r['cpu_SE_tol'] / r['cpu_ours']:.1f}" for r in rows)
              + ("; never passed in relax (step.relax) " + ", ".join(missed) if missed else
                 "; every relax passed"))
    print("# p = -dE/dV for both (p SE = -body[1].pressure); dx = largest vertex distance between "
          "the two conformations after rigid alignment (R = 1); res = |grad E - lam grad V| / "
          "|grad E| of each side's conformation, computed by shellbuckle; it SE = g + hessian/"
          "hessian_seek + saddle steps; neg = eigenneg (SE) / inertia (ours); cpu us of step 1 "
          "includes the run set-up")
    print(f"# Evolver {se['version']}; shellbuckle {source_version()}, numpy "
          f"{np.__version__}, Python {platform.python_version()}, {platform.machine()}, "
          f"load average {os.getloadavg()[0]:.2f}")

    if args.json:
        out = {"command": " ".join(["python benchmarks/bench_evolver.py"]
                                   + list(argv if argv is not None else sys.argv[1:])),
               "mesh": args.mesh, "vertices": mesh.n_vertices, "seed": args.seed,
               "gamma": args.gamma, "nu": args.nu, "schedule": schedule,
               "c0_cycle": args.c0_cycle, "temperature": args.temperature,
               "jiggle_seed": args.jiggle_seed, "tol_ours": args.tol, "etol_evolver": args.etol,
               "confirm_evolver": args.confirm, "hessian_normal_evolver": args.hessian_normal,
               "rescale_evolver": args.rescale, "rescale_ours": args.rescale,
               "pinned_evolver_ids": None if pinned is None else [v + 1 for v in pinned],
               "model_check_rel": model,
               "evolver": se["version"], "shellbuckle": source_version(),
               "numpy": np.__version__, "python": platform.python_version(),
               "machine": platform.machine(), "load_average": os.getloadavg()[0],
               "machine_description": machine, "reference_workload_ms": ref,
               "evolver_process_wall_s": se["process_wall_s"],
               "evolver_process_cpu_s": se["process_cpu_s"],
               "ours_total_wall_s": ours["total_wall_s"], "ours_total_cpu_s": ours["total_cpu_s"],
               "ours_runs_cpu_s": ours["runs_cpu_s"], "reference_workload_ms_after": ref_after,
               "cpu_ratio": cpu_se / cpu_us, "wall_ratio": wall_se / wall_us,
               "to_tolerance": tol_totals, "steps": rows,
               "shapes": shapes}
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(_finite_or_none(out), indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
