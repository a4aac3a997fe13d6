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
        prm = dict(self.params)
        prm.update(self._assign(prm, self.parameter, p))
        return prm

    def interp_matrix(self, xi) -> np.ndarray:
        """Interpolation from the nodes to points ``xi`` of [-1, 1]."""
        return self._f_interp(self.N, xi)

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
        h = 0.5 * prm["delta"]
        c, s = np.cos(th), np.sin(th)
        x = h * (self.Qh @ c)
        z = h * (self.Qh @ s)
        w = h * self.wh
        a0 = 0.5 * float(w @ (x * s - z * c))
        xN, zN = x[-1], z[-1]
        d = math.hypot(xN, zN)
        tau, st, ct, lam, kappa = cap_geometry(prm["area"] - a0, d)
        # grad A0_j = -1/2 sum_k w_k Q_kj cos(th_k - th_j) + 1/2 w_j (x_j c_j + z_j s_j)
        Q = h * self.Qh
        wc, ws = w * c, w * s
        grad_a0 = -0.5 * (c * (wc @ Q) + s * (ws @ Q)) + 0.5 * w * (x * c + z * s)
        grad_d = Q[-1] * (-xN * s + zN * c) / d
        st_ = WetState(th, x, z, a0, d, tau, st, ct, lam, kappa, grad_a0, grad_d, prm)
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
        prm = S.params
        B, gam, delta = prm["B"], prm["gamma"], prm["delta"]
        return B * (2.0 / delta) * (self.K @ S.theta) + gam * (
            -S.kappa * S.grad_a0 + S.cos_tau * S.grad_d
        )

    def _lambda_second(self, S):
        """Second derivatives of lambda(A1, d): (L_AA, L_Ad, L_dd)."""
        a1 = S.params["area"] - S.a0
        ta, td = cap_tau_derivatives(S.tau, S.sin_tau, S.cos_tau, a1, S.d)
        l_aa = 2.0 * S.cos_tau * ta / S.d
        l_ad = -S.sin_tau * ta
        l_dd = -S.sin_tau * td
        return l_aa, l_ad, l_dd, ta, td

    # -------------------------------------------------------------------- Problem API
    def residual(self, u, p):
        S = self.state(u, p)
        r = np.empty(self.n)
        r[: self.N + 1] = self._grad(S) + u[-1]
        r[-1] = u[0] + u[self.N]
        return r

    def hessian(self, u, p):
        """Hessian of E_N in theta, shape (N+1, N+1) (symmetric)."""
        S = self.state(u, p)
        B, gam, delta = S.params["B"], S.params["gamma"], S.params["delta"]
        h = 0.5 * delta
        th, x, z = S.theta, S.x, S.z
        c, s = np.cos(th), np.sin(th)
        Q = h * self.Qh
        w = h * self.wh
        # Hessian of A0 (symmetric): 1/2 w_i Q_ij sin(th_i - th_j) + transpose + diagonal
        # sin(th_i - th_j) = s_i c_j - c_i s_j: two outer products instead of N^2 sines
        M = 0.5 * (w[:, None] * Q) * (np.multiply.outer(s, c) - np.multiply.outer(c, s))
        H_a0 = M + M.T
        wc, ws = w * c, w * s
        diag = 0.5 * (s * (wc @ Q) - c * (ws @ Q)) + 0.5 * w * (z * c - x * s)
        # the k-sum term: -1/2 delta_ij sum_k w_k Q_kj sin(th_k - th_j)
        H_a0.flat[:: H_a0.shape[0] + 1] += diag
        # Hessian of d
        xN, zN, d = x[-1], z[-1], S.d
        gx = -Q[-1] * s
        gz = Q[-1] * c
        G = np.stack([gx, gz])
        H_d = (G.T @ G - np.multiply.outer(S.grad_d, S.grad_d)) / d
        H_d.flat[:: H_d.shape[0] + 1] += (-xN * Q[-1] * c - zN * Q[-1] * s) / d
        l_aa, l_ad, l_dd, _ta, _td = self._lambda_second(S)
        ga, gd = S.grad_a0, S.grad_d
        # the rank-2 part [ga gd] [[l_aa, -l_ad], [-l_ad, l_dd]] [ga gd]^T in one product
        V = np.stack([ga, gd])
        C2 = np.array([[l_aa, -l_ad], [-l_ad, l_dd]])
        H_cap = -S.kappa * H_a0 + S.cos_tau * H_d + V.T @ C2 @ V
        return B * (2.0 / delta) * self.K + gam * H_cap

    def jacobian(self, u, p):
        n = self.N + 1
        J = np.zeros((self.n, self.n))
        J[:n, :n] = self.hessian(u, p)
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
        cap = -S.kappa * S.grad_a0 + S.cos_tau * S.grad_d
        if key == "B":
            out[: self.N + 1] = (2.0 / delta) * (self.K @ S.theta)
        elif key == "gamma":
            out[: self.N + 1] = cap
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
            bend = -B * (2.0 / delta**2) * (self.K @ S.theta)
            out[: self.N + 1] = bend + gam * (
                -dkappa * S.grad_a0
                - S.kappa * (2.0 / delta) * S.grad_a0
                + dcos * S.grad_d
                + S.cos_tau * S.grad_d / delta
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
