"""Force stiffness in the implicit stepper's Newton matrix (the optional ``stiffness`` hook
of the effect protocol): the drop's Hessian as band + rank 5, the Woodbury solve, the
Newton matrix against finite differences, and what it does to the Newton iterations."""

import numpy as np
import pytest
from dyn_helpers import band_to_dense, dense_to_band, simulate_midpoint
from dyn_stiff_kernels import BadTether, NodeSpring, Tether

from dynamics import Damping, Gravity, RestCriterion, Rod, stable_dt
from dynamics.midpoint import (
    KL,
    band_backward,
    band_forward,
    band_lu,
    band_lu_nopivot,
    bending_hessian_add,
    compile_stepper,
    contact_lowrank,
    contact_rows_save,
    ground_rows_matrix,
    kkt_assemble,
    kkt_residual,
    lowrank_correct,
    lowrank_setup,
    stiffness_band_add,
)
from elastocap.capillary import Capillary, capillary_kernel
from elastocap.capillary_hessian import capillary_stiffness, stiffness_dense
from elastocap.strip.model import capillary_hessian_nodes

# ----------------------------------------------------------------------------- the drop


def _arc(n, L, turn, seed=0, noise=1e-3):
    """A polyline of n edges of length L/n turning uniformly by ``turn`` (radians), with a
    little noise so that no symmetry hides an error."""
    h = L / n
    th = turn * ((np.arange(n) + 0.5) / n - 0.5)
    th += noise * np.random.default_rng(seed).standard_normal(n)
    x = np.zeros((n + 1, 2))
    x[1:, 0] = np.cumsum(h * np.cos(th))
    x[1:, 1] = np.cumsum(h * np.sin(th))
    return x, np.full(n, h)


def _hook(x, el, params):
    n = x.shape[0]
    K = np.zeros((n, 2, 5, 2))
    U = np.zeros((8, n, 2))
    C = np.zeros((8, 8))
    k = capillary_stiffness(x, np.zeros_like(x), 0.0, params, el, np.ones(n), K, U, C)
    return stiffness_dense(K, U, C, k), k, K, U, C


def _fd_hessian(x, el, params, eps=1e-6):
    """Central differences of the force of capillary_kernel (truncation ~eps**2, round-off
    ~1e-16 / eps relative)."""
    n = x.shape[0]
    H = np.zeros((2 * n, 2 * n))
    for j in range(2 * n):
        fs = []
        for sgn in (1.0, -1.0):
            xp = x.copy()
            xp.ravel()[j] += sgn * eps
            f = np.zeros_like(x)
            capillary_kernel(xp, xp, 0.0, params, el, np.ones(n), f)
            fs.append(f.ravel())
        H[:, j] = -(fs[0] - fs[1]) / (2 * eps)
    return H


# (edges, length, turn of the rod, area, S1, S2, gamma): contact points in mid-edge, a
# hair (1e-9 h) inside either end of an edge, both in one edge, in neighbouring edges, a
# wet part wrapped by 1.6 pi round the drop (encapsulated), and the fig3-strip drop
H3 = 3.0 / 30
CASES = {
    "supp-fig5": (40, 4.6, 0.3, 1.5, 1.07, 3.53, 1.0),
    "node-boundaries": (30, 3.0, 0.5, 0.3, 10 * H3 + 1e-9 * H3, 21 * H3 - 1e-9 * H3, 40.0),
    "one-edge": (30, 3.0, 0.2, 0.01, 12.2 * H3, 12.7 * H3, 40.0),
    "neighbour-edges": (30, 3.0, 0.2, 0.02, 12.6 * H3, 13.3 * H3, 40.0),
    "wrapped": (60, 4.6, 1.6 * np.pi / 0.87, 1.5, 0.3, 4.3, 1.0),
    "fig3-strip": (198, 14.3, 0.8, 0.36, 11.72, 12.88, 40.0),
}


@pytest.mark.parametrize("case", list(CASES))
def test_capillary_stiffness_is_the_exact_hessian(case):
    """Band + rank 5 reassembled equals the dense reference Hessian to round-off and a
    finite difference of the force to its truncation."""
    n, L, turn, area, s1, s2, gamma = CASES[case]
    x, el = _arc(n, L, turn)
    params = np.array([area, s1, s2, gamma])
    H, k, K, U, C = _hook(x, el, params)
    assert k == 5
    s_nodes = np.concatenate(([0.0], np.cumsum(el)))
    i1, Hr = capillary_hessian_nodes(x, s_nodes, s1, s2, area, gamma)
    ref = np.zeros_like(H)
    m = Hr.shape[0]
    ref[2 * i1:2 * i1 + m, 2 * i1:2 * i1 + m] = Hr
    scale = np.abs(ref).max()
    # measured <= 4e-16 relative (the same formulas, summed in another order)
    np.testing.assert_allclose(H, ref, rtol=0, atol=1e-13 * scale)
    # measured 4e-11 - 6e-10 relative (eps = 1e-6)
    np.testing.assert_allclose(H, _fd_hessian(x, el, params), rtol=0, atol=2e-8 * scale)
    # the band part is within one node of the diagonal; the rest is rank <= 5
    for o in (0, 4):
        assert not K[:, :, o, :].any()
    assert np.linalg.matrix_rank(H - stiffness_dense(K, U, C, 0), tol=1e-12 * scale) <= 5
    np.testing.assert_allclose(C[:5, :5], C[:5, :5].T, rtol=0, atol=0)


def test_capillary_stiffness_of_the_wrapped_drop_is_really_wrapped():
    # the "wrapped" case closes round the drop: turning 1.6 pi along the wet part, the cap
    # bulging beyond a half circle
    n, L, turn, area, s1, s2, gamma = CASES["wrapped"]
    x, el = _arc(n, L, turn)
    g = np.zeros_like(x)
    from elastocap.drop import capillary_energy_and_gradient

    s_nodes = np.concatenate(([0.0], np.cumsum(el)))
    _e, tau, _kappa = capillary_energy_and_gradient(x, s_nodes, s1, s2, area, gamma, g)
    e = np.diff(x, axis=0)
    th = np.unwrap(np.arctan2(e[:, 1], e[:, 0]))
    wet = (s_nodes[:-1] > s1) & (s_nodes[1:] < s2)
    assert th[wet][-1] - th[wet][0] > 1.4 * np.pi
    assert abs(tau) > np.pi / 2


def test_degenerate_cap_gives_no_stiffness():
    x, el = _arc(10, 1.0, 0.1)
    x[:] = 0.0  # both contact points on one spot: d = 0
    n = x.shape[0]
    K, U, C = np.zeros((n, 2, 5, 2)), np.zeros((8, n, 2)), np.zeros((8, 8))
    params = np.array([0.1, 0.25, 0.75, 1.0])
    assert capillary_stiffness(x, x, 0.0, params, el, np.ones(n), K, U, C) == 0
    assert not K.any() and not U.any() and not C.any()


# ----------------------------------------------------------------------------- Woodbury


def _dense(ab, kl=KL, ku=KL):
    return band_to_dense(ab, kl, ku)


def _band(A, kl=KL, ku=KL):
    return dense_to_band(A, kl, ku)


@pytest.mark.parametrize("pivoting", [False, True])
def test_woodbury_solve_equals_the_dense_solve(pivoting):
    """(A + q W U^T C U) y = b by the band LU and Woodbury, against numpy, with held rows
    (their low-rank row is zero) and the low-rank vectors starting mid-rod."""
    rng = np.random.default_rng(7)
    n = 30
    N = 3 * n - 1
    A = np.zeros((N, N))
    for r in range(N):
        for c in range(max(0, r - KL), min(N, r + KL + 1)):
            A[r, c] = rng.standard_normal()
    if not pivoting:
        A += np.diag(np.full(N, 20.0))
    k = 5
    U = np.zeros((8, n, 2))
    U[:k, 12:] = rng.standard_normal((k, n - 12, 2))
    C = rng.standard_normal((8, 8))
    winv = rng.random((n, 2)) + 0.5
    held = np.zeros(n)
    held[[14, 20]] = 1.0
    q = 0.3
    idx = np.array([(3 * i - 1 if i else 0) + a for i in range(n) for a in range(2)])
    Ln = q * winv.reshape(-1, 1) * U[:k].reshape(k, -1).T
    Ln[2 * np.flatnonzero(held) + 1] = 0.0
    Lk = np.zeros((N, k))
    Lk[idx] = Ln
    Vk = np.zeros((k, N))
    Vk[:, idx] = C[:k, :k] @ U[:k].reshape(k, -1)
    M = A + Lk @ Vk
    b = rng.standard_normal(N)
    exact = np.linalg.solve(M, b)

    ab = _band(A)
    piv = np.zeros(N, dtype=np.int64)
    if pivoting:
        assert band_lu(ab, piv, KL, KL) == 0
        assert np.any(piv != np.arange(N))
    else:
        assert band_lu_nopivot(ab, KL, KL, 1e-10) == 0
        piv[0] = -1
    G, H = np.full((N, 8), 7.0), np.full((N, 8), 7.0)  # stale entries must not be read
    S, spiv = np.zeros((8, 8)), np.zeros(8, dtype=np.int64)
    start = lowrank_setup(ab, piv, U, C, k, q, winv, held, G, H, S, spiv)
    # the vectors start at node 12, coordinate row 35; interchanges move rows up <= KL
    assert start == 3 * 12 - 1 - KL
    y = b.copy()
    band_forward(ab, piv, KL, y)
    lowrank_correct(y, k, start, G, H, S, spiv, np.zeros(8))
    band_backward(ab, piv, KL, KL, y)
    np.testing.assert_allclose(y, exact, rtol=0, atol=1e-11 * np.abs(exact).max())
    # a singular capacitance matrix I + Vt A^-1 L is reported, not used: rank 1 with
    # C = -1 / (u^T A^-1 l), l = q W u (held rows zeroed)
    u = np.zeros(N)
    u[idx] = U[0].ravel()
    C1 = np.zeros((8, 8))
    C1[0, 0] = -1.0 / (u @ np.linalg.solve(A, Lk[:, 0]))
    U1 = np.zeros_like(U)
    U1[0] = U[0]
    assert lowrank_setup(ab, piv, U1, C1, 1, q, winv, held, G, H, S, spiv) == -1


@pytest.mark.parametrize("pivoting", [False, True])
@pytest.mark.parametrize("k", [0, 5])
def test_contact_rows_switched_by_a_low_rank_update(pivoting, k):
    """Nodes caught or released by the ground after the factorisation: the Woodbury
    update of their rows (contact_lowrank) solves like a dense matrix assembled with the
    new held set, with and without a low-rank stiffness part."""
    rng = np.random.default_rng(11 + k + 2 * pivoting)
    n = 30
    N = 3 * n - 1
    idx = np.array([(3 * i - 1 if i else 0) + a for i in range(n) for a in range(2)])
    A0 = np.zeros((N, N))
    for r in range(N):
        for c in range(max(0, r - KL), min(N, r + KL + 1)):
            A0[r, c] = rng.standard_normal()
    if not pivoting:
        A0 += np.diag(np.full(N, 20.0))
    U = np.zeros((8, n, 2))
    U[:k, 12:] = rng.standard_normal((k, n - 12, 2))
    C = rng.standard_normal((8, 8))
    winv = rng.random((n, 2)) + 0.5
    q = 0.3

    def dense(held):
        ab = _band(A0)
        ground_rows_matrix(held, ab)
        M = _dense(ab)
        if k:
            Ln = q * winv.reshape(-1, 1) * U[:k].reshape(k, -1).T
            Ln[2 * np.flatnonzero(held) + 1] = 0.0
            Lk = np.zeros((N, k))
            Lk[idx] = Ln
            Vk = np.zeros((k, N))
            Vk[:, idx] = C[:k, :k] @ U[:k].reshape(k, -1)
            M = M + Lk @ Vk
        return M

    held_f = np.zeros(n)
    held_f[[14, 20, 25]] = 1.0
    R = 8 + 4  # room for 4 contact columns
    # stale entries everywhere, as left by earlier factorisations (whose contact columns
    # may start above this one's stiffness columns): the kernels must not read them
    G, H = np.full((N, R), 7.0), np.full((N, R), 7.0)
    S, spiv = np.zeros((R, R)), np.zeros(R, dtype=np.int64)
    kinfo = np.zeros(8, dtype=np.int64)
    mom, hf = np.zeros((n, 3 * KL + 1)), np.zeros(n)
    ab = _band(A0)
    contact_rows_save(ab, held_f, mom, hf)
    ground_rows_matrix(held_f, ab)
    piv = np.zeros(N, dtype=np.int64)
    if pivoting:
        assert band_lu(ab, piv, KL, KL) == 0
    else:
        assert band_lu_nopivot(ab, KL, KL, 1e-10) == 0
        piv[0] = -1
    if k:
        kinfo[0] = k
        kinfo[2] = kinfo[6] = lowrank_setup(ab, piv, U, C, k, q, winv, held_f, G, H, S, spiv)
    # caught (3, 17, 28), released (14, 20, 25), both, and back to the factorisation's
    for nodes, c_exp in (([14, 20, 25, 3], 1), ([20, 25, 17], 2), ([14, 28], 3), ([], 3),
                         ([14, 20, 25], 0)):
        held = np.zeros(n)
        held[nodes] = 1.0
        assert contact_lowrank(ab, piv, held, hf, mom, U, C, k, q, winv, G, H, S, spiv,
                               kinfo) == c_exp == kinfo[4]
        b = rng.standard_normal(N)
        exact = np.linalg.solve(dense(held), b)
        y = b.copy()
        band_forward(ab, piv, KL, y)
        if k + c_exp:
            lowrank_correct(y, k + c_exp, kinfo[2], G, H, S, spiv, np.zeros(R))
        band_backward(ab, piv, KL, KL, y)
        # measured 2e-16 - 1.2e-13 relative
        np.testing.assert_allclose(y, exact, rtol=0, atol=1e-11 * np.abs(exact).max())
    # more changes than columns: refused, the caller refactors
    held = np.zeros(n)
    held[1:14] = 1.0  # 16 changes, room for 12 - k
    assert contact_lowrank(ab, piv, held, hf, mom, U, C, k, q, winv, G, H, S, spiv,
                           kinfo) == -1


def test_newton_matrix_with_the_drop_is_the_jacobian_of_the_residual():
    """Mass, constraints, bending and now the drop: the band matrix plus the rank-5 part
    equals a dense finite-difference Jacobian of the residual, and the generated
    ``_jacobian`` / ``_solve`` pair solves with it."""
    n_e = 24
    x, el = _arc(n_e, 4.6, 2.5, seed=3)
    rng = np.random.default_rng(4)
    rod = Rod.from_positions(x, 0.1 * rng.random(x.shape))
    el = rod.edge_len
    # gamma = 10 and dt = 0.1: the rank-5 part would slow the simplified Newton to a rate
    # of 0.46 without it (above LOWRANK_MIN_RATE, so the stepper uses it)
    cap = Capillary(1.5, 1.0, 3.6, 10.0)
    mod = compile_stepper((cap,))
    assert mod.HAS_STIFFNESS
    n = rod.n_nodes
    N = 3 * n - 1
    dt = 0.1
    w = np.repeat((1 / rod.mass)[:, None], 2, axis=1)
    d0 = dt * rod.v + 1e-3 * rng.standard_normal((n, 2))
    mu0 = 1e-4 * rng.standard_normal(n - 1)
    idx = np.array([(3 * k - 1 if k else 0) + a for k in range(n) for a in range(2)])
    midx = 3 * np.arange(n - 1) + 4

    def residual(z):
        d = np.zeros((n, 2))
        d.ravel()[:] = z[idx]
        xm = rod.x + 0.5 * d
        F, e = np.zeros((n, 2)), np.zeros(2)
        mod._forces(xm, d / dt, 0.0, el, rod.mass, 1.0, F, e, (cap.params,))
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
    xm = rod.x + 0.5 * d0
    ab = np.zeros((N, 3 * KL + 1))
    kkt_assemble(rod.x, d0, xm, mu0, w, el, ab)
    bending_hessian_add(xm, el, 1.0, 0.25 * dt * dt, w, ab)
    K, U, C = np.zeros((n, 2, 5, 2)), np.zeros((8, n, 2)), np.zeros((8, 8))
    k = capillary_stiffness(xm, d0 / dt, 0.0, cap.params, el, rod.mass, K, U, C)
    stiffness_band_add(K, 0.25 * dt * dt, w, ab)
    M = _dense(ab)
    Hlr = stiffness_dense(K, U, C, k) - stiffness_dense(K, U, C, 0)
    M[np.ix_(idx, idx)] += 0.25 * dt * dt * w.reshape(-1, 1) * Hlr
    # the drop's couplings beyond the band are there (S1 and S2 are 14 edges apart),
    # measured 8.6e-5 of the largest entry: 1e4 x the tolerance below
    assert np.abs(M - _dense(_band(M))).max() > 4e-5 * np.abs(M).max()
    # measured 3e-10 against entries of order 1 (FD truncation and round-off)
    np.testing.assert_allclose(M, J, rtol=0, atol=1e-8 * np.abs(J).max())

    # the generated pair: factor, Woodbury, solve
    lr = (np.zeros((n, 2, 5, 2)), np.zeros((8, n, 2)), np.zeros((8, 8)), np.zeros((N, 8)),
          np.zeros((N, 8)), np.zeros((8, 8)), np.zeros(8, dtype=np.int64),
          np.zeros(8, dtype=np.int64), np.zeros(8), np.zeros(0), np.zeros((0, 3 * KL + 1)))
    piv = np.zeros(N, dtype=np.int64)
    ab = np.zeros((N, 3 * KL + 1))
    info = mod._jacobian(rod.x, d0, xm, d0 / dt, 0.0, mu0, w, el, rod.mass, 1.0, dt, ab, piv,
                         np.zeros(n), lr, True, (cap.params,))
    assert info == 0 and lr[7][0] == 5 and lr[7][1] == 0
    b = rng.standard_normal(N)
    y = b.copy()
    mod._solve(ab, piv, y, lr)
    np.testing.assert_allclose(y, np.linalg.solve(M, b), rtol=0,
                               atol=1e-10 * np.abs(y).max())


# ----------------------------------------------------------------------------- the protocol


def test_an_effect_without_the_hook_costs_nothing():
    assert not compile_stepper((Gravity(), Damping(0.1))).HAS_STIFFNESS
    assert compile_stepper((Capillary(1.0, 1.0, 2.0, 1.0), Gravity())).HAS_STIFFNESS


def test_hooks_compose_and_the_converged_steps_do_not_depend_on_them():
    """A stiff vertical tether between nodes 22 apart (rank 1, far outside the band) and
    a node spring (band only): with their stiffness Newton converges in fewer iterations,
    to the same steps (the converged solution does not depend on the Newton matrix).  The
    hooks are switched by the run's ``stiffness`` option: one compiled stepper."""
    rod = Rod.straight(30, 3.0)
    rod.v[:, 1] = 0.5 * np.sin(3 * np.pi * np.linspace(0.0, 1.0, 31))
    runs = [simulate_midpoint(rod, (Tether(3, 25, 300.0), NodeSpring(10, 5.0)),
                              dt=0.02, t_end=2.0, frames=21, stiffness=h)
            for h in (True, False)]
    on, off = runs
    assert on.success and off.success
    assert on.stats["rejected_steps"] == off.stats["rejected_steps"] == 0
    # Newton's linear rate without the tether's stiffness is ~ dt**2 k / (4 m) = 0.3;
    # measured 7.06 iterations a step with it, 16.24 without
    assert on.stats["iterations_mean"] < 7.5
    assert off.stats["iterations_mean"] > 2 * on.stats["iterations_mean"]
    # 100 steps each converged to 1e-13 h (h = 0.1): measured 4.5e-13
    assert np.abs(on.positions - off.positions).max() < 1e-11
    np.testing.assert_allclose(on.energies["total"], off.energies["total"], rtol=0,
                               atol=1e-10)


def test_a_hook_breaking_the_protocol_is_refused_by_message():
    rod = Rod.straight(10, 1.0)
    rod.v[:, 1] = np.linspace(-0.1, 0.1, 11)  # a rotation: the first step needs Newton
    with pytest.raises(ValueError, match="a stiffness hook returned a rank outside"):
        # the effects of the test above (a spring of zero stiffness): its compiled stepper
        simulate_midpoint(rod, (BadTether(1, 8, 1.0), NodeSpring(5, 0.0)), dt=0.01,
                          t_end=0.02)


# ----------------------------------------------------------------------------- impacts


def _supp_fig5(delta, k, stiffness, n=100, L=4.6):
    x0 = np.zeros((n + 1, 2))
    x0[:, 0] = np.linspace(0.0, L, n + 1)
    rod = Rod(x0, np.zeros_like(x0), np.full(n, L / n), 1.0, 1.0)
    effects = (Capillary(1.5, L / 2 - delta / 2, L / 2 + delta / 2, 1.0), Damping(0.2))
    dt = k * stable_dt(rod.edge_len, 1.0, 1.0)
    return simulate_midpoint(rod, effects, dt=dt, t_end=200.0, frames=401,
                             rest=RestCriterion(1e-6 * delta, 1.0), stiffness=stiffness)
