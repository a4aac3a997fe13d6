"""All equilibrium branches of the strip on the ground in Delta, every contact topology.

What ``elastocap branches fig3-strip`` runs (parameter ``drop.wetted_length``). The strip is
:class:`~elastocap.strip.model.DiscreteStrip` (z >= 0 at every node, frictionless ground):
the part lying on the ground, the lift-off point, a free end touching down again and the
drop's footprint resting on the ground are all contact sets of the same problem, so no
topology is excluded.

Search (:func:`trace_contact_branches`, :func:`search_contact_branches`)
    The generic deflated search :class:`continuation.BranchSearch` on
    :class:`ContactProblem`: the strip as one fixed-size semismooth problem (state and one
    reaction per node, complementarity as min(r, c z) = 0), whose seeds at each of
    ``SEED_DELTAS`` inside the range are a quasi-static deposition (descent from the flat
    strip, :func:`~elastocap.strip.solve.open_state`) and the strip folded over the drop
    (:func:`~elastocap.strip.solve.wrapped_state`). Each seed is Newton-solved deflated
    against the states known at its Delta (the recorded crossings of every branch traced so
    far), so a seed on a traced branch is not traced again; a new one is continued both
    ways by the search's continuer :func:`continue_contact_branch`, which runs the trace
    below at the seed's contact set and joins the segments into one branch.
Trace (:func:`trace_discrete_branch`)
    Each new seed is followed both ways by pseudo-arclength continuation
    (:func:`continuation.continue_branch`, H. B. Keller 1977) of the equality-constrained
    problem obtained by holding a fixed set A of nodes on the ground
    (:func:`active_set_problem`): unknowns v = (u, r_A), u = (z_0, theta_0 .. theta_{n-1})
    and one reaction r_k >= 0 (force) per held node, equations

        grad E(u) - sum_{k in A} r_k grad z_k(u) = 0,      c z_k(u) = 0  (k in A),

    with c = B / h^3 (the gaps compared as the force that would cause them; written
    between consecutive held nodes, which makes the rows of a flat stretch free to
    factorize, :func:`active_set_problem`). The Jacobian is exact (the Lagrangian
    Hessian bordered by the constraint gradients); dF/dDelta is a centred difference of
    the residual. The fixed-set branch is a branch of contact
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
Self-contact (a strip with ``thickness`` d > 0, :mod:`elastocap.strip.model`)
    The held pairs (i, j, sigma) of nodes on segments (or nodes) at distance d are held like
    the ground's nodes: one force mu_p >= 0 per pair in the fixed-set problem, its gap held
    at 0 (:func:`active_set_problem`). Events: a pair's force crosses 0
    (``pair_lift_off``), a node without a pair comes to d from its closest tested segment
    (``pair_touch_down``; -1 once the strip crosses itself, so a step cannot jump through
    the tube unseen), a pair's foot reaches the end of its segment (``pair_switch``: the
    pair that continues it, :func:`~elastocap.strip.model.pair_switch`); the segment
    restarts with the new pair set (:func:`_restart_pair`). A touch-down or lift-off may
    turn Delta back: a contact fold, as at the ground. Off (d = 0) none of this runs and
    the branches are the same bit for bit. The branch search
    (:func:`trace_contact_branches`) runs without self-contact: its strip has thickness 0
    whatever the scene's, and ``metadata["contact_note"]`` says so.
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
    at the finer resolution, on the branch traced there from the same seed or start (any
    branch where none was traced from it); none where there is no such point.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numba
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
    BranchSearch,
    ContinuationSettings,
    FunctionProblem,
    Problem,
    SearchSettings,
    SpecialPoint,
    continue_branch,
    factorize,
    inertia_negative,
)
from elastocap._version import __version__
from elastocap.branchset import BranchModel, BranchSet
from elastocap.geometry import count_crossings
from elastocap.scene import Scene, SceneError
from elastocap.strip.model import (
    DiscreteStrip,
    closest_segments,
    discrete_strip_for,
    is_encapsulated,
    pair_gaps,
    pair_hessian,
    pair_jacobian,
    pair_switch,
    point_measures,
    redundant_pair,
)
from elastocap.strip.solve import (
    R_REL,
    STIFF_PENALTY,
    Equilibrium,
    lagrangian_hessian,
    minimize_energy,
    open_state,
    solve_equilibrium,
    stability,
    unstable_mode,
    wrapped_state,
)
from elastocap.strip.solve import (
    refine as refine_equilibrium,
)

__all__ = ["CHORD_STOP", "DEFAULTS", "NOT_HANDLED", "SEARCH", "STRIP", "ActiveSetEvent",
           "BranchSegment", "ContactProblem", "DiscreteBranch", "active_set_problem",
           "continue_contact_branch", "open_branch_end", "report_lines",
           "search_contact_branches", "segments_of", "solved_crossings",
           "trace_contact_branches", "trace_discrete_branch", "window"]

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
# Event guard: the event value of the nodes switched at the start of a segment is ~0 (of
# either sign, or exactly 0) at that point; there it is left out of the minimum, so that
# the start neither fires the event again nor hides a sign change of another node (an
# exact 0 at the start is no sign change for the package). A point counts as the start
# within _START_TOL in Delta (length) and _START_U in the max norm of u (the corrector's
# round-off is ~1e-13; the first step moves Delta by >~ 1e-4).
_START_TOL = 1e-11
_START_U = 1e-8
# Simultaneous switches: at a located lift-off or touch-down, every other node whose
# event value (r_k or c z_k over q h, dimensionless) is within this of 0 switches with
# it. Where the drop's centre sits on a node or mid-edge, the discrete strip is
# mirror-symmetric about it (the flat parts on the ground carry no moment and, on a
# frictionless ground, no tension), and nodes lift off and touch down in mirror pairs at
# one Delta (measured: x = 4, n = 143, nodes 80 and 126 at Delta = 0.6126721518, values
# 1e-12 apart). Switching one of a pair leaves the other's constraint violated at the
# restart and the tracer turned back along nearly the same states. Values of events
# ~1e-9 in Delta apart are within this; merging them moves the later one by less than
# the corrector's tolerance (newton_tol 1e-9) moves a point.
_SIMULTANEOUS = 1e-8
# Event location with self-contact (arclength, relative): the pairs' gaps and feet are
# differences of positions of nodes far apart along the strip, and on the arc's corrected
# points they carry noise of ~1e-11 (measured at x = 3, n = 100, a pair's foot at the end
# of its segment: signs alternating at values 1e-13 .. 7e-12 near the root), where Brent's
# method at the default 1e-12 ran out of its 60 iterations. 1e-10 is still ~1e-8 of the
# discretization error of any located Delta. Only segments that hold pairs use it: the
# ground's simultaneous events (_SIMULTANEOUS) need the default (at x = 3, n = 286 on the
# open branch, two ground events at one Delta located to 1e-10 were not merged, and the
# restart between them left a reaction negative).
_SELF_LOCATE_TOL = 1e-10
# A node that comes within this fraction of d of the thickness and leaves again grazes:
# the held contacts carry the tip at exactly d over the flat base, so as the tip passes
# over a base node their distance is d at one instant (a minimum, no crossing), and the
# corrector holds the pairs' gaps only to newton_tol / c (3e-12 at n = 100, measured: a
# "touch-down" of that node 3.5e-9 in Delta before the tip's foot reached it). 1e-8 d is
# above that and far below any physical gap.
_GRAZE = 1e-8
# A segment with self-contact whose event values start below this (dimensionless: forces
# and gaps over the node weight, feet in edges) is refused: a violated constraint at the
# start keeps the minimum negative, and no event could fire on it (measured at x = 3,
# n = 429: a pair force at -0.54 q h all along a segment after two simultaneous switches).
# Round-off at a restart is ~1e-10.
_START_VIOLATION = 1e-6
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
    switched : tuple of (kind, node, value)
        Every node whose contact changes here, this one first: the nodes whose event
        value vanishes with it (``_SIMULTANEOUS``; mirror pairs on a symmetric grid).
        Empty for a kink and where the contact lines meet.
    followed : tuple of int
        The nodes the next segment switched (all of ``switched`` unless a subset is the
        stable way on; set by the driver when it restarts here).
    alternatives : tuple of (tuple of int, int)
        The other valid ways on from here, (nodes switched, index at the event): branches
        that start at this point and were not traced.
    pairs : ndarray of int, shape (m, 3)
        The self-contact pairs held up to the event (a strip with a thickness).
    pair_forces : ndarray, shape (m,)
        Their forces at the event (force).
    pair : tuple
        For a self-contact event (kinds ``pair_lift_off``: a pair's force crosses 0,
        ``pair_touch_down``: a node reaches the thickness from its closest tested segment,
        ``pair_switch``: a pair's form stops holding, its foot at the end of its segment,
        :func:`~elastocap.strip.model.pair_switch`), the pair (i, j, sigma) concerned;
        ``node`` is i and ``value`` the force, the gap or the pair's region value.
    """

    kind: str
    node: int
    delta: float
    u: np.ndarray
    reactions: np.ndarray
    value: float
    precision: float
    switched: tuple = ()
    followed: tuple = ()
    alternatives: tuple = ()
    pairs: np.ndarray | None = None
    pair_forces: np.ndarray | None = None
    pair: tuple = ()


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
    pairs : ndarray of int, shape (m_p, 3)
        Held self-contact pairs (i, j, sigma) (empty without a thickness).
    pair_forces : ndarray, shape (m, m_p)
        Their forces (force) at the points.
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
    pairs: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=np.int64))
    pair_forces: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))


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


@numba.njit(cache=True)
def _held_blocks(hc, A, J, N, c, rs):
    """The held constraints' blocks of the fixed-set Jacobian into the zeroed ``J``:
    columns N + i, -rs grad z_{A_i} (1 at z_0, h cos theta_j for j < A_i), and rows N + i,
    c grad z_{A_0}, then c (grad z_{A_i} - grad z_{A_{i-1}}) (h cos theta_j for A_{i-1} <= j
    < A_i), entry by entry (the bits of the products and differences of the dense rows:
    the entries that cancel are +0)."""
    for i in range(A.shape[0]):
        a = A[i]
        J[0, N + i] = -rs
        for j in range(a):
            J[1 + j, N + i] = -rs * hc[j]
        if i == 0:
            J[N, 0] = c
            lo = 0
        else:
            lo = A[i - 1]
        for j in range(lo, a):
            J[N + i, 1 + j] = c * hc[j]


def active_set_problem(strip: DiscreteStrip, active, pairs=None) -> tuple[FunctionProblem, dict]:
    """The fixed-contact-set problem F(v, Delta) = 0 as a :class:`continuation.Problem`.

    Parameters
    ----------
    strip : DiscreteStrip
        Supplies everything but Delta.
    active : ndarray of bool, shape (n + 1,)
        Held nodes A.
    pairs : array_like of int, shape (m, 3), optional
        Held self-contact pairs P (i, j, sigma) (a strip with a thickness): their gaps
        (:func:`~elastocap.strip.model.pair_gaps`) are held at 0 like the ground's, with
        one contact force mu_p per pair, unknowns after r_A.

    Returns
    -------
    problem : continuation.FunctionProblem
        Unknowns v = (u, r_A, mu_P), shape (n + 1 + |A| + |P|,); ``hessian`` /
        ``constraint_jacobian`` give the Lagrangian Hessian (N, N) and the held
        constraints' gradients (|A|, N), N = n + 1, as in F (below; for the stability
        index); observables ``energy``, ``min_reaction`` (force), ``min_gap`` (length).
    tools : dict
        ``split(v) -> (u, r)`` with r of shape (n + 1,), ``join(u, r, mu=None) -> v``,
        ``mu(v)`` (the pair forces, shape (m,)), ``A`` (the held node indices), ``P`` (the
        held pairs), ``c`` (the gap scale B / h^3).

    Notes
    -----
    The held constraints are written c z_{a_1} = 0 and c (z_{a_i} - z_{a_{i-1}}) = 0 for
    the held nodes a_1 < a_2 < ... (the same conditions, rows changed by a unit lower
    bidiagonal matrix, so Newton's iterates are the same): where two neighbours are held
    the row has one nonzero, h cos theta of the edge between them, and the package's dense
    factorization pivots on it first, so a stretch lying on the ground adds no LU work
    (measured at x = 4, n = 297: 156 held nodes, LU of size 455 against 300).
    """
    act = np.asarray(active, dtype=bool)
    N = strip.size
    if act.shape != (N,):
        raise ValueError(f"active: got shape {act.shape}; expected ({N},) (one flag per node)")
    A = np.flatnonzero(act)
    free_nodes = np.flatnonzero(~act)
    na = A.size
    P = np.zeros((0, 3), dtype=np.int64) if pairs is None else \
        np.asarray(pairs, dtype=np.int64).reshape(-1, 3)
    npr = P.shape[0]
    if npr and not strip.thickness > 0.0:
        raise ValueError(f"pairs: got {npr} self-contact pairs; expected none for a strip "
                         "without a thickness")
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
        r[A] = rs * v[N:N + na]
        return v[:N], r

    def mu_of(v):
        return rs * np.asarray(v[N + na:])

    def join(u, r, mu=None):
        if not npr:
            return np.concatenate([u, np.asarray(r)[A] / rs])
        return np.concatenate([u, np.asarray(r)[A] / rs, np.asarray(mu) / rs])

    # a free rod: the stationarity rows of the gauge unknowns (z_0 and one angle), which
    # hold identically at any solution of the others (the energy and the gaps are
    # invariant under translations and rotations), are replaced by cg u_k = 0
    gauge = strip.gauge
    cg = strip.B / strip.h

    def residual(v, p):
        s = cache.at(p)
        if s is None:
            # a Newton iterate put the drop off the strip: a failed step for the
            # continuation (it halves the step), not an exception
            return np.full(N + na + npr, np.nan)
        if not npr:
            # the rows below in one compiled pass (the same bits)
            out = s.held_residual(v[:N], A, rs * v[N:N + na], c)
            out[gauge] = cg * v[gauge]
            return out
        u, r = split(v)
        stat, zs = s.stationarity(u, r)
        z = zs[A]
        z[1:] -= zs[A[:-1]]
        gp, _w = pair_gaps(s, u, P)
        stat -= pair_jacobian(s, u, P).T @ mu_of(v)
        stat[gauge] = cg * u[gauge]
        return np.concatenate([stat, c * z, c * gp])

    def lagrangian_hessian(v, p):
        s = cache.at(p)
        u, r = split(v)
        W = s.hessian(u)
        rs = np.cumsum(r[::-1])[::-1]
        W[idx, idx] += s.h * np.sin(u[1:]) * rs[1:]
        if npr:
            W -= pair_hessian(s, u, P, mu_of(v))
        return W

    def jacobian(v, p):
        s = cache.at(p)
        u, _r = split(v)
        J = np.zeros((N + na + npr, N + na + npr))
        J[:N, :N] = lagrangian_hessian(v, p)
        _held_blocks(s.h * np.cos(np.asarray(u[1:], dtype=float)), A, J, N, c, rs)
        if npr:
            Gp = pair_jacobian(s, u, P)
            J[:N, N + na:] = -rs * Gp.T
            J[N + na:, :N] = c * Gp
        if gauge.size:
            J[gauge, :] = 0.0
            J[gauge, gauge] = cg
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
        # the rows of the held constraints in F (see the docstring); inertia_negative
        # eliminates those with one nonzero before its LDL^T
        G = cache.at(p).constraint_jacobian(v[:N], A)
        D = G.copy()
        D[1:] -= G[:-1]
        if npr:
            D = np.vstack([D, pair_jacobian(cache.at(p), v[:N], P)])
        if gauge.size:  # the gauge unknowns are held: rows with one nonzero
            D = np.vstack([D, np.eye(N)[gauge]])
        return D

    def observables(v, p):
        s = cache.at(p)
        u, r = split(v)
        z = s.heights(u)
        return {"energy": s.energy(u),
                "min_reaction": float(np.min(r[A])) if na else math.inf,
                "min_gap": float(np.min(z[free_nodes])) if free_nodes.size else math.inf}

    prob = FunctionProblem(residual, jacobian=jacobian, dfdp=dfdp,
                           hessian=lagrangian_hessian,
                           constraint_jacobian=constraint_jacobian
                           if na or npr or gauge.size else None,
                           observables=observables, name=f"discrete strip, |A| = {na}" +
                           (f", |P| = {npr}" if npr else ""))
    return prob, {"split": split, "join": join, "mu": mu_of, "A": A, "P": P, "c": c,
                  "cache": cache, "side": side, "nearest_kink": nearest_kink}


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
    """The entries r_k / (q h) of the held nodes and c z_k / (q h) of the free ones (and
    the drop's and the self-contact's, below): their minimum is negative once the
    fixed-set branch stops being a contact equilibrium (dimensionless)."""
    split, A, c, cache = tools["split"], tools["A"], tools["c"], tools["cache"]
    N = strip.size
    free_nodes = np.setdiff1d(np.arange(N), A)
    scale = strip.q * strip.h if strip.q > 0.0 else 1.0
    sc = strip.thickness > 0.0
    P = tools["P"]
    npr = P.shape[0]
    unpaired = np.setdiff1d(np.arange(N), P[:, 0])
    held = {int(i): (int(j), int(sg)) for i, j, sg in P}

    def values(v, p):
        u, r = split(v)
        st = cache.at(p)
        z = st.heights(u)
        val = np.full(N + 1 + (2 * npr + 1 if sc else 0), np.inf)
        val[A] = r[A] / scale
        if st.ground:
            val[free_nodes] = c * z[free_nodes] / scale
        # last entry: the contact lines closing around the drop (ends the branch)
        stop = CHORD_STOP * st.delta
        val[N] = (st.chord(u) - stop) / stop
        if sc:
            # self-contact (_pair_event_layout): the held pairs' forces, the gap of the
            # unpaired nodes to their closest tested segment (-1 once the rod crosses
            # itself: a step cannot jump through the tube unseen), the pairs' feet
            X = st.positions(u)
            if npr:
                val[N + 1:N + 1 + npr] = tools["mu"](v) / scale
                val[N + 2 + npr:] = pair_gaps(st, u, P)[1]
            jc, dist, _d, _w = closest_segments(st, u, X)
            dist = dist[unpaired]
            if npr:
                # a node whose pair would be redundant with a held one is not tested
                # (solve_equilibrium does not add it either)
                for a, i in enumerate(unpaired):
                    if dist[a] < 2.0 * st.thickness and redundant_pair(u, i, jc[i], held):
                        dist[a] = np.inf
            # less _GRAZE: a node the held contacts carry past another at exactly d (the
            # tip sliding over a node of the lying base) grazes, not touches
            val[N + 1 + npr] = c * (float(np.min(dist)) - (1.0 - _GRAZE) * st.thickness
                                    ) / scale if unpaired.size else np.inf
            if count_crossings(X, X, True, 0, N):
                val[N + 1 + npr] = -1.0
        if guard and abs(p - p0) <= _START_TOL and \
                float(np.max(np.abs(v[:N] - v0[:N]))) <= _START_U:
            val[list(guard)] = math.inf
        return val

    return values


def _tangent(prob, v, p, orient):
    """Null vector t = (dv/ds, dDelta/ds) of [dF/dv, dF/dDelta] at (v, p), with
    orient . t > 0, and the sign of det [[dF/dv, dF/dDelta], [t^T]] (None if not known).

    One LU solve dF/dv w = -dF/dDelta, t = (w, 1) / |(w, 1)|, where dF/dv is regular (a
    restart point is no fold of the new contact set, generically); the SVD of the bordered
    matrix otherwise (4-6x the cost at n = 200). With t = a (w, 1) the bordered
    determinant is det(dF/dv) a (1 + |w|^2): its sign, from the same LU, is the sign of
    det(dF/dv) times that of dDelta/ds, which ``continue_branch`` takes instead of
    factorizing the bordered matrix at the start again.
    """
    Jv, fp = prob.jacobian(v, p), prob.dfdp(v, p)
    t = None
    det = None
    fac = factorize(Jv.copy())
    if fac is not None:
        w = fac.solve(-fp)
        if np.all(np.isfinite(w)) and np.linalg.norm(Jv @ w + fp) <= 1e-8 * (
                np.linalg.norm(fp) + np.linalg.norm(Jv, np.inf) * np.linalg.norm(w)):
            t = np.append(w, 1.0)
            t /= np.linalg.norm(t)
            det = fac.det_sign()
    if t is None:
        _U, _s, Vt = np.linalg.svd(np.column_stack([Jv, fp]))
        t = Vt[-1]
    if float(orient(t)) < 0.0:
        t = -t
    return t, (None if det is None else det * (1 if t[-1] > 0.0 else -1))


# --------------------------------------------------------------------------- driver
def _segment(strip, u0, r0, active, lo, hi, settings, tangent=None, guard=(), pairs=None,
             mu0=None, det_sign=None):
    prob, tools = active_set_problem(strip, active, pairs)
    v0 = tools["join"](u0, r0, mu0)
    p0 = float(strip.delta)
    values = _event_function(strip, tools, guard, v0, p0)
    st = settings.replace(p_min=lo, p_max=hi)
    if tools["P"].shape[0]:
        st = st.replace(locate_tol=max(st.locate_tol, _SELF_LOCATE_TOL))
    if settings.direction == 0 and tangent is None:
        raise ValueError("settings.direction: got 0; expected +1 or -1 (a chain of segments "
                         "follows one way; trace twice for both)")
    sign = float(np.sign(tangent[-1])) if tangent is not None else float(settings.direction)
    tools["side"][0] = sign
    if tangent is not None:
        # a given tangent already points the way (continue_branch reverses it for
        # direction = -1, which turned a restarted downward segment back up)
        st = st.replace(direction=1)
    # the contact event as the vector of its entries: continue_branch locates its sign
    # change on the one entry that makes it (smooth, where their minimum has kinks)
    events = {"contact": values, **_kink_events(strip, v0, p0, sign)}
    if strip.thickness > 0.0:
        # a constraint already violated at the start would keep the event function
        # negative all along, and no later event could fire
        why = _violated_start(values, v0, p0, "; try a smaller ds0")
        if why:
            return prob, tools, _empty(why), values
    br = continue_branch(prob, v0, p0, st, events=events, stop_on=tuple(events),
                         tangent=tangent, tangent_det_sign=det_sign)
    if strip.thickness > 0.0 and len(br.p):
        # the same at the corrected first point (a restart at two nearly simultaneous
        # self-contact events can start a hair inside a tube: measured at x = 3, n = 429,
        # a base node 2e-9 inside the tail's first free segment where the tail leaves
        # the base, which masked every later event of that segment)
        why = _violated_start(values, br.u[0], br.p[0],
                              " (at two nearly simultaneous contact events)")
        if why:
            return prob, tools, _empty(why), values
    return prob, tools, br, values


def _violated_start(values, v, p, hint):
    """Why a segment starting at ``(v, p)`` cannot trace (a constraint already violated
    there keeps its event function negative, so no later event could fire), or ""."""
    vals = values(v, p)
    if float(np.min(vals)) >= -_START_VIOLATION:
        return ""
    k = int(np.argmin(vals))
    return (f"the segment at Delta = {p:.12g} starts with event value {k} at {vals[k]:.3g} "
            f"(a constraint violated): its events could not fire{hint}")


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
        switched = ()
        k = int(np.argmin(np.abs(vals)))
        u, r = split(ev_sp.u)
        if ev_sp.name in ("kink_s1", "kink_s2"):
            st = cache.at(ev_sp.p)
            sc = st.s1 if ev_sp.name == "kink_s1" else st.s2
            k = int(round(sc / st.h))
            kind, val = ("contact_point_on_node", float(sc - k * st.h))
        elif k == strip.size:
            kind, k, val = "contact_lines_meet", -1, float(cache.at(ev_sp.p).chord(u))
        elif k > strip.size:
            kind, k, val, pair = _pair_event(strip, tools, ev_sp.u, ev_sp.p, k)
        else:
            z = cache.at(ev_sp.p).heights(u)
            # the located node first, then any that switch with it (_SIMULTANEOUS)
            both = [k] + [int(j) for j in np.argsort(np.abs(vals[:strip.size]))
                          if j != k and abs(vals[j]) <= _SIMULTANEOUS]
            switched = tuple(("lift_off", j, float(r[j])) if active[j] else
                             ("touch_down", j, float(z[j])) for j in both)
            kind, _k, val = switched[0]
        event = ActiveSetEvent(kind, k, float(ev_sp.p), u.copy(), r.copy(), val,
                               float(ev_sp.precision), switched)
        if tools["P"].shape[0] or strip.thickness > 0.0:
            event.pairs, event.pair_forces = tools["P"].copy(), tools["mu"](ev_sp.u)
            if k >= 0 and kind.startswith("pair_"):
                event.pair = pair
    I = [int(i) for i in br.stability[:m]]
    if stopped:
        I.append(_index(prob, ev_sp.u, ev_sp.p))
    U, R, E, IS, MU = [], [], [], [], []
    Pp = tools["P"]
    for v, p, idx in zip(V, P, I, strict=True):
        s = cache.at(p)
        u, r = split(v)
        U.append(u.copy())
        R.append(r)
        E.append(s.energy(u))
        mu = tools["mu"](v)
        MU.append(mu)
        if np.all(r[active] > R_REL * s.q * s.h) and np.all(mu > R_REL * s.q * s.h):
            # every held contact is strongly active: the two tangent spaces are the same
            IS.append(idx)
            continue
        eq = Equilibrium(u=u, energy=E[-1], parts={}, reactions=np.maximum(r, 0.0),
                         active=active.copy(), residual=0.0, iterations=0,
                         status="converged", message="")
        if Pp.shape[0]:
            eq.pairs, eq.pair_forces = Pp, np.maximum(mu, 0.0)
        IS.append(stability(s, eq)[0])
    folds = []
    for sp in br.folds:
        # a fold in the step of the event counts if it is a contact equilibrium
        if stopped and (sp.index > m or (sp.index == m and (
                sp.u is None or float(np.min(values(sp.u, sp.p))) < -1e-9))):
            continue
        uf, rf = split(sp.u) if sp.u is not None else (None, None)
        f = {"delta": float(sp.p), "located": bool(sp.located),
             "u": uf.copy() if uf is not None else None,
             "r": rf.copy() if rf is not None else None,
             "precision": float(sp.precision) if math.isfinite(sp.precision) else 0.0,
             "index": None}
        for o in br.points("stability"):
            if o.index == sp.index:
                f["index"] = tuple(int(i) for i in o.data["stability"])
        folds.append(f)
    return BranchSegment(active.copy(), np.array(P), np.array(U), np.array(R), np.array(E),
                         np.array(I, dtype=int), np.array(IS, dtype=int), folds, event, br,
                         "event" if stopped else _status_name(br), br.message,
                         Pp.copy(), np.array(MU).reshape(len(MU), Pp.shape[0]))


def _pair_event(strip, tools, v, p, k):
    """(kind, node, value, pair) of the self-contact event at entry k of the event values
    (:func:`_event_function`: after the N ground entries and the chord, the m held pairs'
    forces, the unpaired nodes' closing gap, the m pairs' feet)."""
    N = strip.size
    P = tools["P"]
    m = P.shape[0]
    st = tools["cache"].at(p)
    u = v[:N]
    off = k - N - 1
    if off < m:
        i, j, sg = (int(a) for a in P[off])
        return "pair_lift_off", i, float(tools["mu"](v)[off]), (i, j, sg)
    if off == m:
        jc, dist, dsgn, w = closest_segments(st, u)
        cand = np.setdiff1d(np.arange(N), P[:, 0])
        held = {int(a): (int(b), int(c)) for a, b, c in P}
        dc = np.array([np.inf if redundant_pair(u, a, jc[a], held) else dist[a] for a in cand])
        i = int(cand[np.argmin(dc)])
        j = int(jc[i])
        if w[i] < 0.0 or w[i] > 1.0:
            # the closest point is an end of the segment: a point pair with that node
            return "pair_touch_down", i, float(dist[i] - st.thickness), \
                (i, j if w[i] < 0.0 else j + 1, 0)
        # the side: where the node is at the event (at the thickness, outside the tube)
        return "pair_touch_down", i, float(dist[i] - st.thickness), \
            (i, j, 1 if dsgn[i] >= 0.0 else -1)
    q = off - m - 1
    i, j, sg = (int(a) for a in P[q])
    return "pair_switch", i, float(pair_gaps(st, u, P[q:q + 1])[1][0]), (i, j, sg)


def _restart_pair(strip: DiscreteStrip, active, event: ActiveSetEvent, d_in):
    """(active, u, reactions, pairs, forces, tangent, its bordered determinant's sign (or
    None, :func:`_tangent`), guard) of the segment that starts at
    a self-contact event.

    ``pair_lift_off``: the pair is released, the tangent chosen so that its gap opens;
    ``pair_touch_down``: the pair (i, j, sigma) is held with force 0, the tangent chosen so
    that its force grows (either may turn Delta back: a contact fold); ``pair_switch``: the
    node's pair becomes the one that continues it (:func:`~elastocap.strip.model.
    pair_switch`: the same gap there, same force), Delta going on the way it went
    (``d_in``); where none does (the strip's end), the pair is released. Other held pairs
    whose foot reaches the end of their segment at the same point switch with it.
    ``guard``: the entries of the new event values that are ~0 at the start (left out
    there, as the ground's switched nodes). The ground's held set is kept.
    """
    N = strip.size
    P, mu = event.pairs.copy(), event.pair_forces.copy()
    i, j, sg = event.pair
    rows = {int(a): (int(b), int(c), float(f)) for (a, b, c), f in zip(P, mu, strict=True)}
    u0, r0 = event.u, np.where(active, event.reactions, 0.0)
    if event.kind == "pair_lift_off":
        del rows[i]
    elif event.kind == "pair_touch_down":
        rows[i] = (j, sg, 0.0)
    else:
        nxt = pair_switch(strip, event.u, (i, j, sg))
        if nxt is None:
            del rows[i]
        else:
            rows[i] = (nxt[1], nxt[2], rows[i][2])
    # other held pairs whose form ends here too (a tail lying flat on the base has its
    # nodes over the base's nodes at once): switched with it, and guarded
    also = []
    for a, (b, c, f) in list(rows.items()):
        if a == i:
            continue
        reg = pair_gaps(strip, event.u, np.array([[a, b, c]]))[1][0]
        if reg < _SIMULTANEOUS:
            nxt = pair_switch(strip, event.u, (a, b, c))
            if nxt is None:
                del rows[a]
            else:
                rows[a] = (nxt[1], nxt[2], f)
                also.append(a)
    keys = sorted(rows)
    Pn = np.array([(a, rows[a][0], rows[a][1]) for a in keys], dtype=np.int64).reshape(-1, 3)
    mun = np.array([rows[a][2] for a in keys])
    m = Pn.shape[0]
    na = int(np.count_nonzero(active))
    extra = tuple(N + 2 + m + keys.index(a) for a in also)
    prob, tools = active_set_problem(strip, active, Pn)
    v0 = tools["join"](u0, r0, mun)
    if event.kind == "pair_lift_off":
        G = pair_jacobian(strip, event.u, np.array([[i, j, sg]]))[0]

        def orient(t):
            return G @ t[:N]
        guard = (N + 1 + m,)
    elif event.kind == "pair_touch_down" and i in rows:
        q = keys.index(i)

        def orient(t):
            return t[N + na + q]
        guard = (N + 1 + q, N + 1 + m)
    elif event.kind == "pair_switch" and i in rows:
        q = keys.index(i)

        def orient(t):
            return t[-1] * d_in
        guard = (N + 2 + m + q,)
    else:
        def orient(t):
            return t[-1] * d_in
        guard = ()
    tangent, det = _tangent(prob, v0, strip.delta, orient)
    return active, u0, r0, Pn, mun, tangent, det, guard + extra


def _index(prob, v, p):
    C = prob.constraint_jacobian(v, p) if prob.constraint_jacobian is not None else None
    return inertia_negative(prob.hessian(v, p), C)


_STATUS_NAMES = {MAX_STEPS: "max_steps", PARAMETER_BOUND: "parameter_bound",
                 STEP_TOO_SMALL: "step_too_small", START_FAILED: "start_failed",
                 STOPPED: "stopped", NON_FINITE: "non_finite", LOOP_CLOSED: "loop_closed"}


def _status_name(br):
    return _STATUS_NAMES.get(br.status, str(br.status))


def _restart(strip: DiscreteStrip, active, event: ActiveSetEvent):
    """(held set, tangent, its bordered determinant's sign (or None, :func:`_tangent`),
    switched nodes, alternatives) of the segment that starts at
    ``event``.

    With one node at the event, it switches. With several (``event.switched``: their
    event values vanish together), the contact set can change in several ways, as at a
    nonsmooth bifurcation: each subset of them may switch (all subsets up to three
    nodes; else all of them or one). A way is valid when its tangent leaves the invalid
    side for every node of the event: a held node's reaction grows (a touched-down one,
    or one that stays held), a free node rises (a lifted one, or one that stays free).
    Of the valid ways the driver follows a stable one (index 0 at the event) if any,
    switching as many nodes as possible; the other valid ways are returned as
    ``alternatives`` ((nodes, index), not traced). When none is valid, every node
    switches (the others' events then follow within a step or two).
    """
    N = strip.size
    G = strip.constraint_jacobian(event.u)
    nodes = [j for _kd, j, _v in event.switched]
    if len(nodes) == 1:
        groups = [nodes]
    elif len(nodes) <= 3:
        groups = [[j for b, j in enumerate(nodes) if m >> b & 1]
                  for m in range(2 ** len(nodes) - 1, 0, -1)]
    else:
        groups = [nodes] + [[j] for j in nodes]
    ways = []
    for group in groups:
        new = active.copy()
        new[group] = ~new[group]
        r0 = np.where(new, event.reactions, 0.0)
        nprob, ntools = active_set_problem(strip, new, event.pairs)
        A = ntools["A"]

        def rates(t, new=new, A=A):
            # > 0 on the valid side: d r_j (held now) or d z_j (free now), every node
            return np.array([t[N + int(np.searchsorted(A, j))] if new[j]
                             else G[j] @ t[:N] for j in nodes])

        lead = nodes.index(group[0])
        v0 = ntools["join"](event.u, r0, event.pair_forces)
        tangent, det = _tangent(nprob, v0, strip.delta, lambda t, rates=rates, lead=lead:
                           rates(t)[lead])
        r = rates(tangent)
        valid = len(nodes) == 1 or bool(np.all(r > -1e-12 * np.max(np.abs(r))))
        index = _index(nprob, v0, strip.delta) if len(nodes) > 1 else 0
        ways.append((tuple(group), new, tangent, valid, index, det))
    valid = [w for w in ways if w[3]]
    pick = min(valid, key=lambda w: (w[4] > 0, -len(w[0]))) if valid else ways[0]
    alternatives = tuple((w[0], int(w[4])) for w in valid if w is not pick)
    return pick[1], pick[2], pick[5], pick[0], alternatives


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
    pairs, mu0 = (state.pairs, state.pair_forces) if len(state.pairs) else (None, None)
    cur, tangent, tdet, guard = strip, None, None, ()
    segments, events, turning = [], [], []
    status, message = "max_segments", f"stopped after max_segments = {max_segments}"
    for _ in range(max_segments):
        prob, tools, br, values = _segment(cur, u0, r0, active, lo, hi, settings, tangent,
                                           guard, pairs, mu0, tdet)
        if len(br.p) == 0:
            status, message = _status_name(br), br.message
            break
        seg = _collect(cur, active, prob, tools, br, values)
        segments.append(seg)
        status, message = seg.status, seg.message
        if seg.event is None:
            break
        kink = seg.event.kind == "contact_point_on_node"
        self_contact = seg.event.kind.startswith("pair_")
        if guard and not kink and not self_contact and seg.event.node in guard and \
                len(seg.delta) <= 2:
            status = "restart_failed"
            message = (f"the segment restarted at Delta = {cur.delta:.12g} with node(s) "
                       f"{', '.join(str(j) for j in guard)} switched undid the switch at its "
                       f"first step ({seg.event.kind} of node {seg.event.node}): the "
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
        message = (", ".join(f"{kd} of node {j}" for kd, j, _v in seg.event.switched)
                   or f"{seg.event.kind} of node {seg.event.node}") + \
            f" at Delta = {seg.event.delta:.12g}"
        if not restart:
            break
        if self_contact:
            prev = segments[-2].event if len(segments) > 1 else None
            undo = prev is not None and prev.kind.startswith("pair_") and \
                prev.node == seg.event.node and (
                    {prev.kind, seg.event.kind} == {"pair_touch_down", "pair_lift_off"} or
                    (prev.kind == seg.event.kind == "pair_switch" and
                     pair_switch(cur, seg.event.u, seg.event.pair) is not None and
                     pair_switch(cur, seg.event.u, seg.event.pair)[1] == prev.pair[1]))
            if len(seg.delta) <= 2 and undo:
                status = "restart_failed"
                message = (f"the segment restarted at Delta = {cur.delta:.12g} "
                           f"({segments[-2].event.kind} of node {seg.event.node}) undid it at "
                           f"its first step ({seg.event.kind}): not transversal there; try a "
                           "smaller ds0")
                break
            cur = strip.with_(delta=seg.event.delta)
            # the way Delta went into the event: the last step that moved it (a segment
            # between two events at the same Delta has none)
            d_in = next((float(dd[dd != 0.0][-1]) for dd in
                         (np.diff(x.delta) for x in reversed(segments)) if np.any(dd != 0.0)),
                        float(settings.direction))
            active, u0, r0, pairs, mu0, tangent, tdet, guard = _restart_pair(
                cur, active, seg.event, d_in)
            u0 = u0.copy()
            continue
        if kink:
            # same contact set on the far side of the kink: the tangent from the one-sided
            # dF/dDelta there, Delta going on the same way (a corner, not a fold)
            cur = strip.with_(delta=seg.event.delta)
            u0, r0 = seg.event.u.copy(), seg.event.reactions.copy()
            if pairs is not None:
                mu0 = seg.event.pair_forces
            nprob, ntools = active_set_problem(cur, active, pairs)
            d_in = seg.delta[-1] - seg.delta[-2] if seg.delta.size > 1 else \
                (tangent[-1] if tangent is not None else float(settings.direction))
            ntools["side"][0] = float(np.sign(d_in))

            def orient(t, d_in=d_in):
                return t[-1] * d_in

            tangent, tdet = _tangent(nprob, ntools["join"](u0, r0, mu0), cur.delta, orient)
            guard = ()
            continue
        # the next segment: updated set, from the event, away from the invalid side
        cur = strip.with_(delta=seg.event.delta)
        active, tangent, tdet, guard, seg.event.alternatives = _restart(cur, active,
                                                                        seg.event)
        seg.event.followed = guard
        u0 = seg.event.u.copy()
        r0 = np.where(active, seg.event.reactions, 0.0)
        if pairs is not None:
            mu0 = seg.event.pair_forces
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
    "rod-rod contact in the branch search (the strip may cross itself: such states are "
    "marked inadmissible, not excluded; a branch with contact, rod.thickness > 0, is traced "
    "from one state by trace_discrete_branch); branches not reached from the seeds "
    "(deposition and fold at "
    f"Delta = {', '.join(f'{d:g}' for d in SEED_DELTAS)}); only drop.wetted_length "
    "as the parameter"
)


def _searched_strip(scene: Scene, n) -> DiscreteStrip:
    """The discrete strip of the branch search: the scene's, without self-contact."""
    strip = discrete_strip_for(scene, n)
    return strip.with_(thickness=0.0) if strip.thickness else strip


def contact_note(scene: Scene) -> str:
    """What the branch search leaves out of a scene with a thickness ("" without one)."""
    d = scene.rod.thickness
    if not d:
        return ""
    return (f"rod.thickness = {d:g} is left out of the strip's branch search (run at 0: "
            "states whose strip crosses itself are marked inadmissible); a branch with "
            "self-contact: elastocap.strip.trace.trace_discrete_branch from a state of "
            "elastocap.strip.solve.wrapped_state (docs/guide/strip.md)")


# --------------------------------------------------------------------------- checks
def check_trace_request(scene: Scene, parameter: str, prange):
    """Raise the :class:`SceneError` that :func:`trace_contact_branches` would raise for this
    scene, parameter and range, without tracing; else return the range (lo, hi)."""
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
    from elastocap.statics.branches import DROP_AREA_OVER_DELTA2_MAX

    lo_min = math.sqrt(scene.drop.area / DROP_AREA_OVER_DELTA2_MAX)
    if lo < lo_min:
        raise SceneError("--range", [lo, hi],
                         f"expected LO >= {lo_min:.4g}: the drop model is checked for "
                         f"drop.area / Delta^2 <= {DROP_AREA_OVER_DELTA2_MAX:g}")
    return lo, hi


# --------------------------------------------------------------------------- the search
class ContactProblem(Problem):
    """The strip on the ground as one fixed-size, semismooth problem F(v, Delta) = 0.

    Unknowns v = (u, w), shape (2 N,), N = n + 1: the state u = (z_0, theta_0 ..
    theta_{n-1}) and one reaction per node, w_k = r_k / gamma (r_k force, 0 off the
    ground). Residual (force units)::

        grad E(u) - sum_k r_k grad z_k(u)      (N equations)
        min(r_k, c z_k)                        (N equations, c = B / h^3)

    the complementarity z >= 0, r >= 0, r z = 0 written as the semismooth equation of the
    primal-dual active-set method (Hintermueller, Ito & Kunisch 2002). ``jacobian`` is its
    generalized Jacobian (row c grad z_k where c z_k < r_k, the node held; row d r_k / d w_k
    otherwise), so Newton on F is the active-set method and the size of v never changes at
    a contact event: the generic search (:class:`continuation.BranchSearch`) records,
    deflates and compares strip states as for any problem. The branches themselves are
    continued one contact set at a time (:func:`continue_contact_branch`, the search's
    continuer), where F is smooth.

    ``seeds(Delta)``: at the values of ``seed_deltas``, the deposition
    (:func:`~elastocap.strip.solve.open_state`) and the fold
    (:func:`~elastocap.strip.solve.wrapped_state`), in that order (a descent that fails
    gives a non-finite seed, which the search's Newton refuses at once); none elsewhere.
    ``only``: the (Delta, seed index) pairs to compute (the others are non-finite seeds);
    default all. ``deflation_indices``: u (the reactions are not measured).
    """

    SEED_KINDS = ("deposition", "fold")

    def __init__(self, strip: DiscreteStrip, seed_deltas=(), only=None):
        self.strip = strip
        self.only = None if only is None else {(round(float(d), 10), int(j)) for d, j in only}
        self.N = strip.size
        self.c = strip.B / strip.h**3
        self.rs = strip.gamma if strip.gamma > 0.0 else 1.0
        self.seed_deltas = tuple(float(d) for d in seed_deltas)
        self.deflation_indices = slice(0, self.N)
        self.name = f"discrete strip on the ground, n = {strip.n}"
        self.parameters = {"n_edges": strip.n}
        self._cache = _Cache(strip)
        #: the polished seed equilibria computed so far, by (Delta, seed index)
        self.seed_states = {}

    def split(self, v) -> tuple[np.ndarray, np.ndarray]:
        """(u, r): the state (N,) and the reactions (N,, force)."""
        v = np.asarray(v, dtype=float)
        return v[: self.N], self.rs * v[self.N:]

    def join(self, u, r) -> np.ndarray:
        """v from the state u and the reactions r (force)."""
        return np.concatenate([np.asarray(u, dtype=float), np.asarray(r, dtype=float) / self.rs])

    def residual(self, v, p):
        s = self._cache.at(p)
        if s is None:
            return np.full(2 * self.N, np.nan)
        u, r = self.split(v)
        stat, z = s.stationarity(u, r)
        return np.concatenate([stat, np.minimum(r, self.c * z)])

    def jacobian(self, v, p):
        s = self._cache.at(p)
        N = self.N
        u, r = self.split(v)
        G = s.constraint_jacobian(u)
        J = np.zeros((2 * N, 2 * N))
        J[:N, :N] = lagrangian_hessian(s, u, r)
        J[:N, N:] = -self.rs * G.T
        held = self.c * s.heights(u) < r
        J[N:, :N][held] = self.c * G[held]
        free = np.flatnonzero(~held)
        J[N + free, N + free] = self.rs
        return J

    def dfdp(self, v, p):
        e = _FD_DELTA * (1.0 + abs(p))
        return (self.residual(v, p + e) - self.residual(v, p - e)) / (2.0 * e)

    def held(self, v, p) -> np.ndarray:
        """The contact set of v (bool, (N,)): where the min picks the gap."""
        u, r = self.split(v)
        return self.c * self._cache.at(p).heights(u) < r

    def seeds(self, p):
        if not any(abs(p - d) <= 1e-12 for d in self.seed_deltas):
            return []
        s = self.strip.with_(delta=float(p))
        out = []
        for j, seed in enumerate((open_state, wrapped_state)):
            if self.only is not None and (round(float(p), 10), j) not in self.only:
                out.append(np.full(2 * self.N, np.nan))
                continue
            eq = seed(s)
            if eq.success:
                # polished to the round-off floor: the search's Newton accepts it as it is
                eq = solve_equilibrium(s, eq.u, active=eq.active, tol=_POLISH, max_iter=10,
                                       compute_index=False)
            self.seed_states[(round(float(p), 10), j)] = eq
            out.append(self.join(eq.u, np.where(eq.active, eq.reactions, 0.0))
                       if eq.success else np.full(2 * self.N, np.nan))
        return out


# Relative KKT residual of a polished seed (solve_equilibrium's tol): the round-off floor
# is ~1e-12 of the largest generalized force, so 1e-11 leaves max|F| ~ 4e-10 at gamma = 40,
# below the search's newton_tol of 1e-9.
_POLISH = 1e-11


def _empty(message: str) -> Branch:
    return Branch(p=np.empty(0), u=None, tangent=None, ds=np.empty(0),
                  newton_iterations=np.empty(0, dtype=int), stability=np.empty(0, dtype=int),
                  observables={}, special_points=[], status=START_FAILED, message=message)


_END_CODES = {"parameter_bound": PARAMETER_BOUND, "max_steps": MAX_STEPS,
              "max_segments": MAX_STEPS, "step_too_small": STEP_TOO_SMALL,
              "restart_failed": STEP_TOO_SMALL, "non_finite": NON_FINITE,
              "start_failed": START_FAILED}


def continue_contact_branch(problem: ContactProblem, v, p: float,
                            settings: ContinuationSettings, events=None,
                            stop_on=()) -> Branch:
    """The branch of the strip through the KKT point ``(v, p)``, both ways (the search's
    continuer).

    From the contact set of v, :func:`trace_discrete_branch` follows the branch down and up
    in Delta through every contact event (restarting at the updated set) and every corner;
    the two chains are joined into one :class:`continuation.Branch` in the problem's fixed
    unknowns v = (u, r / gamma), in order of the arclength (the downward chain reversed,
    then the upward one; a segment's end and the next one's start are the same event
    point, both kept).

    Each point carries ``stability`` (the index at its contact set), the observables of
    :func:`~elastocap.strip.model.point_measures`, ``index_strong``
    (:func:`~elastocap.strip.solve.stability`) and ``segment``. Special points: smooth folds
    (``fold``, name ``"smooth"``), contact folds (``fold``, name ``"contact"``: Delta turns
    back at an event; ``data``: ``node``, ``event``, ``stability`` in branch order),
    contact events (``event``, named by their kind) and the two ends (``endpoint``, named by
    the status of that end). ``metadata``: ``segments`` (``start``, ``stop`` point indices,
    ``held`` node indices), ``start_index`` (the point v), ``end_status`` and
    ``end_message`` (down, up). ``settings`` supplies the range (``p_min``, ``p_max``) and
    the step controls; ``events`` and ``stop_on`` are not used (the segments have their
    own: the contact events).
    """
    strip = problem.strip.with_(delta=float(p))
    u, r = problem.split(v)
    eq = solve_equilibrium(strip, u, active=problem.held(v, p), tol=_POLISH, max_iter=30)
    if not eq.success:
        return _empty(f"the start at Delta = {p:.12g} is not a contact equilibrium "
                      f"({eq.message})")
    halves = []
    for direction in (-1, 1):
        st = settings.replace(direction=direction)
        halves.append(trace_discrete_branch(strip, eq, (settings.p_min, settings.p_max), st,
                                            restart=True, max_segments=MAX_SEGMENTS))
    return _join(problem, halves)


def _join(problem: ContactProblem, halves) -> Branch:
    down, up = halves
    base = problem.strip
    P, V, I, IS, SEG, segs, sps = [], [], [], [], [], [], []
    at = {}  # id of each segment's event (kinks included) -> its point's index

    def add_segment(seg, reverse):
        i0 = len(P)
        order = range(seg.delta.size - 1, -1, -1) if reverse else range(seg.delta.size)
        k = len(segs)
        for j in order:
            P.append(float(seg.delta[j]))
            V.append(problem.join(seg.u[j], seg.reactions[j]))
            I.append(int(seg.index[j]))
            IS.append(int(seg.index_strong[j]))
            SEG.append(k)
        segs.append({"start": i0, "stop": len(P),
                     "held": [int(q) for q in np.flatnonzero(seg.active)]})
        ev = seg.event
        if ev is not None:
            at[id(ev)] = i0 if reverse else len(P) - 1
        if ev is not None and ev.kind != "contact_point_on_node":
            sps.append(SpecialPoint("event", i0 if reverse else len(P) - 1, ev.delta,
                                    problem.join(ev.u, ev.reactions), ev.precision, True,
                                    ev.kind, {"node": int(ev.node), "value": float(ev.value),
                                              "switched": [[kd, int(j), float(val)] for
                                                           kd, j, val in ev.switched
                                                           if not ev.followed or j in ev.followed],
                                              "not_followed": [
                                                  {"nodes": [int(j) for j in g], "index": i}
                                                  for g, i in ev.alternatives]}))
        for f in seg.folds:
            if f["u"] is None:
                continue
            near = i0 + int(np.argmin(np.abs(np.array(P[i0:]) - f["delta"])))
            chg = f["index"][::-1] if (reverse and f["index"]) else f["index"]
            sps.append(SpecialPoint("fold", near, f["delta"], problem.join(f["u"], f["r"]),
                                    f["precision"], f["located"], "smooth",
                                    {"stability": list(chg) if chg else None}))

    for seg in reversed(down.segments):
        add_segment(seg, True)
    start = len(P) - 1 if down.segments else 0
    for seg in up.segments:
        add_segment(seg, False)
    if not P:
        return _empty(f"no segment traced: {down.message}; {up.message}")
    for half, reverse in ((down, True), (up, False)):
        for tp in half.turning_points:
            # the event where Delta turns back (a contact event, or a corner where a contact
            # point crosses a node: not among the branch's contact events)
            ev = next(sg.event for sg in half.segments if sg.event is not None
                      and sg.event.delta == tp["delta"] and sg.event.node == tp["node"])
            i = at[id(ev)]
            chg = list(tp["index"][::-1]) if reverse else list(tp["index"])
            sps.append(SpecialPoint("fold", i, ev.delta, problem.join(ev.u, ev.reactions),
                                    ev.precision, True, "contact",
                                    {"node": int(tp["node"]), "event": tp["kind"],
                                     "stability": chg}))
    m = len(P)
    sps += _stability_changes(problem, P, V, I, SEG, segs, sps)
    for i, half in ((0, down), (m - 1, up)):
        sps.append(SpecialPoint("endpoint", i, P[i], V[i].copy(), 0.0, True, half.status,
                                {"message": half.message}))
    sps.sort(key=lambda sp: (sp.index, sp.p))
    rows = [point_measures(base.with_(delta=d), V[i][: problem.N]) for i, d in enumerate(P)]
    obs = {k: np.array([row[k] for row in rows], dtype=float) for k in rows[0]}
    obs["index_strong"] = np.array(IS, dtype=float)
    obs["segment"] = np.array(SEG, dtype=float)
    codes = [_END_CODES.get(h.status, STOPPED) for h in (down, up)]
    bad = [c for c in codes if c not in (PARAMETER_BOUND, STOPPED)]
    status = bad[0] if bad else (PARAMETER_BOUND if codes == [PARAMETER_BOUND] * 2
                                 else STOPPED)
    return Branch(
        p=np.array(P), u=np.array(V), tangent=None, ds=np.zeros(m),
        newton_iterations=np.zeros(m, dtype=int), stability=np.array(I, dtype=int),
        observables=obs, special_points=sps, status=status,
        message=f"down: {down.status} ({down.message}); up: {up.status} ({up.message})",
        metadata={"problem": problem.name, "segments": segs, "start_index": int(start),
                  "end_status": [down.status, up.status],
                  "end_message": [down.message, up.message]})


def _as_equilibrium(s: DiscreteStrip, u, r, held) -> Equilibrium:
    """A traced point (state u, reactions r, held nodes) as an Equilibrium of ``s``."""
    return Equilibrium(u=u, energy=s.energy(u), parts={}, reactions=np.maximum(r, 0.0),
                       active=held, residual=0.0, iterations=0, status="converged",
                       message="")


def _stability_changes(problem: ContactProblem, P, V, I, SEG, segs, sps) -> list:
    """Unlocated branch points where the index changes with Delta going on the same way
    (no fold): another branch crosses there. Where the drop's centre is on a node or
    mid-edge the strip is mirror-symmetric and the symmetric open state loses stability to
    an antisymmetric mode this way (measured: n = 60, drop mid-strip, Delta = 1.2278). Each
    carries its ``kernel``: the unstable mode at the point of higher index
    (:func:`~elastocap.strip.solve.unstable_mode`, strongly active contacts held), so the
    search's seeds next to unlocated special points (:class:`continuation.BranchSearch`)
    try Newton from the state pushed both ways along it, deflated against the known
    states."""
    folds = {sp.index for sp in sps if sp.kind == "fold"}
    out = []
    base = problem.strip
    for i in range(1, len(P)):
        if I[i] == I[i - 1] or {i - 1, i} & folds:
            continue
        # the way Delta goes on either side (event points are doubled: skip equal Deltas)
        a = next((P[i - 1] - P[k] for k in range(i - 2, -1, -1) if P[k] != P[i - 1]), 0.0)
        b = next((P[k] - P[i] for k in range(i + 1, len(P)) if P[k] != P[i]), 0.0)
        if a * b <= 0.0:
            continue
        j = i if I[i] > I[i - 1] else i - 1
        s = base.with_(delta=P[j])
        u, r = problem.split(V[j])
        held = np.zeros(problem.N, dtype=bool)
        held[segs[SEG[j]]["held"]] = True
        mode = unstable_mode(s, _as_equilibrium(s, u, r, held))
        out.append(SpecialPoint("branch_point", j, float(P[j]), V[j].copy(), 0.0, False,
                                "stability_change",
                                {"kernel": np.concatenate([mode, np.zeros(problem.N)]),
                                 "stability": [int(I[i - 1]), int(I[i])]}))
    return out


def segments_of(br: Branch):
    """(slice of points, held nodes (bool, (N,))) of each fixed-set segment of a strip
    branch (:func:`continue_contact_branch`)."""
    N = br.u.shape[1] // 2
    for seg in br.metadata["segments"]:
        held = np.zeros(N, dtype=bool)
        held[np.asarray(seg["held"], dtype=int)] = True
        yield slice(seg["start"], seg["stop"]), held


def _label(origin, kinds) -> str:
    how, p = origin["how"], origin.get("p")
    if how == "seed":
        return f"{kinds[origin['seed']]} at Delta = {p:.4g}"
    if how == "neighbour":
        return f"from a state at Delta = {origin['from_sample']:.4g}, at Delta = {p:.4g}"
    if how == "special_point":
        return f"next to a {origin['kind']} at Delta = {origin['near']:.4g}"
    return f"{how} at Delta = {p:.4g}"


#: The generic search's settings for the strip. Samples are the seed values (and the two
#: range ends); the seeds are the physics' two states there. Neighbour seeds (each known
#: state tried, deflated, at the next sample) are on: measured at n = 60, x = 2 and 3, they
#: found no branch the seeds miss (1 and 2 branches) for +0.5 and -0.1 s CPU (6.0 and
#: 8.8 s). Switching is off: the fixed-set problem is generic in Delta (no branch points).
SEARCH = SearchSettings(samples=0, same_tol=_SAME, switch=False, max_rounds=3)


#: Descent seeds past a stability change without a fold (an unlocated branch point):
#: Delta this fraction of the range to either side, the state pushed along the unstable
#: mode by PUSH radians at its largest. Measured where the mirror-symmetric open state
#: loses stability (n = 60, drop mid-strip, Delta = 1.2278): 0.02 above it the pushed
#: descent reaches the asymmetric stable state (heights 0.53 off their mirror image);
#: below it, the symmetric state again.
PAST_CHANGE = 0.01
PUSH = 0.05


def _descend_pushed(s: DiscreteStrip, u, mode) -> list:
    """[(stable state or None, why None)] reached at the strip ``s``'s Delta by descent
    (with the stiff ground penalty, :data:`~elastocap.strip.solve.STIFF_PENALTY`) from
    ``u`` pushed by +PUSH and -PUSH (radians at its largest entry) along ``mode`` (u
    alone, one state, if mode is None); ``why``: "max_iter" where the descent did not come
    to rest, else "no minimum"."""
    N = s.size
    u = np.asarray(u)[:N]
    if mode is None:
        starts = [u]
    else:
        k = np.asarray(mode)[:N]
        push = PUSH * k / max(float(np.max(np.abs(k))), 1e-300)
        starts = [u + push, u - push]
    out = []
    for u0 in starts:
        # the stiff ground penalty: a soft one keeps the state just past a loss of
        # stability as its minimum (STIFF_PENALTY)
        eq = minimize_energy(s, u0, penalty=STIFF_PENALTY)
        if eq.success and eq.index == 0:
            eq = solve_equilibrium(s, eq.u, active=eq.active, tol=_POLISH, max_iter=10,
                                   compute_index=False)
        if eq.success and eq.index in (0, -1):
            out.append((eq, None))
        else:
            out.append((None, "max_iter" if eq.message.startswith(
                "the descent stopped at max_iter") else "no minimum"))
    return out


def _descent_starts(strip: DiscreteStrip, prob: ContactProblem, branches, lo, hi):
    """(v, Delta, Delta of the change) of stable states reached by descent from the state
    at each unlocated branch point pushed both ways along its kernel, PAST_CHANGE of the
    range to either side (:func:`_descend_pushed`): the branches another branch meets where
    the index changes."""
    out, d = [], PAST_CHANGE * (hi - lo)
    for br in branches:
        for sp in br.special_points:
            if sp.kind != "branch_point" or sp.located or "kernel" not in sp.data:
                continue
            for pp in (sp.p - d, sp.p + d):
                if not lo <= pp <= hi:
                    continue
                for eq, _why in _descend_pushed(strip.with_(delta=pp), sp.u,
                                                sp.data["kernel"]):
                    if eq is not None:
                        out.append((prob.join(eq.u, np.where(eq.active, eq.reactions, 0.0)),
                                    pp, float(sp.p)))
    return out


def _seed_grid(lo: float, hi: float) -> tuple:
    """The Delta values of the search's seeds inside (lo, hi) (its midpoint if none)."""
    return tuple(d for d in SEED_DELTAS if lo < d < hi) or (0.5 * (lo + hi),)


def _branch_settings(lo: float, hi: float) -> ContinuationSettings:
    """The continuation settings of a branch traced over lo <= Delta <= hi."""
    return ContinuationSettings(**{**DEFAULTS, "max_steps": _MAX_STEPS, "p_min": lo,
                                   "p_max": hi})


def search_contact_branches(strip: DiscreteStrip, lo: float, hi: float, progress=None,
                            settings: SearchSettings = SEARCH, only=None, starts=(),
                            descend: bool = True):
    """Every branch of ``strip`` over lo <= Delta <= hi reached by the generic search.

    :class:`continuation.BranchSearch` on :class:`ContactProblem` with the continuer
    :func:`continue_contact_branch`: seeds at ``SEED_DELTAS`` inside the range (its
    midpoint if none), each deflated against the states known there (the crossings of every
    branch already traced, recorded at each seed value), new ones continued both ways.
    ``only`` limits the seeds (:class:`ContactProblem`); ``starts`` (v, Delta) are
    continued first. ``descend``: then descend past every stability change without a fold
    (:func:`_descent_starts`) and continue the search from the stable states reached
    (:meth:`continuation.BranchSearch.extend`). Returns (branches, labels, search result,
    the seed equilibria computed: :attr:`ContactProblem.seed_states`).
    """
    grid = _seed_grid(lo, hi)
    prob = ContactProblem(strip, grid, only)
    cont = _branch_settings(lo, hi)
    search = BranchSearch(prob, cont, settings.replace(sample_values=grid), starts=starts,
                          parameter="drop.wetted_length", continuer=continue_contact_branch)
    labels = []

    def report(br, label):
        labels.append(label)
        if progress is not None:
            progress(f"traced {labels[-1]} (n = {strip.n}): {len(br)} points, "
                     f"{len(br.metadata['segments'])} segments, ends "
                     f"{' / '.join(br.metadata['end_status'])}")

    for br in search:
        report(br, _label(search.result.origins[len(labels)], prob.SEED_KINDS))
    done = 0
    while descend and done < len(search.result.branches):
        # each new branch may carry stability changes of its own
        past = _descent_starts(strip, prob, search.result.branches[done:], lo, hi)
        done = len(search.result.branches)
        if not past:
            break
        search.extend([(v, p) for v, p, _c in past])
        for o in search.result.origins[len(labels):]:
            c = next((c for v, p, c in past if p == o.get("p")), None) \
                if o.get("how") == "start" else None
            report(search.result.branches[len(labels)],
                   f"descent past a stability change at Delta = {c:.4g}, at Delta = "
                   f"{o['p']:.4g}" if c is not None else
                   _label(o, prob.SEED_KINDS))
    return search.result.branches, labels, search.result, prob.seed_states


# --------------------------------------------------------------------------- reporting
def _fold_list(strip: DiscreteStrip, branches, labels) -> list:
    folds = []
    N = strip.size
    for br, lab in zip(branches, labels, strict=True):
        for sp in br.folds:
            m = point_measures(strip.with_(delta=sp.p), sp.u[:N])
            folds.append({"value": float(sp.p), "kind": sp.name,
                          "node": sp.data.get("node"), "event": sp.data.get("event"),
                          "stability_change": sp.data.get("stability"),
                          "measure": m["measure"], "energy": m["energy"],
                          "encapsulated": bool(m["encapsulated"]),
                          "admissible": bool(m["admissible"]), "branch": lab,
                          "index": int(sp.index), "located": bool(sp.located),
                          "error_estimate": None})
    return sorted(folds, key=lambda f: f["value"])


def _event_list(branches, labels) -> list:
    return [{"delta": float(sp.p), "kind": sp.name, "node": sp.data["node"], "branch": lab,
             "value": sp.data.get("value"), "switched": sp.data.get("switched", []),
             "not_followed": sp.data.get("not_followed", [])}
            for br, lab in zip(branches, labels, strict=True) for sp in br.points("event")]


def _event_residuals(events) -> dict:
    """Largest |reaction| (force) and |gap| (length) at the located lift-off and
    touch-down events: how exactly the contact set changes where it is said to."""
    out = {}
    for key, kinds in (("reaction", ("lift_off",)), ("gap", ("touch_down",))):
        vals = [abs(v) for e in events for kd, _j, v in
                (e.get("switched") or [[e["kind"], e["node"], e.get("value")]])
                if kd in kinds and v is not None]
        out[key] = max(vals) if vals else None
    return out


def _kind_changes(strip: DiscreteStrip, branches, labels) -> list:
    """Where the paper's criterion flips along a branch, located to ~1e-12 in Delta.

    Between two consecutive traced points of a segment whose verdicts differ, Delta is
    bisected, each state solved by Newton at the segment's contact set from the nearer
    point; the criterion x(S_c) - x(L) is continuous along the branch, so the flip is where
    the free end passes above the impact centre. Returns dicts ``value``, ``index`` (the
    stability index there), ``from``, ``admissible``, ``branch``.
    """
    out = []
    N = strip.size
    for br, lab in zip(branches, labels, strict=True):
        enc = br.observables["encapsulated"] == 1.0
        for sl, held in segments_of(br):
            for i in range(sl.start, sl.stop - 1):
                if enc[i] == enc[i + 1] or br.p[i] == br.p[i + 1]:
                    continue
                a, c = float(br.p[i]), float(br.p[i + 1])
                ua, ea, ok = br.u[i][:N], bool(enc[i]), True
                for _ in range(60):
                    if abs(c - a) <= 1e-12 * (1.0 + abs(a)):
                        break
                    mid = 0.5 * (a + c)
                    eq = solve_equilibrium(strip.with_(delta=mid), ua, active=held,
                                           tol=1e-11, max_iter=30, compute_index=False)
                    if not eq.success:
                        ok = False
                        break
                    if is_encapsulated(strip.with_(delta=mid), eq.u) == ea:
                        a, ua = mid, eq.u
                    else:
                        c = mid
                if ok:
                    m = point_measures(strip.with_(delta=a), ua)
                    out.append({"value": 0.5 * (a + c), "index": int(br.stability[i]),
                                "from": "encapsulated" if ea else "open",
                                "admissible": bool(m["admissible"]), "branch": lab})
    return out


def _window(branches, folds=(), kind_changes=()) -> dict:
    """Largest Delta of a stable open state, smallest of a stable encapsulated one.

    A stable stretch of a branch ends at a located special point: a fold, a contact fold
    where the index changes, or a kind change (the verdict flips on a stable stretch, no
    fold); those count with the traced stable points, and ``how`` says which one gave
    each end (``"smooth_fold"``, ``"contact_fold"``, ``"kind_change"``; for a traced
    point, ``"stability_lost"`` or ``"inadmissible"`` when a neighbouring point on the
    branch is unstable or crosses itself, else ``"range"``: the stable stretch reaches the
    branch's end).
    """
    opens, encs = [], []

    def traced(br, sel, pick):
        i = int(np.flatnonzero(sel)[pick(br.p[sel])])
        nb = [j for j in (i - 1, i + 1) if 0 <= j < br.p.size]
        if any(br.stability[j] > 0 for j in nb):
            how = "stability_lost"
        elif any(br.observables["admissible"][j] != 1.0 for j in nb):
            how = "inadmissible"
        else:
            how = "range"
        return float(br.p[i]), how

    for br in branches:
        o = br.observables
        ok = (br.stability == 0) & (o["admissible"] == 1.0)
        enc = o["encapsulated"] == 1.0
        if np.any(ok & ~enc):
            opens.append(traced(br, ok & ~enc, np.argmax))
        if np.any(ok & enc):
            encs.append(traced(br, ok & enc, np.argmin))
    for f in folds:
        if f["admissible"] and f["stability_change"] and 0 in f["stability_change"]:
            (encs if f["encapsulated"] else opens).append((f["value"], f"{f['kind']}_fold"))
    for k in kind_changes:
        if k["index"] == 0 and k["admissible"]:
            opens.append((k["value"], "kind_change"))
            encs.append((k["value"], "kind_change"))
    # at a tie a located special point names the end (an event is also a traced point)
    located = ("smooth_fold", "contact_fold", "kind_change")
    top = max(opens, key=lambda t: (t[0], t[1] in located)) if opens else None
    bot = min(encs, key=lambda t: (t[0], t[1] not in located)) if encs else None
    return {
        "open_max": {"value": top[0] if top else None, "how": top[1] if top else None,
                     "error_estimate": None},
        "encapsulated_min": {"value": bot[0] if bot else None,
                             "how": bot[1] if bot else None, "error_estimate": None},
        "bistable": bool(top and bot and top[0] > bot[0]),
        "width": (top[0] - bot[0]) if top and bot else None,
    }


def _open_end(branches, labels, folds, kind_changes, at=None) -> dict:
    """The stable open stretch traced up from the deposition at the lowest seed value:
    from the point ``at`` = (branch index, point index) where given
    (:func:`_deposition_point`), else from the start of the branch labelled as that
    deposition."""
    if at is not None:
        k, s0 = at
        forward = None  # the way Delta rises from that point
    else:
        ks = [k for k, lab in enumerate(labels) if lab.startswith("deposition at")]
        if not ks:
            return {"value": None, "how": "no deposition branch"}
        k = min(ks, key=lambda q: float(labels[q].rsplit("= ", 1)[1]))
        # the branch's upward chain starts at its start point (continue_contact_branch)
        s0, forward = int(branches[k].metadata["start_index"]), True
    out = _stretch_up(branches[k], labels[k], s0, folds, kind_changes, forward=forward)
    if out["value"] is None:
        return {"value": None, "how": "deposition not a stable open state", "label": labels[k]}
    return out


def _locate_stability_loss(strip: DiscreteStrip, br, i: int, j: int, tol: float = 1e-10):
    """The Delta where ``br``'s stability index leaves 0 between its traced points ``i``
    (index 0) and ``j`` (index > 0) of one fixed-contact segment, by bisection: at each
    midpoint Newton at the segment's contact set from the mean of the bracket's states, and the
    index of the state found (:func:`~elastocap.strip.solve.solve_equilibrium`). Returns
    (Delta, [a, b]) with the index 0 at a and > 0 at b; the bisection stops early where
    Newton does not converge or changes the contact set (next to the singular point:
    measured at x = 5, n = 286, within 2e-5 of it), and the bracket says how far it got.
    None if the points are on different segments (the index changes at a contact event,
    which is then located already)."""
    segs = [(sl, h) for sl, h in segments_of(br) if sl.start <= min(i, j) and
            max(i, j) < sl.stop]
    if not segs:
        return None
    held = segs[0][1]
    N = strip.size
    a, b, ua, ub = float(br.p[i]), float(br.p[j]), br.u[i][:N], br.u[j][:N]
    while abs(b - a) > tol * (1.0 + abs(a)):
        m = 0.5 * (a + b)
        # Newton from the midpoint of the bracket's two states
        eq = solve_equilibrium(strip.with_(delta=m), 0.5 * (ua + ub), active=held,
                               tol=1e-11, max_iter=30)
        if not eq.success or not np.array_equal(eq.active, held):
            break
        if eq.index == 0:
            a, ua = m, eq.u
        else:
            b, ub = m, eq.u
    return 0.5 * (a + b), sorted((a, b))


def _point_of(s: DiscreteStrip, branches, eq: Equilibrium):
    """(branch index, point index) of the traced branch through the state ``eq`` at the
    strip ``s``'s Delta (:func:`solved_crossings`, the same state to 1e-7), or None."""
    index_of = {id(b): q for q, b in enumerate(branches)}
    return next(((index_of[id(b)], j) for b, j, e in solved_crossings(s, branches)
                 if e.success and np.max(np.abs(e.u - eq.u)) < 1e-7), None)


def _deposition_point(strip: DiscreteStrip, branches, lo: float, hi: float, seeded=None):
    """(branch index, point index) of the deposition at the lowest seed value on the traced
    branches: the branch through the seed's state (:func:`~elastocap.strip.solve.
    open_state`, the same state to 1e-7, :func:`solved_crossings`), whichever seed or
    start traced it. (A branch continued from another start can pass through it first; the
    seed is then not traced again and no branch carries its label: measured at x = 5,
    n = 286 following n = 143, where the branch of the state past the symmetric state's
    loss of stability runs down through the symmetric state.) The seed's state is taken
    from ``seeded`` (the search's :attr:`ContactProblem.seed_states`) where the search
    computed it, else descended to. None if no branch passes through it."""
    d0 = _seed_grid(lo, hi)[0]
    s = strip.with_(delta=d0)
    eq = (seeded or {}).get((round(float(d0), 10), 0))
    if eq is None:
        eq = open_state(s)
    return _point_of(s, branches, eq) if eq.success else None


def _stretch_up(br, label, s0, folds, kind_changes, forward=None) -> dict:
    """The stretch of stable, open, admissible points of ``br`` from its point ``s0`` the
    way Delta rises (along the arrays if ``forward``, against them if not; by default the
    way Delta rises from s0), and how it ends (:func:`open_branch_end`'s keys; ``stop``:
    the index of the first point past it, or None; ``step``: +1 or -1, the way walked).
    ``value`` None if the point s0 is not one."""
    o = br.observables
    mask = (br.stability == 0) & (o["encapsulated"] == 0.0) & (o["admissible"] == 1.0)
    fwd = forward if forward is not None else (
        s0 + 1 < br.p.size and (br.p[s0 + 1] >= br.p[s0] or s0 == 0))
    idx = np.arange(s0, br.p.size) if fwd else np.arange(s0, -1, -1)
    ok, d_all = mask[idx], br.p[idx]
    if not ok[0]:
        return {"value": None, "how": None, "label": label, "stop": None, "step": 0}
    # the stretch a spreading follows: stable open points while Delta does not decrease
    # (where it turns back, the state stops existing: a fold, smooth or at an event)
    turn = np.flatnonzero(np.diff(d_all) < 0.0)
    stop = int(np.argmin(ok)) if not ok.all() else ok.size
    turned = turn.size > 0 and turn[0] + 1 <= stop
    if turned:
        stop = int(turn[0]) + 1
    end = float(d_all[:stop].max())
    change = None
    if turned:
        how = "turning point (not located)"
    elif stop == ok.size:
        # how this direction of the branch ended
        status = br.metadata.get("end_status", ["?", "?"])[1 if fwd else 0]
        how = "range" if status == "parameter_bound" else f"branch end ({status})"
    elif br.stability[idx[stop]] != 0:
        how = "stability lost"
    elif o["encapsulated"][idx[stop]] == 1.0:
        how = "kind change"
    else:
        how = "inadmissible"
    # the located special point between the last stable open point and the next one
    if stop < ok.size:
        a, b = sorted((end, float(d_all[stop])))
        # where Delta turns back, the fold lies at or beyond the highest traced point, its
        # index between the first point at that height (several segments may meet at one
        # Delta) and the first point past the turn
        first, last = int(idx[int(np.argmax(d_all[:stop]))]), int(idx[stop])
        i_lo, i_hi = (first - 1, last) if fwd else (last - 1, first)
        fa, fb = (end, math.inf) if turned else (a, b)
        for f in folds:
            on_side = f["index"] >= s0 if fwd else f["index"] <= s0 + 1
            if f["branch"] == label and on_side and \
                    fa - 1e-9 <= f["value"] <= fb + 1e-9 and \
                    (not turned or i_lo <= f["index"] <= i_hi):
                end, how, change = f["value"], f"{f['kind']} fold", f["stability_change"]
                break
        # a kind change lies between the last stable open point and the next one
        for c in kind_changes:
            if c["branch"] == label and a - 1e-9 <= c["value"] <= b + 1e-9:
                end, how, change = c["value"], "kind change", None
    # a fold whose index does not change (0 on both sides): the branch turns back at an
    # active-set event with the open state stable on both sides; a spreading there jumps
    # to whatever state lies beyond, which this end does not say
    return {"value": end, "how": how, "label": label, "stability_change": change,
            "stable_both_sides": bool(change is not None and list(change) == [0, 0]),
            "stop": int(idx[stop]) if stop < ok.size else None, "step": 1 if fwd else -1}


#: Jumps a spreading is followed through past the deposited state's end (:func:`_past_loss`).
MAX_JUMPS = 8


def _jump(strip: DiscreteStrip, br, end: dict, pp: float, sign: int | None) -> list:
    """The stable states a spreading can land on at Delta ``pp`` past ``end`` (a stretch of
    ``br`` ending at a fold, a turning point or a loss of stability): [(push, Equilibrium
    or None, why None)]. After a fold, the descent from the last stable state; where that does not
    reach a stable state (it can stay on a saddle it cannot leave by symmetry), and after
    a loss of stability, the descents from the first unstable point past the end pushed
    along its unstable mode: both ways (push +1, -1) if ``sign`` is None, else that way."""
    j, step = int(end["stop"]), int(end["step"])
    s = strip.with_(delta=pp)
    if end["how"] != "stability lost":
        ((eq, why),) = _descend_pushed(s, br.u[j - step], None)
        if eq is not None:
            return [(0, eq, None)]
        if why == "max_iter":
            # the descent does not come to rest (a push along a mode does not help here:
            # measured at x = 5, n = 143 past the contact fold at 1.6684, the strip stays
            # open and admissible while its energy creeps down through contact changes)
            return [(0, None, "the descent did not come to rest within its max_iter "
                     "trust-region iterations")]
    # the first unstable point past the end (an event point is doubled: its first copy
    # can carry the index of the segment before)
    jj = next((q for q in range(j, j + 3 * step, step)
               if 0 <= q < br.p.size and br.stability[q] >= 1), None)
    if jj is None:
        return [(0, None, "no stable state reached, and no unstable point to push from")]
    held = next(h for sl, h in segments_of(br) if sl.start <= jj < sl.stop)
    u, r = ContactProblem(strip).split(br.u[jj])
    sj = strip.with_(delta=float(br.p[jj]))
    mode = unstable_mode(sj, _as_equilibrium(sj, u, r, held))
    # orient the mode: +1 is the way its largest entry is positive
    mode = mode * math.copysign(1.0, mode[int(np.argmax(np.abs(mode)))])
    pushed = _descend_pushed(s, u, mode)
    out = [(sg, eq, None if eq is not None else "the descent pushed along the unstable "
            "mode reached no stable state") for sg, (eq, _why) in
           zip((1, -1), pushed, strict=True)]
    return out if sign is None else [q for q in out if q[0] == sign]


def _spreading(end: dict) -> dict:
    """Where a quasi-static spreading from the deposition stops being open: ``value``
    (None: open to the range's end, or not decided) and ``how``; ``open_up_to``: the last
    end it was followed to (a lower bound where ``value`` is None). From ``past_loss`` where
    the deposited state's stretch ends by a fold or a loss of stability; else the
    stretch's own end where its state turns encapsulated or crosses itself."""
    past, how = end.get("past_loss"), end.get("how") or ""
    if past is not None:
        return {"value": past["value"], "how": past["how"],
                "open_up_to": past["open_up_to"]}
    if how in ("kind change", "inadmissible"):
        return {"value": end["value"], "how": how, "open_up_to": end["value"]}
    return {"value": None, "how": how or "no deposition", "open_up_to": end.get("value")}


def _trace_landing(strip: DiscreteStrip, eq: Equilibrium, p: float, lo: float, hi: float,
                   label: str, branches, labels, folds, kind_changes):
    """The branch through the stable state ``eq`` at Delta ``p``
    (:func:`continue_contact_branch`), appended to ``branches`` and ``labels``, its folds
    and kind changes to ``folds`` (kept sorted) and ``kind_changes``; (its index, the index
    of eq's point), or None if it could not be traced."""
    prob = ContactProblem(strip)
    v = prob.join(eq.u, np.where(eq.active, eq.reactions, 0.0))
    br = continue_contact_branch(prob, v, p, _branch_settings(lo, hi))
    if br.u is None or len(br) == 0:
        return None
    branches.append(br)
    labels.append(label)
    folds.extend(_fold_list(strip, [br], [label]))
    folds.sort(key=lambda f: f["value"])
    kind_changes.extend(_kind_changes(strip, [br], [label]))
    return len(branches) - 1, int(br.metadata["start_index"])


def _past_loss(strip: DiscreteStrip, branches, labels, folds, kind_changes, end: dict,
               lo: float, hi: float) -> dict | None:
    """Where a quasi-static spreading goes after the deposited state stops existing or
    being stable, up to where it is no longer open (``end``: :func:`_open_end`, ending by
    a fold, a turning point or ``stability lost``; None for the other ends, where the
    state turns encapsulated, crosses itself or the branch ends).

    At each end the strip jumps: the stable state it lands on is found by descent at
    Delta PAST_CHANGE of the range above the end (:func:`_jump`), and the traced branch
    through it (:func:`solved_crossings`, the same state to 1e-7; traced then, and added
    to ``branches``, ``labels``, ``folds`` and ``kind_changes``, if the search did not
    reach it: :func:`_trace_landing`) is followed up in Delta as the deposition's was
    (:func:`_stretch_up`), to its own end; and so on, up to MAX_JUMPS. Where a
    mirror-symmetric state loses stability the two tilts are followed apart (``sides``,
    push +1 and -1; later jumps keep the side's way).

    Returns ``{"value", "how", "sides", "open_up_to"}``. Each side: ``push``, ``jumps``
    (``from``: the end's Delta, ``how`` it ended, ``landing``: Delta of the descent,
    ``to``: the branch landed on, or what happened instead), ``open_up_to`` (the last end
    it was followed to) and ``value``: the Delta from which it lands on an encapsulated
    or a self-crossing state (``how`` "jump to an encapsulated state", "jump to an
    inadmissible state"), or where its open state turns encapsulated or crosses itself
    (``kind change``, ``inadmissible``); None if it stays open to the range's end
    (``how`` "range") or could not be followed (``how`` says why: e.g. the descent past
    an end does not come to rest). ``value``: the smallest side's value, None if a side
    is None; ``open_up_to``: the smallest side's.
    """
    how0 = end.get("how") or ""
    if end.get("stop") is None or not (how0 == "stability lost" or how0.endswith("fold")
                                       or how0.startswith("turning point")):
        return None
    d = PAST_CHANGE * (hi - lo)
    todo = [(None, end, [])]
    sides = []
    while todo:
        sign, cur, jumps = todo.pop(0)
        side = None
        for _ in range(MAX_JUMPS + 1):
            how = cur.get("how") or ""
            if not (how == "stability lost" or how.endswith("fold")
                    or how.startswith("turning point")):
                # a stretch ending where its open state turns encapsulated or crosses
                # itself, or at the range's (or branch's) end
                side = {"value": None if how == "range" or how.startswith("branch end")
                        else cur["value"], "how": how}
                break
            if len(jumps) == MAX_JUMPS:
                side = {"value": None, "how": f"not followed past {MAX_JUMPS} jumps"}
                break
            pp = cur["value"] + d
            if pp > hi:
                side = {"value": None, "how": "range (the last end lies within "
                        "PAST_CHANGE of the range's end)"}
                break
            br = branches[labels.index(cur["label"])]
            landed = _jump(strip, br, cur, pp, sign)
            if sign is None and len(landed) == 2:
                # the two tilts of a symmetric state: each followed on its own
                for push, _eq, _why in landed[1:]:
                    todo.append((push, cur, list(jumps)))
                sign = landed[0][0]
            _push, eq, why = landed[0]
            jump = {"from": cur["value"], "how": how, "landing": pp}
            jumps.append(jump)
            s = strip.with_(delta=pp)
            if eq is None:
                jump["to"] = f"no stable state ({why})"
                side = {"value": None, "how": f"not followed: {why}"}
                break
            if is_encapsulated(s, eq.u):
                jump["to"] = "encapsulated"
                side = {"value": cur["value"], "how": "jump to an encapsulated state"}
                break
            if point_measures(s, eq.u)["admissible"] != 1.0:
                jump["to"] = "a state that crosses itself (inadmissible)"
                side = {"value": cur["value"], "how": "jump to an inadmissible state"}
                break
            hit = _point_of(s, branches, eq)
            if hit is None:
                # a state the search did not reach: its branch is traced now and joins the
                # branch set (with its folds and kind changes)
                hit = _trace_landing(strip, eq, pp, lo, hi, f"spreading past Delta = "
                                     f"{cur['value']:.6g}", branches, labels, folds,
                                     kind_changes)
                if hit is None:
                    jump["to"] = "an open state whose branch could not be traced"
                    side = {"value": None, "how": "not followed: the branch of the state "
                            "reached could not be traced"}
                    break
            k2, j2 = hit
            b2, lab2 = branches[k2], labels[k2]
            jump["to"] = lab2
            nxt = _stretch_up(b2, lab2, j2, folds, kind_changes)
            if nxt["value"] is None:
                side = {"value": None, "how": "not followed: the state reached is not "
                        f"stable and open on its branch (index {int(b2.stability[j2])})"}
                break
            cur = nxt
        # the spreading is open up to the last end it was followed to
        up_to = max([cur["value"], *(q["from"] for q in jumps)])
        sides.append({"push": sign if sign is not None else 0, "jumps": jumps,
                      "open_up_to": up_to, **side})
    vals = [q["value"] for q in sides]
    if all(v is not None for v in vals):
        first = min(sides, key=lambda q: q["value"])
        value, how = first["value"], first["how"]
    else:
        value, how = None, "; ".join(q["how"] for q in sides if q["value"] is None)
    return {"value": value, "how": how, "sides": sides,
            "open_up_to": min(q["open_up_to"] for q in sides)}


def _follow(coarse: dict, strip: DiscreteStrip) -> tuple[dict, dict]:
    """The seeds and starts that make the branches of the analysis ``coarse`` at the
    resolution of ``strip``: the same seeds (Delta, kind) where a seed made a branch; the
    other branches' first states carried to ``strip`` by :func:`~elastocap.strip.solve.
    refine` (identity kept). Returns (the search's keywords ``only`` and ``starts``, the
    coarse branch's label of each: ``seeds`` by (Delta, kind), ``starts`` in order)."""
    only, starts = set(), []
    # the coarse branch's label of each seed and start (:func:`_followed`)
    seeds, start_labels = {}, []
    cprob = coarse["problem"]
    fine = ContactProblem(strip)
    # the search's branches (those the spreading traced after it follow from its starts)
    origins = coarse["search"].origins
    for o, br, lab in zip(origins, coarse["branches"][:len(origins)],
                          coarse["labels"][:len(origins)], strict=True):
        if o["how"] == "seed":
            only.add((o["p"], o["seed"]))
            seeds[(round(float(o["p"]), 10), int(o["seed"]))] = lab
            continue
        i = int(br.metadata["start_index"])
        d = float(br.p[i])
        cs = cprob.strip.with_(delta=d)
        u, _r = cprob.split(br.u[i])
        eq = solve_equilibrium(cs, u, active=cprob.held(br.u[i], d), tol=_POLISH)
        if eq.success:
            eq = refine_equilibrium(cs, eq, strip.with_(delta=d))
        if eq.success:
            starts.append((fine.join(eq.u, np.where(eq.active, eq.reactions, 0.0)), d))
            start_labels.append(lab)
    return {"only": only, "starts": starts}, {"seeds": seeds, "starts": start_labels}


def _followed(origins, labels, sources) -> dict:
    """{label of a branch traced by following: label of the coarse branch it follows}: a
    branch made by a seed follows the coarse branch that seed made; one made by a start,
    the coarse branch whose state that start carries (``sources``, from :func:`_follow`).
    Branches found otherwise (next to a special point) follow none."""
    out = {}
    for o, lab in zip(origins, labels, strict=True):
        if o["how"] == "seed":
            src = sources["seeds"].get((round(float(o["p"]), 10), int(o["seed"])))
        elif o["how"] == "start":
            src = sources["starts"][int(o["start"])]
        else:
            src = None
        if src is not None:
            out[lab] = src
    return out


def _analyse(strip: DiscreteStrip, lo: float, hi: float, progress=None, follow=None,
             spreading: bool = False) -> dict:
    """Search, then the special points, kind changes, window and open branch's end (with
    ``spreading``, the spreading past it: :func:`_past_loss`). ``follow`` (another
    resolution's analysis): trace the same branches, seeded as there, instead of every
    seed (:func:`_follow`)."""
    kw, sources = {}, None
    if follow is not None:
        # following, not searching: no neighbour seeds and one round
        kw, sources = _follow(follow, strip)
        kw["settings"] = SEARCH.replace(neighbour_seeds=False, max_rounds=1)
    branches, labels, res, seeded = search_contact_branches(strip, lo, hi, progress,
                                                    descend=follow is None, **kw)
    folds = _fold_list(strip, branches, labels)
    kinds = _kind_changes(strip, branches, labels)
    end = _open_end(branches, labels, folds, kinds,
                    at=_deposition_point(strip, branches, lo, hi, seeded))
    if end.get("how") == "stability lost" and end.get("stop") is not None:
        # located between the last stable traced point and the first unstable one
        br = branches[labels.index(end["label"])]
        j = int(end["stop"])
        loc = _locate_stability_loss(strip, br, j - int(end["step"]), j)
        if loc is not None:
            end["value"], end["bracket"] = loc
    # the spreading past the deposition's end may trace branches the search did not reach
    branches, labels = list(branches), list(labels)
    if spreading:
        end["past_loss"] = _past_loss(strip, branches, labels, folds, kinds, end, lo, hi)
        end["spreading"] = _spreading(end)
    end.pop("stop", None)
    end.pop("step", None)
    window = _window(branches, folds, kinds)
    return {"branches": branches, "labels": labels, "search": res, "folds": folds,
            "followed": {} if sources is None else _followed(res.origins, labels, sources),
            "problem": ContactProblem(strip),
            "kind_changes": kinds, "window": window, "events": _event_list(branches, labels),
            "open_branch_end": end}


#: Distances in the plane (Delta, measure) that differ by less are equal when folds are
#: paired across resolutions: the two folds of a mirror pair (a drop centred on a node)
#: differ by about 1e-13.
TIE = 1e-9


def _fold_errors(folds, refined, followed) -> None:
    """Set each fold's ``error_estimate``: the distance in Delta to its counterpart among
    the folds of the same kind and stability change at the finer resolution (``refined``);
    None where it has none.

    Folds are points (Delta, measure) of their branches, and a fold's counterpart moves by
    the discretization error in both. Counterparts are paired one to one, the pairs of
    least total distance in that plane (:func:`scipy.optimize.linear_sum_assignment`):
    first the folds of each branch with those of the branch that follows it there
    (``followed``: {refined branch's label: label of the branch it follows},
    :func:`_followed`), then the folds of branches that no refined branch follows with the
    refined folds left. A pair is kept only when no other fold of the kind, at either
    resolution, is nearer (by more than :data:`TIE`) to one of its two folds than the
    other is: else the refined fold is another fold's counterpart, or this fold has
    another, and a fold of another branch is no estimate of this one's. A fold without a
    finite measure is placed at measure 0 (paired by Delta alone). Measured: at x = 4.5,
    n = 198, a smooth fold at 0.3948 without a counterpart at n = 297 was paired with one
    at 1.3801 on the deposition's branch (0.0047 from the deposition's own fold); at x = 4
    a contact fold at 0.3603 (measure 1.00) of a branch that no refined branch follows
    with one at 1.3793 (measure -0.09), which is 0.19 in the plane from the deposition's
    fold at 1.4220 (measure -0.27); the mirror pairs of a drop centred on a node, two folds
    at one point, are each paired."""
    from scipy.optimize import linear_sum_assignment

    def kind(f):
        return (f["kind"], tuple(f["stability_change"] or ()))

    def point(f):
        m = f.get("measure")
        return np.array([f["value"], m if m is not None and math.isfinite(m) else 0.0])

    def near(p, q):
        """Distances between the points (rows) of p and q."""
        return np.hypot(*(p[:, None, :] - q[None, :, :]).transpose(2, 0, 1))

    def pair(mine, theirs):
        for k in sorted({kind(f) for f in mine}):
            a = [f for f in mine if kind(f) == k]
            b = [g for g in theirs if kind(g) == k and id(g) not in used]
            if not b:
                continue
            pa = np.array([point(f) for f in a])
            pb = np.array([point(g) for g in b])
            cost = near(pa, pb)
            # every fold of the kind at each resolution, against this pairing's folds
            rival_a = near(np.array([point(f) for f in folds if kind(f) == k]), pb)
            rival_b = near(pa, np.array([point(g) for g in refined if kind(g) == k]))
            for r, c in zip(*linear_sum_assignment(cost), strict=True):
                d = cost[r, c] - TIE  # mirror pairs: equal but for round-off
                if (rival_a[:, c] < d).any() or (rival_b[r] < d).any():
                    continue  # another fold's counterpart, or this one has another
                a[r]["error_estimate"] = abs(a[r]["value"] - b[c]["value"])
                used.add(id(b[c]))

    used = set()
    for fo in folds:
        fo["error_estimate"] = None
    for label in sorted({f["branch"] for f in folds} & set(followed.values())):
        pair([f for f in folds if f["branch"] == label],
             [g for g in refined if followed.get(g["branch"]) == label])
    pair([f for f in folds if f["branch"] not in followed.values()], refined)


def trace_contact_branches(scene: Scene, parameter: str = "drop.wetted_length", prange=None,
                           n: int | None = None, refine: bool = True,
                           progress=None, n_refined: int | None = None,
                           spreading: bool = False) -> BranchSet:
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
        Trace the same branches again at ``REFINE`` n edges for the error estimates: seeded
        by the seeds that made a branch at n (the others are not tried again), the other
        branches' first states carried to the finer strip.
    progress : callable(message), optional
        Called with a line after each branch is traced.
    n_refined : int, optional
        Edges of the refined run (default ``round(REFINE * n)``).
    spreading : bool
        Also follow a quasi-static spreading past the deposited state's end, through its
        jumps, to where it stops being open (``open_branch_end``'s ``past_loss`` and
        ``spreading``: :func:`open_branch_end`); it can trace branches the search did not
        reach. Off by default: at x = 5 (198 + 297 edges) it costs 2.3 s of CPU (34.5 s
        against 32.2 s for the whole trace).

    Returns
    -------
    elastocap.branchset.BranchSet
        ``metadata["model"]`` is ``"strip"``; ``results`` holds ``window`` (largest Delta
        of a stable admissible open state, smallest of a stable admissible encapsulated
        one, each with ``error_estimate``), ``open_branch_end``, ``kind_changes`` and
        ``events``; ``problem`` is the :class:`ContactProblem` at n edges.
    """
    lo, hi = check_trace_request(scene, parameter, prange)
    t0 = time.perf_counter()
    note = contact_note(scene)
    strip = _searched_strip(scene, n)
    n_fine = None
    with threadpool_limits(limits=1, user_api="blas"):
        a = _analyse(strip, lo, hi, progress, spreading=spreading)
        window, end = a["window"], {**a["open_branch_end"], "error_estimate": None}
        if refine:
            n_fine = int(n_refined) if n_refined is not None else int(round(REFINE * strip.n))
            if n_fine == strip.n:
                raise ValueError(f"n_refined: got {n_fine}; expected it to differ from n = "
                                 f"{strip.n}")
            f = _analyse(strip.with_(n=n_fine), lo, hi, progress, follow=a,
                         spreading=spreading)
            fend = f["open_branch_end"]
            end["value_refined"], end["how_refined"] = fend["value"], fend["how"]
            if end["value"] is not None and fend["value"] is not None:
                end["error_estimate"] = abs(end["value"] - fend["value"])
            if spreading:
                sp, fsp = end["spreading"], fend["spreading"]
                sp["value_refined"], sp["how_refined"] = fsp["value"], fsp["how"]
                sp["open_up_to_refined"] = fsp["open_up_to"]
                sp["error_estimate"] = (abs(sp["value"] - fsp["value"]) if sp["value"]
                                        is not None and fsp["value"] is not None else None)
            _fold_errors(a["folds"], f["folds"], f["followed"])
            for key in ("open_max", "encapsulated_min"):
                u, v = window[key]["value"], f["window"][key]["value"]
                if u is not None and v is not None:
                    window[key]["error_estimate"] = abs(u - v)
                window[key]["value_refined"] = v
                window[key]["how_refined"] = f["window"][key]["how"]
            window["bistable_refined"] = f["window"]["bistable"]
            window["width_refined"] = f["window"]["width"]
    window["open_branch_end"] = end
    bs = BranchSet(scene, parameter, (lo, hi), ContactProblem(strip), a["branches"],
                   a["labels"], a["folds"])
    bs.results = {"window": window, "kind_changes": a["kind_changes"],
                  "events": a["events"], "not_handled": NOT_HANDLED}
    bs.metadata = {
        "model": "strip",
        "scene": scene.data,
        "scene_name": scene.name,
        "parameter": parameter,
        "range": [lo, hi],
        "N": strip.n,
        "n_edges": strip.n,
        "n_edges_refined": n_fine,
        "solver": "discrete strip (elastocap.strip.model); continuation.BranchSearch on the "
                  "semismooth contact problem, pseudo-arclength at fixed contact sets with "
                  "located lift-off/touch-down events",
        "seed_deltas": list(a["search"].samples[1:-1]) if len(a["search"].samples) > 2
        else [],
        "search": a["search"].to_dict(),
        "continuation": dict(DEFAULTS),
        "contact_event_residual": _event_residuals(a["events"]),
        "contact_note": note,
        "version": __version__,
        "wall_time_s": time.perf_counter() - t0,
    }
    return bs


def window(bs: BranchSet) -> dict:
    """The window of a strip branch set (``bs.results["window"]``)."""
    return bs.results["window"]


def open_branch_end(bs: BranchSet) -> dict:
    """Where the state a quasi-static spreading lands on stops existing or being stable.

    The branch traced up in Delta from the deposition at the lowest seed: the largest Delta
    of its leading stretch of stable, open, admissible states (``value``, length), and
    ``how`` it ends: a ``contact fold`` or ``smooth fold`` (located; Delta turns back
    there), a ``kind change`` (the verdict flips on a stable stretch, located), ``stability
    lost`` or ``inadmissible`` at a traced point, ``turning point (not located)``,
    ``range`` (the stretch reaches the range's end) or ``branch end (STATUS)`` (the branch
    ended otherwise, e.g. the contact lines met). ``stability_change`` is the located
    fold's index on its two sides; ``stable_both_sides`` flags a fold at an active-set
    event with the open state stable on both sides (the branch turns back with no change
    of stability, so where a spreading goes beyond it is not decided by this branch).
    ``value`` is None when there is no such branch (``how`` says why).

    Where the stretch ends by ``stability lost`` (no fold: the mirror-symmetric open state
    tilts), ``past_loss`` says where the spreading goes on (:func:`_past_loss`): the
    stable state a descent past the change reaches on either side, followed up its
    branch; ``past_loss["value"]`` is where the first of the two stops being stable and
    open. ``spreading`` (``value``, ``how``; with the refined run's ``value_refined`` and
    ``error_estimate``) is where the spreading stops being open: ``past_loss``'s value, or
    the stretch's own end where its state turns encapsulated or crosses itself. A branch
    set from :func:`trace_contact_branches` returns the end it computed (with
    ``past_loss``, ``spreading`` and the refined run's values); otherwise the end is found
    again from the branches (without them: they need the strip).
    """
    stored = bs.results.get("window", {}).get("open_branch_end")
    if stored is not None:
        return stored
    out = _open_end(bs.branches, bs.labels, bs.folds, bs.results.get("kind_changes", []))
    out.pop("stop", None)
    out.pop("step", None)
    return out


def solved_crossings(strip: DiscreteStrip, branches):
    """Each place a traced segment crosses the strip's Delta, solved there exactly.

    Yields (branch, point index j, Equilibrium): Newton at the segment's contact set from
    its traced point j nearest the crossing (converged or not: check ``success``).
    """
    d0 = strip.delta
    for br in branches:
        N = br.u.shape[1] // 2
        for sl, held in segments_of(br):
            d = br.p[sl]
            if d.size < 2 or not d.min() <= d0 <= d.max():
                continue
            for i in range(d.size - 1):
                if d[i] == d[i + 1] or (d[i] - d0) * (d[i + 1] - d0) > 0.0:
                    continue
                j = sl.start + (i if abs(d[i] - d0) <= abs(d[i + 1] - d0) else i + 1)
                yield br, j, solve_equilibrium(strip, br.u[j][:N], active=held, tol=1e-11,
                                               max_iter=30)


# --------------------------------------------------------------------------- the model
def _rebuild_problem(scene: Scene, meta: dict) -> ContactProblem:
    return ContactProblem(_searched_strip(scene, int(meta["n_edges"])))


def _plot(bs, path=None):
    from elastocap.strip.plot import plot_contact_branch_set

    return plot_contact_branch_set(bs, path)


def report_lines(bs: BranchSet) -> list[str]:
    """Human-readable report (the CLI without ``--json``)."""
    m = bs.metadata
    n, nf = m["n_edges"], m.get("n_edges_refined")
    out = [f"{bs.scene.name}: {len(bs.branches)} branches in {bs.parameter} over "
           f"[{bs.prange[0]:.6g}, {bs.prange[1]:.6g}] (discrete strip, n = {n}"
           f" edges, {len(bs.results.get('events', []))} contact events, "
           f"{m['wall_time_s']:.1f} s)"]

    def err(e):
        if nf is None:
            return "(not estimated)"
        return f"± {e:.1e}" if e is not None else f"(no match at n = {nf})"

    for f in bs.folds:
        what = "smooth fold " if f["kind"] == "smooth" else \
            f"contact fold ({f['event']} of node {f['node']})"
        out.append(f"  {what:38s} Delta {f['value']:.9f} {err(f['error_estimate']):22s}"
                   f" stability {f['stability_change']}  measure {f['measure']:+.4f}"
                   + ("" if f["admissible"] else "  (strip crosses itself)"))
    w = bs.results.get("window", {})
    for key, name in (("open_max", "stable open state up to"),
                      ("encapsulated_min", "stable encapsulated state from"),
                      ("open_branch_end", "deposition's open branch ends at")):
        v = w.get(key)
        if v and v["value"] is not None:
            out.append(f"  {name:32s} Delta {v['value']:.9f} {err(v['error_estimate'])}")
    sp = (w.get("open_branch_end") or {}).get("spreading")
    if sp:
        head = "a spreading stops being open at"
        if sp["value"] is not None:
            out.append(f"  {head:32s} Delta {sp['value']:.9f} "
                       f"{err(sp.get('error_estimate'))} ({sp['how']})")
        else:
            up = sp.get("open_up_to")
            out.append(f"  {head:32s} not found"
                       + (f" (open at least to Delta {up:.9f})" if up is not None else "")
                       + f": {sp['how']}")
    line = f"  bistable at n = {n}: {w.get('bistable')}"
    if w.get("width") is not None:
        line += f" (width {w['width']:+.2e})"
    if nf is not None:
        wr = w.get("width_refined")
        line += f"; at n = {nf}: {w.get('bistable_refined')}" + (
            f" (width {wr:+.2e})" if wr is not None else "")
    out.append(line)
    splits = [e for e in bs.results.get("events", []) if e.get("not_followed")]
    if splits:
        out.append(f"  {len(splits)} contact events where several nodes switch together "
                   "also start branches not traced (another subset of them switching):")
        for e in splits:
            ways = "; ".join(f"nodes {w['nodes']} index {w['index']}"
                             for w in e["not_followed"])
            out.append(f"    Delta {e['delta']:.9f} ({e['branch']}): {ways}")
    return out


#: The strip on the ground as a model of :class:`elastocap.branchset.BranchSet`.
STRIP = BranchModel("strip", _rebuild_problem, _plot, report_lines)
