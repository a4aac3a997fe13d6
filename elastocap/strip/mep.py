"""Minimum-energy path, saddle and energy barrier between the open and the encapsulated strip.

Method
------
1. The two minima of :class:`~elastocap.strip.discrete.DiscreteStrip` on the ground:
   the open state by descent from the flat strip with the drop spread to Delta (a
   quasi-static deposition, :func:`open_state`), the encapsulated state by descent from
   the strip folded over the drop (:func:`wrapped_state`); either can instead come from a
   continuation in Delta (:func:`continue_in_delta`).
2. A string (E, Ren & Vanden-Eijnden 2007) between them, started on the straight line in
   u, relaxed on the energy with an exterior ground penalty (:func:`string_method`).
3. From the top of the string, the active-set Newton method with the exact constraint
   (:func:`refine_saddle`): a KKT point with zero residual whose index must be 1.
4. Two descents from the saddle, pushed along its unstable mode both ways
   (:func:`descend_from_saddle`): they must end on the open and on the encapsulated state.
   This is what certifies the saddle as the top of a path joining the two minima; the
   barrier is then E_saddle - E_open.

Why a string, not a constrained-minimum ("drag") path: the least energy at prescribed tip
angle theta(L) jumps. Measured at x = 3, Delta = 1.1, n = 100: the constrained minimum
jumps at theta(L) = 0.569 and 1.216 rad (the tail either stands up or flips over the drop),
and the drag path's maximum (50.494) lies 0.22 above the saddle (50.2733), which is
39 % of the barrier. The string does not need a reaction coordinate.

Energies in the scene's unit (mu g l_eg^2 = B / l_eg for ``fig3-strip``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from elastocap.strip.discrete import (
    _R_REL,
    DiscreteStrip,
    Equilibrium,
    flat_state,
    minimize_energy,
    solve_equilibrium,
)

__all__ = [
    "BarrierResult",
    "StringPath",
    "barrier",
    "END_REASONS",
    "continue_in_delta",
    "continue_in_delta_end",
    "descend_from_saddle",
    "is_encapsulated",
    "open_state",
    "refine_saddle",
    "string_method",
    "unstable_mode",
    "wrapped_state",
]

# Continuation in Delta: a corrector moving some edge by more than this (radians) has
# left the branch (the steps of 0.05 in Delta move the edges by < 0.05 rad on a branch).
_JUMP = 0.3
# Push off the saddle along its unstable mode before each descent (radians, max norm of
# the displacement): large enough for the descent to leave the saddle's neighbourhood at
# once, small next to the distance to either minimum (~1-3 rad in the tail angles).
_PUSH = 0.02
# Two minima are the same state when their energies agree to this, relative to the energy
# span |E_saddle - E_open| + 1 (measured agreement 1e-12 when they are); also the slack of
# the monotonicity test of the string profile.
_SAME_E = 1e-7


def polish(strip, eq: Equilibrium, tol=1e-10) -> Equilibrium:
    """Release the held tip angle of a C = 0 state and converge the free strip."""
    return solve_equilibrium(strip, eq.u, active=eq.active, tol=tol)


def open_state(strip: DiscreteStrip) -> Equilibrium:
    """The state reached by descent from the flat strip (a quasi-static deposition)."""
    return minimize_energy(strip, flat_state(strip))


def is_encapsulated(strip: DiscreteStrip, u) -> bool:
    """The paper's criterion (Methods): the free end lies left of the impact centre."""
    X = strip.positions(u)
    s = strip.s_nodes
    xc = float(np.interp(strip.L - strip.x_end, s, X[:, 0]))
    return bool(X[-1, 0] < xc)


def continue_in_delta(strip: DiscreteStrip, eq: Equilibrium, deltas,
                      min_step=1e-3, keep_kind=True) -> list[tuple[float, Equilibrium]]:
    """Natural continuation of a stable equilibrium in Delta; stops where it is lost.

    Parameters
    ----------
    strip : DiscreteStrip
        At the Delta of ``eq``.
    eq : Equilibrium
    deltas : sequence of float
        Increasing or decreasing values of Delta to visit.
    min_step : float
        Bisection resolution of the end of the branch (length).
    keep_kind : bool
        Also end the branch where the state changes kind (open to encapsulated or back,
        the paper's criterion): at small x the open state turns into the encapsulated one
        continuously, without a fold (measured at x = 1.5).

    Returns
    -------
    list of (Delta, Equilibrium): the stable states, the last one within ``min_step`` of
    the Delta where the branch ends: a fold (Newton fails or the index turns 1), a jump
    to another branch (an edge turns by more than ``_JUMP``), or a change of kind.
    :func:`continue_in_delta_end` also says which.
    """
    return continue_in_delta_end(strip, eq, deltas, min_step, keep_kind)[0]


#: Why a continuation in Delta stopped (the last failed attempt, within ``min_step`` of the
#: last state kept): ``scan_limit`` (every Delta asked for was reached), ``no_convergence``
#: (Newton failed: a fold, or a contact change it cannot follow), ``unstable`` (converged
#: to an index >= 1 point: past a fold), ``jump`` (converged onto another branch: some edge
#: turned by more than ``_JUMP``), ``kind_change`` (a stable state of the other kind,
#: reached continuously).
END_REASONS = ("scan_limit", "no_convergence", "unstable", "jump", "kind_change")


def continue_in_delta_end(strip: DiscreteStrip, eq: Equilibrium, deltas, min_step=1e-3,
                          keep_kind=True) -> tuple[list[tuple[float, Equilibrium]], dict]:
    """:func:`continue_in_delta`, also returning how the branch ended.

    Returns
    -------
    states : list of (Delta, Equilibrium)
    end : dict
        ``reason`` (one of :data:`END_REASONS`), ``delta_failed`` (the Delta of the last
        failed attempt, None for ``scan_limit``; the end lies between the last state kept
        and it, an interval of at most ``min_step``).
    """
    out = []
    cur_d, cur = strip.delta, eq
    kind = is_encapsulated(strip, eq.u)
    for d in deltas:
        target = float(d)
        while True:
            s = strip.with_(delta=target)
            nx = solve_equilibrium(s, cur.u, active=cur.active)
            # a jump to another branch is a failure too
            near = nx.success and float(np.max(np.abs(nx.u - cur.u))) < _JUMP
            same = not keep_kind or (near and is_encapsulated(s, nx.u) == kind)
            if near and same and nx.index == 0:
                out.append((target, nx))
                cur_d, cur = target, nx
                if target == float(d):
                    break
                target = float(d)
                continue
            if abs(target - cur_d) <= min_step:
                if not nx.success:
                    reason = "no_convergence"
                elif not near:
                    reason = "jump"
                elif nx.index != 0:
                    reason = "unstable"
                else:
                    reason = "kind_change"
                return out, {"reason": reason, "delta_failed": target}
            target = 0.5 * (target + cur_d)
    return out, {"reason": "scan_limit", "delta_failed": None}


# --------------------------------------------------------------------------- string method
# Eigenvalue floor of the saddle-free Newton preconditioner |H| (energy units). Measured at
# x = 3, Delta = 1.1, n = 100, 21 images, 300 iterations: floors 1e-3, 1e-2, 1e-1 all give
# the same refined saddle (to 1e-11); the largest keeps the images from drifting along the
# soft directions (max image-energy change per 10 iterations 7e-2, 5e-2, 3e-3 with dt = 1).
_EIG_FLOOR = 1e-1
# Largest change of an edge angle in one string iteration (radians): keeps the images in
# the range where the quadratic model holds.
_STRING_TURN = 0.1
# The energy profile of the string is compared every this many iterations.
_CHECK_EVERY = 10


@dataclass
class StringPath:
    """A converged string (minimum-energy path) and its top.

    Attributes
    ----------
    images : ndarray, shape (m, n + 1)
    energy : ndarray, shape (m,)
        Exact energy (the ground penetration of the penalized images is O(r / k), 1e-5).
    alpha : ndarray, shape (m,)
        Normalized arclength of the images (Euclidean in u).
    iterations : int
    change : float
        Max change of an image energy over the last ``_CHECK_EVERY`` iterations.
    top : int
        Image of highest energy.
    """

    images: np.ndarray
    energy: np.ndarray
    alpha: np.ndarray
    iterations: int
    change: float

    @property
    def top(self) -> int:
        return int(np.argmax(self.energy))


def _reparametrize(U):
    d = np.linalg.norm(np.diff(U, axis=0), axis=1)
    a = np.concatenate([[0.0], np.cumsum(d)])
    a /= a[-1]
    t = np.linspace(0.0, 1.0, U.shape[0])
    out = np.empty_like(U)
    for j in range(U.shape[1]):
        out[:, j] = np.interp(t, a, U[:, j])
    return out, t


def string_method(strip: DiscreteStrip, U0, iters=400, dt=1.0, tol=1e-4) -> StringPath:
    """Simplified string method (E, Ren & Vanden-Eijnden 2007) with the ground as a constraint.

    Parameters
    ----------
    strip : DiscreteStrip
    U0 : ndarray, shape (m, n + 1)
        Initial images; the first and last (the two minima) stay fixed.
    iters : int
        Maximum number of iterations.
    dt : float
        Step, as a fraction of the saddle-free Newton step (dimensionless); 1 is a full
        Newton step in the stiff directions (capped at ``_STRING_TURN``).
    tol : float
        Stop when no image energy changes by more than ``tol`` times the energy span of
        the string over ``_CHECK_EVERY`` iterations (the images themselves keep sliding
        along the path by O(step) near the top, where |H| is small along it).

    Notes
    -----
    Each interior image takes the step d of the quadratic model with the metric |H| (the
    Hessian with its eigenvalues replaced by their absolute values, floored), on the
    linearized contacts of its own contact set A:

        [[|H|, G_A^T], [G_A, 0]] [d; -r] = [-grad E; -z_A],

    a Newton step in the stiff directions and a descent step in every direction, which
    keeps the contact nodes on the ground. A node that goes below the ground joins A, a
    node with r < 0 leaves it. Then the images are redistributed at equal arclength
    (Euclidean in u). A stiff exterior penalty instead of the contact set was tried first:
    the images oscillated across the contact changes (image energies still moving by 0.6
    per 10 iterations after 300 at x = 4, Delta = 1.4), the contact set does not.
    """
    U = np.array(U0, dtype=float)
    m = U.shape[0]
    act = [strip.heights(u) <= 1e-9 for u in U]
    change = math.inf
    it = 0
    E_old = None
    alpha = np.linspace(0.0, 1.0, m)
    for it in range(1, iters + 1):
        Un = U.copy()
        for i in range(1, m - 1):
            _E, g, H = strip.derivatives(U[i])
            z = strip.heights(U[i])
            lam, V = np.linalg.eigh(H)
            Mh = (V * np.maximum(np.abs(lam), _EIG_FLOOR)) @ V.T
            A = np.flatnonzero(act[i])
            Ga = strip.constraint_jacobian(U[i])[A]
            nf, na = strip.size, A.size
            K = np.zeros((nf + na, nf + na))
            K[:nf, :nf] = Mh
            K[:nf, nf:] = Ga.T
            K[nf:, :nf] = Ga
            sol = np.linalg.solve(K, np.concatenate([-g, -z[A]]))
            d, r = sol[:nf], -sol[nf:]
            big = float(np.max(np.abs(d)))
            scale = dt if dt * big <= _STRING_TURN else _STRING_TURN / big
            Un[i] = U[i] + scale * d
            keep = np.zeros(strip.size, dtype=bool)
            keep[A[r > 0.0]] = True
            act[i] = keep | (strip.heights(Un[i]) < 0.0)
        Un, alpha = _reparametrize(Un)
        U = Un
        if it % _CHECK_EVERY == 0:
            E = np.array([strip.energy(u) for u in U])
            if E_old is not None:
                change = float(np.max(np.abs(E - E_old)))
                if change <= tol * max(1.0, float(np.max(E) - np.min(E))):
                    break
            E_old = E
    E = np.array([strip.energy(u) for u in U])
    return StringPath(U, E, alpha, it, change)


def refine_saddle(strip: DiscreteStrip, path: StringPath, tol=1e-10) -> Equilibrium:
    """Newton (active-set, exact constraint) from the top of a string: the saddle.

    Starts tried in turn, until one converges to an index-1 KKT point: the maximum of the
    parabola through the energies of the top image and its two neighbours (in arclength),
    the top image, its two neighbours. Returns the last attempt if none does (status or
    index then say so). Newton from the parabola's top alone failed at x = 3,
    Delta = 1.1, n = 143 (it left the saddle's basin), the top image worked.
    """
    i = min(max(path.top, 1), len(path.energy) - 2)
    a, E = path.alpha[i - 1 : i + 2], path.energy[i - 1 : i + 2]
    c2, c1, _c0 = np.polyfit(a, E, 2)
    a_top = float(np.clip(-c1 / (2.0 * c2), a[0], a[2])) if c2 < 0.0 else float(a[1])
    j = 0 if a_top < a[1] else 1
    w = (a_top - a[j]) / (a[j + 1] - a[j])
    starts = [(1.0 - w) * path.images[i - 1 + j] + w * path.images[i + j],
              path.images[i], path.images[i - 1], path.images[i + 1]]
    eq = None
    for u in starts:
        z = strip.heights(u)
        eq = solve_equilibrium(strip, u, active=z <= 1e-9, tol=tol)
        if eq.success and eq.index == 1:
            return eq
    return eq


def wrapped_state(strip: DiscreteStrip) -> Equilibrium:
    """The state reached by descent from the strip folded over the drop.

    Seed: flat up to S1, turning by pi at a constant rate over the wet part [S1, S2] (a
    half-circle around the drop), the tail straight back over the drop.
    """
    s = (np.arange(strip.n) + 0.5) * strip.h
    th = math.pi * np.clip((s - strip.s1) / (strip.s2 - strip.s1), 0.0, 1.0)
    return minimize_energy(strip, np.concatenate([[0.0], th]))


def unstable_mode(strip: DiscreteStrip, eq: Equilibrium) -> np.ndarray:
    """Eigenvector of the most negative eigenvalue of the Lagrangian Hessian on the
    tangent space of the strongly active contacts (shape (n + 1,), unit max norm)."""
    u, r = eq.u, eq.reactions
    N = strip.size
    H = strip.hessian(u)
    rs = np.cumsum(r[::-1])[::-1]
    H[np.arange(1, N), np.arange(1, N)] += strip.h * np.sin(u[1:]) * rs[1:]
    strong = eq.active & (r > _R_REL * strip.q * strip.h)
    G = strip.constraint_jacobian(u)[strong]
    if G.shape[0]:
        _q, sv, vt = np.linalg.svd(G, full_matrices=True)
        Z = vt[int(np.sum(sv > 1e-12 * sv[0])):].T
    else:
        Z = np.eye(N)
    ev, V = np.linalg.eigh(Z.T @ H @ Z)
    v = Z @ V[:, 0]
    return v / np.max(np.abs(v))


def descend_from_saddle(strip: DiscreteStrip, saddle: Equilibrium, push=_PUSH):
    """The two minima reached by descent from the saddle pushed along ±(unstable mode)."""
    v = unstable_mode(strip, saddle)
    out = []
    for sgn in (1.0, -1.0):
        u = saddle.u + sgn * push * v
        # stay on or above the ground: a contact node pushed below is put back on it
        z = strip.heights(u)
        if z[0] < 0.0:
            u[0] -= z[0]
        out.append(minimize_energy(strip, u))
    return out


@dataclass
class BarrierResult:
    """Open state, saddle, encapsulated state and the barrier at one (x, Delta, n).

    ``status``: "ok" (index-1 saddle whose two descents end on an open and on an
    encapsulated minimum; if the open one is not the deposition's open state, the string
    must climb monotonically from it to the saddle, and ``message`` says so);
    "no_open_state" (descent from the flat strip encapsulates); "no_wrapped_state"
    (descent from the folded strip opens); "bad_saddle" (Newton from the string's top did
    not give an index-1 KKT point); "not_connecting" (the saddle's descents end elsewhere).
    """

    x: float
    delta: float
    n: int
    status: str
    open: Equilibrium | None = None
    saddle: Equilibrium | None = None
    wrapped: Equilibrium | None = None
    string: StringPath | None = None
    ends: tuple = ()
    message: str = ""

    @property
    def barrier(self) -> float:
        if self.open is None or self.saddle is None or not self.saddle.success:
            return math.nan
        return self.saddle.energy - self.open.energy

    def summary(self) -> dict:
        def e(s):
            return math.nan if s is None else float(s.energy)

        return {
            "x": self.x, "delta": self.delta, "n": self.n, "status": self.status,
            "e_open": e(self.open), "e_saddle": e(self.saddle), "e_wrapped": e(self.wrapped),
            "barrier": self.barrier,
            "string_max": math.nan if self.string is None else float(np.max(self.string.energy)),
            "saddle_index": -1 if self.saddle is None else self.saddle.index,
            "saddle_residual": math.nan if self.saddle is None else self.saddle.residual,
            "saddle_tip_angle": math.nan if self.saddle is None else float(self.saddle.u[-1]),
            "ends": [e(s) for s in self.ends],
            "message": self.message,
        }


def barrier(strip: DiscreteStrip, open_eq: Equilibrium | None = None,
            wrapped_eq: Equilibrium | None = None, images=15, iters=150) -> BarrierResult:
    """The energy barrier E_saddle - E_open between the open and the encapsulated state.

    Parameters
    ----------
    strip : DiscreteStrip
    open_eq, wrapped_eq : Equilibrium, optional
        The two minima; by default :func:`open_state` and :func:`wrapped_state`.
    images : int
        Images of the string (the two minima included).
    iters : int
        String iterations (the string only has to bring Newton into the saddle's basin:
        measured at x = 3, Delta = 1.1, n = 100, 21 images, the same saddle to 1e-11
        after 300 iterations with three preconditioner settings).
    """
    res = BarrierResult(strip.x_end, strip.delta, strip.n, "ok")
    op = open_state(strip) if open_eq is None else open_eq
    if not (op.success and op.index == 0) or is_encapsulated(strip, op.u):
        res.status, res.wrapped = "no_open_state", op
        res.message = (f"descent from the flat strip: status {op.status}, index {op.index}, "
                       f"encapsulated {is_encapsulated(strip, op.u)}")
        return res
    res.open = op
    wr = wrapped_state(strip) if wrapped_eq is None else wrapped_eq
    if not (wr.success and wr.index == 0) or not is_encapsulated(strip, wr.u):
        res.status = "no_wrapped_state"
        res.message = (f"descent from the folded strip: status {wr.status}, index {wr.index},"
                       f" encapsulated {is_encapsulated(strip, wr.u)}")
        return res
    res.wrapped = wr
    U0 = np.array([(1.0 - t) * op.u + t * wr.u for t in np.linspace(0.0, 1.0, images)])
    res.string = string_method(strip, U0, iters=iters)
    sad = refine_saddle(strip, res.string)
    if not (sad.success and sad.index == 1):
        # once more, from a string with twice the images, relaxed twice as long
        U1 = np.array([np.interp(np.linspace(0.0, 1.0, 2 * images - 1), res.string.alpha,
                                 res.string.images[:, k]) for k in range(strip.size)]).T
        res.string = string_method(strip, U1, iters=2 * iters)
        sad = refine_saddle(strip, res.string)
    res.saddle = sad
    if not (sad.success and sad.index == 1):
        res.status = "bad_saddle"
        res.message = f"Newton from the string's top: status {sad.status}, index {sad.index}"
        return res
    ends = descend_from_saddle(strip, sad)
    res.ends = tuple(ends)
    span = abs(sad.energy - op.energy) + 1.0
    kinds = sorted("wrapped" if is_encapsulated(strip, e.u) else "open" for e in ends)
    ok_ends = all(e.success and e.index == 0 for e in ends) and kinds == ["open", "wrapped"]
    e_open_end = min(ends, key=lambda e: is_encapsulated(strip, e.u)).energy
    if not ok_ends:
        res.status = "not_connecting"
        res.message = (f"descents from the saddle end at energies "
                       f"{[e.energy for e in ends]}, kinds {kinds}")
    elif abs(e_open_end - op.energy) > _SAME_E * span:
        # the path from the open state passes another open minimum first: the barrier is
        # still E_saddle - E_open if the string climbs monotonically to its top
        Es = res.string.energy[: res.string.top + 1]
        mono = bool(np.all(np.diff(Es) >= -_SAME_E * span))
        res.message = (f"via an intermediate open minimum at E = {e_open_end:.6f} "
                       f"(string monotone up to its top: {mono})")
        if not mono:
            res.status = "not_connecting"
    return res
