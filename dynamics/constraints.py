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
SHAKE_TOL = 1e-14

#: Residual below which one more Newton update is applied without re-checking (if the
#: iteration is visibly quadratic, see SHAKE_QUADRATIC): from 1e-8 a quadratic step lands
#: at the round-off floor (measured constant up to ~30 in ground contact: 3e-15); the
#: result is measured at the next step for free (the old edges are needed anyway).  This
#: saves one of the 3 residual passes per step.  1e-7 left 3e-13 in contact runs.
SHAKE_FINAL = 1e-8

#: The unverified last update is taken only if the iteration is visibly quadratic,
#: ``err_k <= SHAKE_QUADRATIC * err_{k-1}**2`` (free rods: 1e-4 -> 1e-8, constant ~1);
#: with held coordinates (ground contact) convergence can turn linear, and without this
#: test the unverified update left 8e-9 instead of round-off.
SHAKE_QUADRATIC = 1.0

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
    inv = 1.0 / b[0]
    cp[0] = c[0] * inv
    dp[0] = d[0] * inv
    for i in range(1, m):
        # one division per row: it sits on the serial dependency chain
        inv = 1.0 / (b[i] - a[i] * cp[i - 1])
        cp[i] = c[i] * inv
        dp[i] = (d[i] - a[i] * dp[i - 1]) * inv
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
def shake(x_old, x_new, winv, edge_len, cp, dp, dx, dz, final_tol=SHAKE_FINAL):
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
    cp, dp, dx, dz : ndarray, shape (n - 1,)
        Work arrays.
    final_tol : float, optional
        See ``err``; 0 disables the unverified last update (used for the re-projection
        after new contacts).

    Returns
    -------
    err : float
        Largest ``|r_i.r_i - l_i**2| / (2 l_i**2)`` (relative length error) at the last
        residual evaluation.  When it is below ``final_tol`` one last Newton update is
        applied without re-evaluating the residual (quadratic convergence takes it to
        round-off); the caller measures the accepted positions at the next call through
        ``err_old``.
    iters : int
        Newton updates applied; ``-1`` if the iteration failed (residual above
        ``SHAKE_FAIL`` after ``SHAKE_MAX_ITER`` updates, or not finite).
    edge : int
        Edge with the largest residual.
    err_old : float
        Relative length error of ``x_old`` (the previous step's result), free by-product.

    Notes
    -----
    Hand-fused: each Newton iteration builds the tridiagonal row of edge ``i`` and
    eliminates it in the same loop, then back-substitutes while updating the nodes.  The
    Thomas recurrence is a serial chain of divisions (latency-bound, 12 ns per row
    measured); fusing lets the out-of-order core hide the row construction behind it.
    Measured on 200 edges: 6.8 us instead of 12.9 us for 3 Newton iterations with
    separate build / solve / update passes (1.9x).
    """
    m = edge_len.shape[0]
    err_old = 0.0
    for i in range(m):
        dx[i] = x_old[i + 1, 0] - x_old[i, 0]
        dz[i] = x_old[i + 1, 1] - x_old[i, 1]
        li2 = edge_len[i] * edge_len[i]
        e = abs(dx[i] * dx[i] + dz[i] * dz[i] - li2) / (2.0 * li2)
        if not e <= err_old:
            err_old = e
    err_prev = np.inf
    err_prev_prev = 0.0
    err = np.inf
    edge = 0
    for it in range(SHAKE_MAX_ITER + 1):
        err = 0.0
        pc = 0.0
        pd = 0.0
        for i in range(m):
            rx = x_new[i + 1, 0] - x_new[i, 0]
            rz = x_new[i + 1, 1] - x_new[i, 1]
            li2 = edge_len[i] * edge_len[i]
            phi = rx * rx + rz * rz - li2
            e = abs(phi) / (2.0 * li2)
            if not e <= err:
                err = e
                edge = i
            wx0 = winv[i, 0]
            wz0 = winv[i, 1]
            wx1 = winv[i + 1, 0]
            wz1 = winv[i + 1, 1]
            # d(phi_i)/d(lam_k): x_new_j += W_j (d_{j-1} lam_{j-1} - d_j lam_j)
            bb = 2.0 * (rx * (wx0 + wx1) * dx[i] + rz * (wz0 + wz1) * dz[i])
            scale = 2.0 * (abs(rx * dx[i]) + abs(rz * dz[i])) * (wx0 + wx1 + wz0 + wz1)
            aa = 0.0
            cc = 0.0
            rh = -phi
            if abs(bb) <= 1e-12 * scale or scale == 0.0:
                # both ends held in the directions that matter: identity row, no update
                bb = 1.0
                rh = 0.0
            else:
                if i > 0:
                    aa = -2.0 * (rx * wx0 * dx[i - 1] + rz * wz0 * dz[i - 1])
                if i < m - 1:
                    cc = -2.0 * (rx * wx1 * dx[i + 1] + rz * wz1 * dz[i + 1])
            inv = 1.0 / (bb - aa * pc)
            pc = cc * inv
            pd = (rh - aa * pd) * inv
            cp[i] = pc
            dp[i] = pd
        if err <= SHAKE_TOL:
            return err, it, edge, err_old
        if not err < np.inf:
            return err, -1, edge, err_old
        if it == SHAKE_MAX_ITER or (err < SHAKE_FAIL and err >= 0.5 * err_prev):
            # stagnation at the round-off floor is accepted; anything else is a failure
            if err < SHAKE_FAIL:
                return err, it, edge, err_old
            return err, -1, edge, err_old
        err_prev = err
        # back substitution fused with x_new_j += W_j (d_{j-1} dl_{j-1} - d_j dl_j)
        dn = dp[m - 1]
        x_new[m, 0] += winv[m, 0] * dx[m - 1] * dn
        x_new[m, 1] += winv[m, 1] * dz[m - 1] * dn
        for i in range(m - 2, -1, -1):
            di = dp[i] - cp[i] * dn
            x_new[i + 1, 0] += winv[i + 1, 0] * (dx[i] * di - dx[i + 1] * dn)
            x_new[i + 1, 1] += winv[i + 1, 1] * (dz[i] * di - dz[i + 1] * dn)
            dn = di
        x_new[0, 0] -= winv[0, 0] * dx[0] * dn
        x_new[0, 1] -= winv[0, 1] * dz[0] * dn
        if err <= final_tol and err <= SHAKE_QUADRATIC * err_prev_prev * err_prev_prev:
            return err, it + 1, edge, err_old
        err_prev_prev = err
    return err, -1, edge, err_old


@numba.njit(cache=True)
def velocity_projection(x, v, winv, cp, dp, dx, dz):
    """Remove the constraint-violating velocity: ``v <- v + W G^T mu`` with ``G v = 0``.

    Parameters
    ----------
    x : ndarray, shape (n, 2)
        Positions (satisfying the constraints).
    v : ndarray, shape (n, 2)
        Velocities, projected in place.
    winv : ndarray, shape (n, 2)
        Inverse mass per coordinate; 0 for held coordinates.
    cp, dp, dx, dz : ndarray, shape (n - 1,)
        Work arrays.

    Returns
    -------
    float
        Largest relative edge-stretching rate ``|r_i.(v_{i+1}-v_i)| / l_i**2`` *before*
        the projection (1/time units), a measure of how much was removed.

    Notes
    -----
    Row construction fused with the Thomas elimination, and back substitution with the
    velocity update, as in :func:`shake` (200 edges: 2.7 us instead of 4.5 us).
    """
    m = x.shape[0] - 1
    worst = 0.0
    for i in range(m):
        dx[i] = x[i + 1, 0] - x[i, 0]
        dz[i] = x[i + 1, 1] - x[i, 1]
    pc = 0.0
    pd = 0.0
    for i in range(m):
        rx = dx[i]
        rz = dz[i]
        cv = rx * (v[i + 1, 0] - v[i, 0]) + rz * (v[i + 1, 1] - v[i, 1])
        r2 = rx * rx + rz * rz
        sv = abs(cv) / r2
        if sv > worst:
            worst = sv
        wx0 = winv[i, 0]
        wz0 = winv[i, 1]
        wx1 = winv[i + 1, 0]
        wz1 = winv[i + 1, 1]
        bb = rx * rx * (wx0 + wx1) + rz * rz * (wz0 + wz1)
        scale = r2 * (wx0 + wx1 + wz0 + wz1)
        aa = 0.0
        cc = 0.0
        rh = -cv
        if bb <= 1e-12 * scale or scale == 0.0:
            bb = 1.0
            rh = 0.0
        else:
            if i > 0:
                aa = -(rx * wx0 * dx[i - 1] + rz * wz0 * dz[i - 1])
            if i < m - 1:
                cc = -(rx * wx1 * dx[i + 1] + rz * wz1 * dz[i + 1])
        inv = 1.0 / (bb - aa * pc)
        pc = cc * inv
        pd = (rh - aa * pd) * inv
        cp[i] = pc
        dp[i] = pd
    dn = dp[m - 1]
    v[m, 0] += winv[m, 0] * dx[m - 1] * dn
    v[m, 1] += winv[m, 1] * dz[m - 1] * dn
    for i in range(m - 2, -1, -1):
        di = dp[i] - cp[i] * dn
        v[i + 1, 0] += winv[i + 1, 0] * (dx[i] * di - dx[i + 1] * dn)
        v[i + 1, 1] += winv[i + 1, 1] * (dz[i] * di - dz[i + 1] * dn)
        dn = di
    v[0, 0] -= winv[0, 0] * dx[0] * dn
    v[0, 1] -= winv[0, 1] * dz[0] * dn
    return worst
