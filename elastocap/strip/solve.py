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

import math
from dataclasses import dataclass

import numpy as np

from continuation import factorize
from elastocap.strip.model import DiscreteStrip, flat_state

__all__ = [
    "Equilibrium",
    "R_REL",
    "descend_from_saddle",
    "lagrangian_hessian",
    "minimize_energy",
    "open_state",
    "prolong",
    "refine",
    "solve_equilibrium",
    "stability",
    "unstable_mode",
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
# Push off the saddle along its unstable mode before each descent (radians, max norm of
# the displacement): large enough for the descent to leave the saddle's neighbourhood at
# once, small next to the distance to either minimum (~1-3 rad in the tail angles).
_PUSH = 0.02


def lagrangian_hessian(strip: DiscreteStrip, u, r) -> np.ndarray:
    """Hessian of E - sum_k r_k z_k in u, shape (n + 1, n + 1).

    - sum_k r_k d^2 z_k / du^2 = diag_j(h sin theta_j sum_{k > j} r_k).
    """
    N = strip.size
    H = strip.hessian(u)
    rs = np.cumsum(np.asarray(r)[::-1])[::-1]
    H[np.arange(1, N), np.arange(1, N)] += strip.h * np.sin(u[1:]) * rs[1:]
    return H


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
        return np.eye(N)
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

    @property
    def success(self) -> bool:
        return self.status == "converged"

    @property
    def contacts(self) -> int:
        return int(np.count_nonzero(self.active))


def solve_equilibrium(strip: DiscreteStrip, u0, active=None, tol=1e-10,
                      max_iter=_MAX_ITER, compute_index=True, trace=None,
                      max_turn=_MAX_TURN) -> Equilibrium:
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

    Returns
    -------
    Equilibrium
        ``status`` "converged" only with a zero-residual KKT point with every reaction
        >= 0 and every node on or above the ground (to ``tol``).
    """
    u = np.array(u0, dtype=float)
    N = strip.size
    free = np.ones(N, dtype=bool)
    z = strip.heights(u)
    act = (z <= 1e-12) if active is None else np.array(active, dtype=bool)
    can = np.ones(N, dtype=bool)
    r = np.zeros(N)
    seen = {}
    # PDAS weight: a node displaced by dz meets a bending force ~ B dz / h^3
    cpd = _PDAS_C * strip.B / strip.h**3
    zscale = cpd  # penetration (length) compared as the force it would take to cause it
    status, msg, it = "max_iter", "", 0
    res = math.inf
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
        K = np.zeros((nf + na, nf + na))
        K[:nf, :nf] = W[np.ix_(fi, fi)]
        K[:nf, nf:] = Ga.T
        K[nf:, :nf] = Ga
        # solve for the change of the multipliers, not the multipliers themselves: the
        # KKT matrix is ill-conditioned (B/h^3 against q h), and a correction keeps the
        # final residual at the accuracy of its evaluation (1e-12), not of the solve (1e-9)
        rhs = np.concatenate([-(g - strip.reaction_forces(u, np.where(act, r, 0.0)))[fi],
                              -z[A]])
        # the contact rows taken between consecutive contacts (the same solution): where
        # two neighbours are held the row has one nonzero, which factorize pivots on first
        K[nf + 1:, :nf] -= Ga[:-1]
        rhs[nf + 1:] += z[A[:-1]]
        fac = factorize(K)
        if fac is None:
            status, msg = "singular", "singular KKT matrix; try another initial contact set"
            break
        sol = fac.solve(rhs)
        du = np.zeros(N)
        du[fi] = sol[:nf]
        r_new = np.zeros(N)
        r_new[A] = r[A] - sol[nf:]
        # residual at the current point with the new multipliers: stop test
        stat = g - strip.reaction_forces(u, r_new)
        res = max(float(np.max(np.abs(stat[fi]))), zscale * float(max(0.0, -np.min(z))),
                  zscale * float(np.max(np.abs(z[A]))) if na else 0.0)
        # relative to the largest generalized force (q L on z_0, gamma on the wet edges):
        # the round-off floor of the residual is ~1e-11 of it
        fscale = max(1.0, float(np.max(np.abs(g))))
        res /= fscale
        ok_sign = (na == 0) or float(np.min(r_new[A])) >= -tol * fscale
        step = float(np.max(np.abs(du[1:]))) if N > 1 else 0.0
        if res <= tol and ok_sign and step <= 1e3 * tol:
            r = r_new
            status, msg = "converged", "KKT residual below tol with r >= 0"
            break
        alpha = min(1.0, max_turn / step) if step > 0.0 else 1.0
        if trace is not None:
            trace.append((it, res, na, step, alpha))
        u = u + alpha * du
        r = r_new
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
    if eq.success and compute_index:
        eq.index, eq.degenerate = stability(strip, eq)
    return eq


def stability(strip: DiscreteStrip, eq: Equilibrium) -> tuple[int, int]:
    """(index, degenerate contacts) of an equilibrium.

    The index is the number of negative eigenvalues of the Lagrangian Hessian restricted to
    the free unknowns tangent to the strongly active contacts (r_k > R_REL q h).
    """
    H = lagrangian_hessian(strip, eq.u, eq.reactions)
    strong, weak = _strong_weak(strip, eq)
    Z = _tangent_basis(strip, eq.u, strong)
    on = np.flatnonzero(np.any(Z != 0.0, axis=1))  # the unknowns the contacts leave free
    Hr = Z[on].T @ H[np.ix_(on, on)] @ Z[on]
    if Hr.shape[0] == 0:  # the contacts fix every unknown (the flat strip)
        return 0, int(np.count_nonzero(weak))
    ev = np.linalg.eigvalsh(0.5 * (Hr + Hr.T))
    # eigenvalues at round-off level of the largest count as zero, not negative
    neg = int(np.sum(ev < -1e-10 * max(1.0, float(np.max(np.abs(ev))))))
    return neg, int(np.count_nonzero(weak))


def _penalty(strip, u, k):
    """Energy plus (k/2) sum min(z, 0)^2, its gradient and Hessian (the descent phase)."""
    E, g, H = strip.derivatives(u)
    z = strip.heights(u)
    pen = np.minimum(z, 0.0)
    neg = np.flatnonzero(pen < 0.0)
    if neg.size:
        G = strip.constraint_jacobian(u)[neg]
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


def _trust_step(lam, V, g, radius):
    """The exact trust-region step (More & Sorensen 1983) on the eigen-decomposition
    H = V diag(lam) V^T (lam ascending): d = argmin g.d + d.H d / 2 over |d| <= radius.
    Returns (d, the model decrease, whether d is on the boundary)."""
    c = V.T @ g
    lo = float(lam[0])
    if lo > 0.0:
        w = c / lam
        if float(np.linalg.norm(w)) <= radius:
            return -(V @ w), float(c @ w - 0.5 * w @ (lam * w)), False
    # mu > max(0, -lo) with |c / (lam + mu)| = radius: Newton on the concave, increasing
    # phi(mu) = 1 / |w(mu)| - 1 / radius (More & Sorensen), from just above the pole
    mu = max(0.0, -lo)
    mu += 1e-12 * max(1.0, abs(lo), float(lam[-1]))
    w = c / (lam + mu)
    nw = float(np.linalg.norm(w))
    if nw > radius:
        for _ in range(100):
            phi = 1.0 / nw - 1.0 / radius
            if abs(phi) <= 1e-10 / radius:
                break
            dphi = float(np.sum(w * w / (lam + mu))) / nw**3
            mu -= phi / dphi
            w = c / (lam + mu)
            nw = float(np.linalg.norm(w))
    elif lo < 0.0:
        # hard case: g has (almost) no component along the lowest mode; go along it to the
        # boundary
        w = w.copy()
        w[0] = math.sqrt(max(radius**2 - float(w[1:] @ w[1:]), 0.0))
    pred = float(c @ w - 0.5 * w @ (lam * w))
    return -(V @ w), pred, True


def minimize_energy(strip: DiscreteStrip, u0, tol=1e-10, max_iter=500) -> Equilibrium:
    """A local minimum of the energy on z >= 0, reached by descent from ``u0``.

    Phase 1: trust-region Newton with the exact Hessian (the subproblem solved exactly on
    its eigen-decomposition, More & Sorensen 1983; radius 1 to start, as scipy's
    ``trust-exact``) on the energy plus an exterior penalty (k/2) sum min(z_k, 0)^2,
    k = 10 B / h^3: the energy falls at every accepted step, so the descent cannot jump
    over a barrier the way a Newton iteration can. Phase 2: the active-set Newton
    :func:`solve_equilibrium` from the penalty minimum, with the penetrating nodes as the
    initial contacts, makes it an exact KKT point.
    """
    u = np.array(u0, dtype=float)
    # 10 B / h^3: the penetration r / k is ~1e-5 (r ~ q h), close enough for the polish to
    # start on the right contact set; measured at n = 100, x = 4, Delta = 1.1: 57 trust
    # iterations against 461 with 1e3 B / h^3, same polished state
    k = 10.0 * strip.B / strip.h**3
    E, g, H = _penalty(strip, u, k)
    radius = 1.0
    eig = None  # the eigen-decomposition of H, kept while a rejected step leaves H as it is
    for _ in range(max_iter):
        if float(np.linalg.norm(g)) <= _DESCENT_GTOL:
            break
        if eig is None:
            eig = np.linalg.eigh(0.5 * (H + H.T))
        d, pred, boundary = _trust_step(eig[0], eig[1], g, radius)
        E1, g1, H1 = _penalty(strip, u + d, k)
        rho = (E - E1) / pred if pred > 0.0 else -1.0
        if rho < 0.25:
            radius *= 0.25
        elif rho > 0.75 and boundary:
            radius = min(2.0 * radius, 1e3)
        if rho > 0.15:
            u, E, g, H = u + d, E1, g1, H1
            eig = None
        if radius < 1e-14:
            break
    z = strip.heights(u)
    # contacts: penetrating, or within the penalty's reach of the ground
    act = z <= 1e-9
    return solve_equilibrium(strip, u, active=act, tol=tol)


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


def open_state(strip: DiscreteStrip) -> Equilibrium:
    """The state reached by descent from the flat strip (a quasi-static deposition)."""
    return minimize_energy(strip, flat_state(strip))


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
    H = lagrangian_hessian(strip, eq.u, eq.reactions)
    Z = _tangent_basis(strip, eq.u, np.flatnonzero(_strong_weak(strip, eq)[0]))
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
