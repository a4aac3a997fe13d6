"""Inextensibility constraints of a chain: RATTLE position and velocity projections.

Each edge ``i`` carries the holonomic constraint ``|x_{i+1} - x_i|**2 = l_i**2``.  The
RATTLE integrator (Andersen 1983, J. Comput. Phys. 52, 24; Leimkuhler & Reich 2004,
"Simulating Hamiltonian Dynamics", sec. 7.2) needs two projections per step:

* position (SHAKE) stage: find multipliers ``lam`` such that
  ``x_new = x_star + W G(x_old)^T lam`` satisfies every constraint, where ``W`` is the
  per-coordinate inverse mass and ``G`` the constraint Jacobian at the *old* positions;
* velocity stage: ``v <- v + W G(x_new)^T mu`` with ``G(x_new) v = 0`` (linear).

For a chain each constraint couples two neighbouring nodes, so the Jacobian of the
constraint residuals with respect to the multipliers is tridiagonal.  We solve the SHAKE
stage by Newton's method on the multipliers with a Thomas tridiagonal solve (quadratic
convergence: 2-3 iterations per step from a Verlet predictor) instead of the classical
Gauss-Seidel SHAKE sweeps, whose convergence slows down with the chain length; see
``benchmarks/dynamics_speed.py`` and ``tests/dynamics/test_constraints.py`` for the
measurement.

Held coordinates (clamped nodes, nodes in ground contact) are expressed by a zero entry of
``W``; a constraint whose two ends are both held in the relevant directions is skipped
(it is satisfied by construction of the held positions).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["shake", "velocity_projection", "solve_tridiagonal", "constraint_error"]

#: Newton iteration cap for SHAKE.  From a Verlet predictor the initial residual is
#: O(dt**2) and Newton converges quadratically, so 3-4 iterations suffice; 50 leaves room
#: for violent contacts and is still cheap enough to detect a real failure quickly.
SHAKE_MAX_ITER = 50

#: Relative edge-length tolerance of SHAKE, ``max_i ||e_i| - l_i| / l_i``.  The round-off
#: floor is about ``eps * max|x| / min(l)`` (1e-14 for a rod of 200 edges), so 1e-12 is
#: reached in one extra quadratic Newton step and sits at round-off in practice (the last
#: iteration usually lands at 1e-16).
SHAKE_TOL = 1e-12

#: Residual above which an unconverged SHAKE is reported as a failure (below it, and not
#: improving, the iteration is at its round-off floor and accepted).
SHAKE_FAIL = 1e-8


@numba.njit(cache=True)
def solve_tridiagonal(a, b, c, d, out, cp, dp):
    """Thomas algorithm for ``a_i y_{i-1} + b_i y_i + c_i y_{i+1} = d_i``.

    Parameters
    ----------
    a, b, c, d : ndarray, shape (m,)
        Sub-diagonal (``a[0]`` unused), diagonal, super-diagonal (``c[m-1]`` unused) and
        right-hand side.
    out, cp, dp : ndarray, shape (m,)
        Solution (overwritten) and two work arrays.

    Notes
    -----
    No pivoting: the matrices built here are diagonally dominant (velocity stage: symmetric
    positive definite) for any time step small enough to be stable.
    """
    m = b.shape[0]
    cp[0] = c[0] / b[0]
    dp[0] = d[0] / b[0]
    for i in range(1, m):
        den = b[i] - a[i] * cp[i - 1]
        cp[i] = c[i] / den
        dp[i] = (d[i] - a[i] * dp[i - 1]) / den
    out[m - 1] = dp[m - 1]
    for i in range(m - 2, -1, -1):
        out[i] = dp[i] - cp[i] * out[i + 1]
    return out


@numba.njit(cache=True)
def constraint_error(x, edge_len):
    """Largest relative edge-length error ``max_i ||x_{i+1}-x_i| - l_i| / l_i``.

    Parameters
    ----------
    x : ndarray, shape (n_nodes, 2)
    edge_len : ndarray, shape (n_nodes - 1,)

    Returns
    -------
    err : float
    edge : int
        Index of the worst edge.
    """
    err = 0.0
    edge = 0
    for i in range(edge_len.shape[0]):
        dx = x[i + 1, 0] - x[i, 0]
        dz = x[i + 1, 1] - x[i, 1]
        e = abs(np.sqrt(dx * dx + dz * dz) - edge_len[i]) / edge_len[i]
        if not e <= err:  # also catches NaN
            err = e
            edge = i
    return err, edge


@numba.njit(cache=True)
def shake(x_old, x_new, winv, edge_len, a, b, c, rhs, delta, cp, dp):
    """Project ``x_new`` onto the constraints along ``W G(x_old)^T`` (Newton + Thomas).

    Parameters
    ----------
    x_old : ndarray, shape (n, 2)
        Positions at the start of the step (satisfy the constraints).
    x_new : ndarray, shape (n, 2)
        Unconstrained prediction, projected in place.
    winv : ndarray, shape (n, 2)
        Inverse mass per coordinate (1/mass units); 0 for held coordinates.
    edge_len : ndarray, shape (n - 1,)
        Rest edge lengths.
    a, b, c, rhs, delta, cp, dp : ndarray, shape (n - 1,)
        Work arrays.

    Returns
    -------
    err : float
        Final ``max_i |r_i.r_i - l_i**2| / (2 l_i**2)`` (relative length error).
    iters : int
        Newton iterations used; ``-1`` if the iteration failed (residual above
        ``SHAKE_FAIL`` after ``SHAKE_MAX_ITER`` iterations, or not finite).
    edge : int
        Edge with the largest residual.
    """
    m = edge_len.shape[0]
    err_prev = np.inf
    err = np.inf
    edge = 0
    for it in range(SHAKE_MAX_ITER + 1):
        err = 0.0
        for i in range(m):
            rx = x_new[i + 1, 0] - x_new[i, 0]
            rz = x_new[i + 1, 1] - x_new[i, 1]
            li2 = edge_len[i] * edge_len[i]
            phi = rx * rx + rz * rz - li2
            e = abs(phi) / (2.0 * li2)
            if not e <= err:
                err = e
                edge = i
            dx = x_old[i + 1, 0] - x_old[i, 0]
            dz = x_old[i + 1, 1] - x_old[i, 1]
            # d(phi_i)/d(lam_k): x_new_j += W_j (d_{j-1} lam_{j-1} - d_j lam_j)
            bb = 2.0 * (rx * (winv[i, 0] + winv[i + 1, 0]) * dx
                        + rz * (winv[i, 1] + winv[i + 1, 1]) * dz)
            scale = 2.0 * (abs(rx * dx) + abs(rz * dz)) * (
                winv[i, 0] + winv[i + 1, 0] + winv[i, 1] + winv[i + 1, 1])
            if abs(bb) <= 1e-12 * scale or scale == 0.0:
                # both ends held in the directions that matter: identity row, no update
                a[i] = 0.0
                b[i] = 1.0
                c[i] = 0.0
                rhs[i] = 0.0
                continue
            b[i] = bb
            rhs[i] = -phi
            if i > 0:
                px = x_old[i, 0] - x_old[i - 1, 0]
                pz = x_old[i, 1] - x_old[i - 1, 1]
                a[i] = -2.0 * (rx * winv[i, 0] * px + rz * winv[i, 1] * pz)
            else:
                a[i] = 0.0
            if i < m - 1:
                qx = x_old[i + 2, 0] - x_old[i + 1, 0]
                qz = x_old[i + 2, 1] - x_old[i + 1, 1]
                c[i] = -2.0 * (rx * winv[i + 1, 0] * qx + rz * winv[i + 1, 1] * qz)
            else:
                c[i] = 0.0
        if err <= SHAKE_TOL:
            return err, it, edge
        if not err < np.inf:
            return err, -1, edge
        if it == SHAKE_MAX_ITER or (err < SHAKE_FAIL and err >= 0.5 * err_prev):
            # stagnation at the round-off floor is accepted; anything else is a failure
            if err < SHAKE_FAIL:
                return err, it, edge
            return err, -1, edge
        err_prev = err
        solve_tridiagonal(a, b, c, rhs, delta, cp, dp)
        # apply x_new_j += W_j (d_{j-1} delta_{j-1} - d_j delta_j)
        for j in range(m + 1):
            fx = 0.0
            fz = 0.0
            if j > 0:
                fx += (x_old[j, 0] - x_old[j - 1, 0]) * delta[j - 1]
                fz += (x_old[j, 1] - x_old[j - 1, 1]) * delta[j - 1]
            if j < m:
                fx -= (x_old[j + 1, 0] - x_old[j, 0]) * delta[j]
                fz -= (x_old[j + 1, 1] - x_old[j, 1]) * delta[j]
            x_new[j, 0] += winv[j, 0] * fx
            x_new[j, 1] += winv[j, 1] * fz
    return err, -1, edge


@numba.njit(cache=True)
def velocity_projection(x, v, winv, a, b, c, rhs, mu, cp, dp):
    """Remove the constraint-violating velocity: ``v <- v + W G^T mu`` with ``G v = 0``.

    Parameters
    ----------
    x : ndarray, shape (n, 2)
        Positions (satisfying the constraints).
    v : ndarray, shape (n, 2)
        Velocities, projected in place.
    winv : ndarray, shape (n, 2)
        Inverse mass per coordinate; 0 for held coordinates.
    a, b, c, rhs, mu, cp, dp : ndarray, shape (n - 1,)
        Work arrays.

    Returns
    -------
    float
        Largest relative edge-stretching rate ``|r_i.(v_{i+1}-v_i)| / l_i**2`` *before*
        the projection (1/time units), a measure of how much was removed.
    """
    m = x.shape[0] - 1
    worst = 0.0
    for i in range(m):
        rx = x[i + 1, 0] - x[i, 0]
        rz = x[i + 1, 1] - x[i, 1]
        cv = rx * (v[i + 1, 0] - v[i, 0]) + rz * (v[i + 1, 1] - v[i, 1])
        r2 = rx * rx + rz * rz
        s = abs(cv) / r2
        if s > worst:
            worst = s
        bb = rx * rx * (winv[i, 0] + winv[i + 1, 0]) + rz * rz * (winv[i, 1] + winv[i + 1, 1])
        scale = r2 * (winv[i, 0] + winv[i + 1, 0] + winv[i, 1] + winv[i + 1, 1])
        if bb <= 1e-12 * scale or scale == 0.0:
            a[i] = 0.0
            b[i] = 1.0
            c[i] = 0.0
            rhs[i] = 0.0
            continue
        b[i] = bb
        rhs[i] = -cv
        if i > 0:
            px = x[i, 0] - x[i - 1, 0]
            pz = x[i, 1] - x[i - 1, 1]
            a[i] = -(rx * winv[i, 0] * px + rz * winv[i, 1] * pz)
        else:
            a[i] = 0.0
        if i < m - 1:
            qx = x[i + 2, 0] - x[i + 1, 0]
            qz = x[i + 2, 1] - x[i + 1, 1]
            c[i] = -(rx * winv[i + 1, 0] * qx + rz * winv[i + 1, 1] * qz)
        else:
            c[i] = 0.0
    solve_tridiagonal(a, b, c, rhs, mu, cp, dp)
    for j in range(m + 1):
        fx = 0.0
        fz = 0.0
        if j > 0:
            fx += (x[j, 0] - x[j - 1, 0]) * mu[j - 1]
            fz += (x[j, 1] - x[j - 1, 1]) * mu[j - 1]
        if j < m:
            fx -= (x[j + 1, 0] - x[j, 0]) * mu[j]
            fz -= (x[j + 1, 1] - x[j, 1]) * mu[j]
        v[j, 0] += winv[j, 0] * fx
        v[j, 1] += winv[j, 1] * fz
    return worst
