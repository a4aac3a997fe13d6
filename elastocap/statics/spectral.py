"""Chebyshev-Gauss-Lobatto collocation on [-1, 1]: nodes, differentiation, integration.

Nodes xi_j = -cos(j pi / N), j = 0..N, increasing from -1 to 1. For values f_j of a smooth
function at the nodes, ``D @ f`` is the derivative of the interpolating polynomial at the
nodes, ``Q @ f`` its indefinite integral from -1 (so ``Q[-1]`` are the Clenshaw-Curtis
weights), and the error of both decays spectrally (faster than any power of 1/N) for
analytic f. Trefethen, *Spectral Methods in MATLAB* (2000), ch. 6 and 12.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = [
    "cheb_nodes",
    "cheb_diff",
    "cheb_integ",
    "cheb_interp_matrix",
    "lgl_nodes",
    "lgl_diff",
    "lgl_integ",
    "lgl_interp_matrix",
]


@lru_cache(maxsize=64)
def cheb_nodes(N: int) -> np.ndarray:
    """Chebyshev-Gauss-Lobatto nodes, shape (N+1,), increasing from -1 to 1."""
    if N < 2:
        raise ValueError(f"N: got {N}; expected at least 2 intervals")
    x = -np.cos(np.pi * np.arange(N + 1) / N)
    x.setflags(write=False)
    return x


@lru_cache(maxsize=64)
def cheb_diff(N: int) -> np.ndarray:
    """Differentiation matrix, shape (N+1, N+1), on :func:`cheb_nodes` (Trefethen's cheb)."""
    x = cheb_nodes(N)
    c = np.ones(N + 1)
    c[0] = c[-1] = 2.0
    c *= (-1.0) ** np.arange(N + 1)
    X = np.tile(x, (N + 1, 1)).T
    dX = X - X.T
    D = np.outer(c, 1.0 / c) / (dX + np.eye(N + 1))
    # negative-sum trick: rows of D annihilate constants to round-off
    D -= np.diag(D.sum(axis=1))
    D.setflags(write=False)
    return D


@lru_cache(maxsize=64)
def cheb_integ(N: int) -> np.ndarray:
    """Integration matrix, shape (N+1, N+1): (Q f)_k = integral from -1 to xi_k of p_f."""
    x = cheb_nodes(N)
    n = np.arange(N + 1)
    # values -> Chebyshev coefficients: T_n(xi_j) = cos(n (pi - j pi / N)) at our nodes
    V = np.cos(np.outer(np.arccos(x), n))
    # antiderivatives of T_n evaluated at x, minus their value at -1
    theta = np.arccos(x)
    A = np.empty((N + 1, N + 1))
    A[:, 0] = x
    A[:, 1] = 0.5 * x * x
    for k in range(2, N + 1):
        A[:, k] = 0.5 * (np.cos((k + 1) * theta) / (k + 1) - np.cos((k - 1) * theta) / (k - 1))
    A -= A[0]
    Q = A @ np.linalg.inv(V)
    Q[0] = 0.0
    Q.setflags(write=False)
    return Q


def cheb_interp_matrix(N: int, xi: np.ndarray) -> np.ndarray:
    """Barycentric interpolation matrix from the N+1 nodes to points ``xi`` in [-1, 1]."""
    x = cheb_nodes(N)
    w = (-1.0) ** np.arange(N + 1)
    w[0] *= 0.5
    w[-1] *= 0.5
    return _barycentric(x, w, xi)


# ---------------------------------------------------------------------------------------------
# Legendre-Gauss-Lobatto: the quadrature is exact for polynomials of degree 2N - 1, so the
# bending energy int theta'^2 of the polynomial theta (degree 2N - 2) is integrated exactly
# and the discrete energy is a true Ritz-Galerkin discretization (variationally consistent).


def _legendre_all(N: int, x: np.ndarray) -> np.ndarray:
    """P_0..P_N at x, shape (len(x), N+1)."""
    P = np.empty((x.size, N + 1))
    P[:, 0] = 1.0
    if N >= 1:
        P[:, 1] = x
    for n in range(1, N):
        P[:, n + 1] = ((2 * n + 1) * x * P[:, n] - n * P[:, n - 1]) / (n + 1)
    return P


@lru_cache(maxsize=64)
def lgl_nodes(N: int) -> np.ndarray:
    """Legendre-Gauss-Lobatto nodes, shape (N+1,), increasing from -1 to 1."""
    if N < 2:
        raise ValueError(f"N: got {N}; expected at least 2 intervals")
    x = -np.cos(np.pi * np.arange(N + 1) / N)  # Chebyshev start: within O(1/N^2)
    # Newton on (1 - x^2) P_N'(x) = 0 through the identity x P_N - P_{N-1} (Hesthaven-Warburton)
    for _ in range(100):
        P = _legendre_all(N, x)
        xold = x.copy()
        x = xold - (x * P[:, N] - P[:, N - 1]) / ((N + 1) * P[:, N])
        if np.max(np.abs(x - xold)) < 1e-16:
            break
    x[0], x[-1] = -1.0, 1.0
    x = np.sort(x)
    x.setflags(write=False)
    return x


@lru_cache(maxsize=64)
def lgl_diff(N: int) -> np.ndarray:
    """Differentiation matrix on :func:`lgl_nodes`."""
    x = lgl_nodes(N)
    PN = _legendre_all(N, x)[:, N]
    X = x[:, None] - x[None, :]
    np.fill_diagonal(X, 1.0)
    D = (PN[:, None] / PN[None, :]) / X
    np.fill_diagonal(D, 0.0)
    # negative-sum trick for the diagonal (exactly -N(N+1)/4, 0, ..., N(N+1)/4 in theory)
    np.fill_diagonal(D, -D.sum(axis=1))
    D.setflags(write=False)
    return D


@lru_cache(maxsize=64)
def lgl_integ(N: int) -> np.ndarray:
    """Integration matrix on :func:`lgl_nodes` (last row: the Gauss-Lobatto weights)."""
    x = lgl_nodes(N)
    V = _legendre_all(N, x)
    P1 = _legendre_all(N + 1, x)
    A = np.empty((N + 1, N + 1))
    A[:, 0] = x + 1.0
    for n in range(1, N + 1):
        A[:, n] = (P1[:, n + 1] - P1[:, n - 1]) / (2 * n + 1)
    A -= A[0]
    Q = A @ np.linalg.inv(V)
    Q[0] = 0.0
    Q.setflags(write=False)
    return Q


def lgl_interp_matrix(N: int, xi: np.ndarray) -> np.ndarray:
    """Interpolation matrix from the LGL nodes to points ``xi`` (barycentric formula)."""
    x = lgl_nodes(N)
    diff0 = x[:, None] - x[None, :]
    np.fill_diagonal(diff0, 1.0)
    w = 1.0 / diff0.prod(axis=1)
    return _barycentric(x, w, xi)


def _barycentric(x, w, xi):
    xi = np.atleast_1d(np.asarray(xi, dtype=float))
    diff = xi[:, None] - x[None, :]
    exact = diff == 0.0
    diff[exact] = 1.0
    M = w[None, :] / diff
    M /= M.sum(axis=1, keepdims=True)
    rows = exact.any(axis=1)
    M[rows] = exact[rows].astype(float)
    return M
