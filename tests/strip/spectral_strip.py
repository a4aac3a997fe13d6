"""Test oracle: the spectral one-topology strip (flat on [0, s_c], lifted beyond).

An independent discretization of the strip of Fig 3, kept in the tests only: the shipped
model is the discrete any-topology strip (:mod:`elastocap.strip.model`). The tests check
this solver against closed forms (a heavy strip lifted by an end force: linear theory and
shooting) and then use it as the reference the discrete strip converges to at order 2.

Model
-----
Units g = mu = B = 1 in the built-in ``fig3-strip`` scene (length l_eg); here B, q = mu g,
gamma are kept as parameters. The strip [0, L] lies flat on the rigid ground z = 0 on
[0, s_c] and is lifted on [s_c, L]; the drop wets [S1, S2] with S1 = L - x - Delta/2,
S2 = L - x + Delta/2 and s_c < S1 (paper, main text eq. [1] and supplementary [2]-[8]).
The flat part is straight, unloaded in bending and holds no energy (z = 0, theta = 0), so
the energy is that of the lifted part,

    E[theta, s_c] = int_{s_c}^{L} [(B/2) theta'^2 + q (L - s) sin theta] ds
                    + gamma lambda(A - A0[theta], d[theta]) - F z(L),

where the gravity term int q z ds was integrated by parts with z(s_c) = 0, and F is an
optional vertical point force at the free end (0 in the scene; used for the closed-form
test of a strip lifted off a table). Tangent angle theta, positions x = x(s_c) + int cos,
z = int sin; the horizontal translation x(s_c) is free (frictionless ground): it is gauged
by x(s_c) = 0, so that E has no zero mode.

Lift-off conditions (free boundary s_c, inextensible rod, rigid frictionless plane, no
adhesion): theta(s_c) = 0 and z(s_c) = 0 (continuity with the flat part), and the
transversality condition. Varying s_c with theta(s_c) = 0 maintained
(delta theta(s_c) = -theta'(s_c) delta s_c) gives

    dE = [B theta' delta theta - (B/2) theta'^2 delta s_c]_{s_c} = (B/2) theta'(s_c)^2 delta s_c,

so stationarity requires **theta'(s_c) = 0: zero curvature at lift-off** (with an adhesion
energy w it would be (B/2) kappa^2 = w). The ground transmits no horizontal force, and the
flat part no moment, so the lifted part receives only a vertical point reaction
R = q (L - s_c) + F >= 0 at s_c.

That condition is a *double* root of dE/ds_c: imposing dE/ds_c = 0 as an equation gives a
Jacobian that is singular at every equilibrium (the reduced energy E(s_c) has an
inflection there, and a discretization error splits the root into two or none). We
therefore impose its square root theta'(s_c) = 0 as the equation for s_c. The Jacobian is
then regular but not symmetric; the stability index is computed from the energy instead
(see :meth:`StripProblem.hessian`).

Discretization
--------------
theta at Legendre-Gauss-Lobatto nodes on three segments [s_c, S1], [S1, S2], [S2, L]
(N1, N2, N3 intervals), sharing their end nodes (continuity of theta at S1, S2 is built
in; theta' is continuous weakly, as a natural condition). The first segment stretches with
s_c. Bending by the exact LGL quadrature of theta'^2, gravity by LGL quadrature of
(L - s) sin theta, the capillary part on [S1, S2] by :class:`WetElasticaProblem` (which
reuses ``elastocap.drop.cap_geometry`` / ``cap_tau_derivatives``). Unknowns
u = (theta_1, ..., theta_M, s_c) (theta_0 = 0 eliminated). Equations:
dE_N/dtheta_i = 0 (i = 1..M; the natural conditions theta' = 0 at S = L come out of the
variation) and theta'(s_c) = 0. Jacobian analytic (tested against finite differences);
dF/dp by central differences (the parameters enter through the segment lengths and node
positions; this affects only the tangent predictor and the fold location's Newton rate).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from continuation import Problem
from elastocap.scene import Scene, SceneError
from elastocap.statics.spectral import lgl_diff, lgl_integ, lgl_interp_matrix, lgl_nodes
from elastocap.statics.wet_elastica import WetElasticaProblem

__all__ = ["PARAMETERS", "STRIP_N", "StripProblem", "StripState", "refine_state", "seeds",
           "shape_at", "strip_problem_for"]

#: Scene keys a strip branch can be continued in, and the attribute they set.
PARAMETERS = {
    "drop.wetted_length": "delta",
    "drop.distance_from_end": "x_end",
    "drop.area": "area",
    "drop.line_tension": "gamma",
    "end_force": "F",
    "tip_angle": "Theta",
}

# Relative central-difference step for dF/dp: eps^(1/3) balances truncation and rounding.
_FD_P = np.finfo(float).eps ** (1.0 / 3.0)


@dataclass
class StripState:
    """Geometry of one configuration of the lifted part (arrays on the M+1 global nodes)."""

    theta: np.ndarray
    s: np.ndarray
    x: np.ndarray
    z: np.ndarray
    s_c: float
    lengths: tuple


class StripProblem(Problem):
    """grad E_N = 0 and theta'(s_c) = 0 for the lifted strip, continued in one key.

    Parameters
    ----------
    N : int or (int, int, int)
        LGL intervals on [s_c, S1], [S1, S2], [S2, L] (one int: the same on each).
    L : float
        Strip length (scene length unit).
    x_end : float
        Distance x of the drop centre from the free end S = L.
    delta, area, gamma : float
        Wetted length Delta, drop area A (length^2), line tension gamma (force).
    B : float
        Bending modulus (force length^2).
    q : float
        Weight per unit length mu g (force / length).
    F : float
        Vertical point force at S = L (force), 0 for the scene.
    parameter : str
        Key continued (:data:`PARAMETERS`).
    tip_angle : float or None
        When given, the tip angle theta(L) is prescribed (a couple C at the free end is an
        extra unknown, the last entry of u before s_c): the equilibria of E at prescribed
        theta(L) (a least-energy path at prescribed tip angle). C = 0
        on such a path is a true equilibrium.
    """

    def __init__(self, N, L, x_end, delta, area, gamma, B=1.0, q=1.0, F=0.0,
                 parameter="drop.wetted_length", tip_angle=None):
        if parameter not in PARAMETERS:
            raise ValueError(
                f"parameter: got {parameter!r}; expected one of {', '.join(PARAMETERS)}"
            )
        Ns = (int(N),) * 3 if np.ndim(N) == 0 else tuple(int(v) for v in N)
        if len(Ns) != 3 or min(Ns) < 2:
            raise ValueError(f"N: got {N!r}; expected an int >= 2 or three of them")
        self.Ns = Ns
        self.offsets = (0, Ns[0], Ns[0] + Ns[1])
        self.M = sum(Ns)
        self.xi = [lgl_nodes(k) for k in Ns]
        self.D = [lgl_diff(k) for k in Ns]
        self.Q = [lgl_integ(k) for k in Ns]
        self.w = [q_[-1].copy() for q_ in self.Q]
        self.K = [d.T @ (w[:, None] * d) for d, w in zip(self.D, self.w, strict=True)]
        self.params = {
            "L": float(L), "x_end": float(x_end), "delta": float(delta), "area": float(area),
            "gamma": float(gamma), "B": float(B), "q": float(q), "F": float(F),
            "Theta": math.nan if tip_angle is None else float(tip_angle),
        }
        self.constrained = tip_angle is not None
        self.parameter = parameter
        self.n = self.M + 1 + int(self.constrained)
        # the theta unknowns for elastocap.statics.branches.newton (it damps u[:N+1])
        self.N = self.M - 1
        self.name = f"lifted strip (N={Ns}) in {parameter}"
        self._wet = WetElasticaProblem(Ns[1], delta, area, gamma, 0.0, L, 0.0)
        self._check()

    # ------------------------------------------------------------------ parameters
    def _check(self):
        p = self.params
        if not p["x_end"] - 0.5 * p["delta"] > 0.0:
            raise ValueError(
                f"drop.distance_from_end: got x = {p['x_end']}; the drop must not reach the "
                f"free end (x > Delta/2 = {0.5 * p['delta']})"
            )

    def get(self, key: str) -> float:
        return self.params[PARAMETERS[key]]

    def set(self, key: str, value: float) -> None:
        attr = PARAMETERS[key]
        self.params[attr] = float(value)
        if attr in ("delta", "area", "gamma"):
            self._wet.params[attr] = float(value)
            self._wet._cache_key = None

    def _with_p(self, p):
        if p is not None and p != self.get(self.parameter):
            self.set(self.parameter, p)

    def copy(self, parameter=None, N=None) -> StripProblem:
        """The same problem (optionally another key or resolution)."""
        p = self.params
        return StripProblem(N or self.Ns, p["L"], p["x_end"], p["delta"], p["area"],
                            p["gamma"], p["B"], p["q"], p["F"], parameter or self.parameter,
                            None if not self.constrained else p["Theta"])

    @property
    def s1(self) -> float:
        p = self.params
        return p["L"] - p["x_end"] - 0.5 * p["delta"]

    @property
    def s2(self) -> float:
        p = self.params
        return p["L"] - p["x_end"] + 0.5 * p["delta"]

    # ------------------------------------------------------------------ geometry
    def full_theta(self, u) -> np.ndarray:
        return np.concatenate([[0.0], u[: self.M]])

    def segments(self, u):
        """(start, length) of the three segments for unknowns u."""
        s_c = float(u[-1])
        return ((s_c, self.s1 - s_c), (self.s1, self.params["delta"]),
                (self.s2, self.params["L"] - self.s2))

    def _slices(self):
        return [slice(o, o + n + 1) for o, n in zip(self.offsets, self.Ns, strict=True)]

    def state(self, u, p=None) -> StripState:
        """Arclengths and positions at the global nodes (x(s_c) = z(s_c) = 0)."""
        self._with_p(p)
        th = self.full_theta(u)
        s = np.empty(self.M + 1)
        x = np.empty(self.M + 1)
        z = np.empty(self.M + 1)
        X = Z = 0.0
        for k, (sl, (a, ell)) in enumerate(zip(self._slices(), self.segments(u), strict=True)):
            h = 0.5 * ell
            tk = th[sl]
            s[sl] = a + h * (self.xi[k] + 1.0)
            x[sl] = X + h * (self.Q[k] @ np.cos(tk))
            z[sl] = Z + h * (self.Q[k] @ np.sin(tk))
            X, Z = x[sl][-1], z[sl][-1]
        return StripState(th, s, x, z, float(u[-1]), tuple(e for _, e in self.segments(u)))

    def interp(self, u, n_per_segment=60):
        """Dense points (s, x, z) of the lifted part, for drawing and admissibility checks."""
        st = self.state(u)
        out_s, out_x, out_z = [], [], []
        for k, sl in enumerate(self._slices()):
            xi = np.linspace(-1.0, 1.0, n_per_segment)
            Mi = lgl_interp_matrix(self.Ns[k], xi)
            out_s.append(Mi @ st.s[sl])
            out_x.append(Mi @ st.x[sl])
            out_z.append(Mi @ st.z[sl])
        return np.concatenate(out_s), np.concatenate(out_x), np.concatenate(out_z)

    # ------------------------------------------------------------------ energy
    def energy_parts(self, u, p=None) -> dict:
        """Bending, gravity, capillary and end-force energies (energy units B / length)."""
        self._with_p(p)
        prm = self.params
        th = self.full_theta(u)
        bend = grav = zend = 0.0
        for k, (sl, (a, ell)) in enumerate(zip(self._slices(), self.segments(u), strict=True)):
            h = 0.5 * ell
            tk = th[sl]
            sk = a + h * (self.xi[k] + 1.0)
            bend += (prm["B"] / ell) * float(tk @ self.K[k] @ tk)
            grav += prm["q"] * h * float(self.w[k] @ ((prm["L"] - sk) * np.sin(tk)))
            zend += h * float(self.w[k] @ np.sin(tk))
        wet_u = np.concatenate([th[self._slices()[1]], [0.0]])
        cap = prm["gamma"] * self._wet.state(wet_u).lam
        return {"bending": bend, "gravity": grav, "capillary": cap, "end_force": -prm["F"] * zend}

    def energy(self, u, p=None) -> float:
        return float(sum(self.energy_parts(u, p).values()))

    def _pieces(self, u):
        """Gradient in the full theta (M+1), its s_c derivative, and the theta-Hessian."""
        prm = self.params
        B, q, F, L = prm["B"], prm["q"], prm["F"], prm["L"]
        th = self.full_theta(u)
        g = np.zeros(self.M + 1)
        g_s = np.zeros(self.M + 1)
        H = np.zeros((self.M + 1, self.M + 1))
        for k, (sl, (a, ell)) in enumerate(zip(self._slices(), self.segments(u), strict=True)):
            h = 0.5 * ell
            tk = th[sl]
            c, sn = np.cos(tk), np.sin(tk)
            xi, w = self.xi[k], self.w[k]
            sk = a + h * (xi + 1.0)
            Kt = self.K[k] @ tk
            g[sl] += (2.0 * B / ell) * Kt + h * w * (q * (L - sk) - F) * c
            H[sl, sl] += (2.0 * B / ell) * self.K[k]
            H[sl, sl][np.diag_indices(len(tk))] += -h * w * (q * (L - sk) - F) * sn
            if k == 0:
                # ell_1 = S1 - s_c, h = ell_1/2, s_j = s_c + h (xi_j + 1): d/ds_c
                g_s[sl] += (2.0 * B / ell**2) * Kt + w * c * (
                    -0.5 * (q * (L - sk) - F) - q * h * 0.5 * (1.0 - xi)
                )
        sl2 = self._slices()[1]
        wet_u = np.concatenate([th[sl2], [0.0]])
        S = self._wet.state(wet_u)
        g[sl2] += self._wet._grad(S)
        H[sl2, sl2] += self._wet.hessian(wet_u, None)
        return g, g_s, H

    def _lift_curvature(self, u):
        """theta'(s_c) and its derivatives in theta (segment 1 nodes) and s_c."""
        ell = self.s1 - float(u[-1])
        n1 = self.Ns[0] + 1
        row = (2.0 / ell) * self.D[0][0]
        th1 = self.full_theta(u)[:n1]
        kap = float(row @ th1)
        return kap, row, kap / ell

    # ------------------------------------------------------------------ Problem API
    def residual(self, u, p):
        self._with_p(p)
        g, _gs, _H = self._pieces(u)
        r = np.empty(self.n)
        r[: self.M] = g[1:]
        # B theta'(s_c): the bending moment at lift-off, in force units like the rest
        r[-1] = self.params["B"] * self._lift_curvature(u)[0]
        if self.constrained:
            # Lagrangian E - C (theta(L) - Theta): C is the couple applied at S = L
            r[self.M - 1] -= u[self.M]
            r[self.M] = u[self.M - 1] - self.params["Theta"]
        return r

    def jacobian(self, u, p):
        self._with_p(p)
        _g, g_s, H = self._pieces(u)
        J = np.zeros((self.n, self.n))
        J[: self.M, : self.M] = H[1:, 1:]
        J[: self.M, -1] = g_s[1:]
        _k, row, dk_ds = self._lift_curvature(u)
        B = self.params["B"]
        J[-1, : self.Ns[0]] = B * row[1:]
        J[-1, -1] = B * dk_ds
        if self.constrained:
            J[self.M - 1, self.M] = -1.0
            J[self.M, self.M - 1] = 1.0
        return J

    def hessian(self, u, p):
        """A symmetric matrix whose inertia is the stability index (size n).

        Block-diagonal (H, sigma): H = d2E/dtheta2 at fixed s_c (theta_0 = 0), and
        sigma = d theta'(s_c)/d s_c along the equilibria at fixed s_c of the theta
        equations (the Schur complement of the Jacobian). The reduced energy E(s_c)
        satisfies dE/ds_c = (B/2) theta'(s_c)^2, and shapes lifted beyond the lift-off
        point are admissible only with theta'(s_c) >= 0 (z >= 0 near s_c): the lift-off
        point is stable when sigma > 0 (peeling further would need negative curvature),
        unstable when sigma < 0 (peeling further lowers the energy). The index is
        (negative eigenvalues of H) + (1 if sigma < 0), and det J = B det H sigma, so it
        changes by one exactly at the folds of the full system.
        """
        J = self.jacobian(u, p)
        # with a prescribed tip angle theta(L) (the last theta) is not free
        m = self.M - 1 if self.constrained else self.M
        H = J[:m, :m]
        H = 0.5 * (H + H.T)
        b = J[:m, -1]
        r = J[-1, :m]
        sigma = (J[-1, -1] - r @ np.linalg.solve(H, b)) / self.params["B"]
        out = np.eye(self.n)  # the entries beyond H are positive placeholders
        out[:m, :m] = H
        out[-1, -1] = sigma
        return out

    def dfdp(self, u, p):
        """Central differences in the parameter (relative step eps^(1/3))."""
        p0 = self.get(self.parameter) if p is None else float(p)
        h = _FD_P * max(1.0, abs(p0))
        rp = self.residual(u, p0 + h)
        rm = self.residual(u, p0 - h)
        self.set(self.parameter, p0)
        return (rp - rm) / (2.0 * h)

    def observables(self, u, p):
        """``energy``, ``lift_off`` s_c, ``measure`` theta(L)/pi, ``encapsulation``
        x(L - x) - x(L) (> 0: the paper's criterion), ``end_height`` z(L), ``reaction`` at
        s_c (force)."""
        self._with_p(p)
        st = self.state(u)
        sl = self._slices()[1]
        x_mid = float((lgl_interp_matrix(self.Ns[1], np.array([0.0])) @ st.x[sl])[0])
        prm = self.params
        return {"energy": self.energy(u), "lift_off": float(u[-1]),
                "measure": float(st.theta[-1] / math.pi),
                "encapsulation": x_mid - float(st.x[-1]), "end_height": float(st.z[-1]),
                "reaction": prm["q"] * (prm["L"] - float(u[-1])) + prm["F"]}


# --------------------------------------------------------------------------- scene, seeds, shapes
_SEED_WRAP = (0.5 * math.pi, math.pi, 1.25 * math.pi)
_SEED_TAIL = (0.0, 0.6)
_SEED_DRY = (0.1, 0.4, 1.0, 2.0, 3.5)

#: LGL intervals per segment per accuracy preset. Measured (tests/strip, README text):
#: the lift-off point of the wrapped state at x = 2, Delta = 1.16 converges spectrally,
#: error 2.5e-9 at N = 8, 2e-10 at N = 12, round-off at N = 16.
STRIP_N = {"draft": 10, "default": 14, "publication": 20}


def _check_scene(scene: Scene) -> None:
    if not (scene.effects.gravity > 0.0 and scene.effects.ground):
        raise SceneError(
            "effects",
            {"gravity": scene.effects.gravity, "ground": scene.effects.ground},
            "the strip statics needs gravity > 0 and ground = true (for the free rod use "
            "elastocap.statics.branches.trace_branches)",
        )


def strip_problem_for(scene: Scene, parameter="drop.wetted_length", N=None) -> StripProblem:
    """The lifted-strip problem of a scene with gravity and ground."""
    _check_scene(scene)
    if parameter not in PARAMETERS:
        raise SceneError("--param", parameter, f"expected one of {', '.join(PARAMETERS)}")
    if N is None:
        N = scene.numerics.cheb_points or STRIP_N[scene.numerics.accuracy]
    d = scene.drop
    try:
        return StripProblem(
            N,
            scene.rod.length,
            scene.distance_from_end,
            d.wetted_length,
            d.area,
            d.line_tension,
            scene.rod.bending_modulus,
            scene.rod.mass_per_length * scene.effects.gravity,
            0.0,
            parameter,
        )
    except ValueError as exc:
        raise SceneError("drop.distance_from_end", scene.distance_from_end, str(exc)) from None


def seeds(problem: StripProblem, wraps=_SEED_WRAP, tails=_SEED_TAIL, drys=_SEED_DRY):
    """Seed states: theta rising on the dry lifted part, turning by ``wrap`` on the wet part
    (the drop wrapped), turning by ``tail`` more on the tail; lift-off ``dry`` before S1."""
    out = []
    for dry in drys:
        s_c = problem.s1 - dry * problem.params["delta"]
        if s_c <= 0.0:
            continue
        for wrap in wraps:
            for tail in tails:
                u = np.zeros(problem.n)
                u[-1] = s_c
                st = problem.state(u)
                s = st.s
                t1 = 0.3 * np.clip((s - s_c) / (problem.s1 - s_c), 0.0, 1.0) ** 2
                t2 = wrap * np.clip((s - problem.s1) / problem.params["delta"], 0.0, 1.0)
                ell3 = problem.params["L"] - problem.s2
                t3 = tail * np.clip((s - problem.s2) / ell3, 0.0, 1.0)
                u[:-1] = (t1 + t2 + t3)[1:]
                out.append(u)
    return out


def refine_state(problem: StripProblem, u, N2) -> tuple[StripProblem, np.ndarray]:
    """The state u interpolated segment by segment onto a problem with N2 intervals."""
    fine = problem.copy(N=N2)
    th = problem.full_theta(u)
    out = [np.zeros(1)]
    for k, sl in enumerate(problem._slices()):
        Mi = lgl_interp_matrix(problem.Ns[k], fine.xi[k])
        out.append((Mi @ th[sl])[1:])
    return fine, np.concatenate(out[1:] + [[u[-1]]])


def shape_at(problem, u, S) -> np.ndarray:
    """Positions (len(S), 2) of the equilibrium at arclengths S (flat part included;
    lift-off point at x = 0). Spectral interpolation on each segment."""
    S = np.atleast_1d(np.asarray(S, float))
    st = problem.state(u)
    out = np.zeros((S.size, 2))
    flat = S <= st.s_c
    out[flat, 0] = S[flat] - st.s_c
    for k, (sl, (a, ell)) in enumerate(zip(problem._slices(), problem.segments(u), strict=True)):
        m = (S > a) & (S <= a + ell) & ~flat if k else (S > a) & (S <= a + ell)
        if not m.any():
            continue
        xi = np.clip(2.0 * (S[m] - a) / ell - 1.0, -1.0, 1.0)
        Mi = lgl_interp_matrix(problem.Ns[k], xi)
        out[m, 0] = Mi @ st.x[sl]
        out[m, 1] = Mi @ st.z[sl]
        flat |= m
    return out
