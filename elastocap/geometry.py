"""Geometry of a rod shape, once for the whole model: the turning (encapsulation) measure,
arclength, the drop interface's arc, and crossing tests (the admissibility of a shape).

Used by the statics (``elastocap.statics``, ``elastocap.strip``), the impact run and its
criteria (``elastocap.impact``, ``elastocap.criteria``, ``elastocap.crossings``) and the
figures.  Polylines are arrays (n, 2) of (x, z) points, S = 0 first.

The encapsulation measure is the rod's total turning divided by pi,

    M = (theta(L) - theta(0)) / pi,

0 for a flat rod, 1 when the two ends are antiparallel (a U around the drop), 2 for a rod
whose ends have come round to their starting direction (a closed loop). It is positive when
the rod curls toward the drop side.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = [
    "arc_offsets",
    "arc_points",
    "arclength",
    "count_crossings",
    "encapsulation_measure",
    "proper_crossing",
    "segments_cross",
    "turning_angles",
    "turning_from",
    "turning_measure",
    "turning_measures",
]

#: Points on a drawn interface arc by default.
_N_ARC_SAMPLES = 120


def encapsulation_measure(theta_first: float, theta_last: float) -> float:
    """M = (theta(L) - theta(0)) / pi from the end tangent angles (radians)."""
    return (theta_last - theta_first) / math.pi


def arc_offsets(tau, v):
    """The interface's arc in the frame of its chord: (along, across) at the samples v in
    [-1, 1] of an arc of half-angle tau, both in units of the half-chord.

    The point at v is mid + d/2 (along c + across n) with c the unit chord x1 -> x2, n = (-c_z,
    c_x) and d the chord's length; v = -1 and 1 are the ends. Written without the radius,
    and the offset across as the product 2 sin(tau (1 + v) / 2) sin(tau (1 - v) / 2) /
    sin(tau) (the difference of cosines loses its digits as tau -> 0), so that a nearly flat
    interface keeps its digits; |tau| < 1e-8 takes the leading order (the parabola, exact
    to O(tau^2) relative). tau and v broadcast against each other (numpy arrays or
    floats), so one call draws the arcs of many frames (``tau[:, None]``).
    """
    tau = np.asarray(tau, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        st = np.sin(tau)
        flat = np.abs(tau) < 1e-8
        along = np.where(flat, v, np.sin(tau * v) / st)
        # cos(tau v) - cos(tau) as a product: the difference loses every digit for small tau
        across = np.where(flat, 0.5 * tau * (1.0 - v * v),
                          2.0 * np.sin(0.5 * tau * (1.0 + v)) * np.sin(0.5 * tau * (1.0 - v)) / st)
    return along, across


def arc_points(x1, x2, tau, n=_N_ARC_SAMPLES):
    """Points of the drop interface from x1 to x2, shape (n, 2).

    The arc bulges to the left of x1 -> x2 (the +q side) for tau > 0, with half-angle tau
    (:func:`arc_offsets`).
    """
    x1x, x1z = float(x1[0]), float(x1[1])
    x2x, x2z = float(x2[0]), float(x2[1])
    cx, cz = x2x - x1x, x2z - x1z
    d = math.hypot(cx, cz)
    mx, mz = 0.5 * (x1x + x2x), 0.5 * (x1z + x2z)
    out = np.empty((n, 2))
    if d == 0.0:
        out[:, 0] = mx
        out[:, 1] = mz
        return out
    cx, cz = cx / d, cz / d
    along, across = arc_offsets(float(tau), _unit_samples(n))
    hd = 0.5 * d
    # mid + d/2 (along c + across nrm), nrm = (-c_z, c_x)
    out[:, 0] = mx + hd * (along * cx - across * cz)
    out[:, 1] = mz + hd * (along * cz + across * cx)
    return out


_UNIT_SAMPLES: dict = {}


def _unit_samples(n: int) -> np.ndarray:
    """``np.linspace(-1, 1, n)``, read-only and cached (arcs are drawn at every point of
    every branch)."""
    v = _UNIT_SAMPLES.get(n)
    if v is None:
        v = np.linspace(-1.0, 1.0, n)
        v.setflags(write=False)
        _UNIT_SAMPLES[n] = v
    return v


def turning_measure(x: np.ndarray) -> float:
    """M = (theta(L) - theta(0)) / pi of a polyline (n, 2): the summed turning angles
    (:func:`turning_measures` of one frame)."""
    return float(turning_measures(np.asarray(x, dtype=np.float64)[None])[0])


def arclength(x: np.ndarray, length: float | None) -> np.ndarray:
    """Node arclengths (n + 1,) of a polyline, rescaled so the last one is ``length``."""
    seg = np.hypot(*np.diff(x, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if length is not None and s[-1] > 0.0:
        s *= length / s[-1]
    return s


def turning_from(x: np.ndarray, s_from: float, length: float) -> float:
    """(theta(L) - theta(s_from)) / pi: summed turning angles of the edges after s_from."""
    sn = arclength(x, length)
    k = int(np.clip(np.searchsorted(sn, s_from, side="right") - 1, 0, len(sn) - 2))
    e = np.diff(x[k:], axis=0)
    if len(e) < 2:
        return 0.0
    cross = e[:-1, 0] * e[1:, 1] - e[:-1, 1] * e[1:, 0]
    dot = np.sum(e[:-1] * e[1:], axis=1)
    return float(np.sum(np.arctan2(cross, dot)) / math.pi)


def proper_crossing(ax, az, rx, rz, bx, bz, sx, sz):
    """Do the segments a + t r and b + u s cross properly (0 < t, u < 1)? Returns (hit, u).

    Touching end points (t or u within 1e-9 of 0 or 1) and parallel segments (den = 0) do
    not count. Plain arithmetic on floats or on numpy arrays of segments (then call it under
    ``np.errstate(divide="ignore", invalid="ignore")``); :func:`segments_cross` is this
    function compiled.
    """
    den = rx * sz - rz * sx
    qx, qz = bx - ax, bz - az
    t = (qx * sz - qz * sx) / den
    u = (qx * rz - qz * rx) / den
    hit = (den != 0.0) & (1e-9 < t) & (t < 1.0 - 1e-9) & (1e-9 < u) & (u < 1.0 - 1e-9)
    return hit, u


#: :func:`proper_crossing` compiled for scalars (division by zero gives inf, as in numpy).
segments_cross = numba.njit(cache=True, error_model="numpy")(proper_crossing)


#: Segments of b per block of :func:`count_crossings`'s bounding-box pruning.
CROSSING_BLOCK = 16


@numba.njit(cache=True)
def count_crossings(a, b, same, skip_a0, skip_a1):
    """Proper crossings of the segments of polyline a (m, 2) with those of b (k, 2).

    With ``same`` (a is b) adjacent segments are not tested; segments of a with index below
    ``skip_a0`` or from ``skip_a1`` on are skipped (e.g. the ends of an interface that start
    on the rod). Touching end points (within 1e-9 of a segment's length) do not count.

    Segments with disjoint bounding boxes cannot cross and are not tested; b's segments
    are grouped in blocks of ``CROSSING_BLOCK`` whose bounding boxes are tested first, so a
    block that is nowhere near a segment of a costs one test (the count is the one of the
    pair-by-pair test: a block's box holds its segments' boxes).
    """
    nb = b.shape[0] - 1
    nblk = (nb + CROSSING_BLOCK - 1) // CROSSING_BLOCK if nb > 0 else 0
    box = np.empty((nblk, 4))
    for kb in range(nblk):
        k0 = kb * CROSSING_BLOCK
        k1 = min(k0 + CROSSING_BLOCK, nb)
        bx0 = bx1 = b[k0, 0]
        bz0 = bz1 = b[k0, 1]
        for k in range(k0 + 1, k1 + 1):
            bx0 = min(bx0, b[k, 0])
            bx1 = max(bx1, b[k, 0])
            bz0 = min(bz0, b[k, 1])
            bz1 = max(bz1, b[k, 1])
        box[kb, 0], box[kb, 1], box[kb, 2], box[kb, 3] = bx0, bx1, bz0, bz1
    count = 0
    for i in range(max(skip_a0, 0), min(a.shape[0] - 1, skip_a1)):
        ax, az = a[i, 0], a[i, 1]
        ex, ez = a[i + 1, 0], a[i + 1, 1]
        rx, rz = ex - ax, ez - az
        x0, x1 = min(ax, ex), max(ax, ex)
        z0, z1 = min(az, ez), max(az, ez)
        j0 = i + 2 if same else 0
        for kb in range(j0 // CROSSING_BLOCK, nblk):
            if (box[kb, 0] > x1 or box[kb, 1] < x0 or box[kb, 2] > z1
                    or box[kb, 3] < z0):
                continue
            for j in range(max(j0, kb * CROSSING_BLOCK), min(kb * CROSSING_BLOCK
                                                            + CROSSING_BLOCK, nb)):
                bx, bz = b[j, 0], b[j, 1]
                cx, cz = b[j + 1, 0], b[j + 1, 1]
                # segments with disjoint bounding boxes cannot cross: skip the exact test
                if ((bx > x1 and cx > x1) or (bx < x0 and cx < x0)
                        or (bz > z1 and cz > z1) or (bz < z0 and cz < z0)):
                    continue
                if segments_cross(ax, az, rx, rz, bx, bz, cx - bx, cz - bz)[0]:
                    count += 1
    return count


#: Frames per block of :func:`turning_angles` callers (bounds the temporaries: a block of
#: 1024 frames of 450 edges is 3.7 MB per array).
FRAME_BLOCK = 1024


def turning_angles(positions: np.ndarray) -> np.ndarray:
    """Signed turning angles (radians) at the interior nodes of each frame: ``arctan2(e_i x
    e_{i+1}, e_i * e_{i+1})`` (cross and dot products) of consecutive edges, shape
    (n_frames, n_nodes - 2).

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_nodes, 2)
    """
    e = np.diff(positions, axis=1)
    a, b = e[:, :-1], e[:, 1:]
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    dot = a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]
    return np.arctan2(cross, dot)


def turning_measures(positions: np.ndarray) -> np.ndarray:
    """M = (theta(L) - theta(0)) / pi of each frame (n_frames, n_nodes, 2): summed turns.

    Vectorised numpy (the sum of each row of :func:`turning_angles`, numpy's pairwise
    summation, as :func:`turning_measure`).  Not compiled: a numba version costs 0.9 s of
    compile in the first impact of a fresh install and saves 1-10 ms per impact (1062
    frames of 100 edges: 2.2 ms against 1.1 ms; 4001 frames of 450 edges: about 45 ms
    against 34 ms; measured: docs/guide/time-stepping.md, "Compile cost").
    """
    positions = np.asarray(positions, dtype=np.float64)
    out = np.empty(positions.shape[0])
    for k0 in range(0, positions.shape[0], FRAME_BLOCK):
        block = positions[k0:k0 + FRAME_BLOCK]
        out[k0:k0 + block.shape[0]] = np.sum(turning_angles(block), axis=1) / math.pi
    return out
