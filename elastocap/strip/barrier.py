"""The energy barrier between the open and the encapsulated strip: string method, saddle, graph.

Units: energies in the scene's unit (mu g l_eg^2 = B / l_eg for ``fig3-strip``, 1.245e-8 J
for the paper's strip: mu = 51.8 g/m^2 x 2 mm, l_eg = 3.50 mm).

One path: :func:`barrier`
-------------------------
1. The two minima of :class:`~elastocap.strip.model.DiscreteStrip` on the ground: the open
   state by descent from the flat strip with the drop spread to Delta (a quasi-static
   deposition, :func:`~elastocap.strip.solve.open_state`), the encapsulated state by
   descent from the strip folded over the drop (:func:`~elastocap.strip.solve.wrapped_state`).
2. A string (E, Ren & Vanden-Eijnden 2007) between them, started on the straight line in u,
   relaxed on the energy with the ground as a constraint (:func:`string_method`).
3. From the top of the string, the active-set Newton method with the exact constraint
   (:func:`refine_saddle`): a KKT point with zero residual whose index must be 1.
4. Two descents from the saddle, pushed along its unstable mode both ways
   (:func:`~elastocap.strip.solve.descend_from_saddle`): they must end on the open and on
   the encapsulated state. This certifies the saddle as the top of a path joining the two
   minima; the barrier is then E_saddle - E_open.

Why a string, not a constrained-minimum ("drag") path: the least energy at prescribed tip
angle theta(L) jumps. Measured at x = 3, Delta = 1.1, n = 100: the constrained minimum jumps
at theta(L) = 0.569 and 1.216 rad (the tail either stands up or flips over the drop), and
the drag path's maximum (50.494) lies 0.22 above the saddle (50.2733), 39 % of the barrier.
The string does not need a reaction coordinate.

Every traced saddle: :func:`barrier_graph`
------------------------------------------
At one Delta, the branches traced by :func:`~elastocap.strip.trace.trace_contact_branches`
cross it at every equilibrium they reach: minima (index 0) and saddles (index 1). Each
saddle is joined to the two minima its descents end on; minima found only by a descent are
added. On that graph, the barrier of an open minimum m is the minimax of the saddle energies
over paths from m to any encapsulated minimum, minus E(m): the least energy the strip must
be given to leave m for encapsulation through the saddles found (Kruskal's order with a
union-find: saddles are added by increasing energy until m's component holds an
encapsulated minimum). What it does not prove: that the traced branches hold every saddle
(saddles on branches not reached from the seeds are missed).

Against the impact: :func:`kinetic_energy` is the drop's kinetic energy (1/2) rho V U^2 with
V = A l_eg (the paper's A = V / l_eg) and rho U^2 = gamma We / R, so
E_k = A gamma_hat We / (2 w R) in scene units, w = strip width / l_eg; the release state of
the impact model is the straight strip with the drop spread to Delta
(:func:`~elastocap.strip.model.flat_energy`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from elastocap.strip.model import DiscreteStrip, discrete_strip_for, is_encapsulated
from elastocap.strip.solve import (
    Equilibrium,
    descend_from_saddle,
    open_state,
    solve_equilibrium,
    stability,
    wrapped_state,
)
from elastocap.strip.trace import solved_crossings

__all__ = [
    "PAPER_WIDTH",
    "BarrierGraph",
    "BarrierResult",
    "StringPath",
    "barrier",
    "barrier_graph",
    "equilibria_at",
    "kinetic_energy",
    "lowest_barriers",
    "refine_saddle",
    "string_method",
]

# Two minima are the same state when their energies agree to this, relative to the energy
# span |E_saddle - E_open| + 1 (measured agreement 1e-12 when they are); also the slack of
# the monotonicity test of the string profile.
_SAME_E = 1e-7

#: Strip width over l_eg for the paper's 2D experiment (w = 2 mm, l_eg = 3.4996 mm as in
#: the fig3-strip scene); the 2D model itself has no width, only E_k needs it.
PAPER_WIDTH = 2.0 / 3.4996


def kinetic_energy(scene, we, width: float = PAPER_WIDTH) -> float:
    """Kinetic energy of the impacting drop, (1/2) rho V U^2, in scene energy units.

    Parameters
    ----------
    scene : Scene
        Supplies A (= V / l_eg), gamma_hat and R (``spreading.drop_radius``).
    we : float
        Weber number rho U^2 R / gamma (not its square root).
    width : float
        Strip width in scene length units (gamma = gamma_hat / width is the surface
        tension).
    """
    if scene.spreading is None:
        raise ValueError("scene.spreading: got None; the kinetic energy needs drop_radius")
    R = scene.spreading.drop_radius
    return scene.drop.area * scene.drop.line_tension * we / (2.0 * width * R)


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
        The two minima; by default :func:`~elastocap.strip.solve.open_state` and
        :func:`~elastocap.strip.solve.wrapped_state`.
    images : int
        Images of the string (the two minima included).
    iters : int
        String iterations (the string only has to bring Newton into the saddle's basin:
        measured at x = 3, Delta = 1.1, n = 100, 21 images, the same saddle to 1e-11
        after 300 iterations with three preconditioner settings).

    Runs with one BLAS thread (scoped, as :func:`~elastocap.strip.trace.trace_contact_branches`).
    """
    with threadpool_limits(limits=1, user_api="blas"):
        return _barrier(strip, open_eq, wrapped_eq, images, iters)


def _barrier(strip, open_eq, wrapped_eq, images, iters) -> BarrierResult:
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


# Two states are the same equilibrium when their u differ by less than this (max norm;
# Newton converges to ~1e-12, distinct equilibria differ by >~ 1e-4 in the cases seen).
_SAME = 1e-7


def equilibria_at(bs, delta: float) -> list[tuple[int, Equilibrium]]:
    """Every distinct equilibrium the traced branches of ``bs`` cross at ``delta``.

    Each crossing is solved exactly at ``delta`` by Newton at its segment's contact set from
    the nearer traced point. Returns (stability index, Equilibrium) pairs, by energy.
    """
    lo, hi = bs.prange
    if not lo <= delta <= hi:
        raise ValueError(f"delta: got {delta}; expected it inside the traced range "
                         f"[{lo}, {hi}]")
    strip = discrete_strip_for(bs.scene, bs.metadata["n_edges"]).with_(delta=float(delta))
    found: list[tuple[int, Equilibrium]] = []
    for br, j, eq in solved_crossings(strip, bs.branches):
        if eq.success and not any(np.max(np.abs(eq.u - e.u)) < _SAME for _, e in found):
            # the index of the solved state itself: Newton from a point next to a fold can
            # land on the other side of it (measured at x = 4, Delta = 1.1: the saddle,
            # found from a point of the open branch); with a contact of zero reaction the
            # fixed-set index of the segment is kept
            idx, weak = stability(strip, eq)
            found.append((int(br.stability[j]) if weak else idx, eq))
    return sorted(found, key=lambda t: t[1].energy)


@dataclass
class BarrierGraph:
    """Minima and saddles at one Delta, the saddles' connections, the lowest barriers.

    Attributes
    ----------
    delta : float
    minima : list of dict
        ``energy``, ``encapsulated`` (the paper's criterion), ``tip_angle`` theta(L)
        (rad), ``from_descent`` (found only by descending from a saddle).
    saddles : list of dict
        ``energy``, ``joins`` (the two minima indices its descents end on; -1 when a
        descent failed), ``tip_angle``.
    barriers : list of dict
        One per open minimum: ``minimum`` (index), ``barrier`` (energy units; inf when no
        path to an encapsulated minimum is found), ``via`` (the bottleneck saddle index).
    """

    delta: float
    minima: list = field(default_factory=list)
    saddles: list = field(default_factory=list)
    barriers: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"delta": self.delta, "minima": self.minima, "saddles": self.saddles,
                "barriers": self.barriers}


def lowest_barriers(energies_min, encapsulated, saddles) -> list[dict]:
    """Minimax barriers on a graph of minima joined by saddles.

    Parameters
    ----------
    energies_min : sequence of float
        Energy of each minimum.
    encapsulated : sequence of bool
        Kind of each minimum.
    saddles : sequence of (energy, i, j)
        A saddle of that energy joining minima i and j (-1: unknown end, ignored).

    Returns
    -------
    list of dict
        For each open minimum m: ``minimum``, ``barrier`` = E_bottleneck - E(m) (inf if no
        path), ``via`` (index into ``saddles`` of the bottleneck, -1 if none).
    """
    n = len(energies_min)
    parent = list(range(n))

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    open_ids = [m for m in range(n) if not encapsulated[m]]
    done = {m: (math.inf, -1) for m in open_ids}
    for k in sorted(range(len(saddles)), key=lambda k: saddles[k][0]):
        e, i, j = saddles[k]
        if i < 0 or j < 0:
            continue
        a, b = find(i), find(j)
        if a != b:
            parent[a] = b
        for m in open_ids:
            if done[m][1] >= 0:
                continue
            root = find(m)
            if any(encapsulated[q] and find(q) == root for q in range(n)):
                done[m] = (e, k)
    return [{"minimum": m,
             "barrier": (done[m][0] - energies_min[m]) if done[m][1] >= 0 else math.inf,
             "via": done[m][1]} for m in open_ids]


def barrier_graph(bs, delta: float) -> BarrierGraph:
    """Minima, saddles and the lowest barrier of each open minimum at ``delta``.

    ``bs`` is a strip's :class:`~elastocap.branchset.BranchSet`; one BLAS thread (scoped).
    """
    with threadpool_limits(limits=1, user_api="blas"):
        return _barrier_graph(bs, delta)


def _barrier_graph(bs, delta):
    strip: DiscreteStrip = discrete_strip_for(bs.scene, bs.metadata["n_edges"]).with_(
        delta=float(delta))
    eqs = equilibria_at(bs, delta)
    minima = [eq for idx, eq in eqs if idx == 0]
    from_descent = [False] * len(minima)
    saddle_eqs = [eq for idx, eq in eqs if idx == 1]

    def index_of(eq):
        for k, m in enumerate(minima):
            if np.max(np.abs(m.u - eq.u)) < 1e-6:
                return k
        minima.append(eq)
        from_descent.append(True)
        return len(minima) - 1

    saddles = []
    for sad in saddle_eqs:
        ends = descend_from_saddle(strip, sad)
        joins = [index_of(e) if (e is not None and e.success and e.index == 0) else -1
                 for e in ends]
        saddles.append({"energy": float(sad.energy), "joins": joins,
                        "tip_angle": float(sad.u[-1])})
    enc = [is_encapsulated(strip, m.u) for m in minima]
    g = BarrierGraph(float(delta))
    g.minima = [{"energy": float(m.energy), "encapsulated": bool(e),
                 "tip_angle": float(m.u[-1]), "from_descent": f}
                for m, e, f in zip(minima, enc, from_descent, strict=True)]
    g.saddles = saddles
    g.barriers = lowest_barriers([m["energy"] for m in g.minima], enc,
                                 [(s["energy"], *s["joins"]) for s in saddles])
    return g
