"""The constrained implicit-midpoint stepper (dynamics.midpoint): its kernels, its order
in dt, exact constraints, energy far above the explicit bound, agreement with RATTLE."""

import numpy as np
import pytest
from dyn_helpers import band_to_dense, dense_to_band, rod_from_angles, simulate_midpoint

from dynamics import (
    Clamp,
    Damping,
    Gravity,
    Ground,
    PointLoad,
    RestCriterion,
    Rod,
    SelfContact,
    SimulationResult,
    euler_bernoulli_omega,
    simulate,
    stable_dt,
)
from dynamics.bending import bending_force_add
from dynamics.midpoint import (
    FD_REL_STEP,
    KL,
    band_lu,
    band_lu_nopivot,
    band_solve,
    bending_hessian_add,
    compile_stepper,
    hessian_columns_add,
    kkt_assemble,
    kkt_residual,
)
from dynamics.reference import BETA_L, crossing_period

#: A free rod's effects: no gravity and the ground far below (exact no-ops on these rods),
#: so that the free-rod runs share the compiled stepper of the ground tests
#: (``test_dynamics_implicit_ground``) instead of compiling one of their own.
FREE = (Gravity(0.0), Ground(-100.0))

# ----------------------------------------------------------------------------- kernels


def _dense(ab, kl=KL, ku=KL):
    return band_to_dense(ab, kl, ku)


def _band(A, kl=KL, ku=KL):
    return dense_to_band(A, kl, ku)


def test_band_lu_solves_like_dense_with_and_without_pivoting():
    rng = np.random.default_rng(0)
    N = 40
    A = np.zeros((N, N))
    for r in range(N):
        for c in range(max(0, r - KL), min(N, r + KL + 1)):
            A[r, c] = rng.standard_normal()
    b = rng.standard_normal(N)
    exact = np.linalg.solve(A, b)
    # a general band matrix needs the row interchanges
    ab = _band(A)
    piv = np.zeros(N, dtype=np.int64)
    assert band_lu(ab, piv, KL, KL) == 0
    assert np.any(piv != np.arange(N))
    y = band_solve(ab, piv, KL, KL, b.copy())
    np.testing.assert_allclose(y, exact, rtol=0, atol=1e-10 * np.abs(exact).max())
    # the unpivoted factorisation refuses it (a tiny pivot relative to its row) ...
    A[0, 0] = 1e-14
    assert band_lu_nopivot(_band(A), KL, KL, 1e-10) == 1
    # ... and solves a diagonally dominant one
    A += np.diag(np.full(N, 20.0))
    ab = _band(A)
    assert band_lu_nopivot(ab, KL, KL, 1e-10) == 0
    piv[0] = -1
    y = band_solve(ab, piv, KL, KL, b.copy())
    np.testing.assert_allclose(y, np.linalg.solve(A, b), rtol=0, atol=1e-13)


def _curved(n=12, h=0.1, seed=1):
    rng = np.random.default_rng(seed)
    th = np.cumsum(0.5 * rng.standard_normal(n))
    x = np.zeros((n + 1, 2))
    x[1:, 0] = np.cumsum(h * np.cos(th))
    x[1:, 1] = np.cumsum(h * np.sin(th))
    return x + 1e-3 * rng.standard_normal(x.shape), np.full(n, h) * 1.01


def test_bending_hessian_analytic_equals_coloured_finite_differences():
    """The two Jacobian paths: analytic Hessian vs 5-colour central differences of the
    exact force; and the coloured FD vs a plain dense FD (colouring loses nothing)."""
    x, el = _curved()
    n = x.shape[0]
    N = 3 * n - 1
    w = np.random.default_rng(2).random((n, 2)) + 0.5
    ab_an = np.zeros((N, 3 * KL + 1))
    bending_hessian_add(x, el, 1.3, 0.7, w, ab_an)
    ab_fd = np.zeros_like(ab_an)
    eps = FD_REL_STEP * 0.1
    for col in range(5):
        for a in range(2):
            fp, fm = np.zeros((n, 2)), np.zeros((n, 2))
            xp = x.copy()
            xp[col::5, a] += eps
            bending_force_add(xp, el, 1.3, fp)
            xp = x.copy()
            xp[col::5, a] -= eps
            bending_force_add(xp, el, 1.3, fm)
            hessian_columns_add(fp, fm, col, a, 0.5 / eps, 0.7, w, ab_fd)
    scale = np.abs(ab_an).max()
    # measured 1.5e-10 (FD truncation eps**2 and round-off 1e-16/eps)
    assert np.abs(ab_an - ab_fd).max() < 1e-8 * scale
    # dense FD, one coordinate at a time
    H = np.zeros((2 * n, 2 * n))
    for k in range(n):
        for a in range(2):
            fp, fm = np.zeros((n, 2)), np.zeros((n, 2))
            xp = x.copy()
            xp[k, a] += eps
            bending_force_add(xp, el, 1.3, fp)
            xp[k, a] -= 2 * eps
            bending_force_add(xp, el, 1.3, fm)
            H[:, 2 * k + a] = -(fp - fm).ravel() / (2 * eps)
    idx = np.array([(3 * k - 1 if k else 0) + a for k in range(n) for a in range(2)])
    An = _dense(ab_an)[np.ix_(idx, idx)]
    np.testing.assert_allclose(An, 0.7 * w.ravel()[:, None] * H, rtol=0, atol=1e-8 * scale)
    Hs = An / w.ravel()[:, None]
    np.testing.assert_allclose(Hs, Hs.T, rtol=0, atol=1e-12 * scale)


def test_newton_matrix_is_the_jacobian_of_the_residual():
    """Bending-only residual: the assembled band matrix equals a dense FD Jacobian."""
    x, _ = _curved(n=8, h=0.125, seed=3)
    rod = Rod.from_positions(x, 0.1 * np.random.default_rng(4).random(x.shape))
    mod = compile_stepper(())
    n = rod.n_nodes
    N = 3 * n - 1
    dt = 0.01
    w = np.repeat((1 / rod.mass)[:, None], 2, axis=1)
    el = rod.edge_len
    rng = np.random.default_rng(5)
    d0 = dt * rod.v + 1e-3 * rng.standard_normal((n, 2))
    mu0 = 1e-4 * rng.standard_normal(n - 1)
    idx = np.array([(3 * k - 1 if k else 0) + a for k in range(n) for a in range(2)])
    midx = 3 * np.arange(n - 1) + 4

    def residual(z):
        d = np.zeros((n, 2))
        d.ravel()[:] = z[idx]
        xm = rod.x + 0.5 * d
        F, e = np.zeros((n, 2)), np.zeros(1)
        mod._forces(xm, d / dt, 0.0, el, rod.mass, 1.0, F, e, ())
        rhs = np.zeros(N)
        kkt_residual(rod.x, rod.v, d, xm, F, z[midx].copy(), w, el, dt, rhs)
        return -rhs

    z0 = np.zeros(N)
    z0[idx] = d0.ravel()
    z0[midx] = mu0
    J = np.zeros((N, N))
    for c in range(N):
        e = np.zeros(N)
        e[c] = 1e-7
        J[:, c] = (residual(z0 + e) - residual(z0 - e)) / 2e-7
    ab = np.zeros((N, 3 * KL + 1))
    xm = rod.x + 0.5 * d0
    kkt_assemble(rod.x, d0, xm, mu0, w, el, ab)
    bending_hessian_add(xm, el, 1.0, 0.25 * dt * dt, w, ab)
    # measured 5e-10 against entries of order 15
    np.testing.assert_allclose(_dense(ab), J, rtol=0, atol=1e-8 * np.abs(J).max())


# ----------------------------------------------------------------------------- validation


def _free_free_mode(s, L):
    bL = BETA_L["free-free"]
    b = bL / L
    sg = (np.cosh(bL) - np.cos(bL)) / (np.sinh(bL) - np.sin(bL))
    return np.cosh(b * s) + np.cos(b * s) - sg * (np.sinh(b * s) + np.sin(b * s))


def _first_mode_error(n, dt, implicit, periods=5, amplitude=1e-4):
    """Relative error of the first free-free frequency (L = B = mu = 1), as in
    test_dyn_validation, with a frame at every step for the implicit runs."""
    L = 1.0
    omega = euler_bernoulli_omega("free-free", L, 1.0, 1.0)
    h = L / n
    s = np.arange(n + 1) * h
    phi = _free_free_mode(s, L)
    rod = rod_from_angles(amplitude * np.diff(phi) / h, h)
    t_end = periods * 2 * np.pi / omega
    if implicit:
        r = simulate_midpoint(rod, FREE, dt=dt, t_end=t_end,
                              frames=np.arange(int(t_end / dt) + 1) * dt)
    else:
        r = simulate(rod, (), dt=dt, t_end=t_end, frames=periods * 120)
    assert r.success, r.message
    q = (r.positions[:, :, 1] * (rod.mass * phi)).sum(axis=1)
    q -= q.mean()
    return 2 * np.pi / crossing_period(r.times, q) / omega - 1.0


def test_first_mode_frequency_second_order_in_dt():
    """40 edges, dt = 18, 36, 71 x the explicit bound.  The space error is measured with
    RATTLE at dt = h**2/4 (its time error < 1e-7); the rest is the midpoint rule's,
    -(omega dt)**2 / 12, checked three ways: observed order, coefficient, and the exact
    midpoint dispersion (2/dt) atan(omega_N dt / 2)."""
    n = 40
    omega = euler_bernoulli_omega("free-free", 1.0, 1.0, 1.0)
    e_space = _first_mode_error(n, 0.25 / n**2, implicit=False)
    dts = np.array([0.02, 0.01, 0.005])
    assert dts[-1] > 15 * stable_dt(np.full(n, 1 / n), 1.0, 1.0)
    errs = np.array([_first_mode_error(n, dt, implicit=True) for dt in dts])
    e_time = errs - e_space
    order = np.polyfit(np.log(dts), np.log(np.abs(e_time)), 1)[0]
    # measured: e_time = -1.61e-2, -4.11e-3, -1.03e-3 (order 1.98)
    assert order == pytest.approx(2.0, abs=0.1), f"observed order {order:.3f}, {e_time}"
    ratio = e_time / (-(omega * dts) ** 2 / 12)
    # measured 0.962, 0.986, 0.990 (-> 1 as omega dt -> 0)
    assert np.all((ratio > 0.95) & (ratio < 1.01)), ratio
    omega_n = omega * (1 + e_space)
    pred = 2 / dts * np.arctan(omega_n * dts / 2) / omega - 1
    # measured 2.9e-5, 3.0e-6, 5.3e-7
    assert np.all(np.abs(errs - pred) < 6e-5), errs - pred


def test_constraints_exact_far_above_the_bound(wavy_rod):
    dt = 16 * stable_dt(wavy_rod.edge_len, 1.0, 1.0)
    r = simulate_midpoint(wavy_rod, FREE, dt=dt, t_end=20.0, frames=21)
    assert r.success, r.message
    assert r.stats["rejected_steps"] == 0
    # measured 3.2e-14 (RATTLE: 4e-14)
    assert r.stats["constraint_error"] < 2e-13
    for x in r.positions:
        e = np.abs(np.linalg.norm(np.diff(x, axis=0), axis=1) / wavy_rod.edge_len - 1)
        assert e.max() < 2e-13


def test_energy_bounded_second_order_no_drift_far_above_bound(wavy_rod):
    """Undamped, t = 200 (about 200 periods of the first mode), at 4 and 8 x the
    explicit bound: the error is bounded, O(dt**2), and does not drift."""
    b = stable_dt(wavy_rod.edge_len, 1.0, 1.0)
    errs = []
    for k in (4, 8):
        r = simulate_midpoint(wavy_rod, FREE, dt=k * b, t_end=200.0, frames=1001)
        assert r.success, r.message
        E = r.energies["total"]
        scale = r.energies["bending"][0]
        err = np.abs(E - E[0]).max() / scale
        drift = abs(E[-100:].mean() - E[:100].mean()) / scale
        errs.append(err)
        # measured drift/err = 0.32 (k = 4) and 0.32 (k = 8): the mean wanders within
        # the oscillation band but does not grow (same ratio at t = 60)
        assert drift < 0.5 * err, f"k={k}: drift {drift:.2e} vs error {err:.2e}"
    order = np.log(errs[1] / errs[0]) / np.log(2.0)
    # measured 1.9e-4 and 8.1e-4 (order 2.1); RATTLE at 0.9 x bound: 1.0e-2
    assert order == pytest.approx(2.0, abs=0.3), f"observed order {order:.3f}, {errs}"
    assert errs[0] < 4e-4


def test_damping_is_exact_on_a_rigid_translation():
    rod = Rod.straight(20, 1.0)
    rod.v[:, 0] = 1.0
    # the loaded contact tests' effects with no gravity, the ground far below, no load and
    # no contact on the straight rod: their compiled stepper
    eff = (Gravity(0.0), Ground(-100.0), SelfContact(0.01), Damping(0.3),
           *(PointLoad(k, (0.0, 0.0), name=f"load_{k}") for k in (0, 10, 20)))
    r = simulate_midpoint(rod, eff, dt=0.05, t_end=2.0, frames=5)
    assert r.stats["self_contact_steps"] == 0
    assert r.success, r.message
    # uniform rate c / mu: v = exp(-0.3 t), exactly (split exact decay)
    np.testing.assert_allclose(r.velocities[:, 0], np.exp(-0.6), rtol=1e-13)
    np.testing.assert_allclose(r.energies["kinetic"], 0.5 * np.exp(-0.6 * r.times), rtol=1e-12)


def test_refuses_constraint_effects_other_than_one_ground_by_name():
    rod = Rod.straight(10, 1.0)
    with pytest.raises(ValueError, match="effect 'clamp': constraint effects other than a "
                       "ground"):
        simulate_midpoint(rod, (Clamp(0, (0.0, 0.0), angle=0.0),), dt=0.01, t_end=0.1)
    with pytest.raises(ValueError, match="effect 'g2': the midpoint method handles one ground"):
        simulate_midpoint(rod, (Ground(), Ground(name="g2")), dt=0.01, t_end=0.1)
    with pytest.raises(ValueError, match="dt must be > 0"):
        simulate_midpoint(rod, (), dt=0.0, t_end=0.1)
    with pytest.raises(ValueError, match="jacobian_age must be >= 1"):
        simulate_midpoint(rod, (), dt=0.01, t_end=0.1, jacobian_age=0)


# ----------------------------------------------------------------------------- impacts


def _impact(delta, implicit, k, n=100, L=4.6):
    # built as elastocap.impact.run_impact builds supp-fig5 (straight rod at rest, drop
    # centred, damping 0.2, rest at 1e-6 gamma Delta for 1 time unit)
    from elastocap.capillary import Capillary

    x0 = np.zeros((n + 1, 2))
    x0[:, 0] = np.linspace(0.0, L, n + 1)
    rod = Rod(x0, np.zeros_like(x0), np.full(n, L / n), 1.0, 1.0)
    effects = (Capillary(1.5, L / 2 - delta / 2, L / 2 + delta / 2, 1.0), Damping(0.2))
    dt = k * stable_dt(rod.edge_len, 1.0, 1.0)
    f = simulate_midpoint if implicit else simulate
    return f(rod, effects, dt=dt, t_end=200.0, frames=401,
             rest=RestCriterion(1e-6 * delta, 1.0))


def _theta(x):
    e = np.diff(x, axis=0)
    th = np.unwrap(np.arctan2(e[:, 1], e[:, 0]))
    return th - th.mean()


@pytest.mark.parametrize("delta", [2.5, 4.0])
def test_damped_supp_fig5_final_shape_agrees_with_rattle(delta):
    from elastocap.geometry import turning_measure

    ref = _impact(delta, False, 0.9)
    r = _impact(delta, True, 16)
    assert isinstance(r, SimulationResult)
    assert r.status == "at_rest" and ref.status == "at_rest", r.message
    assert set(r.energies) == {"kinetic", "bending", "capillary", "total"}
    M, Mref = turning_measure(r.positions[-1]), turning_measure(ref.positions[-1])
    assert (M > 1) == (Mref > 1) == (delta > 3.6)
    # measured |dM| = 6.4e-5 (2.5) and 1.8e-4 (4.0): the level at which the rest
    # criterion stops the creeping rod (README: 1.7e-3 from the statics)
    assert abs(M - Mref) < 5e-4
    # the whole shape: tangent angles, rotation removed; measured 1.0e-4 / 3.2e-4 rad
    assert np.abs(_theta(r.positions[-1]) - _theta(ref.positions[-1])).max() < 1e-3
    assert r.steps < ref.steps / 15
    assert r.stats["constraint_error"] < 2e-13


@pytest.mark.parametrize("delta", [3.50, 3.55])
def test_outcome_near_the_threshold_agrees_with_rattle(delta):
    """Delta* = 3.527 at 100 edges: 3.50 stays open, 3.55 encapsulates, with either
    stepper, at 16 and 64 x the explicit bound."""
    from elastocap.geometry import turning_measure

    Mref = turning_measure(_impact(delta, False, 0.9).positions[-1])
    for k in (16, 64):
        r = _impact(delta, True, k)
        assert r.status == "at_rest", f"k = {k}: {r.message}"
        M = turning_measure(r.positions[-1])
        assert (M > 1) == (Mref > 1) == (delta > 3.527), f"k = {k}: M = {M}, RATTLE {Mref}"
        # measured |dM| <= 4.3e-5 at k = 16 and 64
        assert abs(M - Mref) < 5e-4, f"k = {k}: M = {M}, RATTLE {Mref}"
