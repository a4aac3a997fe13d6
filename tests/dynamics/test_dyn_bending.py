"""Discrete-Elastic-Rods bending energy and its exact gradient."""

import numpy as np
import pytest
from dyn_helpers import rod_from_angles
from hypothesis import given, settings
from hypothesis import strategies as st

from dynamics import bending_energy, bending_gradient, discrete_curvature
from dynamics.bending import BENDING_WORK_ROWS, bending_force_add


def _random_rod(seed, n=12, spread=0.6):
    rng = np.random.default_rng(seed)
    theta = np.cumsum(spread * rng.standard_normal(n))
    return rod_from_angles(theta, 0.3)


def test_curvature_is_two_tan_half_turning_angle():
    rod = _random_rod(1)
    e = np.diff(rod.x, axis=0)
    ang = np.arctan2(e[:, 1], e[:, 0])
    psi = np.angle(np.exp(1j * np.diff(ang)))
    kb = discrete_curvature(rod.x, np.empty(rod.n_nodes))
    np.testing.assert_allclose(kb[1:-1], 2 * np.tan(psi / 2), rtol=1e-13, atol=1e-14)
    assert kb[0] == 0.0 and kb[-1] == 0.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gradient_matches_central_differences(seed):
    rod = _random_rod(seed)
    B = 1.7
    g = np.empty_like(rod.x)
    E = bending_gradient(rod.x, rod.edge_len, B, g)
    assert E == pytest.approx(bending_energy(rod.x, rod.edge_len, B), rel=1e-14)
    fd = np.empty_like(g)
    eps = 1e-6  # central differences: truncation ~eps**2, round-off ~1e-16/eps -> ~1e-10
    for i in range(rod.n_nodes):
        for k in range(2):
            xp = rod.x.copy()
            xm = rod.x.copy()
            xp[i, k] += eps
            xm[i, k] -= eps
            fd[i, k] = (bending_energy(xp, rod.edge_len, B)
                        - bending_energy(xm, rod.edge_len, B)) / (2 * eps)
    np.testing.assert_allclose(g, fd, rtol=1e-7, atol=1e-8 * np.abs(g).max())


def test_circle_energy_closed_form_and_second_order():
    """Regular polygon inscribed in an arc of curvature k0 and length L.

    Every interior node turns by psi = k0 L / n, so E = (n-1) B (2 tan(psi/2))**2 / (2 h)
    exactly; the end nodes carry no curvature (free ends), hence the continuum limit is
    (B/2) k0**2 (L - L/n) with an O(h**2) error.
    """
    k0, L, B = 1.3, 2.0, 0.8
    ns = [8, 16, 32, 64]
    errs = []
    for n in ns:
        psi = k0 * L / n
        h = 2 * np.sin(psi / 2) / k0  # chord of an arc of length L/n
        rod = rod_from_angles((np.arange(n) + 0.5) * psi, h)
        E = bending_energy(rod.x, rod.edge_len, B)
        closed = (n - 1) * B * (2 * np.tan(psi / 2)) ** 2 / (2 * h)
        assert E == pytest.approx(closed, rel=1e-12)
        errs.append(abs(E - 0.5 * B * k0**2 * (L - L / n)))
    order = -np.polyfit(np.log(ns), np.log(errs), 1)[0]
    assert order == pytest.approx(2.0, abs=0.1), f"observed order {order:.3f}, errors {errs}"
    assert errs[-1] < 5e-4 * 0.5 * B * k0**2 * L


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.floats(-np.pi, np.pi), st.floats(-5, 5), st.floats(-5, 5))
def test_energy_invariant_under_rigid_motion(seed, angle, tx, tz):
    rod = _random_rod(seed)
    c, s = np.cos(angle), np.sin(angle)
    y = rod.x @ np.array([[c, s], [-s, c]]) + np.array([tx, tz])
    E0 = bending_energy(rod.x, rod.edge_len, 1.0)
    assert bending_energy(y, rod.edge_len, 1.0) == pytest.approx(E0, rel=1e-10, abs=1e-14)
    g = np.empty_like(y)
    bending_gradient(y, rod.edge_len, 1.0, g)
    # internal forces: zero net force and zero net torque
    assert np.abs(g.sum(axis=0)).max() < 1e-10 * max(1.0, np.abs(g).max())
    torque = np.sum(y[:, 0] * g[:, 1] - y[:, 1] * g[:, 0])
    assert abs(torque) < 1e-9 * max(1.0, np.abs(g).max())


def _force_add_fused(x, edge_len, B, out):
    """The former single fused pass of ``bending_force_add`` (plain Python: IEEE double
    arithmetic in the same order), the reference of the three-pass SIMD kernel."""
    n = x.shape[0]
    E = 0.0
    ax, az = x[1, 0] - x[0, 0], x[1, 1] - x[0, 1]
    la = np.sqrt(ax * ax + az * az)
    ila = 1.0 / la
    for i in range(1, n - 1):
        bx, bz = x[i + 1, 0] - x[i, 0], x[i + 1, 1] - x[i, 1]
        lb = np.sqrt(bx * bx + bz * bz)
        ilb = 1.0 / lb
        c = ax * bz - az * bx
        den = la * lb + ax * bx + az * bz
        idn = 1.0 / den
        kb = 2.0 * c * idn
        w = B / (edge_len[i - 1] + edge_len[i])
        E += w * kb * kb
        s = 4.0 * w * kb * idn * idn
        rab, rba = lb * ila, la * ilb
        ga_x = s * (bz * den - c * (ax * rab + bx))
        ga_z = s * (-bx * den - c * (az * rab + bz))
        gb_x = s * (-az * den - c * (bx * rba + ax))
        gb_z = s * (ax * den - c * (bz * rba + az))
        out[i - 1, 0] += ga_x
        out[i - 1, 1] += ga_z
        out[i, 0] -= ga_x - gb_x
        out[i, 1] -= ga_z - gb_z
        out[i + 1, 0] -= gb_x
        out[i + 1, 1] -= gb_z
        ax, az, la, ila = bx, bz, lb, ilb
    return E


@pytest.mark.parametrize("n", [3, 4, 5, 6, 13, 101, 199])
def test_force_kernel_bit_identical_to_the_fused_pass(n):
    """The SIMD kernel adds each node's contributions in the order of the fused loop it
    replaced: forces identical bit for bit, with or without a work array, and accumulated
    onto what ``out_force`` held; the energy is summed by four partial sums (equal to the
    running sum to round-off)."""
    rod = _random_rod(n, n=n - 1, spread=0.3)
    rng = np.random.default_rng(n)
    el = rod.edge_len * (1.0 + 0.01 * rng.random(n - 1))
    f0 = rng.standard_normal(rod.x.shape)
    f_ref, f1, f2 = f0.copy(), f0.copy(), f0.copy()
    e_ref = _force_add_fused(rod.x, el, 1.7, f_ref)
    e1 = bending_force_add(rod.x, el, 1.7, f1)
    e2 = bending_force_add(rod.x, el, 1.7, f2, np.full((BENDING_WORK_ROWS, n), np.nan))
    assert e1 == e2 and abs(e1 - e_ref) <= 1e-15 * n * abs(e_ref)
    assert np.array_equal(f1, f_ref) and np.array_equal(f2, f_ref)
