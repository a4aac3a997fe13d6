"""The quasi-static drop (elastocap.drop) against an independent mpmath evaluation, finite
differences and the paper's force expressions [6]-[8]."""

import math

import mpmath as mp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from elastocap.drop import (
    CapGeometry,
    cap_geometry,
    cap_half_angle,
    cap_ratio,
    cap_tau_derivatives,
    capillary_energy_and_gradient,
    contact_angles,
    wet_polygon_area,
)


def _ref_cap(a1, d):
    """phi, r, lambda in 60-digit arithmetic by bracketed root finding (no shared code)."""
    # a local precision: other test modules set mpmath's global precision too
    with mp.workdps(60):
        return _ref_cap_60(a1, d)


def _rel(a, b):
    with mp.workdps(60):
        return float(abs((mp.mpf(a) - b) / b))


def _ref_cap_60(a1, d):
    a1 = mp.mpf(a1)
    d = mp.mpf(d)
    a = abs(a1) / d**2
    sgn = 1 if a1 >= 0 else -1

    def f_low(t):
        return (2 * t - mp.sin(2 * t)) / (8 * mp.sin(t) ** 2) - a

    def f_high(s):  # tau = pi - s
        return (2 * mp.pi - 2 * s + mp.sin(2 * s)) / (8 * mp.sin(s) ** 2) - a

    if a <= mp.pi / 8:
        lo, hi = mp.mpf(0), mp.pi / 2
        # geometric bisection first (the root spans 300 decades), then anderson
        lo = mp.mpf(10) ** -330
        for _ in range(60):
            mid = mp.sqrt(lo * hi)
            if f_low(mid) > 0:
                hi = mid
            else:
                lo = mid
        t = mp.findroot(f_low, (lo, hi), solver="anderson")
        sin_t = mp.sin(t)
    else:
        lo, hi = mp.mpf(10) ** -330, mp.pi / 2
        for _ in range(60):
            mid = mp.sqrt(lo * hi)
            if f_high(mid) > 0:
                lo = mid
            else:
                hi = mid
        s = mp.findroot(f_high, (lo, hi), solver="anderson")
        t = mp.pi - s
        sin_t = mp.sin(s)
    phi = sgn * 2 * t
    r = sgn * d / (2 * sin_t)
    lam = 2 * t * d / (2 * sin_t)
    return phi, r, lam


# The whole range the model must cover: |A1|/d^2 from 1e-12 to 1e12 with either sign, and
# chords down to 1e-12 of the drop size (|A1|/d^2 up to 1e24).
ratios = st.floats(min_value=-12.0, max_value=12.0).map(lambda e: 10.0**e)
signs = st.sampled_from([-1.0, 1.0])
chords = st.floats(min_value=-12.0, max_value=3.0).map(lambda e: 10.0**e)


@given(ratio=ratios, sign=signs, d=chords)
def test_cap_matches_mpmath_over_whole_range(ratio, sign, d):
    a1 = sign * ratio * d * d
    tau, _s, _c, lam, kappa = cap_geometry(a1, d)
    phi_ref, r_ref, lam_ref = _ref_cap(a1, d)
    # 1e-12 relative is the bound; the implementation reaches ~1e-15
    assert _rel(2 * tau, phi_ref) <= 1e-12
    assert _rel(1.0 / kappa, r_ref) <= 1e-12
    assert _rel(lam, lam_ref) <= 1e-12


@given(size=st.floats(min_value=-12.0, max_value=0.0).map(lambda e: 10.0**e), sign=signs)
def test_tiny_chord_relative_to_drop(size, sign):
    """d down to 1e-12 of the drop size: the cap is nearly a closed circle."""
    a1 = sign * 1.0
    tau, _s, _c, lam, kappa = cap_geometry(a1, size)
    phi_ref, r_ref, lam_ref = _ref_cap(a1, size)
    assert _rel(2 * tau, phi_ref) <= 1e-12
    assert _rel(1.0 / kappa, r_ref) <= 1e-12
    assert _rel(lam, lam_ref) <= 1e-12


def test_limits_flat_and_closed_circle():
    # flat interface: lambda = d exactly, curvature 0
    assert cap_geometry(0.0, 2.0) == (0.0, 0.0, 1.0, 2.0, 0.0)
    # tiny cap: lambda - d = d tau^2 / 6 + ..., with tau = 6 a
    d = 1.0
    a = 1e-9
    lam = cap_geometry(a * d * d, d)[3]
    assert lam == pytest.approx(d * (1 + (6 * a) ** 2 / 6), rel=1e-15)
    # d -> 0: circle of area A1 has length 2 sqrt(pi A1)
    assert cap_geometry(2.0, 1e-13)[3] == pytest.approx(2 * math.sqrt(math.pi * 2.0), rel=1e-12)
    assert cap_geometry(2.0, 0.0)[3] == pytest.approx(2 * math.sqrt(math.pi * 2.0), rel=1e-15)
    # semicircle: A1 / d^2 = pi / 8
    tau = cap_half_angle(math.pi / 8)[0]
    assert tau == pytest.approx(math.pi / 2, rel=1e-15)


@given(tau=st.floats(min_value=-math.pi + 1e-9, max_value=math.pi - 1e-9))
def test_ratio_is_inverse_of_solve(tau):
    back = cap_half_angle(cap_ratio(tau))[0]
    assert back == pytest.approx(tau, rel=1e-13, abs=1e-300)


@given(
    ratio=st.floats(min_value=-6.0, max_value=6.0).map(lambda e: 10.0**e),
    sign=signs,
    d=st.floats(min_value=0.1, max_value=10.0),
)
def test_tau_derivatives_against_finite_differences(ratio, sign, d):
    a1 = sign * ratio * d * d
    tau, s, c, _lam, _k = cap_geometry(a1, d)
    dta, dtd = cap_tau_derivatives(tau, s, c, a1, d)
    h1 = 1e-6 * max(abs(a1), 1e-300)
    fd_a = (cap_geometry(a1 + h1, d)[0] - cap_geometry(a1 - h1, d)[0]) / (2 * h1)
    h2 = 1e-6 * d
    fd_d = (cap_geometry(a1, d + h2)[0] - cap_geometry(a1, d - h2)[0]) / (2 * h2)
    # central differences with h = 1e-6 relative: truncation ~1e-12, round-off ~1e-10
    assert dta == pytest.approx(fd_a, rel=1e-6)
    assert dtd == pytest.approx(fd_d, rel=1e-6, abs=1e-9 * abs(dta) * abs(a1) / d)


def test_length_derivatives_are_tension_and_pressure():
    """d lambda / d d = cos(tau), d lambda / d A1 = kappa (the forces behind [7] and [8])."""
    for a1, d in [(0.3, 1.0), (-0.7, 1.3), (5.0, 0.4), (1e-4, 2.0)]:
        tau, _s, c, _lam, kappa = cap_geometry(a1, d)
        h = 1e-6
        dl_dd = (cap_geometry(a1, d + h)[3] - cap_geometry(a1, d - h)[3]) / (2 * h)
        dl_da = (cap_geometry(a1 + h, d)[3] - cap_geometry(a1 - h, d)[3]) / (2 * h)
        assert dl_dd == pytest.approx(c, rel=1e-7, abs=1e-9)
        assert dl_da == pytest.approx(kappa, rel=1e-7)


# ------------------------------------------------------------------------------------------
def _random_rod(rng, n, length=3.0, bend=0.3):
    s = np.linspace(0.0, length, n)
    th = np.cumsum(rng.normal(0.0, bend, n - 1))
    x = np.zeros((n, 2))
    h = np.diff(s)
    x[1:, 0] = np.cumsum(h * np.cos(th))
    x[1:, 1] = np.cumsum(h * np.sin(th))
    return s, x


def _energy(x, s, s1, s2, area, gamma):
    return capillary_energy_and_gradient(x, s, s1, s2, area, gamma, np.zeros_like(x))[0]


@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(2, 30),
    f1=st.floats(0.0, 1.0),
    f2=st.floats(0.0, 1.0),
    area=st.floats(0.05, 5.0),
)
def test_gradient_against_finite_differences(seed, n, f1, f2, area):
    rng = np.random.default_rng(seed)
    s, x = _random_rod(rng, n)
    s1, s2 = sorted((f1 * 3.0, f2 * 3.0))
    if s2 - s1 < 1e-3:
        s2 = min(s1 + 0.5, 3.0)
        s1 = s2 - 0.5
    grad = np.zeros_like(x)
    capillary_energy_and_gradient(x, s, s1, s2, area, 1.7, grad)
    fd = np.zeros_like(x)
    h = 1e-6
    for i in range(n):
        for j in range(2):
            xp = x.copy()
            xp[i, j] += h
            xm = x.copy()
            xm[i, j] -= h
            fd[i, j] = (_energy(xp, s, s1, s2, area, 1.7) - _energy(xm, s, s1, s2, area, 1.7)) / (
                2 * h
            )
    scale = max(1.0, np.abs(grad).max())
    # central differences, h = 1e-6: error ~ h^2 |E'''| + eps |E| / h ~ 1e-9 relative
    assert np.abs(fd - grad).max() <= 1e-6 * scale


def _paper_forces(x, s, s1, s2, area, gamma):
    """Nodal forces assembled from the paper's [6]-[8]: line tension at S1, S2 along the
    interface (angles theta1, theta2 of S1) and pressure -gamma/r q on the wet polyline,
    each lumped by linear interpolation (the exact work-equivalent lumping)."""
    n = len(s)
    f = np.zeros_like(x)

    def locate(sv):
        i = min(max(np.searchsorted(s, sv, side="right") - 1, 0), n - 2)
        w = (sv - s[i]) / (s[i + 1] - s[i])
        return i, w

    i1, w1 = locate(s1)
    i2, w2 = locate(s2)
    p1 = (1 - w1) * x[i1] + w1 * x[i1 + 1]
    p2 = (1 - w2) * x[i2] + w2 * x[i2 + 1]
    a0 = wet_polygon_area(x, s, s1, s2)
    tau, _s, _c, _lam, kappa = cap_geometry(area - a0, np.linalg.norm(p2 - p1))
    t1 = (x[i1 + 1] - x[i1]) / np.linalg.norm(x[i1 + 1] - x[i1])
    t2 = (x[i2 + 1] - x[i2]) / np.linalg.norm(x[i2 + 1] - x[i2])
    rot = np.array([[0.0, -1.0], [1.0, 0.0]])  # q = (-e_y) x t: t turned by +90 degrees
    q1, q2 = rot @ t1, rot @ t2
    th1, th2 = contact_angles(tau, t1, t2, p1, p2)
    f1 = gamma * (t1 * np.cos(th1) + q1 * np.sin(th1))  # [7a]
    f2 = gamma * (-t2 * np.cos(th2) + q2 * np.sin(th2))  # [7b]
    pts = [(p1, [(i1, 1 - w1), (i1 + 1, w1)])]
    pts += [(x[k], [(k, 1.0)]) for k in range(i1 + 1, i2 + 1)]
    pts += [(p2, [(i2, 1 - w2), (i2 + 1, w2)])]

    def add(weights, force):
        for k, w in weights:
            f[k] += w * force

    add(pts[0][1], f1)
    add(pts[-1][1], f2)
    for (pa, wa), (pb, wb) in zip(pts[:-1], pts[1:], strict=True):
        seg = pb - pa
        fp = -gamma * kappa * (rot @ seg)  # [8] integrated over the segment
        add(wa, 0.5 * fp)
        add(wb, 0.5 * fp)
    return f


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("area", [0.2, 1.5, 6.0, -0.5])
def test_gradient_equals_paper_forces(seed, area):
    rng = np.random.default_rng(seed)
    s, x = _random_rod(rng, 14, bend=0.4)
    s1, s2 = 0.37 + 0.1 * seed, 2.61 - 0.05 * seed
    grad = np.zeros_like(x)
    capillary_energy_and_gradient(x, s, s1, s2, area, 2.0, grad)
    f = _paper_forces(x, s, s1, s2, area, 2.0)
    # the two are the same expression rearranged: round-off only
    assert np.abs(-grad - f).max() <= 1e-12 * max(1.0, np.abs(f).max())


def test_same_edge_contacts_and_node_contacts():
    s = np.array([0.0, 1.0, 2.0, 3.0])
    x = np.column_stack([s, np.zeros(4)])
    # both contact points in one edge: A0 = 0, cap on a flat chord of length 0.5
    assert wet_polygon_area(x, s, 1.2, 1.7) == 0.0
    g = np.zeros_like(x)
    e = capillary_energy_and_gradient(x, s, 1.2, 1.7, 0.3, 1.0, g)[0]
    assert e == pytest.approx(CapGeometry.from_chord(0.3, 0.5).length, rel=1e-15)
    # contacts exactly at nodes give the same energy as just inside the edge (continuity)
    e_node = capillary_energy_and_gradient(x, s, 1.0, 3.0, 0.3, 1.0, np.zeros_like(x))[0]
    e_near = capillary_energy_and_gradient(
        x, s, 1.0 + 1e-14, 3.0 - 1e-14, 0.3, 1.0, np.zeros_like(x)
    )[0]
    assert e_node == pytest.approx(e_near, rel=1e-12)


def test_cup_shape_has_positive_a0():
    """Sign convention: a rod cupped under the drop (ends up) has A0 > 0."""
    s = np.linspace(0, np.pi, 50)
    x = np.column_stack([-np.cos(s), -np.sin(s)])  # lower half circle, left to right
    s_nodes = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(x, axis=0), axis=1))])
    a0 = wet_polygon_area(x, s_nodes, 0.0, s_nodes[-1])
    assert a0 > 0
    # polygon area of the inscribed half 49-gon
    assert a0 == pytest.approx(0.5 * 49 * np.sin(np.pi / 49), rel=1e-12)


def test_cap_geometry_dataclass_rejects_bad_input():
    with pytest.raises(ValueError, match="chord: got 0.0; expected a finite length > 0"):
        CapGeometry.from_chord(1.0, 0.0)
    with pytest.raises(ValueError, match="cap_area: got nan"):
        CapGeometry.from_chord(float("nan"), 1.0)
    cap = CapGeometry.from_chord(math.pi / 2, 2.0)  # semicircle of radius 1
    assert cap.phi == pytest.approx(math.pi, rel=1e-15)
    assert cap.radius == pytest.approx(1.0, rel=1e-15)
