"""The problem interface F(u, p) = 0 and its evaluator (analytic or finite differences)."""

from __future__ import annotations

import warnings
import weakref
from collections.abc import Callable

import numpy as np

from ._linalg import as_matrix


class FiniteDifferenceWarning(UserWarning):
    """A derivative the problem does not supply is approximated by finite differences."""


class JacobianError(ValueError):
    """A supplied derivative disagrees with finite differences of the residual."""


class Problem:
    """Base class (and protocol) for a smooth problem ``F(u, p) = 0``.

    Subclass it and override :meth:`residual`; override the optional methods
    that you can supply. An object that is not a subclass works too, as long
    as it has the same attributes (optional ones may be absent or ``None``).

    Attributes
    ----------
    name : str
        Recorded in a branch's metadata.
    parameters : dict, optional
        The fixed parameters (JSON-able), recorded in a branch's metadata.

    Methods
    -------
    residual(u, p) -> ndarray, shape (n,)
        Required. ``u`` has shape (n,), ``p`` is a float.
    jacobian(u, p) -> ndarray (n, n) | scipy.sparse matrix | BandedJacobian
        dF/du. Dense arrays are factorized with LAPACK, sparse and banded
        matrices with SuperLU. If absent: central differences, with one
        :class:`FiniteDifferenceWarning` per problem object.
    dfdp(u, p) -> ndarray, shape (n,)
        dF/dp. If absent: central differences (same warning).
    hessian(u, p) -> ndarray (N, N) | sparse
        For problems that are gradients of an energy: the symmetric Hessian.
        When present, the stability index (number of negative eigenvalues) is
        recorded at every point. A metric (an SPD mass matrix M in
        ``H v = mu M v``) needs no argument: by Sylvester's law of inertia it
        does not change the number of negative eigenvalues.
    constraint_jacobian(u, p) -> ndarray (m, N)
        Optional: the Hessian is restricted to the null space of this matrix
        (admissible directions). ``N`` may differ from ``n`` (e.g. ``u`` holds
        Lagrange multipliers that the energy variables do not).
    observables(u, p) -> dict[str, float]
        Optional: named scalars recorded at every point of a branch.
    """

    name: str = "problem"
    jacobian = None
    dfdp = None
    hessian = None
    constraint_jacobian = None
    observables = None

    def residual(self, u: np.ndarray, p: float) -> np.ndarray:
        raise NotImplementedError("Problem subclasses must implement residual(u, p)")


class FunctionProblem(Problem):
    """A :class:`Problem` assembled from plain functions.

    Parameters
    ----------
    residual : callable ``(u, p) -> (n,)``
    jacobian, dfdp, hessian, constraint_jacobian, observables : callable, optional
        As the methods of :class:`Problem`.
    name : str

    Examples
    --------
    >>> import numpy as np
    >>> prob = FunctionProblem(lambda u, p: u**3 - u - p,
    ...                        jacobian=lambda u, p: np.diag(3 * u**2 - 1),
    ...                        dfdp=lambda u, p: -np.ones_like(u), name="cubic")
    """

    def __init__(
        self,
        residual: Callable,
        jacobian: Callable | None = None,
        dfdp: Callable | None = None,
        hessian: Callable | None = None,
        constraint_jacobian: Callable | None = None,
        observables: Callable | None = None,
        name: str = "problem",
    ):
        self._residual = residual
        self.jacobian = jacobian
        self.dfdp = dfdp
        self.hessian = hessian
        self.constraint_jacobian = constraint_jacobian
        self.observables = observables
        self.name = name

    def residual(self, u, p):
        return self._residual(u, p)


_WARNED: weakref.WeakSet = weakref.WeakSet()

# Central-difference steps: eps**(1/3) balances O(h^2) truncation against
# O(eps/h) rounding, giving ~1e-10 relative accuracy on smooth problems.
_FD_REL = np.finfo(float).eps ** (1.0 / 3.0)


def _warn_fd_once(problem, missing: list[str]) -> None:
    try:
        if problem in _WARNED:
            return
        _WARNED.add(problem)
    except TypeError:  # not weak-referenceable: warn every time rather than never
        pass
    warnings.warn(
        f"problem {getattr(problem, 'name', type(problem).__name__)!r} does not supply "
        f"{' and '.join(missing)}; using central finite differences (2n residual "
        "evaluations per Jacobian). Supply them for speed; fold and branch-point "
        "locations stay exact, only Newton's convergence rate is affected.",
        FiniteDifferenceWarning,
        stacklevel=4,
    )


class Evaluator:
    """Uniform access to F, dF/du, dF/dp of a problem, with finite-difference fallbacks."""

    def __init__(self, problem):
        if not callable(getattr(problem, "residual", None)):
            raise TypeError(
                f"problem: expected an object with a method residual(u, p); got "
                f"{type(problem).__name__}. Subclass continuation.Problem or use "
                "continuation.FunctionProblem(residual, ...)."
            )
        self.problem = problem
        self._jac = getattr(problem, "jacobian", None)
        self._dfdp = getattr(problem, "dfdp", None)
        self.hessian = getattr(problem, "hessian", None)
        self.constraint_jacobian = getattr(problem, "constraint_jacobian", None)
        self.observables = getattr(problem, "observables", None)
        missing = []
        if self._jac is None:
            missing.append("jacobian (dF/du)")
        if self._dfdp is None:
            missing.append("dfdp (dF/dp)")
        self.fd_missing = missing
        self.nfev = 0
        self.njev = 0

    def warn_if_fd(self) -> None:
        if self.fd_missing:
            _warn_fd_once(self.problem, self.fd_missing)

    def F(self, u, p) -> np.ndarray:
        self.nfev += 1
        return np.asarray(self.problem.residual(u, p), dtype=float)

    def J(self, u, p):
        self.njev += 1
        if self._jac is not None:
            return as_matrix(self._jac(u, p))
        return fd_jacobian(lambda v: self.F(v, p), u)

    def Fp(self, u, p) -> np.ndarray:
        if self._dfdp is not None:
            return np.asarray(self._dfdp(u, p), dtype=float)
        h = _FD_REL * (1.0 + abs(p))
        return (self.F(u, p + h) - self.F(u, p - h)) / (2.0 * h)


def fd_jacobian(f: Callable, u: np.ndarray) -> np.ndarray:
    """Dense central-difference Jacobian of ``f`` at ``u`` (2n evaluations)."""
    n = u.size
    J = np.empty((f(u).size, n))
    for j in range(n):
        h = _FD_REL * (1.0 + abs(u[j]))
        e = u.copy()
        e[j] += h
        fp = f(e)
        e[j] = u[j] - h
        J[:, j] = (fp - f(e)) / (2.0 * h)
    return J


def check_jacobian(problem, u, p, rtol: float = 1e-5, n_directions: int = 3, seed: int = 0):
    """Compare a problem's dF/du and dF/dp with finite differences of its residual.

    Checks ``J v`` against ``(F(u + h v) - F(u - h v)) / 2h`` for a few random
    unit directions ``v``, and ``dF/dp`` against a central difference in p,
    each at two step sizes (the difference estimates the quotient's own
    error); cheap enough to run at
    every start. Counts ``4 * n_directions + 4`` residual evaluations.

    Parameters
    ----------
    problem : Problem
    u : ndarray, shape (n,)
    p : float
    rtol : float
        Allowed relative mismatch, ``|J v - FD| / max(|J v|, |FD|, 1e-8 |F|)``.
        Central differences are accurate to ~1e-10 relative, so 1e-5 flags only
        real errors (a wrong sign, a missing term, a transposed block).
    n_directions : int
    seed : int

    Returns
    -------
    float
        The worst relative mismatch found.

    Raises
    ------
    JacobianError
        If a mismatch exceeds ``rtol``; the message names the derivative, the
        mismatch, the worst component and what to try.
    """
    ev = Evaluator(problem)
    u = np.asarray(u, dtype=float)
    F0 = ev.F(u, p)
    scale_u = 1.0 + np.linalg.norm(u, np.inf)
    rng = np.random.default_rng(seed)
    worst = 0.0
    if ev._jac is not None:
        J = as_matrix(ev._jac(u, p))
        for _ in range(n_directions):
            v = rng.standard_normal(u.size)
            v /= np.linalg.norm(v)
            h = _FD_REL * scale_u
            fd = (ev.F(u + h * v, p) - ev.F(u - h * v, p)) / (2.0 * h)
            fd2 = (ev.F(u + 2 * h * v, p) - ev.F(u - 2 * h * v, p)) / (4.0 * h)
            jv = np.asarray(J @ v).ravel()
            err, comp = _rel_mismatch(jv, fd, F0, fd2)
            worst = max(worst, err)
            if err > rtol:
                raise JacobianError(
                    f"problem {getattr(problem, 'name', '')!r}: jacobian(u, p) disagrees with "
                    f"finite differences of residual(u, p) at p={p!r}: relative mismatch "
                    f"{err:.3e} > rtol={rtol:.1e} along a random direction, worst at "
                    f"component {comp} (J@v={jv[comp]:.6e}, FD={fd[comp]:.6e}). Check that "
                    "row/column of jacobian (sign, missing term, transposed block), or drop "
                    "jacobian to use finite differences."
                )
    if ev._dfdp is not None:
        h = _FD_REL * (1.0 + abs(p))
        fd = (ev.F(u, p + h) - ev.F(u, p - h)) / (2.0 * h)
        fd2 = (ev.F(u, p + 2 * h) - ev.F(u, p - 2 * h)) / (4.0 * h)
        fp = np.asarray(ev._dfdp(u, p), dtype=float)
        err, comp = _rel_mismatch(fp, fd, F0, fd2)
        worst = max(worst, err)
        if err > rtol:
            raise JacobianError(
                f"problem {getattr(problem, 'name', '')!r}: dfdp(u, p) disagrees with finite "
                f"differences of residual(u, p) in p at p={p!r}: relative mismatch {err:.3e} > "
                f"rtol={rtol:.1e}, worst at component {comp} (dfdp={fp[comp]:.6e}, "
                f"FD={fd[comp]:.6e}). Check dfdp, or drop it to use finite differences."
            )
    return worst


def _rel_mismatch(a, b, F0, b2):
    """Relative mismatch of ``a`` against the difference quotient ``b``.

    ``|b - b2|`` (two step sizes) estimates the difference quotient's own
    error; mismatches within 10 times that estimate are not counted, so a
    Jacobian that vanishes where F is cubic (a pitchfork) is not flagged.
    """
    diff = np.maximum(np.abs(a - b) - 10.0 * np.abs(b - b2), 0.0)
    scale = max(np.linalg.norm(a, np.inf), np.linalg.norm(b, np.inf),
                1e-8 * np.linalg.norm(F0, np.inf), 1e-300)
    comp = int(np.argmax(diff))
    return float(diff[comp] / scale), comp
