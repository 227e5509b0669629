# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # shellbuckle from Python
#
# A shell with Föppl–von Kármán number γ = 2333 and ν = 1/3 (the paper's incompressible
# shells, d/R = 0.0586) deflated with the protocol of Quilliet et al. (EPJE 27, 13 (2008)):
# volume steps of 0.019 V0, a jiggle and the zero-spontaneous-curvature cycle at every step.
# Then: the per-step table as a DataFrame, the automatic analysis (shape classes, buckling
# events and thresholds), figures, the interactive viewer, exports to ParaView and to Surface
# Evolver, and a path in γ at fixed volume.
#
# Run it as a script (`python examples/notebook.py`) or open it in Jupyter with jupytext.
# `SHELLBUCKLE_EXAMPLE_QUICK=1` makes everything smaller (a few hundred vertices, a shorter
# deflation) for a fast check; `SHELLBUCKLE_EXAMPLE_OUT=DIR` chooses where files go (default:
# a new temporary folder).

# %%
import logging
import os
import tempfile
from pathlib import Path

import numpy as np

from shellbuckle import ShellParameters
from shellbuckle.mesh import random_sphere
from shellbuckle.run import Run, compare_paths, continue_in_parameter, deflate

logging.basicConfig(level=logging.WARNING)
QUICK = os.environ.get("SHELLBUCKLE_EXAMPLE_QUICK", "") not in ("", "0")
OUT = Path(os.environ.get("SHELLBUCKLE_EXAMPLE_OUT") or tempfile.mkdtemp(prefix="shellbuckle-"))
OUT.mkdir(parents=True, exist_ok=True)
N_VERTICES, UNTIL = (250, 0.2) if QUICK else (1000, 0.5)
print(f"output folder: {OUT}")

# %% [markdown]
# ## A deflation
#
# `deflate` stores every finished step in the run folder; calling it again with the same
# arguments resumes an interrupted run.

# %%
params = ShellParameters.from_gamma(2333, nu=1 / 3)
print(f"gamma = {params.gamma:g}, nu = {params.nu:.4f}, d/R = {params.d_over_R:.4f}")
mesh = random_sphere(N_VERTICES, seed=1)
run = deflate(mesh, params, until=UNTIL, seed=1, out=OUT / "g2333")
print(run)

# %% [markdown]
# ## The table
#
# One row per step (step 0 is the sphere): target and reached ΔV/V, energies (units of κ),
# pressure (the Lagrange multiplier of the volume constraint), minimizer residual and work.

# %%
table = run.table
table[["step", "dV_over_V", "E_bend", "E_stretch", "E_total", "pressure", "iterations"]]

# %%
# the volume constraint holds at every step, and the energy grows as the shell deflates
assert np.allclose(table["dV_over_V"], table["target_dV_over_V"], rtol=0, atol=1e-9)
assert table["E_total"].iloc[-1] > table["E_total"].iloc[1]

# %% [markdown]
# ## Analysis
#
# Every conformation is classified (sphere, dimples, capsule, polygonal, wrinkled) and the
# buckling events are found from the shapes and the pressure. `analyze_run` stores the
# analysis columns in the run folder, so the table now has `shape`, `corners` and `W`.

# %%
from shellbuckle.analysis import analyze_run, classify, events, thresholds

table = analyze_run(run)
table[["step", "dV_over_V", "shape", "n_dimples", "corners", "W", "dent_depth"]]

# %%
for event in events(run):
    print(f"{event.name}: dV/V = {event.dV_over_V:.3f} (step {event.step})")
found = thresholds(run)
print(found)

# %%
from shellbuckle import theory

# the sphere buckles past the crossing of U_sphere and U_axisym (hysteresis, paper Fig. 9)
crossing = theory.crossing(params)
print(f"U_sphere = U_axisym at dV/V = {crossing:.4f}; primary buckling seen at "
      f"{found['primary_buckling']:.4f}")
last = classify(run.positions(-1), run.faces)
print(f"last step: {last.shape}, W = {last.W}, dent depth = {last.dent_depth:.3f} R")

# %% [markdown]
# ## Figures
#
# The run figure (energies and pressure against ΔV/V with the theory, and the last
# conformation coloured by mean curvature) and the theory alone.

# %%
import matplotlib

matplotlib.use("Agg")
from shellbuckle.plots import plot_theory
from shellbuckle.plots.run import plot_deflation

plot_deflation(run, path=OUT / "deflation.png")
plot_theory(params, path=OUT / "theory.png")
print(sorted(p.name for p in OUT.glob("*.png")))

# %% [markdown]
# ## The viewer
#
# One self-contained HTML page: a slider over the steps, drag to rotate, colours by mean
# curvature or energy density, the table and the curves. In Jupyter,
# `shellbuckle.plots.viewer.show(run)` displays it inline.

# %%
from shellbuckle.plots.viewer import write_html

page = write_html(run, OUT / "view.html")
print(f"{page} ({page.stat().st_size / 1e6:.2f} MB)")

# %% [markdown]
# ## Exports
#
# Any step to VTU for ParaView (with the mean curvature and energy densities as fields) and to
# a Surface Evolver datafile that Evolver reads and continues from. Reading the `.fe` back
# with the Evolver energy reader gives the run's stretching energy (the rest metrics travel
# as `form_factors`); its bending energy is Evolver's `star_perp_sq_mean_curvature`, the
# run's own only for runs made with `bending="evolver"` (this one uses Jülicher's).

# %%
from shellbuckle.energies.evolver import evolver_energy
from shellbuckle.export import export_step

k = run.steps[-1]
vtu = export_step(run, k, OUT / "last.vtu")
fe = export_step(run, k, OUT / "last.fe")
back = evolver_energy(fe)
row = run.table.iloc[k]
print(f"{vtu.name}, {fe.name}: E_stretch {back['E_stretch']:.10g} (run {row['E_stretch']:.10g}), "
      f"E_bend {back['E_bend']:.6g} (Evolver's discretization; run {row['E_bend']:.6g})")
assert abs(back["E_stretch"] - row["E_stretch"]) <= 1e-10 * abs(row["E_stretch"])

# %% [markdown]
# ## A path in γ at fixed volume
#
# From the capsule reached at an intermediate volume, raise γ in equal ratios at that volume
# (each increment: jiggle, minimization, zero-curvature cycle) — the kind of path by which the
# paper reached its Fig. 11 conformation — and compare with the conformation that progressive
# deflation gives at the same γ and volume.

# %%
start = int(run.table["step"].iloc[len(run.table) // 2])
path = continue_in_parameter(run, start, OUT / "g2333_to_g7465", gamma=7465,
                             increments=2 if QUICK else 4)
path.table[["step", "gamma", "dV_over_V", "E_bend", "E_stretch", "E_total"]]

# %%
direct = deflate(random_sphere(N_VERTICES, seed=1), ShellParameters.from_gamma(7465),
                 until=float(run.table["target_dV_over_V"].iloc[start]), seed=1,
                 out=OUT / "g7465")
result = compare_paths(path, -1, direct, -1)
print(f"path: {result['a']['shape']} E = {result['a']['E_total']:.5g}; "
      f"deflation: {result['b']['shape']} E = {result['b']['E_total']:.5g}; "
      f"E_deflation / E_path = {result['ratio']:.3f}; same parameters: "
      f"{result['same_parameters']}")
assert result["same_parameters"]
assert Run.open(path.path).params_at(-1).gamma == 7465
