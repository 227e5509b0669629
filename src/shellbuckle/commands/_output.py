"""What the commands print about a run they made or extended, and JSON on stdout."""

from __future__ import annotations

import json


def report_run(run, *, plot: bool = False) -> int:
    """Print the run folder, its status and its last step; along a path in gamma or c0 (the
    run's protocol control) the step's gamma and c0, otherwise its pressure; the located
    events (:mod:`shellbuckle.locate`) if any. With ``plot``,
    write the run figure (``deflation.png`` in the run folder) and name it. Returns 0."""
    k = run.store.last_step  # its record, not the table: pandas is not needed to say it
    last = {"step": k, **run.store.record(k)}
    print(f"run folder: {run.path}")
    status, message = run.store.current_status()
    print(f"status: {status} ({message})")
    if run.protocol.control in ("gamma", "c0"):
        print(f"steps: {int(last['step'])}, gamma = {run.params_at(-1).gamma:.6g}, "
              f"c0 = {run.c0_at(-1):.6g}, dV/V = {last['dV_over_V']:.4f}, "
              f"E/kappa = {last['E_over_kappa']:.6g}")
    else:
        print(f"steps: {int(last['step'])}, dV/V = {last['dV_over_V']:.4f}, "
              f"E/kappa = {last['E_over_kappa']:.6g}, "
              f"pressure = {_pressure(run.params, last['pressure'])}")
    from ..store.located import read_located

    points = read_located(run.path)
    if points:
        print_located(run, points)
    if plot:
        from ..plots.pv import family, plot_pv
        from ..plots.run import plot_deflation

        path = run.path / "deflation.png"
        plot_deflation(run, path=path)
        print(f"figure: {path}")
        path = run.path / "pv.png"
        plot_pv(family(run), path)
        print(f"pressure-volume figure: {path}")
    return 0


def print_json(value, indent=None) -> int:
    """Print ``value`` as strict JSON (non-finite numbers as null). Returns 0."""
    from ..util import json_safe

    print(json.dumps(json_safe(value), indent=indent))
    return 0


def _old_branch_text(branch: dict | None) -> str:
    """Where the old branch of a located jump, followed without jiggle, ends (empty for a
    continuous event or a point located before the branch was followed)."""
    if not branch:
        return ""
    if branch.get("end_hi") is not None:
        share = 100 * branch["anticipation"]
        from ..locate import ended_by

        how = " where no minimum is found" if ended_by(branch) == "no minimum" else ""
        parts = [f"ends at {0.5 * (branch['end_lo'] + branch['end_hi']):.4f}{how}",
                 f"the located point is {share:.0f} % of that volume short of it" if share >= 0
                 else f"{-share:.0f} % before the located point"]
    elif branch.get("failure"):
        parts = [f"reached {branch['followed_to']:.4f}"]
    else:
        parts = [f"goes on past {branch['followed_to']:.4f}"]
    if branch.get("failure"):
        parts.append(branch["failure"])
    return " (the old branch without jiggle " + "; ".join(parts) + ")"


def _pressure(params, stored) -> str:
    """A stored pressure (the run's units) in kappa/R^3, and for a shell made from a material
    in Pa (its SI units) as well."""
    from ..params import unit_scale

    reduced = f"{stored / unit_scale(params, 'pressure'):.6g} kappa/R^3"
    return f"{reduced} ({stored:.6g} Pa)" if params.is_material else reduced


def print_located(run, points: dict) -> None:
    """One line per located event: the step reading, the located value and the mechanism;
    pressures in kappa/R^3 (stored in the run's units: Pa for a shell made from a material)."""
    if not points:
        print(f"{run.path}: no buckling event to locate (the run stays a sphere)")
        return
    from ..params import unit_scale

    unit = unit_scale(run.params, "pressure")
    print("located events (dV/V; pressures in kappa/R^3):")
    table = run.table.set_index("step")
    for name, p in sorted(points.items(), key=lambda item: item[1]["lo"]):
        old, new = p["old"], p["new"]
        k = p["step"]
        before = float(table.loc[k - 1, "dV_over_V"]) if k - 1 in table.index else float("nan")
        print(f"  {name:<17} {p['dV_over_V']:.5f} ± {p['uncertainty']:.1e}   (the steps: "
              f"between {before:.4f} and {p['step_dV_over_V']:.4f}, step {k})")
        line = (f"  {'':<17} {old['shape']} -> {new['shape']}, E/kappa {old['E_over_kappa']:.5g} "
                f"-> {new['E_over_kappa']:.5g}, p {old['pressure'] / unit:.5g} -> "
                f"{new['pressure'] / unit:.5g}, "
                f"lowest eigenvalue {old['lowest_eigenvalue']:.3g} -> "
                f"{new['lowest_eigenvalue']:.3g}: {p['mechanism']}")
        line += _old_branch_text(p.get("old_branch"))
        if not p.get("complete", True):
            line += f"; incomplete: {p['failure']}"
        print(line)
