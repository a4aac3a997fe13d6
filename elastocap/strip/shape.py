"""Shapes and measures of a strip equilibrium: the whole strip, the drop, admissibility."""

from __future__ import annotations

import math

import numpy as np

from elastocap.geometry import arc_points, count_crossings
from elastocap.statics.spectral import lgl_interp_matrix

__all__ = [
    "lowest_point",
    "lowest_point_arclength",
    "shape_at",
    "strip_full_shape",
    "strip_measures",
]


def lowest_point(problem, u) -> float:
    """min z over the lifted part beyond the lift-off point (dense samples, length units).

    Negative when the strip goes through the ground (the free end or another part would
    touch down first: another contact topology, not handled by :class:`StripProblem`).
    The lift-off point and the first 5% of the dry lifted segment are excluded; there
    z ~ R (s - s_c)^3 / 6B > 0 (R > 0, the lift-off reaction).
    """
    s, _x, z = problem.interp(u)
    return float(np.min(z[s >= _near_lift_off(problem, u)]))


def _near_lift_off(problem, u) -> float:
    # Near s_c, z = R (s - s_c)^3 / 6B > 0 with R > 0 the lift-off reaction: a sign there is
    # set by the polynomial's wiggles at coarse N, not by a contact, so the first 5% of the
    # dry lifted segment is not searched for a touchdown.
    return float(u[-1]) + 0.05 * max(problem.s1 - float(u[-1]), 0.0) + 1e-12


def lowest_point_arclength(problem, u) -> float:
    """Arclength S of the lowest point of the lifted part beyond s_c (where it would land)."""
    s, _x, z = problem.interp(u)
    m = s >= _near_lift_off(problem, u)
    return float(s[m][np.argmin(z[m])])


def shape_at(problem, u, S) -> np.ndarray:
    """Positions (len(S), 2) of the equilibrium at arclengths S (flat part included;
    lift-off point at x = 0). Spectral interpolation on each segment."""
    S = np.atleast_1d(np.asarray(S, float))
    st = problem.state(u)
    out = np.zeros((S.size, 2))
    flat = S <= st.s_c
    out[flat, 0] = S[flat] - st.s_c
    for k, (sl, (a, ell)) in enumerate(zip(problem._slices(), problem.segments(u), strict=True)):
        m = (S > a) & (S <= a + ell) & ~flat if k else (S > a) & (S <= a + ell)
        if not m.any():
            continue
        xi = np.clip(2.0 * (S[m] - a) / ell - 1.0, -1.0, 1.0)
        Mi = lgl_interp_matrix(problem.Ns[k], xi)
        out[m, 0] = Mi @ st.x[sl]
        out[m, 1] = Mi @ st.z[sl]
        flat |= m
    return out


def strip_full_shape(problem, u, p=None) -> dict:
    """The whole strip (flat part + lifted part) and the drop interface.

    Returns dict with ``rod`` (m, 2) from S = 0 to S = L, ``s`` (m,) and ``interface``
    (k, 2); the lift-off point is at x = 0.
    """
    problem._with_p(p)
    s, x, z = problem.interp(u)
    s_c = float(u[-1])
    rod = np.vstack([[[-s_c, 0.0]], np.column_stack([x, z])])
    ss = np.concatenate([[0.0], s])
    # drop contact points and cap half-angle
    st = problem.state(u)
    sl = problem._slices()[1]
    wet_u = np.concatenate([st.theta[sl], [0.0]])
    tau = problem._wet.state(wet_u).tau
    p1 = np.array([st.x[sl][0], st.z[sl][0]])
    p2 = np.array([st.x[sl][-1], st.z[sl][-1]])
    return {"rod": rod, "s": ss, "interface": arc_points(p1, p2, tau)}


def strip_measures(problem, u, p=None) -> dict[str, float]:
    """Observables recorded along a strip branch.

    Keys: ``energy`` and its parts (``bending``, ``gravity``, ``capillary``),
    ``lift_off`` s_c, ``lifted_length`` L - s_c, ``dry_length`` S1 - s_c, ``measure``
    (theta(L)/pi: total turning; the flat part has theta = 0), ``tip_angle``,
    ``end_height`` z(L), ``lowest_point`` (see :func:`lowest_point`), ``encapsulation``
    x(S = L - x) - x(L) (> 0: the free end lies left of the impact centre, the paper's
    criterion, Methods), ``reaction`` (vertical point reaction at s_c, force units),
    ``cap_angle`` phi, ``chord`` d, ``rod_crossings``, ``interface_crossings``,
    ``admissible`` (1 when the strip is above the ground and nothing crosses).
    """
    problem._with_p(p)
    prm = problem.params
    parts = problem.energy_parts(u)
    st = problem.state(u)
    sl = problem._slices()[1]
    wet_u = np.concatenate([st.theta[sl], [0.0]])
    ws = problem._wet.state(wet_u)
    # x at the impact centre S = L - x: the middle (xi = 0) of the wet segment
    Mi = lgl_interp_matrix(problem.Ns[1], np.array([0.0]))
    x_mid = float((Mi @ st.x[sl])[0])
    shp = strip_full_shape(problem, u)
    rod, iface = shp["rod"], shp["interface"]
    rod_x = count_crossings(rod, rod, True, 0, len(rod))
    if_x = count_crossings(iface, rod, False, 1, len(iface) - 2)
    low = lowest_point(problem, u)
    out = {
        "energy": float(sum(parts.values())),
        "bending": parts["bending"],
        "gravity": parts["gravity"],
        "capillary": parts["capillary"],
        "lift_off": float(u[-1]),
        "lifted_length": prm["L"] - float(u[-1]),
        "dry_length": problem.s1 - float(u[-1]),
        "measure": float(st.theta[-1] / math.pi),
        "tip_angle": float(st.theta[-1]),
        "end_height": float(st.z[-1]),
        "lowest_point": low,
        "lowest_point_s": lowest_point_arclength(problem, u),
        "encapsulation": x_mid - float(st.x[-1]),
        "reaction": prm["q"] * (prm["L"] - float(u[-1])) + prm["F"],
        "cap_angle": 2.0 * ws.tau,
        "chord": ws.d,
        "rod_crossings": float(rod_x),
        "interface_crossings": float(if_x),
        "admissible": float(low >= -1e-9 and rod_x == 0 and if_x == 0 and abs(ws.tau) < math.pi),
    }
    if problem.constrained:
        out["couple"] = float(u[problem.M])
    return out
