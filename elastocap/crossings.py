"""Where a trajectory leaves the model's validity: rod self-crossings, interface crossings.

The paper's model has no rod-rod contact and lets the drop's interface pass through the
rod; :func:`first_crossing_frames` finds, on a sequence of frames, the first frame where
the rod crosses itself and the first where the circular-cap interface crosses the rod.
One compiled pass over all frames: per frame, the interface is drawn with
``INTERFACE_POINTS`` points from the cap half-angle of
:func:`elastocap.drop.capillary_energy_and_gradient` (the same arc as
:func:`elastocap.statics.shape.arc_points`), and the crossing test is
:func:`elastocap.statics.shape.count_crossings` (touching end points do not count).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from elastocap.drop import _locate, capillary_energy_and_gradient
from elastocap.statics.shape import count_crossings

__all__ = ["INTERFACE_POINTS", "first_crossing_frames", "turning_measures"]

#: Points on the drawn interface (its ends sit on the rod and are not tested).
INTERFACE_POINTS = 80


@numba.njit(cache=True)
def _point_at(x, s_nodes, s):
    """Position at arclength s on the polyline (linear interpolation, clipped to the ends)."""
    i, w = _locate(s, s_nodes)
    return (1.0 - w) * x[i, 0] + w * x[i + 1, 0], (1.0 - w) * x[i, 1] + w * x[i + 1, 1]


@numba.njit(cache=True)
def _interface_points(x, s_nodes, area, s1, s2, gamma, grad, out):
    """Fill ``out`` (k, 2) with the interface arc from x(S1) to x(S2); ``grad`` is scratch."""
    _e, tau, _kappa = capillary_energy_and_gradient(x, s_nodes, s1, s2, area, gamma, grad)
    x1x, x1z = _point_at(x, s_nodes, s1)
    x2x, x2z = _point_at(x, s_nodes, s2)
    cx = x2x - x1x
    cz = x2z - x1z
    d = math.sqrt(cx * cx + cz * cz)
    mx = 0.5 * (x1x + x2x)
    mz = 0.5 * (x1z + x2z)
    k = out.shape[0]
    if d == 0.0:
        for j in range(k):
            out[j, 0] = mx
            out[j, 1] = mz
        return
    ux = cx / d
    uz = cz / d
    st = math.sin(tau)
    ct = math.cos(tau)
    for j in range(k):
        v = -1.0 + 2.0 * j / (k - 1)
        if abs(tau) < 1e-8:
            along = v
            across = 0.5 * tau * (1.0 - v * v)
        else:
            along = math.sin(tau * v) / st
            across = (math.cos(tau * v) - ct) / st
        out[j, 0] = mx + 0.5 * d * (along * ux - across * uz)
        out[j, 1] = mz + 0.5 * d * (along * uz + across * ux)


@numba.njit(cache=True)
def first_crossing_frames(positions, s_nodes, cap_params):
    """First frames where the rod crosses itself and where the interface crosses the rod.

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_nodes, 2)
        Node positions per frame.
    s_nodes : ndarray, shape (n_nodes,)
        Arclength of each node (length units).
    cap_params : ndarray, shape (n_frames, 4)
        The capillary effect's ``[area, S1, S2, gamma]`` in force at each frame.

    Returns
    -------
    k_rod, k_interface : int
        Frame indices, -1 where there is no crossing. The interface is not tested on
        frame 0 (the release state, where it rests on the straight rod's chord).
    """
    n_frames = positions.shape[0]
    n = positions.shape[1]
    k_rod = -1
    k_if = -1
    grad = np.zeros((n, 2))
    iface = np.empty((INTERFACE_POINTS, 2))
    for k in range(n_frames):
        if k_rod >= 0 and k_if >= 0:
            break
        pos = positions[k]
        if k_rod < 0 and count_crossings(pos, pos, True, 0, n) > 0:
            k_rod = k
        if k_if < 0 and k > 0:
            p = cap_params[k]
            _interface_points(pos, s_nodes, p[0], p[1], p[2], p[3], grad, iface)
            if count_crossings(iface, pos, False, 1, INTERFACE_POINTS - 2) > 0:
                k_if = k
    return k_rod, k_if


def turning_measures(positions: np.ndarray) -> np.ndarray:
    """M = (theta(L) - theta(0)) / pi of each frame (n_frames, n_nodes, 2): summed turns."""
    e = np.diff(positions, axis=1)
    cross = e[:, :-1, 0] * e[:, 1:, 1] - e[:, :-1, 1] * e[:, 1:, 0]
    dot = np.einsum("fik,fik->fi", e[:, :-1], e[:, 1:])
    return np.sum(np.arctan2(cross, dot), axis=1) / math.pi
