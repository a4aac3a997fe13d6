"""Helpers shared by the dynamics tests (a plain module: `conftest` is ambiguous when
several test directories have one)."""

import numpy as np

import dynamics


def rod_from_angles(theta, h, origin=(0.0, 0.0), mu=1.0, B=1.0, v=None):
    """Rod with edges of length ``h`` at tangent angles ``theta`` (radians)."""
    theta = np.asarray(theta, dtype=float)
    x = np.zeros((theta.size + 1, 2))
    x[0] = origin
    x[1:, 0] = origin[0] + np.cumsum(h * np.cos(theta))
    x[1:, 1] = origin[1] + np.cumsum(h * np.sin(theta))
    if v is None:
        v = np.zeros_like(x)
    return dynamics.Rod(x, v, np.full(theta.size, h), mu, B)
