"""Figures: the paper's theory curves (and, as they come, the simulation figures)."""

from .theory import plot_theory

__all__ = ["plot_theory"]
