"""shellbuckle: buckling of thin elastic spherical shells under volume loss.

Units: the initial radius R = 1 and the bending modulus kappa = 1 unless a material is
given; then the 2D Young modulus A equals the Foppl-von Karman number gamma = A R^2 / kappa.
Bending convention: c = c1 + c2 (twice the mean curvature), so the stress-free sphere has
spontaneous curvature c0 = 2/R (the paper's "c0 = 1/R" is a mean curvature).
"""

__version__ = "0.1.0"

from .params import ShellParameters  # noqa: E402
from . import theory  # noqa: E402
