"""Hard cases of the drop cap (elastocap.drop): phi -> 0, phi -> +-2 pi, chord d -> 0.

Each case is checked against an independent 50-digit mpmath solution of the cap equation
(phi - sin phi) / (8 sin^2(phi/2)) = A1/d^2, written in sigma = pi - |phi|/2 near the closed
circle so the reference keeps its precision there.
"""

import math

import mpmath as mp
import numpy as np
import pytest

from elastocap.drop import CapGeometry, capillary_energy_and_gradient


def _reference(a1, d):
    """(phi, radius, length) of the cap of area a1 on chord d, by mpmath (50 digits)."""
    with mp.workdps(50):
        return _reference_50(a1, d)


def _reference_50(a1, d):
    a = mp.mpf(a1) / mp.mpf(d) ** 2
    s = mp.sign(a)
    a = abs(a)
    if a < mp.pi / 8:  # tau = phi/2 in (0, pi/2]
        f = lambda t: (2 * t - mp.sin(2 * t)) / (8 * mp.sin(t) ** 2) - a  # noqa: E731
        # below 1e-30 the series tau = 6 a (1 + O(a^2)) is exact to 60 digits
        tau = 6 * a if a < mp.mpf(1e-30) else mp.findroot(f, 6 * a)
        sin_t = mp.sin(tau)
    else:  # sigma = pi - tau small for a large cap
        f = lambda sg: (2 * mp.pi - 2 * sg + mp.sin(2 * sg)) / (8 * mp.sin(sg) ** 2) - a  # noqa: E731
        sg = mp.findroot(f, mp.sqrt(2 * mp.pi / (8 * a)))
        tau = mp.pi - sg
        sin_t = mp.sin(sg)
    r = mp.mpf(d) / (2 * sin_t)
    return float(s * 2 * tau), float(s * r), float(2 * tau * r)


@pytest.mark.parametrize(
    "a1, d",
    [
        (1e-14, 1.0),  # phi ~ 1.2e-13: nearly flat interface
        (-1e-14, 1.0),
        (1e-200, 1.0),
        (1e12, 1.0),  # phi -> 2 pi: a nearly closed circle on a tiny chord (relative)
        (-1e12, 1.0),  # phi -> -2 pi
        (1.0, 1e-12),  # d -> 0 at fixed cap area
        (-1.0, 1e-12),
        (2.5, 1e-6),
    ],
)
def test_cap_extremes_match_mpmath(a1, d):
    cap = CapGeometry.from_chord(a1, d)
    phi, r, lam = _reference(a1, d)
    # relative accuracy of the README (<= 1e-12), asserted on phi, r and lambda
    assert cap.phi == pytest.approx(phi, rel=1e-12, abs=0)
    assert cap.radius == pytest.approx(r, rel=1e-12, abs=0)
    assert cap.length == pytest.approx(lam, rel=1e-12, abs=0)
    assert abs(cap.phi) < 2 * math.pi


def test_closed_circle_limit_is_the_circle():
    # d -> 0 at fixed area: the cap becomes the full circle of area A1
    cap = CapGeometry.from_chord(1.0, 1e-12)
    assert cap.length == pytest.approx(2 * math.sqrt(math.pi * 1.0), rel=1e-11)
    assert 2 * math.pi - abs(cap.phi) < 1e-11


@pytest.mark.parametrize("d", [0.0, -1.0, math.nan, math.inf])
def test_degenerate_chord_is_refused_clearly(d):
    with pytest.raises(ValueError, match=r"^chord: got .*expected a finite length > 0"):
        CapGeometry.from_chord(1.0, d)


def test_contact_lines_almost_meeting_on_a_wrapped_rod():
    """A rod bent into a circle of circumference 1 with S1, S2 = 1e-9 apart across the
    closure: the chord is ~1e-9, the wet polygon is the whole disc, A1 = A - A0 is small
    and the energy and its gradient stay finite (the gradient is the paper's forces)."""
    n = 64
    s = np.linspace(0.0, 1.0, n + 1)
    R = 1.0 / (2 * math.pi)
    x = np.column_stack([R * np.sin(2 * math.pi * s), R - R * np.cos(2 * math.pi * s)])
    s1, s2 = 0.5e-9, 1.0 - 0.5e-9
    area = math.pi * R * R * 1.01
    g = np.zeros_like(x)
    e, tau, kappa = capillary_energy_and_gradient(x, s, s1, s2, area, 1.0, g)
    assert np.isfinite(e) and np.all(np.isfinite(g)) and np.isfinite(kappa)
    # the cap holds A1 = 1% of the disc on a chord of 1e-9: nearly the full circle of area
    # A1 (within the chord's and the polygon's O(h^2) share)
    a1 = area - math.pi * R * R * (1 - (2 * math.pi / n) ** 2 / 6)
    assert e == pytest.approx(2 * math.sqrt(math.pi * a1), rel=2e-2)
