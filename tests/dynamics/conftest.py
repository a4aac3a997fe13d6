"""Shared helpers for the dynamics tests."""

import numpy as np
import pytest

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


@pytest.fixture
def wavy_rod():
    """A free rod of 40 edges, length 4.6, gently curved (bending energy ~1e-2)."""
    n = 40
    h = 4.6 / n
    s = (np.arange(n) + 0.5) * h
    return rod_from_angles(0.3 * np.sin(2 * np.pi * s / 4.6), h)
