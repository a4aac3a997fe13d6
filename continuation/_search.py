"""Deflated multi-start branch search: every branch of ``F(u, p) = 0`` over ``[p_min, p_max]``.

The design follows BifurcationKit's ``DeflatedContinuation`` (problem / parameters /
iterator / result): a problem (any :class:`continuation.Problem`, optionally with
``seeds(p)``), frozen :class:`SearchSettings`, an iterator :class:`BranchSearch` that yields
each branch as it is found, and a plain-data :class:`SearchResult`.

The algorithm
-------------
Let ``P = {p_0 = p_min < p_1 < ... < p_K = p_max}`` be the *sample values* (the two range
ends, ``SearchSettings.samples`` interior values, and any the caller adds).

1. **Starts.** Each supplied start ``(u, p)`` (a known solution or a good guess, e.g. the
   trivial state, or a point of a fold curve, see :func:`continuation.fold_crossings`) is
   Newton-corrected and continued both ways.
2. **Recording.** Every computed branch is cut at every sample value it crosses and the
   crossing is Newton-corrected there: the *known solutions* at each ``p_k``.
3. **Deflated seeds.** At each sample ``p_k``, Newton is started from every seed the
   problem supplies (``problem.seeds(p_k)``, first round) and from every known solution
   at the neighbouring samples ``p_{k-1}``, ``p_{k+1}`` not tried there before (deflated
   continuation, Farrell, Beentjes & Birkisson 2016), each *deflated* against the
   solutions known at ``p_k`` (Farrell, Birkisson & Funke 2015: the residual is
   multiplied by ``prod_i (|u - u_i|^-power + shift)``, so Newton cannot converge to a
   known solution). A new solution starts a new branch, continued both ways and
   recorded (step 2) before the next seed is tried.
4. **Branch switching** at every located simple branch point of every branch, and
   deflated seeds next to every special point that could not be located and every branch
   end inside the range: at ``p`` a little to either side, Newton from the point's state
   deflated against every known solution there (the other branch through an unlocated
   branch point, e.g. where a branch turns at a pitchfork, is found this way).
5. Steps 3-4 repeat (new known solutions give new neighbour seeds) until a round finds
   nothing new (at most ``max_rounds`` rounds).

Why it is complete, and what it can miss
----------------------------------------
A branch is found if any one of these holds: (a) it crosses some sample value ``p_k``
inside the basin of attraction of one of the deflated seeds or of a neighbour solution
there (deflation removes the known solutions from the problem at ``p_k``, so a seed that
would fall back onto a known branch is pushed towards an unknown one or fails); (b) it is
connected to a found branch through a simple branch point, or passes near a special
point or an interior end of a found branch within the basin of the deflated Newton
started there; (c) it passes through a
supplied start (for example it carries a fold that a fold curve in a second parameter
crosses). The range ends are samples, so a branch that reaches either end is subject to
(a) there; the neighbour seeds make the search independent of how well the problem's own
seeds fit one particular parameter value, since a solution found at one sample is tried,
deflated, at the next. Along a found branch no fold is stepped over: the continuation
shortens its steps where dp/ds falls towards zero and rejects a step whose p moves
against dp/ds at both ends (the two folds of an S next to a cusp inside one step). At
the fixed point of step 5 every known solution at every sample has been used as a
deflated seed at its neighbours and every branch point has been switched.

What it can still miss: an *isola* (a closed branch) or a branch segment that lies
entirely between two consecutive samples, is outside every seed's deflated basin, is not
connected through a simple branch point to a found branch, and contains no supplied start;
branches connected to the found ones only through degenerate (non-simple) branch
points, where switching is not attempted; and two folds inside one step whose p moves
with dp/ds at both ends (the step overshoots the whole S). Add samples (``samples``,
``sample_values``), seeds or starts (a point of a fold curve), or lower ``ds_max``, to
close such gaps; a search whose result does not change when they are doubled is complete
for the problem's solution set up to that resolution.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np

from ._branch import Branch
from ._core import continue_branch, switch_branch
from ._linalg import as_matrix, factorize
from ._problem import Evaluator
from ._settings import ContinuationSettings, checked_fields

__all__ = [
    "BranchSearch",
    "NewtonResult",
    "SearchResult",
    "SearchSettings",
    "deflated_newton",
    "point_on_branch",
    "search_branches",
]


# ================================================================== settings
@dataclass(frozen=True)
class SearchSettings:
    """Immutable settings of :class:`BranchSearch` (validated; errors quote the field).

    Parameters
    ----------
    samples : int
        Interior sample values, uniformly spaced in ``(p_min, p_max)``; the two range ends
        are always samples too. Deflated seeds are tried at every sample.
    sample_values : tuple of float
        Extra sample values (inside the range), e.g. the problem's own parameter value.
    newton_tol : float or None
        Absolute tolerance on ``max|F|`` of the seed Newton; ``None``: the continuation
        settings' ``newton_tol``.
    max_newton : int
        Iterations of a seed Newton (deflated Newton from far seeds needs more than a
        corrector; 25 is ample with the damping below).
    max_step : float
        Damping: the largest change of any deflated component per Newton iteration (in the
        units of ``u``). ``math.inf``: undamped.
    deflation_power, deflation_shift : float
        The deflation operator ``prod_i (|u - u_i|^-power + shift)`` (Farrell et al. 2015:
        power 2, shift 1).
    same_tol : float
        Two solutions at the same parameter value are the same when they differ by at most
        this (max norm over the deflated components).
    match_radius : float
        A new branch is compared with a known one where the known one's interpolated state
        is within this distance (max norm) of the new one's; a Newton correction then
        decides. Larger is safer and slower.
    neighbour_seeds : bool
        Use the known solutions at the neighbouring samples as extra deflated seeds.
    switch : bool
        Switch branches at every located simple branch point.
    max_branches : int
        Stop the search (with a note in the result) after this many branches.
    max_rounds : int
        Rounds of steps 3-4 (see the module docstring); the search stops earlier at a
        round that finds nothing new.
    """

    samples: int = 4
    sample_values: tuple = ()
    newton_tol: float | None = None
    max_newton: int = 25
    max_step: float = 0.5
    deflation_power: float = 2.0
    deflation_shift: float = 1.0
    same_tol: float = 1e-6
    match_radius: float = 0.2
    neighbour_seeds: bool = True
    switch: bool = True
    max_branches: int = 64
    max_rounds: int = 3

    def __post_init__(self):
        def bad(f, v, expected):
            raise ValueError(f"SearchSettings.{f}={v!r}: expected {expected}.")

        for f in ("samples",):
            v = getattr(self, f)
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
                bad(f, v, "an integer >= 0")
        for f in ("max_newton", "max_branches", "max_rounds"):
            v = getattr(self, f)
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= 1):
                bad(f, v, "an integer >= 1")
        for f in ("max_step", "deflation_power", "same_tol", "match_radius"):
            v = getattr(self, f)
            if not (isinstance(v, int | float) and v > 0 and not math.isnan(v)):
                bad(f, v, "a number > 0")
        if not (self.deflation_shift >= 0 and math.isfinite(self.deflation_shift)):
            bad("deflation_shift", self.deflation_shift, "a finite number >= 0")
        if self.newton_tol is not None and not (
                isinstance(self.newton_tol, int | float) and math.isfinite(self.newton_tol)
                and self.newton_tol > 0):
            bad("newton_tol", self.newton_tol, "None or a finite number > 0")
        try:
            vals = tuple(float(v) for v in self.sample_values)
        except (TypeError, ValueError):
            bad("sample_values", self.sample_values, "a sequence of numbers")
        if not all(math.isfinite(v) for v in vals):
            bad("sample_values", self.sample_values, "finite numbers")
        object.__setattr__(self, "sample_values", vals)

    def replace(self, **changes) -> SearchSettings:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """Plain JSON data: every field; an undamped ``max_step`` (inf) is ``None`` (JSON
        ``null``: no limit). :meth:`from_dict` reads it back."""
        d = dataclasses.asdict(self)
        d["sample_values"] = list(self.sample_values)
        d["max_step"] = None if math.isinf(self.max_step) else self.max_step
        return d

    @classmethod
    def from_dict(cls, d: dict) -> SearchSettings:
        """The settings :meth:`to_dict` wrote (``max_step`` ``None``: undamped)."""
        d = checked_fields(cls, d)
        if d.get("max_step", 0.0) is None:
            d["max_step"] = math.inf
        if "sample_values" in d:
            d["sample_values"] = tuple(d["sample_values"])
        return cls(**d)


# ================================================================== deflated Newton
@dataclass
class NewtonResult:
    """Outcome of :func:`deflated_newton`.

    Attributes
    ----------
    u : ndarray
        The last iterate (the solution when ``converged``).
    converged : bool
    iterations : int
    residual : float
        ``max|F|`` at ``u``.
    reason : str
        Why it stopped when not converged ("" otherwise).
    """

    u: np.ndarray
    converged: bool
    iterations: int
    residual: float
    reason: str = ""


def deflated_newton(
    problem,
    u0,
    p: float,
    known: Iterable = (),
    *,
    tol: float = 1e-11,
    max_iter: int = 40,
    max_step: float = math.inf,
    indices=None,
    power: float = 2.0,
    shift: float = 1.0,
) -> NewtonResult:
    """Damped, optionally deflated Newton for ``F(u, p) = 0`` at fixed ``p``.

    Parameters
    ----------
    problem : Problem
        Needs ``residual``; ``jacobian`` if present (else central differences).
    u0 : array_like, shape (n,)
    p : float
    known : iterable of ndarray
        Known solutions at ``p``; the deflation operator
        ``m(u) = prod_i (1 / |u - u_i|^power + shift)`` (norm over ``indices``) keeps
        Newton away from them (Farrell, Birkisson & Funke 2015). The deflated step is the
        plain step scaled by ``1 / (1 - grad(ln m) . du)`` (Sherman-Morrison).
    tol : float
        Converged when ``max|F| <= tol`` (absolute).
    max_iter : int
    max_step : float
        Damping: the step is scaled so that no component in ``indices`` changes by more.
    indices : index array, slice or None
        The components that deflation measures and damping limits (default: all), e.g.
        the state without Lagrange multipliers.

    Returns
    -------
    NewtonResult
        Never raises for a numerical failure; divergence (the residual grows by 1e6 over
        its first value), stagnation (no halving in 12 iterations), a singular Jacobian
        and non-finite values end the iteration with ``converged=False`` and a reason.
    """
    ev = Evaluator(problem)
    u = np.array(u0, dtype=float).ravel()
    idx = slice(None) if indices is None else indices
    # the known solutions' deflated components, one row each (the deflation factor and its
    # gradient are then a few array operations, whatever their number)
    kd = (np.array([np.asarray(k, dtype=float).ravel()[idx] for k in known])
          if known else None)
    if kd is not None and kd.size == 0:
        kd = None
    r_first = None
    rn = math.inf
    with np.errstate(all="ignore"):
        for it in range(max_iter + 1):
            r = ev.F(u, p)
            rn = float(np.abs(r).max()) if r.size else 0.0
            if not math.isfinite(rn):
                return NewtonResult(u, False, it, math.inf, "non-finite residual")
            if rn <= tol:
                return NewtonResult(u, True, it, rn)
            if it == max_iter:
                break
            r_first = rn if r_first is None else r_first
            if rn > 1e6 * r_first:
                return NewtonResult(u, False, it, rn, "diverging (residual grew by 1e6)")
            if it >= 12 and rn > 0.5 * r_first:
                return NewtonResult(u, False, it, rn,
                                    "stagnating (no halving in 12 iterations)")
            fac = factorize(as_matrix(ev.J(u, p)))
            if fac is None:
                return NewtonResult(u, False, it, rn, "singular Jacobian")
            du = fac.solve(-r)
            if kd is not None:
                e = u[idx] - kd
                r2 = np.einsum("ij,ij->i", e, e)
                if not r2.all():
                    return NewtonResult(u, False, it, rn, "landed on a known solution")
                rp = r2 if power == 2.0 else r2 ** (0.5 * power)
                # d/du ln(r^-power + shift) = -power r^(-power-2) e / (r^-power + shift)
                # = -power e / (r^2 (1 + shift r^power)), summed over the known solutions
                coef = -power / (r2 * (1.0 + shift * rp))
                den = 1.0 - float(coef @ (e @ du[idx]))
                if den == 0.0 or not math.isfinite(den):
                    return NewtonResult(u, False, it, rn, "deflation singular")
                du = du / den
            big = float(np.abs(du[idx]).max()) if du[idx].size else 0.0
            if not math.isfinite(big):
                return NewtonResult(u, False, it, rn, "non-finite Newton step")
            u = u + (du if big <= max_step else du * (max_step / big))
    return NewtonResult(u, False, max_iter, rn,
                        f"not converged in {max_iter} iterations (max|F|={rn:.2e} > {tol:.1e})")


def point_on_branch(problem, u, p: float, branch: Branch, *, tol: float = 1e-11,
                    same_tol: float = 1e-6, match_radius: float = 0.2, indices=None) -> bool:
    """Whether the solution ``(u, p)`` lies on ``branch`` (which must store its states).

    For every step of the branch that brackets ``p`` and whose linearly interpolated state
    is within ``match_radius`` of ``u`` (max norm over ``indices``), Newton at ``p`` from
    the interpolation decides: the branch passes through ``u`` when it converges to within
    ``same_tol`` of ``u``.
    """
    if branch.u is None or len(branch) == 0:
        return False
    idx = slice(None) if indices is None else indices
    u = np.asarray(u, dtype=float)
    bp = branch.p
    for i in range(len(branch) - 1):
        a, b = bp[i], bp[i + 1]
        if (a - p) * (b - p) > 0.0:
            continue
        w = 0.0 if a == b else (p - a) / (b - a)
        guess = (1 - w) * branch.u[i] + w * branch.u[i + 1]
        if np.max(np.abs(guess[idx] - u[idx])) > match_radius:
            continue
        res = deflated_newton(problem, guess, p, tol=tol, max_iter=12, indices=indices)
        if res.converged and np.max(np.abs(res.u[idx] - u[idx])) <= same_tol:
            return True
    if len(branch) == 1:
        return bool(abs(bp[0] - p) <= 1e-12 * (1 + abs(p))
                    and np.max(np.abs(branch.u[0][idx] - u[idx])) <= same_tol)
    return False


# ================================================================== result
@dataclass
class SearchResult:
    """Every branch a :class:`BranchSearch` found, with how it was found (plain data).

    Attributes
    ----------
    branches : list of Branch
    origins : list of dict
        One per branch: ``{"how": "start" | "seed" | "neighbour" | "switch" |
        "special_point", "p": ...}``
        plus ``seed`` (its index) or ``branch`` (the parent branch of a switch).
    samples : ndarray
        The sample values.
    known : list of list of ndarray
        The known solutions at each sample (recorded crossings).
    parameter : str
        Name of the continued parameter.
    stats : dict
        Counts (``seeds_tried``, ``seeds_converged``, ``seeds_new``, ``starts_failed``,
        ``switches``, ``switches_new``, ``rounds``), ``wall_time_s``, and ``notes`` (a
        list of strings: anything that limited the search).
    settings : dict
        The search and continuation settings.
    """

    branches: list = field(default_factory=list)
    origins: list = field(default_factory=list)
    samples: np.ndarray = field(default_factory=lambda: np.empty(0))
    known: list = field(default_factory=list)
    parameter: str = "p"
    stats: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """True when at least one branch was found."""
        return bool(self.branches)

    def special_points(self, kind: str) -> list:
        """``(branch index, SpecialPoint)`` of one kind over every branch."""
        return [(b, sp) for b, br in enumerate(self.branches) for sp in br.points(kind)]

    def to_dict(self) -> dict:
        """JSON-able summary (no state arrays)."""
        return {
            "parameter": self.parameter,
            "samples": [float(v) for v in self.samples],
            "known_per_sample": [len(k) for k in self.known],
            "branches": [
                {"origin": o, "n_points": len(b),
                 "range": [float(b.p.min()), float(b.p.max())] if len(b) else None,
                 "status": b.metadata.get("end_status")}
                for b, o in zip(self.branches, self.origins, strict=True)
            ],
            "stats": self.stats,
            "settings": self.settings,
        }


#: Branch ends (status names) next to which deflated seeds are tried: the ends where the
#: continuation failed, not those where it reached a bound or a terminal event.
_SEED_ENDS = ("step_too_small", "non_finite", "max_steps")


def _relocate_branch_point(problem, br: Branch, sp, cont: ContinuationSettings,
                           events, stop_on):
    """Locate a bracketed branch point by continuing again across its bracket with steps
    of an eighth of it; the located point (or None)."""
    k = sp.index
    if br.u is None or br.tangent is None or not 1 <= k < len(br):
        return None
    x0 = np.concatenate([br.u[k - 1], [br.p[k - 1]]])
    x1 = np.concatenate([br.u[k], [br.p[k]]])
    n = br.u.shape[1]
    wu = cont.theta / n
    d = x1 - x0
    arc = math.sqrt(wu * float(d[:n] @ d[:n]) + (1 - cont.theta) * float(d[n] ** 2))
    if not arc > 0:
        return None
    for frac in (8.0, 5.0, 13.0):  # other step sizes put other points next to it
        ds = arc / frac
        sub = cont.replace(ds0=max(ds, cont.ds_min), ds_max=max(ds, cont.ds_min),
                           ds_min=min(cont.ds_min, ds / 64), max_steps=int(frac) + 4,
                           step_grow=1.0, direction=1, check_jacobian=False)
        t = br.tangent[k - 1]
        nb = continue_branch(problem, br.u[k - 1], float(br.p[k - 1]), sub, tangent=t)
        for q in nb.branch_points:
            if q.located and "kernel" in q.data:
                return q
    return None


# ================================================================== the iterator
class BranchSearch:
    """Deflated multi-start search for every branch over a parameter range (an iterator).

    Iterating yields each new :class:`Branch` as it is found; :meth:`run` runs the search
    to the end and returns the :class:`SearchResult` (also available as ``.result``
    during and after iteration). The problem is never modified.

    Parameters
    ----------
    problem : Problem
        ``residual(u, p)`` (required), ``jacobian``, ... as for :func:`continue_branch`;
        optionally ``seeds(p) -> iterable of ndarray`` (initial guesses at parameter ``p``,
        chosen from the problem's physics) and ``deflation_indices`` (the components that
        deflation measures, e.g. without multipliers; default all).
    continuation : ContinuationSettings
        Settings of every continuation; ``p_min`` and ``p_max`` (finite) are the search
        range, ``direction`` is ignored (branches are continued both ways).
    settings : SearchSettings, optional
    starts : iterable of (u, p), optional
        Known solutions or guesses, started before the seeds.
    seeds : callable ``p -> iterable of ndarray``, optional
        Overrides ``problem.seeds``.
    events, stop_on : as in :func:`continue_branch`
        Passed to every continuation (e.g. a domain boundary that ends branches).
    parameter : str
        Name of ``p`` recorded in every branch (``Branch.parameter``).
    accept : callable ``(u, p) -> bool``, optional
        A solution for which it returns False is not continued (e.g. outside the domain).
    continuer : callable, optional
        How a solution becomes a branch: ``continuer(problem, u, p, settings, events=...,
        stop_on=...) -> Branch``, called with the search's continuation settings
        (``direction`` 0: both ways) wherever the search continues a start or a new
        solution. Default :func:`continue_branch`. A problem that is smooth only piecewise
        (e.g. a complementarity residual ``min(a, b)`` whose pieces are continued one at a
        time and joined where the active piece changes) supplies its own; the branch it
        returns must store its states (``u``) in the problem's unknowns, so that recording,
        deflation and the duplicate test work on it as on any branch.

    Examples
    --------
    >>> import numpy as np
    >>> from continuation import FunctionProblem, ContinuationSettings, BranchSearch
    >>> prob = FunctionProblem(lambda u, p: u**3 - p * u,
    ...                        jacobian=lambda u, p: np.diag(3 * u**2 - p),
    ...                        dfdp=lambda u, p: -u)
    >>> prob.seeds = lambda p: [np.array([-2.0]), np.array([0.1]), np.array([2.0])]
    >>> res = BranchSearch(prob, ContinuationSettings(p_min=-1.0, p_max=2.0, ds_max=0.1,
    ...                    check_jacobian=False)).run()
    >>> len(res.branches)   # u = 0 and the parabola u^2 = p (through the pitchfork)
    2
    """

    def __init__(
        self,
        problem,
        continuation: ContinuationSettings,
        settings: SearchSettings | None = None,
        *,
        starts: Iterable = (),
        seeds: Callable | None = None,
        events: Mapping[str, Callable] | None = None,
        stop_on=(),
        parameter: str = "p",
        accept: Callable | None = None,
        continuer: Callable | None = None,
    ):
        if not isinstance(continuation, ContinuationSettings):
            raise TypeError("continuation: expected ContinuationSettings; got "
                            f"{type(continuation).__name__}")
        if not (math.isfinite(continuation.p_min) and math.isfinite(continuation.p_max)):
            raise ValueError(
                f"continuation: p_min={continuation.p_min!r}, p_max={continuation.p_max!r}; "
                "a search needs a finite range (set both)")
        self.settings = SearchSettings() if settings is None else settings
        if not isinstance(self.settings, SearchSettings):
            raise TypeError(f"settings: expected SearchSettings; got {type(settings).__name__}")
        self.problem = problem
        self.cont = continuation.replace(direction=0, store_states=True)
        self.starts = [(np.asarray(u, dtype=float).ravel(), float(p)) for u, p in starts]
        self.seed_fn = seeds if seeds is not None else getattr(problem, "seeds", None)
        self.events = dict(events or {})
        self.stop_on = tuple(stop_on)
        self.parameter = parameter
        self.accept = accept
        self.continuer = continue_branch if continuer is None else continuer
        self.indices = getattr(problem, "deflation_indices", None)
        s = self.settings
        lo, hi = self.cont.p_min, self.cont.p_max
        for v in s.sample_values:
            if not lo <= v <= hi:
                raise ValueError(f"SearchSettings.sample_values: {v!r} is outside the range "
                                 f"[{lo!r}, {hi!r}]")
        vals = set(np.linspace(lo, hi, s.samples + 2).tolist()) | set(s.sample_values)
        self.samples = np.array(sorted(vals))
        self.tol = self.cont.newton_tol if s.newton_tol is None else s.newton_tol
        self.result = SearchResult(
            samples=self.samples, known=[[] for _ in self.samples], parameter=parameter,
            stats={"seeds_tried": 0, "seeds_converged": 0, "seeds_new": 0, "starts": 0,
                   "starts_failed": 0, "switches": 0, "switches_new": 0, "rounds": 0,
                   "duplicates": 0, "notes": []},
            settings={"search": s.to_dict(), "continuation": self.cont.to_dict()},
        )
        self._switched: set = set()
        self._tried: dict = {}

    # ------------------------------------------------------------------ helpers
    def _newton(self, u, p, known):
        s = self.settings
        return deflated_newton(self.problem, u, p, known, tol=self.tol, max_iter=s.max_newton,
                               max_step=s.max_step, indices=self.indices,
                               power=s.deflation_power, shift=s.deflation_shift)

    def _same(self, u, v) -> bool:
        idx = slice(None) if self.indices is None else self.indices
        return float(np.max(np.abs(u[idx] - v[idx]))) <= self.settings.same_tol

    def _known_at(self, k, u) -> bool:
        return any(self._same(u, v) for v in self.result.known[k])

    def _on_known_branch(self, u, p) -> bool:
        s = self.settings
        return any(point_on_branch(self.problem, u, p, br, tol=self.tol, same_tol=s.same_tol,
                                   match_radius=s.match_radius, indices=self.indices)
                   for br in self.result.branches)

    def _duplicate(self, br: Branch) -> bool:
        """The new branch is a known one: its points at 1/4 and 3/4 of its length (away
        from a branch point it may start from) both lie on one known branch."""
        m = len(br)
        if m == 0:
            return True
        picks = sorted({m // 4, (3 * m) // 4})
        s = self.settings
        for old in self.result.branches:
            if all(point_on_branch(self.problem, br.u[i], float(br.p[i]), old, tol=self.tol,
                                   same_tol=s.same_tol, match_radius=s.match_radius,
                                   indices=self.indices) for i in picks):
                return True
        return False

    def _record(self, br: Branch) -> None:
        """Newton-correct the branch's crossings of every sample value (known solutions)."""
        for k, pk in enumerate(self.samples):
            for i in range(len(br) - 1):
                a, b = br.p[i], br.p[i + 1]
                if (a - pk) * (b - pk) > 0.0 or (a == b):
                    continue
                w = (pk - a) / (b - a)
                if w == 1.0 and i + 1 < len(br) - 1:
                    continue  # counted on the next step
                guess = (1 - w) * br.u[i] + w * br.u[i + 1]
                res = self._newton(guess, pk, ())
                if res.converged and not self._known_at(k, res.u):
                    self.result.known[k].append(res.u)
            if len(br) == 1 and br.p[0] == pk and not self._known_at(k, br.u[0]):
                self.result.known[k].append(br.u[0].copy())

    def _continue(self, u, p, origin) -> Branch | None:
        if self.accept is not None and not self.accept(u, p):
            return None
        br = self.continuer(self.problem, u, p, self.cont, events=self.events,
                            stop_on=self.stop_on)
        return self._add(br, origin)

    def _add(self, br: Branch, origin) -> Branch | None:
        if not len(br):
            self.result.stats["starts_failed"] += 1
            self.result.stats["notes"].append(
                f"a start at p={origin.get('p')!r} ({origin['how']}) failed: {br.message}")
            return None
        if self._duplicate(br):
            self.result.stats["duplicates"] += 1
            return None
        br.parameter = self.parameter
        br.metadata["origin"] = origin
        self.result.branches.append(br)
        self.result.origins.append(origin)
        self._record(br)
        return br

    def _full(self) -> bool:
        if len(self.result.branches) >= self.settings.max_branches:
            note = (f"stopped at max_branches={self.settings.max_branches}; raise it to "
                    "continue the search")
            if note not in self.result.stats["notes"]:
                self.result.stats["notes"].append(note)
            return True
        return False

    # ------------------------------------------------------------------ the stages
    def _starts(self) -> Iterator[Branch]:
        st = self.result.stats
        lo, hi = self.cont.p_min, self.cont.p_max
        for j, (u, p) in enumerate(self.starts):
            if self._full():
                return
            st["starts"] += 1
            if not lo <= p <= hi:
                st["notes"].append(f"start {j} at p={p!r} is outside [{lo!r}, {hi!r}]: skipped")
                continue
            res = self._newton(u, p, ())
            if not res.converged:
                st["starts_failed"] += 1
                st["notes"].append(f"start {j} at p={p!r}: Newton failed ({res.reason})")
                continue
            if self._on_known_branch(res.u, p):
                st["duplicates"] += 1
                continue
            br = self._continue(res.u, p, {"how": "start", "p": p, "start": j})
            if br is not None:
                yield br

    def _seed_round(self, first: bool) -> Iterator[Branch]:
        """One round of deflated seeds at every sample: the problem's seeds (first round
        only) and the known solutions at the neighbouring samples not tried before."""
        st = self.result.stats
        s = self.settings
        K = len(self.samples)
        for k, pk in enumerate(self.samples):
            pk = float(pk)
            tries = []
            if first and self.seed_fn is not None:
                tries += [("seed", j, u) for j, u in enumerate(self.seed_fn(pk))]
            if s.neighbour_seeds:
                for kk in (k - 1, k + 1):
                    if not 0 <= kk < K:
                        continue
                    done = self._tried.setdefault((k, kk), 0)
                    tries += [("neighbour", float(self.samples[kk]), u)
                              for u in list(self.result.known[kk])[done:]]
                    self._tried[(k, kk)] = len(self.result.known[kk])
            for how, tag, u0 in tries:
                if self._full():
                    return
                st["seeds_tried"] += 1
                res = self._newton(u0, pk, self.result.known[k])
                if not res.converged:
                    continue
                st["seeds_converged"] += 1
                if self._known_at(k, res.u):
                    continue
                origin = {"how": how, "p": pk}
                origin["seed" if how == "seed" else "from_sample"] = tag
                br = self._continue(res.u, pk, origin)
                if br is None:
                    # not continued (rejected, failed or a duplicate): still known here, so
                    # the next seeds are deflated against it
                    self.result.known[k].append(res.u)
                    continue
                st["seeds_new"] += 1
                if not self._known_at(k, res.u):
                    self.result.known[k].append(res.u)
                yield br

    def slice_at(self, p: float) -> list:
        """Every known solution at ``p``: the Newton-corrected crossings of ``p`` by every
        branch found so far."""
        out = []
        for br in self.result.branches:
            for i in range(len(br) - 1):
                a, b = br.p[i], br.p[i + 1]
                if (a - p) * (b - p) > 0.0 or a == b:
                    continue
                w = (p - a) / (b - a)
                res = self._newton((1 - w) * br.u[i] + w * br.u[i + 1], p, ())
                if res.converged and not any(self._same(res.u, v) for v in out):
                    out.append(res.u)
        return out

    def _special_point_round(self) -> Iterator[Branch]:
        """Deflated seeds next to the special points that were not located and next to
        the ends of branches inside the range: at ``p`` a little to either side, Newton
        from the point's state (and along its kernel), deflated against every known
        solution there. A branch point that could not be located (e.g. where the branch
        turns at a pitchfork) is crossed there by the other branch."""
        st = self.result.stats
        lo, hi = self.cont.p_min, self.cont.p_max
        span = hi - lo
        b = 0
        while b < len(self.result.branches):
            br = self.result.branches[b]
            b += 1
            ends = br.metadata.get("end_status") or []
            failed_end = {0: bool(ends) and ends[0] in _SEED_ENDS,
                          len(br) - 1: bool(ends) and ends[-1] in _SEED_ENDS}
            pts = [sp for sp in br.special_points
                   if (sp.kind in ("fold", "branch_point") and not sp.located)
                   or (sp.kind == "endpoint" and lo < sp.p < hi
                       and failed_end.get(sp.index, False))]
            for sp in pts:
                if sp.u is None:
                    continue
                key = ("sp", round(float(sp.p), 9), b)
                if key in self._switched:
                    continue
                self._switched.add(key)
                width = sp.precision if math.isfinite(sp.precision) else 0.0
                delta = min(max(2.0 * width, 1e-4 * span), 2e-2 * span)
                guesses = [sp.u]
                kern = sp.data.get("kernel")
                if kern is not None and np.size(kern) >= sp.u.size:
                    kv = np.asarray(kern, dtype=float)[: sp.u.size]
                    kv = kv / max(float(np.max(np.abs(kv))), 1e-300)
                    guesses += [sp.u + 0.05 * kv, sp.u - 0.05 * kv]
                for pp in (sp.p - delta, sp.p + delta):
                    if not lo <= pp <= hi:
                        continue
                    known = self.slice_at(pp)
                    for g in guesses:
                        if self._full():
                            return
                        st["seeds_tried"] += 1
                        res = self._newton(g, pp, known)
                        if not res.converged or any(self._same(res.u, v) for v in known):
                            continue
                        st["seeds_converged"] += 1
                        nb = self._continue(res.u, pp, {"how": "special_point", "p": pp,
                                                        "near": float(sp.p),
                                                        "kind": sp.kind, "branch": b - 1})
                        known.append(res.u)
                        if nb is not None:
                            st["seeds_new"] += 1
                            yield nb

    def _switch_round(self) -> Iterator[Branch]:
        st = self.result.stats
        b = 0
        while b < len(self.result.branches):
            br = self.result.branches[b]
            for j, sp in enumerate(list(br.special_points)):
                if sp.kind != "branch_point":
                    continue
                key = (round(float(sp.p), 9), b)
                if key in self._switched:
                    continue
                self._switched.add(key)
                if not sp.located or "kernel" not in sp.data:
                    q = _relocate_branch_point(self.problem, br, sp, self.cont,
                                               self.events, self.stop_on)
                    if q is None:
                        continue
                    # the branch's own record of the point: now located
                    q.index = sp.index
                    br.special_points[j] = q
                    sp = q
                    st["relocated"] = st.get("relocated", 0) + 1
                if self._full():
                    return
                st["switches"] += 1
                # a few steps first: if they lie on a known branch, the switch leads there
                probe = switch_branch(self.problem, sp, self.cont.replace(max_steps=3),
                                      events=self.events, stop_on=self.stop_on)
                if not len(probe) or self._duplicate(probe):
                    st["duplicates"] += 1
                    continue
                nb = switch_branch(self.problem, sp, self.cont, events=self.events,
                                   stop_on=self.stop_on)
                new = self._add(nb, {"how": "switch", "p": float(sp.p), "branch": b})
                if new is not None:
                    st["switches_new"] += 1
                    yield new
            b += 1

    def __iter__(self) -> Iterator[Branch]:
        t0 = time.perf_counter()
        st = self.result.stats
        yield from self._starts()
        for r in range(self.settings.max_rounds):
            st["rounds"] += 1
            n0 = len(self.result.branches)
            yield from self._seed_round(first=(r == 0))
            if self.settings.switch:
                yield from self._switch_round()
            yield from self._special_point_round()
            if len(self.result.branches) == n0 or self._full():
                break
        else:
            st["notes"].append(f"max_rounds={self.settings.max_rounds} reached with new "
                               "branches in the last round; raise max_rounds")
        st["wall_time_s"] = time.perf_counter() - t0

    def run(self) -> SearchResult:
        """Run the whole search; return the :class:`SearchResult`."""
        for _ in self:
            pass
        return self.result

    def extend(self, starts: Iterable) -> list:
        """Continue the search from more starts ``(u, p)`` after :meth:`run` (e.g. points
        of fold curves through the folds found): each start, then rounds of neighbour
        seeds and branch switching until nothing new. Returns the new branches."""
        t0 = time.perf_counter()
        self.starts = [(np.asarray(u, dtype=float).ravel(), float(p)) for u, p in starts]
        new = list(self._starts())
        for _ in range(self.settings.max_rounds):
            n0 = len(self.result.branches)
            new += list(self._seed_round(first=False))
            if self.settings.switch:
                new += list(self._switch_round())
            new += list(self._special_point_round())
            if len(self.result.branches) == n0 or self._full():
                break
        st = self.result.stats
        st["wall_time_s"] = st.get("wall_time_s", 0.0) + time.perf_counter() - t0
        return new


def search_branches(problem, continuation: ContinuationSettings,
                    settings: SearchSettings | None = None, **kw) -> SearchResult:
    """``BranchSearch(problem, continuation, settings, **kw).run()``."""
    return BranchSearch(problem, continuation, settings, **kw).run()
