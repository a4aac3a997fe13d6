"""The constraint projections: SHAKE (Newton + tridiagonal) and the velocity projection."""

import numpy as np
import pytest
from dyn_helpers import rod_from_angles

from dynamics.constraints import (
    constraint_error,
    shake,
    solve_tridiagonal,
    velocity_projection,
)


def _setup(n=60, seed=0):
    rng = np.random.default_rng(seed)
    rod = rod_from_angles(np.cumsum(0.2 * rng.standard_normal(n)), 0.1)
    winv = np.repeat((1.0 / rod.mass)[:, None], 2, axis=1).copy()
    return rod, winv, [np.zeros(n) for _ in range(4)], rng


def test_solve_tridiagonal_against_dense():
    rng = np.random.default_rng(3)
    m = 30
    a, c = rng.standard_normal(m), rng.standard_normal(m)
    b = 4.0 + rng.random(m)
    d = rng.standard_normal(m)
    A = np.diag(b) + np.diag(a[1:], -1) + np.diag(c[:-1], 1)
    y = solve_tridiagonal(a, b, c, d, np.empty(m), np.empty(m), np.empty(m))
    np.testing.assert_allclose(A @ y, d, atol=1e-13)


@pytest.mark.parametrize("step", [1e-4, 1e-3, 1e-2])
def test_shake_converges_quadratically_to_round_off(step):
    rod, winv, w, rng = _setup()
    xn = rod.x + step * rng.standard_normal(rod.x.shape)
    err, it, _, err_old = shake(rod.x, xn, winv, rod.edge_len, *w)
    assert it > 0 and err_old < 1e-14
    final, _ = constraint_error(xn, rod.edge_len)
    assert final < 1e-14, f"step {step}: residual {final:.2e} after {it} iterations"
    # quadratic convergence: random displacements of every node by 0.1%, 1%, 10% of an
    # edge need 3, 4, 6 updates (measured); a Verlet predictor needs 2
    assert it <= {1e-4: 3, 1e-3: 4, 1e-2: 6}[step]


def test_shake_moves_along_old_constraint_gradients_weighted_by_inverse_mass():
    """x_new - x_star = W G(x_old)^T lam: held coordinates do not move."""
    rod, winv, w, rng = _setup()
    winv[0] = 0.0  # node 0 held
    winv[10, 1] = 0.0  # vertical coordinate of node 10 held
    xs = rod.x + 1e-3 * rng.standard_normal(rod.x.shape)
    xn = xs.copy()
    shake(rod.x, xn, winv, rod.edge_len, *w)
    assert np.all(xn[0] == xs[0]) and xn[10, 1] == xs[10, 1]
    assert constraint_error(xn, rod.edge_len)[0] < 1e-14


def test_velocity_projection_removes_stretching_and_keeps_tangent_part():
    rod, winv, w, rng = _setup()
    v = rng.standard_normal(rod.x.shape)
    v0 = v.copy()
    velocity_projection(rod.x, v, winv, *w)
    e = np.diff(rod.x, axis=0)
    rate = np.abs(np.sum(e * np.diff(v, axis=0), axis=1)) / rod.edge_len**2
    assert rate.max() < 1e-12
    # a projection: idempotent, and the removed part is M-orthogonal to the kept part
    v2 = v.copy()
    velocity_projection(rod.x, v2, winv, *w)
    np.testing.assert_allclose(v2, v, atol=1e-13)
    assert abs(np.sum(rod.mass[:, None] * v * (v0 - v))) < 1e-10 * np.sum(v0**2)
