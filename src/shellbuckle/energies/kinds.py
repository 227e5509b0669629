"""The names of the energies' discretizations, for what describes or checks a run without
computing an energy (the command line, :class:`~shellbuckle.protocol.spec.Protocol`)."""

BENDING_KINDS = ("juelicher", "evolver")
"""Bending discretizations: Jülicher's edge-based mean curvature (default) and Surface
Evolver's ``star_perp_sq_mean_curvature``."""
