"""The capillary effect in the dynamics: energy conservation (the force is the exact
gradient of gamma lambda), the secondary-drop event, and consistency with the statics."""

import numpy as np

from dynamics import Event, Rod, simulate, stable_dt
from elastocap.capillary import Capillary
from elastocap.scene import load_scene
from elastocap.statics.branches import newton, problem_for


def _straight(n, L):
    x = np.zeros((n + 1, 2))
    x[:, 0] = np.linspace(0.0, L, n + 1)
    return Rod(x, np.zeros_like(x), np.full(n, L / n), 1.0, 1.0)


def _drift(dt_fraction, n=40, t_end=10.0, events=()):
    rod = _straight(n, 4.6)
    dt = dt_fraction * stable_dt(rod.edge_len, 1.0, 1.0)
    cap = Capillary(1.5, 0.9, 3.7, 1.0)  # Delta = 2.8, contact lines inside edges
    res = simulate(rod, [cap], dt=dt, t_end=t_end, frames=201, events=events)
    assert res.success, res.message
    E = res.energies["total"]
    return np.max(np.abs(E - E[0])) / abs(E[0]), res


def test_energy_conserved_without_damping_and_drift_scales_as_dt2():
    d1, _ = _drift(0.5)
    d2, _ = _drift(0.25)
    # velocity Verlet + RATTLE: the energy error is O(dt^2) and bounded (no secular drift)
    assert d1 < 1e-5
    assert 3.0 < d1 / d2 < 5.0, (d1, d2)


def test_secondary_drop_event_moves_contact_line_across_edges():
    # S2 jumps from 3.7 to 4.1 (across several nodes) at t = 2
    ev = [Event(2.0, "capillary", "s2", 4.1)]
    drift, res = _drift(0.5, events=ev)
    assert res.events_fired and res.events_fired[0][3] == 4.1
    E = res.energies["total"]
    t = res.times
    before, after = E[t < 2.0 - 1e-9], E[t > 2.0 + 0.05]
    # energy is conserved on each side of the event; the event itself changes gamma lambda
    assert np.ptp(before) / abs(before[0]) < 1e-5
    assert np.ptp(after) / abs(after[0]) < 1e-5
    assert abs(after[0] - before[-1]) > 1e-3


def test_damped_run_settles_on_the_static_equilibrium():
    """Delta = 2.3 with the caption's damping: the rod comes to rest on the flat branch; the
    final shape's measure converges to the statics at O(h^2)."""
    scene = load_scene("supp-fig5", {"drop.wetted_length": 2.3})
    P = problem_for(scene, N=32)
    u = newton(P, np.concatenate([0.5 * np.pi * 0.3 * P.xi, [0.0]]), 2.3, 1e-12)
    ref = P.observables(u, 2.3)
    errs = []
    levels = [20, 40, 80]  # contact lines (L/4, 3L/4) on nodes at every level
    for n in levels:
        rod = _straight(n, 4.6)
        dt = 0.5 * stable_dt(rod.edge_len, 1.0, 1.0)
        from dynamics import Damping, RestCriterion

        res = simulate(
            rod,
            [Capillary(1.5, 1.15, 3.45, 1.0), Damping(1.04)],
            dt=dt,
            t_end=60.0,
            frames=3,
            rest=RestCriterion(1e-14, 1.0),
        )
        x = res.positions[-1]
        e = np.diff(x, axis=0)
        turn = (
            np.sum(
                np.arctan2(
                    e[:-1, 0] * e[1:, 1] - e[:-1, 1] * e[1:, 0], np.sum(e[:-1] * e[1:], axis=1)
                )
            )
            / np.pi
        )
        errs.append(abs(turn - ref["measure"]))
    order = -np.polyfit(np.log(levels), np.log(errs), 1)[0]
    assert 1.7 < order < 2.3, (order, errs)
    assert errs[-1] < 3e-4
