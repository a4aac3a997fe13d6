"""The discrete strip of Fig 3 on a frictionless ground: energy, exact derivatives, geometry.

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

Self-contact (``thickness`` d > 0; the dynamics' :mod:`dynamics.contact`): node i and
segment j (nodes j, j + 1) far enough apart along the strip (arc-length gap >= pi d / 2,
``dynamics.contact.exclusion_length``) stay at least d apart. A contact is a *pair*
(i, j, sigma): node i on the side sigma = +-1 of segment j, with the gap

    g = sigma n_j . (X_i - X_j) - d,     n_j = (-sin theta_j, cos theta_j),

the signed distance to the segment's line (:func:`pair_gaps`), which is the distance to
the segment while the closest point lies inside it (0 <= w <= 1, w the position along the
segment). In the angles it reads sigma h sum_m sin(theta_m - theta_j) - d over the edges m
between j and i, so its gradient and Hessian are closed forms (:func:`pair_jacobian`,
:func:`pair_hessian`). Off (d = 0) no pair exists and nothing is evaluated.

Ground: z_k >= 0 at every node k = 0..n (the constraint values :meth:`DiscreteStrip.heights`
and their gradients :meth:`DiscreteStrip.constraint_jacobian`); the contact set is an
unknown, so one model covers every contact topology (the open state, the lifted and the
floppy encapsulated states, the saddles between them). The equilibria are solved in
:mod:`elastocap.strip.solve`, traced in :mod:`elastocap.strip.trace`.

Free rod (``ground = False``, q = F = 0; :func:`discrete_strip_for` of the ``supp-fig5`` scene):
no ground constraint; the energy and the pair gaps are invariant under translations and
rotations, so z_0 and the angle of the edge holding the drop's centre are held at 0
(:attr:`DiscreteStrip.gauge`, :func:`fix_gauge`) and the solver and the tracer leave them
out (:mod:`elastocap.strip.freerod`).

Also here: the geometry and observables of a state (:func:`is_encapsulated`,
:func:`strip_and_interface`, :func:`point_measures`) and the energy of the impact's release
state (:func:`flat_energy`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, fields

import numba
import numpy as np

from dynamics.contact import exclusion_length
from elastocap.capillary_hessian import CAPILLARY_RANK, capillary_stiffness
from elastocap.drop import (
    cap_geometry,
    cap_tau_derivatives,
    capillary_energy_and_gradient,
    locate_on_rod,
    wet_polygon_area,
)
from elastocap.geometry import arc_points, count_crossings

__all__ = [
    "REDUNDANT_SIN",
    "DiscreteStrip",
    "capillary_hessian_nodes",
    "closest_segments",
    "discrete_strip_for",
    "fix_gauge",
    "flat_energy",
    "flat_state",
    "is_encapsulated",
    "pair_gaps",
    "pair_hessian",
    "pair_jacobian",
    "pair_switch",
    "point_measures",
    "redundant_pair",
    "shoelace_derivatives",
    "strip_and_interface",
]


def _edge_at(s, s_nodes):
    """Edge index i and fraction w in [0, 1] with s = (1 - w) s_i + w s_{i+1} (the
    placement of a contact point in the edges, as in :mod:`elastocap.drop`)."""
    n = s_nodes.shape[0]
    i = int(np.clip(np.searchsorted(s_nodes, s, side="right") - 1, 0, n - 2))
    w = float(np.clip((s - s_nodes[i]) / (s_nodes[i + 1] - s_nodes[i]), 0.0, 1.0))
    return i, w

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


@numba.njit(cache=True)
def _constraint_jacobian(hc, out):
    """d z_k / du into the zeroed ``out`` (n + 1, n + 1): column 0 ones, row k holds
    ``hc[j] = h cos theta_j`` for j < k (the lower triangle, written entry by entry)."""
    for k in range(out.shape[0]):
        out[k, 0] = 1.0
        for j in range(k):
            out[k, j + 1] = hc[j]
    return out


@numba.njit(cache=True)
def _held_residual(g, X, cs, h, A, ra, c, out):
    """The fixed-set residual (without pairs) from :func:`_energy_gradient`'s gradient
    ``g``, positions ``X`` and cosines ``cs``: ``out[:n + 1]`` = g - sum_k r_k grad z_k
    with r zero but r[A] = ``ra`` (A ascending), ``out[n + 1 + i]`` = c (z_{A_i} -
    z_{A_{i-1}}) (c z_{A_0} first). The operations of :meth:`DiscreteStrip.stationarity`'s
    numpy form in their order (the suffix sums of r as ``np.cumsum`` of the reversed r),
    so the same bits."""
    N = g.shape[0]
    r = np.zeros(N)
    for i in range(A.shape[0]):
        r[A[i]] = ra[i]
    rs = np.empty(N)
    acc = r[N - 1]
    rs[N - 1] = acc
    for k in range(N - 2, -1, -1):
        acc = acc + r[k]
        rs[k] = acc
    out[0] = g[0] - rs[0]
    for j in range(N - 1):
        out[j + 1] = g[j + 1] - h * cs[j] * rs[j + 1]
    for i in range(A.shape[0]):
        z = X[A[i], 1]
        if i > 0:
            z = z - X[A[i - 1], 1]
        out[N + i] = c * z


@numba.njit(cache=True)
def _energy_gradient(u, B, h, w, f0, s_nodes, s1, s2, area, gamma, g, hd, ho, sn, cs, X, gX,
                     Gx, Gz):
    """Energy; its gradient in u written into ``g`` (n + 1,); the bending Hessian's diagonal
    ``hd`` and off-diagonal ``ho``; sin, cos of the angles; the node positions ``X``; the
    capillary node gradient ``gX`` and its suffix sums over the nodes beyond each edge
    ``Gx``, ``Gz`` (n,) (every output array overwritten).

    Gravity and the end force: ``w`` (n,) = q h (L - s_mid) - F h, ``f0`` = q L - F.
    ``gamma`` = 0: no drop (``gX``, ``Gx``, ``Gz`` zero).
    """
    n = u.shape[0] - 1
    th = u[1:]
    g[:] = 0.0
    hd[:] = 0.0
    ho[:] = 0.0
    E = _bending(th, B, h, g[1:], hd, ho)
    z0 = u[0]
    E += f0 * z0
    g[0] += f0
    X[0, 0] = 0.0
    X[0, 1] = z0
    for j in range(n):
        sj = math.sin(th[j])
        cj = math.cos(th[j])
        sn[j] = sj
        cs[j] = cj
        E += w[j] * sj
        g[j + 1] += w[j] * cj
        X[j + 1, 0] = X[j, 0] + h * cj
        X[j + 1, 1] = X[j, 1] + h * sj
    gX[:, :] = 0.0
    if gamma > 0.0:
        E += capillary_energy_and_gradient(X, s_nodes, s1, s2, area, gamma, gX)[0]
        # chain rule: d X_k / d theta_j = h (-sin, cos) theta_j for k > j, d X_k / d z_0
        # = (0, 1)
        ax = 0.0
        az = 0.0
        for j in range(n - 1, -1, -1):
            ax += gX[j + 1, 0]
            az += gX[j + 1, 1]
            Gx[j] = ax
            Gz[j] = az
            g[j + 1] += h * (-sn[j] * ax + cs[j] * az)
        g[0] += az + gX[0, 1]
    else:
        Gx[:] = 0.0
        Gz[:] = 0.0
    return E


@numba.njit(cache=True)
def _capillary_angle_hessian(X, params, edge_len, sn, cs, h, H):
    """ADD the Hessian of gamma lambda in the edge angles to ``H`` (n + 1, n + 1), rows and
    columns 1 + j; returns False (nothing added) where the cap is degenerate.

    The node Hessian is :func:`elastocap.capillary_hessian.capillary_stiffness`'s band K
    plus U^T C U (rank 5). With d X_k / d theta_j = h e_j (e_j = (-sin, cos) theta_j) for
    k > j, the angle Hessian of a node matrix M is h^2 e_j^T (sum_{k > j, k' > j'}
    M_kk') e_j': double suffix sums over the wet nodes, O(m^2) for m wet nodes, instead
    of the products with the (2m, m - 1) Jacobian. lambda is translation invariant: only
    the wet edges i1 .. i2 act (as in :func:`elastocap.drop.capillary_energy_and_gradient`,
    S1 in edge i1, S2 in edge i2).
    """
    nn = X.shape[0]
    K = np.zeros((nn, 2, 5, 2))
    U = np.zeros((CAPILLARY_RANK, nn, 2))
    C = np.zeros((CAPILLARY_RANK, CAPILLARY_RANK))
    if capillary_stiffness(X, X, 0.0, params, edge_len, edge_len, K, U, C) == 0:
        return False
    s_nodes = np.empty(nn)
    s_nodes[0] = 0.0
    for i in range(nn - 1):
        s_nodes[i + 1] = s_nodes[i] + edge_len[i]
    i1 = locate_on_rod(params[1], s_nodes)[0]
    i2 = locate_on_rod(params[2], s_nodes)[0]
    ne = i2 - i1 + 1  # wet edges i1 .. i2; nodes i1 .. i2 + 1 (local 0 .. ne)
    # rank 5: V[r, b] = e_b . sum_{k > i1 + b} U[r, k]
    V = np.zeros((CAPILLARY_RANK, ne))
    for r in range(CAPILLARY_RANK):
        ax = 0.0
        az = 0.0
        for b in range(ne - 1, -1, -1):
            k = i1 + b + 1
            ax += U[r, k, 0]
            az += U[r, k, 1]
            j = i1 + b
            V[r, b] = h * (-sn[j] * ax + cs[j] * az)
    # band: T[a, p, c, q] = sum_{a' > c} K[a, p, a', q] (local nodes a, a'; edge c), then
    # S[b, p, c, q] = sum_{a > b} T[a, p, c, q]
    T = np.zeros((ne + 1, 2, ne, 2))
    for a in range(ne + 1):
        for p in range(2):
            for q in range(2):
                acc = 0.0
                for c in range(ne - 1, -1, -1):
                    a2 = c + 1  # the node entering the sum
                    o = a2 - a + 2
                    if 0 <= o < 5:
                        acc += K[i1 + a, p, o, q]
                    T[a, p, c, q] = acc
    S = np.zeros((ne, 2, ne, 2))
    for c in range(ne):
        for p in range(2):
            for q in range(2):
                acc = 0.0
                for b in range(ne - 1, -1, -1):
                    acc += T[b + 1, p, c, q]
                    S[b, p, c, q] = acc
    Hc = np.empty((ne, ne))
    for b in range(ne):
        jb = i1 + b
        ex_b, ez_b = -sn[jb], cs[jb]
        for c in range(ne):
            jc = i1 + c
            ex_c, ez_c = -sn[jc], cs[jc]
            v = h * h * (ex_b * (S[b, 0, c, 0] * ex_c + S[b, 0, c, 1] * ez_c)
                         + ez_b * (S[b, 1, c, 0] * ex_c + S[b, 1, c, 1] * ez_c))
            for r in range(CAPILLARY_RANK):
                vr = V[r, b]
                for t in range(CAPILLARY_RANK):
                    v += C[r, t] * vr * V[t, c]
            Hc[b, c] = v
    for b in range(ne):
        for c in range(ne):
            H[1 + i1 + b, 1 + i1 + c] += 0.5 * (Hc[b, c] + Hc[c, b])
    return True


@numba.njit(cache=True)
def _constraint_rows(hc, nodes, out):
    """The rows ``nodes`` of :func:`_constraint_jacobian` into the zeroed ``out``
    (len(nodes), n + 1)."""
    for i in range(nodes.shape[0]):
        out[i, 0] = 1.0
        for j in range(nodes[i]):
            out[i, j + 1] = hc[j]
    return out


def shoelace_derivatives(P):
    """Gradient (npt, 2) and Hessian (2 npt, 2 npt) of the shoelace area of the closed
    polygon P (npt, 2) in its points, ordered (x_0, z_0, x_1, ...).

    dA/dP_k = (z_{k+1} - z_{k-1}, -(x_{k+1} - x_{k-1})) / 2; the Hessian is constant: the
    blocks (k, k + 1) and (k, k - 1) are +R/2 and -R/2 with R = [[0, 1], [-1, 0]].
    """
    npt = P.shape[0]
    Pn, Pp = np.roll(P, -1, axis=0), np.roll(P, 1, axis=0)  # P_{k+1}, P_{k-1}
    gA = np.empty((npt, 2))
    gA[:, 0] = 0.5 * (Pn[:, 1] - Pp[:, 1])
    gA[:, 1] = 0.5 * -(Pn[:, 0] - Pp[:, 0])
    return gA, _shoelace_hessian(npt)


@functools.lru_cache(maxsize=8)  # npt changes along a branch: bounded (2 npt)^2 floats each
def _shoelace_hessian(npt):
    R = np.array([[0.0, 1.0], [-1.0, 0.0]])  # d/dP_{k+1} of (1/2) J P_{k+1}, times 2
    HA = np.zeros((2 * npt, 2 * npt))
    for k in range(npt):
        kn, kp = (k + 1) % npt, (k - 1) % npt
        HA[2 * k : 2 * k + 2, 2 * kn : 2 * kn + 2] += 0.5 * R
        HA[2 * k : 2 * k + 2, 2 * kp : 2 * kp + 2] -= 0.5 * R
    HA.flags.writeable = False
    return HA


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
    i1, w1 = _edge_at(s1, s_nodes)
    i2, w2 = _edge_at(s2, s_nodes)
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
    gA, HA = shoelace_derivatives(P)
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
    # T (x) I_2, the interpolation acting on (x, z) pairs (T >= 0: the entries of the
    # Kronecker product, written directly)
    T2 = np.zeros((2 * npt, 2 * m))
    T2[0::2, 0::2] = T
    T2[1::2, 1::2] = T
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
    thickness : float
        The strip's thickness d (length, scene key ``rod.thickness``): node-segment
        self-contact (module docstring); 0 turns it off.
    ground : bool
        True: the ground z >= 0 holds every node. False: a free rod (no ground; q and F
        must be 0), whose energy is invariant under translations and rotations: the
        unknowns :attr:`gauge` (z_0 and the angle of the edge holding the drop's centre)
        are held at 0 (:func:`fix_gauge`) and the solver and the tracer leave them out.
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
    thickness: float = 0.0
    ground: bool = True

    def __post_init__(self):
        if int(self.n) != self.n or self.n < 4:
            raise ValueError(f"n: got {self.n!r}; expected an integer number of edges >= 4")
        for name, lo, strict in (("L", 0.0, True), ("B", 0.0, True), ("q", 0.0, False),
                                 ("gamma", 0.0, False), ("area", 0.0, self.gamma > 0.0),
                                 ("thickness", 0.0, False)):
            v = getattr(self, name)
            if not (math.isfinite(v) and (v > lo if strict else v >= lo)):
                raise ValueError(
                    f"{name}: got {v!r}; expected a finite value {'>' if strict else '>='} {lo}"
                )
        if not self.ground:
            for name in ("q", "F"):
                if getattr(self, name) != 0.0:
                    raise ValueError(
                        f"{name}: got {getattr(self, name)!r}; expected 0 for a free rod "
                        "(ground = False: no load may act on it but the drop)")
        self._check_drop()

    def _check_drop(self):
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

    @functools.cached_property
    def s_nodes(self) -> np.ndarray:
        """Arclength of each node, shape (n + 1,) (length); computed once per strip (the
        derivatives are evaluated ~1e5 times per trace)."""
        return np.linspace(0.0, self.L, self.n + 1)

    @functools.cached_property
    def gauge(self) -> np.ndarray:
        """Indices in u held at 0 by the gauge: none on the ground; for a free rod z_0
        (x_0 = 0 already fixes the other translation) and the angle of the edge holding
        the drop's centre L - x (for odd n and a centred drop the middle edge, so that a
        mirror-symmetric state is symmetric about the vertical through its midpoint)."""
        if self.ground:
            return np.zeros(0, dtype=np.int64)
        k = min(int(math.floor((self.L - self.x_end) / self.h + 1e-9)), self.n - 1)
        return np.array([0, 1 + k], dtype=np.int64)

    @property
    def tip(self) -> int:
        """Index in u of the last edge angle theta_{n-1}."""
        return self.n

    def with_(self, **kw) -> DiscreteStrip:
        """A copy with some parameters changed (e.g. ``delta``, ``n``).

        The copy shares this strip's node arrays (:attr:`s_nodes`, the mid-edge
        arclengths, the edge lengths and the load per angle) where the parameters they
        depend on are unchanged: a trace makes a strip at every Delta it evaluates. A copy
        with another ``delta`` alone (the trace's) is made without the constructor, whose
        checks of the other parameters this strip has passed: only the drop's place on
        the strip is checked (3 us against 21 us a copy)."""
        mine = self.__dict__
        if len(kw) == 1 and "delta" in kw:
            new = object.__new__(DiscreteStrip)
            theirs = new.__dict__
            for name in _FIELDS:
                theirs[name] = mine[name]
            theirs["delta"] = kw["delta"]
            new._check_drop()
            for name in ("s_nodes", "_s_mid", "_edge_len", "_load"):
                if name in mine:
                    theirs[name] = mine[name]
            return new
        new = DiscreteStrip(**{**self.to_dict(), **kw})
        theirs = new.__dict__
        if new.n == self.n and new.L == self.L:
            for name in ("s_nodes", "_s_mid", "_edge_len"):
                if name in mine:
                    theirs[name] = mine[name]
            if new.q == self.q and new.F == self.F and "_load" in mine:
                theirs["_load"] = mine["_load"]
        return new

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

    def constraint_jacobian(self, u, nodes=None) -> np.ndarray:
        """d z_k / du, shape (n + 1, n + 1): row k = (1, h cos theta_j for j < k, 0...);
        with ``nodes`` (int array, shape (m,)) only those rows, shape (m, n + 1)."""
        hc = self.h * np.cos(np.asarray(u[1:], dtype=float))
        if nodes is None:
            return _constraint_jacobian(hc, np.zeros((self.n + 1, self.n + 1)))
        k = np.ascontiguousarray(nodes, dtype=np.int64).ravel()
        return _constraint_rows(hc, k, np.zeros((k.size, self.n + 1)))

    def reaction_forces(self, u, r) -> np.ndarray:
        """sum_k r_k grad z_k(u), shape (n + 1,): the generalized force of the reactions r
        (force, shape (n + 1,)) without the (n + 1)^2 constraint Jacobian: component 0 is
        sum_k r_k, component j + 1 is h cos theta_j sum_{k > j} r_k."""
        rs = np.cumsum(np.asarray(r, dtype=float)[::-1])[::-1]
        out = np.empty(self.n + 1)
        out[0] = rs[0]
        out[1:] = self.h * np.cos(np.asarray(u[1:], dtype=float)) * rs[1:]
        return out

    # ------------------------------------------------------------------ energy
    @functools.cached_property
    def _s_mid(self):
        return (np.arange(self.n) + 0.5) * self.h

    @functools.cached_property
    def _load(self):
        """Gravity and end force per angle: q h (L - s_mid) - F h, shape (n,)."""
        return self.q * self.h * (self.L - self._s_mid) - self.F * self.h

    @functools.cached_property
    def _edge_len(self):
        """Edge lengths as differences of :attr:`s_nodes`: their running sums give back
        ``s_nodes`` bit for bit (each difference and sum exact, Sterbenz), so the capillary
        kernels that take edge lengths place S1, S2 in the same edges as the gradient."""
        return np.diff(self.s_nodes)

    def energy_parts(self, u) -> dict:
        """Bending, gravity, capillary and end-force energies (energy units)."""
        th = np.asarray(u[1:], dtype=float)
        n = self.n
        bend = _bending(th, self.B, self.h, np.zeros(n), np.zeros(n), np.zeros(n - 1))
        grav = self.q * (self.L * u[0] + self.h * np.sum((self.L - self._s_mid) * np.sin(th)))
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

    def stationarity(self, u, r):
        """dE/du - sum_k r_k grad z_k(u) (the KKT residual of the ground's reactions r,
        force, shape (n + 1,)) and the heights z_k (shape (n + 1,)), from one pass of
        :func:`_energy_gradient` (the positions and the angles' cosines it computes)."""
        u = np.ascontiguousarray(u, dtype=float)
        g, X, cs = self._first_order(u)[1:4]
        rs = np.cumsum(np.asarray(r, dtype=float)[::-1])[::-1]
        g[0] -= rs[0]
        g[1:] -= self.h * cs * rs[1:]
        return g, X[:, 1]

    def held_residual(self, u, A, ra, c):
        """The fixed-set residual without pairs, shape (n + 1 + len(A),): the
        :meth:`stationarity` rows for reactions zero but ``ra`` at the held nodes ``A``
        (ascending), then c z_{A_0} and c (z_{A_i} - z_{A_{i-1}}); the same bits as those
        numpy operations, in one compiled pass after the energy's."""
        u = np.ascontiguousarray(u, dtype=float)
        g, X, cs = self._first_order(u)[1:4]
        out = np.empty(self.n + 1 + A.shape[0])
        _held_residual(g, X, cs, self.h, A, np.ascontiguousarray(ra, dtype=float),
                       float(c), out)
        return out

    def _first_order(self, u):
        """(E, g, X, cos, sin, bending Hessian diagonal and off-diagonal, Gx, Gz) of
        :func:`_energy_gradient` at the contiguous float ``u``."""
        n = self.n
        g = np.empty(n + 1)
        hd, ho, sn, cs = np.empty(n), np.empty(n - 1), np.empty(n), np.empty(n)
        X, gX = np.empty((n + 1, 2)), np.empty((n + 1, 2))
        Gx, Gz = np.empty(n), np.empty(n)
        E = _energy_gradient(u, self.B, self.h, self._load, self.q * self.L - self.F,
                             self.s_nodes, self.s1, self.s2, self.area, self.gamma, g, hd,
                             ho, sn, cs, X, gX, Gx, Gz)
        return E, g, X, cs, sn, hd, ho, Gx, Gz

    def derivatives(self, u, hessian=True):
        """Energy, gradient and (optionally) the exact Hessian in u.

        One compiled pass (:func:`_energy_gradient`) for the energy and the gradient; the
        Hessian is tridiagonal (bending, gravity) plus the drop's: the diagonal term of the
        positions' curvature and the dense block of the wet edges
        (:func:`_capillary_angle_hessian`)."""
        u = np.ascontiguousarray(u, dtype=float)
        n, h, w = self.n, self.h, self._load
        E, g, X, cs, sn, hd, ho, Gx, Gz = self._first_order(u)
        if not hessian:
            return float(E), g, None
        H = np.zeros((n + 1, n + 1))
        idx = np.arange(1, n + 1)
        # d^2 X_k / d theta_j^2 = -h (cos, sin) theta_j for k > j (diagonal only)
        H[idx, idx] = hd - w * sn - h * (cs * Gx + sn * Gz)
        H[idx[:-1], idx[1:]] = ho
        H[idx[1:], idx[:-1]] = ho
        if self.gamma > 0.0:
            params = np.array([self.area, self.s1, self.s2, self.gamma])
            if not _capillary_angle_hessian(X, params, self._edge_len, sn, cs, h, H):
                # a degenerate cap (the contact points on each other): the dense
                # reference, whatever it gives there
                i1, HX = capillary_hessian_nodes(X, self.s_nodes, self.s1, self.s2,
                                                 self.area, self.gamma)
                m = HX.shape[0] // 2
                J = np.zeros((2 * m, m - 1))
                low = np.tri(m, m - 1, -1)  # entry (a, b) is 1 for b < a
                J[0::2] = -h * low * sn[i1 : i1 + m - 1]
                J[1::2] = h * low * cs[i1 : i1 + m - 1]
                cols = 1 + i1 + np.arange(m - 1)
                Hc = J.T @ HX @ J
                H[np.ix_(cols, cols)] += 0.5 * (Hc + Hc.T)
        return float(E), g, H

    def to_dict(self) -> dict:
        return {name: getattr(self, name) for name in _FIELDS}


#: the parameters of a strip, in their order
_FIELDS = tuple(f.name for f in fields(DiscreteStrip))


def discrete_strip_for(scene, n=None) -> DiscreteStrip:
    """The discrete model of a scene: the strip on the ground with gravity (``fig3-strip``)
    or the free rod without either (``supp-fig5``: ``ground = False``, q = 0).

    ``n`` defaults to the scene's impact resolution (``numerics.n_edges``, or the accuracy
    preset's edges when it is 0, as :func:`elastocap.impact.edge_count` resolves it; the
    impact's own checks of the wet interval at the scene's Delta do not apply to statics, which
    trace across Delta). For a centred drop on the free rod an odd n puts the gauge edge's
    midpoint on the drop's centre.
    """
    g, ground = scene.effects.gravity, scene.effects.ground
    if not ((g > 0.0 and ground) or (g == 0.0 and not ground)):
        raise ValueError(
            f"scene.effects: got gravity = {g}, ground = {ground}; the discrete statics needs "
            "gravity > 0 with ground = true (the strip) or gravity = 0 with ground = false "
            "(the free rod)"
        )
    if n is None:
        from elastocap.impact import edge_count

        n = edge_count(scene)
    d = scene.drop
    return DiscreteStrip(
        int(n), scene.rod.length, scene.distance_from_end, d.wetted_length, d.area,
        d.line_tension, scene.rod.bending_modulus, scene.rod.mass_per_length * g,
        thickness=float(scene.rod.thickness or 0.0), ground=bool(ground),
    )


def fix_gauge(strip: DiscreteStrip, u) -> np.ndarray:
    """The state u moved rigidly into the strip's gauge (a copy): for a free rod rotated
    so that the gauge edge's angle is 0, with z_0 = 0 (node 0 stays at the origin); on
    the ground, u unchanged."""
    u = np.array(u, dtype=float)
    if strip.ground:
        return u
    k = int(strip.gauge[1])
    u[1:] -= u[k]
    u[0] = 0.0
    return u


def flat_state(strip: DiscreteStrip) -> np.ndarray:
    """u of the straight strip lying on the ground."""
    return np.zeros(strip.size)


def flat_energy(area: float, gamma: float, delta: float) -> float:
    """gamma lambda(A, Delta): the drop on the straight strip (the impact's release state)."""
    return gamma * cap_geometry(area, delta)[3]


def is_encapsulated(strip: DiscreteStrip, u) -> bool:
    """The paper's criterion (Methods): the free end lies left of the impact centre."""
    X = strip.positions(u)
    s = strip.s_nodes
    xc = float(np.interp(strip.L - strip.x_end, s, X[:, 0]))
    return bool(X[-1, 0] < xc)


def strip_and_interface(strip: DiscreteStrip, u):
    """Node positions (n + 1, 2), the drop's interface (k, 2) from X(S1) to X(S2), and the
    chord d (length)."""
    X = strip.positions(u)
    s = strip.s_nodes
    p1 = np.array([np.interp(strip.s1, s, X[:, 0]), np.interp(strip.s1, s, X[:, 1])])
    p2 = np.array([np.interp(strip.s2, s, X[:, 0]), np.interp(strip.s2, s, X[:, 1])])
    d = float(np.hypot(*(p2 - p1)))
    a1 = strip.area - wet_polygon_area(X, s, strip.s1, strip.s2)
    tau = cap_geometry(a1, d)[0] if d > 0.0 else math.pi
    return X, arc_points(p1, p2, tau), d


def point_measures(strip: DiscreteStrip, u, flat: float | None = None) -> dict:
    """Observables of one state of the discrete strip.

    Keys: ``energy`` (energy units), ``energy_above_flat`` (energy minus gamma lambda of the
    drop on the straight strip at the same Delta), ``measure`` (theta(L)/pi: the turning of
    the strip, 0 flat, ~1 folded over), ``encapsulated`` (1.0/0.0, the paper's criterion:
    the free end left of the impact centre), ``tip_height`` z(L) (length), ``chord`` d
    (length), ``contacts`` (nodes at z <= 1e-12), ``rod_crossings`` (counts; nodes with
    |z| <= 1e-12 taken on the ground) and ``interface_crossings`` (counts), ``admissible``
    (1.0 when both are 0).
    """
    X, iface, d = strip_and_interface(strip, u)
    # nodes on the ground (z <= 1e-12, as ``contacts``) at exactly z = 0 for the rod's own
    # crossings: a stretch lying on the ground over another (the folded tail back on the
    # ground over the base) then touches it (parallel segments), instead of crossing it or
    # not as the round-off of heights ~1e-13 falls (measured: x = 4, Delta = 0.3, n = 198,
    # tail nodes 192-198 at |z| ~ 2e-13 over nodes 113-130)
    Xg = X.copy()
    Xg[np.abs(Xg[:, 1]) <= 1e-12, 1] = 0.0
    rod_x = int(count_crossings(Xg, Xg, True, 0, len(Xg)))
    if_x = int(count_crossings(iface, X, False, 1, len(iface) - 2))
    e = strip.energy(u)
    if flat is None:
        flat = flat_energy(strip.area, strip.gamma, strip.delta)
    return {
        "energy": float(e),
        "energy_above_flat": float(e - flat),
        "measure": float(u[-1] / math.pi),
        "encapsulated": float(is_encapsulated(strip, u)),
        "tip_height": float(X[-1, 1]),
        "chord": d,
        "contacts": int(np.sum(X[:, 1] <= 1e-12)),
        "rod_crossings": rod_x,
        "interface_crossings": if_x,
        "admissible": float(rod_x == 0 and if_x == 0),
    }


# --------------------------------------------------------------------------- self-contact
def _pair_edges(i, j):
    """The edges m between segment j and node i, and the sign s with X_i - X_j =
    s h sum_m (cos, sin) theta_m: m = j .. i - 1 (s = +1) for i > j + 1, m = i .. j - 1
    (s = -1) for i < j."""
    return (np.arange(j, i), 1.0) if i > j else (np.arange(i, j), -1.0)


def _as_pairs(pairs) -> np.ndarray:
    P = np.asarray(pairs, dtype=np.int64).reshape(-1, 3)
    return P


def pair_gaps(strip: DiscreteStrip, u, pairs):
    """Gaps of the self-contact pairs and where each one's form holds.

    Parameters
    ----------
    strip : DiscreteStrip
    u : ndarray, shape (n + 1,)
    pairs : array_like of int, shape (m, 3)
        (i, j, sigma): with sigma = +-1 a *line* pair, node i on the side sigma of segment j
        (nodes j, j + 1); with sigma = 0 a *point* pair, node i against node j (the closest
        point of the strip to node i is the vertex j).

    Returns
    -------
    gap : ndarray, shape (m,)
        Line pair: sigma n_j . (X_i - X_j) - d, the distance to the segment's line minus the
        thickness on the pair's side (negative inside the tube or across); point pair:
        |X_i - X_j| - d (length).
    region : ndarray, shape (m,)
        >= 0 while the pair's form is the distance to the strip: line pair, min(w, 1 - w)
        with w the foot's position along the segment (0 at node j, 1 at node j + 1); point
        pair, min(-(X_i - X_j) . t_j, (X_i - X_j) . t_{j-1}) / h over the edges at node j
        (t the unit tangents; the foot on neither edge).
    """
    P = _as_pairs(pairs)
    X = strip.positions(u)
    th = np.asarray(u[1:], dtype=float)
    gap = np.empty(P.shape[0])
    region = np.empty(P.shape[0])
    h = strip.h
    for a, (i, j, sg) in enumerate(P):
        D = X[i] - X[j]
        if sg != 0:
            gap[a] = sg * (-math.sin(th[j]) * D[0] + math.cos(th[j]) * D[1]) - strip.thickness
            w = (math.cos(th[j]) * D[0] + math.sin(th[j]) * D[1]) / h
            region[a] = min(w, 1.0 - w)
        else:
            gap[a] = math.hypot(D[0], D[1]) - strip.thickness
            r = math.inf
            if j < strip.n:
                r = -(math.cos(th[j]) * D[0] + math.sin(th[j]) * D[1]) / h
            if j >= 1:
                r = min(r, (math.cos(th[j - 1]) * D[0] + math.sin(th[j - 1]) * D[1]) / h)
            region[a] = r
    return gap, region


def _point_parts(strip, th, i, k, X):
    """X_i - X_k, the edges m between them, dD/dtheta_m (2, |M|) and the sign s."""
    m, s = _pair_edges(int(i), int(k))
    D = X[i] - X[k]
    dD = s * strip.h * np.vstack([-np.sin(th[m]), np.cos(th[m])])
    return D, m, dD, s


def pair_jacobian(strip: DiscreteStrip, u, pairs) -> np.ndarray:
    """d gap / du of the pairs, shape (m, n + 1) (column 0, z_0, is zero: a gap does not
    depend on a translation).

    Line pair: with d = s h sum_m sin(theta_m - theta_j) (edges m of :func:`_pair_edges`),
    d d / d theta_m = s h cos(theta_m - theta_j), d d / d theta_j = -s h sum_m cos(theta_m
    - theta_j); times sigma. Point pair: d|D| / d theta_m = D . dD/dtheta_m / |D|.
    """
    P = _as_pairs(pairs)
    th = np.asarray(u[1:], dtype=float)
    out = np.zeros((P.shape[0], strip.size))
    X = None
    for a, (i, j, sg) in enumerate(P):
        if sg != 0:
            m, s = _pair_edges(int(i), int(j))
            c = sg * s * strip.h * np.cos(th[m] - th[j])
            out[a, 1 + m] += c
            out[a, 1 + j] -= float(np.sum(c))
        else:
            X = strip.positions(u) if X is None else X
            D, m, dD, _s = _point_parts(strip, th, i, j, X)
            out[a, 1 + m] = (D @ dD) / math.hypot(D[0], D[1])
    return out


def pair_hessian(strip: DiscreteStrip, u, pairs, mu) -> np.ndarray:
    """sum_p mu_p d^2 gap_p / du^2, shape (n + 1, n + 1) (mu: force, shape (m,)).

    Line pair, with c_m = sigma s h sin(theta_m - theta_j): d^2 / d theta_m^2 = -c_m,
    d^2 / d theta_m d theta_j = +c_m, d^2 / d theta_j^2 = -sum_m c_m (m over the edges of
    :func:`_pair_edges`; the term m = j vanishes). Point pair, rho = |D|:
    d^2 rho = (dD^T dD + D . d^2 D) / rho - grad rho grad rho^T / rho, with d^2 D /
    d theta_m^2 = -s h (cos, sin) theta_m (diagonal)."""
    P = _as_pairs(pairs)
    th = np.asarray(u[1:], dtype=float)
    H = np.zeros((strip.size, strip.size))
    X = None
    for (i, j, sg), f in zip(P, np.asarray(mu, dtype=float), strict=True):
        if f == 0.0:
            continue
        if sg != 0:
            m, s = _pair_edges(int(i), int(j))
            c = f * sg * s * strip.h * np.sin(th[m] - th[j])
            H[1 + m, 1 + m] -= c
            H[1 + m, 1 + j] += c
            H[1 + j, 1 + m] += c
            H[1 + j, 1 + j] -= float(np.sum(c))
        else:
            X = strip.positions(u) if X is None else X
            D, m, dD, s = _point_parts(strip, th, i, j, X)
            rho = math.hypot(D[0], D[1])
            gr = (D @ dD) / rho
            d2 = -s * strip.h * (D[0] * np.cos(th[m]) + D[1] * np.sin(th[m]))
            blk = (dD.T @ dD - np.outer(gr, gr)) / rho
            blk[np.diag_indices_from(blk)] += d2 / rho
            H[np.ix_(1 + m, 1 + m)] += f * blk
    return H


#: Two layers lying on each other at an angle below this (|sin|) make the pairs of one
#: layer's nodes on the other's segments and those the other way redundant (exactly so
#: when parallel: a singular KKT matrix); one direction is held (:func:`redundant_pair`).
#: A node of the other direction can then sit inside the tube by at most ~ d sin^2 / 2
#: (1.25e-3 d here, 2e-5 at the paper's d = 0.0157).
REDUNDANT_SIN = 0.05


def redundant_pair(u, i, j, held) -> bool:
    """Whether the line pair (node i, segment j) is redundant with a held one: a node of
    segment j (j or j + 1) held by a line pair on a segment ending at node i (i - 1 or i)
    that is parallel to segment j within :data:`REDUNDANT_SIN`.

    ``held``: mapping node -> (segment, sigma) of the held pairs."""
    th = u[1:]
    for k in (j, j + 1):
        m, sg = held.get(int(k), (-9, 0))[:2]
        if sg != 0 and m in (i - 1, i) and abs(math.sin(th[m] - th[j])) < REDUNDANT_SIN:
            return True
    return False


def pair_switch(strip: DiscreteStrip, u, pair):
    """The pair that continues ``pair`` (i, j, sigma) once its form stops holding (its
    ``region`` of :func:`pair_gaps` reaches 0), with the same gap there.

    A line pair whose foot reaches node k (an end of its segment) moves to the next
    segment when that one continues the line (|theta difference| < 1e-12: the stretch lying
    flat on the ground), else becomes the point pair (i, k, 0). A point pair becomes the
    line pair of the edge at k that the node's foot enters, on the node's side of it.
    Returns None where no such pair exists (the strip's end).
    """
    i, j, sg = (int(a) for a in pair)
    th = np.asarray(u[1:], dtype=float)
    X = strip.positions(u)
    D = X[i] - X[j]
    if sg != 0:
        w = (math.cos(th[j]) * D[0] + math.sin(th[j]) * D[1]) / strip.h
        k, nxt = (j, j - 1) if w < 0.5 else (j + 1, j + 1)
        if 0 <= nxt < strip.n and abs(th[nxt] - th[j]) < 1e-12 and nxt != i and nxt + 1 != i:
            return (i, nxt, sg)
        return (i, k, 0) if k != i else None
    # point pair: the edge the foot enters (the one D has a positive projection on)
    fwd = j < strip.n and (math.cos(th[j]) * D[0] + math.sin(th[j]) * D[1]) > 0.0
    e = j if fwd else j - 1
    if e < 0 or e >= strip.n or e == i or e + 1 == i:
        return None
    E = X[i] - X[e]
    side = -math.sin(th[e]) * E[0] + math.cos(th[e]) * E[1]
    return (i, e, 1 if side >= 0.0 else -1)


@numba.njit(cache=True)
def _closest_segments(X, s_nodes, lex, out_j, out_dist, out_d, out_w):
    n1 = X.shape[0]
    for i in range(n1):
        best = np.inf
        for j in range(n1 - 1):
            if j > i:
                if s_nodes[j] - s_nodes[i] < lex:
                    continue
            elif j + 1 < i:
                if s_nodes[i] - s_nodes[j + 1] < lex:
                    continue
            else:
                continue
            ax, az = X[j, 0], X[j, 1]
            ex, ez = X[j + 1, 0] - ax, X[j + 1, 1] - az
            px, pz = X[i, 0] - ax, X[i, 1] - az
            l2 = ex * ex + ez * ez
            w = (px * ex + pz * ez) / l2
            wc = min(max(w, 0.0), 1.0)
            qx, qz = px - wc * ex, pz - wc * ez
            dist = math.sqrt(qx * qx + qz * qz)
            if dist < best:
                best = dist
                out_j[i] = j
                out_dist[i] = dist
                out_d[i] = (ex * pz - ez * px) / math.sqrt(l2)  # signed, to the left
                out_w[i] = w
    return out_j


def closest_segments(strip: DiscreteStrip, u, X=None):
    """For every node, the nearest segment it is tested against (arc-length gap >= pi d / 2,
    as ``dynamics.contact``), by brute force, O(n^2).

    Returns
    -------
    j : ndarray of int, shape (n + 1,)
        The segment (-1 where none is tested).
    dist : ndarray, shape (n + 1,)
        Distance to it (length; inf where none).
    d : ndarray, shape (n + 1,)
        Signed distance to its line, positive on the left of the segment (n_j side).
    w : ndarray, shape (n + 1,)
        Position of the foot along it (unclamped).
    """
    if X is None:
        X = strip.positions(u)
    n1 = X.shape[0]
    j = np.full(n1, -1, dtype=np.int64)
    dist = np.full(n1, np.inf)
    d = np.zeros(n1)
    w = np.zeros(n1)
    _closest_segments(X, strip.s_nodes, exclusion_length(strip.thickness), j, dist, d, w)
    return j, dist, d, w
