"""The midpoint method of :func:`dynamics.simulate` (``method="midpoint"``): the
constrained implicit midpoint rule, a time step set by accuracy, not by bending.

Why
---
The explicit RATTLE method (:mod:`dynamics.rattle`) is stable only for
``dt <= 0.45 h**2 sqrt(mu/B)``: the shortest bending wave sets the step and the cost of a
run grows as ``N**3``.  Here the bending force is implicit, so the step is limited only by
the accuracy wanted on the motion that matters (the slow modes, the capillary dynamics).

Scheme (one step of size ``dt``)
--------------------------------
Damping effects are split around the step exactly as in RATTLE (Strang, their exact decay
over ``dt/2`` before and after).  The conservative step is the implicit midpoint rule with
the edge-length constraints imposed at the new positions by Lagrange multipliers (index 3),
the constraint forces acting along the constraint gradients at the midpoint::

    D      = x1 - x0,   xm = x0 + D/2,   vm = D/dt,   v1 = 2 vm - v0
    M (v1 - v0) = dt F(xm, vm, t + dt/2) + dt G(xm)^T lam
    phi_j(x1) = (|e_j(x1)|**2 - l_j**2) / (2 l_j) = 0          (every edge j)

Because every ``phi_j`` is quadratic, ``phi(x1) - phi(x0) = G(xm) D`` exactly, so the
constraint forces do no work: the kinetic energy changes by exactly ``D . F(xm)``, the
midpoint quadrature of the work of the applied forces.  Hence the total energy error is
that quadrature error, O(dt**2) and bounded for oscillations (no drift measured), at any
``dt``.  For linear dynamics the scheme is the trapezoidal rule (Newmark beta = 1/4,
gamma = 1/2): A-stable, no numerical damping, second order, frequency error
``-(omega dt)**2 / 12``.  Unresolved stiff modes keep their (small) energy and are damped
only by the physical damping.  Edge lengths are exact to the Newton tolerance (round-off).
All forces, including the nonlocal capillary one, are evaluated at the midpoint inside the
Newton loop (fully implicit, symmetric): there is no explicit/implicit splitting error.

The velocities ``v1 = 2 vm - v0`` are not projected on the tangent space at ``x1``
(RATTLE's velocity stage): they carry a normal component that flips sign from step to
step, harmless to the positions (the scheme is equivalent to a two-step recursion in
``x``), but projecting it away dissipated 8% of the energy of a released rod over t = 60
at 4x the explicit bound (measured), so it is kept.

Solver
------
Newton on ``(D, mu = dt**2/2 lam)``.  The matrix holds the mass, the exact bending Hessian
(analytic, :func:`bending_hessian_add`; a 5-colour finite-difference version,
:func:`hessian_columns_add`, checks it in the tests), the constraint gradients and their
curvature, and the stiffness of the force effects that supply the optional ``stiffness``
hook (:mod:`dynamics.effects`): its band part is added to the band matrix, its low-rank
part (the drop couples its two contact lines, far apart along the rod) enters by Woodbury's
formula between the two sweeps of the band solve (:func:`lowrank_setup`,
:func:`lowrank_correct`), when it matters (:data:`LOWRANK_MIN_RATE`).  Effects without the
hook (gravity: zero stiffness) are left out and cost nothing; a force's missing stiffness
slows the simplified Newton to a linear rate ``~ dt**2 |K_ext| / (4 m)``.  Measured on
supp-fig5 impacts (100 edges): 4-5 iterations a step at 16x the explicit bound either way;
an encapsulating run (Delta = 4) needs 6.1 at 64x and 6.4 at 128x with the drop's
stiffness, 11.6 and 22 (with 426 rejected steps) without.  On fig3-strip (gamma = 40, a
ground) the drop's stiffness saves 1 iteration of 7.3 at 4x the bound and 8 of 16 at 16x;
what remains there is set by the active-set changes of the ground contact (0.4 a step,
each restarting the iteration on a changed system) and by the unresolved fast bending
waves, which make the predictor of a step miss by ~4 % of an edge (measured), so that
even a fresh exact Newton matrix needs 4-5 iterations to reach the tolerance.  The
factorisation is reused for ``JACOBIAN_AGE`` steps and refreshed when the iteration slows
(``REFRESH_RATE``, ``REFRESH_MOVE``).  Unknowns are ordered node by node with each edge's
multiplier after its second node, so the KKT matrix is banded
(7 sub- and super-diagonals); it is factored without pivoting (every leading block is a
KKT matrix of a sub-chain), with banded partial pivoting as the fallback: ``O(N)`` a step.

Ground contact (:class:`~dynamics.Ground`, frictionless, perfectly inelastic)
--------------------------------------------------------------------------------
An active set of held nodes: the vertical momentum row of a held node is replaced by its
height constraint ``z_i(x1) = z0`` (an identity row in the same banded KKT matrix), and
that row's residual is its contact impulse (:func:`ground_rows_residual`).  The set is
updated on Newton iterates near convergence and again after convergence
(:func:`ground_update`): a free node ending below the ground is held, a held node the
ground pulls is released (lift-off, no adhesion); a node released and caught again in the
same step stays held (no cycling).  A change of the held set switches rows of the Newton
matrix; the factored matrix takes them as a low-rank update (one Woodbury column per node
that differs from the factorisation's set, :func:`contact_lowrank`) instead of being
refactored: a third fewer factorisations on fig3-strip and on a dropped rod (measured).
A held node ends the step at ``z0`` with zero vertical velocity: the landing is perfectly
inelastic (the midpoint rule alone would give ``v1 = -v0``, a bounce), a resting rod has
no jitter, and the contact forces do no positive work (``D_z <= 0`` where they push).
A ground is recognised by the effect protocol (``ground_height_param``, see
:mod:`dynamics.effects`); other constraint effects (:class:`~dynamics.Clamp`) are refused.

References: Hairer, Lubich & Wanner, "Geometric Numerical Integration" (2006), sec. VII.1
(constrained mechanical systems), sec. V.4 and VI.3 (midpoint rule); Newmark (1959);
Gonzalez, "Exact energy and momentum conserving algorithms" (1999/2000) for the
quadratic-constraint argument.
"""

from __future__ import annotations

import sys
from types import SimpleNamespace

import numba
import numpy as np

from .cache import dependency_digest, is_compiled, load_module
from .codegen import compile_estimate, kernel_ref, render, stepper_depends
from .contact import (
    NO_CONTACT_WORK,
    check_self_contact,
    contact_failure,
    contact_stats,
    new_contact_work,
)
from .effects import KINDS, STIFFNESS_BAND, STIFFNESS_RANK, is_ground, is_self_contact
from .rattle import stable_dt

__all__ = [
    "Run",
    "compile_stepper",
    "band_lu",
    "band_solve",
    "band_lu_nopivot",
    "band_forward",
    "band_backward",
    "kkt_assemble",
    "kkt_residual",
    "kkt_update",
    "midpoint_ok",
    "hessian_columns_add",
    "bending_hessian_add",
    "ground_rows_residual",
    "ground_rows_matrix",
    "ground_update",
    "stiffness_band_add",
    "lowrank_rate",
    "contact_rows_save",
    "contact_lowrank",
    "lowrank_setup",
    "lowrank_correct",
    "KL",
]

#: Sub-/super-diagonals of the KKT matrix in the node-interleaved ordering
#: (x_0, z_0, x_1, z_1, mu_0, x_2, z_2, mu_1, ...): bending couples node k to node k+2,
#: 3 unknowns apart per node, so coordinate (k, 0) reaches (k+2, 1) at offset 7.
KL = 7

#: Newton iteration cap per step.  Measured means of 4-8 iterations at dt up to 64x the
#: explicit bound (supp-fig5) and 16x (fig3-strip), 12 for an encapsulating supp-fig5 impact
#: at 64x without the drop's stiffness in the matrix; 25 leaves room for a slower linear
#: rate before the step is rejected and retried with substeps (a cap of 8 made that 64x run
#: slower, with 1000 rejected steps, and the 128x run fail).
NEWTON_MAX_ITER = 25

#: Convergence: a Newton correction of the positions below NEWTON_TOL_X * h_min, or a
#: momentum residual (a displacement, scaled by 1/m) below NEWTON_TOL_X * h_min together
#: with a relative edge-length error below NEWTON_TOL_C.  1e-13 h is far below the
#: per-step truncation error at any dt used and leaves the edge lengths at round-off
#: (measured 2e-14 - 6e-14, the level of RATTLE; 1e-12 h left 1e-13 - 1.5e-12 and saved
#: 8% of the time).
NEWTON_TOL_X = 1e-13
NEWTON_TOL_C = 1e-13

#: Default number of steps a factorisation of the Newton matrix is reused (it is also
#: refreshed whenever the iteration slows, see REFRESH_RATE).  Measured on supp-fig5
#: impacts (100 edges, dt = 16-64x the explicit bound): 4 is 1.3x faster than refactoring
#: every step, and 16 or never (only on slowdown) are no faster (more iterations).
JACOBIAN_AGE = 4

#: A Newton correction below NEWTON_TOL_X * h_min is accepted without re-evaluating the
#: residual only if the edge-length error it corrects is already below FINAL_C (the
#: iteration is in its fast-converging phase; cf. SHAKE_FINAL in dynamics.constraints).
FINAL_C = 1e-8

#: A step whose Newton iteration fails is retried as 2, 4, ..., 2**MAX_HALVINGS substeps.
MAX_HALVINGS = 4

#: The Newton matrix is refactored whenever a Newton correction is more than this
#: fraction of the previous one (simplified Newton turning slow); 0.1 keeps the count of
#: iterations at 2-4 (measured) while reusing a factorisation across steps when it still
#: contracts.
REFRESH_RATE = 0.1

#: Shortest midpoint edge accepted, relative to its length: the midpoint of an edge that
#: turns by psi in one step has length l cos(psi / 2), so 0.2 allows turns up to 157
#: degrees per step; shorter means a diverging iterate, and the bending kernel would divide
#: by a vanishing length.  The step is then rejected and retried with substeps.
MIN_MID_EDGE = 0.2

#: Smallest ``1 + cos(psi)`` of a midpoint joint accepted (psi its turning angle): 1e-3
#: rejects turns beyond 177 degrees, which only diverging iterates reach (measured: a
#: fig3-strip run at dt = 0.02 otherwise stopped on a division by zero).
MIN_JOINT_DEN = 1e-3

#: A second refresh within one step needs the iterate to have moved by more than this
#: fraction of an edge since the last one (sum of the corrections' max norms).  Measured:
#: a released wavy rod (bending only, exact Jacobian, 16x the bound) needs repeated
#: refreshes (full Newton) through its nonlinear first iterations, while an encapsulating
#: supp-fig5 impact at 64x without the capillary stiffness in the matrix refreshed 6 times
#: a step to no avail: 0.19 s instead of 0.42 s with one refresh a step.
REFRESH_MOVE = 0.01

#: Finite-difference step of the coloured FD bending Hessian (:func:`hessian_columns_add`,
#: the check of the analytic one), relative to the edge length: central differences,
#: truncation ~ eps_fd**2 (1e-10) and round-off ~ 1e-16 / eps_fd (1e-11) relative.
FD_REL_STEP = 1e-5

#: Rounds of the contact complementarity loop per step (hold the nodes that end below the
#: ground, release those the ground pulls, solve again); a step still inconsistent after
#: them is rejected and retried with substeps.  With the active set also updated inside
#: Newton (near convergence), fig3-strip impacts (198 edges, dt = 0.005-0.01) need 0.5-0.7
#: active-set changes a step on average (measured).
MAX_CONTACT_ROUNDS = 8

#: A held node is released when the ground pulls it by more than this (relative to the
#: shortest edge, as the scaled impulse ``dt**2/2 f / m``, length units): 1e3 times the
#: Newton tolerance, so that the round-off of a converged multiplier (~NEWTON_TOL_X h)
#: never releases a resting node, and far below the weight of a node over a step
#: (``dt**2 g / 2 ~ 1e-4`` at dt = 0.02).
CONTACT_PULL_TOL = 1e-10

#: The capacitance matrix ``I + Vt A^{-1} L`` of the Woodbury solve (the low-rank part of
#: the force stiffness, :func:`lowrank_setup`) is treated as singular when a pivot falls
#: below this fraction of its largest entry (or of 1, the scale of ``I``): a condition
#: number above 1e12 leaves the Newton correction ~1e-4 accurate at best, and the band
#: matrix alone (simplified Newton, linear convergence) is the safer choice.  Never
#: happened in the benchmarks (``stiffness_dropped`` = 0).
SMALL_PIVOT = 1e-12

#: The low-rank part of the force stiffness enters the Newton matrix only when the
#: simplified Newton iteration would contract at a rate above this without it
#: (:func:`lowrank_rate`): below, it saves less than it costs (an O(k N) correction in
#: every solve, k band sweeps per factorisation).  Measured: supp-fig5 at the automatic dt
#: (rate 0.004 at Delta = 2.5, 0.05 at 4) ran 10-25 % slower with it for the same or 0.8
#: fewer iterations a step; fig3-strip (0.11) broke even; 0.85 and above (supp-fig5 at 64x
#: the bound) halved the iterations.
LOWRANK_MIN_RATE = 0.1

#: Most nodes whose held status may differ from that of the factored Newton matrix: their
#: rows are switched by a low-rank update (:func:`contact_lowrank`, one column each); more,
#: and the matrix is refactored.  Columns the drop's stiffness leaves unused are added.
#: Measured on fig3-strip (damped, 4x and 16x the explicit bound): 4, 8, 16 and 32 ran
#: within timing noise of each other (0.66-0.55 factorisations a step at 4x: more columns
#: save factorisations, and cost O(N) each in every solve).
CONTACT_RANK = 8

#: Deepest penetration of a self-contact's linearised gap, relative to the thickness, that
#: a step's contact projection accepts; a step whose implicit solve ends deeper is rejected
#: and retried with substeps (:data:`MAX_HALVINGS`).  A node that enters the rod by more
#: than half the thickness within one step has moved, relative to the segment, beyond
#: what the contact linearised at the start of the step describes: on fig3-strip (200
#: edges, 8x the explicit bound) the free end slid 3 thicknesses (0.65 of an edge) a step
#: over the other layer, its gaps 0.5-1.2 thicknesses deep, the energy rose at those steps
#: and the projection finally diverged.  The tests' long-step contacts stay below 0.31
#: (the folded rod at 4x: unchanged); a resting contact under a load enters by about
#: ``a dt**2 / 2`` a step, far less (0.25 made fig3-strip's folded strip reject steps while
#: it rested and never reach rest; 0.5 did not).
CONTACT_MAX_DEPTH = 0.5

#: Largest shortfall of a true node-segment distance below the thickness, relative to it,
#: at the end of a step with a contact projection (:func:`dynamics.contact.contact_shortfall`);
#: more, and the step is rejected and retried with substeps.  The shortfall is second
#: order in the contact's turn within the step; the next step restores it, and the
#: midpoint relation ``v1 = 2 D / dt - v0`` turns that correction into a kick.  Measured:
#: the tests' midpoint collisions at 4x stay below 7.2e-3 (unchanged); a hairpin thrown
#: at 8x fell 0.20 short and gained 1.3e-2 of its energy, with this check 9.1e-3 short
#: and 2.1e-4.
CONTACT_MAX_SHORTFALL = 1e-2

#: (module, kernel) of the one constraint effect the implicit stepper handles.



# ----------------------------------------------------------------------------- banded LU


@numba.njit(cache=True)
def band_lu(ab, piv, kl, ku):
    """In-place banded LU with partial pivoting (LAPACK ``dgbtrf`` layout, unblocked).

    Parameters
    ----------
    ab : ndarray, shape (N, 2 kl + ku + 1)
        Row ``r`` holds columns ``r - kl .. r + kl + ku`` of the matrix at
        ``ab[r, c - r + kl]``; the last ``kl`` slots of each row are fill-in space (zero on
        entry).  Overwritten by the multipliers (``c < r``) and ``U``.
    piv : ndarray of int64, shape (N,)
        Row interchanged with row ``k`` at step ``k``.
    kl, ku : int
        Sub- and super-diagonals.

    Returns
    -------
    int
        0, or ``k + 1`` if the pivot of column ``k`` is exactly zero (singular).
    """
    N = ab.shape[0]
    w = kl + ku
    for k in range(N):
        rmax = min(k + kl, N - 1)
        p = k
        best = abs(ab[k, kl])
        for r in range(k + 1, rmax + 1):
            a = abs(ab[r, k - r + kl])
            if a > best:
                best = a
                p = r
        piv[k] = p
        if best == 0.0:
            return k + 1
        cmax = min(k + w, N - 1)
        if p != k:
            for c in range(k, cmax + 1):
                tmp = ab[k, c - k + kl]
                ab[k, c - k + kl] = ab[p, c - p + kl]
                ab[p, c - p + kl] = tmp
        inv = 1.0 / ab[k, kl]
        for r in range(k + 1, rmax + 1):
            f = ab[r, k - r + kl] * inv
            ab[r, k - r + kl] = f
            if f != 0.0:
                for c in range(k + 1, cmax + 1):
                    ab[r, c - r + kl] -= f * ab[k, c - k + kl]
    return 0


@numba.njit(cache=True)
def band_lu_nopivot(ab, kl, ku, tiny):
    """Banded LU without pivoting, same layout as :func:`band_lu` (fill-in slots unused).

    Returns 0, or ``k + 1`` if the pivot of column ``k`` is below ``tiny`` times the
    largest entry of its row (the caller then refactors with :func:`band_lu`).

    Notes
    -----
    The KKT matrices here have their multipliers ordered after the nodes they join, so
    every leading block is itself a nonsingular KKT matrix and elimination in order is
    well defined; measured: partial pivoting never swapped a row on them, nor was this
    fallback ever taken, also with the band part of the drop's stiffness (indefinite,
    ``-gamma kappa`` times the shoelace Hessian: fig3-strip at 4-16x and supp-fig5 at
    16-128x the explicit bound; the stiff parts, ``1/d`` and the closing chord, are in the
    low-rank part, outside the factored band).  Without the pivot search, the swaps and
    the ``kl`` extra fill-in columns the elimination costs N kl ku instead of
    N kl (kl + ku) (100 edges: 18 us instead of 60 us).
    """
    N = ab.shape[0]
    for k in range(N):
        rmax = min(k + kl, N - 1)
        cmax = min(k + ku, N - 1)
        piv = ab[k, kl]
        big = 0.0
        for c in range(max(0, k - kl), cmax + 1):
            a = abs(ab[k, c - k + kl])
            if a > big:
                big = a
        if not abs(piv) > tiny * big:
            return k + 1
        inv = 1.0 / piv
        if kl == KL and ku == KL and rmax == k + KL:
            # the full band (the KKT matrix's, all but its last KL rows): constant trip
            # counts, the same operations in the same order (bit for bit), 2.3x faster at
            # 367 edges (measured: 31 us instead of 71 us)
            for t in range(1, KL + 1):
                f = ab[k + t, KL - t] * inv
                ab[k + t, KL - t] = f
                if f != 0.0:
                    for u in range(1, KL + 1):
                        ab[k + t, KL - t + u] -= f * ab[k, KL + u]
            continue
        for r in range(k + 1, rmax + 1):
            f = ab[r, k - r + kl] * inv
            ab[r, k - r + kl] = f
            if f != 0.0:
                off_r = kl - r
                off_k = kl - k
                for c in range(k + 1, cmax + 1):
                    ab[r, c + off_r] -= f * ab[k, c + off_k]
    return 0


@numba.njit(cache=True)
def band_forward(ab, piv, kl, b):
    """First half of :func:`band_solve`: ``b <- L^{-1} P b`` in place (row interchanges
    and unit lower factor, both interleaved as in LAPACK ``dgbtrs``)."""
    N = ab.shape[0]
    pivoted = piv[0] >= 0
    k0 = 0
    if not pivoted and kl == KL:
        # no interchanges: the rows below the first N - KL all exist, a constant trip
        # count, the same operations in the same order (bit for bit), 2.3x faster at 367
        # edges (measured: 4.9 us instead of 11.2 us)
        k0 = max(N - KL, 0)
        for k in range(k0):
            bk = b[k]
            if bk != 0.0:
                for t in range(1, KL + 1):
                    b[k + t] -= ab[k + t, KL - t] * bk
    for k in range(k0, N):
        if pivoted:
            p = piv[k]
            if p != k:
                tmp = b[k]
                b[k] = b[p]
                b[p] = tmp
        bk = b[k]
        if bk != 0.0:
            for r in range(k + 1, min(k + kl, N - 1) + 1):
                b[r] -= ab[r, k - r + kl] * bk
    return b


@numba.njit(cache=True)
def band_backward(ab, piv, kl, ku, b):
    """Second half of :func:`band_solve`: ``b <- U^{-1} b`` in place (``U`` has
    ``kl + ku`` super-diagonals after pivoting, ``ku`` without)."""
    N = ab.shape[0]
    w = kl + ku if piv[0] >= 0 else ku
    for k in range(N - 1, -1, -1):
        s = b[k]
        for c in range(k + 1, min(k + w, N - 1) + 1):
            s -= ab[k, c - k + kl] * b[c]
        b[k] = s / ab[k, kl]
    return b


@numba.njit(cache=True)
def band_solve(ab, piv, kl, ku, b):
    """Solve ``A y = b`` in place with the factors of :func:`band_lu` (``piv[0] < 0``:
    of :func:`band_lu_nopivot`)."""
    band_forward(ab, piv, kl, b)
    return band_backward(ab, piv, kl, ku, b)


@numba.njit(cache=True)
def band_forward_multi(ab, piv, kl, Y, j0, m, start):
    """:func:`band_forward` on the columns ``Y[:, j0:j0 + m]`` (``Y`` shape (N, >= j0 + m)),
    all zero in rows ``< start`` (the sweep starts there: what a zero head leaves
    unchanged)."""
    N = ab.shape[0]
    pivoted = piv[0] >= 0
    k0 = start
    if not pivoted and kl == KL:
        # constant trip counts where the band is full, as in band_forward (bit for bit;
        # measured 11.7 us instead of 13.1 us for 5 columns over the last third, 367 edges)
        k0 = max(N - KL, start)
        for k in range(start, k0):
            for t in range(1, KL + 1):
                f = ab[k + t, KL - t]
                if f != 0.0:
                    for j in range(j0, j0 + m):
                        Y[k + t, j] -= f * Y[k, j]
    for k in range(k0, N):
        if pivoted:
            p = piv[k]
            if p != k:
                for j in range(j0, j0 + m):
                    tmp = Y[k, j]
                    Y[k, j] = Y[p, j]
                    Y[p, j] = tmp
        for r in range(k + 1, min(k + kl, N - 1) + 1):
            f = ab[r, k - r + kl]
            if f != 0.0:
                for j in range(j0, j0 + m):
                    Y[r, j] -= f * Y[k, j]
    return Y


@numba.njit(cache=True)
def band_backward_transpose_multi(ab, piv, kl, ku, Y, j0, m, start):
    """Solve ``U^T H = Y[:, j0:j0 + m]`` in place (``H = (Y^T U^{-1})^T``, the rows of
    ``Y^T U^{-1}`` as columns), ``Y`` zero in rows ``< start``, where ``H`` is zero too
    (``U^T`` is lower triangular)."""
    N = ab.shape[0]
    w = kl + ku if piv[0] >= 0 else ku
    for k in range(start, N):
        for c in range(max(start, k - w), k):
            f = ab[c, k - c + kl]
            if f != 0.0:
                for j in range(j0, j0 + m):
                    Y[k, j] -= f * Y[c, j]
        inv = 1.0 / ab[k, kl]
        for j in range(j0, j0 + m):
            Y[k, j] *= inv
    return Y


# ----------------------------------------------------------------------------- KKT system


@numba.njit(cache=True)
def _node_index(k):
    """Position of coordinate 0 of node ``k`` in the interleaved ordering."""
    return 3 * k - 1 if k > 0 else 0


@numba.njit(cache=True)
def _node_rows_max(rhs, n):
    """Largest |entry| of the node (momentum) rows of the KKT vector ``rhs`` (NaN-safe)."""
    rmax = 0.0
    for i in range(n):
        b = _node_index(i)
        for a in range(2):
            r = abs(rhs[b + a])
            if not r <= rmax:
                rmax = r
    return rmax


@numba.njit(cache=True)
def kkt_residual(x0, v0, d, xm, F, mu, winv, edge_len, dt, rhs):
    """Minus the Newton residual, in the interleaved ordering; returns its norms.

    Parameters
    ----------
    x0, v0 : ndarray, shape (n, 2)
        State at the start of the step.
    d : ndarray, shape (n, 2)
        Current increment ``x1 - x0`` (length units).
    xm : ndarray, shape (n, 2)
        ``x0 + d/2``.
    F : ndarray, shape (n, 2)
        Applied forces at the midpoint (force units).
    mu : ndarray, shape (n - 1,)
        Scaled multipliers ``dt**2 lam / 2`` (force x time**2 units).
    winv : ndarray, shape (n, 2)
        Inverse node masses.
    edge_len : ndarray, shape (n - 1,)
    dt : float
    rhs : ndarray, shape (3 n - 1,)
        Overwritten with ``-R``: momentum rows
        ``R_i = d_i - dt v0_i - dt**2/2 w_i F_i - w_i (G(xm)^T mu)_i`` (length units) and
        constraint rows ``phi_j(x0 + d)`` (length units).

    Returns
    -------
    rmax : float
        Largest ``|R_i|``.
    cmax : float
        Largest relative edge-length error ``|phi_j| / l_j``.
    """
    n = x0.shape[0]
    m = n - 1
    half_dt2 = 0.5 * dt * dt
    for i in range(n):
        b = _node_index(i)
        for a in range(2):
            r = d[i, a] - dt * v0[i, a] - half_dt2 * winv[i, a] * F[i, a]
            rhs[b + a] = -r
    # constraint forces at the midpoint, and the constraints at x1
    cmax = 0.0
    for j in range(m):
        ex = xm[j + 1, 0] - xm[j, 0]
        ez = xm[j + 1, 1] - xm[j, 1]
        il = 1.0 / edge_len[j]
        gx = mu[j] * ex * il
        gz = mu[j] * ez * il
        b0 = _node_index(j)
        b1 = _node_index(j + 1)
        rhs[b1] += winv[j + 1, 0] * gx
        rhs[b1 + 1] += winv[j + 1, 1] * gz
        rhs[b0] -= winv[j, 0] * gx
        rhs[b0 + 1] -= winv[j, 1] * gz
        fx = (x0[j + 1, 0] + d[j + 1, 0]) - (x0[j, 0] + d[j, 0])
        fz = (x0[j + 1, 1] + d[j + 1, 1]) - (x0[j, 1] + d[j, 1])
        phi = 0.5 * ((fx * fx + fz * fz) * il - edge_len[j])
        rhs[3 * j + 4] = -phi
        c = abs(phi) * il
        if not c <= cmax:
            cmax = c
    return _node_rows_max(rhs, n), cmax


@numba.njit(cache=True)
def kkt_assemble(x0, d, xm, mu, winv, edge_len, ab):
    """Band storage of the (simplified) Newton matrix of :func:`kkt_residual`, without
    the bending block.

    Writes ``I - 1/2 W sum_j mu_j Hphi_j`` (``Hphi_j`` the constant Hessian of the
    quadratic constraint), the multiplier columns ``-W G(xm)^T`` and the constraint rows
    ``G(x0 + D)``.  The bending block ``dt**2/4 W H_b(xm)`` is added by
    :func:`bending_hessian_add`, the force effects' stiffness by
    :func:`stiffness_band_add` and :func:`lowrank_setup`.
    ``ab`` has shape ``(3 n - 1, 3 KL + 1)`` (banded LU layout, fill-in slots zeroed).
    """
    n = x0.shape[0]
    m = n - 1
    kl = KL
    ab[:, :] = 0.0
    for i in range(n):
        b = _node_index(i)
        ab[b, kl] = 1.0
        ab[b + 1, kl] = 1.0
    for j in range(m):
        il = 1.0 / edge_len[j]
        b0 = _node_index(j)
        b1 = _node_index(j + 1)
        cm = 3 * j + 4
        # geometric stiffness of the constraint forces: -1/2 W mu_j Hphi_j
        g = 0.5 * mu[j] * il
        for a in range(2):
            ab[b0 + a, kl] -= winv[j, a] * g
            ab[b0 + a, (b1 + a) - (b0 + a) + kl] += winv[j, a] * g
            ab[b1 + a, kl] -= winv[j + 1, a] * g
            ab[b1 + a, (b0 + a) - (b1 + a) + kl] += winv[j + 1, a] * g
        # multiplier column: -W G(xm)^T
        ex = (xm[j + 1, 0] - xm[j, 0]) * il
        ez = (xm[j + 1, 1] - xm[j, 1]) * il
        ab[b1, cm - b1 + kl] -= winv[j + 1, 0] * ex
        ab[b1 + 1, cm - b1 - 1 + kl] -= winv[j + 1, 1] * ez
        ab[b0, cm - b0 + kl] += winv[j, 0] * ex
        ab[b0 + 1, cm - b0 - 1 + kl] += winv[j, 1] * ez
        # constraint row: G(x1)
        fx = ((x0[j + 1, 0] + d[j + 1, 0]) - (x0[j, 0] + d[j, 0])) * il
        fz = ((x0[j + 1, 1] + d[j + 1, 1]) - (x0[j, 1] + d[j, 1])) * il
        ab[cm, b1 - cm + kl] += fx
        ab[cm, b1 + 1 - cm + kl] += fz
        ab[cm, b0 - cm + kl] -= fx
        ab[cm, b0 + 1 - cm + kl] -= fz
    return ab


@numba.njit(cache=True)
def hessian_columns_add(fp, fm, col, a, inv2e, q, winv, ab):
    """Add ``q W H_b`` columns ``(k, a)``, ``k = col, col + 5, ...``, to ``ab``.

    ``fp`` and ``fm`` (n, 2) are the bending forces with coordinate ``a`` of those nodes
    moved by ``+eps`` and ``-eps`` (``inv2e = 1/(2 eps)``).  The force at node ``j``
    depends on nodes ``j-2 .. j+2`` only, so nodes 5 apart perturbed together never
    share a row (graph colouring: 5 colours x 2 coordinates = 10 columns groups).
    """
    n = fp.shape[0]
    kl = KL
    for k in range(col, n, 5):
        cidx = _node_index(k) + a
        for jn in range(max(0, k - 2), min(n - 1, k + 2) + 1):
            rb = _node_index(jn)
            for bb in range(2):
                hval = -(fp[jn, bb] - fm[jn, bb]) * inv2e
                ab[rb + bb, cidx - (rb + bb) + kl] += q * winv[jn, bb] * hval


@numba.njit(cache=True)
def bending_hessian_add(x, edge_len, B, q, winv, ab):
    """Add ``q W H_b(x)`` to the band matrix ``ab``: the exact bending Hessian.

    ``E_b = sum_i w_i kb_i**2`` with ``w_i = B / (l_{i-1} + l_i)`` and ``kb = 2 c / den``,
    ``c = a x b``, ``den = |a||b| + a.b``, ``a = x_i - x_{i-1}``, ``b = x_{i+1} - x_i``
    (:mod:`dynamics.bending`).  Per interior node the 4x4 Hessian in ``u = (a, b)`` is
    ``2 w (g g^T + kb d2kb)`` with ``g = dkb/du``,
    ``d2kb = 2 [d2c/den - (dc dden^T + dden dc^T)/den**2 - c d2den/den**2
    + 2 c dden dden^T/den**3]``; it is mapped to the three nodes by ``a``, ``b``.

    Parameters
    ----------
    x : ndarray, shape (n, 2)
    edge_len : ndarray, shape (n - 1,)
    B : float
    q : float
        Factor (``dt**2 / 4`` in the Newton matrix).
    winv : ndarray, shape (n, 2)
        Row scaling (inverse masses).
    ab : ndarray, shape (3 n - 1, 3 KL + 1)
        Band matrix, accumulated into.

    Notes
    -----
    Analytic, replacing central differences of the force with a 5-colour graph colouring
    (20 force evaluations per Hessian), measured 4x slower at 100 edges; both agree to
    1e-9 relative (``tests/dynamics/test_dynamics_implicit.py``).
    """
    n = x.shape[0]
    kl = KL
    g = np.empty(4)
    dc = np.empty(4)
    dd = np.empty(4)
    d2d = np.empty((4, 4))
    H = np.empty((4, 4))
    blk = np.empty((3, 3))
    for i in range(1, n - 1):
        ax = x[i, 0] - x[i - 1, 0]
        az = x[i, 1] - x[i - 1, 1]
        bx = x[i + 1, 0] - x[i, 0]
        bz = x[i + 1, 1] - x[i, 1]
        la = np.sqrt(ax * ax + az * az)
        lb = np.sqrt(bx * bx + bz * bz)
        c = ax * bz - az * bx
        den = la * lb + ax * bx + az * bz
        idn = 1.0 / den
        kb = 2.0 * c * idn
        w = B / (edge_len[i - 1] + edge_len[i])
        dc[0] = bz
        dc[1] = -bx
        dc[2] = -az
        dc[3] = ax
        rab = lb / la
        rba = la / lb
        dd[0] = ax * rab + bx
        dd[1] = az * rab + bz
        dd[2] = bx * rba + ax
        dd[3] = bz * rba + az
        # second derivatives of den
        ia3 = lb / (la * la * la)
        ib3 = la / (lb * lb * lb)
        d2d[0, 0] = rab - ax * ax * ia3
        d2d[0, 1] = -ax * az * ia3
        d2d[1, 1] = rab - az * az * ia3
        d2d[2, 2] = rba - bx * bx * ib3
        d2d[2, 3] = -bx * bz * ib3
        d2d[3, 3] = rba - bz * bz * ib3
        ilab = 1.0 / (la * lb)
        d2d[0, 2] = ax * bx * ilab + 1.0
        d2d[0, 3] = ax * bz * ilab
        d2d[1, 2] = az * bx * ilab
        d2d[1, 3] = az * bz * ilab + 1.0
        for r in range(4):
            g[r] = 2.0 * (dc[r] * den - c * dd[r]) * idn * idn
        i2 = idn * idn
        for r in range(4):
            for s_ in range(r, 4):
                if r < 2 and s_ >= 2:
                    d2 = d2d[r, s_]
                else:
                    d2 = d2d[r, s_] if r <= s_ else d2d[s_, r]
                # d2c: only (ax, bz) = 1 and (az, bx) = -1
                d2c = 0.0
                if r == 0 and s_ == 3:
                    d2c = 1.0
                elif r == 1 and s_ == 2:
                    d2c = -1.0
                d2kb = 2.0 * (d2c * idn - (dc[r] * dd[s_] + dd[r] * dc[s_]) * i2
                              - c * d2 * i2 + 2.0 * c * dd[r] * dd[s_] * i2 * idn)
                H[r, s_] = 2.0 * w * (g[r] * g[s_] + kb * d2kb)
                H[s_, r] = H[r, s_]
        # node derivatives: d/dx_{i-1} = -d/da, d/dx_i = d/da - d/db, d/dx_{i+1} = d/db;
        # block (p, pp) of nodes i-1+p, i-1+pp is sum ca_p ca_pp Haa + ca_p cb_pp Hab
        # + cb_p ca_pp Hba + cb_p cb_pp Hbb with ca = (-1, 1, 0), cb = (0, -1, 1), its
        # nonzero terms written out in that order (x + 0 = x: the same sums bit for bit;
        # measured at 367 edges: 28 us instead of 35 us)
        for s1 in range(2):
            for s2 in range(2):
                haa = H[s1, s2]
                hab = H[s1, 2 + s2]
                hba = H[2 + s1, s2]
                hbb = H[2 + s1, 2 + s2]
                blk[0, 0] = haa
                blk[0, 1] = -haa + hab
                blk[0, 2] = -hab
                blk[1, 0] = -haa + hba
                blk[1, 1] = ((haa - hab) - hba) + hbb
                blk[1, 2] = hab - hbb
                blk[2, 0] = -hba
                blk[2, 1] = hba - hbb
                blk[2, 2] = hbb
                for p in range(3):
                    row = _node_index(i - 1 + p) + s1
                    wq = q * winv[i - 1 + p, s1]
                    for pp in range(3):
                        col = _node_index(i - 1 + pp) + s2
                        ab[row, col - row + kl] += wq * blk[p, pp]
    return ab


@numba.njit(cache=True)
def midpoint_ok(xm, edge_len):
    """False if an edge of the midpoint configuration is shorter than
    ``MIN_MID_EDGE * l`` or a coordinate is not finite (a diverging Newton iterate)."""
    for j in range(edge_len.shape[0]):
        ex = xm[j + 1, 0] - xm[j, 0]
        ez = xm[j + 1, 1] - xm[j, 1]
        lim = MIN_MID_EDGE * edge_len[j]
        if not ex * ex + ez * ez >= lim * lim:
            return False
    # a joint folded back on itself (turn > 177 degrees) would divide by zero in the
    # bending kernel (kb = 2 tan(psi/2)); only a diverging iterate gets there
    for j in range(1, edge_len.shape[0]):
        ax = xm[j, 0] - xm[j - 1, 0]
        az = xm[j, 1] - xm[j - 1, 1]
        bx = xm[j + 1, 0] - xm[j, 0]
        bz = xm[j + 1, 1] - xm[j, 1]
        la = np.sqrt(ax * ax + az * az)
        lb = np.sqrt(bx * bx + bz * bz)
        if not la * lb + ax * bx + az * bz > MIN_JOINT_DEN * la * lb:
            return False
    return True


@numba.njit(cache=True)
def kkt_update(d, mu, rhs):
    """Apply the Newton correction ``rhs`` (interleaved) to ``d`` and ``mu``; return
    the largest displacement correction."""
    n = d.shape[0]
    dmax = 0.0
    for i in range(n):
        b = _node_index(i)
        for a in range(2):
            d[i, a] += rhs[b + a]
            if abs(rhs[b + a]) > dmax:
                dmax = abs(rhs[b + a])
    for j in range(n - 1):
        mu[j] += rhs[3 * j + 4]
    return dmax


@numba.njit(cache=True)
def ground_rows_residual(x0, d, held, z0, rhs, wnu):
    """Replace the vertical momentum rows of held nodes by their contact constraint.

    For a held node ``i`` (``held[i] != 0``) the row ``z_i(x1) = z0`` replaces the vertical
    momentum row; that row's residual is then the (scaled) contact impulse, saved in
    ``wnu[i] = -rhs`` before the overwrite: ``w_i nu_i = dt**2/2 w_i f_i`` with ``f_i``
    the mean contact force over the step (length units; > 0 pushes the node up).

    Parameters
    ----------
    x0, d : ndarray, shape (n, 2)
        Start of the step and increment (length units).
    held : ndarray, shape (n,)
        Nonzero for held nodes.
    z0 : float
        Ground height (length units).
    rhs : ndarray, shape (3 n - 1,)
        Minus the residual of :func:`kkt_residual`, modified in place.
    wnu : ndarray, shape (n,)
        Written for held nodes.

    Returns
    -------
    float
        Largest ``|R_i|`` over the momentum rows, held rows now included as constraints.
    """
    n = x0.shape[0]
    for i in range(n):
        if held[i] != 0.0:
            b = _node_index(i) + 1
            wnu[i] = -rhs[b]
            rhs[b] = -(x0[i, 1] + d[i, 1] - z0)
    return _node_rows_max(rhs, n)


@numba.njit(cache=True)
def ground_rows_matrix(held, ab):
    """Identity rows for the vertical coordinate of held nodes in the band matrix ``ab``
    (the Jacobian of the rows written by :func:`ground_rows_residual`)."""
    kl = KL
    for i in range(held.shape[0]):
        if held[i] != 0.0:
            r = _node_index(i) + 1
            ab[r, :] = 0.0
            ab[r, kl] = 1.0


@numba.njit(cache=True)
def ground_update(x0, d, held, released, wnu, z0, tol_pull):
    """One round of the contact complementarity check, after a converged Newton solve.

    A held node whose contact impulse pulls (``wnu < -tol_pull``) is released, unless it
    was already released and re-caught in this step (``released == 2``: no cycling); a
    free node that ends below the ground is held (``d`` put on the ground).

    Returns
    -------
    int
        Number of nodes whose status changed (0: the active set is consistent).
    """
    n = x0.shape[0]
    changed = 0
    for i in range(n):
        if held[i] != 0.0:
            if wnu[i] < -tol_pull and released[i] == 0.0:
                held[i] = 0.0
                released[i] = 1.0
                changed += 1
        elif x0[i, 1] + d[i, 1] < z0:
            held[i] = 1.0
            d[i, 1] = z0 - x0[i, 1]
            if released[i] != 0.0:
                released[i] = 2.0
            changed += 1
    return changed


# ----------------------------------------------------------------------------- stiffness


@numba.njit(cache=True)
def stiffness_band_add(K, q, winv, ab):
    """Add ``q W K`` to the band matrix ``ab``: the band part of the force effects'
    stiffness (``K`` in the node-band layout of the ``stiffness`` hook,
    :mod:`dynamics.effects`, shape (n, 2, 2 STIFFNESS_BAND + 1, 2), force / length)."""
    n = K.shape[0]
    nb = STIFFNESS_BAND
    kl = KL
    for i in range(n):
        rb = _node_index(i)
        for o in range(2 * nb + 1):
            j = i + o - nb
            if j < 0 or j >= n:
                continue
            cb = _node_index(j)
            for a in range(2):
                for b in range(2):
                    h = K[i, a, o, b]
                    if h != 0.0:
                        ab[rb + a, cb + b - (rb + a) + kl] += q * winv[i, a] * h


@numba.njit(cache=True)
def _small_lu(S, spiv, k):
    """In-place LU with partial pivoting of ``S[:k, :k]``; -1 if a pivot is below
    SMALL_PIVOT times the largest entry or 1, the scale of ``S = I + ...`` (numerically
    singular)."""
    big = 1.0
    for r in range(k):
        for c in range(k):
            if abs(S[r, c]) > big:
                big = abs(S[r, c])
    for c in range(k):
        p = c
        best = abs(S[c, c])
        for r in range(c + 1, k):
            if abs(S[r, c]) > best:
                best = abs(S[r, c])
                p = r
        spiv[c] = p
        if not best > SMALL_PIVOT * big:
            return -1
        if p != c:
            for cc in range(k):
                tmp = S[c, cc]
                S[c, cc] = S[p, cc]
                S[p, cc] = tmp
        inv = 1.0 / S[c, c]
        for r in range(c + 1, k):
            f = S[r, c] * inv
            S[r, c] = f
            for cc in range(c + 1, k):
                S[r, cc] -= f * S[c, cc]
    return 0


@numba.njit(cache=True)
def lowrank_rate(U, C, k, q, winv):
    """Estimated rate ``q max(W) |U^T C U|_F`` at which the simplified Newton iteration
    would contract without the low-rank stiffness ``U^T C U`` in its matrix (the
    Frobenius norm, from the k x k Gram matrix of ``U``: O(k**2 n))."""
    n = U.shape[1]
    gm = np.zeros((k, k))
    for r in range(k):
        for c in range(r, k):
            acc = 0.0
            for i in range(n):
                acc += U[r, i, 0] * U[c, i, 0] + U[r, i, 1] * U[c, i, 1]
            gm[r, c] = acc
            gm[c, r] = acc
    # |U^T C U|_F**2 = trace(C Gm C Gm)
    cg = np.zeros((k, k))
    for r in range(k):
        for c in range(k):
            acc = 0.0
            for j in range(k):
                acc += C[r, j] * gm[j, c]
            cg[r, c] = acc
    tr = 0.0
    for r in range(k):
        for c in range(k):
            tr += cg[r, c] * cg[c, r]
    wmax = 0.0
    for i in range(n):
        wmax = max(wmax, winv[i, 0], winv[i, 1])
    return q * wmax * np.sqrt(max(tr, 0.0))


@numba.njit(cache=True)
def lowrank_setup(ab, piv, U, C, k, q, winv, held, G, H, S, spiv):
    """Prepare the Woodbury solve of ``(A + L Vt) y = b`` once ``A`` (the band Newton
    matrix) is factored: the low-rank part ``q W U^T C U`` of the force stiffness.

    Parameters
    ----------
    ab, piv : the factors ``P A = L_f U_f`` of :func:`band_lu` / :func:`band_lu_nopivot`.
    U : ndarray, shape (>= k, n, 2)
        Low-rank node vectors of the ``stiffness`` hooks.
    C : ndarray, shape (>= k, >= k)
        Their coefficients, ``sum_rs C[r, s] U[r] U[s]^T`` in force / length.
    k : int
        Rank.
    q : float
        ``dt**2 / 4``, the factor of the stiffness in the Newton matrix.
    winv : ndarray, shape (n, 2)
        Inverse masses (the momentum rows are scaled by them).
    held : ndarray, shape (n,)
        Nonzero for nodes held by the ground: their vertical row is the contact
        constraint, without stiffness (``L`` is zero there).
    G, H : ndarray, shape (3 n - 1, >= k)
        Overwritten with ``G = L_f^{-1} P L`` (``L[:, r] = q W U[r]``) and
        ``H = (Vt U_f^{-1})^T`` (``Vt = C U^T``), in the interleaved KKT ordering; both are
        zero above row ``start``.
    S, spiv : ndarray, shape (>= k, >= k) and (>= k,)
        Overwritten with the LU factors of the capacitance matrix ``I + H^T G`` (k x k).

    Returns
    -------
    start : int
        First row where ``G`` or ``H`` may be nonzero, or -1 if ``I + H^T G`` is
        numerically singular (then so is the Newton matrix ``A + L Vt``; the caller
        drops the low-rank part and keeps ``A``).

    Notes
    -----
    ``A^{-1} = U_f^{-1} L_f^{-1} P``, so Woodbury's
    ``(A + L Vt)^{-1} b = A^{-1} b - A^{-1} L (I + Vt A^{-1} L)^{-1} Vt A^{-1} b`` is
    ``U_f^{-1} (t - G (I + H^T G)^{-1} H^T t)`` with ``t = L_f^{-1} P b``: the correction
    goes between the two sweeps of the band solve (:func:`lowrank_correct`).  The
    right-hand sides ``L`` and ``Vt^T`` are zero before the first node the stiffness
    touches, and so are ``G`` and ``H`` (triangular solves): setting them up costs k
    partial forward and k partial transposed backward sweeps, a fraction of k full band
    solves when the drop sits near the end of the rod (fig3-strip).  Exact, unlike
    leaving the far couplings of the drop out of the band.
    """
    n = U.shape[1]
    N = ab.shape[0]
    first = n
    for r in range(k):
        for i in range(n):
            if U[r, i, 0] != 0.0 or U[r, i, 1] != 0.0:
                if i < first:
                    first = i
                break
    if first == n:
        return -1
    # row interchanges can move an entry up by at most kl rows
    start = max(0, _node_index(first) - KL)
    # whole columns: rows above start may hold contact columns of an earlier matrix, and
    # contact columns added later (contact_lowrank) can start above this start
    for j in range(N):
        for r in range(k):
            G[j, r] = 0.0
            H[j, r] = 0.0
    for i in range(first, n):
        b = _node_index(i)
        for a in range(2):
            for r in range(k):
                acc = 0.0
                for s_ in range(k):
                    acc += C[r, s_] * U[s_, i, a]
                H[b + a, r] = acc
                if not (a == 1 and held[i] != 0.0):
                    G[b + a, r] = q * winv[i, a] * U[r, i, a]
    band_forward_multi(ab, piv, KL, G, 0, k, start)
    band_backward_transpose_multi(ab, piv, KL, KL, H, 0, k, start)
    if _capacitance(G, H, S, spiv, k, start) != 0:
        return -1
    return start


@numba.njit(cache=True)
def _capacitance(G, H, S, spiv, k, start):
    """``S = I + H^T G`` over the first k columns (rows >= start), LU-factored in place;
    -1 if singular (:func:`_small_lu`)."""
    N = G.shape[0]
    for r in range(k):
        for c in range(k):
            S[r, c] = 1.0 if r == c else 0.0
    for j in range(start, N):
        for r in range(k):
            hr = H[j, r]
            if hr != 0.0:
                for c in range(k):
                    S[r, c] += hr * G[j, c]
    return _small_lu(S, spiv, k)


@numba.njit(cache=True)
def contact_rows_save(ab, held, mom, held_f):
    """Save the vertical momentum rows of all nodes (``mom`` (n, 3 KL + 1), band layout)
    and the held set (``held_f``) of the matrix about to be factored, before
    :func:`ground_rows_matrix` replaces the held rows: what :func:`contact_lowrank` needs
    to switch rows later without refactoring."""
    for i in range(held.shape[0]):
        r = _node_index(i) + 1
        for c in range(ab.shape[1]):
            mom[i, c] = ab[r, c]
        held_f[i] = held[i]


@numba.njit(cache=True)
def contact_lowrank(ab, piv, held, held_f, mom, U, C, k, q, winv, G, H, S, spiv, kinfo):
    """Rank-c update of the factored Newton matrix for a changed set of held nodes.

    Each node ``i`` whose held status differs from the factorisation's (``held_f``)
    changes one row ``r`` of the Newton matrix ``M`` (its vertical momentum row, or the
    contact row ``e_r``): ``M_new = M + sum_i e_r delta_i^T`` with
    ``delta_i = s_i (e_r - m_r - l_i Vt)``, ``s_i = +1`` for a node caught, -1 for one
    released, ``m_r`` the saved band row (:func:`contact_rows_save`) and ``l_i Vt`` the
    row of the stiffness's low-rank part (``k`` columns already in ``G, H``).  The update
    becomes columns ``k .. k + c`` of ``G = L_f^{-1} P E`` and ``H = (Delta U_f^{-1})^T``
    (partial sweeps from the first changed row) and the capacitance matrix is refactored.

    Returns
    -------
    int
        ``c`` (0: the held set is the factorisation's again), or -1 when there is no room
        for ``c`` more columns (``G.shape[1] - k``) or the capacitance matrix is singular:
        the caller refactors.  ``kinfo[4]`` holds ``c``, ``kinfo[2]`` the first row of all
        the columns in use (restored to the stiffness's, ``kinfo[6]``, when ``c`` is 0).
    """
    n = held.shape[0]
    N = ab.shape[0]
    room = G.shape[1] - k
    # first node of the stiffness vectors: delta_i reaches down to it through l_i Vt
    first = n
    for r_ in range(k):
        for m in range(n):
            if U[r_, m, 0] != 0.0 or U[r_, m, 1] != 0.0:
                first = min(first, m)
                break
    c = 0
    rmin = N
    for i in range(n):
        if (held[i] != 0.0) == (held_f[i] != 0.0):
            continue
        if c >= room:
            kinfo[4] = 0
            return -1
        j = k + c
        r = _node_index(i) + 1
        sg = 1.0 if held[i] != 0.0 else -1.0
        for jj in range(N):
            G[jj, j] = 0.0
            H[jj, j] = 0.0
        G[r, j] = 1.0
        H[r, j] += sg
        for cc in range(max(0, r - KL), min(N, r + KL + 1)):
            H[cc, j] -= sg * mom[i, cc - r + KL]
        rmin = min(rmin, r - KL)
        if k > 0 and winv[i, 1] != 0.0:
            # l_i Vt = sum_s a_s U[s], a_s = q w_i sum_r U[r, i, z] C[r, s]
            for s_ in range(k):
                a = 0.0
                for r_ in range(k):
                    a += U[r_, i, 1] * C[r_, s_]
                a *= q * winv[i, 1]
                if a != 0.0:
                    for m in range(first, n):
                        b = _node_index(m)
                        H[b, j] -= sg * a * U[s_, m, 0]
                        H[b + 1, j] -= sg * a * U[s_, m, 1]
            rmin = min(rmin, _node_index(first))
        c += 1
    kinfo[4] = c
    start = kinfo[6] if k > 0 else N
    if c > 0:
        # row interchanges can move an entry up by at most KL rows
        cstart = max(0, rmin - KL)
        band_forward_multi(ab, piv, KL, G, k, c, cstart)
        band_backward_transpose_multi(ab, piv, KL, KL, H, k, c, cstart)
        start = min(start, cstart)
    kinfo[2] = start
    if k + c > 0 and _capacitance(G, H, S, spiv, k + c, start) != 0:
        kinfo[4] = 0
        return -1
    return c


@numba.njit(cache=True)
def lowrank_correct(t, k, start, G, H, S, spiv, tv):
    """``t <- t - G (I + H^T G)^{-1} H^T t`` in place, between the forward and the
    backward sweep of the band solve (data of :func:`lowrank_setup`); ``tv`` (>= k,) is
    scratch."""
    N = t.shape[0]
    for r in range(k):
        tv[r] = 0.0
    for j in range(start, N):
        tj = t[j]
        if tj != 0.0:
            for r in range(k):
                tv[r] += H[j, r] * tj
    for c in range(k):
        p = spiv[c]
        if p != c:
            tmp = tv[c]
            tv[c] = tv[p]
            tv[p] = tmp
    for r in range(k):
        for c in range(r):
            tv[r] -= S[r, c] * tv[c]
    for r in range(k - 1, -1, -1):
        acc = tv[r]
        for c in range(r + 1, k):
            acc -= S[r, c] * tv[c]
        tv[r] = acc / S[r, r]
    for j in range(start, N):
        acc = 0.0
        for r in range(k):
            acc += G[j, r] * tv[r]
        t[j] -= acc
    return t


# ----------------------------------------------------------------------------- codegen

#: Body of the generated module (:func:`dynamics.codegen.render`): the dispatch functions
#: of the effects (``_external_forces``, ``_damp``, ``_stiffness``, ``_ground_height``) and
#: the flags are generated before it; ``$pargs`` / ``$fargs`` stand for the effects'
#: parameter arrays (all of them / the force effects').  Generated (not a generic loop over
#: first-class functions) for the same reason as :mod:`dynamics.rattle`: numba caches it
#: on disk.
_TEMPLATE = '''

@numba.njit(cache=True)
def _forces(x, v, t, edge_len, mass, B, F, energy$fargs):
    for i in range(x.shape[0]):
        F[i, 0] = 0.0
        F[i, 1] = 0.0
    energy[0] = bending_force_add(x, edge_len, B, F)
    _external_forces(x, v, t, edge_len, mass, F, energy$fargs)


@numba.njit(cache=True)
def _assemble(x0, d, xm, mu, winv, edge_len, B, dt, ab, held, lr, stiff):
    kkt_assemble(x0, d, xm, mu, winv, edge_len, ab)
    bending_hessian_add(xm, edge_len, B, 0.25 * dt * dt, winv, ab)
    if HAS_STIFFNESS:
        if stiff:
            stiffness_band_add(lr[0], 0.25 * dt * dt, winv, ab)
    if HAS_GROUND:
        contact_rows_save(ab, held, lr[10], lr[9])
        ground_rows_matrix(held, ab)


@numba.njit(cache=True)
def _jacobian(x0, d, xm, vm, t, mu, winv, edge_len, mass, B, dt, ab, piv, held, lr,
              stiff$fargs):
    K = lr[0]
    k = 0
    lr[7][0] = 0
    lr[7][4] = 0
    lr[7][2] = ab.shape[0]
    if HAS_STIFFNESS:
        if stiff:
            K[:, :, :, :] = 0.0
            lr[1][:, :, :] = 0.0
            lr[2][:, :] = 0.0
            k = _stiffness(xm, vm, t, edge_len, mass, K, lr[1], lr[2]$fargs)
    _assemble(x0, d, xm, mu, winv, edge_len, B, dt, ab, held, lr, stiff)
    # no pivoting unless a pivot is tiny (see band_lu_nopivot)
    res = 0
    if band_lu_nopivot(ab, KL, KL, 1e-10) == 0:
        piv[0] = -1
    else:
        _assemble(x0, d, xm, mu, winv, edge_len, B, dt, ab, held, lr, stiff)
        if band_lu(ab, piv, KL, KL) != 0:
            return -1
        res = 1
    if HAS_STIFFNESS:
        if k > 0 and lowrank_rate(lr[1], lr[2], k, 0.25 * dt * dt, winv) >= LOWRANK_MIN_RATE:
            start = lowrank_setup(ab, piv, lr[1], lr[2], k, 0.25 * dt * dt, winv, held,
                                  lr[3], lr[4], lr[5], lr[6])
            if start >= 0:
                lr[7][0] = k
                lr[7][2] = start
                lr[7][6] = start
                lr[7][3] += 1
            else:
                lr[7][1] += 1
    return res


@numba.njit(cache=True)
def _contact_update(ab, piv, held, lr, winv, dt):
    lr[7][7] += 1
    return contact_lowrank(ab, piv, held, lr[9], lr[10], lr[1], lr[2], lr[7][0],
                           0.25 * dt * dt, winv, lr[3], lr[4], lr[5], lr[6], lr[7])


@numba.njit(cache=True)
def _solve(ab, piv, rhs, lr):
    band_forward(ab, piv, KL, rhs)
    if HAS_STIFFNESS or HAS_GROUND:
        k = lr[7][0] + lr[7][4]
        if k > 0:
            lowrank_correct(rhs, k, lr[7][2], lr[3], lr[4], lr[5], lr[6], lr[8])
    band_backward(ab, piv, KL, KL, rhs)


@numba.njit(cache=True)
def _step(x, v, t, dt, edge_len, mass, winv, B, ws, mu, ab, piv, rhs, energy, diag,
          opts, lr, ck$pargs):
    n = x.shape[0]
    x0 = ws[0]
    v0 = ws[1]
    d = ws[2]
    xm = ws[3]
    F = ws[4]
    acc = ws[5]
    held = ws[6][:, 0]
    wnu = ws[6][:, 1]
    released = ws[7][:, 0]
    vm = ws[9]
    half = 0.5 * dt
    inv_dt = 1.0 / dt
    tol_x = opts[0]
    tol_c = opts[1]
    max_iter = int(opts[2])
    max_age = opts[3]
    tol_pull = opts[4]
    stiff = opts[5] != 0.0
    refresh_rate = opts[6]
    refresh_move = opts[7]
    # contact changes by a low-rank update of the factored matrix (else: refactor)
    cupd = opts[8] != 0.0
    z0 = _ground_height(t$pargs)
    _damp(x, v, t, edge_len, mass, half$pargs)
    for i in range(n):
        for k in range(2):
            x0[i, k] = x[i, k]
            v0[i, k] = v[i, k]
            d[i, k] = dt * v[i, k] + half * dt * acc[i, k]
    if HAS_GROUND:
        for i in range(n):
            released[i] = 0.0
            if held[i] != 0.0:
                d[i, 1] = z0 - x0[i, 1]
    # a factorisation made for another dt (substeps) or too old is refreshed
    if diag[9] != dt or diag[8] >= max_age:
        diag[8] = max_age
    it = 0
    ok = False
    h_min = edge_len.min()
    rounds = 0
    rmax = np.inf
    while True:
        # Newton for the current set of held nodes
        ok = False
        d_prev = np.inf
        theta = 0.0
        refreshed = False
        moved = 0.0
        while True:
            for i in range(n):
                for k in range(2):
                    xm[i, k] = x0[i, k] + 0.5 * d[i, k]
                    vm[i, k] = d[i, k] * inv_dt
            if not midpoint_ok(xm, edge_len):
                rmax = np.inf
                break
            _forces(xm, vm, t + half, edge_len, mass, B, F, energy$fargs)
            rmax, cmax = kkt_residual(x0, v0, d, xm, F, mu, winv, edge_len, dt, rhs)
            if HAS_GROUND:
                rmax = ground_rows_residual(x0, d, held, z0, rhs, wnu)
                # active-set update on the current iterate once it is near convergence
                # (edge lengths within FINAL_C; earlier iterates flip nodes spuriously): a
                # semi-smooth Newton step.  Each node changes at most 3 times a step
                # (free -> held -> released -> held for good), so this cannot cycle.
                # The held rows changed: the factored matrix gets them by a low-rank
                # update, or is refactored (measured: a matrix with stale rows lets the
                # iterate diverge)
                if (cmax <= FINAL_C
                        and ground_update(x0, d, held, released, wnu, z0, tol_pull) > 0):
                    diag[4] += 1
                    if (not cupd or diag[8] >= max_age
                            or _contact_update(ab, piv, held, lr, winv, dt) < 0):
                        diag[8] = max_age
                    continue
            if not (rmax < np.inf and cmax < np.inf):
                break
            if rmax <= tol_x and cmax <= tol_c:
                ok = True
                break
            if it >= max_iter:
                break
            # refresh the factorisation when it is stale or the corrections contract
            # slowly (the residual is no guide near convergence: it sits on its round-off
            # floor) (again in the same step only if the iterate has moved since: a fresh
            # matrix that still contracts slowly near where it was made is missing the
            # external forces' stiffness, which no refresh adds)
            if diag[8] >= max_age or (theta > refresh_rate
                                      and (not refreshed or moved > refresh_move * h_min)):
                info = _jacobian(x0, d, xm, vm, t + half, mu, winv, edge_len, mass, B, dt,
                                 ab, piv, held, lr, stiff$fargs)
                diag[10] += 1
                if info == 1:
                    diag[1] += 1
                    info = 0
                diag[8] = 0
                diag[9] = dt
                refreshed = True
                moved = 0.0
                if info != 0:
                    break
            _solve(ab, piv, rhs, lr)
            dmax = kkt_update(d, mu, rhs)
            moved += dmax
            it += 1
            # the residual has a round-off floor ~ eps |x| (1 + (omega_max dt)**2 / 4)
            # that grows with dt; the correction does not.  Error left after this
            # correction, estimated from the observed contraction theta (Hairer & Wanner,
            # sec. IV.8): theta / (1 - theta) * dmax; accepted without one more force
            # evaluation
            est = dmax
            theta = 0.0
            if it > 1 and d_prev > 0.0:
                theta = dmax / d_prev
                est = theta / (1.0 - theta) * dmax if theta < 0.5 else np.inf
            d_prev = dmax
            if est <= tol_x and cmax <= FINAL_C:
                ok = True
                break
        if not ok or not HAS_GROUND:
            break
        # contact complementarity: hold the nodes that end below the ground, release
        # those the ground pulls; solve again until the set is consistent
        if ground_update(x0, d, held, released, wnu, z0, tol_pull) == 0:
            break
        rounds += 1
        diag[4] += 1
        # the held rows changed: a low-rank update, or a refactorisation
        if (not cupd or diag[8] >= max_age
                or _contact_update(ab, piv, held, lr, winv, dt) < 0):
            diag[8] = max_age
        if rounds > MAX_CONTACT_ROUNDS:
            ok = False
            break
    if not ok:
        diag[5] = rmax
        diag[8] = max_age
        diag[11] = 0.0
        return -1
    diag[8] += 1
    if it > diag[2]:
        diag[2] = it
    diag[3] += it
    for i in range(n):
        for k in range(2):
            x[i, k] = x0[i, k] + d[i, k]
            v[i, k] = 2.0 * d[i, k] * inv_dt - v0[i, k]
    for i in range(n):
        for k in range(2):
            acc[i, k] = (v[i, k] - v0[i, k]) * inv_dt
    if HAS_GROUND:
        # perfectly inelastic: a held node ends the step on the ground at rest vertically
        # (the midpoint rule alone would return v1 = -v0: a bounce)
        for i in range(n):
            if held[i] != 0.0:
                x[i, 1] = z0
                v[i, 1] = 0.0
                acc[i, 1] = 0.0
    if HAS_CONTACT:
        # self-contact after the implicit step: project the new positions onto the edge
        # lengths and the non-penetration constraints (linearised at x0), the velocities
        # following the scheme (v1 = 2 D / dt - v0), then restitution 0 where the rod
        # touches (the contacts pushed end at rest relative to each other, as held ground
        # nodes do); ground-held coordinates stay held
        th = _contact_thickness(t + dt$pargs)
        wc = ck.scratch[2]
        xs = ck.scratch[0]
        for i in range(n):
            wc[i, 0] = winv[i, 0]
            wc[i, 1] = 0.0 if (HAS_GROUND and held[i] != 0.0) else winv[i, 1]
            xs[i, 0] = x[i, 0]
            xs[i, 1] = x[i, 1]
        cst = contact_positions(x0, x, wc, edge_len, ck.vec[12], th, opts[9] * th, ck)
        if cst < 0:
            diag[11] = 1.0
            diag[8] = max_age
            return -1
        if cst > 0 and contact_shortfall(x, th, opts[10], ck):
            # the contacts turned too far within the step for their linearisation at its
            # start: rejected, retried with substeps (the shortfall falls as dt**2)
            diag[11] = 1.0
            diag[8] = max_age
            return -1
        if cst > 0:
            for i in range(n):
                for k in range(2):
                    v[i, k] += 2.0 * (x[i, k] - xs[i, k]) * inv_dt
        cvs = contact_velocities(x, v, wc, edge_len, th, dt, 2.0, True, True, ck)
        if cvs < -1:
            # a non-finite velocity: the step is rejected (retried with substeps) before
            # it reaches the state
            diag[11] = 1.0
            diag[8] = max_age
            return -1
        if cvs < 0:
            diag[12] += 1.0
    _damp(x, v, t + half, edge_len, mass, half$pargs)
    return it


@numba.njit(cache=True)
def run(x, v, t0, dt, n_steps, edge_len, mass, winv, B, ws, mu, ab, piv, rhs, energy,
        diag, rest, opts, lr, ck$pargs):
    n = x.shape[0]
    acc = ws[5]
    xb = ws[10]
    vb = ws[11]
    ab_ = ws[12]
    held = ws[6][:, 0]
    hb = ws[8][:, 0]
    mub = np.empty_like(mu)
    status = 0
    steps = 0
    for s in range(n_steps):
        t = t0 + s * dt
        _copy2(xb, x)
        _copy2(vb, v)
        _copy2(ab_, acc)
        _copy1(mub, mu)
        _copy1(hb, held)
        st = _step(x, v, t, dt, edge_len, mass, winv, B, ws, mu, ab, piv, rhs, energy, diag,
                   opts, lr, ck$pargs)
        if st < 0:
            # rejected step: retry as 2, 4, ... 2**MAX_HALVINGS substeps
            for level in range(1, MAX_HALVINGS + 1):
                _copy2(x, xb)
                _copy2(v, vb)
                _copy2(acc, ab_)
                _copy1(mu, mub)
                _copy1(held, hb)
                diag[6] += 1
                sub = 2 ** level
                h = dt / sub
                for j in range(sub):
                    st = _step(x, v, t + j * h, h, edge_len, mass, winv, B, ws, mu, ab, piv,
                               rhs, energy, diag, opts, lr, ck$pargs)
                    if st < 0:
                        break
                if st >= 0:
                    if level > diag[7]:
                        diag[7] = level
                    break
            if st < 0:
                _copy2(x, xb)
                _copy2(v, vb)
                _copy1(held, hb)
                status = 2
                break
        steps += 1
        # rest is judged on the step's displacement rate D/dt (kinetic energy of the
        # midpoint velocity), not on v1 = 2 D/dt - v0: v1 can carry the midpoint rule's
        # sign-flipping mode (v, -v with D = 0), which a contact change excites and no
        # force damps without damping; a rod lying still kept 1.3 % of its initial energy
        # in it (measured), so v1 never fell below a rest threshold
        ke = 0.0
        kem = 0.0
        inv_dt2 = 1.0 / (dt * dt)
        for i in range(n):
            ke += mass[i] * (v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1])
            dx0 = x[i, 0] - xb[i, 0]
            dx1 = x[i, 1] - xb[i, 1]
            kem += mass[i] * (dx0 * dx0 + dx1 * dx1) * inv_dt2
        ke *= 0.5
        kem *= 0.5
        if not np.isfinite(ke):
            status = 3
            break
        if _at_rest(kem, dt, rest):
            status = 1
            break
    _record_constraint_error(x, edge_len, diag)
    return status, steps
'''


#: The method's own imports in its generated module.
_IMPORTS = """\
from dynamics.bending import bending_force_add
from dynamics.contact import contact_positions, contact_shortfall, contact_velocities
from dynamics.midpoint import (FINAL_C, KL, LOWRANK_MIN_RATE, MAX_CONTACT_ROUNDS, MAX_HALVINGS,
                               band_backward, band_forward, band_lu, band_lu_nopivot,
                               bending_hessian_add, contact_lowrank, contact_rows_save,
                               ground_rows_matrix, ground_rows_residual, ground_update,
                               kkt_assemble, kkt_residual, kkt_update, lowrank_correct,
                               lowrank_rate, lowrank_setup, midpoint_ok, stiffness_band_add)
"""


def _generate_source(refs):
    """Source of a midpoint stepper module for ``refs = [(kind, module, name, stiffness,
    ground), ...]`` (:func:`dynamics.codegen.render` of :data:`_TEMPLATE`)."""
    return render(_TEMPLATE, refs, _IMPORTS)


_MODULES: dict = {}


def _stiffness_ref(effect):
    """(module, name) of a force effect's optional ``stiffness`` hook, or None."""
    hook = getattr(effect, "stiffness", None)
    if hook is None:
        return None
    return kernel_ref(SimpleNamespace(name=effect.name, kernel=hook))


def compile_stepper(effects=()):
    """Return the generated midpoint stepper module for these effects.

    Parameters
    ----------
    effects : sequence of effect objects
        Force and damping effects (see :mod:`dynamics.effects`) and at most one ground;
        other constraint effects are refused.

    Returns
    -------
    module
        With numba functions ``run``, ``_step``, ``_forces`` and ``_jacobian``.
    """
    refs = []
    grounds = 0
    for e in effects:
        hook = _stiffness_ref(e) if e.kind == "force" else None
        if e.kind not in KINDS:
            raise ValueError(f"effect {e.name!r}: kind must be one of {KINDS}, got {e.kind!r}")
        ref = kernel_ref(e)
        ground = e.kind == "constraint" and is_ground(e)
        contact = check_self_contact(e, effects)
        if contact:
            refs.append((e.kind, *ref, None, contact))
            continue
        if e.kind == "constraint":
            if not ground:
                raise ValueError(
                    f"effect {e.name!r}: constraint effects other than a ground (a clamp, "
                    "your own without ground_height_param) are not supported by the "
                    "midpoint method; use method='rattle' for this scene"
                )
            if int(e.ground_height_param) != 0:
                raise ValueError(f"effect {e.name!r}: the midpoint method reads the ground "
                                 "height from params[0]; got ground_height_param = "
                                 f"{e.ground_height_param!r}")
            grounds += 1
            if grounds > 1:
                raise ValueError(
                    f"effect {e.name!r}: the midpoint method handles one ground; got "
                    f"{grounds} ground effects"
                )
        refs.append((e.kind, *ref, hook, ground))
    refs = tuple(refs)
    if refs in _MODULES:
        return _MODULES[refs]
    files = [r[:3] for r in refs] + [("force", *r[3]) for r in refs if r[3] is not None]
    module = load_module("midpoint", _generate_source(refs),
                         stepper_depends(files) + dependency_digest(["dynamics.midpoint"]))
    _MODULES[refs] = module
    return module


#: Compile time of a new midpoint stepper when the package's kernels are cached, the base
#: of the estimate the driver announces before a first compile
#: (:func:`dynamics.codegen.compile_estimate` adds what is not cached, and self-contact):
#: measured (benchmarks/compile_speed.py, CPU, 2 shared cores) 6.8 s bending only and
#: 14.9 s with fig3-strip's four effects; 15.7 s (wall) for supp-fig5's two.
COMPILE_BASE_S = 10.0
COMPILE_PER_EFFECT_S = 2.0


class Run:
    """A midpoint run in progress (the method protocol of :mod:`dynamics.driver`).

    Same effects as RATTLE except constraints (at most one ground); no explicit stability
    bound: ``dt`` may exceed :func:`dynamics.stable_dt` by any factor, it is chosen for
    accuracy (the error is O(dt**2), frequency error ``-(omega dt)**2/12``).

    Options
    -------
    jacobian_age : int, optional
        Steps a Newton matrix factorisation is reused (1 = refactor every step); it is
        refreshed earlier whenever a Newton correction exceeds ``REFRESH_RATE`` times the
        previous one.
    tol_x, tol_c : float, optional
        Newton tolerances: momentum residual (relative to the shortest edge) and relative
        edge-length error.
    stiffness : bool, optional
        Put the stiffness of the force effects that supply a ``stiffness`` hook
        (:mod:`dynamics.effects`; the drop does) into the Newton matrix.  False leaves it
        out (simplified Newton, more iterations); the converged steps are the same to the
        Newton tolerance either way.
    contact_updates : bool, optional
        With a ground, switch the rows of nodes caught or released since the Newton matrix
        was factored by a low-rank update (:func:`contact_lowrank`); False refactors the
        matrix at every change of the held set.

    ``stats`` adds ``jacobians`` (factorisations of the Newton matrix),
    ``pivoted_factorisations``, ``stiffness_lowrank``, ``contact_updates`` and
    ``stiffness_dropped`` (factorisations whose low-rank stiffness part was left out, its
    Woodbury capacitance matrix being singular).  ``iterations_*`` count Newton
    iterations a step.  The velocities and ``energies["kinetic"]`` are those of the
    scheme's v1 (the quantity it conserves), which may carry the sign-flipping mode
    ``(v, -v)`` of the midpoint rule that does not move the rod; ``rest`` is judged on the
    displacement rate instead.
    """


    def __init__(self, rod, effects, dt, t0, rest, jacobian_age=JACOBIAN_AGE,
                 tol_x=NEWTON_TOL_X, tol_c=NEWTON_TOL_C, stiffness=True,
                 contact_updates=True):
        if int(jacobian_age) < 1:
            raise ValueError(f"jacobian_age must be >= 1, got {jacobian_age!r}")
        if rod.n_nodes < 3:
            raise ValueError(f"the midpoint method needs >= 2 edges, got {rod.n_nodes - 1}")
        self.dt, self.t0, self.B = dt, t0, rod.B
        self.effects = effects
        self.label = "+".join(e.name for e in effects) or "bending"
        self.mod = compile_stepper(effects)
        self.params = tuple(e.params for e in effects)
        self.force_names = [e.name for e in effects if e.kind == "force"]
        self.n_energies = 1 + len(self.force_names)
        self.dt_max = stable_dt(rod.edge_len, rod.mu, rod.B)
        self.x = x = rod.x.copy()
        self.v = rod.v.copy()
        n = x.shape[0]
        self.edge_len = edge_len = rod.edge_len.copy()
        self.mass = rod.mass
        winv = np.empty((n, 2))
        winv[:, 0] = 1.0 / self.mass
        winv[:, 1] = 1.0 / self.mass
        N = 3 * n - 1
        self.energy = np.zeros(self.n_energies)
        # diag: [0] largest constraint error, [1] pivoted factorisations, [2] most
        # iterations, [3] iteration sum, [4] contact rounds, [5] failing residual,
        # [6] rejected steps, [7] deepest halving, [10] factorisations, [11] the failing
        # part was the self-contact projection, [12] unsettled self-contact velocity stages
        self.diag = np.zeros(13)
        self.rest_arr = np.zeros(3)
        if rest is not None:
            self.rest_arr[0] = rest.kinetic_energy
            self.rest_arr[1] = rest.duration
        h_min = float(edge_len.min())
        opts = np.array([tol_x * h_min, tol_c, NEWTON_MAX_ITER, float(int(jacobian_age)),
                         CONTACT_PULL_TOL * h_min, 1.0 if stiffness else 0.0, REFRESH_RATE,
                         REFRESH_MOVE, 1.0 if contact_updates else 0.0, CONTACT_MAX_DEPTH,
                         CONTACT_MAX_SHORTFALL])
        self.ws = ws = np.zeros((13, n, 2))
        self.mu = np.zeros(n - 1)
        # workspace of the low-rank parts of the Newton matrix: the force stiffness (K
        # band, U, C), the Woodbury data (G, H, S, pivots), counters [stiffness rank,
        # dropped, first row, used, contact columns, -, stiffness's first row, contact
        # updates], scratch, and the held set and momentum rows saved at the factorisation
        # (ground only); empty arrays when no effect has a stiffness hook and there is no
        # ground
        hooks = sum(1 for e in effects
                    if e.kind == "force" and getattr(e, "stiffness", None) is not None)
        ground = [e for e in effects if e.kind == "constraint" and is_ground(e)]
        self.contact = any(is_self_contact(e) for e in effects)
        self.ck = new_contact_work(edge_len) if self.contact else NO_CONTACT_WORK
        R = STIFFNESS_RANK * hooks
        nk = n if hooks else 0
        # columns for the stiffness and for the rows of contact changes
        Rt = R + (CONTACT_RANK if ground else 0)
        ng = n if ground else 0
        self.lr = (np.zeros((nk, 2, 2 * STIFFNESS_BAND + 1, 2)), np.zeros((R, nk, 2)),
                   np.zeros((R, R)), np.zeros((N, Rt)), np.zeros((N, Rt)),
                   np.zeros((Rt, Rt)), np.zeros(Rt, dtype=np.int64),
                   np.zeros(8, dtype=np.int64), np.zeros(Rt), np.zeros(ng),
                   np.zeros((ng, 3 * KL + 1)))
        self.work = (edge_len, self.mass, winv, rod.B, ws, self.mu, np.zeros((N, 3 * KL + 1)),
                     np.zeros(N, dtype=np.int64), np.zeros(N), self.energy, self.diag)
        self.opts = opts
        if ground:
            # nodes on (or below) the ground at the start are held; the first step's
            # complementarity check releases those the ground pulls
            ws[6][:, 0] = x[:, 1] <= ground[0].params[0]
        self.acc_save = np.empty((n, 2))

    def compiled(self) -> bool:
        return is_compiled(self.mod, ("run", "_forces"))

    def compile_estimate(self) -> float:
        return compile_estimate(COMPILE_BASE_S, COMPILE_PER_EFFECT_S, self.effects,
                                ((sys.modules[__name__], ("band_lu", "band_forward")),))

    def _forces_at_x(self, t):
        F = self.ws[4]
        self.mod._forces(self.x, self.v, t, self.edge_len, self.mass, self.B, F,
                         self.energy, self.params)

    def warm(self):
        """Compile (or load) the stepper; the state is restored afterwards."""
        x, v, ws = self.x, self.v, self.ws
        # the first step's predictor is x0 + dt v0: the applied acceleration alone
        # (without the constraint forces that balance most of it) made the first Newton
        # iteration diverge on a released curved rod at 16x the explicit bound (measured)
        ws[5][:, :] = 0.0
        self._forces_at_x(self.t0)
        xs, vs, accs, hs = x.copy(), v.copy(), ws[5].copy(), ws[6].copy()
        ck_state = [a.copy() for a in self.ck]
        self.mod.run(x, v, self.t0, self.dt, 1, *self.work, np.zeros(3), self.opts, self.lr,
                     self.ck, self.params)
        for a, b in zip(self.ck, ck_state, strict=True):
            a[...] = b
        x[:, :], v[:, :], ws[5][:, :], ws[6][:, :] = xs, vs, accs, hs
        self.mu[:] = 0.0
        self.diag[:] = 0.0
        self.lr[7][:] = 0

    def advance(self, step, stops, record, pos, ens, rec_steps, nrec):
        status = 0
        for k in range(stops.shape[0]):
            stop = int(stops[k])
            if stop > step:
                status, done = self.mod.run(self.x, self.v, self.t0 + step * self.dt,
                                            self.dt, stop - step, *self.work, self.rest_arr,
                                            self.opts, self.lr, self.ck, self.params)
                step += done
                if status != 0:
                    break
            if record[k]:
                nrec = self.frame(pos, ens, rec_steps, nrec, step)
        return status, step, nrec

    def after_event(self, step):
        pass  # the forces are evaluated inside each step's Newton iteration

    def frame(self, pos, ens, rec_steps, nrec, step):
        ws = self.ws
        pos[nrec] = self.x
        self.acc_save[:, :] = ws[5]
        self._forces_at_x(self.t0 + step * self.dt)
        ws[5][:, :] = self.acc_save
        ens[nrec, 0] = 0.5 * float(np.sum(self.mass[:, None] * self.v * self.v))
        ens[nrec, 1:] = self.energy
        rec_steps[nrec] = step
        return nrec + 1

    @property
    def status_names(self):
        if self.diag[11]:
            return {2: ("contact_failed", "self-contact projection did not converge")}
        return {2: ("newton_failed", "the implicit step's Newton iteration did not converge")}

    def contact_forces(self):
        """Self-contact forces on the nodes, mean over the last step (None without it)."""
        return self.ck.forces.copy() if self.contact else None

    def failure(self, status, step, t_final):
        dt = self.dt
        if status == 2 and self.diag[11]:
            return contact_failure(self.ck, t_final + dt, step + 1, dt, 2**MAX_HALVINGS)
        if status == 2:
            return (f"{self.status_names[2][1]} at t = {t_final + dt:g} (step {step + 1}): "
                    f"momentum residual {self.diag[5]:.3g} after {NEWTON_MAX_ITER} "
                    f"iterations, even with {2**MAX_HALVINGS} substeps. Try a smaller dt "
                    f"(now {dt:g}, {dt / self.dt_max:.3g}x the explicit bound) or check the "
                    "forces for a blow-up.")
        return (f"non-finite state (NaN/inf) at t = {t_final:g} (step {step}): the "
                f"integration blew up. Try a smaller dt (now {dt:g}).")

    def stats(self) -> dict:
        d, c = self.diag, self.lr[7]
        return {"rejected_steps": int(d[6]), "max_halvings": int(d[7]),
                "iterations_max": float(d[2]), "iterations_sum": float(d[3]),
                "contact_rounds": int(d[4]), "constraint_error": float(d[0]),
                "jacobians": int(d[10]), "pivoted_factorisations": int(d[1]),
                "stiffness_lowrank": int(c[3]), "contact_updates": int(c[7]),
                "stiffness_dropped": int(c[1]),
                **(contact_stats(self.ck, int(d[12])) if self.contact else {})}
