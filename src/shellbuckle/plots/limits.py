"""The ranges a figure's or an animation's resolution and speed may take, one definition for
the Python API (:func:`~.animation.animate_run`) and the command line (``--dpi``, ``--fps``).

A light module (the standard library only): the command line checks its options with it before
it loads matplotlib.
"""

from __future__ import annotations

#: Dots per inch: below 50 nothing is legible; a figure at 1200 dpi is already about 10000
#: pixels wide (hundreds of MB in memory).
DPI = (50, 1200)

#: Frames per second: a frame per second at least; screens show at most 60.
FPS = (1, 60)

#: An animation frame's side, inches.
FRAME_SIZE = (1.0, 40.0)
