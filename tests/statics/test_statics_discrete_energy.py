"""Cross-check: the equilibria of the discrete energy that `dynamics` integrates (DER
bending + gamma lambda of the polyline, inextensible edges) converge to the spectral BVP
solution at the rate O(h^2) of the DER discretization."""

import numpy as np
import pytest
from discrete_energy import DiscreteRodEnergy

from elastocap.statics.branches import newton
from elastocap.statics.wet_elastica import WetElasticaProblem


def _stationary(D, phi, iters=6):
    """Newton on grad E(phi) = 0 with a finite-difference Hessian (least squares: the
    rotation mode is a zero eigenvalue). No descent method first: it would slide off a
    saddle; the start (the BVP shape) is well inside Newton's basin."""
    for _ in range(iters):
        g = D.energy_grad(phi)[1]
        n, h = len(phi), 1e-6
        H = np.empty((n, n))
        for j in range(n):
            e = np.zeros(n)
            e[j] = h
            H[:, j] = (D.energy_grad(phi + e)[1] - D.energy_grad(phi - e)[1]) / (2 * h)
        step = np.linalg.lstsq(0.5 * (H + H.T), -g, rcond=1e-10)[0]
        phi = phi + step
        if np.max(np.abs(step)) < 1e-12:
            break
    return phi


def _bvp_solution(delta, turns, pick):
    P = WetElasticaProblem(32, delta, 1.5, 1.0, 1.0, 4.6, 2.3)
    for t in turns:
        u = newton(P, np.concatenate([0.5 * np.pi * t * P.xi, [0.0]]), delta, 1e-12)
        if u is not None and pick(P.observables(u, delta)["measure"]):
            return P, u
    raise AssertionError("BVP solution not found")


@pytest.mark.parametrize(
    ("delta", "turns", "pick"),
    [
        (2.5, [0.3], lambda m: m < 0.5),  # the nearly flat (only) state
        (4.0, [1.3, 1.6, 2.0], lambda m: 0.9 < m < 1.1),  # the saddle between the two
    ],
)
def test_discrete_equilibria_converge_at_second_order(delta, turns, pick):
    P, u = _bvp_solution(delta, turns, pick)
    ref = P.observables(u, delta)
    s1, s2 = 2.3 - 0.5 * delta, 2.3 + 0.5 * delta
    errs_e, errs_m = [], []
    # n = 92, 184, 368 put both contact points on nodes at every level (same lumping)
    levels = [92, 184, 368]
    for n in levels:
        D = DiscreteRodEnergy(n, 4.6, 1.0, 1.0, 1.5, s1, s2)
        sm = (np.arange(n) + 0.5) * 4.6 / n
        phi0 = P.interp_matrix(np.clip(2 * (sm - s1) / delta - 1, -1, 1)) @ u[: P.N + 1]
        phi = _stationary(D, phi0)
        assert np.max(np.abs(D.energy_grad(phi)[1])) < 1e-9  # a stationary point
        errs_e.append(abs(D.energy_grad(phi)[0] - ref["energy"]))
        errs_m.append(abs((phi[-1] - phi[0]) / np.pi - ref["measure"]))
    for errs in (errs_e, errs_m):
        order = np.polyfit(np.log(levels), np.log(errs), 1)[0]
        # DER is second order; the fit over 3 levels is within 0.2 of 2 when converged
        assert -2.2 < order < -1.8, f"observed order {-order:.3f}, errors {errs}"
    assert errs_e[-1] < 5e-5 and errs_m[-1] < 5e-5
