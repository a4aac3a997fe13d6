"""Analytic reference solutions used to validate the stepper."""

from __future__ import annotations

import math

__all__ = ["BETA_L", "euler_bernoulli_omega"]

#: First-mode eigenvalues beta L of the Euler-Bernoulli beam (first roots of
#: cos(bL) cosh(bL) = 1 for free-free and = -1 for clamped-free).
BETA_L = {"free-free": 4.730040744862704, "clamped-free": 1.875104068711961}


def euler_bernoulli_omega(kind, L, B, mu):
    """First bending-mode angular frequency ``(beta L)**2 sqrt(B / (mu L**4))``.

    Parameters
    ----------
    kind : {"free-free", "clamped-free"}
    L : float
        Beam length (length units).
    B : float
        Bending modulus (energy x length).
    mu : float
        Mass per unit length.

    Returns
    -------
    float
        Angular frequency (rad / time unit).
    """
    if kind not in BETA_L:
        raise ValueError(f"kind must be one of {sorted(BETA_L)}, got {kind!r}")
    return BETA_L[kind] ** 2 * math.sqrt(B / (mu * L**4))
