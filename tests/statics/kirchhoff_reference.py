"""An independent second discretization of the wet-part equilibrium, for the tests.

The Kirchhoff equations in strong form (paper, supplementary [2a]-[2d], [6]-[8]), derived by
hand and NOT from the energy used by elastocap.statics: on the wet part s in [0, Delta]
(x(0) = 0), with n(s) the internal force,

    theta' = m / B,   m' = -(t x n),   x' = cos theta,   z' = sin theta,
    a' = (x sin theta - z cos theta) / 2          (accumulates A0),
    n(s) = n1 + gamma kappa J(x(s)),   J(x, z) = (-z, x)   (uniform pressure load),

with n1 = -f1 = -gamma u1 (the point force [7a] at S1; u1 the interface's unit tangent) and
kappa the interface curvature. Unknown parameters n1 (2) and kappa; boundary conditions
m(0) = 0 (free dry arm), x(0) = z(0) = a(0) = 0, theta(0) + theta(Delta) = 0 (gauge) and the
cap closure: kappa and n1 equal those of the circular cap of area A - a(Delta) on the chord
x(Delta). The remaining free-end condition m(Delta) = 0 follows from the global moment
balance and is checked, not imposed. Solved by scipy.integrate.solve_bvp (4th-order
collocation): a different discretization of independently derived equations.
"""

import math

import numpy as np
from scipy.integrate import solve_bvp

from elastocap.drop import cap_geometry


def solve_kirchhoff(delta, area, gamma, B, y_guess, p_guess, tol=1e-10):
    """Solve the strong form from a guess.

    Parameters
    ----------
    y_guess : callable s -> ndarray (5, len(s))
        Initial (theta, m, x, z, a).
    p_guess : array (3,)
        Initial (n1x, n1z, kappa).

    Returns
    -------
    scipy's BVP result (``sol.sol(s)``, ``sol.p``, ``sol.success``).
    """

    def rhs(s, y, prm):
        th, m, x, z, _a = y
        n1x, n1z, kap = prm
        Nx = n1x - gamma * kap * z
        Nz = n1z + gamma * kap * x
        c, sn = np.cos(th), np.sin(th)
        return np.vstack([m / B, -(c * Nz - sn * Nx), c, sn, 0.5 * (x * sn - z * c)])

    def bc(ya, yb, prm):
        n1x, n1z, kap = prm
        d = math.hypot(yb[2], yb[3])
        tau, st, ct, _lam, kappa = cap_geometry(area - yb[4], d)
        cx, cz = yb[2] / d, yb[3] / d
        # interface tangent at x1: the chord direction turned by +tau
        ux, uz = ct * cx - st * cz, st * cx + ct * cz
        return np.array(
            [
                ya[1],
                ya[2],
                ya[3],
                ya[4],
                ya[0] + yb[0],
                kap - kappa,
                n1x + gamma * ux,
                n1z + gamma * uz,
            ]
        )

    s = np.linspace(0.0, delta, 80)
    return solve_bvp(rhs, bc, s, y_guess(s), np.asarray(p_guess, float), tol=tol, max_nodes=100000)
