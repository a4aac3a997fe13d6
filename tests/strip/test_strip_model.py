"""The discrete strip on the ground (elastocap.strip.model, .solve): the same energy as the
dynamic model, exact derivatives, closed forms, and second-order convergence to the
spectral solver where its topology applies. Tolerances are written next to each assertion."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from spectral_strip import StripProblem, seeds, shape_at, strip_problem_for

from dynamics.bending import bending_energy, bending_gradient
from elastocap.capillary import capillary_kernel
from elastocap.drop import capillary_energy_and_gradient
from elastocap.scene import load_scene
from elastocap.statics.branches import newton
from elastocap.strip.model import (
    DiscreteStrip,
    capillary_hessian_nodes,
    discrete_strip_for,
    flat_state,
    shoelace_derivatives,
)
from elastocap.strip.solve import minimize_energy, solve_equilibrium, stability, wrapped_state
from elastocap.strip.trace import active_set_problem

L = 14.3


def random_state(strip, seed=0, amp=0.05):
    rng = np.random.default_rng(seed)
    return np.concatenate([[0.1], np.cumsum(amp * rng.standard_normal(strip.n))])


def observed_order(ns, errs):
    return -np.polyfit(np.log(ns), np.log(errs), 1)[0]


# ------------------------------------------------------------------ the energy
def test_energy_is_the_dynamic_models_potential():
    # bending (dynamics.bending, DER), gravity with lumped masses (dynamics Gravity) and the
    # capillary effect of the impact run: the same number to round-off, and the gradient
    # is the chain rule of the same node forces
    S = DiscreteStrip(80, L, 2.0, 1.1, 0.36, 40.0)
    u = random_state(S)
    X = np.ascontiguousarray(S.positions(u))
    el = np.full(S.n, S.h)
    mass = np.full(S.n + 1, S.h)
    mass[[0, -1]] = 0.5 * S.h
    fcap = np.zeros_like(X)
    e_cap = capillary_kernel(X, np.zeros_like(X), 0.0, np.array([0.36, S.s1, S.s2, 40.0]),
                             el, mass, fcap)
    e_dyn = bending_energy(X, el, 1.0) + float(mass @ X[:, 1]) + e_cap
    assert abs(S.energy(u) - e_dyn) < 1e-12 * abs(e_dyn)
    gX = np.zeros_like(X)
    bending_gradient(X, el, 1.0, gX)
    gX[:, 1] += mass
    gX -= fcap
    # dX_k/dtheta_j = h (-sin, cos) theta_j for k > j; dX_k/dz0 = (0, 1)
    suffix = np.cumsum(gX[::-1], axis=0)[::-1]
    th = u[1:]
    g_chain = np.concatenate([[suffix[0, 1]],
                              S.h * (-np.sin(th) * suffix[1:, 0] + np.cos(th) * suffix[1:, 1])])
    assert np.max(np.abs(S.gradient(u) - g_chain)) < 1e-11 * np.max(np.abs(g_chain))


def test_gradient_and_hessian_against_finite_differences():
    S = DiscreteStrip(60, L, 3.0, 1.3, 0.36, 40.0, F=0.3)
    u = random_state(S, seed=3)
    E, g, H = S.derivatives(u)
    eps = 1e-6
    I = np.eye(S.size)
    gfd = np.array([(S.energy(u + eps * e) - S.energy(u - eps * e)) / (2 * eps) for e in I])
    Hfd = np.array([(S.gradient(u + eps * e) - S.gradient(u - eps * e)) / (2 * eps) for e in I])
    # central differences: error ~ eps^2 E''' + round-off E / eps ~ 1e-8 of |g| (|g| ~ 14)
    assert np.max(np.abs(g - gfd)) < 1e-7 * np.max(np.abs(g))
    assert np.max(np.abs(H - Hfd)) < 1e-7 * np.max(np.abs(H))
    assert np.array_equal(H, H.T)


def test_capillary_node_hessian_against_its_gradient():
    # the hand-assembled Hessian of gamma lambda (cap kernels of elastocap.drop) against
    # central differences of the exact gradient of elastocap.drop
    S = DiscreteStrip(40, L, 3.0, 1.1, 0.36, 40.0)
    X = S.positions(random_state(S, seed=5, amp=0.2))
    i1, H = capillary_hessian_nodes(X, S.s_nodes, S.s1, S.s2, S.area, S.gamma)
    m = H.shape[0] // 2

    def grad(Y):
        g = np.zeros_like(Y)
        capillary_energy_and_gradient(Y, S.s_nodes, S.s1, S.s2, S.area, S.gamma, g)
        return g[i1 : i1 + m].ravel()

    eps = 1e-6
    Hfd = np.zeros_like(H)
    for a in range(2 * m):
        Yp, Ym = X.copy(), X.copy()
        Yp[i1 + a // 2, a % 2] += eps
        Ym[i1 + a // 2, a % 2] -= eps
        Hfd[:, a] = (grad(Yp) - grad(Ym)) / (2 * eps)
    assert np.max(np.abs(H - Hfd)) < 1e-6 * np.max(np.abs(H))


def test_angle_hessian_is_the_chain_rule_of_the_node_hessian():
    # the compiled Hessian in the angles (capillary_stiffness's band + rank 5, by double
    # suffix sums) against the dense chain rule J^T H_X J of the numpy node Hessian
    # (capillary_hessian_nodes) plus the positions' curvature term, with the gradient's
    # chain rule of elastocap.drop's node gradient; every resolution the trace uses
    for n, x, delta, seed in ((40, 3.0, 1.1, 1), (143, 2.0, 0.4, 2), (198, 4.0, 2.1, 3),
                              (247, 6.0, 1.7, 4), (297, 3.0, 1.3, 5), (429, 5.0, 0.9, 6)):
        S = DiscreteStrip(n, L, x, delta, 0.36, 40.0, F=0.2)
        u = random_state(S, seed=seed, amp=0.05)
        E, g, H = S.derivatives(u)
        X = S.positions(u)
        th = u[1:]
        gX = np.zeros_like(X)
        capillary_energy_and_gradient(X, S.s_nodes, S.s1, S.s2, S.area, S.gamma, gX)
        suffix = np.cumsum(gX[::-1], axis=0)[::-1]
        i1, HX = capillary_hessian_nodes(X, S.s_nodes, S.s1, S.s2, S.area, S.gamma)
        m = HX.shape[0] // 2
        J = np.zeros((2 * m, m - 1))
        low = np.tri(m, m - 1, -1)
        J[0::2] = -S.h * low * np.sin(th[i1:i1 + m - 1])
        J[1::2] = S.h * low * np.cos(th[i1:i1 + m - 1])
        ref = np.zeros_like(H)
        cols = 1 + i1 + np.arange(m - 1)
        ref[np.ix_(cols, cols)] = J.T @ HX @ J
        ref[1:, 1:] += np.diag(-S.h * (np.cos(th) * suffix[1:, 0] + np.sin(th) * suffix[1:, 1]))
        # the rest: bending and gravity (tridiagonal), from the drop-free strip
        ref += S.with_(gamma=0.0, area=0.0).hessian(u)
        assert np.max(np.abs(H - ref)) < 1e-11 * np.max(np.abs(H)), n
        assert np.array_equal(H, H.T)


def test_constraint_jacobian_bit_identical_to_the_triangle_and_the_heights():
    # the compiled kernel writes the matrix of the numpy form np.tril(h cos theta_j) entry
    # by entry: the same bits; and its rows are the derivatives of the heights (central
    # differences, relative step 1e-6: truncation ~1e-12)
    for n, seed in ((4, 1), (37, 2), (198, 3)):
        S = DiscreteStrip(n, L, 2.0, 1.1, 0.36, 40.0)
        u = random_state(S, seed=seed, amp=0.3)
        G = S.constraint_jacobian(u)
        ref = np.zeros((n + 1, n + 1))
        ref[:, 0] = 1.0
        ref[1:, 1:] = np.tril(np.broadcast_to(S.h * np.cos(u[1:]), (n, n)))
        assert np.array_equal(G, ref)
        e = 1e-6
        fd = np.column_stack([(S.heights(u + e * v) - S.heights(u - e * v)) / (2 * e)
                              for v in np.eye(n + 1)])
        assert np.max(np.abs(G - fd)) < 1e-9


def test_constraint_rows_and_reaction_forces_against_the_full_jacobian():
    # rows of chosen nodes equal the rows of the full matrix (the same bits); G^T r by
    # suffix sums equals the product with the full matrix to round-off
    rng = np.random.default_rng(5)
    for n in (4, 37, 198):
        S = DiscreteStrip(n, L, 2.0, 1.1, 0.36, 40.0)
        u = random_state(S, seed=n, amp=0.3)
        G = S.constraint_jacobian(u)
        k = np.sort(rng.choice(n + 1, (n + 1) // 2, replace=False))
        assert np.array_equal(S.constraint_jacobian(u, k), G[k])
        r = rng.uniform(0.0, 1.0, n + 1)
        assert np.max(np.abs(S.reaction_forces(u, r) - G.T @ r)) < 1e-12 * n


@pytest.mark.parametrize("x, delta", [(4.0, 0.3), (4.0, 1.0), (2.0, 1.1)])
def test_stability_index_against_the_projected_hessian(x, delta):
    # the index of real strip states (the fold over the drop and the deposition; a flat
    # stretch of held nodes gives rows with one nonzero, eliminated before the LDL^T /
    # the SVD) against an independent reference: the eigenvalues of the Lagrangian
    # Hessian projected on scipy's null space of the full rows of the held nodes; also at
    # index-1 and index-2 states made by flipping the Hessian's sign along a free unknown
    from scipy.linalg import null_space

    from continuation import inertia_negative

    S = discrete_strip_for(load_scene("fig3-strip", {"drop.distance_from_end": x}), 60)
    S = S.with_(delta=delta)
    for eq in (minimize_energy(S, flat_state(S)), wrapped_state(S)):
        assert eq.success
        prob, tools = active_set_problem(S, eq.active)
        v = tools["join"](eq.u, eq.reactions)
        H = prob.hessian(v, delta)
        C = prob.constraint_jacobian(v, delta)
        Z = null_space(S.constraint_jacobian(eq.u)[eq.active])
        assert Z.shape[1] == S.size - eq.contacts  # the held rows have full rank
        ones = int(np.count_nonzero(np.count_nonzero(C, axis=1) == 1))
        assert ones > eq.contacts // 2  # the elimination is exercised
        ev = np.linalg.eigvalsh(Z.T @ H @ Z)
        assert np.min(np.abs(ev)) > 1e-6 * np.max(np.abs(ev))
        assert inertia_negative(H, C) == int(np.sum(ev < 0)) == stability(S, eq)[0]
        # a large negative curvature added along the unknown the contacts leave most free:
        # one more negative direction (a rank-one change)
        free = int(np.argmax(np.sum(Z * Z, axis=1)))
        Hm = H.copy()
        Hm[free, free] -= 1e3 * np.max(np.abs(H))
        evm = np.linalg.eigvalsh(Z.T @ Hm @ Z)
        assert inertia_negative(Hm, C) == int(np.sum(evm < 0)) == int(np.sum(ev < 0)) + 1


def test_shoelace_derivatives_bit_identical_to_the_loop_and_against_the_area():
    # the vectorized gradient and the cached constant Hessian are the per-point formulas
    # bit for bit; the gradient is the derivative of the shoelace area (central
    # differences, step 1e-6: exact for a quadratic up to rounding, ~1e-10)
    rng = np.random.default_rng(4)
    R = np.array([[0.0, 1.0], [-1.0, 0.0]])
    for npt in (2, 3, 7, 30):
        P = rng.standard_normal((npt, 2))
        gA, HA = shoelace_derivatives(P)
        g_ref = np.zeros((npt, 2))
        H_ref = np.zeros((2 * npt, 2 * npt))
        for k in range(npt):
            kn, kp = (k + 1) % npt, (k - 1) % npt
            g_ref[k] = 0.5 * np.array([P[kn, 1] - P[kp, 1], -(P[kn, 0] - P[kp, 0])])
            H_ref[2 * k : 2 * k + 2, 2 * kn : 2 * kn + 2] += 0.5 * R
            H_ref[2 * k : 2 * k + 2, 2 * kp : 2 * kp + 2] -= 0.5 * R
        assert np.array_equal(gA, g_ref) and np.array_equal(HA, H_ref)

        def area(Q):
            return 0.5 * float(np.sum(Q[:, 0] * np.roll(Q[:, 1], -1)
                                      - np.roll(Q[:, 0], -1) * Q[:, 1]))

        e = 1e-6
        fd = np.zeros_like(P)
        for idx in np.ndindex(P.shape):
            d = np.zeros_like(P)
            d[idx] = e
            fd[idx] = (area(P + d) - area(P - d)) / (2 * e)
        assert np.max(np.abs(gA - fd)) < 1e-9


def _descent_decomposing_every_iteration(strip, u0, tol=1e-10, max_iter=500):
    """minimize_energy's trust-region loop with a tridiagonal reduction at every iteration,
    rejected steps included (the reference for the reduction it keeps)."""
    from elastocap.strip import solve

    u = np.array(u0, dtype=float)
    k = 10.0 * strip.B / strip.h**3
    E, g, H = solve._penalty(strip, u, k)
    radius = 1.0
    for _ in range(max_iter):
        if float(np.linalg.norm(g)) <= solve._DESCENT_GTOL:
            break
        d, pred, boundary = solve._trust_step(solve._Tridiagonal(0.5 * (H + H.T)), g, radius)
        E1, g1, H1 = solve._penalty(strip, u + d, k)
        rho = (E - E1) / pred if pred > 0.0 else -1.0
        if rho < 0.25:
            radius *= 0.25
        elif rho > 0.75 and boundary:
            radius = min(2.0 * radius, 1e3)
        if rho > 0.15:
            u, E, g, H = u + d, E1, g1, H1
        if radius < 1e-14:
            break
    return solve_equilibrium(strip, u, active=strip.heights(u) <= 1e-9, tol=tol)


def test_descent_keeps_the_decomposition_over_rejected_steps_bit_identical(monkeypatch):
    # a rejected trust-region step leaves H as it is: its tridiagonal reduction is kept,
    # the descent is the same bit for bit, with fewer reductions
    from elastocap.strip import solve

    calls = {"n": 0}
    reduce = solve._Tridiagonal

    def counted(a):
        calls["n"] += 1
        return reduce(a)

    monkeypatch.setattr(solve, "_Tridiagonal", counted)
    S = DiscreteStrip(60, L, 2.0, 0.6, 0.36, 40.0)
    s = (np.arange(S.n) + 0.5) * S.h
    folded = np.concatenate([[0.0], math.pi * np.clip((s - S.s1) / (S.s2 - S.s1), 0, 1)])
    for u0 in (flat_state(S), folded):
        calls["n"] = 0
        eq = minimize_energy(S, u0)
        kept = calls["n"]
        calls["n"] = 0
        ref = _descent_decomposing_every_iteration(S, u0)
        assert eq.success and np.array_equal(eq.u, ref.u)
        assert np.array_equal(eq.reactions, ref.reactions) and eq.energy == ref.energy
        assert kept < calls["n"]


def _assert_trust_region_optimal(H, g, radius, d, pred):
    # More & Sorensen (1983), Lemma 2.1: d minimizes g.d + d.H d / 2 over |d| <= radius
    # iff |d| <= radius and (H + mu I) d = -g for some mu >= 0 with H + mu I positive
    # semi-definite and mu (radius - |d|) = 0
    scale = max(1.0, float(np.max(np.abs(H))), float(np.linalg.norm(g)))
    nd = float(np.linalg.norm(d))
    assert nd <= radius * (1 + 1e-9)
    Hd = H @ d
    mu = max(0.0, -float(d @ (Hd + g)) / (nd * nd)) if nd > 0 else 0.0
    assert np.linalg.norm(Hd + mu * d + g) <= 1e-7 * scale * max(1.0, radius)
    assert np.linalg.eigvalsh(H)[0] + mu >= -1e-7 * scale
    assert mu * (radius - nd) <= 1e-7 * scale * radius
    assert pred == pytest.approx(-(g @ d + 0.5 * d @ Hd), rel=1e-9, abs=1e-12 * scale)


@given(n=st.integers(1, 40), shift=st.floats(-20.0, 40.0), radius=st.floats(1e-4, 1e2),
       seed=st.integers(0, 2**32 - 1))
@settings(max_examples=60, deadline=None)
def test_the_trust_region_step_is_the_subproblems_minimum(n, shift, radius, seed):
    # the descent's step on the tridiagonal reduction (minimize_energy) against the
    # optimality conditions of the trust-region subproblem, definite and indefinite
    from elastocap.strip import solve

    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    H = A + A.T + shift * np.eye(n)
    g = rng.standard_normal(n)
    d, pred, boundary = solve._trust_step(solve._Tridiagonal(H), g, radius)
    _assert_trust_region_optimal(H, g, radius, d, pred)
    if boundary:
        assert np.linalg.norm(d) >= radius * (1 - 1e-9)
    else:  # the Newton step, inside
        assert np.linalg.eigvalsh(H)[0] > 0


def test_the_trust_region_step_in_the_hard_case():
    # g orthogonal to the lowest mode of an indefinite H, its Newton step inside the
    # radius: the step goes along the lowest mode to the boundary (mu = -lambda_min)
    from elastocap.strip import solve

    rng = np.random.default_rng(7)
    Qm, _ = np.linalg.qr(rng.standard_normal((6, 6)))
    lam = np.array([-1.0, 1.0, 2.0, 3.0, 5.0, 8.0])
    H = Qm @ np.diag(lam) @ Qm.T
    g = Qm @ np.array([0.0, 1e-3, 2e-3, 0.0, 1e-3, 0.0])
    d, pred, boundary = solve._trust_step(solve._Tridiagonal(H), g, 1.0)
    _assert_trust_region_optimal(H, g, 1.0, d, pred)
    assert boundary and abs(float(Qm[:, 0] @ d)) > 0.99


def test_a_trust_region_subproblem_that_cannot_be_solved_stops_the_descent(monkeypatch):
    # the subproblem's failure (its shifted matrix not positive definite in the
    # arithmetic) ends the descent with the reason, not an exception
    from elastocap.strip import solve

    def fails(T, g, radius):
        raise np.linalg.LinAlgError("T + mu I not positive definite (test)")

    monkeypatch.setattr(solve, "_trust_step", fails)
    S = DiscreteStrip(60, L, 2.0, 1.6, 0.36, 40.0)
    s = (np.arange(S.n) + 0.5) * S.h
    folded = np.concatenate([[0.0], math.pi * np.clip((s - S.s1) / (S.s2 - S.s1), 0, 1)])
    eq = minimize_energy(S, folded, tol=1e-10)
    assert not eq.success
    assert "a trust-region subproblem it could not solve (T + mu I not positive" in eq.message


def test_with_delta_is_the_constructed_strip():
    # a copy at another Delta (made without the constructor) equals the strip the
    # constructor makes, shares the node arrays and refuses a drop off the strip alike
    S = DiscreteStrip(60, L, 2.0, 0.6, 0.36, 40.0)
    u = random_state(S)
    S.derivatives(u)
    C = S.with_(delta=0.8)
    ref = DiscreteStrip(60, L, 2.0, 0.8, 0.36, 40.0)
    assert C == ref and C.to_dict() == ref.to_dict()
    assert C.s_nodes is S.s_nodes and C._load is S._load
    for a, b in zip(C.derivatives(u), ref.derivatives(u), strict=True):
        assert np.array_equal(a, b)
    assert np.array_equal(C.gauge, ref.gauge)
    for bad in (2 * (L - 2.0) + 0.1, 4.1, float("nan")):
        with pytest.raises(ValueError) as e1:
            S.with_(delta=bad)
        with pytest.raises(ValueError) as e2:
            DiscreteStrip(60, L, 2.0, bad, 0.36, 40.0)
        assert str(e1.value) == str(e2.value)


@pytest.mark.parametrize("x, delta", [(3.0, 1.2), (5.0, 0.9)])
def test_coarse_to_fine_descent_reaches_the_direct_descents_minimum(monkeypatch, x, delta):
    # the descent from each seed on 50 and 100 edges first, then 200, lands on the minimum
    # the direct descent on 200 edges reaches (its iterations grow with n from a far start;
    # from a prolonged minimum they do not)
    from elastocap.strip import solve

    monkeypatch.setattr(solve, "DESCENT_COARSE_N", 60)
    sc = load_scene("fig3-strip", {"drop.distance_from_end": x, "drop.wetted_length": delta})
    S = discrete_strip_for(sc, 200)
    calls = []
    minimize = solve.minimize_energy

    def counted(strip, u0, *a, **k):
        calls.append(strip.n)
        return minimize(strip, u0, *a, **k)

    s = (np.arange(S.n) + 0.5) * S.h
    folded = np.concatenate([[0.0], math.pi * np.clip((s - S.s1) / (S.s2 - S.s1), 0, 1)])
    for seed, u0 in ((solve.open_state, flat_state(S)), (solve.wrapped_state, folded)):
        direct = minimize(S, u0)
        calls.clear()
        monkeypatch.setattr(solve, "minimize_energy", counted)
        eq = seed(S)
        monkeypatch.setattr(solve, "minimize_energy", minimize)
        assert calls == [50, 100, 200]
        assert direct.success and eq.success, (direct.message, eq.message)
        assert eq.index == direct.index == 0
        assert np.max(np.abs(eq.u - direct.u)) < 1e-8
        assert np.array_equal(eq.active, direct.active)
        assert abs(eq.energy - direct.energy) < 1e-10 * abs(direct.energy)


def test_coarse_to_fine_descent_falls_back_where_the_coarse_strip_has_no_minimum(
        monkeypatch):
    # x = 4, Delta = 1.2: the descent from the flat strip fails on 107 edges (its polish
    # does not converge) and succeeds on 214: the state is this strip's, as the direct
    # descent gives it
    from elastocap.strip import solve

    monkeypatch.setattr(solve, "DESCENT_COARSE_N", 110)
    sc = load_scene("fig3-strip", {"drop.distance_from_end": 4.0, "drop.wetted_length": 1.2})
    S = discrete_strip_for(sc, 214)
    assert not minimize_energy(S.with_(n=107), flat_state(S.with_(n=107))).success
    direct = minimize_energy(S, flat_state(S))
    eq = solve.open_state(S)
    assert eq.success and eq.u.shape == (S.n + 1,)
    assert np.max(np.abs(eq.u - direct.u)) < 1e-8


def test_a_descent_cut_short_says_so():
    sc = load_scene("fig3-strip", {"drop.distance_from_end": 3.0, "drop.wetted_length": 1.2})
    S = discrete_strip_for(sc, 100)
    eq = minimize_energy(S, flat_state(S), max_iter=3)
    assert not eq.success
    assert "max_iter = 3 trust-region iterations" in eq.message
    assert "descend_coarse_to_fine" in eq.message


def test_invalid_input_named():
    with pytest.raises(ValueError, match="n: got 2"):
        DiscreteStrip(2, L, 2.0, 1.1, 0.36, 40.0)
    with pytest.raises(ValueError, match="expected 0 < S1 < S2 < L"):
        DiscreteStrip(50, L, 0.3, 1.1, 0.36, 40.0)
    sc = load_scene("fig3-strip", {"effects.ground": False})
    with pytest.raises(ValueError, match="gravity > 0 with ground = true"):
        discrete_strip_for(sc, 50)


# ------------------------------------------------------------------ closed forms
def test_heavy_strip_stays_flat_with_lumped_reactions():
    # no drop: the flat strip is an exact equilibrium, every node on the ground carries
    # its lumped weight q h (q h / 2 at the ends), and it is stable
    S = DiscreteStrip(50, L, 2.0, 1.1, 0.36, 0.0, q=1.3)
    eq = solve_equilibrium(S, flat_state(S))
    assert eq.success and eq.residual < 1e-12, eq.message
    w = np.full(S.n + 1, S.q * S.h)
    w[[0, -1]] *= 0.5
    # the reactions come out of one KKT solve (condition ~1e5): 1e-10 absolute, 3e-10 of q h
    assert np.max(np.abs(eq.reactions - w)) < 1e-10
    assert eq.index == 0 and eq.contacts == S.n + 1
    # from a lifted, bent start the descent comes back to it
    u = random_state(S, seed=2, amp=0.02)
    u[0] = 0.3
    eq2 = minimize_energy(S, u)
    assert eq2.success and np.max(np.abs(eq2.u)) < 1e-10
    assert np.max(np.abs(eq2.reactions - w)) < 1e-10


def test_end_force_linear_lift_off():
    # Linear beam theory for a heavy strip lifted by F at its end: lifted length 2F/q,
    # end height q l^4 / (24 B). F = 0.5: l = 1 (slope 1/12: nonlinear terms ~1e-2);
    # with n = 286 edges h = 0.05, the last contact node lies within 1.5 h of it.
    F = 0.5
    S = DiscreteStrip(286, L, 2.0, 1.1, 0.36, 0.0, F=F)
    eq = solve_equilibrium(S, flat_state(S))
    assert eq.success, eq.message
    z = S.heights(eq.u)
    last = int(np.flatnonzero(eq.active)[-1])
    ell = L - S.s_nodes[last]
    assert abs(ell - 2 * F) <= 1.5 * S.h, ell
    assert abs(z[-1] / (1.0 / 24.0) - 1.0) < 0.03, z[-1]
    # ground reactions carry the weight not held by F; all >= 0
    assert abs(eq.reactions.sum() - (S.q * L - F)) < 1e-10
    assert eq.reactions.min() >= 0.0 and eq.index == 0


def spectral_end_force(F):
    P = StripProblem(16, L, 0.3, 0.2, 0.36, 0.0, F=F, parameter="end_force")
    u0 = np.zeros(P.n)
    u0[-1] = L - 2.0 * F
    u = newton(P, u0, F, tol=1e-11, max_iter=60)
    return P, u


def test_end_force_nonlinear_second_order():
    # F = 1: the lifted length is ~2 with slopes up to 0.9 rad. The end height converges to
    # the spectral solution (itself equal to ODE shooting to 1e-9) at second order in h.
    P, u = spectral_end_force(1.0)
    z_ref = P.state(u).z[-1]
    ns = np.array([100, 200, 400])
    errs = []
    for n in ns:
        S = DiscreteStrip(int(n), L, 2.0, 1.1, 0.36, 0.0, F=1.0)
        eq = solve_equilibrium(S, flat_state(S))
        assert eq.success and eq.index == 0, eq.message
        errs.append(abs(S.heights(eq.u)[-1] - z_ref))
    order = observed_order(ns, errs)
    # measured order 2.0; the lift-off between nodes adds an O(h^3) wobble
    assert 1.7 < order < 2.4, f"observed order {order:.2f}, errors {errs}"
    assert errs[-1] < 5e-4, errs


# ------------------------------------------------------------------ against the spectral solver
def spectral_wrapped(x=2.0, delta=1.1):
    sc = load_scene("fig3-strip", {"drop.distance_from_end": x, "drop.wetted_length": delta})
    P = strip_problem_for(sc, N=16)
    for s in seeds(P):
        u = newton(P, s, delta, 1e-11, max_iter=40)
        if u is not None and u[-1] < P.s1:
            return P, u
    raise AssertionError("no wrapped equilibrium")


def discrete_from_spectral(P, u, n, x=2.0, delta=1.1):
    S = DiscreteStrip(n, L, x, delta, 0.36, 40.0)
    X = shape_at(P, u, S.s_nodes)
    d = np.diff(X, axis=0)
    u0 = np.concatenate([[0.0], np.unwrap(np.arctan2(d[:, 1], d[:, 0]))])
    return S, solve_equilibrium(S, u0)


def test_wrapped_state_converges_to_spectral_at_second_order():
    # x = 2, Delta = 1.1: the encapsulated state has the spectral solver's topology (flat on
    # [0, s_c], lifted beyond). Measured energy gaps 0.3162, 0.07653, 0.01915 at n = 100,
    # 200, 400: order 2.02.
    P, u = spectral_wrapped()
    ob = P.observables(u, 1.1)
    ns = np.array([100, 200, 400])
    de, dz = [], []
    for n in ns:
        S, eq = discrete_from_spectral(P, u, int(n))
        assert eq.success and eq.index == 0 and eq.degenerate == 0, eq.message
        assert eq.reactions.min() >= 0.0
        # one contact set: the flat part, nothing touches beyond it
        act = np.flatnonzero(eq.active)
        assert np.array_equal(act, np.arange(act.size))
        assert abs(act.size * S.h - ob["lift_off"]) < 3 * S.h
        de.append(abs(eq.energy - ob["energy"]))
        dz.append(abs(S.heights(eq.u)[-1] - ob["end_height"]))
    oe, oz = observed_order(ns, de), observed_order(ns, dz)
    assert 1.8 < oe < 2.3, f"energy: observed order {oe:.2f}, gaps {de}"
    assert 1.8 < oz < 2.6, f"end height: observed order {oz:.2f}, gaps {dz}"
    assert de[-1] < 0.025 and dz[-1] < 0.01, (de, dz)


def test_open_state_at_large_x_is_stable_with_positive_reactions():
    # x = 4, Delta = 1.1 (fig3-strip scene): descent from the flat strip stays open; the
    # drop lifts the strip around it and the rest lies on the ground.
    sc = load_scene("fig3-strip", {"drop.distance_from_end": 4.0, "drop.wetted_length": 1.1})
    S = discrete_strip_for(sc, 100)
    eq = minimize_energy(S, flat_state(S))
    assert eq.success and eq.index == 0, eq.message
    assert eq.residual < 1e-9
    assert eq.reactions[eq.active].min() > 0.0
    assert np.all(eq.reactions[~eq.active] == 0.0)
    z = S.heights(eq.u)
    assert z.min() > -1e-12
    # the free end still lies on the ground and the strip is not folded
    assert eq.active[-1] and abs(eq.u[-1]) < 1e-9
    X = S.positions(eq.u)
    assert X[-1, 0] > np.interp(S.L - S.x_end, S.s_nodes, X[:, 0])
    assert math.isclose(eq.energy, sum(eq.parts.values()), rel_tol=1e-14)


def test_scene_default_resolution_and_bad_values_named():
    assert discrete_strip_for(load_scene("fig3-strip")).n == 198  # as the impact resolves it
    for kw, name in ((dict(area=-0.36), "area"), (dict(B=0.0), "B"), (dict(q=-1.0), "q")):
        args = {**dict(n=100, L=14.3, x_end=2.0, delta=1.16, area=0.36, gamma=40.0), **kw}
        with pytest.raises(ValueError, match=rf"^{name}: got"):
            DiscreteStrip(**args)


@pytest.mark.parametrize("n", [198, 297])
def test_factorization_of_bordered_strip_matrices_against_numpy(n):
    # continuation.factorize on the trace's bordered matrices (the fixed-set Jacobian of a
    # flat strip held outside the drop, dF/dDelta, a random row: rows with one nonzero
    # pivoted on before LAPACK), as they come and with rows and columns permuted at
    # random (the single-nonzero rows and their columns then out of order): both solves
    # against numpy.linalg.solve, the determinant's sign against numpy's slogdet
    from continuation import factorize
    from continuation._linalg import bordered

    S = discrete_strip_for(load_scene("fig3-strip", {"drop.distance_from_end": 4.0}), n)
    S = S.with_(delta=1.0)
    s = S.s_nodes
    held = (s < S.s1 - 0.3) | (s > S.s2 + 0.3)
    prob, tools = active_set_problem(S, held)
    u = flat_state(S)
    v = tools["join"](u, np.where(held, 0.01, 0.0))
    rng = np.random.default_rng(n)
    M = bordered(prob.jacobian(v, 1.0), prob.dfdp(v, 1.0), rng.standard_normal(v.size),
                 rng.standard_normal())
    ones = int(np.count_nonzero(np.count_nonzero(M, axis=1) == 1))
    assert ones > n // 3  # the pivoting on single rows is exercised
    m = M.shape[0]
    for A in [M] + [M[rng.permutation(m)][:, rng.permutation(m)] for _ in range(6)]:
        f = factorize(A.copy())
        b = rng.standard_normal(A.shape[0])
        for trans, ref in ((False, np.linalg.solve(A, b)), (True, np.linalg.solve(A.T, b))):
            assert np.linalg.norm(f.solve(b, trans=trans) - ref) <= 1e-10 * np.linalg.norm(ref)
        assert f.det_sign() == int(np.linalg.slogdet(A)[0])


@pytest.mark.parametrize("n", [40, 198])
def test_held_residual_is_the_stationarity_rows_bit_for_bit(n):
    # the fixed-set residual in one compiled pass against its numpy form: the stationarity
    # rows with the reactions at the held nodes, then c times the heights of the first
    # held node and the differences of consecutive held nodes (the same bits)
    S = discrete_strip_for(load_scene("fig3-strip", {"drop.distance_from_end": 4.0}), n)
    S = S.with_(delta=1.0)
    rng = np.random.default_rng(n)
    c = S.B / S.h**3
    for seed in range(4):
        u = random_state(S, seed, 0.2)
        A = np.flatnonzero(rng.random(S.size) < (0.5, 0.0, 1.0, 0.1)[seed])
        ra = rng.standard_normal(A.size)
        r = np.zeros(S.size)
        r[A] = ra
        stat, zs = S.stationarity(u, r)
        z = zs[A]
        z[1:] -= zs[A[:-1]]
        ref = np.concatenate([stat, c * z])
        assert np.array_equal(S.held_residual(u, A, ra, c), ref)
        assert np.max(np.abs(stat)) > 0.0 and (A.size == 0 or np.max(np.abs(z)) > 0.0)
