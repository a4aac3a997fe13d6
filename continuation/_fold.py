"""Two-parameter continuation of folds (minimally augmented system).

The second parameter ``q`` enters through a *problem family*: a callable
``family(q) -> Problem`` whose problems are continued in ``p``. This needs no
extra methods on the problem (an application builds its problem with ``p`` and
``q`` chosen by name), and ``dF/dq`` is taken by central differences in
``q``; that only affects Newton's convergence rate, not the computed fold
curve, which solves ``F = 0, g = 0`` to the Newton tolerance at each ``q``.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable

import numpy as np

from ._branch import Branch, SpecialPoint
from ._core import continue_branch, fold_gradient, fold_system
from ._linalg import bordered
from ._problem import Evaluator, Problem, check_jacobian
from ._settings import ContinuationSettings

# Central-difference step in q, relative: eps**(1/3) (truncation vs rounding).
_FDQ = np.finfo(float).eps ** (1.0 / 3.0)


class FoldProblem(Problem):
    """The minimally augmented fold system as a one-parameter problem in ``q``.

    Unknowns ``U = (u, p)`` (size n + 1); residual ``G(U, q) = (F(u, p; q),
    g(u, p; q))`` with ``g`` from the bordered system ``[[J, b], [c^T, 0]]
    [v; g] = [0; 1]`` (Govaerts 2000, sec. 4.2). The borders ``b, c`` are
    refreshed to the current left/right null vectors after every accepted
    step (as BifurcationKit does), keeping the bordered matrix well
    conditioned along the whole curve.

    Parameters
    ----------
    family : callable ``q -> Problem``
    b, c : ndarray, shape (n,)
        Initial left and right null-vector approximations.
    """

    def __init__(self, family: Callable, b, c, name="fold curve"):
        self.family = family
        self.b = np.asarray(b, dtype=float) / np.linalg.norm(b)
        self.c = np.asarray(c, dtype=float) / np.linalg.norm(c)
        self.n = self.b.size
        self.name = name
        self._cache: OrderedDict = OrderedDict()
        # the last bordered solve: the corrector asks for the residual and then the
        # Jacobian at the same point (the borders change only in _on_accept)
        self._last_key = None
        self._last_sys = None

    def _ev(self, q) -> Evaluator:
        q = float(q)
        ev = self._cache.get(q)
        if ev is None:
            ev = Evaluator(self.family(q))
            self._cache[q] = ev
            # The driver needs q, q +- h and a few trial values at a time.
            while len(self._cache) > 8:
                self._cache.popitem(last=False)
        return ev

    def _split(self, U):
        return U[: self.n], float(U[self.n])

    def _system(self, ev, U, q):
        key = (U.tobytes(), float(q))
        if key != self._last_key:
            u, p = self._split(U)
            self._last_sys = fold_system(ev, u, p, self.b, self.c)
            self._last_key = key
        return self._last_sys

    def residual(self, U, q):
        u, p = self._split(U)
        ev = self._ev(q)
        r = self._system(ev, U, q)
        g = r[0] if r is not None else math.nan
        return np.concatenate([ev.F(u, p), [g]])

    def jacobian(self, U, q):
        u, p = self._split(U)
        ev = self._ev(q)
        r = self._system(ev, U, q)
        if r is None:
            return np.full((self.n + 1, self.n + 1), np.nan)
        _, v, w, J = r
        gu, gp = fold_gradient(ev, u, p, v, w)
        return bordered(J, ev.Fp(u, p), gu, gp)

    def dfdp(self, U, q):
        h = _FDQ * (1.0 + abs(q))
        return (self.residual(U, q + h) - self.residual(U, q - h)) / (2.0 * h)

    def observables(self, U, q):
        u, p = self._split(U)
        out = {"p": p}
        base = self._ev(q)
        if base.observables is not None:
            out.update(base.observables(u, p))
        return out

    def _on_accept(self, U, q):
        u, p = self._split(U)
        r = fold_system(self._ev(q), u, p, self.b, self.c)
        if r is not None:
            _, v, w, _ = r
            nv, nw = np.linalg.norm(v), np.linalg.norm(w)
            if nv > 0 and nw > 0 and np.all(np.isfinite(v)) and np.all(np.isfinite(w)):
                self.c, self.b = v / nv, w / nw
                self._last_key = None


def continue_fold(
    family: Callable,
    fold: SpecialPoint,
    q0: float,
    settings: ContinuationSettings | None = None,
    *,
    parameter: str = "q",
    events=None,
    stop_on=(),
    callback=None,
) -> Branch:
    """Follow a fold in a second parameter ``q``: the fold curve ``p(q)``.

    Parameters
    ----------
    family : callable ``q -> Problem``
        Problems ``F(u, p; q)`` continued in ``p`` at fixed ``q``.
    fold : SpecialPoint
        A located fold of ``family(q0)`` (from :func:`continue_branch` or
        :func:`locate_fold`).
    q0 : float
        The value of ``q`` at which ``fold`` was computed.
    settings : ContinuationSettings, optional
        Steps, bounds (``p_min``/``p_max`` bound *q* here) and tolerances of the
        continuation in ``q``. Branch-point detection is turned off (a sign
        change of the augmented determinant would flag a codimension-2 point
        this library does not classify); folds in ``q`` (e.g. a cusp) are
        detected.
    parameter : str
        Name of ``q`` recorded in the branch.
    events, stop_on, callback
        As in :func:`continue_branch`; event functions receive ``(U, q)`` with
        ``U = (u, p)``.

    Returns
    -------
    Branch
        ``branch.p`` holds the values of ``q``; ``branch.observables["p"]`` the
        fold parameter ``p(q)`` (plus the problem's observables);
        ``branch.u[:, :-1]`` the states, ``branch.u[:, -1]`` ``p``.
    """
    settings = ContinuationSettings() if settings is None else settings
    if not isinstance(fold, SpecialPoint) or fold.kind != "fold" or fold.u is None:
        raise ValueError(f"fold: expected a SpecialPoint of kind 'fold' with a state; got {fold!r}")
    if not fold.located:
        raise ValueError(
            f"fold: the fold near p={fold.p:.10g} was only bracketed, not located "
            f"({fold.data.get('message', 'no message')}). Locate it first with locate_fold, "
            "or rerun continue_branch with a smaller ds_max.")
    q0 = float(q0)
    base = family(q0)
    bev = Evaluator(base)
    bev.warn_if_fd()
    u = np.asarray(fold.u, dtype=float)
    if settings.check_jacobian:
        check_jacobian(base, u, fold.p)
    v = np.asarray(fold.data.get("kernel", np.ones(u.size)), dtype=float)[: u.size]
    r = fold_system(bev, u, fold.p, v / np.linalg.norm(v), v / np.linalg.norm(v))
    w = r[2] if r is not None else v
    prob = FoldProblem(family, w, v, name=f"fold curve of {getattr(base, 'name', 'problem')}")
    s2 = settings.replace(detect_branch_points=False, compute_stability=False,
                          check_jacobian=False)
    U0 = np.concatenate([u, [fold.p]])
    br = continue_branch(prob, U0, q0, s2, events=events, stop_on=stop_on, callback=callback)
    br.parameter = parameter
    br.metadata["problem"] = getattr(base, "name", type(base).__name__)
    br.metadata["fold_curve"] = {"p0": float(fold.p), "q0": q0, "parameter": parameter}
    return br


def fold_crossings(
    family: Callable,
    fold: SpecialPoint,
    q0: float,
    q_target: float,
    settings: ContinuationSettings,
    *,
    parameter: str = "q",
    p_bounds: tuple[float, float] | None = None,
) -> tuple[list, Branch]:
    """Every point where the fold curve through ``fold`` crosses ``q = q_target``.

    Continues the fold curve (:func:`continue_fold`) both ways from ``(fold, q0)`` within
    ``[settings.p_min, settings.p_max]`` (bounds on q, which must contain ``q_target``) and
    locates its crossings of ``q_target`` (an event). Each crossing is a fold of
    ``family(q_target)``: a start for :class:`BranchSearch` that finds the branches through
    folds the one-parameter seeds missed, and an independent check of the folds a
    one-parameter search reports.

    ``p_bounds=(lo, hi)`` stops the curve where the fold parameter ``p`` leaves
    ``[lo, hi]`` (crossings outside the one-parameter range are of no use, and the curve
    beyond may be long).

    Returns
    -------
    (list of (u, p), Branch)
        The states and fold parameters at ``q = q_target`` (the starting fold itself when
        ``q0 == q_target``), and the fold curve.
    """
    if not settings.p_min <= q_target <= settings.p_max:
        raise ValueError(f"q_target={q_target!r} is outside [p_min, p_max] = "
                         f"[{settings.p_min!r}, {settings.p_max!r}] of the settings")
    name = "q_target"
    n = fold.u.size
    events = {name: lambda U, q: q - q_target}
    stop = []
    if p_bounds is not None:
        lo, hi = float(p_bounds[0]), float(p_bounds[1])
        events["p_below_range"] = lambda U, q: U[n] - lo
        events["p_above_range"] = lambda U, q: hi - U[n]
        stop = ["p_below_range", "p_above_range"]
    fc = continue_fold(family, fold, q0, settings, parameter=parameter, events=events,
                       stop_on=stop)
    out = []
    for sp in fc.points("event"):
        if sp.name == name and sp.located and sp.u is not None and (
                p_bounds is None or p_bounds[0] <= sp.u[n] <= p_bounds[1]):
            out.append((sp.u[:n].copy(), float(sp.u[n])))
    if fc.u is not None:  # a curve point exactly on q_target is not an event crossing
        for i in np.nonzero(fc.p == q_target)[0]:
            u, p = fc.u[i, :n], float(fc.u[i, n])
            if not any(abs(p - pp) <= 1e-12 * (1 + abs(p)) for _, pp in out):
                out.append((u.copy(), p))
    return out, fc
