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
stage by Newton's method on the multipliers with a direct tridiagonal solve (quadratic
convergence: 2-3 iterations per step from a Verlet predictor, fewer when started from the
previous step's multipliers) instead of the classical Gauss-Seidel SHAKE sweeps, whose
convergence slows down with the chain length; see ``benchmarks/dynamics_speed.py`` and
``tests/dynamics/test_dyn_constraints.py`` for the measurement.

Held coordinates (clamped nodes, nodes in ground contact) are expressed by a zero entry of
``W``; a constraint whose two ends are both held in the relevant directions is skipped
(it is satisfied by construction of the held positions).

Layout of the kernels (why they are written this way)
-----------------------------------------------------
A tridiagonal elimination is a serial chain of divisions (latency-bound: ~20 cycles per
row on the machine of the measurements, AMD Zen 3), while building the rows is independent
work per edge.  So each solve is split into (1) a pass that builds all rows, written
without reductions or branches so that it compiles to SIMD code, from node coordinates
first copied into one contiguous row per component (numba indexes an ``(n, 2)`` array
with a run-time row stride, and even a flat view costs a shuffle per value: 2x slower);
the largest residual is then taken by a SIMD pass of its own (:func:`_row_max`);
(2) the elimination, run from both ends towards the middle in one loop ("burn at both
ends"): two independent dependency chains, half as long, whose pivots come from the
division-free recurrence of the leading minors, so that the division of a row sits off
the chain (:func:`_eliminate`; the Thomas form with the division in the chain,
:func:`_eliminate_serial`, is the fallback when the minors leave their range); (3) the
back substitution, also from the middle outwards; (4) one SIMD pass applying ``W G^T y``
to the nodes.  In SHAKE the last Newton update reuses the factors of the previous one
when that one started within ``SHAKE_CHORD`` of the constraints (a chord step: no row
building, no division chain).  Measured on 198 edges (``benchmarks/dynamics_speed.py
--only 5``): the passes of one Newton iteration take 0.43 (rows), 0.05 (residual
maximum), 0.42 (elimination; 0.62 with the division in the chain and the maximum in the
loop, as before), 0.19 (substitution) and 0.21 us (node update); a velocity projection
1.5 us.  In a run the previous step's multipliers are a better start still (see
:mod:`dynamics.rattle`).

Work arrays: ``work`` has shape ``(WORK_ROWS, n_edges + 2)``; the entry of edge ``i`` sits
in column ``i + 1`` and columns ``0`` and ``n_edges + 1`` are zero pads, so that the first
and last rows need no special case.  The multipliers ``lam`` of :func:`shake` use the same
padded layout.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = [
    "shake",
    "shake_flat",
    "velocity_projection",
    "velocity_projection_flat",
    "solve_tridiagonal",
    "constraint_error",
    "new_work",
    "WORK_ROWS",
]

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

#: The last (unverified, see SHAKE_FINAL) Newton update of SHAKE reuses the factorisation
#: of the previous one (a chord step: residuals and substitutions only, ~half the cost)
#: when the previous residual was below this: the Jacobian has then changed by that
#: relative amount, so the chord step from a residual err <= 1e-8 leaves <= 1e-6 err, i.e.
#: round-off.  It is taken when the last update reduced the residual quadratically or by
#: this factor at least (measured on supp-fig5 from the previous step's multipliers: 3e-7
#: -> 1e-13, a Newton constant of ~1).
SHAKE_CHORD = 1e-6

#: Rows of the work array of :func:`shake` and :func:`velocity_projection`: edge vectors
#: (2), the tridiagonal rows a, b, c, rhs (4), per-edge residuals (1), the mask of rows
#: that are not skipped (1), node coordinates and inverse masses split by component (4).
WORK_ROWS = 12

# Arguments the kernels below pass to one another as ``np.int64`` / ``np.bool_`` values,
# never as bare constants: numba types a constant argument of a call from compiled code as
# a literal and compiles a separate specialisation of the callee for each literal value
# (``_split(.., 8)`` and ``_split(.., 10)`` would be two); a typed value costs nothing
# measurable and lets one specialisation serve every call site and the calls from Python.


def new_work(n_edges):
    """Zeroed work array for :func:`shake` and :func:`velocity_projection`, shape
    ``(WORK_ROWS, n_edges + 2)``."""
    return np.zeros((WORK_ROWS, int(n_edges) + 2))


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


# ----------------------------------------------------------------------------- passes
# The kernels below take flat views (``a.reshape(a.size)``) of C-contiguous (n, 2) arrays:
# element (j, k) is at 2 j + k.


@numba.njit(cache=True, error_model="numpy")
def _edges(xf, work):
    """Edge vectors of the flat positions ``xf`` into work rows 0 and 1 (padded)."""
    m = xf.shape[0] // 2 - 1
    work[0, 0] = 0.0
    work[1, 0] = 0.0
    work[0, m + 1] = 0.0
    work[1, m + 1] = 0.0
    for i in range(m):
        work[0, i + 1] = xf[2 * i + 2] - xf[2 * i]
        work[1, i + 1] = xf[2 * i + 3] - xf[2 * i + 1]


@numba.njit(cache=True, error_model="numpy")
def _split(qf, work, row):
    """Components of the flat node array ``qf`` into work rows ``row`` (x) and ``row + 1``
    (z), node j in column j: the row passes then read contiguous data (reading the
    interleaved array costs a shuffle per value: 2x slower).

    Called with ``row`` an ``np.int64`` (one specialisation for both rows, see the note
    after :data:`WORK_ROWS`)."""
    for j in range(qf.shape[0] // 2):
        work[row, j] = qf[2 * j]
        work[row + 1, j] = qf[2 * j + 1]


@numba.njit(cache=True, error_model="numpy")
def _shake_rows(edge_len, work):
    """Newton rows of SHAKE at the positions in work rows 8, 9 (inverse masses in rows 10,
    11).

    Row i: ``a_i dl_{i-1} + b_i dl_i + c_i dl_{i+1} = -phi_i`` with ``phi_i = |r_i|**2 -
    l_i**2`` (``r`` the current edges, ``d`` the old ones in work rows 0, 1) into work rows
    2-5, and ``|phi_i| / (2 l_i**2)`` into row 6.  A row whose two ends are held in the
    directions that matter becomes the identity with a zero right-hand side (row 7 = 0).
    """
    m = edge_len.shape[0]
    for i in range(m):
        s = i + 1
        rx = work[8, i + 1] - work[8, i]
        rz = work[9, i + 1] - work[9, i]
        li2 = edge_len[i] * edge_len[i]
        phi = rx * rx + rz * rz - li2
        work[6, s] = abs(phi) / (2.0 * li2)
        wx0 = work[10, i]
        wz0 = work[11, i]
        wx1 = work[10, i + 1]
        wz1 = work[11, i + 1]
        dx = work[0, s]
        dz = work[1, s]
        # d(phi_i)/d(lam_k): x_new_j += W_j (d_{j-1} lam_{j-1} - d_j lam_j)
        bb = 2.0 * (rx * (wx0 + wx1) * dx + rz * (wz0 + wz1) * dz)
        scale = 2.0 * (abs(rx * dx) + abs(rz * dz)) * (wx0 + wx1 + wz0 + wz1)
        ident = abs(bb) <= 1e-12 * scale or scale == 0.0
        # the pads make a_0 = c_{m-1} = 0
        aa = -2.0 * (rx * wx0 * work[0, s - 1] + rz * wz0 * work[1, s - 1])
        cc = -2.0 * (rx * wx1 * work[0, s + 1] + rz * wz1 * work[1, s + 1])
        # selects of computed values (a conditionally computed value keeps the loop
        # scalar: 2.2x slower)
        work[2, s] = 0.0 if ident else aa
        work[3, s] = 1.0 if ident else bb
        work[4, s] = 0.0 if ident else cc
        work[5, s] = 0.0 if ident else -phi
        work[7, s] = 0.0 if ident else 1.0


@numba.njit(cache=True, error_model="numpy")
def _shake_residuals(edge_len, work):
    """Right-hand sides ``-phi_i`` at the positions in work rows 8, 9 (zero for skipped
    rows, mask in row 7) into row 5 and ``|phi_i| / (2 l_i**2)`` into row 6, leaving the
    factorised rows untouched."""
    m = edge_len.shape[0]
    for i in range(m):
        s = i + 1
        rx = work[8, i + 1] - work[8, i]
        rz = work[9, i + 1] - work[9, i]
        li2 = edge_len[i] * edge_len[i]
        phi = rx * rx + rz * rz - li2
        work[6, s] = abs(phi) / (2.0 * li2)
        work[5, s] = -phi * work[7, s]


@numba.njit(cache=True, error_model="numpy")
def _velocity_rows(work):
    """Rows of the velocity projection ``G W G^T mu = -G v`` (edges in work rows 0, 1,
    velocities in rows 8, 9, inverse masses in rows 10, 11) into work rows 2-5, and the
    stretching rates ``|r_i.(v_{i+1}-v_i)| / |r_i|**2`` into row 6."""
    m = work.shape[1] - 2
    for i in range(m):
        s = i + 1
        rx = work[0, s]
        rz = work[1, s]
        cv = rx * (work[8, i + 1] - work[8, i]) + rz * (work[9, i + 1] - work[9, i])
        r2 = rx * rx + rz * rz
        work[6, s] = abs(cv) / r2
        wx0 = work[10, i]
        wz0 = work[11, i]
        wx1 = work[10, i + 1]
        wz1 = work[11, i + 1]
        bb = rx * rx * (wx0 + wx1) + rz * rz * (wz0 + wz1)
        scale = r2 * (wx0 + wx1 + wz0 + wz1)
        ident = bb <= 1e-12 * scale or scale == 0.0
        aa = -(rx * wx0 * work[0, s - 1] + rz * wz0 * work[1, s - 1])
        cc = -(rx * wx1 * work[0, s + 1] + rz * wz1 * work[1, s + 1])
        work[2, s] = 0.0 if ident else aa
        work[3, s] = 1.0 if ident else bb
        work[4, s] = 0.0 if ident else cc
        work[5, s] = 0.0 if ident else -cv


#: Rows between two renormalisations of the determinant recurrence of :func:`_eliminate`
#: (the leading minors grow or shrink by about the pivot size per row: 8 rows keep them
#: far from overflow for pivots within 1e+-30).
ELIM_RENORM = 8

#: Range of the leading minors outside which :func:`_eliminate` gives up (its caller then
#: rebuilds the rows and uses :func:`_eliminate_serial`).
ELIM_RANGE = 1e200


@numba.njit(cache=True, error_model="numpy")
def _eliminate(work):
    """Forward elimination of the tridiagonal system in work rows 2-5 (a, b, c, rhs).

    "Burn at both ends": rows 0..p downwards and m-1..p+1 upwards in the same loop, two
    independent dependency chains.  Top row i: ``y_i = pd_i - pc_i y_{i+1}`` with
    ``pc_i = c_i g_i``, ``pd_i = d_i g_i - a_i g_i pd_{i-1}`` and ``g_i = 1 / den_i``,
    ``den_i = b_i - a_i pc_{i-1}`` the Thomas pivot; bottom row j mirrored (``y_j = qd_j -
    qa_j y_{j-1}``).

    The pivots are ratios of leading minors, ``den_i = th_i / th_{i-1}`` with ``th_i = b_i
    th_{i-1} - a_i c_{i-1} th_{i-2}``: that recurrence has no division, so the chain of a
    row is a product and a difference (~6 cycles) instead of a product, a difference and a
    division (~20 cycles); the division ``g_i = th_{i-1} / th_i`` sits off the chain, as
    does the right-hand side chain (a product and a difference).  Every ``ELIM_RENORM``
    rows the pair ``(th_{i-1}, th_i)`` is divided by ``th_i``, i.e. replaced by ``(g_i,
    1)``, so the minors stay of order one; if one leaves ``[1/ELIM_RANGE, ELIM_RANGE]``
    anyway (checked before each renormalisation and at the end; NaN fails the check) the
    result is flagged (``ok`` False) and the caller falls back to
    :func:`_eliminate_serial`.

    Kept for :func:`_resolve` and :func:`_substitute`: g in row 3; for the top rows pc in
    row 4 and a g in row 2; for the bottom rows qa in row 2 and c g in row 4; pd, qd in
    row 5.  Returns ``ok``.  (The largest residual, row 6, is taken apart by
    :func:`_row_max`, in SIMD code: in this loop it cost 12%.)
    """
    m = work.shape[1] - 2
    p = (m - 1) // 2
    nb = m - 1 - p
    # top chain: minors th_{i-1}, th_{i-2}, raw c_{i-1}, pd_{i-1}
    t1 = 1.0
    t2 = 0.0
    cprev = 0.0
    pd = 0.0
    # bottom chain, mirrored
    u1 = 1.0
    u2 = 0.0
    aprev = 0.0
    qd = 0.0
    ok = True
    for k in range(nb):
        i = k + 1
        aa = work[2, i]
        cc = work[4, i]
        th = work[3, i] * t1 - (aa * cprev) * t2
        g = t1 / th
        ag = aa * g
        pd = work[5, i] * g - ag * pd
        work[2, i] = ag
        work[3, i] = g
        work[4, i] = cc * g
        work[5, i] = pd
        cprev = cc
        t2 = t1
        t1 = th
        j = m - k
        aa = work[2, j]
        cc = work[4, j]
        uh = work[3, j] * u1 - (cc * aprev) * u2
        g = u1 / uh
        cg = cc * g
        qd = work[5, j] * g - cg * qd
        work[2, j] = aa * g
        work[3, j] = g
        work[4, j] = cg
        work[5, j] = qd
        aprev = aa
        u2 = u1
        u1 = uh
        if k % ELIM_RENORM == ELIM_RENORM - 1:
            # the range is checked here, where the minors have grown most since the last
            # renormalisation; then the pair is divided by the newest minor:
            # (th_{i-1}, th_i) / th_i = (g_i, 1)
            a1 = abs(th)
            a2 = abs(uh)
            ok = (ok and a1 >= 1.0 / ELIM_RANGE and a1 <= ELIM_RANGE
                  and a2 >= 1.0 / ELIM_RANGE and a2 <= ELIM_RANGE)
            t2 = work[3, i]
            t1 = 1.0
            u2 = g
            u1 = 1.0
    if nb < p + 1:
        # odd m: the middle row belongs to the top half
        i = p + 1
        aa = work[2, i]
        cc = work[4, i]
        th = work[3, i] * t1 - (aa * cprev) * t2
        g = t1 / th
        ag = aa * g
        pd = work[5, i] * g - ag * pd
        work[2, i] = ag
        work[3, i] = g
        work[4, i] = cc * g
        work[5, i] = pd
        t1 = th
    a1 = abs(t1)
    a2 = abs(u1)
    ok = (ok and a1 >= 1.0 / ELIM_RANGE and a1 <= ELIM_RANGE
          and a2 >= 1.0 / ELIM_RANGE and a2 <= ELIM_RANGE)
    return ok


@numba.njit(cache=True, error_model="numpy")
def _eliminate_serial(work):
    """:func:`_eliminate` with the Thomas pivots computed directly (a division in the
    chain of every row): the fallback when the minors leave their range.  Same outputs."""
    m = work.shape[1] - 2
    p = (m - 1) // 2
    nb = m - 1 - p
    pc = 0.0
    pd = 0.0
    qa = 0.0
    qd = 0.0
    for k in range(nb):
        i = k + 1
        aa = work[2, i]
        den = work[3, i] - aa * pc
        pc = work[4, i] / den
        pd = (work[5, i] - aa * pd) / den
        work[2, i] = aa / den
        work[3, i] = 1.0 / den
        work[4, i] = pc
        work[5, i] = pd
        j = m - k
        cc = work[4, j]
        den = work[3, j] - cc * qa
        qa = work[2, j] / den
        qd = (work[5, j] - cc * qd) / den
        work[2, j] = qa
        work[3, j] = 1.0 / den
        work[4, j] = cc / den
        work[5, j] = qd
    if nb < p + 1:
        i = p + 1
        aa = work[2, i]
        den = work[3, i] - aa * pc
        pc = work[4, i] / den
        pd = (work[5, i] - aa * pd) / den
        work[2, i] = aa / den
        work[3, i] = 1.0 / den
        work[4, i] = pc
        work[5, i] = pd


@numba.njit(cache=True, error_model="numpy")
def _row_max(work, row):
    """Largest entry of a work row over the edges; the entries are ``>= 0`` or NaN, and
    NaN wins.

    Taken as the largest bit pattern read as unsigned integers (non-negative doubles order
    like their bits, and NaNs of either sign lie above ``inf``), so that the loop compiles
    to SIMD code (a floating-point maximum that must see NaN stays scalar).  The pad
    column 0 of the row serves as scratch to read the result back as a double.
    """
    bits = work[row].view(np.uint64)
    mx = np.uint64(0)
    for i in range(1, bits.shape[0] - 1):
        b = bits[i]
        mx = b if b > mx else mx
    bits[0] = mx
    err = work[row, 0]
    work[row, 0] = 0.0
    return err


@numba.njit(cache=True, error_model="numpy")
def _row_argmax(work, row):
    """Edge of the largest entry of a work row (the first, NaN first), for the reports."""
    err = 0.0
    edge = 0
    for i in range(work.shape[1] - 2):
        e = work[row, i + 1]
        if e != e:
            return i
        if e > err:
            err = e
            edge = i
    return edge


@numba.njit(cache=True, error_model="numpy")
def _resolve(work):
    """Forward elimination of a new right-hand side (row 5) with the factors kept by
    :func:`_eliminate`: reciprocal pivots g in row 3 and the scaled sub-diagonals a g
    (top) and c g (bottom) in rows 2 and 4, so that the chains hold one product and one
    difference per row."""
    m = work.shape[1] - 2
    p = (m - 1) // 2
    nb = m - 1 - p
    pd = 0.0
    qd = 0.0
    for k in range(nb):
        i = k + 1
        pd = work[5, i] * work[3, i] - work[2, i] * pd
        work[5, i] = pd
        j = m - k
        qd = work[5, j] * work[3, j] - work[4, j] * qd
        work[5, j] = qd
    if nb < p + 1:
        i = p + 1
        pd = work[5, i] * work[3, i] - work[2, i] * pd
        work[5, i] = pd


@numba.njit(cache=True, error_model="numpy")
def _substitute(work):
    """Back substitution after :func:`_eliminate` or :func:`_resolve`, from the middle
    outwards; the solution overwrites work row 5 (pads zeroed)."""
    m = work.shape[1] - 2
    p = (m - 1) // 2
    nb = m - 1 - p
    up = 0.0
    dn = 0.0
    if nb > 0:
        # rows p (top: y_p = pd_p - pc_p y_{p+1}) and p+1 (bottom: y_{p+1} = qd - qa y_p)
        a = p + 1
        b = p + 2
        up = (work[5, a] - work[4, a] * work[5, b]) / (1.0 - work[4, a] * work[2, b])
        dn = work[5, b] - work[2, b] * up
        work[5, a] = up
        work[5, b] = dn
    else:
        up = work[5, 1]
    # the carried values stay in registers (a store-to-load round trip would lengthen
    # the dependency chains)
    for k in range(1, nb):
        i = p + 1 - k
        up = work[5, i] - work[4, i] * up
        work[5, i] = up
        j = p + 2 + k
        dn = work[5, j] - work[2, j] * dn
        work[5, j] = dn
    if nb >= 1 and p == nb:
        work[5, 1] = work[5, 1] - work[4, 1] * up
    work[5, 0] = 0.0
    work[5, m + 1] = 0.0


@numba.njit(cache=True, error_model="numpy")
def _move(qf, wf, work, y):
    """``q_j += W_j (d_{j-1} y_{j-1} - d_j y_j)`` on flat ``qf``: ``d`` the edges in work
    rows 0, 1 and ``y`` padded like a work row (a work row, or the multipliers)."""
    for j in range(qf.shape[0] // 2):
        qf[2 * j] += wf[2 * j] * (work[0, j] * y[j] - work[0, j + 1] * y[j + 1])
        qf[2 * j + 1] += wf[2 * j + 1] * (work[1, j] * y[j] - work[1, j + 1] * y[j + 1])


@numba.njit(cache=True, error_model="numpy")
def _move_acc(qf, wf, work, lam):
    """:func:`_move` with the Newton update in work row 5, also added to the multipliers
    ``lam`` (in the same loop: one pass fewer)."""
    y = work[5]
    for j in range(qf.shape[0] // 2):
        qf[2 * j] += wf[2 * j] * (work[0, j] * y[j] - work[0, j + 1] * y[j + 1])
        qf[2 * j + 1] += wf[2 * j + 1] * (work[1, j] * y[j] - work[1, j + 1] * y[j + 1])
        # entries 1..m (the pad m + 1 adds 0 to 0)
        lam[j + 1] += y[j + 1]


# ----------------------------------------------------------------------------- projections


@numba.njit(cache=True, error_model="numpy")
def shake(x_old, x_new, winv, edge_len, work, lam, warm=False, final_tol=SHAKE_FINAL):
    """Project ``x_new`` onto the constraints along ``W G(x_old)^T`` (Newton, direct
    tridiagonal solves).

    Parameters
    ----------
    x_old : ndarray, shape (n, 2), C-contiguous
        Positions at the start of the step (satisfy the constraints).
    x_new : ndarray, shape (n, 2), C-contiguous
        Unconstrained prediction, projected in place.
    winv : ndarray, shape (n, 2), C-contiguous
        Inverse mass per coordinate (1/mass units); 0 for held coordinates.
    edge_len : ndarray, shape (n - 1,)
        Rest edge lengths.
    work : ndarray, shape (WORK_ROWS, n + 1)
        Work array (:func:`new_work`).
    lam : ndarray, shape (n + 1,)
        Multipliers, padded like ``work`` (entry ``i + 1`` for edge ``i``; the pads are
        zeroed here).  The Newton updates are added to it, so that, started from zeros,
        it returns the multipliers of the projection (``x_new - x_star = W G^T lam``;
        mass units).
    warm : bool, optional
        Start from ``x_new + W G(x_old)^T lam`` (a predictor: the previous step's
        multipliers) instead of ``x_new``.  The root is the same: only the iteration
        count changes (measured on fig3-strip: 2 updates per step instead of 3).
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
        When the iteration failed, the edge with the largest residual (else 0).
    err_old : float
        Relative length error of ``x_old`` (the previous step's result), free by-product.
    """
    return shake_flat(x_old.reshape(x_old.size), x_new.reshape(x_new.size),
                      winv.reshape(winv.size), edge_len, work, lam, warm, final_tol)


@numba.njit(cache=True, error_model="numpy")
def shake_flat(xo, xf, wf, edge_len, work, lam, warm=False, final_tol=SHAKE_FINAL):
    """:func:`shake` on flat views (``a.reshape(a.size)``) of the C-contiguous (n, 2)
    arrays ``x_old``, ``x_new`` and ``winv``: the stepper keeps such views, and a reshape
    per call costs a C call and reference counting (measured 5% of a step)."""
    m = edge_len.shape[0]
    _edges(xo, work)
    for i in range(m):
        li2 = edge_len[i] * edge_len[i]
        work[6, i + 1] = abs(work[0, i + 1] * work[0, i + 1] + work[1, i + 1] * work[1, i + 1]
                             - li2) / (2.0 * li2)
    err_old = _row_max(work, 6)
    lam[0] = 0.0
    lam[m + 1] = 0.0
    _split(wf, work, np.int64(10))
    if warm:
        _move(xf, wf, work, lam)
    err_prev = np.inf
    err_prev_prev = 0.0
    err = np.inf
    for it in range(SHAKE_MAX_ITER + 1):
        if err_prev <= SHAKE_CHORD:
            # the last update may be a chord step with the previous factors (see
            # SHAKE_CHORD): residuals first, the solve only if it is taken
            _split(xf, work, np.int64(8))
            _shake_residuals(edge_len, work)
            err = _row_max(work, 6)
            if err <= SHAKE_TOL:
                return err, it, 0, err_old
            # taken when the iteration is visibly converging fast: quadratically, or by a
            # factor SHAKE_CHORD in the last update (from err_prev <= 1e-6 Newton lands at
            # ~1e-13 with a constant just above 1, which the quadratic test alone rejects)
            if err <= final_tol and (err <= SHAKE_QUADRATIC * err_prev * err_prev
                                     or err <= SHAKE_CHORD * err_prev):
                _resolve(work)
                _substitute(work)
                _move_acc(xf, wf, work, lam)
                return err, it + 1, 0, err_old
            # otherwise a Newton step from the same point (the checks below see this err)
        _split(xf, work, np.int64(8))
        _shake_rows(edge_len, work)
        err = _row_max(work, 6)
        if err <= SHAKE_TOL:
            return err, it, 0, err_old
        if not err < np.inf:
            return err, -1, _row_argmax(work, 6), err_old
        if it == SHAKE_MAX_ITER or (err < SHAKE_FAIL and err >= 0.5 * err_prev):
            # stagnation at the round-off floor is accepted; anything else is a failure
            if err < SHAKE_FAIL:
                return err, it, 0, err_old
            return err, -1, _row_argmax(work, 6), err_old
        if not _eliminate(work):
            _shake_rows(edge_len, work)
            _eliminate_serial(work)
        err_prev = err
        _substitute(work)
        _move_acc(xf, wf, work, lam)
        if err <= final_tol and err <= SHAKE_QUADRATIC * err_prev_prev * err_prev_prev:
            return err, it + 1, 0, err_old
        err_prev_prev = err
    return err, -1, _row_argmax(work, 6), err_old


@numba.njit(cache=True, error_model="numpy")
def velocity_projection(x, v, winv, work):
    """Remove the constraint-violating velocity: ``v <- v + W G^T mu`` with ``G v = 0``.

    Parameters
    ----------
    x : ndarray, shape (n, 2), C-contiguous
        Positions (satisfying the constraints).
    v : ndarray, shape (n, 2), C-contiguous
        Velocities, projected in place.
    winv : ndarray, shape (n, 2), C-contiguous
        Inverse mass per coordinate; 0 for held coordinates.
    work : ndarray, shape (WORK_ROWS, n + 1)
        Work array (:func:`new_work`).

    Returns
    -------
    float
        Largest relative edge-stretching rate ``|r_i.(v_{i+1}-v_i)| / l_i**2`` *before*
        the projection (1/time units), a measure of how much was removed.
    """
    return velocity_projection_flat(x.reshape(x.size), v.reshape(v.size),
                                    winv.reshape(winv.size), work)


@numba.njit(cache=True, error_model="numpy")
def velocity_projection_flat(xf, vf, wf, work, after_shake=False):
    """:func:`velocity_projection` on flat views of ``x``, ``v`` and ``winv`` (see
    :func:`shake_flat`).

    ``after_shake=True`` (the stepper, right after :func:`shake_flat` with the same
    ``wf``): the inverse masses are still split in work rows 10, 11 (only the splits write
    those rows), so that pass is skipped, and so is the largest stretching rate, which
    is then returned as 0.0 (the stepper does not use it): 0.15 us of an 8 us step at
    198 edges.
    """
    _edges(xf, work)
    _split(vf, work, np.int64(8))
    if not after_shake:
        _split(wf, work, np.int64(10))
    _velocity_rows(work)
    worst = 0.0 if after_shake else _row_max(work, 6)
    if not _eliminate(work):
        _velocity_rows(work)
        _eliminate_serial(work)
    _substitute(work)
    _move(vf, wf, work, work[5])
    return worst
