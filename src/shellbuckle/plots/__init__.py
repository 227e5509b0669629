"""Figures: the paper's theory curves, the paper's figures, a run's figures and animations.

The submodules load matplotlib; this package loads nothing until one is asked for, so that
:mod:`.limits` stays light."""

__all__ = ["plot_theory"]


def __getattr__(name):
    if name == "plot_theory":
        from .theory import plot_theory

        return plot_theory
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
