"""All equilibrium branches of the strip on the ground in Delta, every contact topology.

What ``elastocap branches fig3-strip`` runs (parameter ``drop.wetted_length``). The strip is
:class:`~elastocap.strip.model.DiscreteStrip` (z >= 0 at every node, frictionless ground):
the part lying on the ground, the lift-off point, a free end touching down again and the
drop's footprint resting on the ground are all contact sets of the same problem, so no
topology is excluded.

Search (:func:`trace_contact_branches`)
    At each of ``SEED_DELTAS`` inside the range, two seeds: a quasi-static deposition
    (descent from the flat strip, :func:`~elastocap.strip.solve.open_state`) and the strip
    folded over the drop (:func:`~elastocap.strip.solve.wrapped_state`). A seed that lies on
    a branch already traced is skipped (Newton at the seed's Delta from the nearest traced
    point of the same contact set lands on it to ``_SAME``).
Trace (:func:`trace_discrete_branch`)
    Each new seed is followed both ways by pseudo-arclength continuation
    (:func:`continuation.continue_branch`, H. B. Keller 1977) of the equality-constrained
    problem obtained by holding a fixed set A of nodes on the ground
    (:func:`active_set_problem`): unknowns v = (u, r_A), u = (z_0, theta_0 .. theta_{n-1})
    and one reaction r_k >= 0 (force) per held node, equations

        grad E(u) - sum_{k in A} r_k grad z_k(u) = 0,      c z_k(u) = 0  (k in A),

    with c = B / h^3 (the gaps compared as the force that would cause them). The Jacobian
    is exact (the Lagrangian Hessian bordered by the constraint gradients); dF/dDelta is a
    centred difference of the residual. The fixed-set branch is a branch of contact
    equilibria only while every held node pushes (r_k >= 0) and every other node stays
    above the ground (z_k >= 0). The first violation is an event located by Brent's method
    on the arclength (to ~1e-12): a lift-off (r_k crosses 0) or a touch-down (z_k crosses
    0); the next segment starts there with the updated set (contact events as in the
    piecewise-smooth continuation of constrained mechanical systems, Leine & Nijmeijer
    2004, ch. 7). Corners where a contact point S1 or S2 crosses a node are passed the same
    way (same set, one-sided dF/dDelta). A branch ends where Delta leaves the range or the
    strip has wrapped the whole drop (contact lines meeting).
Special points
    Smooth folds (located by the package's minimally augmented system, Govaerts 2000) and
    contact folds: events at which Delta turns back from one contact set to the next
    (nonsmooth; the stability index changes there too). The stability index is the number
    of negative eigenvalues of the Lagrangian Hessian on the tangent space of the held
    contacts (the package's KKT inertia); :func:`~elastocap.strip.solve.stability`
    (strongly active contacts only) is also recorded at every point. The stable (index 0)
    states found give the ``window``: the largest Delta of a stable open state and the
    smallest Delta of a stable encapsulated state (the paper's criterion, Methods), over
    admissible states only (the strip does not cross itself and the interface does not
    cross it).
BLAS threads
    The trace makes thousands of small dense LAPACK calls ((n + |A|)^2 with n ~ 150-300).
    With two OpenBLAS threads on a shared 2-core machine they ran 10-17x slower than with
    one (measured: eigh + solve + matmul of 101 x 101: 45 ms against 4.4 ms; 300 x 300:
    475 ms against 36 ms). :func:`trace_contact_branches` therefore runs inside
    ``threadpoolctl.threadpool_limits(1, "blas")``: the BLAS thread count is 1 for the
    duration of the call and restored on return (the limit is the BLAS library's, so other
    threads of the process see it meanwhile).
Discretization error
    Folds and window ends are computed again at ``REFINE`` times the edges; the estimate of
    each is its distance to the nearest special point of the same kind and stability change
    at the finer resolution.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from continuation import (
    LOOP_CLOSED,
    MAX_STEPS,
    NON_FINITE,
    PARAMETER_BOUND,
    START_FAILED,
    STEP_TOO_SMALL,
    STOPPED,
    Branch,
    ContinuationSettings,
    FunctionProblem,
    continue_branch,
    inertia_negative,
)
from elastocap._version import __version__
from elastocap.scene import Scene, SceneError
from elastocap.strip.model import (
    DiscreteStrip,
    discrete_strip_for,
    is_encapsulated,
    point_measures,
)
from elastocap.strip.solve import (
    R_REL,
    Equilibrium,
    open_state,
    solve_equilibrium,
    stability,
    wrapped_state,
)

__all__ = ["CHORD_STOP", "DEFAULTS", "NOT_HANDLED", "ActiveSetEvent", "BranchSegment",
           "ContactBranchSet", "DiscreteBranch", "active_set_problem", "open_branch_end",
           "solved_crossings", "trace_contact_branches", "trace_discrete_branch"]

# Difference step of dF/dDelta (length): eps^(1/3) ~ 6e-6 balances truncation against
# rounding. The capillary force is piecewise smooth in Delta: its slope jumps where a
# contact point S1 or S2 crosses a node. A centred quotient straddling such a kink gives
# the mean of the two slopes, and the corrector then converges only linearly (measured at
# x = 2, n = 60, S2 on node 53 at Delta = 0.66333: max|F| stalled at 2.5e-9 after 12
# iterations and the step collapsed to ds_min). Within one step of a kink the quotient is
# one-sided, second order, on the side of the kink where Delta lies.
_FD_DELTA = np.finfo(float).eps ** (1.0 / 3.0)
# The branch has corners where a contact point crosses a node (the kinks above): the step
# across one turns the tangent by up to 32 degrees (measured: x = 2, n = 60, S2 on node 56
# at Delta = 2.0933, wrapped strip), above the package's default max_turn of 0.5 rad, so
# the step collapsed to ds_min there. The corner is real (the piecewise-linear placement
# of the contact points), located as an event and restarted from; 1.2 rad (69 degrees)
# lets the step across it be accepted, and ds_max keeps steps short of a jump to another
# branch.
_MAX_TURN = 1.2
# Default continuation settings. Steps in the weighted norm theta |du|^2 / N + (1 - theta)
# dDelta^2: ds_max = 0.02 moves Delta by <~ 0.03 per step (the edges then turn by < 0.3 rad
# per step, and the corrector stays on the branch); newton_tol 1e-9 is ~1e-11
# of the largest generalized force (gamma, q L ~ 40) and sits above the residual's
# round-off floor (~1e-11 at n = 100). Branch points are not sought: the fixed-set problem
# is generic in Delta, and their determinant test costs an LU per point.
DEFAULTS = dict(ds0=0.005, ds_min=1e-7, ds_max=0.02, max_steps=400, newton_tol=1e-9,
                 detect_branch_points=False, check_jacobian=False, max_turn=_MAX_TURN)
# Event guard: the event value of the node switched at the start of a segment is ~0 (of
# either sign, or exactly 0) at that point; there it is left out of the minimum, so that
# the start neither fires the event again nor hides a sign change of another node (an
# exact 0 at the start is no sign change for the package). A point counts as the start
# within _START_TOL in Delta (length) and _START_U in the max norm of u (the corrector's
# round-off is ~1e-13; the first step moves Delta by >~ 1e-4).
_START_TOL = 1e-11
_START_U = 1e-8
# A contact point within this (relative, in Delta) of a node is on it: there the side of
# the one-sided dF/dDelta is the way the segment goes (Brent locates a kink to ~1e-12).
_ON_KINK = 1e-11
# The contact lines closing around the drop end a branch: at chord d -> 0 the strip has
# wrapped the whole drop (A1 -> 0 with d), the cap degenerates and beyond it the strip
# would cross itself. Measured at x = 2 and 3 (n = 143): the corrector stalls near
# Delta = 2.1792 with d = 8e-4 = 4e-4 Delta; 1e-2 Delta stops well before.
CHORD_STOP = 1e-2


@dataclass
class ActiveSetEvent:
    """Where a fixed-set segment stops being a contact equilibrium.

    Attributes
    ----------
    kind : str
        ``"lift_off"`` (a held node's reaction crosses 0), ``"touch_down"`` (a free node
        reaches the ground) or ``"contact_lines_meet"`` (the chord d falls to
        ``CHORD_STOP`` Delta: the strip has wrapped the whole drop; ends the branch).
    node : int
        Node index k (0 .. n); -1 for ``contact_lines_meet``.
    delta : float
        Wetted length Delta at the event (length), located on the arclength.
    u : ndarray, shape (n + 1,)
        State at the event.
    reactions : ndarray, shape (n + 1,)
        Reactions (force) at the event, 0 off the held set.
    value : float
        r_k (force) for a lift-off, z_k (length) for a touch-down, d (length) when the
        contact lines meet, at the located point.
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
        :func:`~elastocap.strip.solve.stability` (strongly active contacts only).
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
    branch: Branch
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
    at the end of ``delta_range``, ``"contact_lines_meet"`` where the strip has wrapped
    the whole drop, ``"restart_failed"``, ``"max_segments"``, or the continuation's
    status).
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
        """The strip at ``delta``; None where the drop would leave it (S1 <= 0 or S2 >= L)."""
        if delta in self._d:
            return self._d[delta]
        if len(self._d) > 8:
            self._d.clear()
        try:
            s = self.strip.with_(delta=float(delta))
        except ValueError:
            s = None
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

    # Reactions enter v in units of gamma: the capillary force at a contact line (~gamma)
    # lands on the held nodes under it, so in force units dr/dDelta would dominate the
    # tangent and its jump where a contact point crosses a node would read as a turn of
    # the branch of ~75 degrees (x = 2, n = 60), refused by the corrector's max_turn.
    rs = strip.gamma if strip.gamma > 0.0 else 1.0

    def split(v):
        r = np.zeros(N)
        r[A] = rs * v[N:]
        return v[:N], r

    def join(u, r):
        return np.concatenate([u, np.asarray(r)[A] / rs])

    def residual(v, p):
        s = cache.at(p)
        if s is None:
            # a Newton iterate put the drop off the strip: a failed step for the
            # continuation (it halves the step), not an exception
            return np.full(N + na, np.nan)
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
        J[:N, N:] = -rs * G.T
        J[N:, :N] = c * G
        return J

    c0, h = strip.L - strip.x_end, strip.h

    def nearest_kink(p):
        # Delta where S1 = c0 - Delta/2 or S2 = c0 + Delta/2 sits on a node j h
        k1 = 2.0 * (c0 - h * round((c0 - 0.5 * p) / h))
        k2 = 2.0 * (h * round((c0 + 0.5 * p) / h) - c0)
        return k1 if abs(k1 - p) <= abs(k2 - p) else k2

    side = [0.0]  # set by the driver at a segment starting on a kink: the way Delta goes

    def dfdp(v, p):
        e = _FD_DELTA * (1.0 + abs(p))
        k = nearest_kink(p)
        if abs(p - k) >= e:
            return (residual(v, p + e) - residual(v, p - e)) / (2.0 * e)
        sg = 1.0 if p >= k else -1.0
        if abs(p - k) <= _ON_KINK * (1.0 + abs(p)) and side[0] != 0.0:
            sg = side[0]
        return sg * (-3.0 * residual(v, p) + 4.0 * residual(v, p + sg * e)
                     - residual(v, p + 2.0 * sg * e)) / (2.0 * e)

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
    return prob, {"split": split, "join": join, "A": A, "c": c, "cache": cache,
                  "side": side, "nearest_kink": nearest_kink}


def _kink_events(strip, v0, p0, sign):
    """Event functions vanishing where S1 (``kink_s1``) or S2 (``kink_s2``) crosses a node.

    sin(pi S / h) changes sign at every node (dimensionless). At the start point of a
    segment that begins on a kink the value is taken a hair (``_ON_KINK``) along the way
    Delta goes (``sign``), so that the start is on the far side and fires nothing.
    """
    N = strip.size
    c0, h = strip.L - strip.x_end, strip.h

    def at_start(v, p):
        return abs(p - p0) <= _START_TOL and \
            float(np.max(np.abs(v[:N] - v0[:N]))) <= _START_U

    def g1(v, p):
        q = p + sign * 1e3 * _ON_KINK if at_start(v, p) else p
        return math.sin(math.pi * (c0 - 0.5 * q) / h)

    def g2(v, p):
        q = p + sign * 1e3 * _ON_KINK if at_start(v, p) else p
        return math.sin(math.pi * (c0 + 0.5 * q) / h)

    return {"kink_s1": g1, "kink_s2": g2}


def _event_function(strip, tools, guard, v0, p0):
    """min over held nodes of r_k / (q h) and over free nodes of c z_k / (q h): negative
    once the fixed-set branch stops being a contact equilibrium (dimensionless)."""
    split, A, c, cache = tools["split"], tools["A"], tools["c"], tools["cache"]
    N = strip.size
    free_nodes = np.setdiff1d(np.arange(N), A)
    scale = strip.q * strip.h if strip.q > 0.0 else 1.0

    def values(v, p):
        u, r = split(v)
        st = cache.at(p)
        z = st.heights(u)
        val = np.full(N + 1, np.inf)
        val[A] = r[A] / scale
        val[free_nodes] = c * z[free_nodes] / scale
        # last entry: the contact lines closing around the drop (ends the branch)
        stop = CHORD_STOP * st.delta
        val[N] = (st.chord(u) - stop) / stop
        if guard is not None and abs(p - p0) <= _START_TOL and \
                float(np.max(np.abs(v[:N] - v0[:N]))) <= _START_U:
            val[guard] = math.inf
        return val

    def g(v, p):
        return float(np.min(values(v, p)))

    return g, values


def _tangent(prob, v, p, orient):
    """Null vector (dv/ds, dDelta/ds) of [dF/dv, dF/dDelta] at (v, p), with orient . t > 0.

    One LU solve dF/dv w = -dF/dDelta, t = (w, 1) / |(w, 1)|, where dF/dv is regular (a
    restart point is no fold of the new contact set, generically); the SVD of the bordered
    matrix otherwise (4-6x the cost at n = 200).
    """
    Jv, fp = prob.jacobian(v, p), prob.dfdp(v, p)
    t = None
    try:
        w = np.linalg.solve(Jv, -fp)
        if np.all(np.isfinite(w)) and np.linalg.norm(Jv @ w + fp) <= 1e-8 * (
                np.linalg.norm(fp) + np.linalg.norm(Jv, np.inf) * np.linalg.norm(w)):
            t = np.append(w, 1.0)
            t /= np.linalg.norm(t)
    except np.linalg.LinAlgError:
        t = None
    if t is None:
        _U, _s, Vt = np.linalg.svd(np.column_stack([Jv, fp]))
        t = Vt[-1]
    return -t if float(orient(t)) < 0.0 else t


# --------------------------------------------------------------------------- driver
def _segment(strip, u0, r0, active, lo, hi, settings, tangent=None, guard=None):
    prob, tools = active_set_problem(strip, active)
    v0 = tools["join"](u0, r0)
    p0 = float(strip.delta)
    g, values = _event_function(strip, tools, guard, v0, p0)
    st = settings.replace(p_min=lo, p_max=hi)
    if settings.direction == 0 and tangent is None:
        raise ValueError("settings.direction: got 0; expected +1 or -1 (a chain of segments "
                         "follows one way; trace twice for both)")
    sign = float(np.sign(tangent[-1])) if tangent is not None else float(settings.direction)
    tools["side"][0] = sign
    if tangent is not None:
        # a given tangent already points the way (continue_branch reverses it for
        # direction = -1, which turned a restarted downward segment back up)
        st = st.replace(direction=1)
    events = {"contact": g, **_kink_events(strip, v0, p0, sign)}
    br = continue_branch(prob, v0, p0, st, events=events, stop_on=tuple(events),
                         tangent=tangent)
    return prob, tools, br, values


def _collect(strip, active, prob, tools, br, values):
    split, cache = tools["split"], tools["cache"]
    # a kink that Brent could not locate (the corrector failed on the arc between the two
    # points, seen next to the contact lines meeting) is taken at the step's end: a
    # corner is no constraint violation, so that point is a valid restart
    evs = [sp for sp in br.special_points if sp.kind == "event" and (
        sp.located or sp.name in ("kink_s1", "kink_s2"))]
    ev_sp = None
    if evs:
        # events of the last step: the first one along it (nearest the previous point)
        last = max(sp.index for sp in evs)
        prev = br.p[last - 1] if last >= 1 else br.p[0]
        ev_sp = min((sp for sp in evs if sp.index == last), key=lambda sp: abs(sp.p - prev))
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
        if ev_sp.name in ("kink_s1", "kink_s2"):
            st = cache.at(ev_sp.p)
            sc = st.s1 if ev_sp.name == "kink_s1" else st.s2
            k = int(round(sc / st.h))
            kind, val = ("contact_point_on_node", float(sc - k * st.h))
        elif k == strip.size:
            kind, k, val = "contact_lines_meet", -1, float(cache.at(ev_sp.p).chord(u))
        else:
            kind = "lift_off" if active[k] else "touch_down"
            val = float(r[k]) if active[k] else float(cache.at(ev_sp.p).heights(u)[k])
        event = ActiveSetEvent(kind, k, float(ev_sp.p), u.copy(), r.copy(), val,
                               float(ev_sp.precision))
    I = [int(i) for i in br.stability[:m]]
    if stopped:
        I.append(_index(prob, ev_sp.u, ev_sp.p))
    U, R, E, IS = [], [], [], []
    for v, p, idx in zip(V, P, I, strict=True):
        s = cache.at(p)
        u, r = split(v)
        U.append(u.copy())
        R.append(r)
        E.append(s.energy(u))
        if np.all(r[active] > R_REL * s.q * s.h):
            # every held contact is strongly active: the two tangent spaces are the same
            IS.append(idx)
            continue
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
    C = prob.constraint_jacobian(v, p) if prob.constraint_jacobian is not None else None
    return inertia_negative(prob.hessian(v, p), C)


_STATUS_NAMES = {MAX_STEPS: "max_steps", PARAMETER_BOUND: "parameter_bound",
                 STEP_TOO_SMALL: "step_too_small", START_FAILED: "start_failed",
                 STOPPED: "stopped", NON_FINITE: "non_finite", LOOP_CLOSED: "loop_closed"}


def _status_name(br):
    return _STATUS_NAMES.get(br.status, str(br.status))


def trace_discrete_branch(strip: DiscreteStrip, state: Equilibrium, delta_range,
                          settings: ContinuationSettings | None = None, *,
                          restart: bool = False, max_segments: int = 10) -> DiscreteBranch:
    """Trace an equilibrium branch of the discrete strip in Delta, through folds.

    Parameters
    ----------
    strip : DiscreteStrip
        At the Delta of ``state``.
    state : Equilibrium
        A converged contact equilibrium (:func:`~elastocap.strip.solve.solve_equilibrium`);
        its ``active`` set is the first segment's held set.
    delta_range : (float, float)
        The branch ends where Delta leaves [d_lo, d_hi] (length); the wet interval must
        stay on the strip there (0 < S1 < S2 < L).
    settings : continuation.ContinuationSettings, optional
        ``direction`` +1 (default) starts towards larger Delta, -1 towards smaller;
        ``p_min``/``p_max`` are replaced by ``delta_range``. Defaults: ``DEFAULTS``.
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
    lo, hi = (float(d) for d in delta_range)
    if not lo <= strip.delta <= hi:
        raise ValueError(f"delta_range: got [{lo}, {hi}]; expected it to contain the "
                         f"strip's Delta = {strip.delta}")
    for d in (lo, hi):
        strip.with_(delta=d)  # raises, naming S1 and S2, if the drop leaves the strip
    if settings is None:
        settings = ContinuationSettings(**DEFAULTS)
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
        kink = seg.event.kind == "contact_point_on_node"
        if guard is not None and not kink and seg.event.node == guard and \
                len(seg.delta) <= 2:
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
        if not kink:
            events.append(seg.event)
        if seg.event.kind == "contact_lines_meet":
            status = "contact_lines_meet"
            message = (f"the contact lines closed around the drop (chord {seg.event.value:.3g}"
                       f" = {CHORD_STOP:g} Delta) at Delta = {seg.event.delta:.12g}: the "
                       "strip has wrapped the whole drop; beyond, it would cross itself")
            break
        message = (f"{seg.event.kind} of node {seg.event.node} at Delta = "
                   f"{seg.event.delta:.12g}")
        if not restart:
            break
        if kink:
            # same contact set on the far side of the kink: the tangent from the one-sided
            # dF/dDelta there, Delta going on the same way (a corner, not a fold)
            cur = strip.with_(delta=seg.event.delta)
            u0, r0 = seg.event.u.copy(), seg.event.reactions.copy()
            nprob, ntools = active_set_problem(cur, active)
            d_in = seg.delta[-1] - seg.delta[-2] if seg.delta.size > 1 else \
                (tangent[-1] if tangent is not None else float(settings.direction))
            ntools["side"][0] = float(np.sign(d_in))

            def orient(t, d_in=d_in):
                return t[-1] * d_in

            tangent = _tangent(nprob, ntools["join"](u0, r0), cur.delta, orient)
            guard = None
            continue
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


#: Seeds of each kind at these Deltas (length) inside the range (its midpoint if none):
#: fixed, so that the branches found do not depend on where the range starts. With 4
#: seeds spread over the range, x = 3, n = 143 found an open branch ending at a smooth fold
#: at Delta = 1.4451 when the range started at 0.3 and missed it from 0.5.
SEED_DELTAS = tuple(round(0.4 + 0.2 * k, 10) for k in range(9))
#: The error estimate's resolution: this many times the edges (rounded).
REFINE = 1.5
#: Segments per traced direction. At x = 2, n = 143 the open branch turns into the
#: encapsulated one through ~90 events (the lift-off point and the drop's footprint
#: crossing nodes one by one); 1000 leaves room for n ~ 10^3.
MAX_SEGMENTS = 1000
# Continuation steps per segment: after a smooth fold the index-1 branch of x = 3 runs
# ~1 in Delta at one contact set (400 steps were not enough).
_MAX_STEPS = 2000
# A seed is on a traced branch when Newton from the traced point lands within this of it
# (max norm of u; Newton converges to ~1e-12, distinct equilibria differ by >~ 1e-3).
_SAME = 1e-7

#: What this solver does not compute (also in every summary).
NOT_HANDLED = (
    "rod-rod contact (the strip may cross itself: such states are marked inadmissible, "
    "not excluded); branches not reached from the seeds (deposition and fold at "
    f"Delta = {', '.join(f'{d:g}' for d in SEED_DELTAS)}); only drop.wetted_length "
    "as the parameter"
)


# --------------------------------------------------------------------------- result
@dataclass
class ContactBranchSet:
    """Branches of the strip on the ground in Delta, with contact handled.

    Attributes
    ----------
    scene : Scene
    parameter : str
        ``"drop.wetted_length"``.
    prange : (float, float)
        Range of Delta (length).
    n : int
        Edges of the discrete strip.
    branches : list of DiscreteBranch
        Each a chain of fixed-contact-set segments; the two directions from a seed are two
        entries (``labels`` say which).
    labels : list of str
    points : list of dict of ndarray
        Per branch, the observables of :func:`point_measures` at every point, plus
        ``delta`` and ``index`` (the stability index: negative eigenvalues of the energy's
        Hessian on the tangent space of the contacts; 0 = stable).
    folds : list of dict
        Smooth and contact folds: ``value`` (Delta), ``kind`` (``"smooth"`` or
        ``"contact"``), ``node`` and ``event`` (contact folds), ``stability_change``
        (index before, after along the trace), ``measure``, ``energy``, ``branch``,
        ``error_estimate`` (length; NaN without refinement).
    window : dict
        ``open_max`` / ``encapsulated_min``: the largest Delta of a stable admissible open
        state and the smallest of a stable admissible encapsulated state (``value``,
        ``error_estimate``), ``bistable`` (open_max > encapsulated_min).
    events : list of dict
        Every active-set change (``delta``, ``kind``, ``node``, ``branch``).
    kind_changes : list of dict
        Where the paper's verdict flips along a branch without a fold (``value``,
        ``index``, ``from``, ``admissible``, ``branch``), located to ~1e-12 in Delta.
    branch_points, maxwell_points : list
        Empty (not searched for here; kept for the CLI's common report).
    metadata : dict
        Scene, resolution, tolerances, version, timing.
    """

    scene: Scene
    parameter: str
    prange: tuple
    n: int
    branches: list = field(default_factory=list)
    labels: list = field(default_factory=list)
    points: list = field(default_factory=list)
    folds: list = field(default_factory=list)
    window: dict = field(default_factory=dict)
    events: list = field(default_factory=list)
    branch_points: list = field(default_factory=list)
    maxwell_points: list = field(default_factory=list)
    metadata: dict = field(default_factory=dict)
    kind_changes: list = field(default_factory=list)

    def summary(self) -> dict:
        """Plain data for ``--json``: special points, window, one line per branch."""
        lines = []
        for lab, br, pts in zip(self.labels, self.branches, self.points, strict=True):
            d = pts["delta"]
            lines.append({
                "label": lab,
                "points": int(d.size),
                "range": [float(d.min()), float(d.max())] if d.size else None,
                "stable_points": int(np.sum(pts["index"] == 0)),
                "segments": len(br.segments),
                "events": len(br.events),
                "status": br.status,
                "message": br.message,
            })
        return {
            "scene": self.scene.name,
            "parameter": self.parameter,
            "range": list(self.prange),
            "solver": "discrete strip, every contact topology (elastocap.strip.trace)",
            "folds": self.folds,
            "window": self.window,
            "kind_changes": self.kind_changes,
            "branch_points": self.branch_points,
            "maxwell_points": self.maxwell_points,
            "events": len(self.events),
            "branches": lines,
            "not_handled": NOT_HANDLED,
            "metadata": self.metadata,
        }

    def save(self, out_dir) -> list:
        """Write ``branch_K.npz`` per traced direction (points, states, contact sets,
        metadata) and ``branches.json`` (the summary and the contact events); each file is
        written to a temporary name and renamed (atomic). :meth:`load` reads them back."""
        import json
        import os

        from elastocap.jsonutil import jsonable

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = []
        meta = json.dumps(jsonable({**self.metadata, "scene": self.scene.data,
                                    "scene_name": self.scene.name}))
        for k, (br, pts) in enumerate(zip(self.branches, self.points, strict=True)):
            u = np.concatenate([s.u for s in br.segments]) if br.segments else np.empty(0)
            held = (np.concatenate([np.repeat(s.active[None], s.delta.size, 0)
                                    for s in br.segments]) if br.segments else np.empty(0))
            p = out / f"branch_{k}.npz"
            tmp = out / f".branch_{k}.tmp.npz"
            sizes = np.array([s.delta.size for s in br.segments], dtype=int)
            np.savez(tmp, u=u, held=held, label=self.labels[k], metadata=meta,
                     status=br.status, message=br.message, segment_sizes=sizes,
                     **{key: np.asarray(v) for key, v in pts.items()})
            os.replace(tmp, p)
            paths.append(p)
        js = out / "branches.json"
        tmp = out / ".branches.json.tmp"
        tmp.write_text(json.dumps(jsonable({**self.summary(), "event_list": self.events,
                                            "prange": list(self.prange), "n": self.n}),
                                  indent=2))
        os.replace(tmp, js)
        paths.append(js)
        return paths

    @classmethod
    def load(cls, out_dir) -> ContactBranchSet:
        """The branch set :meth:`save` wrote to ``out_dir``.

        Points, states, contact sets, special points, window, events and metadata come
        back as saved; each traced direction is one :class:`DiscreteBranch` with its
        segments (points, states, contact set, index) and its events as the dicts of
        ``events``; the continuation's raw output, the reactions and the segments' folds are
        not saved (``branch`` and ``event`` are None).
        """
        import json

        from elastocap.scene import build_scene

        def floats(v):  # jsonable wrote non-finite floats as strings
            if isinstance(v, dict):
                return {key: floats(x) for key, x in v.items()}
            if isinstance(v, list):
                return [floats(x) for x in v]
            return float(v) if v in ("nan", "inf", "-inf") else v

        out = Path(out_dir)
        js = floats(json.loads((out / "branches.json").read_text()))
        k, branches, labels, points = 0, [], [], []
        scene = None
        while (out / f"branch_{k}.npz").is_file():
            with np.load(out / f"branch_{k}.npz") as z:
                meta = json.loads(str(z["metadata"]))
                if scene is None:
                    scene = build_scene(meta["scene"], meta.get("scene_name", "scene"))
                skip = {"u", "held", "label", "metadata", "status", "message",
                        "segment_sizes"}
                pts = {key: np.array(z[key]) for key in z.files if key not in skip}
                u, held = np.array(z["u"]), np.array(z["held"], dtype=bool)
                segs, i = [], 0
                for m in np.array(z["segment_sizes"]):
                    sl = slice(i, i + int(m))
                    segs.append(BranchSegment(held[i].copy(), pts["delta"][sl], u[sl],
                                              np.zeros_like(u[sl]), pts["energy"][sl],
                                              pts["index"][sl], pts["index"][sl], [], None,
                                              None, "loaded", ""))
                    i += int(m)
                label = str(z["label"])
                evs = [e for e in js["event_list"] if e["branch"] == label]
                branches.append(DiscreteBranch(segs, str(z["status"]), str(z["message"]),
                                               evs))
                labels.append(label)
                points.append(pts)
            k += 1
        if scene is None:
            raise FileNotFoundError(f"{out}: no branch_0.npz (expected the files of "
                                    "ContactBranchSet.save)")
        return cls(scene, js["parameter"], tuple(js["prange"]), int(js["n"]), branches,
                   labels, points, js["folds"], js["window"], js["event_list"],
                   js["branch_points"], js["maxwell_points"], js["metadata"],
                   js["kind_changes"])

    def plot(self, path=None, insets=3):
        """The branch diagram (:func:`elastocap.strip.plot.plot_contact_branch_set`)."""
        from elastocap.strip.plot import plot_contact_branch_set

        return plot_contact_branch_set(self, path, insets)

    def report(self) -> str:
        """The human-readable report (:meth:`report_lines`, one string)."""
        return "\n".join(self.report_lines())

    def report_lines(self) -> list[str]:
        """Human-readable report (the CLI without ``--json``)."""
        m = self.metadata
        out = [f"{self.scene.name}: {len(self.branches)} branches in {self.parameter} over "
               f"[{self.prange[0]:.6g}, {self.prange[1]:.6g}] (discrete strip, n = {self.n}"
               f" edges, {len(self.events)} contact events, {m['wall_time_s']:.1f} s)"]
        nf = m.get("n_edges_refined")

        def err(e):
            if nf is None:
                return "(not estimated)"
            return f"± {e:.1e}" if e == e else f"(no match at n = {nf})"

        for f in self.folds:
            what = "smooth fold " if f["kind"] == "smooth" else \
                f"contact fold ({f['event']} of node {f['node']})"
            out.append(f"  {what:38s} Delta {f['value']:.9f} {err(f['error_estimate']):22s}"
                       f" stability {f['stability_change']}  measure {f['measure']:+.4f}"
                       + ("" if f["admissible"] else "  (strip crosses itself)"))
        w = self.window
        for key, name in (("open_max", "stable open state up to"),
                          ("encapsulated_min", "stable encapsulated state from")):
            v = w.get(key)
            if v and v["value"] is not None:
                out.append(f"  {name:32s} Delta {v['value']:.9f} {err(v['error_estimate'])}")
        line = f"  bistable at n = {self.n}: {w.get('bistable')}"
        if w.get("width") is not None:
            line += f" (width {w['width']:+.2e})"
        if nf is not None:
            wr = w.get("width_refined")
            line += f"; at n = {nf}: {w.get('bistable_refined')}" + (
                f" (width {wr:+.2e})" if wr is not None else "")
        out.append(line)
        return out


# --------------------------------------------------------------------------- driver
def _check(scene: Scene, parameter: str, prange):
    if not (scene.effects.gravity > 0.0 and scene.effects.ground):
        raise SceneError("effects", {"gravity": scene.effects.gravity,
                                     "ground": scene.effects.ground},
                         "the strip on the ground needs gravity > 0 and ground = true")
    if parameter != "drop.wetted_length":
        raise SceneError("--param", parameter, "the contact-handling strip solver traces "
                         "drop.wetted_length only")
    x = scene.distance_from_end
    if prange is None:
        prange = (0.3, min(2.2, 1.95 * x))
    lo, hi = (float(v) for v in prange)
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
        raise SceneError("--range", list(prange), "expected two finite numbers 0 < LO < HI")
    if hi >= 2.0 * x:
        raise SceneError("--range", [lo, hi],
                         f"expected HI < 2 x = {2.0 * x} (the drop off the free end)")
    return lo, hi


def solved_crossings(strip: DiscreteStrip, branches):
    """Each place a traced segment crosses the strip's Delta, solved there exactly.

    Yields (segment, j, Equilibrium): Newton at the segment's contact set from its traced
    point j nearest the crossing (converged or not: check ``success``).
    """
    d0 = strip.delta
    for br in branches:
        for seg in br.segments:
            d = seg.delta
            if d.size < 2 or not d.min() <= d0 <= d.max():
                continue
            for i in range(d.size - 1):
                if d[i] == d[i + 1] or (d[i] - d0) * (d[i + 1] - d0) > 0.0:
                    continue
                j = i if abs(d[i] - d0) <= abs(d[i + 1] - d0) else i + 1
                yield seg, j, solve_equilibrium(strip, seg.u[j], active=seg.active,
                                                tol=1e-11, max_iter=30)


def _on_branch(strip: DiscreteStrip, u_seed, br: DiscreteBranch) -> bool:
    """Does the state ``u_seed`` at the strip's Delta lie on the traced branch ``br``?"""
    return any(eq.success and float(np.max(np.abs(eq.u - u_seed))) <= _SAME
               for _seg, _j, eq in solved_crossings(strip, [br]))


def _branch_points(strip: DiscreteStrip, br: DiscreteBranch) -> dict:
    rows = []
    for seg in br.segments:
        for d, u, idx in zip(seg.delta, seg.u, seg.index, strict=True):
            m = point_measures(strip.with_(delta=float(d)), u)
            m["delta"] = float(d)
            m["index"] = int(idx)
            rows.append(m)
    keys = rows[0].keys() if rows else ("delta", "index")
    return {k: np.array([r[k] for r in rows]) for k in keys}


def _special(strip: DiscreteStrip, branches, labels) -> tuple[list, list]:
    folds, events = [], []
    for b, br in enumerate(branches):
        for f in br.folds:
            if f["u"] is None:
                continue
            m = point_measures(strip.with_(delta=f["delta"]), f["u"])
            folds.append({"value": f["delta"], "kind": "smooth", "node": None, "event": None,
                          "stability_change": list(f["index"]) if f["index"] else None,
                          "measure": m["measure"], "energy": m["energy"],
                          "encapsulated": bool(m["encapsulated"]),
                          "admissible": bool(m["admissible"]), "branch": labels[b],
                          "located": f["located"]})
        for tp in br.turning_points:
            ev = next(e for e in br.events if e.delta == tp["delta"] and e.node == tp["node"])
            m = point_measures(strip.with_(delta=ev.delta), ev.u)
            folds.append({"value": tp["delta"], "kind": "contact", "node": tp["node"],
                          "event": tp["kind"], "stability_change": list(tp["index"]),
                          "measure": m["measure"], "energy": m["energy"],
                          "encapsulated": bool(m["encapsulated"]),
                          "admissible": bool(m["admissible"]), "branch": labels[b],
                          "located": True})
        for e in br.events:
            events.append({"delta": e.delta, "kind": e.kind, "node": e.node,
                           "branch": labels[b]})
    # the two directions from one seed can meet the same fold (a seed between two folds
    # on a closed stretch is not possible, but a branch traced from two seeds is skipped;
    # keep the list unique anyway)
    uniq = {}
    for f in folds:
        uniq.setdefault((round(f["value"], 10), f["kind"], f["node"]), f)
    return sorted(uniq.values(), key=lambda f: f["value"]), events


def _kind_changes(strip: DiscreteStrip, branches, labels) -> list:
    """Where the paper's criterion flips along a branch, located to ~1e-12 in Delta.

    Between two consecutive traced points of a segment whose verdicts differ, Delta is
    bisected, each state solved by Newton at the segment's contact set from the nearer
    point; the criterion x(S_c) - x(L) is continuous along the branch, so the flip is where
    the free end passes above the impact centre. Returns dicts ``value``, ``index`` (the
    stability index there), ``branch``.
    """
    out = []
    for b, br in enumerate(branches):
        for seg in br.segments:
            enc = [is_encapsulated(strip.with_(delta=float(d)), u)
                   for d, u in zip(seg.delta, seg.u, strict=True)]
            for i in range(len(enc) - 1):
                if enc[i] == enc[i + 1] or seg.delta[i] == seg.delta[i + 1]:
                    continue
                a, c = float(seg.delta[i]), float(seg.delta[i + 1])
                ua = seg.u[i]
                ea = enc[i]
                ok = True
                for _ in range(60):
                    if abs(c - a) <= 1e-12 * (1.0 + abs(a)):
                        break
                    m = 0.5 * (a + c)
                    eq = solve_equilibrium(strip.with_(delta=m), ua, active=seg.active,
                                           tol=1e-11, max_iter=30)
                    if not eq.success:
                        ok = False
                        break
                    if is_encapsulated(strip.with_(delta=m), eq.u) == ea:
                        a, ua = m, eq.u
                    else:
                        c = m
                if ok:
                    m = point_measures(strip.with_(delta=a), ua)
                    out.append({"value": 0.5 * (a + c), "index": int(seg.index[i]),
                                "from": "encapsulated" if ea else "open",
                                "admissible": bool(m["admissible"]), "branch": labels[b]})
    return out


def _window(points, folds=(), kind_changes=()) -> dict:
    """Largest Delta of a stable open state, smallest of a stable encapsulated one.

    A stable stretch of a branch ends at a located special point: a fold, a contact fold
    where the index changes, or a kind change (the verdict flips on a stable stretch, no
    fold); those count with the traced stable points, and ``how`` says which one gave
    each end (``"smooth_fold"``, ``"contact_fold"``, ``"kind_change"``, or ``"range"``: a
    traced point, the stable stretch reaching the range's end).
    """
    opens, encs = [], []
    for pts in points:
        ok = (pts["index"] == 0) & (pts["admissible"] == 1.0)
        enc = pts["encapsulated"] == 1.0
        if np.any(ok & ~enc):
            opens.append((float(pts["delta"][ok & ~enc].max()), "range"))
        if np.any(ok & enc):
            encs.append((float(pts["delta"][ok & enc].min()), "range"))
    for f in folds:
        if f["admissible"] and f["stability_change"] and 0 in f["stability_change"]:
            (encs if f["encapsulated"] else opens).append((f["value"], f"{f['kind']}_fold"))
    for k in kind_changes:
        if k["index"] == 0 and k["admissible"]:
            opens.append((k["value"], "kind_change"))
            encs.append((k["value"], "kind_change"))
    # at a tie a located special point names the end (an event is also a traced point)
    top = max(opens, key=lambda t: (t[0], t[1] != "range")) if opens else None
    bot = min(encs, key=lambda t: (t[0], t[1] == "range")) if encs else None
    return {
        "open_max": {"value": top[0] if top else None, "how": top[1] if top else None,
                     "error_estimate": math.nan},
        "encapsulated_min": {"value": bot[0] if bot else None,
                             "how": bot[1] if bot else None, "error_estimate": math.nan},
        "bistable": bool(top and bot and top[0] > bot[0]),
        "width": (top[0] - bot[0]) if top and bot else None,
    }


def _trace_all(strip: DiscreteStrip, lo: float, hi: float, progress=None):
    grid = [d for d in SEED_DELTAS if lo < d < hi] or [0.5 * (lo + hi)]
    branches, labels = [], []
    for kind, seed in (("deposition", open_state), ("fold", wrapped_state)):
        for d in grid:
            s = strip.with_(delta=float(d))
            eq = seed(s)
            if not eq.success:
                continue
            if any(_on_branch(s, eq.u, br) for br in branches):
                continue
            for direction in (-1, 1):
                st = ContinuationSettings(**{**DEFAULTS, "direction": direction,
                                             "max_steps": _MAX_STEPS})
                br = trace_discrete_branch(s, eq, (lo, hi), st, restart=True,
                                           max_segments=MAX_SEGMENTS)
                branches.append(br)
                labels.append(f"{kind} at Delta = {d:.4g}, "
                              f"{'down' if direction < 0 else 'up'}")
                if progress is not None:
                    progress(labels[-1], br)
    return branches, labels


def _nearest(value, candidates):
    return min((abs(value - c) for c in candidates), default=math.nan)


def trace_contact_branches(scene: Scene, parameter: str = "drop.wetted_length", prange=None,
                           n: int | None = None, refine: bool = True,
                           progress=None, n_refined: int | None = None) -> ContactBranchSet:
    """Search, trace and classify the branches of a strip-on-the-ground scene in Delta.

    Parameters
    ----------
    scene : Scene
        With gravity > 0 and the ground (``fig3-strip``).
    parameter : str
        Must be ``"drop.wetted_length"``.
    prange : (lo, hi), optional
        Delta range (length); default (0.3, min(2.2, 1.95 x)).
    n : int, optional
        Edges; default the scene's impact resolution (``numerics.n_edges`` or the accuracy
        preset's).
    refine : bool
        Repeat at ``REFINE`` n edges for the error estimates (about 2-3x the time).
    progress : callable(label, branch), optional
        Called after each traced direction.
    n_refined : int, optional
        Edges of the refined run (default ``round(REFINE * n)``).

    Returns
    -------
    ContactBranchSet
    """
    lo, hi = _check(scene, parameter, prange)
    t0 = time.perf_counter()
    strip = discrete_strip_for(scene, n)
    with threadpool_limits(limits=1, user_api="blas"):
        branches, labels = _trace_all(strip, lo, hi, progress)
        points = [_branch_points(strip, br) for br in branches]
        folds, events = _special(strip, branches, labels)
        kinds = _kind_changes(strip, branches, labels)
        window = _window(points, folds, kinds)
        window["open_branch_end"] = {**_open_branch_end(labels, points, folds, kinds),
                                     "error_estimate": math.nan}
        n_fine = None
        if refine:
            n_fine = int(n_refined) if n_refined is not None else int(round(REFINE * strip.n))
            if n_fine == strip.n:
                raise ValueError(f"n_refined: got {n_fine}; expected it to differ from n = "
                                 f"{strip.n}")
            fine = strip.with_(n=n_fine)
            fprog = None
            if progress is not None:
                def fprog(label, br):
                    progress(f"{label} (n = {n_fine}, error estimates)", br)
            fb, fl = _trace_all(fine, lo, hi, fprog)
            ffolds, _ = _special(fine, fb, fl)
            fpoints = [_branch_points(fine, br) for br in fb]
            fkinds = _kind_changes(fine, fb, fl)
            fwin = _window(fpoints, ffolds, fkinds)
            fend = _open_branch_end(fl, fpoints, ffolds, fkinds)
            oe = window["open_branch_end"]
            oe["value_refined"], oe["how_refined"] = fend["value"], fend["how"]
            if oe["value"] is not None and fend["value"] is not None:
                oe["error_estimate"] = abs(oe["value"] - fend["value"])
            for f in folds:
                same = [g["value"] for g in ffolds if g["kind"] == f["kind"]
                        and g["stability_change"] == f["stability_change"]]
                f["error_estimate"] = _nearest(f["value"], same)
            for key in ("open_max", "encapsulated_min"):
                a, b = window[key]["value"], fwin[key]["value"]
                if a is not None and b is not None:
                    window[key]["error_estimate"] = abs(a - b)
                window[key]["value_refined"] = b
                window[key]["how_refined"] = fwin[key]["how"]
            window["bistable_refined"] = fwin["bistable"]
            window["width_refined"] = fwin["width"]
        else:
            for f in folds:
                f["error_estimate"] = math.nan
    bs = ContactBranchSet(scene, parameter, (lo, hi), strip.n, branches, labels, points,
                          folds, window, events, kind_changes=kinds)
    bs.metadata = {
        "scene": scene.name,
        "parameter": parameter,
        "range": [lo, hi],
        "N": strip.n,
        "n_edges": strip.n,
        "n_edges_refined": n_fine,
        "solver": "discrete strip (elastocap.strip.model), pseudo-arclength at fixed "
                  "contact sets with located lift-off/touch-down events",
        "seed_deltas": [d for d in SEED_DELTAS if lo < d < hi] or [0.5 * (lo + hi)],
        "continuation": {k: v for k, v in DEFAULTS.items()},
        "contact_event_tol": "reaction or gap at a located event below 1e-13 (force, length)",
        "version": __version__,
        "wall_time_s": time.perf_counter() - t0,
    }
    return bs


def open_branch_end(bs: ContactBranchSet) -> dict:
    """Where the state a quasi-static spreading lands on stops existing or being stable.

    The branch traced up in Delta from the deposition at the lowest seed: the largest Delta
    of its leading stretch of stable, open, admissible states (``value``, length), and
    ``how`` it ends: a ``contact fold`` or ``smooth fold`` (located), a ``kind change``
    (the verdict flips on a stable stretch, located), ``stability lost`` or
    ``inadmissible`` at a traced point, ``range`` (the stretch reaches the range's end).
    ``value`` is None when there is no such branch (``how`` says why).
    """
    return _open_branch_end(bs.labels, bs.points, bs.folds, bs.kind_changes)


def _open_branch_end(labels, points, folds, kind_changes) -> dict:
    labs = [k for k, lab in enumerate(labels) if lab.startswith("deposition")
            and lab.endswith("up")]
    if not labs:
        return {"value": None, "how": "no deposition branch"}
    k = labs[0]
    pts = points[k]
    ok = (pts["index"] == 0) & (pts["encapsulated"] == 0.0) & (pts["admissible"] == 1.0)
    if not ok[0]:
        return {"value": None, "how": "deposition not a stable open state", "label": labels[k]}
    stop = int(np.argmin(ok)) if not ok.all() else ok.size
    d = pts["delta"][:stop]
    end = float(d.max())
    if stop == ok.size:
        how = "range"
    elif pts["index"][stop] != 0:
        how = "stability lost"
    elif pts["encapsulated"][stop] == 1.0:
        how = "kind change"
    else:
        how = "inadmissible"
    # the located special point between the last stable open point and the next one
    if stop < ok.size:
        a, b = sorted((end, float(pts["delta"][stop])))
        for f in folds:
            if f["branch"] == labels[k] and a - 1e-9 <= f["value"] <= b + 1e-9:
                end, how = f["value"], f"{f['kind']} fold"
        for c in kind_changes:
            if c["branch"] == labels[k] and a - 1e-9 <= c["value"] <= b + 1e-9:
                end, how = c["value"], "kind change"
    return {"value": end, "how": how, "label": labels[k]}
