"""Small-amplitude beam frequencies against Euler-Bernoulli, with observed orders."""

import numpy as np
import pytest
from dyn_helpers import clamped, rod_from_angles

from dynamics import Clamp, euler_bernoulli_omega, simulate
from dynamics.reference import BETA_L, crossing_period


def _mode(kind, s, L):
    bL = BETA_L[kind]
    b = bL / L
    if kind == "free-free":
        sg = (np.cosh(bL) - np.cos(bL)) / (np.sinh(bL) - np.sin(bL))
        return np.cosh(b * s) + np.cos(b * s) - sg * (np.sinh(b * s) + np.sin(b * s))
    sg = (np.cosh(bL) + np.cos(bL)) / (np.sinh(bL) + np.sin(bL))
    return np.cosh(b * s) - np.cos(b * s) - sg * (np.sinh(b * s) - np.sin(b * s))


def first_mode_frequency_error(kind, n_edges, periods=5, amplitude=1e-4):
    """Relative error of the measured first-mode angular frequency (L = B = mu = 1).

    The rod starts at rest in the continuum mode shape (tangent angles from the mode's
    slope, amplitude 1e-4 so the nonlinear shift ~1e-8 is negligible).  The signal is the
    mass-weighted projection of z on the mode shape, which filters the other modes; the
    period is measured between downward zero crossings (insensitive to a constant offset).
    dt = 0.25 h**2 so the Verlet phase error (omega dt)**2 / 24 < 1e-7 is negligible.
    Clamped-free: the clamp holds the first edge, whose midpoint is the beam root s = 0.
    """
    L = 1.0
    omega = euler_bernoulli_omega(kind, L, 1.0, 1.0)
    if kind == "free-free":
        h = L / n_edges
        s = np.arange(n_edges + 1) * h
    else:
        h = L / (n_edges - 0.5)
        s = (np.arange(n_edges + 1) - 0.5) * h
    phi = _mode(kind, np.clip(s, 0.0, None), L)
    theta = amplitude * np.diff(phi) / h
    effects = ()
    if kind == "clamped-free":
        theta[0] = 0.0
        # no gravity, no damping, no load: the cantilever's stepper (test_dyn_effects.py)
        effects = clamped(Clamp(0, (s[0], 0.0), angle=0.0))
    rod = rod_from_angles(theta, h, origin=(s[0], 0.0))
    T = 2 * np.pi / omega
    r = simulate(rod, effects, dt=0.25 * h * h, t_end=periods * T, frames=periods * 120)
    assert r.success, r.message
    q = (r.positions[:, :, 1] * (rod.mass * phi)).sum(axis=1)
    q -= q.mean()
    period = crossing_period(r.times, q)
    return 2 * np.pi / period / omega - 1.0


def _order(ns, errs):
    return -np.polyfit(np.log(ns), np.log(np.abs(errs)), 1)[0]


def test_free_free_first_mode_second_order():
    ns = [10, 20, 40]
    errs = [first_mode_frequency_error("free-free", n) for n in ns]
    order = _order(ns, errs)
    # measured: -3.9e-2, -1.0e-2, -2.6e-3 (order 1.97)
    assert order == pytest.approx(2.0, abs=0.15), f"observed order {order:.3f}, errors {errs}"
    assert abs(errs[-1]) < 3e-3


def test_clamped_free_first_mode_second_order():
    ns = [10, 20, 40]
    errs = [first_mode_frequency_error("clamped-free", n) for n in ns]
    order = _order(ns, errs)
    # measured: -1.76e-3, -4.2e-4, -1.0e-4 (order 2.02)
    assert order == pytest.approx(2.0, abs=0.15), f"observed order {order:.3f}, errors {errs}"
    assert abs(errs[-1]) < 1.5e-4


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["free-free", "clamped-free"])
def test_first_mode_order_four_levels(kind):
    ns = [10, 20, 40, 80]
    errs = [first_mode_frequency_error(kind, n) for n in ns]
    order = _order(ns, errs)
    assert order == pytest.approx(2.0, abs=0.1), f"observed order {order:.3f}, errors {errs}"
