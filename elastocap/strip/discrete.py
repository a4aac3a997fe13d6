"""Discrete statics of the strip of Fig 3 on a frictionless ground, any contact topology.

The spectral :class:`~elastocap.strip.problem.StripProblem` handles one contact topology
(flat on [0, s_c], lifted beyond). The open state (drop resting on the flat strip), the
floppy states (the tail landing again), the rolled states and the saddles between them
touch the ground in other ways. Here the ground is an inequality constraint at every node
and the contact set is an unknown, so one solver covers them all.

Model (paper, main text eq. [1]; the discrete energy of the ``dynamics`` package)
---------------------------------------------------------------------------------
The strip [0, L] is a polyline of n edges of length h = L / n. Unknowns
u = (z_0, theta_0, ..., theta_{n-1}): the height of node 0 and the edge angles (from +x
towards +z). Node k sits at

    x_k = h sum_{j<k} cos theta_j,     z_k = z_0 + h sum_{j<k} sin theta_j,

so inextensibility is exact; x_0 = 0 fixes the horizontal translation, which the
frictionless ground leaves free (no zero mode). The energy is, term for term, the
potential energy of a damped run of :func:`elastocap.impact.run_impact` at the same
resolution (``dynamics.bending``, ``dynamics.effects.Gravity`` with lumped masses,
``elastocap.capillary``), so an equilibrium here is an equilibrium of the dynamic model:

* bending, Discrete Elastic Rods (Bergou et al. 2008): kb_i = 2 tan(psi_i / 2) with
  psi_i = theta_i - theta_{i-1} the turning angle at interior node i, and
  E_b = sum_i B kb_i^2 / (2 h) = (2B/h) sum_i tan^2(psi_i / 2);
* gravity, lumped masses q h (q h / 2 at the ends): E_g = q h sum_edges z_mid
  = q L z_0 + q h sum_j (L - s_j) sin theta_j with s_j the mid-edge arclength;
* capillarity: gamma lambda of the circular cap of area A pinned at S1 = L - x - Delta/2
  and S2 = L - x + Delta/2 (inside edges, linear interpolation), from
  :func:`elastocap.drop.capillary_energy_and_gradient` (exact gradient); its exact
  Hessian is assembled here from the same cap kernels (:func:`capillary_hessian_nodes`);
* optionally a vertical point force F at the free end: E_F = -F z_n (closed-form tests).

Ground: z_k >= 0 at every node k = 0..n, frictionless (a vertical reaction r_k >= 0 at
node k, force units). Equilibria are the KKT points of

    grad E(u) = sum_k r_k grad z_k(u),   z_k >= 0,   r_k >= 0,   r_k z_k = 0,

solved by a primal-dual active-set Newton method (semismooth Newton on
min(r_k, c z_k) = 0; Hintermueller, Ito & Kunisch 2002) with the exact Hessian of the
Lagrangian E - sum r_k z_k. An equilibrium with a negative reaction is not one (the node
would lift off): the solver never returns one as converged.

Stability: the inertia of the Lagrangian Hessian on the tangent space of the strongly
active contacts (r_k > 0): the number of negative eigenvalues is the stability index
(0: a stable state; 1: a saddle). A contact with r_k = 0 (weakly active) is reported
(``degenerate``) since the second-order test is then on a cone, not a space.

Optionally some unknowns are held fixed (e.g. the tip angle theta_{n-1} for the
least-energy path in :mod:`elastocap.strip.mep`); the residual of a held unknown is then
the generalized force needed to hold it (for theta_{n-1}: the couple C applied to the
last edge, dE/dtheta_{n-1}).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np

from elastocap.drop import (
    _locate,
    cap_geometry,
    cap_tau_derivatives,
    capillary_energy_and_gradient,
    wet_polygon_area,
)

__all__ = [
    "DiscreteStrip",
    "Equilibrium",
    "capillary_hessian_nodes",
    "discrete_strip_for",
    "flat_state",
    "minimize_energy",
    "prolong",
    "refine",
    "solve_equilibrium",
    "stability",
]

# PDAS scaling c in min(r, c z): r is a force (~ q h per node) and z a length; c = B / h^3
# is the stiffness of one node pushed by a force against its bending neighbours, so that
# both arguments are of the same size. (For the linear obstacle problem any c > 0 gives the
# same iterates once the active set is right; c only affects the first steps.)
_PDAS_C = 1.0
# A Newton step that turns an edge angle by more than this is scaled down (radians): the
# unknowns are angles, and beyond ~0.5 rad the linearization of sin/cos is poor.
_MAX_TURN = 0.5
# Multipliers below this fraction of the node weight q h count as zero when classifying
# contacts (strongly active / weakly active); the default Newton tolerance is far below.
_R_REL = 1e-7
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


# --------------------------------------------------------------------------- kernels
@numba.njit(cache=True)
def _bending(theta, B, h, grad, hdiag, hoff):
    """DER bending energy in edge angles; ADDS the gradient and the tridiagonal Hessian.

    E_b = (2B/h) sum_i tan^2((theta_i - theta_{i-1}) / 2). Hand-written (not the node-based
    ``dynamics.bending`` kernel) because the angle form gives the Hessian in closed form:
    f(psi) = (2B/h) t^2, f' = (2B/h) t (1 + t^2), f'' = (B/h)(1 + t^2)(1 + 3 t^2).
    ``grad``, ``hdiag`` have length n (angles), ``hoff`` length n - 1.
    """
    n = theta.shape[0]
    E = 0.0
    a = 2.0 * B / h
    for i in range(1, n):
        t = math.tan(0.5 * (theta[i] - theta[i - 1]))
        t2 = t * t
        E += a * t2
        g = a * t * (1.0 + t2)
        grad[i] += g
        grad[i - 1] -= g
        k = (B / h) * (1.0 + t2) * (1.0 + 3.0 * t2)
        hdiag[i] += k
        hdiag[i - 1] += k
        hoff[i - 1] -= k
    return E


@numba.njit(cache=True)
def _positions(z0, theta, h, out):
    """Node positions (n + 1, 2) from z_0 and the edge angles (x_0 = 0)."""
    out[0, 0] = 0.0
    out[0, 1] = z0
    for j in range(theta.shape[0]):
        out[j + 1, 0] = out[j, 0] + h * math.cos(theta[j])
        out[j + 1, 1] = out[j, 1] + h * math.sin(theta[j])
    return out


def capillary_hessian_nodes(X, s_nodes, s1, s2, area, gamma):
    """Exact Hessian of gamma lambda in the positions of the wet nodes.

    Parameters
    ----------
    X : ndarray, shape (n_nodes, 2)
        Node positions (x, z) (length).
    s_nodes : ndarray, shape (n_nodes,)
        Arclength of each node (length).
    s1, s2 : float
        Contact arclengths (length), inside edges, s1 < s2.
    area, gamma : float
        Drop area (length^2) and line tension (force).

    Returns
    -------
    i1 : int
        First node involved (the start of the edge holding S1); the nodes are
        i1 .. i1 + m - 1.
    H : ndarray, shape (2m, 2m)
        d^2 (gamma lambda) / dX dX, ordered (x_{i1}, z_{i1}, x_{i1+1}, ...) (force/length).

    Notes
    -----
    Same cap model and polygon as :func:`elastocap.drop.capillary_energy_and_gradient`:
    the wet polygon P_0 = X(S1), P_1..P_p = the interior wet nodes, P_{p+1} = X(S2) (linear
    interpolation), A1 = A - A0(P), d = |P_{p+1} - P_0|. With d(lambda) = cos(tau) dd +
    kappa dA1 (kappa = 2 sin(tau) / d) and tau(A1, d) from :func:`cap_tau_derivatives`,

        H = gamma [l_dd gd gd^T - l_dA (gd gA^T + gA gd^T) + l_AA gA gA^T
                   + cos(tau) Hd - kappa HA],

    l_dd = -sin(tau) tau_d, l_dA = -sin(tau) tau_A1, l_AA = 2 cos(tau) tau_A1 / d, gd and
    Hd the derivatives of the chord length, gA and HA (constant) those of the shoelace
    area A0.
    """
    i1, w1 = _locate(s1, s_nodes)
    i2, w2 = _locate(s2, s_nodes)
    p = i2 - i1  # interior wet nodes i1+1 .. i2
    npt = p + 2  # polygon points
    m = i2 - i1 + 2  # nodes i1 .. i2+1
    T = np.zeros((npt, m))
    T[0, 0], T[0, 1] = 1.0 - w1, w1
    for k in range(1, p + 1):
        T[k, k] = 1.0
    T[npt - 1, m - 2], T[npt - 1, m - 1] = 1.0 - w2, w2
    P = T @ X[i1 : i2 + 2]
    a0 = wet_polygon_area(X, s_nodes, s1, s2)
    c = P[-1] - P[0]
    d = math.hypot(c[0], c[1])
    a1 = area - a0
    tau, sn, cs, _lam, kappa = cap_geometry(a1, d)
    ta, td = cap_tau_derivatives(tau, sn, cs, a1, d)
    # gradient and (constant) Hessian of the shoelace area over the closed polygon
    R = np.array([[0.0, 1.0], [-1.0, 0.0]])  # d/dP_{k+1} of (1/2) J P_{k+1}, times 2
    gA = np.zeros((npt, 2))
    HA = np.zeros((2 * npt, 2 * npt))
    for k in range(npt):
        kn, kp = (k + 1) % npt, (k - 1) % npt
        gA[k] = 0.5 * np.array([P[kn, 1] - P[kp, 1], -(P[kn, 0] - P[kp, 0])])
        HA[2 * k : 2 * k + 2, 2 * kn : 2 * kn + 2] += 0.5 * R
        HA[2 * k : 2 * k + 2, 2 * kp : 2 * kp + 2] -= 0.5 * R
    u = c / d
    gd = np.zeros((npt, 2))
    gd[0], gd[-1] = -u, u
    Pu = (np.eye(2) - np.outer(u, u)) / d
    Hd = np.zeros((2 * npt, 2 * npt))
    e0, e1 = slice(0, 2), slice(2 * npt - 2, 2 * npt)
    Hd[e0, e0], Hd[e1, e1], Hd[e0, e1], Hd[e1, e0] = Pu, Pu, -Pu, -Pu
    gdv, gAv = gd.ravel(), gA.ravel()
    l_dd = -sn * td
    l_da = -sn * ta
    l_aa = 2.0 * cs * ta / d
    HP = gamma * (
        l_dd * np.outer(gdv, gdv)
        - l_da * (np.outer(gdv, gAv) + np.outer(gAv, gdv))
        + l_aa * np.outer(gAv, gAv)
        + cs * Hd
        - kappa * HA
    )
    T2 = np.kron(T, np.eye(2))
    return i1, T2.T @ HP @ T2


# --------------------------------------------------------------------------- problem
@dataclass(frozen=True)
class DiscreteStrip:
    """The discrete strip of Fig 3: parameters, energy, exact derivatives, constraints.

    Parameters
    ----------
    n : int
        Number of edges (h = L / n).
    L : float
        Strip length (length).
    x_end : float
        Distance x of the drop centre from the free end S = L (length).
    delta, area, gamma : float
        Wetted length Delta (length), drop area A (length^2), line tension gamma (force);
        gamma = 0 removes the drop.
    B : float
        Bending modulus (force length^2).
    q : float
        Weight per unit length mu g (force / length).
    F : float
        Vertical point force on the last node (force), 0 in the scene.
    """

    n: int
    L: float
    x_end: float
    delta: float
    area: float
    gamma: float
    B: float = 1.0
    q: float = 1.0
    F: float = 0.0

    def __post_init__(self):
        if int(self.n) != self.n or self.n < 4:
            raise ValueError(f"n: got {self.n!r}; expected an integer number of edges >= 4")
        for name, lo, strict in (("L", 0.0, True), ("B", 0.0, True), ("q", 0.0, False),
                                 ("gamma", 0.0, False), ("area", 0.0, self.gamma > 0.0)):
            v = getattr(self, name)
            if not (math.isfinite(v) and (v > lo if strict else v >= lo)):
                raise ValueError(
                    f"{name}: got {v!r}; expected a finite value {'>' if strict else '>='} {lo}"
                )
        if self.gamma > 0.0 and not (0.0 < self.s1 < self.s2 < self.L):
            raise ValueError(
                f"drop: got S1 = {self.s1}, S2 = {self.s2} (x = {self.x_end}, Delta = "
                f"{self.delta}); expected 0 < S1 < S2 < L = {self.L}"
            )

    # ------------------------------------------------------------------ geometry
    @property
    def h(self) -> float:
        return self.L / self.n

    @property
    def size(self) -> int:
        """Number of unknowns, n + 1: z_0 and the n edge angles."""
        return self.n + 1

    @property
    def s1(self) -> float:
        return self.L - self.x_end - 0.5 * self.delta

    @property
    def s2(self) -> float:
        return self.L - self.x_end + 0.5 * self.delta

    @property
    def s_nodes(self) -> np.ndarray:
        return np.linspace(0.0, self.L, self.n + 1)

    @property
    def tip(self) -> int:
        """Index in u of the last edge angle theta_{n-1}."""
        return self.n

    def with_(self, **kw) -> DiscreteStrip:
        """A copy with some parameters changed (e.g. ``delta``, ``n``)."""
        return DiscreteStrip(**{**self.__dict__, **kw})

    def positions(self, u) -> np.ndarray:
        """Node positions, shape (n + 1, 2) (length)."""
        return _positions(float(u[0]), np.ascontiguousarray(u[1:], dtype=float), self.h,
                          np.empty((self.n + 1, 2)))

    def heights(self, u) -> np.ndarray:
        """z_k of every node (the constraint values), shape (n + 1,)."""
        return self.positions(u)[:, 1]

    def chord(self, u) -> float:
        """Distance d between the contact points X(S1) and X(S2) (length)."""
        X = self.positions(u)
        s = self.s_nodes
        dx = np.interp(self.s2, s, X[:, 0]) - np.interp(self.s1, s, X[:, 0])
        dz = np.interp(self.s2, s, X[:, 1]) - np.interp(self.s1, s, X[:, 1])
        return math.hypot(dx, dz)

    def constraint_jacobian(self, u) -> np.ndarray:
        """d z_k / du, shape (n + 1, n + 1): row k = (1, h cos theta_j for j < k, 0...)."""
        G = np.zeros((self.n + 1, self.n + 1))
        G[:, 0] = 1.0
        hc = self.h * np.cos(u[1:])
        G[1:, 1:] = np.tril(np.broadcast_to(hc, (self.n, self.n)))
        return G

    # ------------------------------------------------------------------ energy
    def _node_to_u(self, theta, g):
        """Chain rule from a node gradient g (n + 1, 2) to d/du (n + 1,) and the suffix sums."""
        Gs = np.cumsum(g[::-1], axis=0)[::-1]  # Gs[k] = sum_{k' >= k} g_k'
        Gx, Gz = Gs[1:, 0], Gs[1:, 1]  # sums over nodes beyond edge j
        out = np.empty(self.n + 1)
        out[0] = Gs[0, 1]
        out[1:] = self.h * (-np.sin(theta) * Gx + np.cos(theta) * Gz)
        return out, Gx, Gz

    def _smid(self):
        return (np.arange(self.n) + 0.5) * self.h

    def energy_parts(self, u) -> dict:
        """Bending, gravity, capillary and end-force energies (energy units)."""
        th = np.asarray(u[1:], dtype=float)
        n = self.n
        bend = _bending(th, self.B, self.h, np.zeros(n), np.zeros(n), np.zeros(n - 1))
        grav = self.q * (self.L * u[0] + self.h * np.sum((self.L - self._smid()) * np.sin(th)))
        zn = u[0] + self.h * np.sum(np.sin(th))
        cap = 0.0
        if self.gamma > 0.0:
            X = self.positions(u)
            cap, _t, _k = capillary_energy_and_gradient(
                X, self.s_nodes, self.s1, self.s2, self.area, self.gamma, np.zeros_like(X)
            )
        return {"bending": float(bend), "gravity": float(grav), "capillary": float(cap),
                "end_force": float(-self.F * zn)}

    def energy(self, u) -> float:
        return float(sum(self.energy_parts(u).values()))

    def gradient(self, u) -> np.ndarray:
        """dE/du, shape (n + 1,) (force for z_0, energy for the angles)."""
        return self.derivatives(u, hessian=False)[1]

    def hessian(self, u) -> np.ndarray:
        """d^2E/du^2, shape (n + 1, n + 1), exact."""
        return self.derivatives(u)[2]

    def derivatives(self, u, hessian=True):
        """Energy, gradient and (optionally) the exact Hessian in u."""
        u = np.asarray(u, dtype=float)
        th = u[1:]
        n, h, q, L = self.n, self.h, self.q, self.L
        g = np.zeros(n + 1)
        gb, hd, ho = np.zeros(n), np.zeros(n), np.zeros(n - 1)
        E = _bending(th, self.B, h, gb, hd, ho)
        g[1:] += gb
        sn, cs = np.sin(th), np.cos(th)
        w = q * h * (L - self._smid()) - self.F * h
        E += q * L * u[0] + float(w @ sn) - self.F * u[0]
        g[0] += q * L - self.F
        g[1:] += w * cs
        H = None
        if hessian:
            H = np.zeros((n + 1, n + 1))
            idx = np.arange(1, n + 1)
            H[idx, idx] = hd - w * sn
            H[idx[:-1], idx[1:]] = ho
            H[idx[1:], idx[:-1]] = ho
        if self.gamma > 0.0:
            X = self.positions(u)
            gX = np.zeros_like(X)
            ec, _t, _k = capillary_energy_and_gradient(
                X, self.s_nodes, self.s1, self.s2, self.area, self.gamma, gX
            )
            E += ec
            gu, Gx, Gz = self._node_to_u(th, gX)
            g += gu
            if hessian:
                # d^2 X_k / d theta_j^2 = -h (cos, sin) theta_j for k > j (diagonal only)
                H[idx, idx] += -h * (cs * Gx + sn * Gz)
                i1, HX = capillary_hessian_nodes(X, self.s_nodes, self.s1, self.s2,
                                                 self.area, self.gamma)
                m = HX.shape[0] // 2
                # lambda is translation invariant: only the wet edges i1 .. i1+m-2 act.
                # X_{i1+a} - X_{i1} = h sum_{i1 <= j < i1+a} (cos, sin) theta_j
                J = np.zeros((2 * m, m - 1))
                for a in range(1, m):
                    for b in range(a):
                        j = i1 + b
                        J[2 * a, b] = -h * sn[j]
                        J[2 * a + 1, b] = h * cs[j]
                cols = 1 + i1 + np.arange(m - 1)
                Hc = J.T @ HX @ J
                H[np.ix_(cols, cols)] += 0.5 * (Hc + Hc.T)  # symmetric to the last bit
        return float(E), g, H

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def discrete_strip_for(scene, n=None) -> DiscreteStrip:
    """The discrete strip of a scene with gravity and the ground (``fig3-strip``).

    ``n`` defaults to the scene's impact resolution (``numerics.n_edges``, or the accuracy
    preset's edges when it is 0, as :func:`elastocap.impact.impact_settings` resolves it).
    """
    if not (scene.effects.gravity > 0.0 and scene.effects.ground):
        raise ValueError(
            f"scene.effects: got gravity = {scene.effects.gravity}, ground = "
            f"{scene.effects.ground}; the strip statics needs gravity > 0 and ground = true"
        )
    if n is None:
        from elastocap.impact import impact_settings

        n = impact_settings(scene)["n_edges"]
    d = scene.drop
    return DiscreteStrip(
        int(n), scene.rod.length, scene.distance_from_end, d.wetted_length, d.area,
        d.line_tension, scene.rod.bending_modulus,
        scene.rod.mass_per_length * scene.effects.gravity,
    )


def flat_state(strip: DiscreteStrip) -> np.ndarray:
    """u of the straight strip lying on the ground."""
    return np.zeros(strip.size)


# --------------------------------------------------------------------------- solver
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
    held : dict
        Unknowns held fixed {index: generalized force needed to hold it} (the couple at the
        tip for index n).
    index : int
        Negative eigenvalues of the Lagrangian Hessian on the tangent space of the
        strongly active contacts (and the free unknowns); -1 when not computed.
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
    held: dict = field(default_factory=dict)
    index: int = -1
    degenerate: int = 0

    @property
    def success(self) -> bool:
        return self.status == "converged"

    @property
    def contacts(self) -> int:
        return int(np.count_nonzero(self.active))


def _kkt_residual(strip, u, g, r, active, free):
    z = strip.heights(u)
    G = strip.constraint_jacobian(u)
    stat = g - G.T @ r
    res_stat = float(np.max(np.abs(stat[free]))) if free.any() else 0.0
    pen = float(max(0.0, -np.min(z)))
    return max(res_stat, pen), stat, z, G


def solve_equilibrium(strip: DiscreteStrip, u0, active=None, held=(), tol=1e-10,
                      max_iter=_MAX_ITER, compute_index=True, trace=None,
                      max_turn=_MAX_TURN) -> Equilibrium:
    """Primal-dual active-set Newton for the strip on the ground.

    Parameters
    ----------
    strip : DiscreteStrip
    u0 : ndarray, shape (n + 1,)
        Initial guess (held unknowns keep their values).
    active : ndarray of bool, shape (n + 1,), optional
        Initial contact set; default: the nodes with z <= 1e-12 (length).
    held : sequence of int
        Indices of u held fixed (e.g. ``(strip.tip,)`` for a prescribed tip angle).
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
    free[list(held)] = False
    z = strip.heights(u)
    act = (z <= 1e-12) if active is None else np.array(active, dtype=bool)
    # With the last edge's angle held, z_n - z_{n-1} = h sin(theta_{n-1}) is fixed: the two
    # contacts have the same gradient in the free unknowns, and only the lower end can
    # touch (the other one is then above the ground by itself).
    can = np.ones(N, dtype=bool)
    if strip.tip in held:
        can[N - 1 if math.sin(u[strip.tip]) > 0.0 else N - 2] = False
    act &= can
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
        G = strip.constraint_jacobian(u)
        # Lagrangian Hessian: - sum_k r_k d^2 z_k = diag_j(h sin theta_j sum_{k > j} r_k)
        rs = np.cumsum(r[::-1])[::-1]
        W = H.copy()
        W[np.arange(1, N), np.arange(1, N)] += strip.h * np.sin(u[1:]) * rs[1:]
        A = np.flatnonzero(act)
        fi = np.flatnonzero(free)
        Ga = G[np.ix_(A, fi)]
        nf, na = fi.size, A.size
        K = np.zeros((nf + na, nf + na))
        K[:nf, :nf] = W[np.ix_(fi, fi)]
        K[:nf, nf:] = Ga.T
        K[nf:, :nf] = Ga
        # solve for the change of the multipliers, not the multipliers themselves: the
        # KKT matrix is ill-conditioned (B/h^3 against q h), and a correction keeps the
        # final residual at the accuracy of its evaluation (1e-12), not of the solve (1e-9)
        rhs = np.concatenate([-(g - G[A].T @ r[A])[fi], -z[A]])
        try:
            sol = np.linalg.solve(K, rhs)
        except np.linalg.LinAlgError:
            status, msg = "singular", "singular KKT matrix; try another initial contact set"
            break
        du = np.zeros(N)
        du[fi] = sol[:nf]
        r_new = np.zeros(N)
        r_new[A] = r[A] - sol[nf:]
        # residual at the current point with the new multipliers: stop test
        stat = g - G.T @ r_new
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
    E, g, _H = strip.derivatives(u, hessian=False)
    stat = g - strip.constraint_jacobian(u).T @ r
    eq = Equilibrium(
        u=u, energy=float(E), parts=strip.energy_parts(u), reactions=r, active=act,
        residual=float(res), iterations=it, status=status, message=msg,
        held={int(k): float(stat[k]) for k in held},
    )
    if eq.success and compute_index:
        eq.index, eq.degenerate = stability(strip, eq)
    return eq


def stability(strip: DiscreteStrip, eq: Equilibrium) -> tuple[int, int]:
    """(index, degenerate contacts) of an equilibrium.

    The index is the number of negative eigenvalues of the Lagrangian Hessian restricted to
    the free unknowns tangent to the strongly active contacts (r_k > _R_REL q h).
    """
    u, r = eq.u, eq.reactions
    N = strip.size
    free = np.ones(N, dtype=bool)
    free[list(eq.held)] = False
    H = strip.hessian(u)
    rs = np.cumsum(r[::-1])[::-1]
    H[np.arange(1, N), np.arange(1, N)] += strip.h * np.sin(u[1:]) * rs[1:]
    rtol = _R_REL * strip.q * strip.h
    strong = eq.active & (r > rtol)
    weak = eq.active & ~strong
    fi = np.flatnonzero(free)
    G = strip.constraint_jacobian(u)[np.ix_(np.flatnonzero(strong), fi)]
    Hf = H[np.ix_(fi, fi)]
    if G.shape[0]:
        # orthonormal basis of the null space of G
        _q, s, vt = np.linalg.svd(G, full_matrices=True)
        rank = int(np.sum(s > 1e-12 * s[0]))
        Z = vt[rank:].T
        Hr = Z.T @ Hf @ Z
    else:
        Hr = Hf
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


def minimize_energy(strip: DiscreteStrip, u0, held=(), tol=1e-10, max_iter=500) -> Equilibrium:
    """A local minimum of the energy on z >= 0, reached by descent from ``u0``.

    Phase 1: trust-region Newton (scipy ``trust-exact``, exact Hessian) on the energy
    plus an exterior penalty (k/2) sum min(z_k, 0)^2, k = 10 B / h^3; the descent
    cannot jump over a barrier the way a Newton iteration can. Phase 2: the active-set
    Newton :func:`solve_equilibrium` from the penalty minimum, with the penetrating nodes
    as the initial contacts, makes it an exact KKT point. ``held`` unknowns keep their
    values from ``u0``.
    """
    from scipy.optimize import minimize

    u0 = np.array(u0, dtype=float)
    free = np.ones(strip.size, dtype=bool)
    free[list(held)] = False
    fi = np.flatnonzero(free)
    # 10 B / h^3: the penetration r / k is ~1e-5 (r ~ q h), close enough for the polish to
    # start on the right contact set; measured at n = 100, x = 4, Delta = 1.1: 57 trust
    # iterations (1.1 s) against 461 (7.8 s) with 1e3 B / h^3, same polished state
    k = 10.0 * strip.B / strip.h**3

    def full(v):
        u = u0.copy()
        u[fi] = v
        return u

    cache = {}

    def fgh(v):
        key = v.tobytes()
        if key not in cache:
            cache.clear()
            E, g, H = _penalty(strip, full(v), k)
            cache[key] = (E, g[fi], H[np.ix_(fi, fi)])
        return cache[key]

    res = minimize(lambda v: fgh(v)[0], u0[fi], jac=lambda v: fgh(v)[1],
                   hess=lambda v: fgh(v)[2], method="trust-exact",
                   options={"gtol": 1e-8, "maxiter": max_iter})
    u = full(res.x)
    z = strip.heights(u)
    # contacts: penetrating, or within the penalty's reach of the ground
    act = z <= 1e-9
    return solve_equilibrium(strip, u, active=act, held=held, tol=tol)


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
