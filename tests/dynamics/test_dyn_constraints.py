"""The constraint projections: SHAKE (Newton + tridiagonal) and the velocity projection.

The references are dense: Newton on the multipliers with the dense Jacobian and
``numpy.linalg.solve`` (same stopping rules as the kernel), and the dense velocity
projection; the kernels solve the same equations with two-ended tridiagonal eliminations,
so they must agree to round-off and need the same number of Newton updates.
"""

import numpy as np
import pytest
from dyn_helpers import rod_from_angles

from dynamics.constraints import (
    SHAKE_CHORD,
    SHAKE_FINAL,
    SHAKE_TOL,
    _eliminate,
    _eliminate_serial,
    _resolve,
    _row_argmax,
    _row_max,
    _substitute,
    constraint_error,
    new_work,
    shake,
    solve_tridiagonal,
    velocity_projection,
)


def _setup(n=60, seed=0):
    rng = np.random.default_rng(seed)
    rod = rod_from_angles(np.cumsum(0.2 * rng.standard_normal(n)), 0.1)
    winv = np.repeat((1.0 / rod.mass)[:, None], 2, axis=1).copy()
    return rod, winv, rng


def _jacobian_dense(x_old, x_new, winv):
    """d phi_i / d lam_k of phi_i = |r_i|^2 - l_i^2 along x_new = x* + W G(x_old)^T lam."""
    d = np.diff(x_old, axis=0)
    r = np.diff(x_new, axis=0)
    m = d.shape[0]
    # x_j += W_j (d_{j-1} lam_{j-1} - d_j lam_j): dx_new / dlam (nodes x 2, m)
    dX = np.zeros((m + 1, 2, m))
    for k in range(m):
        dX[k + 1, :, k] += winv[k + 1] * d[k]
        dX[k, :, k] -= winv[k] * d[k]
    J = np.zeros((m, m))
    for i in range(m):
        J[i] = 2.0 * (r[i] @ (dX[i + 1] - dX[i]))
    return J, d


def _shake_dense(x_old, x_new, winv, edge_len, final_tol=SHAKE_FINAL):
    """Dense Newton with the stopping rules of ``shake`` (no skipped rows: every test
    rod here has free nodes at both ends of every edge, or a held node on one side)."""
    x = x_new.copy()
    err_prev_prev = 0.0
    lam = np.zeros(edge_len.size)
    for it in range(51):
        r = np.diff(x, axis=0)
        phi = np.sum(r * r, axis=1) - edge_len**2
        err = np.max(np.abs(phi) / (2 * edge_len**2))
        if err <= SHAKE_TOL:
            return x, it, lam
        J, d = _jacobian_dense(x_old, x, winv)
        dl = np.linalg.solve(J, -phi)
        lam += dl
        step = np.zeros_like(x)
        step[1:] += d * dl[:, None]
        step[:-1] -= d * dl[:, None]
        x += winv * step
        if err <= final_tol and err <= err_prev_prev**2:
            return x, it + 1, lam
        err_prev_prev = err
    raise AssertionError("dense Newton did not converge")


def test_solve_tridiagonal_against_dense():
    rng = np.random.default_rng(3)
    m = 30
    a, c = rng.standard_normal(m), rng.standard_normal(m)
    b = 4.0 + rng.random(m)
    d = rng.standard_normal(m)
    A = np.diag(b) + np.diag(a[1:], -1) + np.diag(c[:-1], 1)
    y = solve_tridiagonal(a, b, c, d, np.empty(m), np.empty(m), np.empty(m))
    np.testing.assert_allclose(A @ y, d, atol=1e-13)


@pytest.mark.parametrize("serial", [False, True])
@pytest.mark.parametrize("m", [1, 2, 3, 4, 5, 6, 7, 16, 17, 50, 101])
def test_two_ended_elimination_against_dense(m, serial):
    """Both halves of the elimination (by minors, and the serial fallback), the junction
    and the re-solve with kept factors, for even and odd sizes, with identity rows
    (skipped constraints) among them."""
    rng = np.random.default_rng(m)
    a, c = rng.standard_normal(m), rng.standard_normal(m)
    b = 4.0 + rng.random(m)
    a[0] = c[-1] = 0.0
    ident = rng.random(m) < 0.15
    a[ident], c[ident], b[ident] = 0.0, 0.0, 1.0
    A = np.diag(b) + np.diag(a[1:], -1) + np.diag(c[:-1], 1)
    work = new_work(m)
    work[2, 1:-1], work[3, 1:-1], work[4, 1:-1] = a, b, c
    for first in (True, False):
        d = rng.standard_normal(m)
        d[ident] = 0.0
        work[5, 1:-1] = d
        work[6, 1:-1] = np.abs(d)
        # the second right-hand side reuses the factors kept by the first elimination
        err = _row_max(work, 6)
        assert err == np.abs(d).max() and _row_argmax(work, 6) == int(np.argmax(np.abs(d)))
        assert work[6, 0] == 0.0
        if first and serial:
            _eliminate_serial(work)
        elif first:
            assert _eliminate(work)
        else:
            _resolve(work)
        _substitute(work)
        np.testing.assert_allclose(work[5, 1:-1], np.linalg.solve(A, d), rtol=0, atol=1e-14)
        assert work[5, 0] == 0.0 and work[5, -1] == 0.0


def test_row_max_sees_nan():
    """The SIMD maximum of a residual row: NaN (either sign) wins over inf, the pad used
    as scratch is restored."""
    work = new_work(9)
    work[6, 1:-1] = np.linspace(0.0, 1.0, 9)
    assert _row_max(work, 6) == 1.0 and _row_argmax(work, 6) == 8
    work[6, 3] = np.inf
    assert _row_max(work, 6) == np.inf and _row_argmax(work, 6) == 2
    for nan in (np.nan, -np.nan):
        work[6, 5] = nan
        assert np.isnan(_row_max(work, 6)) and _row_argmax(work, 6) == 4
    assert work[6, 0] == 0.0


@pytest.mark.parametrize("scale", [1e-40, 1e40])
def test_elimination_flags_minors_out_of_range(scale):
    """Pivots far from 1 make the leading minors leave their range within a
    renormalisation block: flagged, and the serial fallback solves the same rows."""
    m = 40
    rng = np.random.default_rng(7)
    a, c = -rng.random(m), -rng.random(m)
    a[0] = c[-1] = 0.0
    b = 2.5 + rng.random(m)
    d = rng.standard_normal(m)
    A = np.diag(b) + np.diag(a[1:], -1) + np.diag(c[:-1], 1)
    work = new_work(m)
    work[2, 1:-1], work[3, 1:-1], work[4, 1:-1], work[5, 1:-1] = scale * a, scale * b, scale * c, d
    rows = work.copy()
    assert not _eliminate(work)
    _eliminate_serial(rows)
    _substitute(rows)
    np.testing.assert_allclose(scale * rows[5, 1:-1], np.linalg.solve(A, d), rtol=0, atol=1e-14)


@pytest.mark.parametrize("step", [1e-4, 1e-3, 1e-2])
def test_shake_converges_quadratically_to_round_off(step):
    rod, winv, rng = _setup()
    xn = rod.x + step * rng.standard_normal(rod.x.shape)
    x_ref, it_ref, _ = _shake_dense(rod.x, xn, winv, rod.edge_len)
    lam = np.zeros(rod.edge_len.size + 2)
    err, it, _, err_old = shake(rod.x, xn, winv, rod.edge_len, new_work(60), lam)
    assert it > 0 and err_old < 1e-14
    final, _ = constraint_error(xn, rod.edge_len)
    assert final < 1e-14, f"step {step}: residual {final:.2e} after {it} iterations"
    # the same Newton iteration as the dense reference: same updates, same projection
    assert it == it_ref
    np.testing.assert_allclose(xn, x_ref, rtol=0, atol=2e-15 * np.abs(rod.x).max())
    # quadratic convergence: random displacements of every node by 0.1%, 1%, 10% of an
    # edge need 3, 4, 6 updates (measured); a Verlet predictor needs 2
    assert it <= {1e-4: 3, 1e-3: 4, 1e-2: 6}[step]


def test_shake_multipliers_and_warm_start():
    """lam returns the multipliers (x_new - x* = W G(x_old)^T lam); started from them the
    projection lands on the same positions in at most one update."""
    rod, winv, rng = _setup(seed=4)
    xs = rod.x + 1e-3 * rng.standard_normal(rod.x.shape)
    x_ref, _, lam_ref = _shake_dense(rod.x, xs, winv, rod.edge_len)
    xn = xs.copy()
    lam = np.zeros(rod.edge_len.size + 2)
    work = new_work(60)
    shake(rod.x, xn, winv, rod.edge_len, work, lam)
    assert lam[0] == 0.0 and lam[-1] == 0.0
    np.testing.assert_allclose(lam[1:-1], lam_ref, rtol=1e-9, atol=0)
    xw = xs.copy()
    lam_w = lam.copy()
    err, it, _, _ = shake(rod.x, xw, winv, rod.edge_len, work, lam_w, True)
    assert it <= 1 and constraint_error(xw, rod.edge_len)[0] < 1e-14
    np.testing.assert_allclose(xw, xn, rtol=0, atol=1e-15 * np.abs(rod.x).max())


def test_shake_from_a_small_residual_uses_kept_factors_and_stays_at_round_off():
    """A start within 1e-6 of the constraints: the last update reuses the factorisation
    (a chord step); the result is the dense Newton projection to round-off."""
    rod, winv, rng = _setup(seed=5)
    xs = rod.x + 1e-8 * rng.standard_normal(rod.x.shape)
    r = np.diff(xs, axis=0)
    err0 = np.max(np.abs(np.sum(r * r, axis=1) - rod.edge_len**2) / (2 * rod.edge_len**2))
    # the first residual is below SHAKE_CHORD, the second above SHAKE_TOL: the second
    # update is a chord step
    assert 1e-8 < err0 < SHAKE_CHORD
    x_ref, it_ref, _ = _shake_dense(rod.x, xs, winv, rod.edge_len)
    xn = xs.copy()
    err, it, _, _ = shake(rod.x, xn, winv, rod.edge_len, new_work(60),
                          np.zeros(rod.edge_len.size + 2))
    assert it == it_ref == 2
    assert constraint_error(xn, rod.edge_len)[0] < 1e-14
    np.testing.assert_allclose(xn, x_ref, rtol=0, atol=2e-15 * np.abs(rod.x).max())


def test_shake_moves_along_old_constraint_gradients_weighted_by_inverse_mass():
    """x_new - x_star = W G(x_old)^T lam: held coordinates do not move."""
    rod, winv, rng = _setup()
    winv[0] = 0.0  # node 0 held
    winv[10, 1] = 0.0  # vertical coordinate of node 10 held
    xs = rod.x + 1e-3 * rng.standard_normal(rod.x.shape)
    xn = xs.copy()
    x_ref, it_ref, _ = _shake_dense(rod.x, xs, winv, rod.edge_len)
    _, it, _, _ = shake(rod.x, xn, winv, rod.edge_len, new_work(60),
                        np.zeros(rod.edge_len.size + 2))
    assert np.all(xn[0] == xs[0]) and xn[10, 1] == xs[10, 1]
    assert constraint_error(xn, rod.edge_len)[0] < 1e-14
    assert it == it_ref
    np.testing.assert_allclose(xn, x_ref, rtol=0, atol=2e-15 * np.abs(rod.x).max())


def test_shake_skips_edges_held_at_both_ends():
    """Two nodes held on a flat ground: their edge's row is the identity, the others are
    projected, and held coordinates keep their values exactly."""
    rod, winv, rng = _setup(n=30)
    winv[[10, 11], 1] = 0.0
    winv[[10, 11], 0] = 0.0
    xs = rod.x + 1e-4 * rng.standard_normal(rod.x.shape)
    xs[[10, 11]] = rod.x[[10, 11]]
    xn = xs.copy()
    err, it, _, _ = shake(rod.x, xn, winv, rod.edge_len, new_work(30),
                          np.zeros(rod.edge_len.size + 2))
    assert it > 0 and constraint_error(xn, rod.edge_len)[0] < 1e-14
    assert np.all(xn[[10, 11]] == xs[[10, 11]])


def test_shake_failure_is_reported_not_raised():
    rod, winv, rng = _setup()
    xn = rod.x + 0.5 * rng.standard_normal(rod.x.shape)  # five edge lengths of noise
    err, it, edge, _ = shake(rod.x, xn, winv, rod.edge_len, new_work(60),
                             np.zeros(rod.edge_len.size + 2))
    assert it == -1 and err > 1e-8 and 0 <= edge < 60


def test_velocity_projection_removes_stretching_and_keeps_tangent_part():
    rod, winv, rng = _setup()
    v = rng.standard_normal(rod.x.shape)
    v0 = v.copy()
    work = new_work(60)
    velocity_projection(rod.x, v, winv, work)
    e = np.diff(rod.x, axis=0)
    rate = np.abs(np.sum(e * np.diff(v, axis=0), axis=1)) / rod.edge_len**2
    assert rate.max() < 1e-12
    # a projection: idempotent, and the removed part is M-orthogonal to the kept part
    v2 = v.copy()
    velocity_projection(rod.x, v2, winv, work)
    np.testing.assert_allclose(v2, v, atol=1e-13)
    assert abs(np.sum(rod.mass[:, None] * v * (v0 - v))) < 1e-10 * np.sum(v0**2)
    # the dense projection v0 + W G^T mu, G W G^T mu = -G v0
    G = np.zeros((60, 61, 2))
    for i in range(60):
        G[i, i + 1] = e[i]
        G[i, i] = -e[i]
    G = G.reshape(60, -1)
    W = winv.ravel()
    mu = np.linalg.solve((G * W) @ G.T, -G @ v0.ravel())
    np.testing.assert_allclose(v, (v0.ravel() + W * (G.T @ mu)).reshape(v.shape), rtol=0,
                               atol=1e-13)
