"""Euler buckling of an inextensible elastica (B = 1, L = 1) under an end load P.

Known answers: branch points at P_k = k^2 pi^2 (discrete: P_k^h in closed
form, see cont_elastica.py); the first post-buckled branch satisfies
sqrt(P) L = 2 K(m), m = sin^2(theta0 / 2) (scipy's ellipk takes m = k^2);
the buckled branch loses stability where the ends meet (x(L) = 0), at
2 E(m) = K(m), theta0 = 130.71 degrees, P = 21.549.
"""

import numpy as np
import pytest
from cont_elastica import Elastica
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

import continuation as C

S = C.ContinuationSettings(ds0=0.1, ds_max=2.0, p_min=0.0, p_max=45.0, max_steps=200)
S_POST = C.ContinuationSettings(ds0=0.05, ds_max=1.0, p_min=0.0, p_max=30.0, max_steps=300)


def exact_P(theta0):
    return (2 * ellipk(np.sin(theta0 / 2) ** 2)) ** 2


@pytest.mark.parametrize("L", [1.0, 2.0])
def test_trivial_branch_points_and_stability(L):
    prob = Elastica(100, L=L)
    br = C.continue_branch(prob, np.zeros(102), 1.0 / L**2, S.replace(p_max=45.0 / L**2))
    bps = br.branch_points
    assert len(bps) == 2 and all(b.located for b in bps)
    for k, b in enumerate(bps, start=1):
        # The discrete problem's exact buckling load, to the location tolerance.
        assert abs(b.p / prob.discrete_buckling_load(k) - 1) < 1e-10
        # Continuum k^2 pi^2 B / L^2: O(h^2) error (k pi h/L)^2 / 12 = 8.2e-5 k^2 at N = 100.
        assert abs(b.p / (k * np.pi / L) ** 2 - 1) < 1.1 * (k * np.pi / 100) ** 2 / 12
    # Stability index = number of loads passed (KKT inertia with y(L) = 0).
    P = br.p
    assert set(br.stability[P < bps[0].p]) == {0}
    assert set(br.stability[(P > bps[0].p) & (P < bps[1].p)]) == {1}
    assert set(br.stability[P > bps[1].p]) == {2}


def test_post_buckled_branch_elliptic_and_order_two():
    errs = []
    for N in (50, 100, 200):
        prob = Elastica(N, sparse=(N == 200))  # the sparse path too
        br = C.continue_branch(prob, np.zeros(N + 2), 1.0, S.replace(p_max=12.0))
        nb = C.switch_branch(prob, br.branch_points[0], S_POST)
        th0 = nb.observables["theta0"]
        on = np.abs(th0) > 0.05  # away from the branch point (theta0 = 0)
        rel = np.abs(nb.p[on] / exact_P(th0[on]) - 1)
        errs.append(rel.max())
        assert np.abs(th0).max() > 2.5  # deep into the post-buckled regime
        # Symmetric halves theta0 > 0 and theta0 < 0 both computed.
        assert th0.min() < -2.5 and th0.max() > 2.5
    order = np.log2(errs[0] / errs[1]), np.log2(errs[1] / errs[2])
    print("post-buckled max rel errors", errs, "observed orders", order)
    assert errs[1] < 1e-4  # (pi h)^2/12 = 8.2e-5 at N = 100, up to theta0 = 2.6
    assert all(abs(o - 2) < 0.05 for o in order), order


def test_buckled_branch_loses_stability_where_ends_meet():
    prob = Elastica(100)
    br = C.continue_branch(prob, np.zeros(102), 1.0, S.replace(p_max=12.0))
    nb = C.switch_branch(prob, br.branch_points[0], S_POST, both_sides=False)
    m_star = brentq(lambda m: 2 * ellipe(m) - ellipk(m), 0.5, 0.99)
    th_star = 2 * np.arcsin(np.sqrt(m_star))
    th0 = np.abs(nb.observables["theta0"])
    assert set(nb.stability[(th0 > 0.05) & (th0 < th_star - 0.05)]) == {0}
    assert set(nb.stability[th0 > th_star + 0.05]) == {1}
    # The rotation of a closed figure-eight is a zero mode: a branch point.
    bps = [b for b in nb.branch_points if b.name != "switched here"]
    assert len(bps) == 1
    assert abs(abs(bps[0].u[0]) - th_star) < 1e-3  # O(h^2) at N = 100
    assert abs(bps[0].p / (2 * ellipk(m_star)) ** 2 - 1) < 2e-4


@pytest.mark.slow
def test_post_buckled_fine_grid():
    prob = Elastica(800, sparse=True)
    br = C.continue_branch(prob, np.zeros(802), 1.0, S.replace(p_max=12.0))
    nb = C.switch_branch(prob, br.branch_points[0], S_POST, both_sides=False)
    th0 = nb.observables["theta0"]
    on = np.abs(th0) > 0.05
    assert np.max(np.abs(nb.p[on] / exact_P(th0[on]) - 1)) < 2e-6  # 8.2e-5 / 64
