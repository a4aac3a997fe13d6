"""Stiffness of the drop: the Hessian of gamma lambda as a band plus a rank-5 part.

The midpoint method (:mod:`dynamics.midpoint`) puts the stiffness of force effects into
its Newton matrix when the effect supplies a ``stiffness`` kernel (the optional hook of the
effect protocol, :mod:`dynamics.effects`).  Without it, Newton converges only linearly
at a rate ``~ dt**2 |K_cap| / (4 m)``: 6-9 iterations a step on fig3-strip (gamma = 40) and
12-22 on an encapsulating supp-fig5 run at 64-128x the explicit bound (measured).

Hessian (same cap model and polygon as :func:`elastocap.drop.capillary_energy_and_gradient`)
------------------------------------------------------------------------------------------
The wet polygon is ``P_0 = x(S1)``, ``P_1 .. P_p`` the interior wet nodes
``i1 + 1 .. i2``, ``P_{p+1} = x(S2)``, the contact points interpolating the end nodes of
their edges (``P_0 = (1 - w1) x_{i1} + w1 x_{i1+1}``, likewise ``P_{p+1}``).  With
``d = |P_{p+1} - P_0|``, the shoelace area ``A0(P)``, ``A1 = A - A0`` and
``d(lambda) = cos(tau) dd + kappa dA1``::

    H = gamma [l_dd gd gd^T - l_dA (gd gA^T + gA gd^T) + l_AA gA gA^T
               + cos(tau) Hd - kappa HA]

``l_dd = -sin(tau) tau_d``, ``l_dA = -sin(tau) tau_A1``, ``l_AA = 2 cos(tau) tau_A1 / d``;
``gd, Hd`` the derivatives of ``d`` (nonzero on ``P_0, P_{p+1}`` only), ``gA`` and the
constant ``HA`` those of ``A0`` (``HA`` couples polygon neighbours, including the closing
chord ``P_{p+1} -> P_0``).  The reference, dense in numpy, is
:func:`elastocap.strip.model.capillary_hessian_nodes`; the tests check this kernel
against it and against finite differences of :func:`elastocap.capillary.capillary_kernel`.

Split
-----
* **Band** (node half-bandwidth 1): ``-gamma kappa HA`` over the polygon edges
  ``P_k -> P_{k+1}``, ``k = 0 .. p``, whose end points share or neighbour nodes.
* **Rank 5**: everything else lives in the span of the four coordinates of ``P_0``,
  ``P_{p+1}`` and the vector ``gA``: ``gd`` and ``Hd`` are supported on the two contact
  points, and so is the closing chord's term of ``HA``, which couples the far ends of the
  wet region.  So ``H = K + U^T C U`` with ``U`` the five node vectors
  ``T^T e_{P_0,x}, T^T e_{P_0,z}, T^T e_{P_{p+1},x}, T^T e_{P_{p+1},z}, T^T gA`` and a
  symmetric 5x5 ``C`` (a rank-7 split, with ``gd`` and ``Hd`` as their own factors, would
  cost two more band solves per factorisation for nothing).

Units: ``H`` in force / length (gamma force, lengths in the rod's length unit).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from elastocap.drop import cap_geometry, cap_tau_derivatives, locate_on_rod, wet_polygon_area

__all__ = ["capillary_stiffness", "CAPILLARY_RANK", "stiffness_dense"]

#: Columns of the low-rank factor written by :func:`capillary_stiffness`.
CAPILLARY_RANK = 5


@numba.njit(cache=True)
def _polygon_point(k, p, i1, w1, i2, w2):
    """Nodes and weights of polygon point ``P_k``: ``P_k = ca x_na + cb x_nb``."""
    if k == 0:
        return i1, 1.0 - w1, i1 + 1, w1
    if k == p + 1:
        return i2, 1.0 - w2, i2 + 1, w2
    return i1 + k, 1.0, i1 + k, 0.0


@numba.njit(cache=True)
def _band_block_add(K, i, j, c, bxz, bzx):
    """``K[i, :, j, :] += c [[0, bxz], [bzx, 0]]`` in node-band storage (offset j - i)."""
    o = j - i + 2
    K[i, 0, o, 1] += c * bxz
    K[i, 1, o, 0] += c * bzx


@numba.njit(cache=True)
def capillary_stiffness(x, v, t, params, edge_len, mass, K, U, C):
    """Hessian of gamma lambda at ``x``: band part added to ``K``, rank-5 part in ``U, C``.

    The optional ``stiffness`` hook of a force effect (:mod:`dynamics.effects`), for the
    :class:`~elastocap.capillary.Capillary` effect, ``params = [A, S1, S2, gamma]``.

    Parameters
    ----------
    x : ndarray, shape (n, 2)
        Node positions (length).
    v, t, mass
        Unused (the force depends on positions only).
    params : ndarray, shape (4,)
        Area A (length^2), contact arclengths S1 < S2 (length), line tension gamma (force).
    edge_len : ndarray, shape (n - 1,)
        Rest edge lengths (length); the contact points sit at arclengths S1, S2 of the rest
        configuration.
    K : ndarray, shape (n, 2, 5, 2)
        Node-band storage, accumulated into: ``K[i, a, j - i + 2, b] +=
        d^2 (gamma lambda) / dx_{i,a} dx_{j,b}`` for the pairs of nodes ``|i - j| <= 1``
        coupled by the polygon edges (force / length).
    U : ndarray, shape (>= 5, n, 2)
        Zero on entry; rows 0..4 receive the node vectors ``T^T e_{P_0,x}``,
        ``T^T e_{P_0,z}``, ``T^T e_{P_{p+1},x}``, ``T^T e_{P_{p+1},z}`` (dimensionless) and
        ``T^T gA`` (length).
    C : ndarray, shape (>= 5, >= 5)
        Zero on entry; ``C[:5, :5]`` receives the symmetric coefficients, so that the
        Hessian is ``K + sum_rs C[r, s] U[r] U[s]^T``.

    Returns
    -------
    int
        5, or 0 (nothing written) when the cap is degenerate (contact points coincide, a
        non-finite geometry): the stepper then runs without the drop's stiffness.
    """
    n = x.shape[0]
    s = np.empty(n)
    s[0] = 0.0
    for i in range(n - 1):
        s[i + 1] = s[i] + edge_len[i]
    area, s1, s2, gamma = params[0], params[1], params[2], params[3]
    i1, w1 = locate_on_rod(s1, s)
    i2, w2 = locate_on_rod(s2, s)
    p = i2 - i1
    p0x = (1.0 - w1) * x[i1, 0] + w1 * x[i1 + 1, 0]
    p0z = (1.0 - w1) * x[i1, 1] + w1 * x[i1 + 1, 1]
    pex = (1.0 - w2) * x[i2, 0] + w2 * x[i2 + 1, 0]
    pez = (1.0 - w2) * x[i2, 1] + w2 * x[i2 + 1, 1]
    cx = pex - p0x
    cz = pez - p0z
    d = math.sqrt(cx * cx + cz * cz)
    a1 = area - wet_polygon_area(x, s, s1, s2)
    if not d > 0.0:
        return 0
    tau, sn, cs, _lam, kappa = cap_geometry(a1, d)
    ta, td = cap_tau_derivatives(tau, sn, cs, a1, d)
    l_dd = -sn * td
    l_da = -sn * ta
    l_aa = 2.0 * cs * ta / d
    if not (math.isfinite(l_dd) and math.isfinite(l_da) and math.isfinite(l_aa)
            and math.isfinite(kappa)):
        return 0
    gk = -0.5 * gamma * kappa
    # band: polygon edges P_k -> P_{k+1}; d2(1/2 P_k x P_{k+1}) / dP_k dP_{k+1} = R/2,
    # R = [[0, 1], [-1, 0]] (rows P_k), and R^T/2 for the transposed block
    for k in range(p + 1):
        na, ca, nb, cb = _polygon_point(k, p, i1, w1, i2, w2)
        ma, da, mb, db = _polygon_point(k + 1, p, i1, w1, i2, w2)
        for ii in range(2):
            ni = na if ii == 0 else nb
            ci = ca if ii == 0 else cb
            if ci == 0.0:
                continue
            for jj in range(2):
                mj = ma if jj == 0 else mb
                cj = da if jj == 0 else db
                if cj == 0.0:
                    continue
                c = gk * ci * cj
                _band_block_add(K, ni, mj, c, 1.0, -1.0)
                _band_block_add(K, mj, ni, c, -1.0, 1.0)
    # low-rank factors: the contact points' coordinates ...
    U[0, i1, 0] = 1.0 - w1
    U[0, i1 + 1, 0] = w1
    U[1, i1, 1] = 1.0 - w1
    U[1, i1 + 1, 1] = w1
    U[2, i2, 0] = 1.0 - w2
    U[2, i2 + 1, 0] = w2
    U[3, i2, 1] = 1.0 - w2
    U[3, i2 + 1, 1] = w2
    # ... and gA = dA0/dP, gA_k = J(P_{k+1} - P_{k-1}) / 2 with J(vx, vz) = (vz, -vx),
    # cyclic over the closed polygon, mapped to the nodes by T^T
    for k in range(p + 2):
        kn = k + 1 if k < p + 1 else 0
        kp = k - 1 if k > 0 else p + 1
        na, ca, nb, cb = _polygon_point(kn, p, i1, w1, i2, w2)
        qx = ca * x[na, 0] + cb * x[nb, 0]
        qz = ca * x[na, 1] + cb * x[nb, 1]
        na, ca, nb, cb = _polygon_point(kp, p, i1, w1, i2, w2)
        qx -= ca * x[na, 0] + cb * x[nb, 0]
        qz -= ca * x[na, 1] + cb * x[nb, 1]
        gx = 0.5 * qz
        gz = -0.5 * qx
        na, ca, nb, cb = _polygon_point(k, p, i1, w1, i2, w2)
        U[4, na, 0] += ca * gx
        U[4, na, 1] += ca * gz
        if cb != 0.0:
            U[4, nb, 0] += cb * gx
            U[4, nb, 1] += cb * gz
    # coefficients in the basis (P_0x, P_0z, P_ex, P_ez, gA)
    ux = cx / d
    uz = cz / d
    gd = np.empty(4)
    gd[0] = -ux
    gd[1] = -uz
    gd[2] = ux
    gd[3] = uz
    # Hd = [[Pu, -Pu], [-Pu, Pu]], Pu = (I - u u^T) / d
    pu = np.empty((2, 2))
    pu[0, 0] = (1.0 - ux * ux) / d
    pu[0, 1] = -ux * uz / d
    pu[1, 0] = pu[0, 1]
    pu[1, 1] = (1.0 - uz * uz) / d
    for r in range(4):
        for c in range(r, 4):
            sg = 1.0 if (r < 2) == (c < 2) else -1.0
            C[r, c] = gamma * (l_dd * gd[r] * gd[c] + cs * sg * pu[r % 2, c % 2])
            C[c, r] = C[r, c]
        C[r, 4] = -gamma * l_da * gd[r]
        C[4, r] = C[r, 4]
    C[4, 4] = gamma * l_aa
    # closing chord P_{p+1} -> P_0 of -gamma kappa HA: R/2 in rows P_{p+1}, columns P_0
    C[2, 1] += gk
    C[3, 0] -= gk
    C[1, 2] += gk
    C[0, 3] -= gk
    return CAPILLARY_RANK


def stiffness_dense(K, U, C, k):
    """Dense ``(2n, 2n)`` matrix ``K + U^T C U`` of a stiffness hook's output (tests,
    diagnostics), coordinates ordered ``(x_0, z_0, x_1, ...)``."""
    n = K.shape[0]
    H = np.zeros((2 * n, 2 * n))
    for i in range(n):
        for o in range(5):
            j = i + o - 2
            if 0 <= j < n:
                H[2 * i:2 * i + 2, 2 * j:2 * j + 2] += K[i, :, o, :]
    Uf = U[:k].reshape(k, 2 * n)
    return H + Uf.T @ C[:k, :k] @ Uf
