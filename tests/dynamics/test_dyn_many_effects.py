"""Any number of effects compiles: seven effects (gravity, ground, self-contact, damping
and three point loads) run with both methods and give the trajectory of the same rod with
the three loads merged into the first (the other two zero), to round-off.  Both runs use
the same compiled stepper (forces are runtime parameters), so each method compiles once;
it is the stepper of the loaded contact tests of ``test_dyn_contact.py`` (the same effects
in the same order), so the suite compiles it once for both files."""

import numpy as np
import pytest

from dynamics import Damping, Gravity, Ground, PointLoad, Rod, SelfContact, simulate, stable_dt

LOADS = ((0.3, 0.1), (-0.1, 0.25), (0.05, -0.2))


def _rod():
    n, L = 24, 1.0
    h = L / n
    s = np.linspace(0.0, L, n + 1)
    x = np.stack([s, 0.3 + 0.05 * np.sin(3.0 * s)], axis=1)
    # the edges of the wavy line are longer than h: rescale onto equal edges h
    e = np.diff(x, axis=0)
    e *= h / np.linalg.norm(e, axis=1)[:, None]
    x = np.concatenate([x[:1], x[0] + np.cumsum(e, axis=0)])
    v = np.zeros_like(x)
    v[:, 1] = 0.2 * np.cos(2.0 * s)
    return Rod(x, v, np.full(n, h), 1.0, 0.05)


def _run(rod, loads, method):
    # a thickness the wavy rod never comes near: the contact code runs, no contact occurs
    common = (Gravity(1.0), Ground(), SelfContact(0.01), Damping(0.05))
    eff = common + tuple(PointLoad(-1, f, name=f"load{k}") for k, f in enumerate(loads))
    dt = 0.5 * stable_dt(rod.edge_len, 1.0, 0.05) * (1 if method == "rattle" else 4)
    return simulate(rod, eff, method=method, dt=dt, t_end=200 * dt, frames=5)


@pytest.mark.parametrize("method", ["rattle", "midpoint"])
def test_seven_effects_compile_and_match_the_merged_loads(method):
    rod = _rod()
    res7 = _run(rod, LOADS, method)
    merged = tuple(np.sum(LOADS, axis=0))
    res_m = _run(rod, (merged, (0.0, 0.0), (0.0, 0.0)), method)
    assert res7.success and res_m.success, (res7.message, res_m.message)
    assert res7.stats["steps"] == res_m.stats["steps"] == 200
    assert res7.stats["constraint_error"] < 1e-12
    assert res7.stats["self_contact_steps"] == res_m.stats["self_contact_steps"] == 0
    # the rod moved (the loads act on the free end), never below the ground
    assert np.abs(res7.positions[-1] - res7.positions[0]).max() > 1e-3
    assert res7.positions[:, :, 1].min() >= 0.0
    # the same forces summed in another order: the same trajectory to round-off
    scale = np.abs(res_m.positions).max()
    assert np.abs(res7.positions - res_m.positions).max() < 1e-12 * scale
    # each load's potential is reported apart; together they are the merged one's
    sum7 = sum(res7.energies[f"load{k}"] for k in range(3))
    assert np.abs(sum7 - res_m.energies["load0"]).max() < 1e-12
    assert not any(res_m.energies[f"load{k}"].any() for k in (1, 2))
    assert np.abs(res7.energies["total"] - res_m.energies["total"]).max() < 1e-12
