"""Equilibria of a free elastica carrying a quasi-static drop, without gravity.

Model and reduction
-------------------
Kirchhoff equations (paper, supplementary [2a]-[2d]) with the capillary load [6]-[8]: point
forces f1, f2 at S1, S2 and the Laplace pressure -gamma kappa q on S1 < S < S2. On a dry part
there is no load and the end is free, so the internal force n and moment m vanish there:
**the dry arms are straight**, tangent to the wet part at S1 and S2, and carry no energy. At
S1 and S2 the moment is continuous, so B theta' = 0 there, and the force jumps by f1, f2. The
equilibrium is therefore that of the wet part alone, a rod of length Delta with natural
(free) ends, loaded by the drop; the rod length L and the drop's position only place the
straight arms (they matter for admissibility and for the encapsulation measure, not for the
equilibrium or its stability). The reduced energy, as a function of the tangent angle
theta(s) on the wet part (x(S1) = 0), is

    E[theta] = (B/2) int_{S1}^{S2} theta'^2 ds + gamma lambda(A - A0[theta], d[theta]),

whose Euler-Lagrange equations are exactly the Kirchhoff equations above with the jump
conditions (variation of lambda: d lambda = cos(phi/2) dd + kappa dA1, see elastocap.drop).

Discretization
--------------
theta at the N+1 Chebyshev-Gauss-Lobatto points of [S1, S2]; x = int cos theta and
A0 = 1/2 int (x z' - z x') by the spectral integration matrix; the bending integral by
Clenshaw-Curtis quadrature. The discrete energy E_N is a smooth function of theta and the
equations are grad E_N = 0: the Jacobian is the Hessian itself (symmetric), folds are exactly
where it becomes singular, and stability is its inertia. E_N is invariant under rotations
(theta -> theta + c): the gauge theta_0 + theta_N = 0 fixes the orientation (the chord of a
mirror-symmetric shape is horizontal) and an unfolding multiplier omega (residual
grad E_N + omega 1; omega = 0 at every solution, to round-off) keeps the system square.
Unknowns u = (theta_0, ..., theta_N, omega). Convergence in N is spectral (measured in
tests/test_statics_convergence.py and the README).

Units: lengths in the scene unit, B and gamma as in the scene; energy per unit width.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numba
import numpy as np

from continuation import Problem
from elastocap.drop import cap_geometry, cap_tau_derivatives
from elastocap.statics.spectral import (
    cheb_diff,
    cheb_integ,
    cheb_interp_matrix,
    cheb_nodes,
    lgl_diff,
    lgl_integ,
    lgl_interp_matrix,
    lgl_nodes,
)

#: Node families: (nodes, differentiation, integration, interpolation).
NODES = {
    "lgl": (lgl_nodes, lgl_diff, lgl_integ, lgl_interp_matrix),
    "chebyshev": (cheb_nodes, cheb_diff, cheb_integ, cheb_interp_matrix),
}

__all__ = ["PARAMETERS", "WetElasticaProblem", "WetState"]

#: Scene keys a branch can be continued in, and the attribute of the problem they set.
PARAMETERS = {
    "drop.wetted_length": "delta",
    "drop.area": "area",
    "drop.line_tension": "gamma",
    "rod.bending_modulus": "B",
    "rod.length": "L",
    "drop.center": "center",
    "drop.distance_from_end": "x_end",
}


# ------------------------------------------------------------------------ compiled kernels
# The search evaluates the residual and the Hessian some thousands of times per diagram on
# matrices of size ~25: the cost is in the calls, not the arithmetic, so both are assembled
# in one compiled loop each (error_model="numpy": a zero chord gives inf/nan, not an
# exception; the callers diagnose non-finite values).
@numba.njit(cache=True, error_model="numpy")
def _weighted_q(c, s, Qh, wh):
    """(sum_k wh_k c_k Qh_kj, sum_k wh_k s_k Qh_kj) for every j."""
    n = c.size
    wcq = np.zeros(n)
    wsq = np.zeros(n)
    for k in range(n):
        a = wh[k] * c[k]
        b = wh[k] * s[k]
        for j in range(n):
            wcq[j] += a * Qh[k, j]
            wsq[j] += b * Qh[k, j]
    return wcq, wsq


@numba.njit(cache=True, error_model="numpy")
def wet_geometry(theta, Qh, wh, K, delta, area, gamma, B):
    """Positions, wet area, chord, cap, the gradients of A0 and d, and grad E_N for angles
    ``theta``.

    Returns ``(G, a0, d, tau, sin_tau, cos_tau, lam, kappa)`` with the rows of ``G`` (6,
    N+1) ``x, z, grad_a0, grad_d, k_theta, grad`` (see :class:`WetState`; ``k_theta = K
    theta``, ``grad = B (2/Delta) K theta + gamma (-kappa grad_a0 + cos(tau) grad_d)``; one
    array, so that one object is boxed per call); the formulas are those of the module
    docstring with ``Q = (Delta/2) Qh`` and ``w = (Delta/2) wh``.
    """
    n = theta.size
    N = n - 1
    h = 0.5 * delta
    c = np.cos(theta)
    s = np.sin(theta)
    G = np.empty((6, n))
    x = G[0]
    z = G[1]
    for i in range(n):
        ax = 0.0
        az = 0.0
        for k in range(n):
            ax += Qh[i, k] * c[k]
            az += Qh[i, k] * s[k]
        x[i] = h * ax
        z[i] = h * az
    a0 = 0.0
    for i in range(n):
        a0 += wh[i] * (x[i] * s[i] - z[i] * c[i])
    a0 *= 0.5 * h
    xN = x[N]
    zN = z[N]
    d = math.hypot(xN, zN)
    tau, st, ct, lam, kappa = cap_geometry(area - a0, d)
    # grad A0_j = -1/2 sum_k w_k Q_kj cos(th_k - th_j) + 1/2 w_j (x_j c_j + z_j s_j)
    wcq, wsq = _weighted_q(c, s, Qh, wh)
    h2 = h * h
    grad_a0 = G[2]
    grad_d = G[3]
    for j in range(n):
        grad_a0[j] = (-0.5 * h2 * (c[j] * wcq[j] + s[j] * wsq[j])
                      + 0.5 * h * wh[j] * (x[j] * c[j] + z[j] * s[j]))
        grad_d[j] = h * Qh[N, j] * (-xN * s[j] + zN * c[j]) / d
    bend = B * (2.0 / delta)
    k_theta = G[4]
    grad = G[5]
    for i in range(n):
        acc = 0.0
        for k in range(n):
            acc += K[i, k] * theta[k]
        k_theta[i] = acc
        grad[i] = bend * acc + gamma * (-kappa * grad_a0[i] + ct * grad_d[i])
    return G, a0, d, tau, st, ct, lam, kappa


@numba.njit(cache=True, error_model="numpy")
def wet_hessian_into(H, theta, G, Qh, wh, K, d, delta, gamma, B, cos_tau, kappa, l_aa,
                     l_ad, l_dd):
    """Write the Hessian of E_N in theta into ``H[:N+1, :N+1]`` (symmetric; ``G`` as
    returned by :func:`wet_geometry`):
    ``B (2/Delta) K + gamma (-kappa H_A0 + cos(tau) H_d + [gA gd] C2 [gA gd]^T)`` with
    ``C2 = [[L_AA, -L_Ad], [-L_Ad, L_dd]]`` (second derivatives of lambda)."""
    n = theta.size
    N = n - 1
    x = G[0]
    z = G[1]
    grad_a0 = G[2]
    grad_d = G[3]
    h = 0.5 * delta
    h2 = h * h
    c = np.cos(theta)
    s = np.sin(theta)
    bend = B * (2.0 / delta)
    xN = x[N]
    zN = z[N]
    for i in range(n):
        qi = Qh[N, i]
        for j in range(i, n):
            # H_A0 off the diagonal: 1/2 (w_i Q_ij - w_j Q_ji) sin(th_i - th_j)
            sij = s[i] * c[j] - c[i] * s[j]
            ha0 = 0.5 * h2 * (wh[i] * Qh[i, j] - wh[j] * Qh[j, i]) * sij
            # H_d = (G^T G - grad_d grad_d^T) / d, G = Q_N (-sin, cos)
            hd = (h2 * qi * Qh[N, j] * (s[i] * s[j] + c[i] * c[j])
                  - grad_d[i] * grad_d[j]) / d
            r2 = (l_aa * grad_a0[i] * grad_a0[j]
                  - l_ad * (grad_a0[i] * grad_d[j] + grad_d[i] * grad_a0[j])
                  + l_dd * grad_d[i] * grad_d[j])
            v = bend * K[i, j] + gamma * (-kappa * ha0 + cos_tau * hd + r2)
            H[i, j] = v
            H[j, i] = v
    wcq, wsq = _weighted_q(c, s, Qh, wh)
    for i in range(n):
        # the diagonal terms: -1/2 sum_k w_k Q_ki sin(th_k - th_i) + 1/2 w_i (z_i c_i - x_i s_i)
        da0 = 0.5 * h2 * (s[i] * wcq[i] - c[i] * wsq[i]) + 0.5 * h * wh[i] * (
            z[i] * c[i] - x[i] * s[i])
        dd = -h * Qh[N, i] * (xN * c[i] + zN * s[i]) / d
        H[i, i] += gamma * (-kappa * da0 + cos_tau * dd)


@lru_cache(maxsize=64)
def _uniform_interp(nodes: str, N: int, n: int) -> np.ndarray:
    M = NODES[nodes][3](N, np.linspace(-1.0, 1.0, n))
    M.setflags(write=False)
    return M


@dataclass
class WetState:
    """Geometry of one discrete equilibrium (all arrays on the N+1 nodes of the wet part)."""

    theta: np.ndarray
    x: np.ndarray
    z: np.ndarray
    a0: float
    d: float
    tau: float
    sin_tau: float
    cos_tau: float
    lam: float
    kappa: float
    grad_a0: np.ndarray
    grad_d: np.ndarray
    params: dict | None = None
    #: K theta and grad E_N (from :func:`wet_geometry`)
    k_theta: np.ndarray | None = None
    grad: np.ndarray | None = None
    #: second derivatives of lambda, computed once when first asked for
    second: tuple | None = None
    #: the rows x, z, grad_a0, grad_d, k_theta, grad in one array (:func:`wet_geometry`)
    geometry: np.ndarray | None = None


class WetElasticaProblem(Problem):
    """grad E_N = 0 for the wet part, continued in one scene parameter chosen by name.

    Parameters
    ----------
    N : int
        Chebyshev intervals on the wet part (N+1 nodes).
    delta, area, gamma, B : float
        Wetted length, drop area, line tension, bending modulus (scene units).
    L, center : float
        Rod length and arclength of the drop centre (place the dry arms only).
    parameter : str
        Scene key continued (see :data:`PARAMETERS`).
    """

    def __init__(
        self, N, delta, area, gamma, B, L, center, parameter="drop.wetted_length", nodes="lgl"
    ):
        if nodes not in NODES:
            raise ValueError(f"nodes: got {nodes!r}; expected one of {', '.join(NODES)}")
        if parameter not in PARAMETERS:
            raise ValueError(
                f"parameter: got {parameter!r}; expected one of {', '.join(PARAMETERS)}"
            )
        self.N = int(N)
        self.nodes = nodes
        f_nodes, f_diff, f_integ, self._f_interp = NODES[nodes]
        self.xi = f_nodes(self.N)
        self.Dh = f_diff(self.N)
        self.Qh = f_integ(self.N)
        self.wh = self.Qh[-1].copy()
        # bending stiffness matrix on [-1, 1]: int theta'^2 = (2/Delta) theta^T K theta
        self.K = self.Dh.T @ (self.wh[:, None] * self.Dh)
        self.params = {
            "delta": float(delta),
            "area": float(area),
            "gamma": float(gamma),
            "B": float(B),
            "L": float(L),
            "center": float(center),
        }
        self.parameter = parameter
        self.name = f"wet elastica (N={self.N}) in {parameter}"
        self.n = self.N + 2
        self._cache_key = None
        self._cache_val = None

    # -------------------------------------------------------------------- parameters
    def with_(self, parameter: str | None = None, N: int | None = None,
              nodes: str | None = None, **values) -> WetElasticaProblem:
        """A new problem with some scene keys changed (this one is not modified).

        ``values`` are scene keys (``P.with_(**{"drop.area": 1.2})``); ``parameter``
        chooses the continued key, ``N`` and ``nodes`` the discretization.
        """
        prm = dict(self.params)
        for key, value in values.items():
            if key not in PARAMETERS:
                raise ValueError(
                    f"{key}: not a parameter of the wet elastica; expected one of "
                    f"{', '.join(PARAMETERS)}")
            prm.update(self._assign(prm, key, value))
        return WetElasticaProblem(
            self.N if N is None else N,
            prm["delta"], prm["area"], prm["gamma"], prm["B"], prm["L"], prm["center"],
            self.parameter if parameter is None else parameter,
            self.nodes if nodes is None else nodes,
        )

    def with_parameter(self, parameter: str) -> WetElasticaProblem:
        """The same problem continued in another scene key."""
        return self.with_(parameter=parameter)

    @staticmethod
    def _assign(prm: dict, key: str, value: float) -> dict:
        attr = PARAMETERS[key]
        if attr == "x_end":
            return {"center": prm["L"] - float(value)}
        return {attr: float(value)}

    def params_at(self, p: float | None) -> dict:
        """The parameters with the continued key at value ``p`` (``None``: as built)."""
        if p is None:
            return self.params
        prm = self.params.copy()
        attr = PARAMETERS[self.parameter]
        if attr == "x_end":
            prm["center"] = prm["L"] - float(p)
        else:
            prm[attr] = float(p)
        return prm

    def interp_matrix(self, xi) -> np.ndarray:
        """Interpolation from the nodes to points ``xi`` of [-1, 1]."""
        return self._f_interp(self.N, xi)

    def uniform_interp_matrix(self, n: int) -> np.ndarray:
        """Interpolation from the nodes to ``n`` equispaced points of [-1, 1] (cached,
        read-only: the drawn shape of every recorded point uses it)."""
        return _uniform_interp(self.nodes, self.N, int(n))

    def get(self, key: str, p: float | None = None) -> float:
        """Value of a scene key (at continuation value ``p`` when given)."""
        prm = self.params_at(p)
        attr = PARAMETERS[key]
        if attr == "x_end":
            return prm["L"] - prm["center"]
        return prm[attr]

    # -------------------------------------------------------------------- seeds
    #: Total turning of the wet part of the seed shapes, in units of pi: the rod can turn
    #: by at most 2 pi around a drop before it crosses itself, so -2..2 at spacing 2 pi/3
    #: covers every admissible turning (both senses: curling towards the drop and away).
    SEED_TURNS = tuple(np.linspace(-2.0, 2.0, 7))
    #: Asymmetric perturbations b (xi^2 - 1/3) of each seed (the first odd mode of the
    #: angle about the gauge): 0 and 0.8, so mirror-asymmetric branches are seeded (the
    #: mirror image of a solution is a solution: one sign suffices).
    SEED_ASYMMETRIES = (0.0, 0.8)

    def seeds(self, p: float):
        """Seed shapes at ``p`` from the physics of the wet part.

        Uniformly curved wet parts with total turning ``M pi`` (``SEED_TURNS``, the
        admissible range of turning at spacing pi/3) and the *wrapping* arc: the wet part
        bent along the circle of the drop's own area (radius ``sqrt(A/pi)``, total
        turning ``Delta / R``, capped at 2 pi) in both senses; each with the asymmetric
        perturbations ``SEED_ASYMMETRIES``.
        """
        prm = self.params_at(p)
        R = math.sqrt(prm["area"] / math.pi)
        wrap = min(prm["delta"] / R, 2.0 * math.pi) / math.pi
        turns = sorted(set(self.SEED_TURNS) | {wrap, -wrap})
        xi = self.xi
        out = []
        for m in turns:
            for b in self.SEED_ASYMMETRIES:
                th = 0.5 * math.pi * m * xi + b * (xi * xi - 1.0 / 3.0)
                out.append(np.concatenate([th, [0.0]]))
        return out

    @property
    def deflation_indices(self) -> slice:
        """Deflation and damping act on the angles (not on the multiplier omega)."""
        return slice(0, self.N + 1)

    # -------------------------------------------------------------------- geometry
    def state(self, u: np.ndarray, p: float | None = None) -> WetState:
        """Geometry of the wet part for unknowns ``u`` (at parameter value ``p``)."""
        prm = self.params_at(p)
        key = (u.tobytes(), tuple(prm.values()))
        if key == self._cache_key:
            return self._cache_val
        th = u[: self.N + 1]
        if not th.flags.c_contiguous:
            th = np.ascontiguousarray(th)
        G, a0, d, tau, st, ct, lam, kappa = wet_geometry(
            th, self.Qh, self.wh, self.K, prm["delta"], prm["area"], prm["gamma"], prm["B"])
        st_ = WetState(th, G[0], G[1], a0, d, tau, st, ct, lam, kappa, G[2], G[3], prm,
                       G[4], G[5], geometry=G)
        self._cache_key, self._cache_val = key, st_
        return st_

    def energy(self, u, p=None) -> float:
        """E_N: bending of the wet part + gamma lambda (the arms are straight)."""
        S = self.state(u, p)
        th = S.theta
        prm = S.params
        return (
            0.5 * prm["B"] * (2.0 / prm["delta"]) * float(th @ self.K @ th)
            + prm["gamma"] * S.lam
        )

    def _grad(self, S):
        return S.grad

    def _lambda_second(self, S):
        """Second derivatives of lambda(A1, d): (L_AA, L_Ad, L_dd)."""
        if S.second is None:
            a1 = S.params["area"] - S.a0
            ta, td = cap_tau_derivatives(S.tau, S.sin_tau, S.cos_tau, a1, S.d)
            l_aa = 2.0 * S.cos_tau * ta / S.d
            l_ad = -S.sin_tau * ta
            l_dd = -S.sin_tau * td
            S.second = (l_aa, l_ad, l_dd, ta, td)
        return S.second

    # -------------------------------------------------------------------- Problem API
    def residual(self, u, p):
        S = self.state(u, p)
        r = np.empty(self.n)
        np.add(S.grad, u[-1], out=r[: self.N + 1])
        r[-1] = u[0] + u[self.N]
        return r

    def hessian(self, u, p):
        """Hessian of E_N in theta, shape (N+1, N+1) (symmetric)."""
        H = np.empty((self.N + 1, self.N + 1))
        self._hessian_into(H, u, p)
        return H

    def _hessian_into(self, H, u, p):
        S = self.state(u, p)
        prm = S.params
        l_aa, l_ad, l_dd, _ta, _td = self._lambda_second(S)
        wet_hessian_into(H, S.theta, S.geometry, self.Qh, self.wh, self.K, S.d,
                         prm["delta"], prm["gamma"], prm["B"], S.cos_tau, S.kappa,
                         l_aa, l_ad, l_dd)

    def jacobian(self, u, p):
        n = self.N + 1
        J = np.zeros((self.n, self.n))
        self._hessian_into(J, u, p)
        J[:n, n] = 1.0
        J[n, 0] = 1.0
        J[n, self.N] = 1.0
        return J

    def constraint_jacobian(self, u, p):
        """The gauge: perturbations with d theta_0 + d theta_N = 0 (rotations removed)."""
        C = np.zeros((1, self.N + 1))
        C[0, 0] = C[0, self.N] = 1.0
        return C

    def dfdp(self, u, p):
        S = self.state(u, p)
        B, gam, delta = S.params["B"], S.params["gamma"], S.params["delta"]
        key = PARAMETERS[self.parameter]
        out = np.zeros(self.n)
        if key == "B":
            out[: self.N + 1] = (2.0 / delta) * S.k_theta
        elif key == "gamma":
            out[: self.N + 1] = -S.kappa * S.grad_a0 + S.cos_tau * S.grad_d
        elif key == "area":
            l_aa, l_ad, _l_dd, _ta, _td = self._lambda_second(S)
            # d/dA of (-kappa grad A0 + cos tau grad d) at fixed theta, dA1/dA = 1
            out[: self.N + 1] = gam * (-l_aa * S.grad_a0 + l_ad * S.grad_d)
        elif key == "delta":
            l_aa, l_ad, l_dd, _ta, _td = self._lambda_second(S)
            # x, z, d scale like Delta; A0 like Delta^2; grad A0 ~ Delta^2; grad d ~ Delta
            da1 = -2.0 * S.a0 / delta
            dd = S.d / delta
            dkappa = l_aa * da1 + l_ad * dd
            dcos = l_ad * da1 + l_dd * dd
            out[: self.N + 1] = (
                (-B * (2.0 / delta**2)) * S.k_theta
                + (gam * (-dkappa - S.kappa * (2.0 / delta))) * S.grad_a0
                + (gam * (dcos + S.cos_tau / delta)) * S.grad_d
            )
        # rod.length, drop.center, drop.distance_from_end: the wet equilibrium does not move
        return out

    def observables(self, u, p):
        from elastocap.statics.shape import measures

        # the continuation records them and the admissibility event asks again: compute once
        key = (u.tobytes(), tuple(self.params_at(p).values()))
        if getattr(self, "_obs_key", None) != key:
            self._obs_key, self._obs_val = key, measures(self, u, p)
        return dict(self._obs_val)
