"""dynamics: a planar inextensible discrete elastic rod time-stepper with pluggable effects.

Depends only on numpy and numba.  (Not the unrelated PyPI project of the same name.)

Quick use::

    from dynamics import Rod, Gravity, Ground, simulate
    rod = Rod.straight(100, 4.6, mu=1.0, B=1.0)
    res = simulate(rod, (Gravity(1.0), Ground()), dt=5e-4, t_end=10.0)
    res.positions  # (n_frames, 101, 2); res.energies["total"]; res.message; res.stats
    res = simulate(rod, (Gravity(1.0), Ground()), method="midpoint", dt=5e-3, t_end=10.0)

One driver (:mod:`dynamics.driver`), one module per method (:mod:`dynamics.rattle`,
:mod:`dynamics.midpoint`), one cache of generated steppers (:mod:`dynamics.cache`).
"""

from .bending import bending_energy, bending_force_add, bending_gradient, discrete_curvature
from .constraints import constraint_error
from .driver import (
    METHODS,
    STATS_KEYS,
    Event,
    RestCriterion,
    SimulationResult,
    frame_steps,
    simulate,
)
from .effects import (
    Clamp,
    Damping,
    DistributedLoad,
    Effect,
    Gravity,
    Ground,
    PointLoad,
    SelfContact,
)
from .rattle import DT_BOUND_C, stable_dt
from .reference import euler_bernoulli_omega
from .rod import Rod

__all__ = [
    "Rod",
    "simulate",
    "frame_steps",
    "METHODS",
    "STATS_KEYS",
    "Event",
    "RestCriterion",
    "SimulationResult",
    "stable_dt",
    "DT_BOUND_C",
    "Effect",
    "Gravity",
    "Ground",
    "Damping",
    "PointLoad",
    "DistributedLoad",
    "Clamp",
    "SelfContact",
    "bending_energy",
    "bending_gradient",
    "bending_force_add",
    "discrete_curvature",
    "constraint_error",
    "euler_bernoulli_omega",
]
