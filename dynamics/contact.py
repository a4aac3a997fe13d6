"""Self-contact of the rod: non-penetration as unilateral constraints inside the projections.

The rod is a tube of diameter ``d`` (:class:`dynamics.SelfContact`) around its centre line.
Two parts of it far apart along the rod must stay at least ``d`` apart: for every node
``i`` and segment ``j`` (nodes ``j, j+1``) whose arc-length gap is at least
:func:`exclusion_length` (``pi d / 2``, the length of the tightest hairpin, a half circle
of diameter ``d``), ``dist(x_i, segment j) >= d``.  In the plane that is the segment-segment
condition: two segments that do not cross are closest at an endpoint of one of them.

Formulation (both methods)
--------------------------
Each constraint enters the position projection of a step *linearised at the start of the
step*, exactly as SHAKE linearises the edge-length constraints there: with ``u0`` the
closest point of segment ``j`` to node ``i`` and ``n0`` the unit vector from that point to
the node, both at the old positions ``xo``::

    g(x) = n0 . (x_i - (1 - u0) x_j - u0 x_{j+1}) - d >= 0,

a half space whose side is fixed by the old state, so a node cannot tunnel through a
segment within one step whatever its speed; the true distance to the old closest point is
``|x_i - p| >= n0 . (x_i - p) >= d``, to the segment it can fall short of ``d`` by a
second-order amount while the contact rotates (restored at the next step).  The
projection::

    x = x* + W G_e(xo)^T lam + W C^T mu,    phi_e(x) = 0,   g(x) >= 0,  mu >= 0,  mu g = 0

(``phi_e`` the edge lengths, ``C`` the rows of the active contacts) is solved by Newton on
``(lam, mu)`` (``_bordered_solve``).  With few contacts (fewer than ``BAND_MIN``) the
contact rows are eliminated by a Schur complement (one tridiagonal factorisation, the
candidate contacts' columns solved in one pass, the contacts' dense capacitance matrix),
whose complementarity problem is solved by projected Gauss-Seidel started from a guess
(``_lcp_guess``: block pivoting from the contacts that push in the previous iteration, or
at the previous step: in sustained contact the first sweep finds it converged).  With
many (a rod lying on itself: 100 and more) that costs ``O(k**3)`` a solve; instead
(``_band_lcp``) the edge rows and the rows of the guessed pushing set are one sparse
system, which a breadth-first order of its unknowns makes a narrow band (two layers: a
ladder, half-width about 5), factorised in ``O(N)`` and refined, with the same block
pivoting on it; what it cannot settle goes to the dense solve.  The candidates are the
listed pairs within twice the deepest penetration, and a pair left out that ends violated
joins them. The velocity stage is the
same with the contact rows at the new positions: relative normal velocity ``>= 0`` where
the rod touches (restitution 0, frictionless), together with the edges' ``G v = 0``
(RATTLE) or with the edges' stretching rates left unchanged (midpoint); an M-orthogonal
projection onto a convex cone, so it never adds kinetic energy. The contact forces are
pairwise and opposite (node against the two nodes of the segment, weights ``1, -(1 - u),
-u``): momentum is conserved to round-off. Redundant contacts (two stacked layers touch
node-on-segment both ways) make the capacitance matrix singular: the positions are unique,
the split of the multipliers is not; a node closest to a vertex is held by one of the two
segments that share it, not both.

Redundant contacts and the pivoting
-----------------------------------
A strip folded flat on the ground is the common redundant case: every node of either layer
touches a segment of the other, and the ground holds the lower layer's normal
coordinates, so a lower node's row is the combination ``(1 - u, u)`` of the rows of the
upper segment's two nodes.  In a problem recorded from fig3-strip at x = 6 (300 edges,
121 contacts) 57 singular values of the capacitance matrix are below 1e-10 of the largest.
Taken together as equations, redundant rows that do not agree exactly pull against each
other through the diagonal shift (there, block pivoting emulated densely: a multiplier of
-1.77 at the third pivot, where the others' smallest push is 8e-6), and
block pivoting (every infeasible contact changed at once) drops them, re-adds them and
cycles.  Both pivotings (:func:`_lcp_guess`, :func:`_band_lcp`) therefore change every
infeasible contact for :data:`BLOCK_PIVOTS` pivots, then one at a time, the most
infeasible first.
This is not Murty's least-index rule: it is not proven to end, and an active set that
does not settle within the pivot cap still goes to the dense solve and projected
Gauss-Seidel, which copes with redundancy but converges slowly on these problems.

Broad phase
-----------
A Verlet list: the pairs within ``d + skin`` of each other at the last rebuild
(``skin = CONTACT_SKIN`` times the shortest edge, or more when one step moves a node
further), found with a hashed uniform grid over the nodes (``O(N)``); it stays valid while
every node, at the start and at the end of the step, is within ``skin / 2`` of where it was
at the rebuild (then a pair not on the list is further than ``d`` apart all through the
step).  A step therefore costs one pass over the nodes plus one over the listed pairs;
the grid is rebuilt only when some node has moved ``skin / 2``.

Work arrays: :func:`new_contact_work`.
"""

from __future__ import annotations

import collections
import math

import numba
import numpy as np

__all__ = [
    "check_self_contact",
    "contact_failure",
    "contact_stats",
    "CONTACT_SKIN",
    "ContactWork",
    "MAX_ACTIVE",
    "exclusion_length",
    "new_contact_work",
    "NO_CONTACT_WORK",
    "contact_positions",
    "contact_velocities",
    "segment_distances",
    "contact_shortfall",
]

#: Skin of the Verlet list, relative to the shortest edge: a larger skin means more listed
#: pairs to test each step, a smaller one more frequent rebuilds.
CONTACT_SKIN = 0.5

#: Listed pairs per node the list can hold (a rod lying on itself lists ~3).
PAIRS_PER_NODE = 16

#: Most contacts active at once (the capacitance matrix is dense in them: its work arrays
#: hold ``min(3 n, MAX_ACTIVE)**2`` and ``m min(3 n, MAX_ACTIVE)`` floats, 8 MB each at
#: 1000 edges).  A strip folded flat on itself touches with about every node of both
#: layers: fig3-strip at x = 6 and 1000 edges reached 510 pushing contacts, and more than 512
#: candidates.
MAX_ACTIVE = 1024

#: Newton iterations of a position projection with contacts (edges converge
#: quadratically, the contact rows are linear: 2-3 are usual).
MAX_NEWTON = 30

#: Rounds of the active-set loop (add violated pairs, drop pulling ones).
MAX_ROUNDS = 30

#: Relative edge-length residual ``|l**2 - l0**2| / (2 l0**2)`` at which the position
#: stage's Newton iteration is declared diverged (failure 6): edges 25 % off their length
#: are nowhere near the manifold the iteration linearises about, and it does not come back
#: (measured on fig3-strip, 200 edges, midpoint at 8x the explicit bound, a step whose
#: contacts start a thickness deep: 3e-14, then 88, 520, 8e3, ..., 3e222, NaN at the 12th
#: iteration, which a NaN-blind convergence test then accepted).  The iteration starts
#: with the edges at round-off, and its first correction is a projection of the size of
#: the penetration, a fraction of an edge.
EDGE_DIVERGED = 0.25

#: Relative edge-length tolerance (as SHAKE's) and gap tolerance (relative to the shortest
#: edge), each with a round-off floor ``TOL_FLOOR`` relative to the size of the coordinates
#: (over the shortest edge for the edges).
TOL_EDGE = 1e-14
TOL_GAP = 1e-13
TOL_FLOOR = 4e-16

#: Complementarity residual accepted, relative to the thickness, when redundant contacts
#: (two stacked layers touching node-on-segment both ways) stall the iteration above
#: round-off (measured: 2e-8 on a rod folded flat onto itself).
TOL_REDUNDANT = 1e-7

#: The velocity stage is skipped when the position stage projected nothing and every listed
#: pair's gap exceeds this fraction of the shortest edge (far above the second-order
#: difference between the linearised and the true gap within a step).
TOUCH_SKIP = 1e-3

#: Relative diagonal shift of the contacts' capacitance matrix (see the module notes).
REGULARISATION = 1e-11

#: Solves of the velocity stage's complementarity problem from the remaining residual.
VELOCITY_REFINEMENTS = 3

#: Sweeps of projected Gauss-Seidel on the contacts' complementarity problem.
PGS_MAX_SWEEPS = 2000

#: Solves of the pivoting that finds the start of projected Gauss-Seidel.
GUESS_PIVOTS = 40

#: Pivots of :func:`_lcp_guess` and :func:`_band_lcp` that change every infeasible contact
#: at once (block principal pivoting) before they change one at a time, the most infeasible.
#: Block pivots alone cycle on redundant contacts (see the module notes): on a strip folded
#: flat on the ground (fig3-strip, x = 6, 300 edges) 2,979 banded solves ran out of pivots
#: and went to the dense solve, 2,131 of those on to projected Gauss-Seidel's sweep cap.
#: With single pivots after these in both pivotings, 85 ran out and 86 dense solves reached
#: the cap; the run took 36 s instead of 75 s (docs/guide/contact.md).
BLOCK_PIVOTS = 3

#: Largest half-bandwidth of the bordered system (edge rows and the active contacts' rows)
#: in the breadth-first order of its unknowns that :func:`_band_lcp` factorises: a rod lying
#: on itself in two layers orders into a band of a few unknowns (a ladder), whatever the
#: number of contacts.  Wider, the dense Schur complement of :func:`_bordered_solve` is used.
BAND_MAX = 40

#: Fewest contacts for which :func:`_bordered_solve` tries the banded solve: with fewer, the
#: dense Schur complement (one pass over the edges, an LU of a few rows) is cheaper.
#: Measured on a rod of 200 edges folded in two layers, one solve started from the
#: solution's multipliers (as in sustained contact), dense against banded: 9.4 against
#: 38 us at 8 contacts, 22 against 22 at 32, 29 against 23 at 40, 71 against 46 at 64,
#: 183 against 53 at 99.
BAND_MIN = 40

#: Changes of the active set :func:`_band_lcp` tries before it hands the problem to the
#: dense Schur complement and projected Gauss-Seidel (redundant contacts can cycle).
BAND_PIVOTS = 40

#: Relative residual of the banded solve (factorised without pivoting, its contact rows
#: shifted) above which it is not trusted and the dense solve is used instead.
BAND_RESIDUAL = 1e-9

#: Rounds of iterative refinement of the banded solve, until its residual (without the
#: shift) is below ``BAND_REFINED`` relative to the right-hand side.
BAND_REFINE = 3
BAND_REFINED = 1e-14

# rows of meta (int64)
(_NPAIRS, _VALID, _REBUILDS, _NACT, _MAXACT, _STEPS, _ROUNDS, _FAIL, _FORCES, _NVEL,
 _NFAIL, _NBAND, _NDENSE) = range(13)
# rows of stat (float64)
_GAPERR, _PENETRATION, _FTOTAL, _SKIN, _GMIN = range(5)


def check_self_contact(effect, effects):
    """``"contact"`` if ``effect`` is the rod's self-contact (by the effect protocol), else
    False; refuses a second one and a thickness read from elsewhere than ``params[0]``."""
    from .effects import is_self_contact

    if not is_self_contact(effect):
        return False
    if int(effect.self_contact_thickness_param) != 0:
        raise ValueError(f"effect {effect.name!r}: the self-contact thickness is read from "
                         "params[0]; got self_contact_thickness_param = "
                         f"{effect.self_contact_thickness_param!r}")
    others = [e.name for e in effects if is_self_contact(e)]
    if len(others) > 1:
        raise ValueError(f"at most one self-contact effect; got {others}")
    return "contact"


_FAILURES = {1: "more candidate pairs than the list holds (PAIRS_PER_NODE per node)",
             2: f"more than the {MAX_ACTIVE} simultaneous contacts the solver holds",
             3: "a singular projection system",
             4: "the Newton iteration on edge lengths and gaps did not converge",
             5: "the active set of contacts did not settle",
             6: "the projection diverged (edge lengths far off, or a non-finite value)",
             7: "a node moved deeper into the rod within one step than the contacts' "
                "linearisation at the start of the step allows (max_depth)",
             8: "the contacts turned too far within the step: a true gap ended short of the "
                "thickness by more than the step accepts (max_shortfall)"}


def contact_failure(ck, t, step, dt, substeps):
    """The message of a step whose self-contact projection failed."""
    code = int(ck.meta[_FAIL])
    return (f"self-contact projection did not converge at t = {t:g} (step {step}): "
            f"{_FAILURES.get(code, 'unknown failure')}, even with {substeps} substeps. A "
            f"smaller dt (now {dt:g}) moves the rod less per step; a thickness much larger "
            "than an edge multiplies the contacts.")


def contact_stats(ck, velocity_failures):
    """The self-contact's entries of ``SimulationResult.stats``.

    ``self_contact_steps`` steps with an active contact; ``self_contact_max_active`` most
    contacts active in a step (position stage); ``self_contact_rounds`` active-set rounds;
    ``self_contact_rebuilds`` rebuilds of the pair list; ``self_contact_band_solves`` and
    ``self_contact_dense_solves`` complementarity problems solved banded (``_band_lcp``)
    and by the dense Schur complement; ``self_contact_gap_error``
    largest ``|gap - thickness| / thickness`` of a pushing contact, or penetration of any
    listed pair, after a projection;
    ``self_contact_penetration`` deepest predicted penetration corrected, relative to the
    thickness; ``self_contact_force`` total magnitude of the contact forces of the last
    step (each pair counted once); ``self_contact_velocity_unsettled`` velocity stages whose
    active set did not settle (their last round was kept); ``self_contact_failures``
    contact stages that failed (the midpoint method then rejects the step and retries it
    with substeps; RATTLE stops) and ``self_contact_failure`` the reason of the last one
    (empty when none failed).
    """
    meta, stat = ck.meta, ck.stat
    return {"self_contact_steps": int(meta[_STEPS]),
            "self_contact_max_active": int(meta[_MAXACT]),
            "self_contact_rounds": int(meta[_ROUNDS]),
            "self_contact_rebuilds": int(meta[_REBUILDS]),
            "self_contact_band_solves": int(meta[_NBAND]),
            "self_contact_dense_solves": int(meta[_NDENSE]),
            "self_contact_gap_error": float(stat[_GAPERR]),
            "self_contact_penetration": float(stat[_PENETRATION]),
            "self_contact_force": float(stat[_FTOTAL]),
            "self_contact_velocity_unsettled": int(velocity_failures),
            "self_contact_failures": int(meta[_NFAIL]),
            "self_contact_failure": (_FAILURES.get(int(meta[_FAIL]), "unknown failure")
                                     if meta[_NFAIL] else "")}


def exclusion_length(thickness):
    """Arc-length gap below which a node and a segment are not tested against each other:
    ``pi d / 2``, the length of the tightest hairpin (half a circle of diameter ``d``)."""
    return 0.5 * math.pi * float(thickness)


#: The work arrays of the contact kernels (:func:`new_contact_work`), one named tuple that
#: numba passes as one argument and whose fields it reads by name at compile time.
ContactWork = collections.namedtuple("ContactWork", [
    "meta",       # counters (int64, rows _NPAIRS ... _NFAIL)
    "stat",       # statistics (rows _GAPERR ... _GMIN)
    "xref",       # (n, 2) positions at the last rebuild of the pair list
    "s_arc",      # (n,) arc length of every node
    "pairs",      # (P, 2) int64 listed pairs (node, segment)
    "pair_geom",  # (P, 4) per listed pair: closest point u, normal (nx, nz), gap
    "active",     # (K,) int64 the active pairs (indices into pairs)
    "mu_pos",     # (K,) their position multipliers
    "mu_vel",     # (K,) the velocity stage's multipliers
    "Y",          # (m K,) the tridiagonal solves of the contacts' columns, (m, na)
    "S",          # (K, K) the contacts' capacitance matrix
    "SA",         # (K, K) its rows and columns of the guessed active set, factorised
    "vec",        # (14, max(m, K) + 2) vectors
    "grid",       # (H + n,) int64 hashed grid: bucket heads, then next node
    "cell",       # (n, 2) int64 grid cell of every node
    "forces",     # (n, 2) the contact forces of the last step
    "scratch",    # (3, n, 2) scratch node arrays
    "piv",        # (K,) int64 pivots
    "mark",       # (P,) int64 per-pair marks (-1 redundant, 0 free, 1 active)
    "pushed",     # (P,) int64 per-pair: 1 if it pushed at the last position stage
    "rows",       # (3, K, 2) int64 (node, segment) of the contact rows being solved
    "flags",      # (4, K) int64 equality flags of those rows (0, 1), guessed pushing (2)
    "guess",      # (2, K) int64 the guessed set (membership, map) of the first solve
    "normals",    # (3, K, 2) their normals
    "weights",    # (3, K) their weights u
    "edges",      # (2, m, 2) edge vectors (current, old)
    "band",       # (m + K, 2 BAND_MAX + 1) the banded bordered system (_band_lcp)
    "band_vec",   # (6, m + K + 2) its edge rows, contacts' diagonal, right-hand side
    "band_int",   # (7, max(n + 1, 3 K, m + K)) int64 incidence, order, active set
    "band_dq",    # (n, 2) the update its solution makes
])


#: What a stepper without self-contact passes in place of the work arrays: its contact code
#: is compiled out, and an empty tuple keeps the 30 arrays' type out of its signatures
#: (a new supp-fig5 stepper compiles 0.25-2.1 s faster: docs/guide/time-stepping.md).
NO_CONTACT_WORK = ()


def new_contact_work(edge_len):
    """The :data:`ContactWork` of the contact kernels for a rod with these rest edge
    lengths: row 0 of ``rows``, ``flags``, ``normals``, ``weights`` holds the position
    stage's contacts, row 1 the velocity stage's."""
    edge_len = np.asarray(edge_len, dtype=np.float64)
    m = edge_len.shape[0]
    n = m + 1
    K = min(3 * n, MAX_ACTIVE)
    H = 1
    while H < 2 * n:
        H *= 2
    s_arc = np.zeros(n)
    s_arc[1:] = np.cumsum(edge_len)
    P = PAIRS_PER_NODE * n
    return ContactWork(
        np.zeros(13, dtype=np.int64), np.zeros(5), np.zeros((n, 2)), s_arc,
        np.zeros((P, 2), dtype=np.int64), np.zeros((P, 4)),
        np.zeros(K, dtype=np.int64), np.zeros(K), np.zeros(K), np.zeros(m * K),
        np.zeros((K, K)), np.zeros((K, K)), np.zeros((14, max(m, K) + 2)),
        np.zeros(H + n, dtype=np.int64), np.zeros((n, 2), dtype=np.int64), np.zeros((n, 2)),
        np.zeros((3, n, 2)), np.zeros(K, dtype=np.int64), np.zeros(P, dtype=np.int64),
        np.zeros(P, dtype=np.int64),
        np.zeros((3, K, 2), dtype=np.int64), np.zeros((4, K), dtype=np.int64),
        np.zeros((2, K), dtype=np.int64),
        np.zeros((3, K, 2)), np.zeros((3, K)), np.zeros((2, m, 2)),
        np.zeros((m + K, 2 * BAND_MAX + 1)), np.zeros((6, m + K + 2)),
        np.zeros((7, max(n + 1, 3 * K, m + K)), dtype=np.int64), np.zeros((n, 2)))


# ----------------------------------------------------------------------------- geometry


@numba.njit(cache=True, inline="always")
def _closest(x, i, j):
    """Closest point of segment j to node i: (u, qx, qz) with q = x_i - p(u)."""
    ax = x[j, 0]
    az = x[j, 1]
    ex = x[j + 1, 0] - ax
    ez = x[j + 1, 1] - az
    px = x[i, 0] - ax
    pz = x[i, 1] - az
    l2 = ex * ex + ez * ez
    u = (px * ex + pz * ez) / l2 if l2 > 0.0 else 0.0
    u = 0.0 if u < 0.0 else (1.0 if u > 1.0 else u)
    return u, px - u * ex, pz - u * ez


@numba.njit(cache=True, inline="always")
def _included(i, j, s_arc, lex):
    """Whether node i and segment j are far enough apart along the rod to be tested."""
    if j > i:
        return s_arc[j] - s_arc[i] >= lex
    if j + 1 < i:
        return s_arc[i] - s_arc[j + 1] >= lex
    return False


@numba.njit(cache=True)
def segment_distances(x, thickness, edge_len):
    """Smallest distance between a node and a segment that are tested against each other
    (arc gap >= :func:`exclusion_length`), by brute force (``O(N**2)``, for checks).

    Returns ``(dmin, node, segment)``; ``(inf, -1, -1)`` when no pair is tested."""
    n = x.shape[0]
    s_arc = np.zeros(n)
    for k in range(n - 1):
        s_arc[k + 1] = s_arc[k] + edge_len[k]
    lex = 0.5 * math.pi * thickness
    best = np.inf
    bi = -1
    bj = -1
    for i in range(n):
        for j in range(n - 1):
            if _included(i, j, s_arc, lex):
                u, qx, qz = _closest(x, i, j)
                dd = math.sqrt(qx * qx + qz * qz)
                if dd < best:
                    best = dd
                    bi = i
                    bj = j
    return best, bi, bj


@numba.njit(cache=True, inline="always")
def _hash(ix, iz, mask):
    return ((ix * 73856093) ^ (iz * 19349663)) & mask


@numba.njit(cache=True)
def _rebuild(x, thickness, skin, ck):
    """List the (node, segment) pairs closer than ``thickness + skin`` at ``x`` (hashed
    grid of cell size ``h_max + 2 (thickness + skin)``, so a segment's box inflated by
    that reach covers at most 2 x 2 cells)."""
    meta = ck.meta
    s_arc = ck.s_arc
    pairs = ck.pairs
    xref = ck.xref
    grid = ck.grid
    cell = ck.cell
    n = x.shape[0]
    lex = 0.5 * math.pi * thickness
    reach = thickness + skin
    hmax = 0.0
    for j in range(n - 1):
        ex = x[j + 1, 0] - x[j, 0]
        ez = x[j + 1, 1] - x[j, 1]
        le = math.sqrt(ex * ex + ez * ez)
        if le > hmax:
            hmax = le
    c = hmax + 2.0 * reach
    inv_c = 1.0 / c
    H = grid.shape[0] - n
    mask = H - 1
    for b in range(H):
        grid[b] = -1
    # nodes into buckets: head grid[b], next grid[H + i]
    for i in range(n):
        ix = int(math.floor(x[i, 0] * inv_c))
        iz = int(math.floor(x[i, 1] * inv_c))
        cell[i, 0] = ix
        cell[i, 1] = iz
        b = _hash(ix, iz, mask)
        grid[H + i] = grid[b]
        grid[b] = i
        xref[i, 0] = x[i, 0]
        xref[i, 1] = x[i, 1]
    npairs = 0
    cap = pairs.shape[0]
    r2 = reach * reach
    for j in range(n - 1):
        x0 = min(x[j, 0], x[j + 1, 0]) - reach
        x1 = max(x[j, 0], x[j + 1, 0]) + reach
        z0 = min(x[j, 1], x[j + 1, 1]) - reach
        z1 = max(x[j, 1], x[j + 1, 1]) + reach
        ix0 = int(math.floor(x0 * inv_c))
        ix1 = int(math.floor(x1 * inv_c))
        iz0 = int(math.floor(z0 * inv_c))
        iz1 = int(math.floor(z1 * inv_c))
        for ix in range(ix0, ix1 + 1):
            for iz in range(iz0, iz1 + 1):
                i = grid[_hash(ix, iz, mask)]
                while i >= 0:
                    if (cell[i, 0] == ix and cell[i, 1] == iz and _included(i, j, s_arc, lex)
                            and x[i, 0] >= x0 and x[i, 0] <= x1 and x[i, 1] >= z0
                            and x[i, 1] <= z1):
                        u, qx, qz = _closest(x, i, j)
                        if qx * qx + qz * qz < r2:
                            if npairs >= cap:
                                meta[_FAIL] = 1
                                meta[_NPAIRS] = npairs
                                return False
                            pairs[npairs, 0] = i
                            pairs[npairs, 1] = j
                            npairs += 1
                    i = grid[H + i]
    # sorted by node, then segment (for the redundancy test of the narrow phase)
    key = np.empty(npairs, dtype=np.int64)
    for p in range(npairs):
        key[p] = pairs[p, 0] * n + pairs[p, 1]
    order = np.argsort(key)
    tmp = pairs[:npairs].copy()
    for p in range(npairs):
        pairs[p, 0] = tmp[order[p], 0]
        pairs[p, 1] = tmp[order[p], 1]
    meta[_NPAIRS] = npairs
    meta[_VALID] = 1
    meta[_REBUILDS] += 1
    return True


@numba.njit(cache=True, inline="always")
def _list_valid(xo, x, ck):
    """Whether every node of ``xo`` and ``x`` is within skin / 2 of the last rebuild; also
    returns the largest displacement ``|x - xo|`` of a node."""
    xref = ck.xref
    half = 0.5 * ck.stat[_SKIN]
    lim = half * half
    worst = 0.0
    step = 0.0
    for i in range(x.shape[0]):
        ax = x[i, 0] - xref[i, 0]
        az = x[i, 1] - xref[i, 1]
        bx = xo[i, 0] - xref[i, 0]
        bz = xo[i, 1] - xref[i, 1]
        cx = x[i, 0] - xo[i, 0]
        cz = x[i, 1] - xo[i, 1]
        a = ax * ax + az * az
        b = bx * bx + bz * bz
        cc = cx * cx + cz * cz
        worst = a if a > worst else worst
        worst = b if b > worst else worst
        step = cc if cc > step else step
    return (worst < lim and ck.meta[_VALID] == 1), math.sqrt(step)


# ----------------------------------------------------------------------------- linear algebra


@numba.njit(cache=True)
def _lu_solve(S, b, piv, na):
    """Dense LU with partial pivoting: solve ``S y = b`` in place (S overwritten)."""
    for k in range(na):
        p = k
        big = abs(S[k, k])
        for r in range(k + 1, na):
            if abs(S[r, k]) > big:
                big = abs(S[r, k])
                p = r
        if big == 0.0 or not np.isfinite(big):
            return False
        piv[k] = p
        if p != k:
            for cc in range(na):
                tmp = S[k, cc]
                S[k, cc] = S[p, cc]
                S[p, cc] = tmp
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
        inv = 1.0 / S[k, k]
        for r in range(k + 1, na):
            fr = S[r, k] * inv
            if fr != 0.0:
                for cc in range(k + 1, na):
                    S[r, cc] -= fr * S[k, cc]
                b[r] -= fr * b[k]
    for k in range(na - 1, -1, -1):
        acc = b[k]
        for cc in range(k + 1, na):
            acc -= S[k, cc] * b[cc]
        b[k] = acc / S[k, k]
    return True


@numba.njit(cache=True, inline="always")
def _node_weight(t, u):
    """Weight of a contact row's node t (0 the node, 1 and 2 the segment's ends)."""
    return 1.0 if t == 0 else (-(1.0 - u) if t == 1 else -u)


@numba.njit(cache=True, inline="always")
def _edge_row(R, O, w, f, e, m):
    """Row e of the edge rows of :func:`_bordered_solve`, ``f R_e . (dq_{e+1} - dq_e)`` in
    the edge multipliers: ``(a, b, c, skip)``, the identity (skip 1) where both ends are
    held in the directions that matter."""
    rx = R[e, 0]
    rz = R[e, 1]
    wx0 = w[e, 0]
    wz0 = w[e, 1]
    wx1 = w[e + 1, 0]
    wz1 = w[e + 1, 1]
    bb = f * (rx * (wx0 + wx1) * O[e, 0] + rz * (wz0 + wz1) * O[e, 1])
    scale = f * (abs(rx * O[e, 0]) + abs(rz * O[e, 1])) * (wx0 + wx1 + wz0 + wz1)
    if abs(bb) <= 1e-12 * scale or scale == 0.0:
        return 0.0, 1.0, 0.0, 1.0
    aa = -f * (rx * wx0 * O[e - 1, 0] + rz * wz0 * O[e - 1, 1]) if e > 0 else 0.0
    cc = -f * (rx * wx1 * O[e + 1, 0] + rz * wz1 * O[e + 1, 1]) if e < m - 1 else 0.0
    return aa, bb, cc, 0.0


@numba.njit(cache=True)
def _bordered_solve(R, O, w, f, rhs_e, na, ci, cu, cn, rhs_c, ck, dl, dm, mu0, eq, hint,
                    pgs_tol, band=True):
    """Solve the edge rows (tridiagonal) bordered by ``na`` contact rows.

    Edge row e: ``f R_e . (dq_{e+1} - dq_e) = rhs_e[e]``, contact row k:
    ``n_k . (dq_i - (1-u) dq_j - u dq_{j+1}) = rhs_c[k]``, with
    ``dq = W (G_O^T dl + C^T dm)`` (``G_O`` the edge directions ``O``).  Rows of edges
    with both ends held are identities (``dl = 0``).  Returns False if a pivot vanished.

    The contact rows are complementarity conditions on the total multipliers
    ``mu0 + dm`` (equalities where ``eq``), solved by projected Gauss-Seidel started from
    the solution of the equations of a guessed set of pushing contacts (``mu0 > 0``, ``eq``
    or ``hint``) when that solution pushes, else from ``mu0``.  With :data:`BAND_MIN`
    contacts or more (and ``band``, the default) :func:`_band_lcp` first tries it on the
    whole system, banded; the dense Schur complement and projected Gauss-Seidel solve what
    it refuses.
    """
    m = R.shape[0]
    if band and na >= BAND_MIN and _band_lcp(R, O, w, f, rhs_e, na, ci, cu, cn,
                                                     rhs_c, ck, dl, dm, mu0, eq, hint,
                                                     pgs_tol):
        ck.meta[_NBAND] += 1
        return True
    if na > 0:
        ck.meta[_NDENSE] += 1
    vec = ck.vec
    S = ck.S
    a = vec[0]
    b = vec[1]
    c = vec[2]
    cp = vec[3]
    gi = vec[4]
    z = vec[5]
    skip = vec[7]
    # Y = T^-1 B (B: the edge rows' response to the contacts' impulses, one column per
    # contact), all columns in one pass (edges outer, contacts inner: each column sees the
    # operations of its own solve); Y is (m, na), row e the edge's entries of the columns.
    # A column's right-hand side has at most 6 nonzero entries (the edges at the contact's
    # three nodes); the forward sweep starts at the first nonzero row of any column (the
    # rows above it stay zero)
    Y = ck.Y[:m * na].reshape((m, na))
    for e in range(m):
        for k in range(na):
            Y[e, k] = 0.0
    e0 = m
    for k in range(na):
        i = ci[k, 0]
        j = ci[k, 1]
        u = cu[k]
        nx = cn[k, 0]
        nz = cn[k, 1]
        for t in range(3):
            q = i if t == 0 else (j if t == 1 else j + 1)
            wq = _node_weight(t, u)
            px = w[q, 0] * wq * nx
            pz = w[q, 1] * wq * nz
            if q - 1 >= 0:
                Y[q - 1, k] += f * (R[q - 1, 0] * px + R[q - 1, 1] * pz)
                e0 = q - 1 if q - 1 < e0 else e0
            if q < m:
                Y[q, k] -= f * (R[q, 0] * px + R[q, 1] * pz)
                e0 = q if q < e0 else e0
    # one pass over the edges: the tridiagonal row, its Thomas pivot (gi = 1 / pivot,
    # cp = c * gi), the forward sweeps of z = T^-1 rhs_e and of Y (independent chains of
    # operations, overlapped by the processor), then the back substitutions together
    for e in range(m):
        a[e], b[e], c[e], skip[e] = _edge_row(R, O, w, f, e, m)
        den = b[e] - (a[e] * cp[e - 1] if e > 0 else 0.0)
        if den == 0.0 or not np.isfinite(den):
            return False
        gi[e] = 1.0 / den
        cp[e] = c[e] * gi[e]
        ae = a[e]
        ge = gi[e]
        r = 0.0 if skip[e] != 0.0 else rhs_e[e]
        z[e] = (r - (ae * z[e - 1] if e > 0 else 0.0)) * ge
        if e >= e0:
            if skip[e] != 0.0:
                for k in range(na):
                    Y[e, k] = (0.0 - (ae * Y[e - 1, k] if e > 0 else 0.0)) * ge
            elif e > 0:
                for k in range(na):
                    Y[e, k] = (Y[e, k] - ae * Y[e - 1, k]) * ge
            else:
                for k in range(na):
                    Y[e, k] = (Y[e, k] - 0.0) * ge
    for e in range(m - 2, -1, -1):
        ce = cp[e]
        z[e] -= ce * z[e + 1]
        for k in range(na):
            Y[e, k] -= ce * Y[e + 1, k]
    if na == 0:
        for e in range(m):
            dl[e] = z[e]
        return True
    # Schur complement S = C W C^T - B2 Y, rhs = rhs_c - B2 z
    smax = 0.0
    for k in range(na):
        ik = ci[k, 0]
        jk = ci[k, 1]
        uk = cu[k]
        nxk = cn[k, 0]
        nzk = cn[k, 1]
        for l in range(na):
            il = ci[l, 0]
            jl = ci[l, 1]
            ul = cu[l]
            s = 0.0
            for t in range(3):
                q = ik if t == 0 else (jk if t == 1 else jk + 1)
                wk = _node_weight(t, uk)
                wl = ((1.0 if q == il else 0.0) - ((1.0 - ul) if q == jl else 0.0)
                      - (ul if q == jl + 1 else 0.0))
                if wl != 0.0:
                    s += wk * wl * (nxk * w[q, 0] * cn[l, 0] + nzk * w[q, 1] * cn[l, 1])
            S[k, l] = s
        if S[k, k] > smax:
            smax = S[k, k]
        rk = rhs_c[k]
        # B2 row k: d g_k / d dl_e = sum_q w_q n_k . W_q (O_{q-1} [e = q-1] - O_q [e = q])
        for t in range(3):
            q = ik if t == 0 else (jk if t == 1 else jk + 1)
            wk = _node_weight(t, uk)
            for side in range(2):
                e = q - 1 if side == 0 else q
                if e < 0 or e >= m:
                    continue
                sg = 1.0 if side == 0 else -1.0
                coef = sg * wk * (nxk * w[q, 0] * O[e, 0] + nzk * w[q, 1] * O[e, 1])
                if coef != 0.0:
                    rk -= coef * z[e]
                    for l in range(na):
                        S[k, l] -= coef * Y[e, l]
        dm[k] = rk
    # the contacts' linear complementarity problem in the total multipliers
    # nu = mu0 + dm: w = S nu + q >= 0 (the gaps after the update), nu >= 0 (not for
    # the equality rows), w nu = 0; projected Gauss-Seidel, which copes with redundant
    # contacts (the positions are unique, the multipliers need not be)
    q = vec[6]
    # complementarity residual at the start (mu0): the gap -rhs where the contact
    # pushes (or is an equality), the penetration elsewhere
    qmax = 0.0
    for k in range(na):
        r0 = abs(dm[k]) if (mu0[k] > 0.0 or eq[k] != 0) else max(dm[k], 0.0)
        qmax = max(qmax, r0)
    for k in range(na):
        acc = -dm[k]
        for l in range(na):
            acc -= S[k, l] * mu0[l]
        q[k] = acc
        dm[k] = mu0[k]
    # to the tolerance, or a millionth of that residual: the Newton iteration around
    # this solve refines what is left
    tol = max(pgs_tol, 1e-6 * qmax)
    _lcp_guess(S, q, dm, na, mu0, eq, hint, REGULARISATION * smax, tol, ck)
    for _sweep in range(PGS_MAX_SWEEPS):
        ch = 0.0
        for k in range(na):
            skk = S[k, k] + REGULARISATION * smax
            if skk <= 0.0:
                continue
            r = q[k]
            for l in range(na):
                r += S[k, l] * dm[l]
            new = dm[k] - r / skk
            if eq[k] == 0 and new < 0.0:
                new = 0.0
            c_ = abs(new - dm[k]) * skk
            ch = c_ if c_ > ch else ch
            dm[k] = new
        if ch <= tol:
            break
    for k in range(na):
        dm[k] -= mu0[k]
    # dl = z - Y^T dm
    for e in range(m):
        s = z[e]
        for k in range(na):
            s -= Y[e, k] * dm[k]
        dl[e] = s
    return True


@numba.njit(cache=True)
def _lcp_guess(S, q, nu, na, mu0, eq, hint, shift, tol, ck):
    """The start of projected Gauss-Seidel on ``w = S nu + q >= 0, nu >= 0``
    (complementary; equalities where ``eq``), by block pivoting from a guessed pushing set
    ``A`` (``mu0 > 0``, ``eq`` or ``hint``): ``nu_A`` solves ``S_AA nu_A = -q_A`` (LU,
    the diagonal shifted by ``shift`` as the iteration's is), 0 elsewhere; the inequality
    rows of ``A`` with ``nu S_kk <= tol`` (pulling, or pushing less than the iteration
    resolves) leave it, else the rows outside with ``w < -tol`` join it (all of them for
    the first :data:`BLOCK_PIVOTS` pivots, then the most infeasible one), and the solve is
    repeated, at most :data:`GUESS_PIVOTS` times.  When a solve changes
    nothing (the contacts that pushed in the previous iteration or step push again, or the
    pivots found the set) ``nu`` is set and the iteration's first sweep finds it
    converged; else ``nu`` is left as it came (``mu0``).  Returns whether ``nu`` was set."""
    SA = ck.SA
    inA = ck.guess[0]
    amap = ck.guess[1]
    b = ck.vec[13]
    piv = ck.piv
    for k in range(na):
        inA[k] = 1 if (mu0[k] > 0.0 or eq[k] != 0 or hint[k] != 0) else 0
    for _pivot in range(GUESS_PIVOTS):
        nA = np.int64(0)  # (as na in _project_positions)
        for k in range(na):
            if inA[k] != 0:
                amap[nA] = k
                nA += 1
        if nA == 0:
            return False
        for r in range(nA):
            k = amap[r]
            for c in range(nA):
                SA[r, c] = S[k, amap[c]]
            SA[r, r] += shift
            b[r] = -q[k]
        if not _lu_solve(SA, b, piv, nA):
            return False
        # after BLOCK_PIVOTS pivots that change every infeasible row, one at a time: the
        # most infeasible
        single = _pivot >= BLOCK_PIVOTS
        changed = False
        kbest = -1
        vbest = np.inf
        for r in range(nA):
            if not np.isfinite(b[r]):
                return False
            # an inequality row leaves when it pulls or when its push is below what the
            # iteration resolves (nu S_kk <= tol: a contact that holds nothing)
            k = amap[r]
            v = b[r] * (S[k, k] + shift)
            if eq[k] == 0 and v <= tol:
                changed = True
                if not single:
                    inA[k] = 0
                elif v < vbest:
                    vbest, kbest = v, k
        if changed:
            if kbest >= 0:
                inA[kbest] = 0
            continue
        for k in range(na):
            if inA[k] == 0:
                wk = q[k]
                for r in range(nA):
                    wk += S[k, amap[r]] * b[r]
                if wk < -tol:
                    changed = True
                    if not single:
                        inA[k] = 1
                    elif wk < vbest:
                        vbest, kbest = wk, k
        if changed:
            if kbest >= 0:
                inA[kbest] = 1
            continue
        for k in range(na):
            nu[k] = 0.0
        for r in range(nA):
            nu[amap[r]] = b[r]
        return True
    return False


# ----------------------------------------------------------------------------- banded solve

@numba.njit(cache=True)
def _band_incidence(na, ci, ck):
    """Node -> contacts lists of the ``na`` contacts (CSR in ``ck.band_int`` rows 0 and
    1: row 0 the node pointers, row 1 the entries ``3 k + t``, t the contact's node: 0 its
    node, 1 and 2 its segment's ends)."""
    n = ck.xref.shape[0]
    ptr = ck.band_int[0]
    lst = ck.band_int[1]
    for q in range(n + 1):
        ptr[q] = 0
    for k in range(na):
        ptr[ci[k, 0] + 1] += 1
        ptr[ci[k, 1] + 1] += 1
        ptr[ci[k, 1] + 2] += 1
    for q in range(n):
        ptr[q + 1] += ptr[q]
    fill = ck.band_int[2]
    for q in range(n):
        fill[q] = ptr[q]
    for k in range(na):
        for t in range(3):
            q = ci[k, 0] if t == 0 else ci[k, 1] + t - 1
            lst[fill[q]] = 3 * k + t
            fill[q] += 1


@numba.njit(cache=True, inline="always")
def _band_add(band, pos, bw, r, c, val):
    pr = pos[r]
    band[pr, pos[c] - pr + bw] += val


@numba.njit(cache=True)
def _band_order(m, na, ci, aidx, amap, ck):
    """Breadth-first (Cuthill-McKee) order of the unknowns, edges ``0 .. m-1`` and active
    contact ``k`` as ``m + aidx[k]``, from edge 0: their positions into ``ck.band_int`` row
    3; returns the half-bandwidth of the system in that order."""
    ptr = ck.band_int[0]
    lst = ck.band_int[1]
    pos = ck.band_int[3]
    queue = ck.band_int[4]
    nu = m
    for k in range(na):
        if aidx[k] >= 0:
            nu += 1
    for r in range(nu):
        pos[r] = -1
    pos[0] = 0
    queue[0] = 0
    head = 0
    tail = 1
    bw = 0
    while head < tail:
        r = queue[head]
        head += 1
        # the neighbours of unknown r: for an edge its two neighbours and the contacts at
        # its two nodes; for a contact the edges and the contacts at its three nodes
        if r < m:
            for s in (r - 1, r + 1):
                if 0 <= s < m:
                    if pos[s] < 0:
                        pos[s] = tail
                        queue[tail] = s
                        tail += 1
                    bw = max(bw, abs(pos[s] - pos[r]))
            q0 = r
            q1 = r + 1
            nq = 2
        else:
            k = amap[r - m]
            q0 = ci[k, 0]
            q1 = ci[k, 1]
            nq = 3
        for t in range(nq):
            q = q0 if t == 0 else q1 + t - 1
            if r >= m:
                for s in (q - 1, q):
                    if 0 <= s < m:
                        if pos[s] < 0:
                            pos[s] = tail
                            queue[tail] = s
                            tail += 1
                        bw = max(bw, abs(pos[s] - pos[r]))
            for e in range(ptr[q], ptr[q + 1]):
                l = lst[e] // 3
                if aidx[l] >= 0:
                    s = m + aidx[l]
                    if pos[s] < 0:
                        pos[s] = tail
                        queue[tail] = s
                        tail += 1
                    bw = max(bw, abs(pos[s] - pos[r]))
    # every contact touches the edges, which form a path: all are reached
    return bw if tail == nu else m + na


@numba.njit(cache=True)
def _band_factor(band, bw, nu):
    """LU factorisation without pivoting of the ``nu`` rows of a band of half-width ``bw``
    (row r holds columns ``r - bw .. r + bw`` in ``band[r, 0 .. 2 bw]``), in place: the
    multipliers below the diagonal.  False at a vanishing or non-finite pivot."""
    for kk in range(nu):
        piv = band[kk, bw]
        if not (abs(piv) > 0.0 and abs(piv) < np.inf):
            return False
        inv = 1.0 / piv
        last = min(nu - 1, kk + bw)
        for r in range(kk + 1, last + 1):
            off = kk - r + bw
            lr = band[r, off] * inv
            band[r, off] = lr
            if lr != 0.0:
                for c in range(1, last - kk + 1):
                    band[r, off + c] -= lr * band[kk, bw + c]
    return True


@numba.njit(cache=True)
def _band_substitute(band, bw, nu, y):
    """Solve with the factors of :func:`_band_factor`: ``y`` is overwritten."""
    for r in range(nu):
        acc = y[r]
        for c in range(max(0, r - bw), r):
            acc -= band[r, c - r + bw] * y[c]
        y[r] = acc
    for r in range(nu - 1, -1, -1):
        acc = y[r]
        for c in range(r + 1, min(nu - 1, r + bw) + 1):
            acc -= band[r, c - r + bw] * y[c]
        y[r] = acc / band[r, bw]


@numba.njit(cache=True)
def _band_lcp(R, O, w, f, rhs_e, na, ci, cu, cn, rhs_c, ck, dl, dm, mu0, eq, hint, tol):
    """The complementarity problem of :func:`_bordered_solve` by active-set changes on the
    whole bordered system, banded; False (nothing decided) hands it to the dense solve.

    For an active set ``A`` (first the contacts that push, ``mu0 > 0``, are equalities or
    are guessed, ``hint``) the edge rows and the rows of ``A`` as equations, the other
    contacts' multipliers zero, are one sparse system in the edges' and ``A``'s
    multipliers; the diagonal of ``A``'s rows is shifted by :data:`REGULARISATION` times
    the largest ``(C W C^T)_kk``, as in the dense solve.  Ordered breadth-first from the
    first edge (:func:`_band_order`) it is a band of half-width ``bw`` (a rod folded on
    itself in two layers: a ladder of a few unknowns per level), factorised without
    pivoting in ``O((m + |A|) bw**2)`` (the edge rows are those SHAKE factorises without
    pivoting, the contact rows a positive diagonal block) and refined against the rows
    without the shift.  Then, as in :func:`_lcp_guess`, an inequality contact of ``A``
    whose multiplier has ``nu_k (C W C^T)_kk <= tol`` leaves, else a contact outside whose
    gap after the update is below ``-tol`` joins (all of them for the first
    :data:`BLOCK_PIVOTS` pivots, then the most infeasible one), at most
    :data:`BAND_PIVOTS` times.  When
    nothing changes and the residual is below ``tol`` or :data:`BAND_RESIDUAL` of the
    right-hand side, the solution is returned: ``dl`` the edges' multipliers, ``dm`` the
    contacts' updates (``nu - mu0``).

    Refused: a band wider than :data:`BAND_MAX`, a vanishing or non-finite pivot, a larger
    residual (near-redundant contacts, whose rows nearly coincide), or an active set that
    does not settle.
    """
    m = R.shape[0]
    n = m + 1
    band = ck.band
    kv = ck.band_vec
    ea = kv[0]
    eb = kv[1]
    ec = kv[2]
    eskip = kv[3]
    dkk = kv[4]
    rhs = kv[5]
    aidx = ck.band_int[5]
    amap = ck.band_int[6]
    dq = ck.band_dq
    for e in range(m):
        ea[e], eb[e], ec[e], eskip[e] = _edge_row(R, O, w, f, e, m)
    # the contacts' diagonal (C W C^T)_kk and the shift of the dense solve
    smax = 0.0
    for k in range(na):
        s = 0.0
        for t in range(3):
            q = ci[k, 0] if t == 0 else ci[k, 1] + t - 1
            wt = _node_weight(t, cu[k])
            s += wt * wt * (cn[k, 0] * cn[k, 0] * w[q, 0] + cn[k, 1] * cn[k, 1] * w[q, 1])
        dkk[k] = s
        smax = s if s > smax else smax
    shift = REGULARISATION * smax
    rscale = 0.0
    for e in range(m):
        if eskip[e] == 0.0:
            rscale = max(rscale, abs(rhs_e[e]))
    for k in range(na):
        rscale = max(rscale, abs(rhs_c[k]))
    _band_incidence(na, ci, ck)
    ptr = ck.band_int[0]
    lst = ck.band_int[1]
    pos = ck.band_int[3]
    for k in range(na):
        aidx[k] = 0 if (mu0[k] > 0.0 or eq[k] != 0 or hint[k] != 0) else -1
    for _pivot in range(BAND_PIVOTS):
        na_in = 0
        for k in range(na):
            if aidx[k] >= 0:
                aidx[k] = na_in
                amap[na_in] = k
                na_in += 1
        nu = m + na_in
        bw = _band_order(m, na, ci, aidx, amap, ck)
        if bw > BAND_MAX:
            return False
        width = 2 * bw + 1
        for r in range(nu):
            rhs[r] = 0.0
            for c in range(width):
                band[r, c] = 0.0
        # edge rows
        for e in range(m):
            pr = pos[e]
            if eskip[e] != 0.0:
                band[pr, bw] = 1.0
                continue
            band[pr, bw] += eb[e]
            if e > 0:
                _band_add(band, pos, bw, e, e - 1, ea[e])
            if e < m - 1:
                _band_add(band, pos, bw, e, e + 1, ec[e])
            rhs[pr] = rhs_e[e]
        # the contacts' columns in the edge rows, B; a contact outside A contributes its
        # fixed update -mu0 to the right-hand side
        for k in range(na):
            if aidx[k] < 0 and mu0[k] == 0.0:
                continue
            for t in range(3):
                q = ci[k, 0] if t == 0 else ci[k, 1] + t - 1
                wt = _node_weight(t, cu[k])
                px = w[q, 0] * wt * cn[k, 0]
                pz = w[q, 1] * wt * cn[k, 1]
                for side in range(2):
                    e = q - 1 if side == 0 else q
                    if e < 0 or e >= m or eskip[e] != 0.0:
                        continue
                    coef = f * (R[e, 0] * px + R[e, 1] * pz)
                    coef = coef if side == 0 else -coef
                    if aidx[k] >= 0:
                        _band_add(band, pos, bw, e, m + aidx[k], coef)
                    else:
                        rhs[pos[e]] += coef * mu0[k]
        # the rows of A: B2 (the edges), C W C^T (the contacts sharing a node), the shift
        for r in range(na_in):
            k = amap[r]
            row = m + r
            pr = pos[row]
            band[pr, bw] += shift
            rhs[pr] = rhs_c[k] - shift * mu0[k]
            for t in range(3):
                q = ci[k, 0] if t == 0 else ci[k, 1] + t - 1
                wt = _node_weight(t, cu[k])
                gx = wt * cn[k, 0] * w[q, 0]
                gz = wt * cn[k, 1] * w[q, 1]
                if q - 1 >= 0:
                    _band_add(band, pos, bw, row, q - 1, gx * O[q - 1, 0] + gz * O[q - 1, 1])
                if q < m:
                    _band_add(band, pos, bw, row, q, -(gx * O[q, 0] + gz * O[q, 1]))
                for ent in range(ptr[q], ptr[q + 1]):
                    l = lst[ent] // 3
                    wl = _node_weight(lst[ent] % 3, cu[l])
                    val = wl * (gx * cn[l, 0] + gz * cn[l, 1])
                    if aidx[l] >= 0:
                        _band_add(band, pos, bw, row, m + aidx[l], val)
                    else:
                        rhs[pr] += val * mu0[l]
        if not _band_factor(band, bw, nu):
            return False
        _band_substitute(band, bw, nu, rhs)
        for e in range(m):
            dl[e] = rhs[pos[e]]
        for k in range(na):
            dm[k] = rhs[pos[m + aidx[k]]] if aidx[k] >= 0 else -mu0[k]
        # iterative refinement on the unshifted rows (the shift stays in the factors: each
        # round divides the error by about REGULARISATION; the multipliers' split between
        # redundant contacts is not unique, the update of the positions is): the residual
        # of the rows with the update of the positions (velocities) it makes,
        # W (G_O^T dl + C^T dm)
        for refine in range(BAND_REFINE + 1):
            for q in range(n):
                dq[q, 0] = 0.0
                dq[q, 1] = 0.0
            _apply(dq, w, O, dl, na, ci, cu, cn, dm, 1.0)
            res = 0.0
            for e in range(m):
                r_ = 0.0
                if eskip[e] == 0.0:
                    r_ = rhs_e[e] - f * (R[e, 0] * (dq[e + 1, 0] - dq[e, 0])
                                         + R[e, 1] * (dq[e + 1, 1] - dq[e, 1]))
                    res = max(res, abs(r_))
                rhs[pos[e]] = r_
            for r in range(na_in):
                k = amap[r]
                r_ = rhs_c[k] - _gap(dq, ci[k, 0], ci[k, 1], cu[k], cn[k, 0], cn[k, 1], 0.0)
                res = max(res, abs(r_))
                rhs[pos[m + r]] = r_
            if res <= BAND_REFINED * rscale or refine == BAND_REFINE:
                break
            _band_substitute(band, bw, nu, rhs)
            for e in range(m):
                dl[e] += rhs[pos[e]]
            for r in range(na_in):
                dm[amap[r]] += rhs[pos[m + r]]
        # contacts that pull leave first (redundant ones, whose equations together have no
        # solution, pull against each other through the shift), then the solution of the
        # rows of a settled set must be accurate
        # (after BLOCK_PIVOTS pivots that change every infeasible contact, one at a time:
        # the most infeasible)
        single = _pivot >= BLOCK_PIVOTS
        changed = False
        kbest = -1
        vbest = np.inf
        for k in range(na):
            if aidx[k] >= 0 and eq[k] == 0:
                v = (dm[k] + mu0[k]) * (dkk[k] + shift)
                if v <= tol:
                    changed = True
                    if not single:
                        aidx[k] = -1
                    elif v < vbest:
                        vbest, kbest = v, k
        if changed:
            if kbest >= 0:
                aidx[kbest] = -1
            for k in range(na):
                if aidx[k] >= 0:
                    aidx[k] = 0
            continue
        if not (res <= BAND_RESIDUAL * rscale or res <= tol):
            return False
        for k in range(na):
            if aidx[k] < 0:
                gk = _gap(dq, ci[k, 0], ci[k, 1], cu[k], cn[k, 0], cn[k, 1], 0.0) - rhs_c[k]
                if gk < -tol:
                    changed = True
                    if not single:
                        aidx[k] = 0
                    elif gk < vbest:
                        vbest, kbest = gk, k
        if not changed:
            return True
        if kbest >= 0:
            aidx[kbest] = 0
        for k in range(na):
            if aidx[k] >= 0:
                aidx[k] = 0
    return False


@numba.njit(cache=True)
def _apply(q, w, O, dl, na, ci, cu, cn, dm, fac):
    """``q += fac W (G_O^T dl + C^T dm)``."""
    m = O.shape[0]
    for jn in range(q.shape[0]):
        gx = 0.0
        gz = 0.0
        if jn >= 1:
            gx += O[jn - 1, 0] * dl[jn - 1]
            gz += O[jn - 1, 1] * dl[jn - 1]
        if jn < m:
            gx -= O[jn, 0] * dl[jn]
            gz -= O[jn, 1] * dl[jn]
        q[jn, 0] += fac * w[jn, 0] * gx
        q[jn, 1] += fac * w[jn, 1] * gz
    for k in range(na):
        i = ci[k, 0]
        j = ci[k, 1]
        u = cu[k]
        mk = fac * dm[k]
        q[i, 0] += w[i, 0] * cn[k, 0] * mk
        q[i, 1] += w[i, 1] * cn[k, 1] * mk
        q[j, 0] -= w[j, 0] * (1.0 - u) * cn[k, 0] * mk
        q[j, 1] -= w[j, 1] * (1.0 - u) * cn[k, 1] * mk
        q[j + 1, 0] -= w[j + 1, 0] * u * cn[k, 0] * mk
        q[j + 1, 1] -= w[j + 1, 1] * u * cn[k, 1] * mk


@numba.njit(cache=True, inline="always")
def _gap(x, i, j, u, nx, nz, d):
    return (nx * (x[i, 0] - (1.0 - u) * x[j, 0] - u * x[j + 1, 0])
            + nz * (x[i, 1] - (1.0 - u) * x[j, 1] - u * x[j + 1, 1]) - d)


@numba.njit(cache=True, inline="always")
def _activate(ck, eq, p, na, K):
    """Pair ``p`` joins the ``na`` active contacts (multiplier 0, an inequality): the new
    count, or -1 (failure 2 recorded) when the ``K`` slots are full."""
    if na >= K:
        ck.meta[_FAIL] = 2
        return -1
    ck.active[na] = p
    ck.mu_pos[na] = 0.0
    eq[na] = 0
    ck.flags[2, na] = ck.pushed[p]
    ck.mark[p] = 1
    return na + 1


@numba.njit(cache=True, inline="always")
def _listed_gap(x, ck, p, d):
    """The linearised gap of listed pair ``p`` at ``x`` (its closest point and normal in
    ``ck.pair_geom``)."""
    pg = ck.pair_geom
    return _gap(x, ck.pairs[p, 0], ck.pairs[p, 1], pg[p, 0], pg[p, 1], pg[p, 2], d)


@numba.njit(cache=True, inline="always")
def _add_impulse(fc, i, j, u, jx, jz):
    """Impulse ``(jx, jz)`` on node ``i`` against segment ``j`` at ``u`` (weights
    ``1, -(1 - u), -u``: the total is zero)."""
    fc[i, 0] += jx
    fc[i, 1] += jz
    fc[j, 0] -= (1.0 - u) * jx
    fc[j, 1] -= (1.0 - u) * jz
    fc[j + 1, 0] -= u * jx
    fc[j + 1, 1] -= u * jz


# ----------------------------------------------------------------------------- stages


@numba.njit(cache=True, inline="always")
def _redundant(pairs, npairs, p, u, u_prev):
    """Whether listed pair p (node i, segment j, closest point u) repeats a neighbour: a
    node closest to the vertex shared by segments j and j +- 1 is held by the constraint of
    the other segment (the pairs are sorted by node, then segment; ``u_prev`` is the
    closest point of pair p - 1)."""
    i = pairs[p, 0]
    j = pairs[p, 1]
    if u >= 1.0 and p + 1 < npairs and pairs[p + 1, 0] == i and pairs[p + 1, 1] == j + 1:
        return True
    if (u <= 0.0 and p > 0 and pairs[p - 1, 0] == i and pairs[p - 1, 1] == j - 1
            and u_prev < 1.0):
        return True
    return False


@numba.njit(cache=True, inline="always")
def _listed_nothing_and_valid(xo, x, ck):
    """Whether nothing is listed, no force is left to clear, and the (empty) list stays valid
    for this step: every node of ``xo`` and ``x`` within skin / 2 of the last rebuild (the
    test of :func:`_list_valid`, stopped at the first node that moved further)."""
    meta = ck.meta
    if meta[_NPAIRS] != 0 or meta[_FORCES] != 0 or meta[_VALID] != 1:
        return False
    xref = ck.xref
    half = 0.5 * ck.stat[_SKIN]
    lim = half * half
    for i in range(x.shape[0]):
        ax = x[i, 0] - xref[i, 0]
        az = x[i, 1] - xref[i, 1]
        bx = xo[i, 0] - xref[i, 0]
        bz = xo[i, 1] - xref[i, 1]
        if ax * ax + az * az >= lim or bx * bx + bz * bz >= lim:
            return False
    return True


@numba.njit(cache=True, inline="always")
def contact_positions(xo, x, w, edge_len, lam, thickness, max_depth, ck):
    """Position stage: project ``x`` (edge lengths already satisfied, e.g. by SHAKE) onto
    the edge lengths and the non-penetration constraints linearised at ``xo``.

    Parameters
    ----------
    xo : ndarray (n, 2)
        Positions at the start of the step (satisfying the constraints).
    x : ndarray (n, 2)
        Projected in place.
    w : ndarray (n, 2)
        Inverse masses (0 for held coordinates).
    edge_len : ndarray (n - 1,)
    lam : ndarray (n + 1,)
        The edge multipliers, padded as SHAKE's (entry e + 1 for edge e): the corrections
        of the edge multipliers are added to it.
    thickness : float
    max_depth : float
        Deepest penetration of a linearised gap (length units) the projection accepts;
        deeper, the step is refused (failure 7) before any projection (``np.inf``: no
        limit).
    ck : ContactWork
        :func:`new_contact_work`.

    Returns
    -------
    int
        0 no contact, 1 contacts projected, -1 failure (``meta[_FAIL]``: 1 too many listed
        pairs, 2 too many contacts, 3 singular system, 4 Newton did not converge, 5 the
        set of contacts did not settle, 6 the projection diverged, 7 deeper than
        ``max_depth``).
    """
    # inlined into the stepper: a step with nothing listed (the usual contact-free step)
    # costs one pass over the nodes and no call
    if _listed_nothing_and_valid(xo, x, ck):
        ck.meta[_NACT] = 0
        ck.stat[_GMIN] = np.inf
        return 0
    st = _project_positions(xo, x, w, edge_len, lam, thickness, max_depth, ck)
    if st < 0:
        ck.meta[_NFAIL] += 1
    return st


@numba.njit(cache=True)
def _project_positions(xo, x, w, edge_len, lam, thickness, max_depth, ck):
    """:func:`contact_positions` past its shortcut."""
    n = x.shape[0]
    m = n - 1
    h_min = edge_len.min()
    if ck.meta[_FORCES] != 0:
        for i in range(n):
            ck.forces[i, 0] = 0.0
            ck.forces[i, 1] = 0.0
        ck.meta[_FORCES] = 0
    ck.meta[_NACT] = 0
    ok, step = _list_valid(xo, x, ck)
    if not ok:
        skin = CONTACT_SKIN * h_min
        if 2.5 * step > skin:
            skin = 2.5 * step
        ck.stat[_SKIN] = skin
        if not _rebuild(x, thickness, skin, ck):
            return -1
    npairs = ck.meta[_NPAIRS]
    ck.stat[_GMIN] = np.inf
    if npairs == 0:
        return 0
    # narrow phase: normals at xo, gaps at x
    worst = 0.0
    gmin = np.inf
    u_prev = 0.0
    for p in range(npairs):
        i = ck.pairs[p, 0]
        j = ck.pairs[p, 1]
        u, qx, qz = _closest(xo, i, j)
        dd = math.sqrt(qx * qx + qz * qz)
        if dd > 0.0:
            nx = qx / dd
            nz = qz / dd
        else:
            # on the segment: its normal
            ex = xo[j + 1, 0] - xo[j, 0]
            ez = xo[j + 1, 1] - xo[j, 1]
            le = math.sqrt(ex * ex + ez * ez)
            nx = -ez / le
            nz = ex / le
        ck.pair_geom[p, 0] = u
        ck.pair_geom[p, 1] = nx
        ck.pair_geom[p, 2] = nz
        g = _gap(x, i, j, u, nx, nz, thickness)
        ck.pair_geom[p, 3] = g
        # the pairs that pushed at the end of the last step (the list unchanged since):
        # the guess of the complementarity problem's first solve
        ck.pushed[p] = 1 if (ok and ck.mark[p] == 1) else 0
        ck.mark[p] = -1 if _redundant(ck.pairs, npairs, p, u, u_prev) else 0
        u_prev = u
        if ck.mark[p] == 0:
            worst = -g if -g > worst else worst
            gmin = g if g < gmin else gmin
    ck.stat[_GMIN] = gmin
    if worst == 0.0:
        return 0
    if worst > max_depth:
        ck.meta[_FAIL] = 7
        return -1
    if worst > ck.stat[_PENETRATION] * thickness:
        ck.stat[_PENETRATION] = worst / thickness
    K = ck.active.shape[0]
    ci = ck.rows[0]
    cn = ck.normals[0]
    cu = ck.weights[0]
    eq = ck.flags[0]
    vec = ck.vec
    R = ck.edges[0]
    O = ck.edges[1]
    for e in range(m):
        O[e, 0] = xo[e + 1, 0] - xo[e, 0]
        O[e, 1] = xo[e + 1, 1] - xo[e, 1]
    phi = vec[8]
    rc = vec[9]
    dl = vec[10]
    dm = vec[11]
    xscale = 0.0
    for i in range(n):
        xscale = max(xscale, abs(x[i, 0]), abs(x[i, 1]))
    tol_g = TOL_GAP * h_min + TOL_FLOOR * xscale
    # the edges' relative residual cannot go below the round-off of edge vectors taken
    # from coordinates of size xscale (SHAKE's own floor; 8e-14 on fig3-strip's 200 edges
    # of a 14.3 long strip): without the floor the Newton iteration would spin to its cap
    tol_e = TOL_EDGE + TOL_FLOOR * xscale / h_min
    # the candidates: pairs within twice the deepest penetration of contact (the
    # projection moves the rod by about that); a pair left out that ends violated is
    # added and the projection repeated
    reach = 2.0 * worst + tol_g
    # an int64 from the start: from a literal 0, numba's type inference would compile the
    # callees (_bordered_solve and all it calls, ~10 s cold) once more, for the literal
    na = np.int64(0)
    for p in range(npairs):
        if ck.mark[p] == 0 and ck.pair_geom[p, 3] < reach:
            na = _activate(ck, eq, p, na, K)
            if na < 0:
                return -1
    settled = False
    for _round in range(MAX_ROUNDS):
        ck.meta[_ROUNDS] += 1
        for k in range(na):
            p = ck.active[k]
            ci[k, 0] = ck.pairs[p, 0]
            ci[k, 1] = ck.pairs[p, 1]
            cu[k] = ck.pair_geom[p, 0]
            cn[k, 0] = ck.pair_geom[p, 1]
            cn[k, 1] = ck.pair_geom[p, 2]
        conv = False
        err_e = np.inf
        err_g = np.inf
        g_prev = np.inf
        for it in range(MAX_NEWTON + 1):
            err_e = 0.0
            for e in range(m):
                R[e, 0] = x[e + 1, 0] - x[e, 0]
                R[e, 1] = x[e + 1, 1] - x[e, 1]
                li2 = edge_len[e] * edge_len[e]
                ph = R[e, 0] * R[e, 0] + R[e, 1] * R[e, 1] - li2
                phi[e] = -ph
                r = abs(ph) / (2.0 * li2)
                # (written so that a NaN propagates: ``r > err_e`` would skip it)
                err_e = err_e if r <= err_e else r
            # complementarity residual: penetration, or a gap where the contact pushes
            err_g = 0.0
            for k in range(na):
                g = _gap(x, ci[k, 0], ci[k, 1], cu[k], cn[k, 0], cn[k, 1], thickness)
                rc[k] = -g
                r = abs(g) if ck.mu_pos[k] > 0.0 else -g
                err_g = err_g if r <= err_g else r
            if not (err_e <= EDGE_DIVERGED and err_g < np.inf):
                # diverged, or non-finite: refused before it reaches the state
                ck.meta[_FAIL] = 6
                return -1
            if err_e <= tol_e and err_g <= tol_g:
                conv = True
                break
            if it == MAX_NEWTON or (it > 4 and err_e <= tol_e and err_g >= 0.5 * g_prev):
                break
            g_prev = err_g
            if not _bordered_solve(R, O, w, 2.0, phi, na, ci, cu, cn, rc, ck, dl, dm,
                                   ck.mu_pos, eq, ck.flags[2], 0.1 * tol_g):
                ck.meta[_FAIL] = 3
                return -1
            # later solves guess from the multipliers (mu_pos > 0)
            for k in range(na):
                ck.flags[2, k] = 0
            _apply(x, w, O, dl, na, ci, cu, cn, dm, 1.0)
            for e in range(m):
                lam[e + 1] += dl[e]
            for k in range(na):
                ck.mu_pos[k] += dm[k]
                if ck.mu_pos[k] < 0.0:
                    ck.mu_pos[k] = 0.0
        if not conv:
            # redundant contacts (stacked layers) stall the complementarity residual above
            # round-off: accepted below TOL_REDUNDANT * thickness, anything else refused
            if not (err_e < 1e-12 and err_g < max(100.0 * tol_g, TOL_REDUNDANT * thickness)):
                ck.meta[_FAIL] = 4
                return -1
        # a pair left out of the candidates that ends violated joins them
        changed = False
        for p in range(npairs):
            if ck.mark[p] == 0:
                g = _listed_gap(x, ck, p, thickness)
                if g < -tol_g:
                    na = _activate(ck, eq, p, na, K)
                    if na < 0:
                        return -1
                    changed = True
        if not changed:
            settled = True
            break
    if not settled:
        ck.meta[_FAIL] = 5
        return -1
    # keep the pushing contacts only (their marks tell the velocity stage)
    k2 = 0
    ge = 0.0
    for k in range(na):
        p = ck.active[k]
        if ck.mu_pos[k] > 0.0:
            ck.active[k2] = p
            ck.mu_pos[k2] = ck.mu_pos[k]
            k2 += 1
            g = abs(_listed_gap(x, ck, p, thickness))
            ge = g if g > ge else ge
        else:
            ck.mark[p] = 0
    na = k2
    for p in range(npairs):
        if ck.mark[p] >= 0:
            g = -_listed_gap(x, ck, p, thickness)
            ge = g if g > ge else ge
    ck.meta[_NACT] = na
    if na > ck.meta[_MAXACT]:
        ck.meta[_MAXACT] = na
    if na > 0:
        ck.meta[_STEPS] += 1
    if ge / thickness > ck.stat[_GAPERR]:
        ck.stat[_GAPERR] = ge / thickness
    return 1


@numba.njit(cache=True)
def contact_shortfall(x, thickness, max_shortfall, ck):
    """Whether a step's contacts turned too far for their linearisation: the largest
    shortfall ``(d - dist) / d`` of the true distance of a listed pair (node to segment,
    not redundant) below the thickness ``d`` at ``x``, after a position stage whose gaps
    were linearised at the start of the step (second order in the contacts' turn within
    the step), exceeds ``max_shortfall``.  True records failure 8 (counted in
    ``self_contact_failures``)."""
    npairs = ck.meta[_NPAIRS]
    worst = 0.0
    for p in range(npairs):
        if ck.mark[p] < 0:
            continue
        _u, qx, qz = _closest(x, ck.pairs[p, 0], ck.pairs[p, 1])
        r = (thickness - math.sqrt(qx * qx + qz * qz)) / thickness
        worst = worst if r <= worst else r
    if worst <= max_shortfall:
        return False
    ck.meta[_FAIL] = 8
    ck.meta[_NFAIL] += 1
    return True


@numba.njit(cache=True, inline="always")
def _touch_row(ck, ci, cu, cn, eq, nc, K, i, j, u, qx, qz, dd, pushed, equality):
    """Node ``i`` touching segment ``j`` at ``u`` (``q`` from the closest point, ``|q| =
    dd``) joins the velocity stage's ``nc`` rows (an equality if ``equality``, guessed
    pushing if the position stage ``pushed`` it): the new count, or -1 (failure 2) when
    the ``K`` slots are full."""
    if nc >= K:
        ck.meta[_FAIL] = 2
        return -1
    ci[nc, 0] = i
    ci[nc, 1] = j
    cu[nc] = u
    cn[nc, 0] = qx / dd
    cn[nc, 1] = qz / dd
    eq[nc] = 1 if equality else 0
    # the guess of the first solve: the contacts the position stage pushed
    ck.flags[2, nc] = 1 if pushed else 0
    return nc + 1


@numba.njit(cache=True, inline="always")
def contact_velocities(x, v, w, edge_len, thickness, dt, pos_factor, keep_rates, equal_active,
                       ck):
    """Velocity stage: where the rod touches itself (gap within tolerance at ``x``), remove
    the approaching relative normal velocity (restitution 0), keeping the edges' ``G v = 0``
    (``keep_rates`` False) or their stretching rates (True).

    ``equal_active``: the contacts the position stage of this step pushed end with zero
    relative normal velocity (equality; the midpoint method, whose step alone would bounce).
    ``pos_factor``: the momentum per unit of a position multiplier over ``dt`` (1 for
    RATTLE, 2 for the midpoint rule), for the contact forces ``ck.forces`` (the mean force of
    the step on every node).  Returns the number of touching pairs, -1 on failure (the
    velocities are then left as they came), -2 when the projection made a velocity
    non-finite (failure 6; the caller must discard the step).
    """
    # inlined into the stepper: nothing listed, or no projection this step and every
    # listed pair clear of contact, costs no call
    if ck.meta[_NPAIRS] == 0:
        return 0
    if ck.meta[_NACT] == 0 and ck.stat[_GMIN] > TOUCH_SKIP * edge_len.min():
        return 0
    nc = _project_velocities(x, v, w, edge_len, thickness, dt, pos_factor, keep_rates,
                             equal_active, ck)
    if nc < -1:
        ck.meta[_NFAIL] += 1
    return nc


@numba.njit(cache=True)
def _project_velocities(x, v, w, edge_len, thickness, dt, pos_factor, keep_rates,
                        equal_active, ck):
    """:func:`contact_velocities` past its shortcuts."""
    n = x.shape[0]
    m = n - 1
    npairs = ck.meta[_NPAIRS]
    nact = ck.meta[_NACT]
    h_min = edge_len.min()
    K = ck.active.shape[0]
    xscale = 0.0
    for i in range(n):
        xscale = max(xscale, abs(x[i, 0]), abs(x[i, 1]))
    tol_touch = 1e-9 * h_min + 1e3 * TOL_FLOOR * xscale
    inv_dt = 1.0 / dt
    # position impulses of this step into the forces
    for k in range(nact):
        p = ck.active[k]
        i = ck.pairs[p, 0]
        j = ck.pairs[p, 1]
        u = ck.pair_geom[p, 0]
        jx = pos_factor * ck.mu_pos[k] * inv_dt * ck.pair_geom[p, 1]
        jz = pos_factor * ck.mu_pos[k] * inv_dt * ck.pair_geom[p, 2]
        _add_impulse(ck.forces, i, j, u, jx, jz)
        ck.meta[_FORCES] = 1
    # touching pairs: true closest point and normal at x; within tol_touch of contact, or
    # pushed by this step's position stage, whose linearised gap is then zero but whose
    # true distance can exceed the thickness by a second-order amount (the contact turns
    # within the step: 1e-9 on fig3-strip's folded strip, above tol_touch); left out, such
    # a contact would end the step approaching, with the half kick of the force pressing
    # it in (a kinetic energy the next position stage removes: the run never reads rest)
    ci = ck.rows[1]
    cn = ck.normals[1]
    cu = ck.weights[1]
    eq = ck.flags[1]
    nc = np.int64(0)  # (as na in _project_positions)
    u_prev = 0.0
    carry = False
    last = -1
    for p in range(npairs):
        i = ck.pairs[p, 0]
        j = ck.pairs[p, 1]
        u, qx, qz = _closest(x, i, j)
        red = _redundant(ck.pairs, npairs, p, u, u_prev)
        u_prev = u
        dd = math.sqrt(qx * qx + qz * qz)
        pushed = ck.mark[p] == 1 or carry
        carry = False
        if red and pushed:
            # the pushed contact is now held by the neighbouring segment at the shared
            # vertex: the next pair (same vertex, u = 0) or the previous one
            if u >= 1.0:
                carry = True
            elif last != p - 1:
                ub, bx, bz = _closest(x, i, j - 1)
                db = math.sqrt(bx * bx + bz * bz)
                if db > 0.0:
                    nc = _touch_row(ck, ci, cu, cn, eq, nc, K, i, j - 1, ub, bx, bz, db,
                                    True, equal_active)
                    if nc < 0:
                        return -1
                    last = p - 1
        if (dd - thickness <= tol_touch or pushed) and dd > 0.0 and not red:
            nc = _touch_row(ck, ci, cu, cn, eq, nc, K, i, j, u, qx, qz, dd, pushed,
                            equal_active and pushed)
            if nc < 0:
                return -1
            last = p
    if nc == 0:
        if ck.meta[_FORCES] != 0:
            _finish_forces(ck.forces, inv_dt, ck.stat)
        return 0
    vmax = 0.0
    for i in range(n):
        vmax = max(vmax, abs(v[i, 0]), abs(v[i, 1]))
    tol_v = 1e-12 * vmax
    approaching = False
    for k in range(nc):
        vn = (cn[k, 0] * (v[ci[k, 0], 0] - (1.0 - cu[k]) * v[ci[k, 1], 0]
                          - cu[k] * v[ci[k, 1] + 1, 0])
              + cn[k, 1] * (v[ci[k, 0], 1] - (1.0 - cu[k]) * v[ci[k, 1], 1]
                            - cu[k] * v[ci[k, 1] + 1, 1]))
        if vn < -tol_v or eq[k] == 1:
            approaching = True
    if not approaching:
        if ck.meta[_FORCES] != 0:
            _finish_forces(ck.forces, inv_dt, ck.stat)
        return nc
    vec = ck.vec
    R = ck.edges[0]
    for e in range(m):
        R[e, 0] = x[e + 1, 0] - x[e, 0]
        R[e, 1] = x[e + 1, 1] - x[e, 1]
    rhs_e = vec[8]
    rc = vec[9]
    dl = vec[10]
    dm = vec[11]
    bm = ck.mu_vel
    for k in range(nc):
        bm[k] = 0.0
    rates = vec[12]
    for e in range(m):
        rates[e] = R[e, 0] * (v[e + 1, 0] - v[e, 0]) + R[e, 1] * (v[e + 1, 1] - v[e, 1])
    # the complementarity problem is solved iteratively: a few refinements from the
    # remaining residual, until it is below tol_v (the edges' rows as rates of length
    # change over the edge length, the contacts' as approach speeds, or any normal speed
    # where a contact pushes or is an equality)
    for refinement in range(VELOCITY_REFINEMENTS):
        res = 0.0
        for e in range(m):
            r = R[e, 0] * (v[e + 1, 0] - v[e, 0]) + R[e, 1] * (v[e + 1, 1] - v[e, 1])
            rhs_e[e] = (rates[e] - r) if keep_rates else -r
            res = max(res, abs(rhs_e[e]) / edge_len[e])
        for k in range(nc):
            i = ci[k, 0]
            j = ci[k, 1]
            u = cu[k]
            rc[k] = -(cn[k, 0] * (v[i, 0] - (1.0 - u) * v[j, 0] - u * v[j + 1, 0])
                      + cn[k, 1] * (v[i, 1] - (1.0 - u) * v[j, 1] - u * v[j + 1, 1]))
            res = max(res, abs(rc[k]) if (bm[k] > 0.0 or eq[k] != 0) else rc[k])
        if refinement > 0 and res <= tol_v:
            break
        if not _bordered_solve(R, R, w, 1.0, rhs_e, nc, ci, cu, cn, rc, ck, dl, dm, bm, eq,
                               ck.flags[2], 0.1 * tol_v):
            ck.meta[_FAIL] = 3
            return -1
        for k in range(nc):
            ck.flags[2, k] = 0
        _apply(v, w, R, dl, nc, ci, cu, cn, dm, 1.0)
        for k in range(nc):
            bm[k] += dm[k]
            dm[k] = bm[k]
    # the residual's maxima skip a NaN: a non-finite velocity is refused here (failure 6)
    for i in range(n):
        if not (abs(v[i, 0]) < np.inf and abs(v[i, 1]) < np.inf):
            ck.meta[_FAIL] = 6
            return -2
    na = 0
    for k in range(nc):
        if dm[k] != 0.0:
            na += 1
        i = ci[k, 0]
        j = ci[k, 1]
        u = cu[k]
        jx = dm[k] * cn[k, 0]
        jz = dm[k] * cn[k, 1]
        _add_impulse(ck.forces, i, j, u, jx, jz)
    if na > ck.meta[_NVEL]:
        ck.meta[_NVEL] = na
    ck.meta[_FORCES] = 1
    _finish_forces(ck.forces, inv_dt, ck.stat)
    return nc


@numba.njit(cache=True)
def _finish_forces(fc, inv_dt, stat):
    """Impulses of the step -> mean forces; their total magnitude into the statistics."""
    tot = 0.0
    for i in range(fc.shape[0]):
        fc[i, 0] *= inv_dt
        fc[i, 1] *= inv_dt
        tot += math.sqrt(fc[i, 0] * fc[i, 0] + fc[i, 1] * fc[i, 1])
    stat[_FTOTAL] = 0.5 * tot
