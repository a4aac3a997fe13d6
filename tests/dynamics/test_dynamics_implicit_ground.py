"""Ground contact in the implicit-midpoint stepper (dynamics.midpoint): a resting rod stays
put, a dropped rod neither penetrates nor bounces and loses energy, and it follows RATTLE."""

import numpy as np
import pytest
from dyn_helpers import rod_from_angles, simulate_midpoint

from dynamics import Damping, Gravity, Ground, RestCriterion, Rod, simulate, stable_dt
from dynamics.midpoint import (
    ground_rows_matrix,
    ground_rows_residual,
    ground_update,
)

G = (Gravity(1.0), Ground())
#: The same effects for RATTLE, undamped (Damping(0) multiplies by exp(0) = 1, the same
#: trajectory bit for bit): the compiled stepper of the ground tests of test_dyn_effects
G_RATTLE = (Gravity(1.0), Ground(), Damping(0.0))


def _dropped_rod():
    """40 edges of 0.1, curved and tilted, lowest node 0.3 above the ground, at rest."""
    th = 0.3 + 0.4 * np.sin(np.linspace(0.0, 2.0 * np.pi, 40))
    return rod_from_angles(th, 0.1, origin=(0.0, 0.3))


def test_ground_rows_and_update_kernels():
    n = 4
    x0 = np.zeros((n, 2))
    x0[:, 1] = [0.0, 0.1, 0.0, 0.2]
    d = np.zeros((n, 2))
    d[:, 1] = [0.0, -0.15, 0.0, -0.1]
    held = np.array([1.0, 0.0, 1.0, 0.0])
    rhs = np.arange(3 * n - 1, dtype=float)
    wnu = np.zeros(n)
    ground_rows_residual(x0, d, held, 0.0, rhs, wnu)
    # held rows: the multiplier is minus the momentum residual, the row z1 - z0 = 0
    assert wnu[0] == -1.0 and wnu[2] == -6.0
    assert rhs[1] == 0.0 and rhs[6] == 0.0
    ab = np.ones((3 * n - 1, 22))
    ground_rows_matrix(held, ab)
    assert ab[1, 7] == 1.0 and ab[1].sum() == 1.0 and ab[6].sum() == 1.0
    released = np.zeros(n)
    wnu[:] = [-1.0, 0.0, 2.0, 0.0]
    # node 0 is pulled -> released; node 1 ends at -0.05 -> held, put on the ground
    assert ground_update(x0, d, held, released, wnu, 0.0, 1e-12) == 2
    np.testing.assert_array_equal(held, [0.0, 1.0, 1.0, 0.0])
    assert x0[1, 1] + d[1, 1] == 0.0
    # a released node that penetrates again is held for the rest of the step
    d[0, 1] = -0.01
    wnu[0] = -1.0
    assert ground_update(x0, d, held, released, wnu, 0.0, 1e-12) == 1
    assert held[0] == 1.0 and released[0] == 2.0
    assert ground_update(x0, d, held, released, wnu, 0.0, 1e-12) == 0


def test_heavy_rod_resting_on_the_ground_stays_put():
    """Straight rod on the ground, gravity 50 (heavy: the weight per node over a step is
    far above the tolerances), 10,000 steps at 11x the explicit bound: no drift, no jitter
    (measured: displacement and velocity exactly 0)."""
    rod = Rod.straight(40, 4.0)
    dt = 0.05
    assert dt > 10 * stable_dt(rod.edge_len, 1.0, 1.0)
    r = simulate_midpoint(rod, (Gravity(50.0), Ground()), dt=dt, t_end=500.0, frames=51)
    assert r.success, r.message
    assert r.steps == 10000 and r.stats["rejected_steps"] == 0
    assert np.abs(r.positions - rod.x).max() < 1e-12
    assert np.abs(r.velocities).max() < 1e-12
    assert r.energies["kinetic"].max() < 1e-24
    # no contact change after the first step
    assert r.stats["contact_rounds"] <= 1


@pytest.mark.parametrize("dt", [0.01, 0.005])
def test_dropped_rod_does_not_penetrate_or_bounce_and_loses_energy(dt):
    """A curved rod dropped from 0.3 lands (t ~ 0.8) and settles flat.  Every frame
    (one per step): no node below the ground; the energy never rises by more than the
    midpoint quadrature error (measured 6.8e-4 at dt = 0.01, 1.2e-4 at 0.005, against
    RATTLE's 3.0e-3 at a quarter of its bound; E0 = 4.78); most of it is lost in the
    landing (perfectly inelastic), none of it comes back as a bounce."""
    rod = _dropped_rod()
    t_end = 10.0
    r = simulate_midpoint(rod, G, dt=dt, t_end=t_end, frames=np.arange(0.0, t_end + 1e-9, dt))
    assert r.success, r.message
    z = r.positions[:, :, 1]
    assert z.min() >= 0.0
    E = r.energies["total"]
    rise = np.max(E - np.minimum.accumulate(E))
    assert rise < {0.01: 2e-3, 0.005: 4e-4}[dt] * E[0]
    assert E[-1] < 0.02 * E[0]
    # no bounce: once the lowest node has landed, the centre of mass never rises above
    # its height at landing (a bounce would lift the rod off)
    zc = z @ rod.mass / rod.mass.sum()
    k = int(np.argmax(z.min(axis=1) <= 0.0))
    assert k > 0
    assert zc[k:].max() <= zc[k] + 1e-12
    # the rod ends flat on the ground (its kinetic energy, 0.06 at dt = 0.01 and 0.03 at
    # 0.005, is the unprojected velocity component along the edges that the midpoint rule
    # carries, see dynamics.midpoint: the positions do not move)
    assert z[-1].max() < 1e-9


def test_dropped_rod_follows_rattle():
    """Same drop, implicit at dt = 0.005 (1.1x the explicit bound) against RATTLE at
    0.25x: the difference is of the order of RATTLE's own between 0.25x and 0.5x of its
    bound (measured at t = 1, 2, 5: implicit 2.8e-3, 3.1e-2, 0.11; RATTLE 2.1e-3, 5.4e-2,
    9.7e-2: the sliding, bouncing-free landing is sensitive to the step); both end flat
    with the same centre of mass (horizontal momentum is conserved)."""
    rod = _dropped_rod()
    b = stable_dt(rod.edge_len, 1.0, 1.0)
    fr = np.array([0.0, 1.0, 2.0, 10.0])
    ref = simulate(rod, G_RATTLE, dt=0.25 * b, t_end=10.0, frames=fr)
    ref2 = simulate(rod, G_RATTLE, dt=0.5 * b, t_end=10.0, frames=fr)
    r = simulate_midpoint(rod, G, dt=0.005, t_end=10.0, frames=fr)
    assert r.success and ref.success and ref2.success
    d = np.abs(r.positions - ref.positions).max(axis=(1, 2))
    d_ref = np.abs(ref2.positions - ref.positions).max(axis=(1, 2))
    assert d[1] < 1e-2 and d[2] < 0.1, d
    assert np.all(d[1:3] < 3 * d_ref[1:3] + 1e-3), (d, d_ref)
    assert d[3] < 1e-9


def test_dropped_rod_comes_to_rest_without_damping():
    """Without damping the midpoint rule's sign-flipping velocity mode, excited by the
    landing, keeps v1 (and the reported kinetic energy, 1.3 % of E0) from vanishing on a
    rod that no longer moves; rest is judged on the displacement rate, so the run stops
    (measured: at rest at t = 7.5; RATTLE at a quarter of its bound: 8.9)."""
    r = simulate_midpoint(
        _dropped_rod(), G, dt=0.01, t_end=40.0, frames=5, rest=RestCriterion(1e-10, 1.0)
    )
    assert r.status == "at_rest", r.message
    assert r.t_final < 15.0
    assert r.positions[-1][:, 1].max() < 1e-9  # flat on the ground


def test_contact_changes_by_low_rank_update_give_the_same_steps_with_fewer_factorisations():
    """The held rows switched by a Woodbury update of the factored Newton matrix
    (contact_lowrank) instead of a refactorisation: the same converged steps (the same
    active-set decisions here), about 30 % fewer factorisations."""
    rod = _dropped_rod()
    on, off = (simulate_midpoint(rod, G, dt=0.02, t_end=10.0, frames=101, contact_updates=c)
               for c in (True, False))
    assert on.success and off.success
    assert on.stats["contact_rounds"] == off.stats["contact_rounds"] == 474
    assert on.stats["contact_updates"] == 474
    assert off.stats["contact_updates"] == 0
    # measured 4e-12 (500 steps converged to 1e-13 h)
    assert np.abs(on.positions - off.positions).max() < 1e-9
    # measured 1039 against 1446
    assert on.stats["jacobians"] < 0.8 * off.stats["jacobians"]
