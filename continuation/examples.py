"""Analytic reference problems with known answers (used by the tests and benchmarks).

- :class:`Bratu` — 1D Bratu ``u'' + lam exp(u) = 0``, ``u(0) = u(1) = 0``, by
  second-order finite differences or Chebyshev collocation; the continuum fold
  is at ``lam* = 3.513830719125161...``.
- :class:`Pitchfork` — ``x (p - x^2) = 0``: a branch point at the origin.
- :func:`cusp_family` — ``x^3 - q x - p = 0``: folds at ``p = +-2 (q/3)^{3/2}``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ._problem import Problem

#: The fold of the continuum Bratu problem, from
#: ``lam = 8 z^2 / cosh(z)^2`` with ``z tanh z = 1``.
BRATU_FOLD = 3.513830719125161


def chebyshev(N: int):
    """Chebyshev-Gauss-Lobatto points on [0, 1] and the differentiation matrix.

    Trefethen, *Spectral Methods in MATLAB* (2000), program ``cheb``, mapped
    from [-1, 1] to [0, 1] (points increasing).

    Returns
    -------
    x : ndarray, shape (N + 1,)
    D : ndarray, shape (N + 1, N + 1)
    """
    j = np.arange(N + 1)
    x = np.cos(np.pi * j / N)
    c = np.where((j == 0) | (j == N), 2.0, 1.0) * (-1.0) ** j
    X = np.tile(x, (N + 1, 1)).T
    dX = X - X.T
    D = np.outer(c, 1.0 / c) / (dX + np.eye(N + 1))
    D -= np.diag(D.sum(axis=1))
    # Map [-1, 1] -> [0, 1] with increasing points: s = (1 - x) / 2, d/ds = -2 d/dx.
    return (1.0 - x) / 2.0, -2.0 * D


class Bratu(Problem):
    """1D Bratu problem ``u'' + lam exp(u) = 0`` on [0, 1], ``u(0) = u(1) = 0``.

    Parameters
    ----------
    N : int
        Finite differences: number of intervals (N - 1 interior unknowns),
        order 2. Chebyshev: polynomial degree (N - 1 interior collocation
        unknowns), spectral.
    method : {"fd", "chebyshev"}
    sparse : bool
        Finite differences only: return the tridiagonal Jacobian as
        ``scipy.sparse`` instead of dense.

    Notes
    -----
    The continuation parameter is ``p = lam``. Observables: ``u_max`` (the
    value at the midpoint for symmetric solutions: the maximum) and
    ``norm`` (discrete l2 norm over the unknowns, divided by sqrt(n)).
    The problem is the gradient of ``E(u) = int u'^2/2 - lam e^u`` (times the
    quadrature weights for FD), so ``hessian`` is supplied for FD.
    """

    def __init__(self, N: int = 64, method: str = "chebyshev", sparse: bool = False):
        if method not in ("fd", "chebyshev"):
            raise ValueError(f"method={method!r}: expected 'fd' or 'chebyshev'")
        if not (isinstance(N, int) and N >= 3):
            raise ValueError(f"N={N!r}: expected an integer >= 3")
        self.N, self.method, self.sparse = N, method, sparse
        self.name = f"bratu-{method}-{N}"
        if method == "fd":
            h = 1.0 / N
            self.x = np.linspace(0.0, 1.0, N + 1)[1:-1]
            n = N - 1
            L = sp.diags([np.ones(n - 1), -2.0 * np.ones(n), np.ones(n - 1)], [-1, 0, 1]) / h**2
            self._Ls = L.tocsr()
            self._L = L.toarray()
        else:
            x, D = chebyshev(N)
            self.x = x[1:-1]
            self._L = (D @ D)[1:-1, 1:-1]
            self._Ls = None
        self.n = self.x.size
        self._mid = int(np.argmin(np.abs(self.x - 0.5)))

    def residual(self, u, p):
        if self._Ls is not None:
            return self._Ls @ u + p * np.exp(u)
        return self._L @ u + p * np.exp(u)

    def jacobian(self, u, p):
        if self.sparse and self._Ls is not None:
            return (self._Ls + sp.diags(p * np.exp(u))).tocsc()
        J = self._L.copy()
        J[np.diag_indices_from(J)] += p * np.exp(u)
        return J

    def dfdp(self, u, p):
        return np.exp(u)

    def observables(self, u, p):
        return {"u_max": float(np.max(u)), "norm": float(np.linalg.norm(u) / np.sqrt(u.size))}

    @property
    def hessian(self):
        if self.method != "fd":
            return None  # collocation is not a Galerkin (symmetric) discretization
        return lambda u, p: -(self._L + np.diag(p * np.exp(u)))


class Pitchfork(Problem):
    """Pitchfork normal form ``F(x, p) = x (p - x^2)``; branches ``x = 0`` and ``x^2 = p``.

    The gradient of ``E = -p x^2 / 2 + x^4 / 4``; the Hessian ``3 x^2 - p``
    is supplied, so ``x = 0`` is stable for ``p < 0`` and unstable for ``p > 0``.
    """

    name = "pitchfork"

    def residual(self, u, p):
        return u * (p - u**2)

    def jacobian(self, u, p):
        return np.atleast_2d(p - 3.0 * u**2)

    def dfdp(self, u, p):
        return u.copy()

    def hessian(self, u, p):
        return -self.jacobian(u, p)

    def observables(self, u, p):
        return {"x": float(u[0])}


class Cusp(Problem):
    """Cusp normal form ``F(x, p; q) = x^3 - q x - p`` at fixed ``q``.

    Folds at ``x = +-sqrt(q/3)``, ``p = -+2 (q/3)^{3/2}`` for ``q > 0``; the
    fold curves meet at the cusp ``q = 0``.
    """

    def __init__(self, q: float = 1.0):
        self.q = float(q)
        self.name = f"cusp(q={self.q:g})"

    def residual(self, u, p):
        return u**3 - self.q * u - p

    def jacobian(self, u, p):
        return np.atleast_2d(3.0 * u**2 - self.q)

    def dfdp(self, u, p):
        return -np.ones_like(u)

    def observables(self, u, p):
        return {"x": float(u[0])}


def cusp_family(q: float) -> Cusp:
    """Problem family ``q -> Cusp(q)`` for :func:`continuation.continue_fold`."""
    return Cusp(q)


def cusp_fold_p(q):
    """Closed-form fold curves of the cusp: ``p = +-2 (q/3)^{3/2}`` (q >= 0)."""
    return 2.0 * (np.asarray(q) / 3.0) ** 1.5
