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

import numpy as np

from elastocap.geometry import (  # noqa: F401  (arc_points, count_crossings: re-exported)
    arc_points,
    count_crossings,
    encapsulation_measure,
)

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
    head, tail = int(s1 > 0.0), int(s2 < L)
    rod = np.empty((n_wet + head + tail, 2))
    s = np.empty(n_wet + head + tail)
    wet = rod[head: head + n_wet]
    np.matmul(problem.uniform_interp_matrix(n_wet), np.column_stack([S.x, S.z]), out=wet)
    s[head: head + n_wet] = np.linspace(s1, s2, n_wet)
    if head:  # the straight dry arm [0, S1], tangent to the wet part at S1
        rod[0, 0] = wet[0, 0] - s1 * math.cos(S.theta[0])
        rod[0, 1] = wet[0, 1] - s1 * math.sin(S.theta[0])
        s[0] = 0.0
    if tail:  # ... and [S2, L]
        rod[-1, 0] = wet[-1, 0] + (L - s2) * math.cos(S.theta[-1])
        rod[-1, 1] = wet[-1, 1] + (L - s2) * math.sin(S.theta[-1])
        s[-1] = L
    iface = arc_points(wet[0], wet[-1], S.tau)
    return {"rod": rod, "s": s, "interface": iface}


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
