"""The spectral equilibrium (grad E_N = 0) against the independently derived Kirchhoff
equations solved by scipy.integrate.solve_bvp: same shape, forces and free-end moment."""

import numpy as np
import pytest
from kirchhoff_reference import solve_kirchhoff

from elastocap.statics.branches import newton
from elastocap.statics.wet_elastica import WetElasticaProblem


@pytest.mark.parametrize(
    ("delta", "turn"),
    [(2.5, 0.3), (4.0, 0.59), (4.0, 1.32), (3.6, 0.97)],  # flat, flat, wrapped, saddle
)
def test_spectral_solution_solves_kirchhoff_equations(delta, turn):
    P = WetElasticaProblem(32, delta, 1.5, 1.0, 1.0, 4.6, 2.3)
    seed = np.concatenate([0.5 * np.pi * turn * P.xi, [0.0]])
    u = newton(P, seed, delta, 1e-12)
    assert u is not None
    S = P.state(u, delta)
    s_nodes = 0.5 * delta * (P.xi + 1.0)

    # the guess: the spectral solution, interpolated (its x, z, A0 integrals and moment)
    m = (2.0 / delta) * (P.Dh @ S.theta)
    a = 0.5 * (0.5 * delta) * (P.Qh @ (S.x * np.sin(S.theta) - S.z * np.cos(S.theta)))

    def guess(s):
        M = P.interp_matrix(2.0 * s / delta - 1.0)
        # perturbed by 0.03 rad, so that scipy has to converge to the solution itself
        th = M @ S.theta + 0.03 * np.sin(np.pi * s / delta)
        return np.vstack([th, M @ m, M @ S.x, M @ S.z, M @ a])

    c, sn = np.cos(S.tau), np.sin(S.tau)
    cx, cz = S.x[-1] / S.d, S.z[-1] / S.d
    p_guess = [-(c * cx - sn * cz), -(sn * cx + c * cz), 1.05 * S.kappa]
    sol = solve_kirchhoff(delta, 1.5, 1.0, 1.0, guess, p_guess, tol=1e-9)
    assert sol.success, sol.message
    th_ref = sol.sol(s_nodes)[0]
    # solve_bvp's tolerance 1e-9 on the collocation residual: shapes agree to ~1e-8
    assert np.max(np.abs(th_ref - S.theta)) < 1e-7
    # the end moment that was NOT imposed vanishes (global moment balance of the drop)
    assert abs(sol.sol(delta)[1]) < 1e-7
    # same Laplace pressure
    assert sol.p[2] == pytest.approx(S.kappa, rel=1e-7)
    # the unfolding multiplier of the spectral system is zero at a solution
    assert abs(u[-1]) < 1e-10
