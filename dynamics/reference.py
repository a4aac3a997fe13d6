"""Analytic reference solutions used to validate the stepper."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["BETA_L", "crossing_period", "euler_bernoulli_omega"]

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


def crossing_period(t, q):
    """Mean period of an oscillating signal from its downward zero crossings.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Times (time units), increasing.
    q : ndarray, shape (n,)
        Signal (e.g. a modal amplitude), mean removed by the caller.

    Returns
    -------
    float
        (t_last - t_first) / (crossings - 1), each crossing time interpolated linearly
        between the frames that bracket it (second-order accurate in the frame spacing).
    """
    i = np.nonzero((q[:-1] > 0) & (q[1:] <= 0))[0]
    if i.size < 2:
        raise ValueError(f"crossing_period: {i.size} downward zero crossing(s); need at least 2")
    tc = t[i] - q[i] * (t[i + 1] - t[i]) / (q[i + 1] - q[i])
    return float((tc[-1] - tc[0]) / (len(tc) - 1))
