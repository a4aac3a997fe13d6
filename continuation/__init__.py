"""continuation: numerical continuation of equilibria F(u, p) = 0 (numpy/scipy only).

A library for any smooth problem; it knows nothing about rods or drops.
(Not the unrelated PyPI project of the same name.)

Public API
----------
Problem
    Base class / protocol: ``residual(u, p)`` (required), optional
    ``jacobian(u, p)`` (dense ndarray, ``scipy.sparse`` or
    :class:`BandedJacobian`; the solver follows the type), ``dfdp(u, p)``,
    ``hessian(u, p)`` and ``constraint_jacobian(u, p)`` (stability),
    ``observables(u, p) -> dict[str, float]`` (recorded at every point).
    Missing derivatives fall back to central differences with one
    :class:`FiniteDifferenceWarning` per problem.
FunctionProblem(residual, jacobian=None, dfdp=None, ...)
    A Problem from plain functions.
ContinuationSettings(ds0, ds_min, ds_max, max_steps, p_min, p_max, direction, newton_tol, ...)
    Frozen, validated; errors quote the field and value.
continue_branch(problem, u0, p0, settings=None, *, events=None, stop_on=(), callback=None,
                tangent=None) -> Branch
    Newton at p0, then pseudo-arclength continuation (Keller or Moore-Penrose),
    bordered LU solves, adaptive steps, fold/branch-point/stability/event detection
    and exact location. ``direction=0`` continues both ways from the start.
locate_fold(problem, u, p, v=None, tol=1e-12) -> SpecialPoint
    Newton on the minimally augmented fold system.
switch_branch(problem, branch_point, settings=None, *, ds=None) -> Branch
    Branch switching at a simple branch point (algebraic bifurcation equation),
    with a check that the new branch is not the old one.
continue_fold(family, fold, q0, settings=None, *, parameter="q") -> Branch
    Two-parameter fold continuation; ``family(q) -> Problem``. ``branch.p`` is q,
    ``branch.observables["p"]`` the fold parameter p(q).
check_jacobian(problem, u, p, rtol=1e-5) -> float
    Compare supplied derivatives with finite differences; raises JacobianError.
Branch
    ``p, u, tangent, ds, newton_iterations, stability, observables, special_points,
    status, message, parameter, metadata``; ``folds``, ``branch_points``,
    ``points(kind)``, ``save(path)``, ``Branch.load(path)``, ``plot(ax, y=name)``.
SpecialPoint(kind, index, p, u, precision, located, name, data)
    kind in {"fold", "branch_point", "stability", "event", "endpoint"}.
Status codes: MAX_STEPS, PARAMETER_BOUND, STEP_TOO_SMALL, START_FAILED, STOPPED,
NON_FINITE, LOOP_CLOSED (``Branch.status``; ``Branch.message`` says what to try).

fold_crossings(family, fold, q0, q_target, settings) -> ([(u, p), ...], Branch)
    The points where the fold curve through a fold crosses q = q_target (starts for a
    search, and the check of a one-parameter search's folds).
BranchSearch(problem, continuation_settings, SearchSettings(...), *, starts, seeds, events,
             stop_on, parameter, accept)
    Deflated multi-start search for every branch over [p_min, p_max] (an iterator of
    new branches; ``.run() -> SearchResult``). The problem may supply ``seeds(p)`` and
    ``deflation_indices``. The completeness argument is in its module docstring
    (``continuation._search``) and in ``help(BranchSearch)``.
search_branches(problem, continuation_settings, settings=None, **kw) -> SearchResult
deflated_newton(problem, u0, p, known=(), *, tol, max_iter, max_step, indices) -> NewtonResult
point_on_branch(problem, u, p, branch, ...) -> bool

FoldProblem(family, b, c)
    The minimally augmented fold system as a one-parameter problem in q (used by
    continue_fold; exposed for users who drive it themselves).
inertia_negative(H, C=None) -> int
    The stability-index kernel (see below).
factorize(A) -> Factor or None
    The LU kernel of the correctors: ``solve(b, trans=False)``, ``det_sign()``; None
    for a singular or non-finite matrix. Dense rows with a single nonzero are pivoted
    on before LAPACK (a constraint fixing one unknown costs no LU work).
continuation.examples
    Reference problems with known answers: Bratu (FD order 2 or Chebyshev),
    Pitchfork, Cusp / cusp_family, BRATU_FOLD.

Two-parameter problems
----------------------
The second parameter q enters through a *problem family* ``family(q) -> Problem``
(e.g. ``lambda q: build_problem(param="delta", fixed={"area": q})``): no extra
methods are needed, dF/dq is taken by central differences (this affects only
Newton's convergence rate; the fold curve solves F = 0, g = 0 at every q).

Example
-------
>>> import numpy as np
>>> from continuation import ContinuationSettings, continue_branch
>>> from continuation.examples import Bratu
>>> prob = Bratu(24, "chebyshev")          # u'' + lam e^u = 0, 23 unknowns
>>> br = continue_branch(prob, np.zeros(prob.n), 0.0,
...                      ContinuationSettings(ds_max=0.5, p_max=4.0, max_steps=40))
>>> abs(br.folds[0].p - 3.513830719125161) < 1e-12
True

Stability index
---------------
With ``hessian`` (N x N, symmetric) and optionally ``constraint_jacobian`` C
(m x N, full row rank), the index is the number of negative eigenvalues of the
Hessian restricted to null(C), computed as the inertia of the KKT matrix
``[[H, C^T], [C, 0]]`` minus m (an LDL^T factorization; no null-space basis). Rows of
C with a single nonzero fix that unknown and are eliminated first.
"""

from ._branch import (
    LOOP_CLOSED,
    MAX_STEPS,
    NON_FINITE,
    PARAMETER_BOUND,
    START_FAILED,
    STEP_TOO_SMALL,
    STOPPED,
    Branch,
    SpecialPoint,
    __version__,
)
from ._core import continue_branch, locate_fold, switch_branch
from ._fold import FoldProblem, continue_fold, fold_crossings
from ._linalg import BandedJacobian, Factor, factorize, inertia_negative
from ._problem import (
    FiniteDifferenceWarning,
    FunctionProblem,
    JacobianError,
    Problem,
    check_jacobian,
)
from ._search import (
    BranchSearch,
    NewtonResult,
    SearchResult,
    SearchSettings,
    deflated_newton,
    point_on_branch,
    search_branches,
)
from ._settings import ContinuationSettings

__all__ = [
    "__version__",
    "Problem", "FunctionProblem", "BandedJacobian", "ContinuationSettings",
    "continue_branch", "locate_fold", "switch_branch", "continue_fold", "FoldProblem",
    "fold_crossings", "BranchSearch", "SearchSettings", "SearchResult", "search_branches",
    "deflated_newton", "NewtonResult", "point_on_branch",
    "check_jacobian", "inertia_negative", "factorize", "Factor", "Branch", "SpecialPoint",
    "FiniteDifferenceWarning", "JacobianError",
    "MAX_STEPS", "PARAMETER_BOUND", "STEP_TOO_SMALL", "START_FAILED", "STOPPED",
    "NON_FINITE", "LOOP_CLOSED",
]
