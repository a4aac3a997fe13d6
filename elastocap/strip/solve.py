"""Equilibria of the discrete strip on the ground: active-set Newton, descent, stability.

Equilibria of :class:`~elastocap.strip.model.DiscreteStrip` are the KKT points of

    grad E(u) = sum_k r_k grad z_k(u),   z_k >= 0,   r_k >= 0,   r_k z_k = 0,

(r_k the vertical ground reaction on node k, force units), solved by a primal-dual
active-set Newton method (semismooth Newton on min(r_k, c z_k) = 0; Hintermueller, Ito &
Kunisch 2002) with the exact Hessian of the Lagrangian E - sum r_k z_k
(:func:`solve_equilibrium`). An equilibrium with a negative reaction is not one (the node
would lift off): the solver never returns one as converged. :func:`minimize_energy`
reaches a local minimum by descent (trust-region Newton on a penalized energy, then the
active-set Newton); :func:`open_state` and :func:`wrapped_state` are the two seeds of the
branch search (a quasi-static deposition and the strip folded over the drop).

Stability: the inertia of the Lagrangian Hessian on the tangent space of the strongly
active contacts (r_k > 0): the number of negative eigenvalues is the stability index
(0: a stable state; 1: a saddle). A contact with r_k = 0 (weakly active) is reported
(``degenerate``) since the second-order test is then on a cone, not a space.
:func:`unstable_mode` and :func:`descend_from_saddle` leave a saddle both ways.

:func:`refine` carries an equilibrium to another number of edges (its identity kept: the
convergence studies follow one state, saddles included).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numba
import numpy as np
from scipy.linalg import eigh_tridiagonal, eigvalsh_tridiagonal
from scipy.linalg.lapack import dsytrd as _sytrd
from scipy.linalg.lapack import dsytrd_lwork as _sytrd_lwork

from continuation import factorize
from elastocap.strip.model import (
    DiscreteStrip,
    closest_segments,
    fix_gauge,
    flat_state,
    pair_gaps,
    pair_hessian,
    pair_jacobian,
    pair_switch,
    redundant_pair,
)

__all__ = [
    "DESCENT_COARSE_N",
    "PAIR_SLACK",
    "PENALTY",
    "STIFF_PENALTY",
    "Equilibrium",
    "contact_pairs_of",
    "R_REL",
    "descend_coarse_to_fine",
    "descend_from_saddle",
    "lagrangian_hessian",
    "minimize_energy",
    "open_state",
    "prolong",
    "refine",
    "solve_equilibrium",
    "stability",
    "unstable_mode",
    "with_self_contact",
    "wrapped_state",
]

# PDAS scaling c in min(r, c z): r is a force (~ q h per node) and z a length; c = B / h^3
# is the stiffness of one node pushed by a force against its bending neighbours, so that
# both arguments are of the same size. (For the linear obstacle problem any c > 0 gives the
# same iterates once the active set is right; c only affects the first steps.)
_PDAS_C = 1.0
# A Newton step that turns an edge angle by more than this is scaled down (radians): the
# unknowns are angles, and beyond ~0.5 rad the linearization of sin/cos is poor.
_MAX_TURN = 0.5
#: Reactions below this fraction of the node weight q h count as zero when classifying
#: contacts (strongly active / weakly active); the default Newton tolerance is far below.
R_REL = 1e-7
# Newton iterations of the active-set method. From a start with every node on the ground
# the multipliers turn negative only at the peeling front, so the contact set shrinks by
# one node per iteration (measured: the strip lifted by an end force F = 1 needs 16, 30,
# 57 iterations at n = 100, 200, 400): the cap must exceed the number of nodes that lift.
_MAX_ITER = 200
# Short Newton steps for :func:`refine`'s second try (radians) and the iterations they
# need: 0.05 rad per step reaches 1-2 rad changes of the tail in ~40 steps, then Newton
# converges quadratically.
_SHORT_TURN = 0.05
_SHORT_ITER = 200
# Descent (:func:`minimize_energy`): stop at |grad| below this (energy units, as scipy's
# trust-exact gtol); the active-set polish then converges quadratically.
_DESCENT_GTOL = 1e-8
# Steps of the thickness continuation that makes a state without contact one with contact
# (after d / 64: d / 16, 2 d / 16, ..., d; measured at x = 3, Delta = 1.2, n = 286: 4
# Newton iterations each).
_THICKNESS_STEPS = 16
# Push off the saddle along its unstable mode before each descent (radians, max norm of
# the displacement): large enough for the descent to leave the saddle's neighbourhood at
# once, small next to the distance to either minimum (~1-3 rad in the tail angles).
_PUSH = 0.02
#: The descent's ground penalty stiffness k = PENALTY B / h^3 (:func:`minimize_energy`).
#: The soft ground moves where a state loses stability: the mirror-symmetric open state
#: (n = 60, drop mid-strip) is a minimum of the penalized energy up to 0.02 in Delta past
#: the exact problem's loss of stability, so a descent pushed off it there comes back to
#: it; with STIFF_PENALTY it leaves it from 0.005 past on (measured). PENALTY keeps the
#: descent from afar short (x = 4, Delta = 1.1, n = 100: 57 trust iterations against 461
#: at 1e3 B / h^3, the same polished state).
PENALTY = 10.0
STIFF_PENALTY = 100.0
#: Edges above which :func:`descend_coarse_to_fine` descends on half the edges first. The
#: direct descent's iterations grow with n (x = 3, Delta = 1.2, from the flat strip: 492
#: at n = 429, past the 500 allowed at 572); up to here it is kept, so that the default
#: resolutions (198 and 297 edges) seed as they do: from a coarser strip a seed can land on
#: another minimum (x = 5, Delta = 1.4, 99 -> 198 edges: a third branch, the window
#: unchanged).
DESCENT_COARSE_N = 300


def lagrangian_hessian(strip: DiscreteStrip, u, r, pairs=None, mu=None) -> np.ndarray:
    """Hessian of E - sum_k r_k z_k - sum_p mu_p gap_p in u, shape (n + 1, n + 1).

    The ground's part, ``-sum_k r_k d^2 z_k / du^2``, is
    ``diag_j(h sin theta_j sum_{k > j} r_k)``; the self-contact pairs (``pairs`` (m, 3),
    forces ``mu`` (m,)) add minus :func:`~elastocap.strip.model.pair_hessian`.
    """
    N = strip.size
    H = strip.hessian(u)
    rs = np.cumsum(np.asarray(r)[::-1])[::-1]
    H[np.arange(1, N), np.arange(1, N)] += strip.h * np.sin(u[1:]) * rs[1:]
    if pairs is not None and len(pairs):
        H -= pair_hessian(strip, u, pairs, mu)
    return H


def _with_pairs(strip, u, Z, pairs):
    """The basis Z (N, k) of the ground's tangent space restricted to the null space of
    the pairs' gradients as well (orthonormal, (N, k'))."""
    if pairs is None or not len(pairs):
        return Z
    C = pair_jacobian(strip, u, pairs) @ Z
    _q, sv, vt = np.linalg.svd(C, full_matrices=True)
    rank = int(np.sum(sv > 1e-12 * max(float(sv[0]), 1e-300))) if sv.size else 0
    return Z @ vt[rank:].T


def _strong_weak(strip, eq):
    rtol = R_REL * strip.q * strip.h
    strong = eq.active & (eq.reactions > rtol)
    return strong, eq.active & ~strong


def _tangent_basis(strip, u, nodes) -> np.ndarray:
    """Orthonormal basis (N, N - rank) of the null space of the gradients of z_k, k in
    ``nodes`` (bool mask or indices; the identity without contacts).

    The rows are taken as the gradients of z at the first node and of the differences of
    z between consecutive nodes (the same null space): where two neighbours k, k + 1 are
    both held the row is h cos theta_k at theta_k alone, which fixes that unknown, so the
    SVD runs only on the other rows and unknowns (a flat stretch on the ground adds
    nothing to it).
    """
    k = np.asarray(nodes)
    k = np.flatnonzero(k) if k.dtype == bool else k.astype(np.int64)
    N = strip.size
    if not k.size:
        # a free rod (no ground contacts): the unknowns but the gauge's
        return np.delete(np.eye(N), strip.gauge, axis=1)
    G = strip.constraint_jacobian(u, k)
    D = G.copy()
    D[1:] -= G[:-1]
    nz = D != 0.0
    single = np.count_nonzero(nz, axis=1) == 1
    cols = np.argmax(nz[single], axis=1)
    keep = np.ones(N, dtype=bool)
    if np.unique(cols).size == cols.size:
        keep[cols] = False
        D = D[~single]
    D = D[:, keep]
    if D.shape[0]:
        _q, sv, vt = np.linalg.svd(D, full_matrices=True)
        basis = vt[int(np.sum(sv > 1e-12 * sv[0])):].T
    else:
        basis = np.eye(int(np.count_nonzero(keep)))
    Z = np.zeros((N, basis.shape[1]))
    Z[keep] = basis
    return Z


@dataclass
class Equilibrium:
    """A KKT point of the strip on the ground, with its contacts and stability.

    Attributes
    ----------
    u : ndarray, shape (n + 1,)
        (z_0, theta_0 .. theta_{n-1}).
    energy : float
        Total energy (energy units); ``parts`` its terms.
    reactions : ndarray, shape (n + 1,)
        Ground reaction on each node (force), >= 0; 0 off contact.
    active : ndarray of bool, shape (n + 1,)
        Nodes held on the ground.
    residual : float
        Max norm of the stationarity residual over the free unknowns, of the ground
        penetration and of the contact gaps (as forces), relative to max |dE/du|.
    index : int
        Negative eigenvalues of the Lagrangian Hessian on the tangent space of the
        strongly active contacts; -1 when not computed.
    pairs : ndarray of int, shape (m, 3)
        Self-contact pairs held (i, j, sigma): node i on the side sigma of segment j
        (:func:`~elastocap.strip.model.pair_gaps`); empty without a thickness.
    pair_forces : ndarray, shape (m,)
        Their contact forces (force), >= 0.
    degenerate : int
        Contacts with z = 0 and r ~ 0 (weakly active).
    status : str
        "converged", "max_iter" or "singular"; ``success`` is status ==
        "converged"; ``message`` says what to try otherwise.
    """

    u: np.ndarray
    energy: float
    parts: dict
    reactions: np.ndarray
    active: np.ndarray
    residual: float
    iterations: int
    status: str
    message: str
    index: int = -1
    degenerate: int = 0
    pairs: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=np.int64))
    pair_forces: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def success(self) -> bool:
        return self.status == "converged"

    @property
    def contacts(self) -> int:
        return int(np.count_nonzero(self.active))


#: Penetration below which a node does not join a self-contact pair (relative to h): the
#: round-off of a distance between stacked layers (~1e-16 L) is far below, a Newton step's
#: penetration far above.
PAIR_SLACK = 1e-12


def _update_pairs(strip, u_old, u, P, mu, cpd):
    """The self-contact pairs after a Newton step (primal-dual active-set rule, as the
    ground's): a held pair stays while mu - c gap > 0; one whose form stops holding (its
    foot off its segment, :func:`~elastocap.strip.model.pair_switch`) becomes the pair that
    continues it (same force); a node of no pair that is within d of its closest tested
    segment joins: a line pair with that segment on the side of its line the node was on
    before the step, or a point pair with the segment's end node where the closest point
    is that end. One pair per node; a line pair redundant with a held one (two layers
    lying on each other: node i on segment j while a node of segment j is held on a
    segment ending at i, parallel, :func:`~elastocap.strip.model.redundant_pair`) is not
    added."""
    keep = {}
    if P.shape[0]:
        gap, region = pair_gaps(strip, u, P)
        for row, f, gv, rv in zip(P, mu, gap, region, strict=True):
            if f - cpd * gv <= 0.0:
                continue
            if rv < 0.0:
                row = pair_switch(strip, u, row)
                if row is None:
                    continue
            keep.setdefault(int(row[0]), (int(row[1]), int(row[2]), float(f)))
    jc, dist, _d, w = closest_segments(strip, u)
    # joins only when inside the tube by more than round-off: where two layers lie on each
    # other (the tail on the base), the base's nodes sit at d from the tail's segments to
    # round-off, and those pairs are redundant with the tail's (a singular KKT matrix)
    close = np.flatnonzero(dist < strip.thickness - PAIR_SLACK * strip.h)
    if close.size:
        Xo = strip.positions(u_old)
        for i in close[np.argsort(dist[close], kind="stable")]:
            j = int(jc[i])
            if int(i) in keep:
                continue
            if w[i] < 0.0 or w[i] > 1.0:
                k = j if w[i] < 0.0 else j + 1
                # not the mirror of a held point pair (two tips against each other: the
                # same gap twice, a singular KKT matrix)
                if k != i and keep.get(int(k), (-1, -1))[:2] != (int(i), 0):
                    keep[int(i)] = (k, 0, 0.0)
                continue
            if redundant_pair(u, i, j, keep):
                continue
            e = Xo[j + 1] - Xo[j]
            side = e[0] * (Xo[i, 1] - Xo[j, 1]) - e[1] * (Xo[i, 0] - Xo[j, 0])
            keep[int(i)] = (j, 1 if side >= 0.0 else -1, 0.0)
    Pn = np.array([(i, j, sg) for i, (j, sg, _f) in sorted(keep.items())],
                  dtype=np.int64).reshape(-1, 3)
    mun = np.array([max(f, 0.0) for _i, (_j, _sg, f) in sorted(keep.items())])
    return Pn, mun


def solve_equilibrium(strip: DiscreteStrip, u0, active=None, tol=1e-10,
                      max_iter=_MAX_ITER, compute_index=True, trace=None,
                      max_turn=_MAX_TURN, pairs=None) -> Equilibrium:
    """Primal-dual active-set Newton for the strip on the ground.

    Parameters
    ----------
    strip : DiscreteStrip
    u0 : ndarray, shape (n + 1,)
        Initial guess.
    active : ndarray of bool, shape (n + 1,), optional
        Initial contact set; default: the nodes with z <= 1e-12 (length).
    tol : float
        On the max norm of the stationarity residual, of the penetration and of the
        contact gap (lengths, times B / h^3 to compare as forces), relative to the largest
        generalized force |dE/du| (at least 1).
    max_iter : int
    trace : list, optional
        Receives (iteration, residual, contacts, step, alpha) per iteration.
    max_turn : float
        Newton steps turning an edge by more than this (radians) are scaled down.
    pairs : array_like of int, shape (m, 3), optional
        Initial self-contact pairs (i, j, sigma) (strip with a thickness only); default
        none. The pair set is an unknown like the ground's: a pair whose force turns
        negative leaves, a node inside the tube of its closest tested segment joins (on
        the side it was on before the step), a pair whose foot leaves its segment moves to
        the neighbouring one.

    Returns
    -------
    Equilibrium
        ``status`` "converged" only with a zero-residual KKT point with every reaction
        >= 0 and every node on or above the ground (to ``tol``); with a thickness, also
        every pair force >= 0 and every tested node-segment distance >= d (to ``tol``).
    """
    u = fix_gauge(strip, u0)
    N = strip.size
    free = np.ones(N, dtype=bool)
    free[strip.gauge] = False  # a free rod: z_0 and one angle held (translation, rotation)
    z = strip.heights(u)
    act = (z <= 1e-12) if active is None else np.array(active, dtype=bool)
    can = np.ones(N, dtype=bool)
    if not strip.ground:
        act[:] = False
        can[:] = False
    r = np.zeros(N)
    seen = {}
    # PDAS weight: a node displaced by dz meets a bending force ~ B dz / h^3
    cpd = _PDAS_C * strip.B / strip.h**3
    zscale = cpd  # penetration (length) compared as the force it would take to cause it
    status, msg, it = "max_iter", "", 0
    res = math.inf
    sc = strip.thickness > 0.0
    P = np.zeros((0, 3), dtype=np.int64) if pairs is None else \
        np.asarray(pairs, dtype=np.int64).reshape(-1, 3).copy()
    if P.size and not sc:
        raise ValueError(f"pairs: got {P.shape[0]} self-contact pairs; expected none for a "
                         "strip without a thickness (strip.thickness = 0)")
    mu = np.zeros(P.shape[0])
    for it in range(1, max_iter + 1):
        E, g, H = strip.derivatives(u)
        z = strip.heights(u)
        # Lagrangian Hessian: - sum_k r_k d^2 z_k = diag_j(h sin theta_j sum_{k > j} r_k)
        rs = np.cumsum(r[::-1])[::-1]
        W = H
        W[np.arange(1, N), np.arange(1, N)] += strip.h * np.sin(u[1:]) * rs[1:]
        A = np.flatnonzero(act)
        fi = np.flatnonzero(free)
        GA = strip.constraint_jacobian(u, A)
        Ga = GA[:, fi]
        nf, na = fi.size, A.size
        npr = P.shape[0]
        if npr:
            W -= pair_hessian(strip, u, P, mu)
            gp, _wp = pair_gaps(strip, u, P)
            Gp = pair_jacobian(strip, u, P)[:, fi]
        K = np.zeros((nf + na + npr, nf + na + npr))
        K[:nf, :nf] = W[np.ix_(fi, fi)]
        K[:nf, nf:nf + na] = Ga.T
        K[nf:nf + na, :nf] = Ga
        if npr:
            K[:nf, nf + na:] = Gp.T
            K[nf + na:, :nf] = Gp
        # solve for the change of the multipliers, not the multipliers themselves: the
        # KKT matrix is ill-conditioned (B/h^3 against q h), and a correction keeps the
        # final residual at the accuracy of its evaluation (1e-12), not of the solve (1e-9)
        rhs = np.concatenate([-(g - strip.reaction_forces(u, np.where(act, r, 0.0)))[fi],
                              -z[A]])
        if npr:
            rhs[:nf] += (Gp.T @ mu)
            rhs = np.concatenate([rhs, -gp])
        # the contact rows taken between consecutive contacts (the same solution): where
        # two neighbours are held the row has one nonzero, which factorize pivots on first
        K[nf + 1:nf + na, :nf] -= Ga[:-1]
        rhs[nf + 1:nf + na] += z[A[:-1]]
        fac = factorize(K)
        if fac is None:
            status, msg = "singular", "singular KKT matrix; try another initial contact set"
            break
        sol = fac.solve(rhs)
        du = np.zeros(N)
        du[fi] = sol[:nf]
        r_new = np.zeros(N)
        r_new[A] = r[A] - sol[nf:nf + na]
        # residual at the current point with the new multipliers: stop test
        stat = g - strip.reaction_forces(u, r_new)
        if npr:
            mu_new = mu - sol[nf + na:]
            stat[fi] -= Gp.T @ mu_new
        res = max(float(np.max(np.abs(stat[fi]))),
                  zscale * float(max(0.0, -np.min(z))) if strip.ground else 0.0,
                  zscale * float(np.max(np.abs(z[A]))) if na else 0.0)
        if sc:
            # every tested node at least d from its closest segment, the held pairs at d
            _j, dist, _d, _w = closest_segments(strip, u)
            res = max(res, zscale * float(max(0.0, strip.thickness - PAIR_SLACK * strip.h
                                                  - np.min(dist))),
                      zscale * float(np.max(np.abs(gp))) if npr else 0.0)
        # relative to the largest generalized force (q L on z_0, gamma on the wet edges):
        # the round-off floor of the residual is ~1e-11 of it
        fscale = max(1.0, float(np.max(np.abs(g))))
        res /= fscale
        ok_sign = (na == 0) or float(np.min(r_new[A])) >= -tol * fscale
        if npr:
            ok_sign = ok_sign and float(np.min(mu_new)) >= -tol * fscale
        step = float(np.max(np.abs(du[1:]))) if N > 1 else 0.0
        if res <= tol and ok_sign and step <= 1e3 * tol:
            r = r_new
            if npr:
                mu = mu_new
            status, msg = "converged", "KKT residual below tol with r >= 0"
            break
        alpha = min(1.0, max_turn / step) if step > 0.0 else 1.0
        if trace is not None:
            trace.append((it, res, na, step, alpha))
        u_old = u
        u = u + alpha * du
        r = r_new
        if sc:
            P, mu = _update_pairs(strip, u_old, u, P, mu_new if npr else mu, cpd)
        z_new = strip.heights(u)
        new_act = ((r - cpd * z_new) > 0.0) & can
        key = new_act.tobytes()
        if key in seen and seen[key] < it - 1 and not np.array_equal(new_act, act):
            # the active set cycles: change one node at a time (the worst offender)
            new_act = act.copy()
            bad_r = np.where(act, r, np.inf)
            bad_z = np.where(~act, z_new, np.inf)
            if np.min(bad_r) < 0.0:
                new_act[int(np.argmin(bad_r))] = False
            elif np.min(bad_z) < 0.0:
                new_act[int(np.argmin(bad_z))] = True
        seen[key] = it
        act = new_act
        r = np.where(act, np.maximum(r, 0.0), 0.0)
    else:
        msg = f"no convergence in {max_iter} iterations (residual {res:.3e} > tol {tol:.1e}); " \
              "start closer (continuation) or raise max_iter"
    E = strip.energy(u)
    eq = Equilibrium(
        u=u, energy=float(E), parts=strip.energy_parts(u), reactions=r, active=act,
        residual=float(res), iterations=it, status=status, message=msg,
    )
    if sc:
        eq.pairs, eq.pair_forces = P, mu
    if eq.success and compute_index:
        eq.index, eq.degenerate = stability(strip, eq)
    return eq


def stability(strip: DiscreteStrip, eq: Equilibrium) -> tuple[int, int]:
    """(index, degenerate contacts) of an equilibrium.

    The index is the number of negative eigenvalues of the Lagrangian Hessian restricted to
    the free unknowns tangent to the strongly active contacts (r_k > R_REL q h).
    """
    H = lagrangian_hessian(strip, eq.u, eq.reactions, eq.pairs, eq.pair_forces)
    strong, weak = _strong_weak(strip, eq)
    Z = _tangent_basis(strip, eq.u, strong)
    nweak = int(np.count_nonzero(weak))
    if len(eq.pairs):
        pstrong = eq.pair_forces > R_REL * strip.q * strip.h
        Z = _with_pairs(strip, eq.u, Z, eq.pairs[pstrong])
        nweak += int(np.count_nonzero(~pstrong))
    on = np.flatnonzero(np.any(Z != 0.0, axis=1))  # the unknowns the contacts leave free
    Hr = Z[on].T @ H[np.ix_(on, on)] @ Z[on]
    if Hr.shape[0] == 0:  # the contacts fix every unknown (the flat strip)
        return 0, nweak
    ev = np.linalg.eigvalsh(0.5 * (Hr + Hr.T))
    # eigenvalues at round-off level of the largest count as zero, not negative
    neg = int(np.sum(ev < -1e-10 * max(1.0, float(np.max(np.abs(ev))))))
    return neg, nweak


def _penalty(strip, u, k):
    """Energy plus (k/2) sum min(z, 0)^2, its gradient and Hessian (the descent phase);
    a free rod: the energy, its gradient and Hessian with the gauge's rows and columns
    zero but a unit diagonal (so that the descent does not move them)."""
    E, g, H = strip.derivatives(u)
    if not strip.ground:
        gi = strip.gauge
        g[gi] = 0.0
        H[gi, :] = 0.0
        H[:, gi] = 0.0
        H[gi, gi] = 1.0
        return E, g, H
    z = strip.heights(u)
    pen = np.minimum(z, 0.0)
    neg = np.flatnonzero(pen < 0.0)
    if neg.size:
        G = strip.constraint_jacobian(u, neg)  # the rows of the penetrating nodes alone
        E += 0.5 * k * float(pen[neg] @ pen[neg])
        g = g + k * (G.T @ pen[neg])
        H = H + k * (G.T @ G)
        # k z_k d^2 z_k: diag_j (-h sin theta_j) summed over the penetrating k > j
        w = np.zeros(strip.size)
        w[neg] = k * pen[neg]
        ws = np.cumsum(w[::-1])[::-1]
        N = strip.size
        H[np.arange(1, N), np.arange(1, N)] += -strip.h * np.sin(u[1:]) * ws[1:]
    return E, g, H


class _Tridiagonal:
    """H = Q T Q^T (LAPACK dsytrd, lower storage): T's diagonal and off-diagonal, its
    smallest and largest eigenvalues (bisection, LAPACK stebz), and Q as its Householder
    reflectors (applied to vectors in O(n^2), :func:`_reflect`). The reduction is the part
    of an eigen-decomposition the trust-region subproblem needs: 0.58 ms against 3.25 ms
    for ``numpy.linalg.eigh`` at n = 199, 1.5 ms against 7.8 ms at 298 (one BLAS thread)."""

    __slots__ = ("a", "tau", "d", "e", "lo", "hi")

    def __init__(self, H):
        n = H.shape[0]
        # H is symmetric: its transpose is the Fortran-ordered array LAPACK works in
        a, d, e, tau, info = _sytrd(np.array(H.T, order="F"), lower=1, lwork=_sytrd_work(n),
                                    overwrite_a=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"dsytrd: info = {info}")
        self.a, self.tau, self.d, self.e = a, tau, d, e
        if n == 1:
            self.lo = self.hi = float(d[0])
        else:
            self.lo = float(eigvalsh_tridiagonal(d, e, select="i", select_range=(0, 0))[0])
            self.hi = float(eigvalsh_tridiagonal(d, e, select="i",
                                                 select_range=(n - 1, n - 1))[0])

    def lowest_vector(self) -> np.ndarray:
        """T's eigenvector of its smallest eigenvalue (unit norm)."""
        if self.d.size == 1:
            return np.ones(1)
        return eigh_tridiagonal(self.d, self.e, select="i", select_range=(0, 0))[1][:, 0]


@functools.cache
def _sytrd_work(n: int) -> int:
    """dsytrd's optimal workspace for size n (LAPACK's query)."""
    return max(1, int(_sytrd_lwork(n, lower=1)[0]))


@numba.njit(cache=True)
def _reflect(a, tau, x, transpose):
    """Q^T x (``transpose``) or Q x, Q = H(0) H(1) ... H(n-2) from dsytrd's lower storage:
    H(i) = I - tau_i v v^T, v = (0, ..., 0, 1, a[i+2:, i]) with the 1 at i + 1."""
    n = x.size
    y = x.copy()
    for k in range(n - 1):
        i = k if transpose else n - 2 - k
        t = tau[i]
        if t == 0.0:
            continue
        s = y[i + 1]
        for j in range(i + 2, n):
            s += a[j, i] * y[j]
        s *= t
        y[i + 1] -= s
        for j in range(i + 2, n):
            y[j] -= s * a[j, i]
    return y


@numba.njit(cache=True)
def _shifted_solve(d, e, mu, b):
    """x with (T + mu I) x = b, T = tridiag(e, d, e), by LDL^T without pivoting; and
    whether T + mu I is positive definite (every pivot > 0; else x is meaningless)."""
    n = d.size
    piv = np.empty(n)
    m = np.empty(max(n - 1, 0))
    x = b.copy()
    piv[0] = d[0] + mu
    if not piv[0] > 0.0:
        return x, False
    for i in range(n - 1):
        m[i] = e[i] / piv[i]
        piv[i + 1] = d[i + 1] + mu - m[i] * e[i]
        if not piv[i + 1] > 0.0:
            return x, False
        x[i + 1] -= m[i] * x[i]
    for i in range(n):
        x[i] /= piv[i]
    for i in range(n - 2, -1, -1):
        x[i] -= m[i] * x[i + 1]
    return x, True


@numba.njit(cache=True)
def _tridiagonal_product(d, e, w):
    y = d * w
    y[:-1] += e * w[1:]
    y[1:] += e * w[:-1]
    return y


@numba.njit(cache=True)
def _boundary_multiplier(d, e, c, lo, hi, radius):
    """(mu, w, |w|, ok, inside): the More-Sorensen Newton iteration on the concave,
    increasing phi(mu) = 1 / |w(mu)| - 1 / radius, w(mu) = (T + mu I)^{-1} c, from just
    above the pole mu = max(0, -lo) (phi' = w.(T + mu I)^{-1} w / |w|^3); ok False where
    T + mu I is not positive definite in the arithmetic at the start (the shift raised
    tenfold, ten times); inside: |w| <= radius at the pole already (no iteration)."""
    mu0 = max(0.0, -lo)
    tiny = 1e-12 * max(1.0, abs(lo), hi)
    ok = False
    w = c.copy()
    mu = mu0
    for k in range(10):
        mu = mu0 + tiny * 10.0**k
        w, ok = _shifted_solve(d, e, mu, c)
        if ok:
            break
    if not ok:
        return mu, w, 0.0, False, False
    nw = math.sqrt(float(np.sum(w * w)))
    if nw <= radius:
        return mu, w, nw, True, True
    for _ in range(100):
        phi = 1.0 / nw - 1.0 / radius
        if abs(phi) <= 1e-10 / radius:
            break
        q, ok = _shifted_solve(d, e, mu, w)
        if not ok:
            return mu, w, nw, False, False
        dphi = float(np.sum(w * q)) / nw**3
        mu -= phi / dphi
        w, ok = _shifted_solve(d, e, mu, c)
        if not ok:
            return mu, w, nw, False, False
        nw = math.sqrt(float(np.sum(w * w)))
    return mu, w, nw, True, False


def _trust_step(T: _Tridiagonal, g, radius):
    """The exact trust-region step (More & Sorensen 1983) on the tridiagonal reduction
    H = Q T Q^T (:class:`_Tridiagonal`): d = argmin g.d + d.H d / 2 over |d| <= radius,
    solved for w = -Q^T d on T (Q is orthogonal: the same problem, with tridiagonal solves
    in place of an eigen-decomposition). Returns (d, the model decrease, whether d is on
    the boundary)."""
    c = _reflect(T.a, T.tau, np.asarray(g, dtype=float), True)
    if T.lo > 0.0:
        w, ok = _shifted_solve(T.d, T.e, 0.0, c)
        if ok and float(np.linalg.norm(w)) <= radius:
            pred = float(c @ w - 0.5 * w @ _tridiagonal_product(T.d, T.e, w))
            return -_reflect(T.a, T.tau, w, False), pred, False
    _mu, w, nw, ok, inside = _boundary_multiplier(T.d, T.e, c, T.lo, T.hi, radius)
    if not ok:
        raise np.linalg.LinAlgError(
            f"the trust-region subproblem: T + mu I not positive definite at mu = {_mu:.3e} "
            f"(smallest eigenvalue {T.lo:.3e})")
    if inside and T.lo < 0.0:
        # hard case: g has (almost) no component along the lowest mode z; go along it to
        # the boundary
        z = T.lowest_vector()
        w = w - float(z @ w) * z
        w = w + math.sqrt(max(radius**2 - float(w @ w), 0.0)) * z
    pred = float(c @ w - 0.5 * w @ _tridiagonal_product(T.d, T.e, w))
    return -_reflect(T.a, T.tau, w, False), pred, True


def minimize_energy(strip: DiscreteStrip, u0, tol=1e-10, max_iter=500,
                    penalty: float = PENALTY) -> Equilibrium:
    """A local minimum of the energy on z >= 0, reached by descent from ``u0``.

    With a thickness the descent runs without self-contact and its minimum is made a
    contact equilibrium (the nodes inside another part's tube get pairs,
    :func:`contact_pairs_of`): a descent may pass the strip through itself on the way.

    Phase 1: trust-region Newton with the exact Hessian (the subproblem solved exactly on
    its tridiagonal reduction, More & Sorensen 1983: radius 1 to start, as scipy's
    ``trust-exact``) on the energy plus an exterior penalty (k/2) sum min(z_k, 0)^2,
    k = ``penalty`` B / h^3: the energy falls at every accepted step, so the descent cannot jump
    over a barrier the way a Newton iteration can. Phase 2: the active-set Newton
    :func:`solve_equilibrium` from the penalty minimum, with the penetrating nodes as the
    initial contacts, makes it an exact KKT point.
    """
    if strip.thickness > 0.0:
        # descent without self-contact (its penalty knows the ground only), then contact
        return with_self_contact(strip, minimize_energy(strip.with_(thickness=0.0), u0, tol,
                                                         max_iter, penalty), tol)
    u = fix_gauge(strip, u0)
    # PENALTY B / h^3: the penetration r / k is ~1e-5 (r ~ q h), close enough for the
    # polish to start on the right contact set
    k = float(penalty) * strip.B / strip.h**3
    E, g, H = _penalty(strip, u, k)
    radius = 1.0
    tri = None  # the tridiagonal reduction of H, kept while a rejected step leaves H as it is
    stopped = "the trust region's radius below 1e-14 rad"
    for _ in range(max_iter):
        if float(np.linalg.norm(g)) <= _DESCENT_GTOL:
            stopped = None
            break
        if tri is None:
            tri = _Tridiagonal(0.5 * (H + H.T))
        try:
            d, pred, boundary = _trust_step(tri, g, radius)
        except np.linalg.LinAlgError as err:
            stopped = f"a trust-region subproblem it could not solve ({err})"
            break
        E1, g1, H1 = _penalty(strip, u + d, k)
        rho = (E - E1) / pred if pred > 0.0 else -1.0
        if rho < 0.25:
            radius *= 0.25
        elif rho > 0.75 and boundary:
            radius = min(2.0 * radius, 1e3)
        if rho > 0.15:
            u, E, g, H = u + d, E1, g1, H1
            tri = None
        if radius < 1e-14:
            break
    else:
        stopped = f"max_iter = {max_iter} trust-region iterations"
    z = strip.heights(u)
    # contacts: penetrating, or within the penalty's reach of the ground
    act = z <= 1e-9
    eq = solve_equilibrium(strip, u, active=act, tol=tol)
    if not eq.success and stopped is not None:
        eq.message = (f"the descent stopped at {stopped} with |grad E| = "
                      f"{float(np.linalg.norm(g)):.3e} > {_DESCENT_GTOL:g} (n = {strip.n}; "
                      f"descend from a coarser strip, descend_coarse_to_fine, or raise "
                      f"max_iter), and the active-set Newton from there failed: "
                      f"{eq.message}")
    return eq


def contact_pairs_of(strip: DiscreteStrip, u) -> np.ndarray:
    """Self-contact pairs (m, 3) for the nodes of ``u`` inside the tube of their closest
    tested segment (a state computed without contact, e.g. the hairpin whose tail lies
    on or through the base): a point pair with the segment's end node where the closest
    point is that end, else a line pair on the side of the segment's line where the
    node's neighbours along the strip lie (the node itself may lie on the line, as the
    tail's tip resting on the ground on the base does; a whole layer on the line rests on
    its upper side). Only nodes nearer the free end than their segment are paired (the
    free end's layer rests on the other: the pairs the other way are redundant with it
    where the layers are parallel, :func:`~elastocap.strip.model.redundant_pair`, and their
    side is ill-defined where the state without contact has the layers through each
    other); the active-set Newton method adds any that end inside a tube."""
    jc, dist, _d, w = closest_segments(strip, u)
    X = strip.positions(u)
    held = {}
    # nodes nearer the free end first: where two layers lie on each other (the tail on the
    # base, both on the ground without contact) the free end's layer rests on the other,
    # and the pairs the other way are redundant with it (redundant_pair)
    for i in np.flatnonzero(dist < strip.thickness)[::-1]:
        j = int(jc[i])
        if j > i:
            # the layer nearer the free end rests on the other: its nodes are paired, the
            # other's nodes only by the active-set Newton method if they end inside a tube
            continue
        if w[i] < 0.0 or w[i] > 1.0:
            held[int(i)] = (j if w[i] < 0.0 else j + 1, 0)
            continue
        if redundant_pair(u, i, j, held):
            continue
        e = X[j + 1] - X[j]
        nb = [k for k in (i - 1, i + 1) if 0 <= k <= strip.n]
        side = sum(e[0] * (X[k, 1] - X[j, 1]) - e[1] * (X[k, 0] - X[j, 0]) for k in nb)
        if side == 0.0:  # a layer on the segment's line: it rests on the upper side
            side = e[0]
        held[int(i)] = (j, 1 if side >= 0.0 else -1)
    return np.array([(i, *held[i]) for i in sorted(held)], dtype=np.int64).reshape(-1, 3)


def with_self_contact(strip: DiscreteStrip, eq: Equilibrium, tol=1e-10) -> Equilibrium:
    """An equilibrium without self-contact (``eq``, e.g. of ``strip.with_(thickness=0)``)
    made one of ``strip`` with its thickness: the nodes in another part's tube get pairs
    (:func:`contact_pairs_of`) and leave the ground (a tail node resting on the base rests
    on it, not on the ground), then continuation in the thickness (d / 64, d / 16,
    2 d / 16, ..., d), each step by the active-set Newton method."""
    if not eq.success:
        return eq
    # continuation in the thickness: d / 64, then d / 16, 2 d / 16, ..., d. The state
    # without contact has its layers on (or through) each other, and Newton from it with
    # the full d swung the tail through the base (n = 286, 429 at x = 3, Delta = 1.2:
    # "singular", pairs all along the strip); at d / 64 only the nodes inside the thin tube
    # get pairs (contact_pairs_of), and from there each solve moves the layers by d / 16
    # at most, its own active-set rule adding and releasing pairs (pairing every node
    # inside the full tube at once forced the tail's end flat on the base: Newton cycled)
    act = eq.active.copy()
    P = contact_pairs_of(strip.with_(thickness=strip.thickness / 64), eq.u)
    act[P[:, 0]] = False
    for f in (1 / 64, *np.arange(1, _THICKNESS_STEPS + 1) / _THICKNESS_STEPS):
        eq = solve_equilibrium(strip.with_(thickness=strip.thickness * f), eq.u,
                               active=act, tol=tol, pairs=P)
        if not eq.success:
            break
        act, P = eq.active, eq.pairs
    if eq.success:
        eq = solve_equilibrium(strip, eq.u, active=act, tol=tol, pairs=P)  # this strip's
    return eq


def prolong(coarse: DiscreteStrip, u, fine: DiscreteStrip) -> np.ndarray:
    """A state of ``coarse`` carried to the edges of ``fine`` (same strip, other n).

    The edge angles are interpolated linearly in arclength between the mid-edge points
    (constant beyond the first and last), z_0 is kept; the result is a starting point for
    :func:`solve_equilibrium` at the finer resolution (coarse-to-fine continuation: the
    equilibrium, saddles included, keeps its identity, which a new search would not
    guarantee).
    """
    s_c = (np.arange(coarse.n) + 0.5) * coarse.h
    s_f = (np.arange(fine.n) + 0.5) * fine.h
    return np.concatenate([[u[0]], np.interp(s_f, s_c, np.asarray(u[1:]))])


def refine(coarse: DiscreteStrip, eq: Equilibrium, fine: DiscreteStrip,
           tol=1e-10, _depth=0) -> Equilibrium:
    """The equilibrium ``eq`` of ``coarse`` continued to ``fine`` by Newton from
    :func:`prolong` (contacts: the fine nodes within h^2 of the ground there); again with
    short steps if that does not give a converged state of the same index, then through
    an intermediate resolution (at most twice)."""
    u = prolong(coarse, eq.u, fine)
    z = fine.heights(u)
    out = solve_equilibrium(fine, u, active=z <= fine.h**2, tol=tol)
    if not (out.success and out.index == eq.index):
        # short steps: full Newton steps from the prolongation left the saddle's basin at
        # x = 3, Delta = 0.8 and 1.2 (n = 143 -> 429); 0.05 rad steps stay in it
        out = solve_equilibrium(fine, u, active=z <= fine.h**2, tol=tol, max_turn=_SHORT_TURN,
                                max_iter=_SHORT_ITER)
    mid = (coarse.n + fine.n) // 2
    if not (out.success and out.index == eq.index) and _depth < 2 and coarse.n < mid < fine.n:
        m = refine(coarse, eq, fine.with_(n=mid), tol, _depth + 1)
        if m.success and m.index == eq.index:
            out = refine(fine.with_(n=mid), m, fine, tol, _depth + 1)
    return out


def descend_coarse_to_fine(strip: DiscreteStrip, start) -> Equilibrium:
    """The minimum reached by descent from ``start(strip)``, found on coarser strips first.

    Above ``DESCENT_COARSE_N`` edges the descent runs on the strip with half the edges
    (recursively), and its minimum, carried to this strip by :func:`prolong`, starts the
    descent here; the basin is chosen on a strip of at most ``DESCENT_COARSE_N`` edges.
    The descent's iterations grow with n from a start far from the minimum (the ground
    penalty stiffens as 1 / h^3 and the trust region shrinks at each node that reaches the
    ground; x = 3, Delta = 1.2, from the flat strip: 492 iterations at n = 429, 1207 at
    n = 572), and from a prolonged minimum they do not. ``start`` is a function of the
    strip giving its starting u (as :func:`~elastocap.strip.model.flat_state`). Where
    the coarser strip gives no minimum (its descent's polish can fail where the fine one's
    does not: x = 4, Delta = 1.2 at n = 107), the descent runs from ``start`` here.
    """
    if strip.n > DESCENT_COARSE_N:
        coarse = strip.with_(n=strip.n // 2)
        eq = descend_coarse_to_fine(coarse, start)
        if eq.success:
            eq = minimize_energy(strip, prolong(coarse, eq.u, strip))
            if eq.success:
                return eq
        # no minimum on the coarser strip (or none from its prolongation): the descent
        # from the start on this one
    return minimize_energy(strip, start(strip))


def open_state(strip: DiscreteStrip) -> Equilibrium:
    """The state reached by descent from the flat strip (a quasi-static deposition;
    :func:`descend_coarse_to_fine`)."""
    return descend_coarse_to_fine(strip, flat_state)


def _half_circle(strip: DiscreteStrip) -> np.ndarray:
    s = (np.arange(strip.n) + 0.5) * strip.h
    th = math.pi * np.clip((s - strip.s1) / (strip.s2 - strip.s1), 0.0, 1.0)
    return np.concatenate([[0.0], th])


def wrapped_state(strip: DiscreteStrip) -> Equilibrium:
    """The state reached by descent from the strip folded over the drop
    (:func:`descend_coarse_to_fine`).

    Seed: flat up to S1, turning by pi at a constant rate over the wet part [S1, S2] (a
    half-circle around the drop), the tail straight back over the drop.
    """
    return descend_coarse_to_fine(strip, _half_circle)


def unstable_mode(strip: DiscreteStrip, eq: Equilibrium) -> np.ndarray:
    """Eigenvector of the most negative eigenvalue of the Lagrangian Hessian on the
    tangent space of the strongly active contacts (shape (n + 1,), unit max norm)."""
    H = lagrangian_hessian(strip, eq.u, eq.reactions, eq.pairs, eq.pair_forces)
    Z = _tangent_basis(strip, eq.u, np.flatnonzero(_strong_weak(strip, eq)[0]))
    if len(eq.pairs):
        Z = _with_pairs(strip, eq.u, Z,
                        eq.pairs[eq.pair_forces > R_REL * strip.q * strip.h])
    _ev, V = np.linalg.eigh(Z.T @ H @ Z)
    v = Z @ V[:, 0]
    return v / np.max(np.abs(v))


def descend_from_saddle(strip: DiscreteStrip, saddle: Equilibrium, push=_PUSH):
    """The two minima reached by descent from the saddle pushed along +-(unstable mode)."""
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
