"""Equilibrium branches of the discrete strip in Delta, through folds, at a fixed contact set.

:func:`~elastocap.strip.mep.continue_in_delta` follows a minimum by natural-parameter steps
and loses it at a fold (its end is bracketed, not located). Here a branch is followed by
pseudo-arclength continuation (:func:`continuation.continue_branch`) of the equality-
constrained problem obtained by holding a fixed set A of nodes on the ground
(:class:`~elastocap.strip.discrete.DiscreteStrip`): unknowns v = (u, r_A), u = (z_0,
theta_0 .. theta_{n-1}) and one reaction r_k >= 0 (force) per held node, equations

    grad E(u) - sum_{k in A} r_k grad z_k(u) = 0,      c z_k(u) = 0  (k in A),

with c = B / h^3 (force per length: the gaps are compared as the force that would cause
them, as in :func:`~elastocap.strip.discrete.solve_equilibrium`). The reactions are those
of :class:`~elastocap.strip.discrete.Equilibrium` (r_k = -lambda_k for the Lagrange
multipliers of grad E + sum lambda_k grad z_k = 0). The Jacobian is exact (the Lagrangian
Hessian of ``solve_equilibrium`` bordered by the constraint gradients); dF/dDelta is a
centred difference of the residual.

The fixed-set branch is a branch of contact equilibria only while every held node pushes
(r_k >= 0) and every other node stays above the ground (z_k >= 0). The first violation is
an event located by Brent's method on the arclength (``continuation``'s events, to
``locate_tol`` ~ 1e-12 in arclength): a lift-off (r_k crosses 0) or a touch-down (z_k
crosses 0). A segment ends there; optionally the next one starts at the event with the
updated set (a chain of segments). Folds (dDelta/ds = 0) are located by the package's
minimally augmented system (Govaerts 2000); the stability index is the number of negative
eigenvalues of the Lagrangian Hessian on the tangent space of the held contacts (the
package's KKT inertia), and :func:`~elastocap.strip.discrete.stability` (tangent space of
the strongly active contacts only) is also recorded at every point.

Method: H. B. Keller (1977) pseudo-arclength continuation; contact events as in the
piecewise-smooth continuation of constrained mechanical systems (a switching of the active
set at an event, e.g. Leine & Nijmeijer 2004, ch. 7).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from continuation import STOPPED, ContinuationSettings, FunctionProblem, continue_branch
from continuation import Branch as _Branch
from elastocap.strip.discrete import DiscreteStrip, Equilibrium, stability

__all__ = ["ActiveSetEvent", "BranchSegment", "DiscreteBranch", "active_set_problem",
           "trace_discrete_branch"]

# Centred-difference step of dF/dDelta (length): eps^(1/3) ~ 6e-6 balances truncation
# against rounding. The capillary force is piecewise smooth in Delta (the contact points
# cross nodes), so the quotient is first-order accurate only across a node; this affects
# the corrector's rate, not the converged points (which solve F = 0).
_FD_DELTA = np.finfo(float).eps ** (1.0 / 3.0)
# Default continuation settings. Steps in the weighted norm theta |du|^2 / N + (1 - theta)
# dDelta^2: ds_max = 0.02 moves Delta by <~ 0.03 per step, below the natural continuation's
# 0.05 that keeps edges within mep._JUMP of their previous values; newton_tol 1e-9 is ~1e-11
# of the largest generalized force (gamma, q L ~ 40) and sits above the residual's
# round-off floor (~1e-11 at n = 100). Branch points are not sought: the fixed-set problem
# is generic in Delta, and their determinant test costs an LU per point.
_DEFAULTS = dict(ds0=0.005, ds_min=1e-7, ds_max=0.02, max_steps=400, newton_tol=1e-9,
                 detect_branch_points=False, check_jacobian=False)
# Event guard: the event value of the node switched at the start of a segment is ~0 (of
# either sign, or exactly 0) at that point; there it is left out of the minimum, so that
# the start neither fires the event again nor hides a sign change of another node (an
# exact 0 at the start is no sign change for the package). A point counts as the start
# within _START_TOL in Delta (length) and _START_U in the max norm of u (the corrector's
# round-off is ~1e-13; the first step moves Delta by >~ 1e-4).
_START_TOL = 1e-11
_START_U = 1e-8


@dataclass
class ActiveSetEvent:
    """Where a fixed-set segment stops being a contact equilibrium.

    Attributes
    ----------
    kind : str
        ``"lift_off"`` (a held node's reaction crosses 0) or ``"touch_down"`` (a free node
        reaches the ground).
    node : int
        Node index k (0 .. n).
    delta : float
        Wetted length Delta at the event (length), located on the arclength.
    u : ndarray, shape (n + 1,)
        State at the event.
    reactions : ndarray, shape (n + 1,)
        Reactions (force) at the event, 0 off the held set.
    value : float
        r_k (force) for a lift-off, z_k (length) for a touch-down, at the located point.
    precision : float
        Arclength bracket of the location (the package's ``precision``).
    """

    kind: str
    node: int
    delta: float
    u: np.ndarray
    reactions: np.ndarray
    value: float
    precision: float


@dataclass
class BranchSegment:
    """A piece of branch at one contact set.

    Attributes
    ----------
    active : ndarray of bool, shape (n + 1,)
        Held nodes.
    delta : ndarray, shape (m,)
        Delta of the points (length), in arclength order; the last one is the event if
        the segment ended by one.
    u : ndarray, shape (m, n + 1)
    reactions : ndarray, shape (m, n + 1)
        Reactions (force), 0 off the held set.
    energy : ndarray, shape (m,)
        Total energy (energy units).
    index : ndarray of int, shape (m,)
        Negative eigenvalues of the Lagrangian Hessian on the tangent space of all held
        contacts (the package's stability index).
    index_strong : ndarray of int, shape (m,)
        :func:`~elastocap.strip.discrete.stability` (strongly active contacts only).
    folds : list of dict
        ``delta`` (located Delta), ``located``, ``index`` (before, after) from the
        package's stability change in the same step, if any.
    event : ActiveSetEvent or None
    branch : continuation.Branch
        The raw continuation result (all points, including the one past the event).
    status, message : str
    """

    active: np.ndarray
    delta: np.ndarray
    u: np.ndarray
    reactions: np.ndarray
    energy: np.ndarray
    index: np.ndarray
    index_strong: np.ndarray
    folds: list
    event: ActiveSetEvent | None
    branch: _Branch
    status: str
    message: str


@dataclass
class DiscreteBranch:
    """A chain of fixed-set segments joined at active-set events.

    ``delta``, ``energy``, ``index`` concatenate the segments; ``folds`` (smooth folds,
    located by the package) and ``events`` list the special points in order;
    ``turning_points`` are the nonsmooth folds: events where Delta turns back from one
    segment to the next (``delta``, ``node``, ``kind``, ``index`` (before, after));
    ``status`` is that of the last segment
    (``"event"`` when it ended at an event and no restart was asked, ``"parameter_bound"``
    at the end of ``delta_range``, ``"max_segments"``, or the continuation's status).
    """

    segments: list
    status: str
    message: str
    events: list = field(default_factory=list)
    turning_points: list = field(default_factory=list)

    @property
    def folds(self) -> list:
        return [f for s in self.segments for f in s.folds]

    @property
    def delta(self) -> np.ndarray:
        return np.concatenate([s.delta for s in self.segments]) if self.segments else \
            np.empty(0)

    @property
    def energy(self) -> np.ndarray:
        return np.concatenate([s.energy for s in self.segments]) if self.segments else \
            np.empty(0)

    @property
    def index(self) -> np.ndarray:
        return np.concatenate([s.index for s in self.segments]) if self.segments else \
            np.empty(0, dtype=int)


# --------------------------------------------------------------------------- the problem
class _Cache:
    """Strips at one Delta (constructing one validates its parameters)."""

    def __init__(self, strip):
        self.strip = strip
        self._d = {}

    def at(self, delta):
        s = self._d.get(delta)
        if s is None:
            if len(self._d) > 8:
                self._d.clear()
            s = self.strip.with_(delta=float(delta))
            self._d[delta] = s
        return s


def active_set_problem(strip: DiscreteStrip, active) -> tuple[FunctionProblem, dict]:
    """The fixed-contact-set problem F(v, Delta) = 0 as a :class:`continuation.Problem`.

    Parameters
    ----------
    strip : DiscreteStrip
        Supplies everything but Delta.
    active : ndarray of bool, shape (n + 1,)
        Held nodes A.

    Returns
    -------
    problem : continuation.FunctionProblem
        Unknowns v = (u, r_A), shape (n + 1 + |A|,); ``hessian`` / ``constraint_jacobian``
        give the Lagrangian Hessian (N, N) and the held constraints' gradients (|A|, N),
        N = n + 1; observables ``energy``, ``min_reaction`` (force), ``min_gap`` (length).
    tools : dict
        ``split(v) -> (u, r)`` with r of shape (n + 1,), ``join(u, r) -> v``, ``A`` (the
        held node indices), ``c`` (the gap scale B / h^3).
    """
    act = np.asarray(active, dtype=bool)
    N = strip.size
    if act.shape != (N,):
        raise ValueError(f"active: got shape {act.shape}; expected ({N},) (one flag per node)")
    A = np.flatnonzero(act)
    free_nodes = np.flatnonzero(~act)
    na = A.size
    c = strip.B / strip.h**3
    cache = _Cache(strip)
    idx = np.arange(1, N)

    def split(v):
        r = np.zeros(N)
        r[A] = v[N:]
        return v[:N], r

    def join(u, r):
        return np.concatenate([u, np.asarray(r)[A]])

    def residual(v, p):
        s = cache.at(p)
        u, r = split(v)
        _E, g, _H = s.derivatives(u, hessian=False)
        G = s.constraint_jacobian(u)[A]
        return np.concatenate([g - G.T @ r[A], c * s.heights(u)[A]])

    def lagrangian_hessian(v, p):
        s = cache.at(p)
        u, r = split(v)
        W = s.hessian(u)
        rs = np.cumsum(r[::-1])[::-1]
        W[idx, idx] += s.h * np.sin(u[1:]) * rs[1:]
        return W

    def jacobian(v, p):
        s = cache.at(p)
        u, _r = split(v)
        G = s.constraint_jacobian(u)[A]
        J = np.zeros((N + na, N + na))
        J[:N, :N] = lagrangian_hessian(v, p)
        J[:N, N:] = -G.T
        J[N:, :N] = c * G
        return J

    def dfdp(v, p):
        e = _FD_DELTA * (1.0 + abs(p))
        return (residual(v, p + e) - residual(v, p - e)) / (2.0 * e)

    def constraint_jacobian(v, p):
        return cache.at(p).constraint_jacobian(v[:N])[A]

    def observables(v, p):
        s = cache.at(p)
        u, r = split(v)
        z = s.heights(u)
        return {"energy": s.energy(u),
                "min_reaction": float(np.min(r[A])) if na else math.inf,
                "min_gap": float(np.min(z[free_nodes])) if free_nodes.size else math.inf}

    prob = FunctionProblem(residual, jacobian=jacobian, dfdp=dfdp,
                           hessian=lagrangian_hessian,
                           constraint_jacobian=constraint_jacobian if na else None,
                           observables=observables, name=f"discrete strip, |A| = {na}")
    return prob, {"split": split, "join": join, "A": A, "c": c, "cache": cache}


def _event_function(strip, tools, guard, v0, p0):
    """min over held nodes of r_k / (q h) and over free nodes of c z_k / (q h): negative
    once the fixed-set branch stops being a contact equilibrium (dimensionless)."""
    split, A, c, cache = tools["split"], tools["A"], tools["c"], tools["cache"]
    N = strip.size
    free_nodes = np.setdiff1d(np.arange(N), A)
    scale = strip.q * strip.h if strip.q > 0.0 else 1.0

    def values(v, p):
        u, r = split(v)
        z = cache.at(p).heights(u)
        val = np.full(N, np.inf)
        val[A] = r[A] / scale
        val[free_nodes] = c * z[free_nodes] / scale
        if guard is not None and abs(p - p0) <= _START_TOL and \
                float(np.max(np.abs(v[:N] - v0[:N]))) <= _START_U:
            val[guard] = math.inf
        return val

    def g(v, p):
        return float(np.min(values(v, p)))

    return g, values


def _tangent(prob, v, p, orient):
    """Null vector (dv/ds, dDelta/ds) of [dF/dv, dF/dDelta] at (v, p), with orient . t > 0."""
    J = np.column_stack([prob.jacobian(v, p), prob.dfdp(v, p)])
    _U, _s, Vt = np.linalg.svd(J)
    t = Vt[-1]
    return -t if float(orient(t)) < 0.0 else t


# --------------------------------------------------------------------------- driver
def _segment(strip, u0, r0, active, lo, hi, settings, tangent=None, guard=None):
    prob, tools = active_set_problem(strip, active)
    v0 = tools["join"](u0, r0)
    p0 = float(strip.delta)
    g, values = _event_function(strip, tools, guard, v0, p0)
    st = settings.replace(p_min=lo, p_max=hi)
    br = continue_branch(prob, v0, p0, st, events={"contact": g}, stop_on=("contact",),
                         tangent=tangent)
    return prob, tools, br, values


def _collect(strip, active, prob, tools, br, values):
    split, cache = tools["split"], tools["cache"]
    ev_sp = next((sp for sp in br.special_points if sp.kind == "event" and sp.located), None)
    stopped = br.status == STOPPED and ev_sp is not None
    m = ev_sp.index if stopped else len(br.p)  # points before the event
    V = list(br.u[:m])
    P = list(br.p[:m])
    event = None
    if stopped:
        V.append(ev_sp.u)
        P.append(ev_sp.p)
        vals = values(ev_sp.u, ev_sp.p)
        k = int(np.argmin(np.abs(vals)))
        u, r = split(ev_sp.u)
        kind = "lift_off" if active[k] else "touch_down"
        val = float(r[k]) if active[k] else float(cache.at(ev_sp.p).heights(u)[k])
        event = ActiveSetEvent(kind, k, float(ev_sp.p), u.copy(), r.copy(), val,
                               float(ev_sp.precision))
    I = [int(i) for i in br.stability[:m]]
    if stopped:
        I.append(_index(prob, ev_sp.u, ev_sp.p))
    U, R, E, IS = [], [], [], []
    for v, p in zip(V, P, strict=True):
        s = cache.at(p)
        u, r = split(v)
        U.append(u.copy())
        R.append(r)
        E.append(s.energy(u))
        eq = Equilibrium(u=u, energy=E[-1], parts={}, reactions=np.maximum(r, 0.0),
                         active=active.copy(), residual=0.0, iterations=0,
                         status="converged", message="")
        IS.append(stability(s, eq)[0])
    folds = []
    for sp in br.folds:
        # a fold in the step of the event counts if it is a contact equilibrium
        if stopped and (sp.index > m or (sp.index == m and (
                sp.u is None or float(np.min(values(sp.u, sp.p))) < -1e-9))):
            continue
        f = {"delta": float(sp.p), "located": bool(sp.located),
             "u": split(sp.u)[0].copy() if sp.u is not None else None, "index": None}
        for o in br.points("stability"):
            if o.index == sp.index:
                f["index"] = tuple(int(i) for i in o.data["stability"])
        folds.append(f)
    return BranchSegment(active.copy(), np.array(P), np.array(U), np.array(R), np.array(E),
                         np.array(I, dtype=int), np.array(IS, dtype=int), folds, event, br,
                         "event" if stopped else _status_name(br), br.message)


def _index(prob, v, p):
    from continuation import inertia_negative

    C = prob.constraint_jacobian(v, p) if prob.constraint_jacobian is not None else None
    return inertia_negative(prob.hessian(v, p), C)


def _status_name(br):
    from continuation._branch import STATUS_NAMES

    return STATUS_NAMES.get(br.status, str(br.status))


def trace_discrete_branch(strip: DiscreteStrip, state: Equilibrium, delta_range,
                          settings: ContinuationSettings | None = None, *,
                          restart: bool = False, max_segments: int = 10) -> DiscreteBranch:
    """Trace an equilibrium branch of the discrete strip in Delta, through folds.

    Parameters
    ----------
    strip : DiscreteStrip
        At the Delta of ``state``.
    state : Equilibrium
        A converged contact equilibrium (:func:`~elastocap.strip.discrete.solve_equilibrium`)
        without held unknowns; its ``active`` set is the first segment's held set.
    delta_range : (float, float)
        The branch ends where Delta leaves [d_lo, d_hi] (length); the wet interval must
        stay on the strip there (0 < S1 < S2 < L).
    settings : continuation.ContinuationSettings, optional
        ``direction`` +1 (default) starts towards larger Delta, -1 towards smaller;
        ``p_min``/``p_max`` are replaced by ``delta_range``. Defaults: ``_DEFAULTS``.
    restart : bool
        At an active-set event, start a new segment there with the updated set (the
        lifted node released, or the touching node held), heading away from the old
        segment's invalid side.
    max_segments : int

    Returns
    -------
    DiscreteBranch
        Never raises for a numerical failure; ``status`` / ``message`` say how it ended.
    """
    if not state.success:
        raise ValueError(f"state: got status {state.status!r}; expected a converged "
                         "Equilibrium (solve_equilibrium)")
    if state.held:
        raise ValueError(f"state.held: got {sorted(state.held)}; expected no held unknowns")
    lo, hi = (float(d) for d in delta_range)
    if not lo <= strip.delta <= hi:
        raise ValueError(f"delta_range: got [{lo}, {hi}]; expected it to contain the "
                         f"strip's Delta = {strip.delta}")
    for d in (lo, hi):
        strip.with_(delta=d)  # raises, naming S1 and S2, if the drop leaves the strip
    if settings is None:
        settings = ContinuationSettings(**_DEFAULTS)
    if max_segments < 1:
        raise ValueError(f"max_segments: got {max_segments}; expected >= 1")
    active = np.array(state.active, dtype=bool)
    u0, r0 = state.u.copy(), np.where(active, state.reactions, 0.0)
    cur, tangent, guard = strip, None, None
    segments, events, turning = [], [], []
    status, message = "max_segments", f"stopped after max_segments = {max_segments}"
    for _ in range(max_segments):
        prob, tools, br, values = _segment(cur, u0, r0, active, lo, hi, settings, tangent,
                                           guard)
        if len(br.p) == 0:
            status, message = _status_name(br), br.message
            break
        seg = _collect(cur, active, prob, tools, br, values)
        segments.append(seg)
        status, message = seg.status, seg.message
        if seg.event is None:
            break
        if guard is not None and seg.event.node == guard and len(seg.delta) <= 2:
            status = "restart_failed"
            message = (f"the segment restarted at Delta = {cur.delta:.12g} with node {guard} "
                       f"switched undid the switch at its first step ({seg.event.kind}): the "
                       "active-set change is not transversal there; try a smaller ds0")
            break
        if len(segments) > 1:
            prev = segments[-2]
            # Delta turns back at the event joining two segments: a nonsmooth fold
            d_in = prev.delta[-1] - prev.delta[-2] if prev.delta.size > 1 else 0.0
            d_out = seg.delta[1] - seg.delta[0] if seg.delta.size > 1 else 0.0
            if d_in * d_out < 0.0:
                turning.append({"delta": float(prev.event.delta), "node": prev.event.node,
                                "kind": prev.event.kind,
                                "index": (int(prev.index[-2]), int(seg.index[1]))})
        events.append(seg.event)
        message = (f"{seg.event.kind} of node {seg.event.node} at Delta = "
                   f"{seg.event.delta:.12g}")
        if not restart:
            break
        # the next segment: updated set, from the event, away from the invalid side
        k = seg.event.node
        active = active.copy()
        active[k] = not active[k]
        cur = strip.with_(delta=seg.event.delta)
        u0, r0 = seg.event.u.copy(), seg.event.reactions.copy()
        r0[k] = 0.0
        nprob, ntools = active_set_problem(cur, active)
        v0 = ntools["join"](u0, r0)
        if active[k]:  # touch-down: the new reaction must grow
            pos = int(np.searchsorted(ntools["A"], k))

            def orient(t, pos=pos):
                return t[strip.size + pos]
        else:  # lift-off: the node must rise
            Gk = cur.constraint_jacobian(u0)[k]

            def orient(t, Gk=Gk):
                return Gk @ t[:strip.size]
        tangent = _tangent(nprob, v0, cur.delta, orient)
        guard = k
    if len(segments) > 1 and status != "restart_failed":
        prev, seg = segments[-2], segments[-1]
        d_in = prev.delta[-1] - prev.delta[-2] if prev.delta.size > 1 else 0.0
        d_out = seg.delta[1] - seg.delta[0] if seg.delta.size > 1 else 0.0
        if d_in * d_out < 0.0 and not any(t["delta"] == prev.event.delta for t in turning):
            turning.append({"delta": float(prev.event.delta), "node": prev.event.node,
                            "kind": prev.event.kind,
                            "index": (int(prev.index[-2]), int(seg.index[1]))})
    return DiscreteBranch(segments, status, message, events, turning)
