"""RATTLE on a free rod: energy conservation (bounded, O(dt**2)) and exact constraints."""

import numpy as np
import pytest

import dynamics
from dynamics import Damping, Gravity, Ground, simulate


def _energy_error(rod, dt, t_end, effects=()):
    r = simulate(rod, effects, dt=dt, t_end=t_end, frames=1001)
    assert r.success, r.message
    E = r.energies["total"]
    scale = r.energies["bending"][0]
    return np.abs(E - E[0]).max() / scale, r


def test_energy_error_bounded_and_second_order(wavy_rod):
    """Long run (t = 60, ~60 bending periods of the first mode): no drift, error ~ dt**2."""
    dts = [4e-3, 2e-3]
    errs = []
    for dt in dts:
        err, r = _energy_error(wavy_rod, dt, 60.0)
        errs.append(err)
        # secular drift: mean energy over the last tenth vs the first tenth
        E = r.energies["total"]
        drift = abs(E[-100:].mean() - E[:100].mean()) / r.energies["bending"][0]
        assert drift < 0.05 * err, f"dt={dt}: drift {drift:.2e} vs oscillation {err:.2e}"
    order = np.log(errs[0] / errs[1]) / np.log(dts[0] / dts[1])
    assert order == pytest.approx(2.0, abs=0.25), f"observed order {order:.3f}, errors {errs}"
    # measured 5.7e-3 at dt = 4e-3 (0.67 of the stability bound)
    assert errs[0] < 1e-2


def test_constraint_error_at_round_off(wavy_rod):
    r = simulate(wavy_rod, (), dt=2e-3, t_end=20.0, frames=11)
    assert r.success
    # round-off floor: eps * max|x| / h = 2.2e-16 * 4.6 / 0.115 ~ 1e-14
    assert r.stats["constraint_error"] < 5e-14
    for x in r.positions:
        err, _ = dynamics.constraint_error(x, wavy_rod.edge_len)
        assert err < 5e-14
    assert r.stats["iterations_max"] <= 3


def test_energy_conserved_with_gravity(wavy_rod):
    """Bending + gravity: kinetic + bending + potential conserved during free fall."""
    # the ground far below and no damping (exp(0) = 1): the ground tests' stepper
    err, r = _energy_error(wavy_rod, 2e-3, 3.0, (Gravity(1.0), Ground(-1e9), Damping(0.0)))
    assert set(r.energies) == {"kinetic", "bending", "gravity", "total"}
    # uniform gravity does not couple to the shape: the error is the bending one
    # (1.49e-3 of the bending energy at dt = 2e-3), although the fall injects a kinetic
    # energy M g**2 t**2 / 2 = 20, 100 times the bending energy
    assert err < 2e-3
    assert r.energies["kinetic"][-1] > 20.0
    # centre of mass falls exactly as g t**2 / 2 (Verlet is exact for constant forces)
    m = wavy_rod.mass
    zc = (r.positions[:, :, 1] * m).sum(axis=1) / m.sum()
    np.testing.assert_allclose(zc - zc[0], -0.5 * r.times**2, atol=1e-9)


def test_momentum_conserved(wavy_rod):
    rod = wavy_rod.copy()
    rod.v[:, 0] = 0.3
    rod.v[:, 1] = -0.1
    r = simulate(rod, (), dt=2e-3, t_end=5.0, frames=6)
    m = rod.mass
    p0 = (m[:, None] * rod.v).sum(axis=0)
    p1 = (m[:, None] * r.velocities).sum(axis=0)
    np.testing.assert_allclose(p1, p0, atol=1e-12)
