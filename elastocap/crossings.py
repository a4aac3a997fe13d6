"""Where a trajectory leaves the model's validity: rod self-crossings, interface crossings.

The paper's model has no rod-rod contact and lets the drop's interface pass through the
rod; :func:`first_crossing_frames` finds, on a sequence of frames, the first frame where
the rod crosses itself and the first where the circular-cap interface crosses the rod.
One compiled pass over all frames: per frame, the interface is drawn with
``INTERFACE_POINTS`` points from the cap half-angle of
:func:`elastocap.drop.capillary_energy_and_gradient` (the same arc as
:func:`elastocap.geometry.arc_points`), and the crossing test is that of
:func:`elastocap.geometry.count_crossings` (touching end points do not count), run
only on the segment pairs whose bounding boxes overlap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from elastocap.drop import capillary_energy_and_gradient, locate_on_rod
from elastocap.geometry import segments_cross

__all__ = [
    "INTERFACE_POINTS",
    "InterfaceTouch",
    "first_crossing_frames",
    "interface_crossings",
    "locate_interface_touch",
]

#: Points on the drawn interface (its ends sit on the rod and are not tested).
INTERFACE_POINTS = 80


@numba.njit(cache=True)
def _point_at(x, s_nodes, s):
    """Position at arclength s on the polyline (linear interpolation, clipped to the ends)."""
    i, w = locate_on_rod(s, s_nodes)
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


#: Segments per block of the bounding-box culling in :func:`_any_crossing`.  With 8, a rod
#: of 100 edges far from touching itself needs 1.3e3 block tests and ~2e2 exact segment
#: tests instead of 5e3 exact tests (measured: supp-fig5, 1062 frames: 35 ms -> 3 ms).
_BLOCK = 8


@numba.njit(cache=True)
def _segment_boxes(b, box, bbox):
    """Bounding boxes of the segments of polyline b (k, 2) into ``box`` (k-1, 4) as (xmin,
    xmax, zmin, zmax), and of blocks of ``_BLOCK`` consecutive segments into ``bbox``."""
    m = b.shape[0] - 1
    for j in range(m):
        box[j, 0] = min(b[j, 0], b[j + 1, 0])
        box[j, 1] = max(b[j, 0], b[j + 1, 0])
        box[j, 2] = min(b[j, 1], b[j + 1, 1])
        box[j, 3] = max(b[j, 1], b[j + 1, 1])
    nb = (m + _BLOCK - 1) // _BLOCK
    for J in range(nb):
        j0 = J * _BLOCK
        j1 = min(j0 + _BLOCK, m)
        bbox[J, 0] = box[j0, 0]
        bbox[J, 1] = box[j0, 1]
        bbox[J, 2] = box[j0, 2]
        bbox[J, 3] = box[j0, 3]
        for j in range(j0 + 1, j1):
            bbox[J, 0] = min(bbox[J, 0], box[j, 0])
            bbox[J, 1] = max(bbox[J, 1], box[j, 1])
            bbox[J, 2] = min(bbox[J, 2], box[j, 2])
            bbox[J, 3] = max(bbox[J, 3], box[j, 3])


@numba.njit(cache=True)
def _crossing_pairs(a, b, same, skip_a0, skip_a1, box, bbox, out):
    """The crossings of :func:`elastocap.geometry.count_crossings(a, b, same, skip_a0,
    skip_a1) <elastocap.geometry.count_crossings>`, testing only the segment pairs whose
    bounding boxes overlap: writes the pairs (segment of a, segment of b) into ``out``
    (m, 2), stopping once it is full; returns how many it wrote.

    ``box`` and ``bbox`` hold the boxes of b's segments (:func:`_segment_boxes`).  A pair of
    segments with disjoint boxes cannot cross; the exact test on the others is the same
    arithmetic as ``count_crossings``, so the answer is the same except where that test is
    decided by round-off alone (segments collinear to machine precision, whose computed
    crossing parameters are then arbitrary), which this one reports as no crossing.
    """
    mb = b.shape[0] - 1
    nb = (mb + _BLOCK - 1) // _BLOCK
    m = 0
    for i in range(max(skip_a0, 0), min(a.shape[0] - 1, skip_a1)):
        ax, az = a[i, 0], a[i, 1]
        rx, rz = a[i + 1, 0] - ax, a[i + 1, 1] - az
        x0 = min(a[i, 0], a[i + 1, 0])
        x1 = max(a[i, 0], a[i + 1, 0])
        z0 = min(a[i, 1], a[i + 1, 1])
        z1 = max(a[i, 1], a[i + 1, 1])
        j0 = i + 2 if same else 0
        for J in range(j0 // _BLOCK, nb):
            if (bbox[J, 0] > x1 or bbox[J, 1] < x0 or bbox[J, 2] > z1
                    or bbox[J, 3] < z0):
                continue
            for j in range(max(j0, J * _BLOCK), min(J * _BLOCK + _BLOCK, mb)):
                if box[j, 0] > x1 or box[j, 1] < x0 or box[j, 2] > z1 or box[j, 3] < z0:
                    continue
                bx, bz = b[j, 0], b[j, 1]
                if segments_cross(ax, az, rx, rz, bx, bz, b[j + 1, 0] - bx,
                                  b[j + 1, 1] - bz):
                    out[m, 0] = i
                    out[m, 1] = j
                    m += 1
                    if m == out.shape[0]:
                        return m
    return m


@numba.njit(cache=True)
def _any_crossing(a, b, same, skip_a0, skip_a1, box, bbox):
    """``count_crossings(a, b, same, skip_a0, skip_a1) > 0``, stopping at the first
    crossing (:func:`_crossing_pairs`)."""
    first = np.empty((1, 2), dtype=np.int64)
    return _crossing_pairs(a, b, same, skip_a0, skip_a1, box, bbox, first) > 0


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
    # the flags and bounds of the crossing tests are passed as np.bool_ / np.int64: a
    # constant argument of a call from compiled code is typed as a literal, and numba
    # compiles the callee once per literal value (here once for both tests)
    n_frames = positions.shape[0]
    n = positions.shape[1]
    k_rod = -1
    k_if = -1
    grad = np.zeros((n, 2))
    iface = np.empty((INTERFACE_POINTS, 2))
    box = np.empty((n - 1, 4))
    bbox = np.empty(((n - 1 + _BLOCK - 1) // _BLOCK, 4))
    for k in range(n_frames):
        if k_rod >= 0 and k_if >= 0:
            break
        pos = positions[k]
        _segment_boxes(pos, box, bbox)
        if k_rod < 0 and _any_crossing(pos, pos, np.bool_(True), np.int64(0), n, box,
                                        bbox):
            k_rod = k
        if k_if < 0 and k > 0:
            p = cap_params[k]
            _interface_points(pos, s_nodes, p[0], p[1], p[2], p[3], grad, iface)
            if _any_crossing(iface, pos, np.bool_(False), np.int64(1),
                             np.int64(INTERFACE_POINTS - 2), box, bbox):
                k_if = k
    return k_rod, k_if


#: Most crossings :func:`interface_crossings` lists on one frame.
MAX_LISTED_CROSSINGS = 64


@numba.njit(cache=True)
def _interface_crossings(x, s_nodes, cap, out_s):
    """Rod arclengths where the drawn interface crosses the rod (into ``out_s``); count."""
    n = x.shape[0]
    grad = np.zeros((n, 2))
    iface = np.empty((INTERFACE_POINTS, 2))
    box = np.empty((n - 1, 4))
    bbox = np.empty(((n - 1 + _BLOCK - 1) // _BLOCK, 4))
    pairs = np.empty((out_s.shape[0], 2), dtype=np.int64)
    _segment_boxes(x, box, bbox)
    _interface_points(x, s_nodes, cap[0], cap[1], cap[2], cap[3], grad, iface)
    m = _crossing_pairs(iface, x, np.bool_(False), np.int64(1),
                        np.int64(INTERFACE_POINTS - 2), box, bbox, pairs)
    for k in range(m):
        i, j = pairs[k, 0], pairs[k, 1]
        ax, az = iface[i, 0], iface[i, 1]
        rx, rz = iface[i + 1, 0] - ax, iface[i + 1, 1] - az
        sx, sz = x[j + 1, 0] - x[j, 0], x[j + 1, 1] - x[j, 1]
        qx, qz = x[j, 0] - ax, x[j, 1] - az
        # the rod parameter of segments_cross's test (same arithmetic)
        u = (qx * rz - qz * rx) / (rx * sz - rz * sx)
        out_s[k] = s_nodes[j] + u * (s_nodes[j + 1] - s_nodes[j])
    return m


def interface_crossings(x, s_nodes, cap) -> np.ndarray:
    """Arclengths S of the rod points where the drop's interface crosses the rod.

    The same test as :func:`first_crossing_frames` on one configuration: the interface
    drawn with ``INTERFACE_POINTS`` points, its end segments (on the rod) not tested.

    Parameters
    ----------
    x : ndarray, shape (n_nodes, 2)
    s_nodes : ndarray, shape (n_nodes,)
    cap : array_like, shape (4,)
        ``[area, S1, S2, gamma]``.

    Returns
    -------
    ndarray
        Sorted arclengths (at most MAX_LISTED_CROSSINGS), empty when there is no crossing.
    """
    out = np.empty(MAX_LISTED_CROSSINGS)
    m = _interface_crossings(np.ascontiguousarray(x, dtype=np.float64),
                             np.ascontiguousarray(s_nodes, dtype=np.float64),
                             np.asarray(cap, dtype=np.float64), out)
    return np.sort(out[:m])


@dataclass(frozen=True)
class InterfaceTouch:
    """Where and when the drop's interface first touches the rod between two states.

    Attributes
    ----------
    time : float
        Touch time, located by bisection on the linear interpolation between the two
        states (times ``t0`` < ``t1``).
    time_bracket : tuple of float
        (last time without a crossing, first time with one) of the bisection.
    s : float
        Arclength of the touched rod point: the mean of the crossings at the first
        crossing time of the bisection (they enclose the touch point).
    s_spread : float
        Distance in arclength between the outermost crossings there.
    """

    time: float
    time_bracket: tuple
    s: float
    s_spread: float


#: Bisection steps of :func:`locate_interface_touch` (the bracket shrinks to 2^-40 of the
#: interval: below round-off of the time for any step).
TOUCH_BISECTIONS = 40


def locate_interface_touch(x0, x1, t0, t1, s_nodes, cap) -> InterfaceTouch:
    """Locate the first touch between a state without crossing and one with a crossing.

    The configuration between the two is the linear interpolation of the node positions
    (for two consecutive time steps its distance to the integrator's trajectory is
    O(dt^2)); the touch is where :func:`interface_crossings` first finds a crossing.

    Raises
    ------
    ValueError
        When ``x0`` already has a crossing or ``x1`` has none.
    """
    x0 = np.asarray(x0, dtype=np.float64)
    x1 = np.asarray(x1, dtype=np.float64)
    if interface_crossings(x0, s_nodes, cap).size:
        raise ValueError(f"locate_interface_touch: the interface already crosses at t = {t0}")
    hit = interface_crossings(x1, s_nodes, cap)
    if not hit.size:
        raise ValueError(f"locate_interface_touch: no crossing at t = {t1}")
    lo, hi = 0.0, 1.0
    for _ in range(TOUCH_BISECTIONS):
        mid = 0.5 * (lo + hi)
        s = interface_crossings((1.0 - mid) * x0 + mid * x1, s_nodes, cap)
        if s.size:
            hi, hit = mid, s
        else:
            lo = mid
    ta, tb = t0 + lo * (t1 - t0), t0 + hi * (t1 - t0)
    return InterfaceTouch(0.5 * (ta + tb), (ta, tb), float(0.5 * (hit[0] + hit[-1])),
                          float(hit[-1] - hit[0]))
