"""What the machine is, and how fast it is right now, for the benchmarks' headers.

Machines of one kind do not run at one speed: on the shared 2-core hosts these benchmarks were
measured on, the same whole run took 74.5 s on one day and 48.1 s on another, with the same
iterations and factorizations to the last one (``bench_deflation.py --gamma 20995``, seed 0).
A time means little without a measure of the machine it was taken on, so the benchmarks print
:func:`describe` (processor and caches) and :func:`reference` (a fixed piece of the work a
deflation does, timed just before) next to their own figures.

The reference workload is the deflation's three costs on the paper's 3594-vertex randomized
mesh (``random_sphere(3594, seed=0)`` uniformly shrunk by 5 %, gamma = 2333, Jülicher bending):
one value and gradient of the energy; the Hessian assembled and factored (PARDISO's
symmetric-indefinite factorization of the Hessian shifted by 1e-3 mean|diag| in double and
in single precision, the pattern analysed beforehand); and one solve with each factor. Each is
the median of several repeats on one thread. Their sum ``step_ms`` (a Hessian, a
single-precision factorization, 20 single-precision solves and 21 gradients) weighs them about
as a Newton step of the protocol followed by its quasi-Newton steps does.

Run alone (``python benchmarks/machine.py``) it prints both lines.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import json  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

REFERENCE_VERTICES = 3594
REFERENCE_GAMMA = 2333.0
REFERENCE_SHRINK = 0.95 ** (1.0 / 3.0)
REFERENCE_KEYS = ("gradient", "hessian", "factor_double", "factor_single", "solve_double",
                  "solve_single", "step_ms")


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _cache_sizes() -> str:
    """The data and unified caches of cpu0 by level (Linux sysfs), e.g. ``L1d 48K, L2 1024K,
    L3 32768K``; empty elsewhere."""
    sizes = []
    for index in sorted(Path("/sys/devices/system/cpu/cpu0/cache").glob("index*")):
        try:
            kind = (index / "type").read_text().strip()
            level = (index / "level").read_text().strip()
            size = (index / "size").read_text().strip()
        except OSError:
            continue
        if kind != "Instruction":
            sizes.append(f"L{level}{'d' if kind == 'Data' else ''} {size}")
    return ", ".join(sizes)


def describe() -> str:
    """One line: processor, cores, caches, Python and the numerical libraries' versions."""
    import scipy

    caches = _cache_sizes()
    return (f"{_cpu_model()}, {os.cpu_count()} cores" + (f" ({caches})" if caches else "")
            + f"; Python {platform.python_version()}, NumPy {np.__version__}, "
              f"SciPy {scipy.__version__}; load average {os.getloadavg()[0]:.2f}")


def median_ms(f, repeat: int, clock=time.perf_counter) -> float:
    """Median time of ``f()`` in ms by ``clock`` over ``repeat`` calls (after one untimed
    call)."""
    f()
    times = []
    for _ in range(repeat):
        t = clock()
        f()
        times.append(clock() - t)
    return 1e3 * float(np.median(times))


def reference(repeat: int = 7) -> dict:
    """Times (ms) of the reference workload (module docstring) on this machine now:
    ``gradient``, ``hessian`` (assembly), ``factor_double``, ``factor_single``,
    ``solve_double``, ``solve_single`` and their weighted sum ``step_ms``. The factorizations
    need PARDISO (Intel MKL); without it they are ``nan``.

    Measured in a child process: in the caller's it would load Numba's compiled kernels and
    MKL ahead of the benchmark, whose first run would then not pay for them."""
    done = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--json",
                           str(int(repeat))], capture_output=True, text=True)
    try:
        return json.loads(done.stdout.strip().splitlines()[-1])
    except (IndexError, ValueError):  # a failed measurement must not end the benchmark
        lines = (done.stderr or done.stdout or "no output").strip().splitlines()
        return {key: float("nan") for key in REFERENCE_KEYS} | {
            "error": f"exit status {done.returncode}: {lines[-1] if lines else ''}"}


def _reference_here(repeat: int) -> dict:
    from shellbuckle.energies.total import ShellEnergy
    from shellbuckle.mesh.random_sphere import random_sphere
    from shellbuckle.params import ShellParameters
    from shellbuckle.solve.linear import _load_mkl
    from shellbuckle.solve.pardiso import PardisoSolver

    mesh = random_sphere(REFERENCE_VERTICES, seed=0)
    energy = ShellEnergy.build(mesh, ShellParameters.from_gamma(REFERENCE_GAMMA, nu=1.0 / 3.0))
    X = mesh.X * REFERENCE_SHRINK
    out = {"gradient": median_ms(lambda: energy.value_and_gradient(X), 20 * repeat),
           "hessian": median_ms(lambda: energy.hessian(X), repeat)}
    H = energy.hessian(X).tocsr()
    shift = 1e-3 * float(np.abs(H.diagonal()).mean())
    upper = sp.triu(H + shift * sp.identity(H.shape[0], format="csr"), format="csr")
    upper.sort_indices()
    b = np.random.default_rng(0).standard_normal(H.shape[0])
    for precision in ("double", "single"):
        if _load_mkl() is None:
            out[f"factor_{precision}"] = out[f"solve_{precision}"] = float("nan")
            continue
        solver = PardisoSolver(1, precision, refinement=0)
        solver.factor(upper, upper=True)  # the symbolic analysis, not timed
        out[f"factor_{precision}"] = median_ms(lambda: solver.factor(upper, upper=True), repeat)
        out[f"solve_{precision}"] = median_ms(lambda: solver.solve(b), 5 * repeat)
    out["step_ms"] = (21 * out["gradient"] + out["hessian"] + out["factor_single"]
                      + 20 * out["solve_single"])
    return out


def reference_line(ref: dict) -> str:
    """:func:`reference` in one line."""
    if "error" in ref:
        return f"reference workload failed ({ref['error']})"
    return (f"reference workload ({REFERENCE_VERTICES} vertices, ms): gradient {ref['gradient']:.3f}, Hessian "
            f"{ref['hessian']:.1f}, factorization {ref['factor_double']:.1f} double / "
            f"{ref['factor_single']:.1f} single, solve {ref['solve_double']:.2f} / "
            f"{ref['solve_single']:.2f}; step {ref['step_ms']:.0f}")


if __name__ == "__main__":
    if sys.argv[1:2] == ["--json"]:  # the child process of reference()
        print(json.dumps(_reference_here(int(sys.argv[2]))))
    else:
        print(describe())
        print(reference_line(reference()))
