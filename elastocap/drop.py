"""The quasi-static 2D drop: a circular cap of fixed area pinned to two points of the rod.

Model (paper, supplementary S1, "Quasi-static reconstruction of the drop"): the fluid-air
interface is the arc of a circle joining the contact points x1 = x(S1) and x2 = x(S2); the
fluid region, bounded by that arc and the wet part of the rod S1 <= S <= S2, has the
prescribed area A. With A0 the signed area between the wet rod and the chord [x1, x2], the
cap area is A1 = A - A0 and its angle phi solves

    (phi - sin phi) / (8 sin^2(phi/2)) = A1 / d^2,      d = |x2 - x1|,   phi in (-2 pi, 2 pi),

then r = d / (2 sin(phi/2)), lambda = phi r and the capillary energy is gamma * lambda.

Sign conventions (used everywhere in elastocap)
------------------------------------------------
* The rod runs in the direction of increasing arclength S with unit tangent t; its normal
  q = (-e_y) x t is t turned by +90 degrees in the (x, z) plane (paper eq. [2a]). A flat rod
  along +x has q = +z.
* The drop sits on the +q side of the wet part (on top of a flat rod running along +x).
* A0 is the area of the polygon "wet rod from x1 to x2, then the chord back to x1", counted
  positive when that loop turns counterclockwise, i.e. when the wet rod bends away from the
  drop side's chord (a cup holding the drop). A1 = A - A0 is the area of the cap beyond the
  chord, on the +q side of the chord when positive.
* phi has the sign of A1: phi > 0 is a cap bulging to the drop side, phi < 0 (A1 < 0) a cap
  bulging toward the rod. The signed curvature of the interface is kappa = 2 sin(phi/2) / d
  (= 1/r), finite for a flat interface; the Laplace pressure in the drop is gamma * kappa.

Numerics
--------
The cap equation is solved in the half angle tau = phi/2 for |A1|/d^2 <= pi/8 (tau <= pi/2),
and in the complement sigma = pi - |tau| beyond, so that a nearly closed circle keeps full
relative precision in sin(tau) = sin(sigma), in r and in lambda. The Newton iteration runs on
the logarithm of the equation (well conditioned from 1e-300 to 1e300) inside a bracket, and
tiny |A1|/d^2 uses the inverted series. The numerator phi - sin(phi) uses its Taylor series
for small angles (no cancellation). Relative accuracy ~1e-15 in phi, r and lambda is checked
against mpmath over |A1|/d^2 from 1e-300 to 1e24 in the tests.

Derivatives: d(lambda) = cos(tau) dd + kappa dA1 (tension along the interface, Laplace
pressure), the identity behind the forces [6]-[8] of the paper. Every kernel here is a
numba ``njit(cache=True)`` function of plain floats and arrays, so statics and dynamics call
the same implementation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

__all__ = [
    "CapGeometry",
    "locate_on_rod",
    "cap_geometry",
    "cap_half_angle",
    "cap_ratio",
    "cap_tau_derivatives",
    "wet_polygon_area",
    "capillary_energy_and_gradient",
    "contact_angles",
]

_PI = math.pi
_HALF_PI = 0.5 * math.pi
# Below this |A1|/d^2 the series t = 6a - 28.8 a^3 + 46656/175 a^5 is exact to ~1e-17
# relative (the next term is O(a^7) with a coefficient of order 1e3).
_SERIES_LIMIT = 1e-3
# Newton stops when the step is below this fraction of the iterate: two ulps.
_NEWTON_RTOL = 4.0 * np.finfo(np.float64).eps
# 60 iterations: the safeguarded iteration converges quadratically in < 8 from our initial
# guesses; the cap only guards against a pathological input (e.g. NaN) looping forever.
_NEWTON_MAXIT = 60


@numba.njit(cache=True)
def _two_t_minus_sin(t):
    """Return 2t - sin(2t) without cancellation, for 0 <= t <= pi/2."""
    if t < 0.5:
        # Taylor series of y - sin y with y = 2t <= 1: terms y^(2k+1)/(2k+1)! alternate;
        # 10 terms reach 1/21! ~ 2e-20, below double precision relative to y^3/6.
        y = 2.0 * t
        y2 = y * y
        term = y * y2 / 6.0
        total = term
        for k in range(2, 12):
            term *= -y2 / ((2 * k) * (2 * k + 1))
            total += term
        return total
    return 2.0 * t - math.sin(2.0 * t)


@numba.njit(cache=True)
def _log_f_low(t):
    """log of f(t) = (2t - sin 2t) / (8 sin^2 t) and its t-derivative, for 0 < t <= pi/2."""
    h = _two_t_minus_sin(t)
    s = math.sin(t)
    val = math.log(h) - 2.0 * math.log(s) - math.log(8.0)
    der = 4.0 * s * s / h - 2.0 * math.cos(t) / s
    return val, der


@numba.njit(cache=True)
def _log_f_high(sig):
    """log of f at tau = pi - sig and its sig-derivative, for 0 < sig <= pi/2."""
    num = 2.0 * _PI - 2.0 * sig + math.sin(2.0 * sig)
    s = math.sin(sig)
    val = math.log(num) - 2.0 * math.log(s) - math.log(8.0)
    der = -4.0 * s * s / num - 2.0 * math.cos(sig) / s
    return val, der


@numba.njit(cache=True)
def _newton_log(log_a, x0, lo, hi, high):
    """Safeguarded Newton on log f(x) = log_a for x in (lo, hi]; bisection when a step leaves."""
    x = x0
    for _ in range(_NEWTON_MAXIT):
        if high:
            g, dg = _log_f_high(x)
        else:
            g, dg = _log_f_low(x)
        g -= log_a
        if g == 0.0:
            # an exact root: the step would be 0, land on the bracket end just set and
            # trigger a bisection away from it (measured: 25 wasted iterations at a = 0.1)
            return x
        if high:
            # log f decreases in sig
            if g > 0.0:
                lo = x
            else:
                hi = x
        else:
            if g > 0.0:
                hi = x
            else:
                lo = x
        step = g / dg
        if abs(step) <= _NEWTON_RTOL * abs(x):
            # converged: a step this small may round onto the bracket end just set
            return x - step
        xn = x - step
        if not (lo < xn < hi):
            xn = 0.5 * (lo + hi)
        if abs(xn - x) <= _NEWTON_RTOL * abs(xn):
            return xn
        x = xn
    return x


@numba.njit(cache=True)
def cap_half_angle(a):
    """Solve the cap equation for a = A1/d^2.

    Parameters
    ----------
    a : float
        Ratio of the cap area to the squared chord, any sign, |a| up to ~1e300.

    Returns
    -------
    tau : float
        Half the cap angle, phi/2, in (-pi, pi), with the sign of ``a``.
    sin_tau : float
        sin(tau) to full relative precision (also for |tau| -> pi).
    cos_tau : float
        cos(tau).
    """
    if a != a:
        return math.nan, math.nan, math.nan
    sgn = 1.0 if a >= 0.0 else -1.0
    m = abs(a)
    if m == 0.0:
        return 0.0, 0.0, 1.0
    if m < _SERIES_LIMIT:
        t = 6.0 * m - 28.8 * m**3 + (46656.0 / 175.0) * m**5
        return sgn * t, sgn * math.sin(t), math.cos(t)
    if m == math.inf:
        return sgn * _PI, 0.0, -1.0
    log_a = math.log(m)
    if m <= _PI / 8.0:
        # f(t) ~ t/6 for small t; f(pi/2) = pi/8
        t0 = min(6.0 * m, _HALF_PI)
        t = _newton_log(log_a, t0, 0.0, _HALF_PI, np.bool_(False))
        return sgn * t, sgn * math.sin(t), math.cos(t)
    # f ~ pi / (4 sig^2) as sig -> 0
    s0 = min(math.sqrt(_PI / (4.0 * m)), _HALF_PI)
    sig = _newton_log(log_a, s0, 0.0, _HALF_PI, np.bool_(True))
    return sgn * (_PI - sig), sgn * math.sin(sig), -math.cos(sig)


@numba.njit(cache=True)
def cap_ratio(tau):
    """Return f(tau) = (2 tau - sin 2 tau) / (8 sin^2 tau) = A1/d^2, the inverse of the solve."""
    m = abs(tau)
    if m == 0.0:
        return 0.0
    sgn = 1.0 if tau > 0.0 else -1.0
    if m < 1e-3:
        # the series, without the underflow of (2 tau)^3 for tiny tau; next term ~ m^7 / 1e3
        m2 = m * m
        return sgn * m * (1.0 / 6.0 + m2 * (1.0 / 45.0 + m2 / 315.0))
    if m <= _HALF_PI:
        s = math.sin(m)
        return sgn * _two_t_minus_sin(m) / (8.0 * s * s)
    sig = _PI - m
    s = math.sin(sig)
    return sgn * (2.0 * _PI - 2.0 * sig + math.sin(2.0 * sig)) / (8.0 * s * s)


@numba.njit(cache=True)
def cap_geometry(a1, d):
    """Cap of area ``a1`` on a chord of length ``d``.

    Parameters
    ----------
    a1 : float
        Signed cap area A1 = A - A0 (length^2).
    d : float
        Chord length |x2 - x1| (length), > 0.

    Returns
    -------
    tau, sin_tau, cos_tau : float
        Half cap angle and its sine and cosine (phi = 2 tau).
    lam : float
        Interface length lambda = d tau / sin tau (length); 2 sqrt(pi |a1|) when d = 0.
    kappa : float
        Signed interface curvature 2 sin(tau) / d = 1/r (1/length).
    """
    if d > 0.0:
        tau, s, c = cap_half_angle(a1 / d / d)
    elif d == 0.0 and a1 != 0.0:
        # a closed circle of area |a1|
        rad = math.sqrt(abs(a1) / _PI)
        sg = 1.0 if a1 > 0 else -1.0
        return sg * _PI, 0.0, -1.0, 2.0 * _PI * rad, sg / rad
    else:
        return math.nan, math.nan, math.nan, math.nan, math.nan
    if s == 0.0:
        lam = d
    else:
        lam = d * (tau / s)
    kappa = 2.0 * s / d
    return tau, s, c, lam, kappa


@numba.njit(cache=True)
def cap_tau_derivatives(tau, sin_tau, cos_tau, a1, d):
    """Partial derivatives of tau(a1, d) from f(tau) = a1/d^2.

    Returns
    -------
    dtau_da1, dtau_dd : float
        d(tau)/d(A1) and d(tau)/d(d) (1/length^2 and 1/length).

    Notes
    -----
    f'(tau) = 1/2 - (2 tau - sin 2 tau) cos(tau) / (4 sin^3 tau), which tends to 1/6 as
    tau -> 0 through a cancellation; the small-angle branch uses its series instead.
    """
    m = abs(tau)
    if m < 1e-3:
        # f(t) = t/6 + t^3/45 + t^5/315 + O(t^7)  ->  f' = 1/6 + t^2/15 + t^4/63
        t2 = tau * tau
        fp = 1.0 / 6.0 + t2 / 15.0 + t2 * t2 / 63.0
    else:
        # f' = [4 s^2 * 8 s^2 - h * 16 s c] / (64 s^4) with h = 2t - sin 2t
        s = abs(sin_tau)
        if m <= _HALF_PI:
            h = _two_t_minus_sin(m)
        else:
            sig = _PI - m
            h = 2.0 * _PI - 2.0 * sig + math.sin(2.0 * sig)
        fp = 0.5 - h * cos_tau / (4.0 * s * s * s)
    dtau_da1 = 1.0 / (d * d * fp)
    dtau_dd = -2.0 * a1 / (d * d * d * fp)
    return dtau_da1, dtau_dd


@numba.njit(cache=True)
def locate_on_rod(s, s_nodes):
    """Edge index i and fraction w in [0, 1] with s = (1-w) s_nodes[i] + w s_nodes[i+1]."""
    n = s_nodes.shape[0]
    if s <= s_nodes[0]:
        return 0, 0.0
    if s >= s_nodes[n - 1]:
        return n - 2, 1.0
    lo = 0
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if s_nodes[mid] <= s:
            lo = mid
        else:
            hi = mid
    w = (s - s_nodes[lo]) / (s_nodes[lo + 1] - s_nodes[lo])
    return lo, w


@numba.njit(cache=True)
def wet_polygon_area(x, s_nodes, s1, s2):
    """Signed area A0 between the wet part of a polyline rod and its chord.

    Parameters
    ----------
    x : ndarray, shape (n_nodes, 2)
        Node positions (x, z) of the rod.
    s_nodes : ndarray, shape (n_nodes,)
        Arclength of each node, increasing.
    s1, s2 : float
        Contact arclengths, s_nodes[0] <= s1 < s2 <= s_nodes[-1].

    Returns
    -------
    a0 : float
        Area (length^2), positive when the loop x1 -> wet rod -> x2 -> chord -> x1 turns
        counterclockwise (the rod cupped under the drop).
    """
    i1, w1 = locate_on_rod(s1, s_nodes)
    i2, w2 = locate_on_rod(s2, s_nodes)
    x1x = (1.0 - w1) * x[i1, 0] + w1 * x[i1 + 1, 0]
    x1z = (1.0 - w1) * x[i1, 1] + w1 * x[i1 + 1, 1]
    x2x = (1.0 - w2) * x[i2, 0] + w2 * x[i2 + 1, 0]
    x2z = (1.0 - w2) * x[i2, 1] + w2 * x[i2 + 1, 1]
    # shoelace relative to x1 (translation invariance keeps round-off small)
    area = 0.0
    px = 0.0
    pz = 0.0
    for k in range(i1 + 1, i2 + 1):
        qx = x[k, 0] - x1x
        qz = x[k, 1] - x1z
        area += px * qz - qx * pz
        px = qx
        pz = qz
    qx = x2x - x1x
    qz = x2z - x1z
    area += px * qz - qx * pz
    return 0.5 * area


@numba.njit(cache=True)
def capillary_energy_and_gradient(x, s_nodes, s1, s2, area, gamma, grad):
    """Capillary energy gamma * lambda of a polyline rod and its exact gradient.

    Parameters
    ----------
    x : ndarray, shape (n_nodes, 2)
        Node positions (x, z).
    s_nodes : ndarray, shape (n_nodes,)
        Arclength of each node (the rod's reference configuration), increasing.
    s1, s2 : float
        Contact arclengths, anywhere inside edges, s1 < s2.
    area : float
        Drop area A (length^2).
    gamma : float
        Line tension (force).
    grad : ndarray, shape (n_nodes, 2)
        Receives d(gamma lambda)/dx, ADDED to its content (the force is -grad).

    Returns
    -------
    energy : float
        gamma * lambda (energy per unit width).
    tau : float
        Half cap angle phi/2.
    kappa : float
        Interface curvature 1/r.

    Notes
    -----
    d(lambda) = cos(tau) d(d) - kappa d(A0); the A0 variation of the shoelace polygon gives
    the Laplace pressure on each wet segment and the chord term that turns the chord force
    cos(tau) c into the line tension along the interface, exactly the forces [6]-[8] of the
    paper lumped onto the nodes.
    """
    i1, w1 = locate_on_rod(s1, s_nodes)
    i2, w2 = locate_on_rod(s2, s_nodes)
    x1x = (1.0 - w1) * x[i1, 0] + w1 * x[i1 + 1, 0]
    x1z = (1.0 - w1) * x[i1, 1] + w1 * x[i1 + 1, 1]
    x2x = (1.0 - w2) * x[i2, 0] + w2 * x[i2 + 1, 0]
    x2z = (1.0 - w2) * x[i2, 1] + w2 * x[i2 + 1, 1]
    a0 = wet_polygon_area(x, s_nodes, s1, s2)
    cx = x2x - x1x
    cz = x2z - x1z
    d = math.sqrt(cx * cx + cz * cz)
    tau, s, c, lam, kappa = cap_geometry(area - a0, d)
    # gradient of d with respect to x2 (minus for x1)
    ux = cx / d
    uz = cz / d
    g1x = -gamma * c * ux
    g1z = -gamma * c * uz
    g2x = gamma * c * ux
    g2z = gamma * c * uz
    # -gamma kappa dA0: polygon x1, nodes i1+1..i2, x2 (closed); dA/dP_k = J(P_{k+1}-P_{k-1})/2
    # with J(vx, vz) = (vz, -vx).
    fac = -gamma * kappa * 0.5
    n_int = i2 - i1  # interior wet nodes i1+1 .. i2
    # previous / next of x1 are x2 (closing chord) and first interior node (or x2)
    if n_int > 0:
        nx = x[i1 + 1, 0]
        nz = x[i1 + 1, 1]
    else:
        nx = x2x
        nz = x2z
    g1x += fac * (nz - x2z)
    g1z += fac * (-(nx - x2x))
    if n_int > 0:
        px = x[i2, 0]
        pz = x[i2, 1]
    else:
        px = x1x
        pz = x1z
    g2x += fac * (x1z - pz)
    g2z += fac * (-(x1x - px))
    for k in range(i1 + 1, i2 + 1):
        if k == i1 + 1:
            ppx = x1x
            ppz = x1z
        else:
            ppx = x[k - 1, 0]
            ppz = x[k - 1, 1]
        if k == i2:
            qqx = x2x
            qqz = x2z
        else:
            qqx = x[k + 1, 0]
            qqz = x[k + 1, 1]
        grad[k, 0] += fac * (qqz - ppz)
        grad[k, 1] += fac * (-(qqx - ppx))
    grad[i1, 0] += (1.0 - w1) * g1x
    grad[i1, 1] += (1.0 - w1) * g1z
    grad[i1 + 1, 0] += w1 * g1x
    grad[i1 + 1, 1] += w1 * g1z
    grad[i2, 0] += (1.0 - w2) * g2x
    grad[i2, 1] += (1.0 - w2) * g2z
    grad[i2 + 1, 0] += w2 * g2x
    grad[i2 + 1, 1] += w2 * g2z
    return gamma * lam, tau, kappa


def _signed_angle(ax, az, bx, bz):
    return math.atan2(ax * bz - az * bx, ax * bx + az * bz)


def contact_angles(tau, t1, t2, x1, x2):
    """Contact angles of the interface in the local frames, paper's S1 formulas.

    theta1 = phi/2 + angle(t1, x2 - x1),  theta2 = phi/2 + angle(x1 - x2, -t2).

    Parameters
    ----------
    tau : float
        Half cap angle.
    t1, t2 : array_like, shape (2,)
        Unit tangents of the rod at S1 and S2.
    x1, x2 : array_like, shape (2,)
        Contact points.

    Returns
    -------
    theta1, theta2 : float
        Radians.
    """
    cx, cz = x2[0] - x1[0], x2[1] - x1[1]
    th1 = tau + _signed_angle(t1[0], t1[1], cx, cz)
    th2 = tau + _signed_angle(-cx, -cz, -t2[0], -t2[1])
    return th1, th2


@dataclass(frozen=True)
class CapGeometry:
    """A drop cap, all lengths in the scene's length unit.

    Attributes
    ----------
    phi : float
        Cap angle (radians), sign of the cap area, in (-2 pi, 2 pi).
    radius : float
        Signed radius r = d / (2 sin(phi/2)); inf for a flat interface.
    curvature : float
        1/r.
    length : float
        Interface length lambda.
    chord : float
        d = |x2 - x1|.
    cap_area : float
        A1 = A - A0.
    """

    phi: float
    radius: float
    curvature: float
    length: float
    chord: float
    cap_area: float

    @classmethod
    def from_chord(cls, cap_area: float, chord: float) -> CapGeometry:
        """Solve the cap for area ``cap_area`` (A1) on a chord of length ``chord`` (d > 0)."""
        if not (math.isfinite(chord) and chord > 0.0):
            raise ValueError(f"chord: got {chord!r}; expected a finite length > 0")
        if not math.isfinite(cap_area):
            raise ValueError(f"cap_area: got {cap_area!r}; expected a finite area")
        tau, _s, _c, lam, kappa = cap_geometry(float(cap_area), float(chord))
        radius = math.inf if kappa == 0.0 else 1.0 / kappa
        return cls(2.0 * tau, radius, kappa, lam, float(chord), float(cap_area))

    def to_dict(self) -> dict[str, float]:
        return {
            "phi": self.phi,
            "radius": self.radius,
            "curvature": self.curvature,
            "length": self.length,
            "chord": self.chord,
            "cap_area": self.cap_area,
        }
