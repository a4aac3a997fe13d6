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


def band_to_dense(ab, kl, ku):
    """Dense (N, N) matrix of LAPACK-style band storage ``ab`` (N, 2 kl + ku + 1), row r
    holding A[r, c] at column c - r + kl (as dynamics.midpoint stores its KKT matrix)."""
    N = ab.shape[0]
    A = np.zeros((N, N))
    for r in range(N):
        for c in range(max(0, r - kl), min(N, r + ku + 1)):
            A[r, c] = ab[r, c - r + kl]
    return A


def dense_to_band(A, kl, ku):
    """Inverse of :func:`band_to_dense` (entries outside the band are dropped)."""
    N = A.shape[0]
    ab = np.zeros((N, 2 * kl + ku + 1))
    for r in range(N):
        for c in range(max(0, r - kl), min(N, r + ku + 1)):
            ab[r, c - r + kl] = A[r, c]
    return ab


def simulate_midpoint(rod, effects=(), **kwargs):
    """``dynamics.simulate`` with the midpoint method."""
    return dynamics.simulate(rod, effects, method="midpoint", **kwargs)


def clamped(clamp, g=0.0, damping=0.0, load=(0.0, 0.0)):
    """The effects of every clamped-rod test: ``clamp``, gravity ``g``, damping and a point
    load on the last node (each an exact no-op at zero), so that they share one compiled
    RATTLE stepper instead of compiling one per combination."""
    return (clamp, dynamics.Gravity(g), dynamics.Damping(damping),
            dynamics.PointLoad(-1, load))
