"""Hard cases of the dynamics and the impact run: high resolution, long undamped runs with
the capillary effect, a rod lying on the ground for a long time, a secondary-drop event in a
scene, a run that cannot be integrated (it must say so), and impacts either side of the
selection threshold (slow)."""

import numpy as np
import pytest

from dynamics import Damping, Gravity, Ground, Rod, constraint_error, simulate, stable_dt
from elastocap.capillary import Capillary
from elastocap.impact import impact_settings, run_impact
from elastocap.scene import build_scene, load_scene

# supp-fig5, damping 0.2: Delta* = 3.5273 (100 edges), 3.5265 (200 edges); wp_dynamics.py
DELTA_STAR = 3.527


def _straight(n, L):
    x = np.zeros((n + 1, 2))
    x[:, 0] = np.linspace(0.0, L, n + 1)
    return Rod(x, np.zeros_like(x), np.full(n, L / n), 1.0, 1.0)


def test_high_resolution_impact_n400_short_run():
    """400 edges (dt = 3e-5, 33,600 steps to t = 1): completes, keeps the edges at
    round-off, and agrees with 200 edges at O(h^2) (measured difference 6e-4)."""
    fine = run_impact(load_scene("supp-fig5", {"numerics.n_edges": 400, "numerics.t_max": 1.0}))
    coarse = run_impact(load_scene("supp-fig5", {"numerics.n_edges": 200, "numerics.t_max": 1.0}))
    assert fine.status == "completed" and fine.settings["n_edges"] == 400
    sim = fine.simulation
    L = 4.6
    err, _edge = constraint_error(sim.positions[-1], np.full(400, L / 400))
    assert err < 1e-12
    assert np.all(np.isfinite(sim.energies["total"]))
    assert abs(fine.final_measure - coarse.final_measure) < 2e-3


def test_long_undamped_capillary_run_has_bounded_energy_error():
    """t = 1000 (about 190,000 steps) without damping: RATTLE's energy error stays bounded
    (6.1e-6 of the energy, measured) and does not grow: the last quarter is no worse than
    twice the first."""
    rod = _straight(30, 4.6)
    res = simulate(
        rod,
        # undamped: Damping(0) multiplies by exp(0) = 1 (supp-fig5's stepper)
        [Capillary(1.5, 0.9, 3.7, 1.0), Damping(0.0)],
        dt=0.5 * stable_dt(rod.edge_len, 1.0, 1.0),
        t_end=1000.0,
        frames=2001,
    )
    assert res.success, res.message
    E = res.energies["total"]
    err = np.abs(E - E[0]) / abs(E[0])
    q = len(E) // 4
    assert err.max() < 2e-5
    assert err[-q:].max() < 2.0 * err[:q].max() + 1e-9
    assert constraint_error(res.positions[-1], rod.edge_len)[0] < 1e-12


def test_rod_resting_on_the_ground_for_a_long_time():
    """A flat strip (fig3-strip's length) lying on the frictionless ground under gravity
    for t = 200 (15,600 steps): it neither sinks nor moves nor gains energy."""
    rod = Rod.straight(60, 14.3, mu=1.0, B=1.0)
    res = simulate(
        rod,
        (Gravity(1.0), Ground(), Damping(0.0)),  # undamped, the ground tests' stepper
        dt=0.5 * stable_dt(rod.edge_len, 1.0, 1.0),
        t_end=200.0,
        frames=101,
    )
    assert res.success, res.message
    z = res.positions[:, :, 1]
    assert z.min() >= 0.0 and z.max() < 1e-12
    assert res.energies["kinetic"].max() < 1e-20
    assert np.abs(res.positions[-1] - res.positions[0]).max() < 1e-12


def test_strip_scene_with_ground_comes_to_rest_above_the_ground():
    scene = load_scene("fig3-strip", {"numerics.accuracy": "draft", "numerics.t_max": 20.0})
    r = run_impact(scene)
    assert r.status in ("at_rest", "completed")
    # an outcome only for a run that came to rest
    assert r.outcome == ("undecided" if r.status == "completed" else r.outcome)
    assert r.outcome in ("open", "encapsulated", "undecided")
    pos = r.simulation.positions
    assert np.all(np.isfinite(pos)) and pos[:, :, 1].min() >= -1e-12


def _scene_with_event(damping):
    data = load_scene("supp-fig5").data
    data = {
        **data,
        "drop": {**data["drop"], "events": [{"time": 2.0, "s2": 4.1}]},
        "effects": {**data.get("effects", {}), "damping": damping},
        "numerics": {"n_edges": 40, "t_max": 6.0},
    }
    return build_scene(data, "event")


def test_secondary_drop_event_in_a_scene_moves_s2_across_edges():
    """The event moves S2 from 3.55 to 4.1 at t = 2: across 4-5 edges of 0.115. Without
    damping the energy is conserved on each side (1e-5) and jumps at the event."""
    scene = _scene_with_event(0.0)
    assert scene.drop.events[0].s2 == 4.1
    r = run_impact(scene)
    sim = r.simulation
    assert sim.success, sim.message
    assert [e[3] for e in sim.events_fired] == [4.1]
    E, t = sim.energies["total"], sim.times
    before, after = E[t < 2.0 - 1e-9], E[t > 2.0 + 0.06]
    assert np.ptp(before) / abs(before[0]) < 1e-5
    assert np.ptp(after) / abs(after[0]) < 1e-5
    assert abs(after[0] - before[-1]) > 1e-3


def test_run_that_cannot_be_integrated_says_so():
    """A line tension of 1e6 at the bending bound blows the first step up: the run reports
    outcome 'failed', where it failed and what to try, never a guessed outcome."""
    r = run_impact(
        load_scene(
            "supp-fig5", {"drop.line_tension": 1e6, "numerics.t_max": 2.0, "numerics.n_edges": 50}
        )
    )
    assert r.outcome == "failed"
    assert r.status in ("shake_failed", "non_finite")
    assert "at t = " in r.message and "try a smaller dt" in r.message


@pytest.mark.slow
@pytest.mark.parametrize(
    "delta, expected", [(DELTA_STAR - 0.02, "open"), (DELTA_STAR + 0.02, "encapsulated")]
)
def test_impacts_either_side_of_the_threshold_are_resolution_stable(delta, expected):
    """Delta* -+ 0.02 with damping 0.2: the outcome holds under halving dt and doubling N
    (Delta* moves by 8e-4 from 100 to 200 edges, 0 when dt is halved: wp_dynamics.py)."""
    base = load_scene("supp-fig5", {"drop.wetted_length": delta})
    dt = impact_settings(base)["dt"]
    runs = [
        run_impact(base),
        run_impact(base.with_overrides({"numerics.dt": 0.5 * dt})),
        run_impact(base.with_overrides({"numerics.n_edges": 200})),
    ]
    for r in runs:
        assert r.status == "at_rest", r.message
        assert r.outcome == expected, (r.final_measure, r.settings["n_edges"], r.settings["dt"])
    # the end states agree to O(h^2) too
    ms = [r.final_measure for r in runs]
    assert max(ms) - min(ms) < 5e-3, ms
