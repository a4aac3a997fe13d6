"""The nonlinear stability limit of the RATTLE step: the 4:1 resonance of Stormer-Verlet.

Linear analysis bounds the step by omega_max dt < 2 (``dynamics.DT_BOUND_C``), but
with large-amplitude grid-scale motion (what a rod slapping the ground or a violent impact
excites) the nonlinear coupling of the highest mode with itself resonates where the
Verlet map turns that mode by a quarter period a step: cos(theta) = 1 - (omega dt)**2 / 2
= 0, omega dt = sqrt(2) (Mandziuk & Schlick 1995; Schlick, Mandziuk, Skeel & Srinivas,
J. Comput. Phys. 140, 1998).  These tests measure where a rod with rough velocities on the
ground loses energy stability, check that the threshold sits at sqrt(2), and that the
impact run's automatic step with a ground stays below it.
"""

import math

import numpy as np
import pytest

from dynamics import DT_BOUND_C, Damping, Ground, Rod, simulate, stable_dt
from dynamics.effects import Gravity
from elastocap.impact import DT_FRACTION_GROUND

N_EDGES, LENGTH = 100, 10.0


def rough_rod(seed: int) -> Rod:
    """A wavy rod above the ground with random vertical node velocities (rms 0.3): energy
    in every mode up to the grid scale, as after a violent impact."""
    h = LENGTH / N_EDGES
    s = np.linspace(0.0, LENGTH, N_EDGES + 1)
    x = np.c_[s, 0.3 * (1.0 + np.sin(3.0 * s))]
    e = np.diff(x, axis=0)
    e *= h / np.hypot(e[:, 0], e[:, 1])[:, None]  # exact edge lengths h
    x = np.vstack([x[:1], x[:1] + np.cumsum(e, axis=0)])
    v = np.zeros_like(x)
    v[:, 1] = 0.3 * np.random.default_rng(seed).standard_normal(N_EDGES + 1)
    return Rod(x, v, np.full(N_EDGES, h), 1.0, 1.0)


def energy_rise(omega_dt: float, seed: int) -> float:
    """Largest rise of the total energy above its running minimum over 5 time units,
    relative to the initial energy, at a step with omega_max dt = omega_dt."""
    rod = rough_rod(seed)
    # stable_dt is DT_BOUND_C h**2 sqrt(mu/B) and omega_max = 4 sqrt(B/mu) / h**2
    dt = omega_dt / 4.0 * stable_dt(rod.edge_len, rod.mu, rod.B) / DT_BOUND_C
    # undamped: Damping(0) multiplies by exp(0) = 1 (the stepper of the ground tests)
    r = simulate(rod, [Gravity(1.0), Ground(), Damping(0.0)], dt=dt, t_end=5.0, frames=201,
                 check_dt=False)
    e = r.energies["total"]
    return float(np.max(e - np.minimum.accumulate(e)) / e[0])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_resonance_threshold_is_sqrt2(seed):
    # 5% either side of sqrt(2) = 1.414: bounded (O(dt**2) fluctuations, measured 2e-3 to
    # 7e-3) below, and an energy gain larger than the whole initial energy above
    below = energy_rise(1.35, seed)
    above = energy_rise(1.44, seed)
    assert below < 1e-2, below
    assert above > 1.0, above


def test_automatic_ground_step_is_below_the_resonance():
    omega_dt = 4.0 * DT_BOUND_C * DT_FRACTION_GROUND
    # 10% below sqrt(2): room for the stiffening of DER bending by curvature
    # (sec**2 of half the turning angle: 1.21 at 0.77 rad an edge)
    assert omega_dt < math.sqrt(2.0) / 1.1
    assert max(energy_rise(omega_dt, seed) for seed in range(3)) < 1e-2
