"""elastocap: a thin elastic strip wrapping a drop (capillary origami), statics and dynamics.

Units: every quantity is dimensionless unless a docstring says otherwise; scenes fix the
units through the rod's bending modulus B, mass per length mu and the line tension gamma
(see :mod:`elastocap.units` for the conversion from a dimensional experiment).
"""

from elastocap._version import __version__

__all__ = ["__version__"]
