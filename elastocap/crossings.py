"""Where a trajectory leaves the model's validity: rod self-crossings, interface crossings.

The paper's model has no rod-rod contact and lets the drop's interface pass through the
rod; :func:`first_crossing_frames` finds, on a sequence of frames, the first frame where
the rod crosses itself and the first where the circular-cap interface crosses the rod.
Per frame, the interface is drawn with ``INTERFACE_POINTS`` points from the cap
half-angle of :func:`elastocap.drop.capillary_energy_and_gradient` (the arc of
:func:`elastocap.geometry.arc_offsets`), and the crossing test is
:func:`elastocap.geometry.proper_crossing` (touching end points do not count), run only on
the segment pairs whose bounding boxes overlap.

Vectorised numpy over blocks of frames, not compiled: a compiled detector cost 2 s of
compile in the first run of a fresh install (measured: docs/guide/time-stepping.md,
"Compile cost").  What keeps the number of segment pairs small:

* a polyline whose edge directions span less than pi (tangent angles, unwrapped, within
  an interval shorter than pi) is monotone along the bisecting direction and cannot cross
  itself; so two segments i < j are tested only when the edges i..j span pi or more
  (checked per frame, then per pair of blocks of ``_BLOCK`` segments);
* pairs of blocks whose bounding boxes do not overlap are skipped, then pairs of segments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from elastocap.drop import capillary_energy_and_gradient, locate_on_rod
from elastocap.geometry import FRAME_BLOCK, arc_offsets, proper_crossing, turning_angles

__all__ = [
    "INTERFACE_POINTS",
    "InterfaceTouch",
    "first_crossing_frames",
    "interface_crossings",
    "locate_interface_touch",
]

#: Points on the drawn interface (its ends sit on the rod and are not tested).
INTERFACE_POINTS = 80

#: Frames in the first block of :func:`first_crossing_frames`, doubled from block to block
#: up to ``FRAME_BLOCK``: a crossing early in a run is found without testing every frame,
#: and a run without one is tested in a few large blocks.
_FIRST_FRAMES = 64

#: Segments per block of the bounding-box culling.
_BLOCK = 8

#: A sub-polyline whose edge directions span less than pi - _ANGLE_MARGIN (radians) is not
#: tested for self-crossings: it is monotone along its bisecting direction, with every
#: edge advancing by at least |e| sin(_ANGLE_MARGIN / 2), far above round-off (the
#: angles themselves are accurate to ~1e-13 after a cumulative sum over 10^3 edges).
_ANGLE_MARGIN = 1e-6


def _interface_points(x, s_nodes, caps):
    """The drawn interfaces (F, INTERFACE_POINTS, 2) of frames x (F, n, 2) with capillary
    parameters caps (F, 4) = [area, S1, S2, gamma] (:func:`elastocap.geometry.arc_offsets`
    at the samples of :func:`elastocap.geometry.arc_points`)."""
    nf, n = x.shape[0], x.shape[1]
    tau = np.empty(nf)
    grad = np.zeros((n, 2))
    ends = np.empty((2, nf, 2))
    for k in range(nf):
        # the cap half-angle (the compiled kernel the capillary force uses)
        tau[k] = capillary_energy_and_gradient(x[k], s_nodes, caps[k, 1], caps[k, 2],
                                               caps[k, 0], caps[k, 3], grad)[1]
        for e in range(2):
            i, w = locate_on_rod(caps[k, 1 + e], s_nodes)
            ends[e, k] = (1.0 - w) * x[k, i] + w * x[k, i + 1]
    (x1x, x1z), (x2x, x2z) = ends[0].T, ends[1].T
    cx = x2x - x1x
    cz = x2z - x1z
    d = np.sqrt(cx * cx + cz * cz)
    mx = 0.5 * (x1x + x2x)
    mz = 0.5 * (x1z + x2z)
    k = INTERFACE_POINTS
    along, across = arc_offsets(tau[:, None], np.linspace(-1.0, 1.0, k))
    with np.errstate(divide="ignore", invalid="ignore"):
        ux = (cx / d)[:, None]
        uz = (cz / d)[:, None]
        hd = (0.5 * d)[:, None]
        out = np.empty((nf, k, 2))
        out[:, :, 0] = mx[:, None] + hd * (along * ux - across * uz)
        out[:, :, 1] = mz[:, None] + hd * (along * uz + across * ux)
    # a chord of length 0: every point at the middle
    out[d == 0.0] = np.stack([mx, mz], axis=1)[d == 0.0][:, None, :]
    return out


def _blocks(v, reduce):
    """``reduce`` (np.minimum or np.maximum) of the points v (F, n) of each block of
    ``_BLOCK`` segments (points 8 K .. 8 K + 8), (F, nb); the last block padded with the
    last point."""
    nf, n = v.shape
    nb = -(-(n - 1) // _BLOCK)
    w = np.empty((nf, nb * _BLOCK + 1))
    w[:, :n] = v
    w[:, n:] = v[:, -1:]
    last = w[:, _BLOCK::_BLOCK]  # the first point of the next block closes a block
    w = w[:, :nb * _BLOCK].reshape(nf, nb, _BLOCK)
    # halving by elementwise calls (a reduction over a short last axis is 5x slower)
    k = _BLOCK
    while k > 1:
        k //= 2
        w = reduce(w[:, :, :k], w[:, :, k:2 * k])
    return reduce(w[:, :, 0], last)


def _boxes(p):
    """The coordinates (x, z), each (F, n) and contiguous, of polylines p (F, n, 2), and the
    boxes (xlo, xhi, zlo, zhi) of their blocks of ``_BLOCK`` consecutive segments, each
    (F, nb)."""
    px, pz = np.ascontiguousarray(p[:, :, 0]), np.ascontiguousarray(p[:, :, 1])
    return (px, pz), (_blocks(px, np.minimum), _blocks(px, np.maximum),
                      _blocks(pz, np.minimum), _blocks(pz, np.maximum))


def _segment_box(coords, f, i):
    """The boxes (xlo, xhi, zlo, zhi) of segments i of frames f."""
    px, pz = coords
    k = f * px.shape[1] + i
    x0, x1, z0, z1 = np.take(px, k), np.take(px, k + 1), np.take(pz, k), np.take(pz, k + 1)
    return np.minimum(x0, x1), np.maximum(x0, x1), np.minimum(z0, z1), np.maximum(z0, z1)


def _overlap(a, b):
    """Do the boxes a and b (xlo, xhi, zlo, zhi) overlap (closed boxes: touching ones
    do)?"""
    return (a[0] <= b[1]) & (b[0] <= a[1]) & (a[2] <= b[3]) & (b[2] <= a[3])


def _take(box, f, i):
    """The boxes at (frame f, block i) (flat indices: faster than a pair of index
    arrays)."""
    k = f * box[0].shape[1] + i
    return tuple(np.take(v, k) for v in box)


def _expand(f, K, L):
    """The segment pairs (f, i, j) of the block pairs (f, K, L), _BLOCK**2 each."""
    r = np.arange(_BLOCK)
    i = (K[:, None, None] * _BLOCK + r[None, :, None])
    j = (L[:, None, None] * _BLOCK + r[None, None, :])
    shape = (K.shape[0], _BLOCK, _BLOCK)
    return (np.broadcast_to(f[:, None, None], shape).ravel(),
            np.broadcast_to(i, shape).ravel(), np.broadcast_to(j, shape).ravel())


def _cross(a, b, f, i, j):
    """Proper crossings (hit, u) of segment i of polylines a with segment j of b in frames f
    (:func:`elastocap.geometry.proper_crossing` on arrays)."""
    ka = 2 * (f * a.shape[1] + i)  # flat indices of (f, i, 0) and (f, j, 0)
    kb = 2 * (f * b.shape[1] + j)
    a, b = a.reshape(-1), b.reshape(-1)
    ax, az = a[ka], a[ka + 1]
    bx, bz = b[kb], b[kb + 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        return proper_crossing(ax, az, a[ka + 2] - ax, a[ka + 3] - az,
                               bx, bz, b[kb + 2] - bx, b[kb + 3] - bz)


def _segment_pairs(acoords, bcoords, f, i, j, ma, mb, same):
    """The pairs (f, i, j) that index segments of both, are not adjacent (``same``) and
    whose boxes overlap."""
    ok = (i < ma) & (j < mb)
    if same:
        ok &= j >= i + 2
    f, i, j = f[ok], i[ok], j[ok]
    ok = _overlap(_segment_box(acoords, f, i), _segment_box(bcoords, f, j))
    return f[ok], i[ok], j[ok]


def _self_crossing(p):
    """Whether each polyline of p (F, n, 2) crosses itself (adjacent segments not tested)."""
    nf, m = p.shape[0], p.shape[1] - 1
    out = np.zeros(nf, dtype=bool)
    if m < 3:
        return out
    # tangent angle of each edge, unwrapped (edge 0 at 0)
    theta = np.zeros((nf, m))
    np.cumsum(turning_angles(p), axis=1, out=theta[:, 1:])
    wide = np.ptp(theta, axis=1) >= math.pi - _ANGLE_MARGIN
    if not wide.any():
        return out
    frames = np.flatnonzero(wide)
    p, theta = p[frames], theta[frames]
    coords, bbox = _boxes(p)
    nb = bbox[0].shape[1]
    # the directions of the edges of each block (and of the next block's first edge: a
    # wider span only adds candidates), as a polyline of m + 1 values
    theta = np.concatenate([theta, theta[:, -1:]], axis=1)
    tmax = _blocks(theta, np.maximum)
    tmin = _blocks(theta, np.minimum)
    # block pairs (K, K + d): the span of the edge directions over blocks K..K+d, grown
    # with d, and the overlap of the two blocks' boxes
    cand = []
    run_max, run_min = tmax, tmin
    for d in range(nb):
        if d:
            run_max = np.maximum(run_max[:, :-1], tmax[:, d:])
            run_min = np.minimum(run_min[:, :-1], tmin[:, d:])
        keep = ((run_max - run_min >= math.pi - _ANGLE_MARGIN)
                & _overlap([v[:, :nb - d] for v in bbox], [v[:, d:] for v in bbox]))
        f, K = np.nonzero(keep)
        cand.append((f, K, K + d))
    f, i, j = _expand(*(np.concatenate(c) for c in zip(*cand, strict=True)))
    f, i, j = _segment_pairs(coords, coords, f, i, j, m, m, True)
    hit, _u = _cross(p, p, f, i, j)
    out[frames[f[hit]]] = True
    return out


def _interface_pairs(x, iface):
    """The candidate pairs (f, i, j) of interface segment i (1 .. INTERFACE_POINTS - 3:
    its end segments start on the rod) and rod segment j, boxes overlapping: blocks of
    the interface against blocks of the rod, then the segments of the interface blocks
    against the rod blocks, then the segments of both."""
    a = iface[:, 1:INTERFACE_POINTS - 1]  # the tested segments 1 .. k - 3, from 0 here
    acoords, ablk = _boxes(a)
    coords, blk = _boxes(x)
    ma, mb = a.shape[1] - 1, x.shape[1] - 1
    f, K, L = np.nonzero(_overlap([v[:, :, None] for v in ablk],
                                  [v[:, None, :] for v in blk]))
    # the segments of interface block K against rod block L
    r = np.arange(_BLOCK)
    i = (K[:, None] * _BLOCK + r).ravel()
    f, L = np.repeat(f, _BLOCK), np.repeat(L, _BLOCK)
    ok = i < ma
    f, i, L = f[ok], i[ok], L[ok]
    ok = _overlap(_segment_box(acoords, f, i), _take(blk, f, L))
    f, i, L = f[ok], i[ok], L[ok]
    j = (L[:, None] * _BLOCK + r).ravel()
    f, i = np.repeat(f, _BLOCK), np.repeat(i, _BLOCK)
    f, i, j = _segment_pairs(acoords, coords, f, i, j, ma, mb, False)
    return f, i + 1, j


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
    positions = np.ascontiguousarray(positions, dtype=np.float64)
    s_nodes = np.ascontiguousarray(s_nodes, dtype=np.float64)
    cap_params = np.asarray(cap_params, dtype=np.float64)
    k_rod = k_if = -1
    k0, size = 0, _FIRST_FRAMES
    while k0 < positions.shape[0] and (k_rod < 0 or k_if < 0):
        x = positions[k0:k0 + size]
        if k_rod < 0:
            hit = np.flatnonzero(_self_crossing(x))
            if hit.size:
                k_rod = k0 + int(hit[0])
        if k_if < 0:
            a = max(1 - k0, 0)  # frame 0 is not tested
            iface = _interface_points(x[a:], s_nodes, cap_params[k0 + a:k0 + x.shape[0]])
            f, i, j = _interface_pairs(x[a:], iface)
            hit, _u = _cross(iface, x[a:], f, i, j)
            if hit.any():
                k_if = k0 + a + int(f[hit].min())
        k0, size = k0 + x.shape[0], min(2 * size, FRAME_BLOCK)
    return k_rod, k_if


#: Most crossings :func:`interface_crossings` lists on one frame.
MAX_LISTED_CROSSINGS = 64


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
        Sorted arclengths (at most MAX_LISTED_CROSSINGS: the first ones along the
        interface), empty when there is no crossing.
    """
    x = np.ascontiguousarray(x, dtype=np.float64)[None]
    s_nodes = np.ascontiguousarray(s_nodes, dtype=np.float64)
    iface = _interface_points(x, s_nodes, np.asarray(cap, dtype=np.float64)[None])
    f, i, j = _interface_pairs(x, iface)
    hit, u = _cross(iface, x, f, i, j)
    i, j, u = i[hit], j[hit], u[hit]
    first = np.lexsort((j, i))[:MAX_LISTED_CROSSINGS]
    j, u = j[first], u[first]
    return np.sort(s_nodes[j] + u * (s_nodes[j + 1] - s_nodes[j]))


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
