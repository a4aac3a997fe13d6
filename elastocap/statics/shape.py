"""Shapes and measures of a static equilibrium: full rod, drop interface, admissibility.

The encapsulation measure (used identically by statics and dynamics) is the rod's total
turning divided by pi,

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
    "arc_points",
    "full_shape",
    "measures",
    "count_crossings",
    "encapsulation_measure",
]

# Points used to draw and to check crossings: 160 on the wet part resolve the crossing
# location to ~1% of Delta, which is what a flag needs (it is not used in any equation).
_N_WET_SAMPLES = 160
_N_ARC_SAMPLES = 120


def encapsulation_measure(theta_first: float, theta_last: float) -> float:
    """M = (theta(L) - theta(0)) / pi from the end tangent angles (radians)."""
    return (theta_last - theta_first) / math.pi


def arc_points(x1, x2, tau, n=_N_ARC_SAMPLES):
    """Points of the drop interface from x1 to x2, shape (n, 2).

    The arc bulges to the left of x1 -> x2 (the +q side) for tau > 0, with half-angle tau.
    Written without the radius so that a flat interface (tau -> 0) needs no special case.
    """
    x1 = np.asarray(x1, float)
    x2 = np.asarray(x2, float)
    chord = x2 - x1
    d = float(np.hypot(*chord))
    mid = 0.5 * (x1 + x2)
    if d == 0.0:
        return np.repeat(mid[None], n, axis=0)
    c = chord / d
    nrm = np.array([-c[1], c[0]])
    v = np.linspace(-1.0, 1.0, n)
    st = math.sin(tau)
    if abs(tau) < 1e-8:
        along = v
        across = 0.5 * tau * (1.0 - v * v)
    else:
        along = np.sin(tau * v) / st
        across = (np.cos(tau * v) - math.cos(tau)) / st
    return mid + 0.5 * d * (along[:, None] * c + across[:, None] * nrm)


def full_shape(problem, u, p=None, n_wet=_N_WET_SAMPLES):
    """The whole rod and the drop interface.

    Returns
    -------
    dict with
        ``rod`` : ndarray (m, 2), points from S = 0 to S = L (dry arm, wet part, dry arm);
        ``s`` : ndarray (m,), their arclengths;
        ``interface`` : ndarray (k, 2), the drop's free surface from x(S1) to x(S2).
    """
    S = problem.state(u, p)
    prm = S.params if getattr(S, "params", None) is not None else problem.params
    delta, L, center = prm["delta"], prm["L"], prm["center"]
    s1 = center - 0.5 * delta
    s2 = center + 0.5 * delta
    xi = np.linspace(-1.0, 1.0, n_wet)
    Mi = problem.interp_matrix(xi)
    wet = np.column_stack([Mi @ S.x, Mi @ S.z])
    t1 = np.array([math.cos(S.theta[0]), math.sin(S.theta[0])])
    t2 = np.array([math.cos(S.theta[-1]), math.sin(S.theta[-1])])
    parts = [wet]
    s_parts = [s1 + 0.5 * delta * (xi + 1.0)]
    if s1 > 0.0:
        parts.insert(0, (wet[0] - s1 * t1)[None])
        s_parts.insert(0, np.array([0.0]))
    if s2 < L:
        parts.append((wet[-1] + (L - s2) * t2)[None])
        s_parts.append(np.array([L]))
    rod = np.vstack(parts)
    s = np.concatenate(s_parts)
    iface = arc_points(wet[0], wet[-1], S.tau)
    return {"rod": rod, "s": s, "interface": iface}


@numba.njit(cache=True)
def segments_cross(ax, az, rx, rz, bx, bz, sx, sz):
    """Do the segments a + t r and b + u s (0 < t, u < 1) cross properly?

    Touching end points (t or u within 1e-9 of 0 or 1) and parallel segments do not count.
    """
    den = rx * sz - rz * sx
    if den == 0.0:
        return False
    qx, qz = bx - ax, bz - az
    t = (qx * sz - qz * sx) / den
    u = (qx * rz - qz * rx) / den
    return 1e-9 < t < 1.0 - 1e-9 and 1e-9 < u < 1.0 - 1e-9


@numba.njit(cache=True)
def count_crossings(a, b, same, skip_a0, skip_a1):
    """Proper crossings of the segments of polyline a (m, 2) with those of b (k, 2).

    With ``same`` (a is b) adjacent segments are not tested; segments of a with index below
    ``skip_a0`` or from ``skip_a1`` on are skipped (e.g. the ends of an interface that start
    on the rod). Touching end points (within 1e-9 of a segment's length) do not count.
    """
    count = 0
    for i in range(max(skip_a0, 0), min(a.shape[0] - 1, skip_a1)):
        ax, az = a[i, 0], a[i, 1]
        rx, rz = a[i + 1, 0] - ax, a[i + 1, 1] - az
        j0 = i + 2 if same else 0
        for j in range(j0, b.shape[0] - 1):
            bx, bz = b[j, 0], b[j, 1]
            if segments_cross(ax, az, rx, rz, bx, bz, b[j + 1, 0] - bx, b[j + 1, 1] - bz):
                count += 1
    return count


def measures(problem, u, p=None) -> dict[str, float]:
    """Observables recorded at every point of a branch.

    Keys: ``measure`` (encapsulation measure M), ``energy``, ``tip_angle`` (theta at S = L,
    radians, in the gauge where the chord of a symmetric shape is horizontal),
    ``asymmetry`` (mean tangent angle on the wet part: 0 for a mirror-symmetric shape, of
    opposite signs for mirror images),
    ``cap_angle`` (phi), ``chord`` (d), ``end_distance`` (|x(L) - x(0)| / L), ``omega``
    (the unfolding multiplier: zero at a solution), ``rod_crossings`` and
    ``interface_crossings`` (counts of self-crossings of the rod and of crossings of the
    drop interface with the rod, from the drawn shape), ``admissible`` (1 when both are 0
    and |phi| < 2 pi).
    """
    S = problem.state(u, p)
    shp = full_shape(problem, u, p)
    rod = shp["rod"]
    iface = shp["interface"]
    rod_x = count_crossings(rod, rod, True, 0, len(rod))
    # the interface starts and ends on the rod: skip its first and last segments
    if_x = count_crossings(iface, rod, False, 1, len(iface) - 2)
    L = (S.params if getattr(S, "params", None) is not None else problem.params)["L"]
    end = float(np.hypot(*(rod[-1] - rod[0])))
    adm = float(rod_x == 0 and if_x == 0 and abs(S.tau) < math.pi)
    return {
        "measure": encapsulation_measure(S.theta[0], S.theta[-1]),
        "energy": problem.energy(u, p),
        "tip_angle": float(S.theta[-1]),
        "cap_angle": 2.0 * S.tau,
        "chord": S.d,
        "end_distance": end / L,
        "asymmetry": float(0.5 * (problem.wh @ S.theta)),
        "omega": float(u[-1]),
        "rod_crossings": float(rod_x),
        "interface_crossings": float(if_x),
        "admissible": adm,
    }
