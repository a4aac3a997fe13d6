"""The drop's interface meets the rod: the touch located in time and arclength, the two
policies of ``drop.interface_contact`` ("ignore": the paper's model, flagged; "wet": the
contact line jumps to the touched point, the area kept), and bad values refused."""

import math

import numpy as np
import pytest

from dynamics import RestCriterion, Rod, simulate
from elastocap.cli import main
from elastocap.crossings import (
    INTERFACE_POINTS,
    interface_crossings,
    locate_interface_touch,
)
from elastocap.drop import cap_geometry, capillary_energy_and_gradient
from elastocap.impact import (
    FRAME_SPACING,
    MAX_FRAMES,
    build_effects,
    impact_settings,
    run_impact,
)
from elastocap.scene import SceneError, load_scene

# supp-fig5 at Delta = 4: the interface first touches the rod at t = 5.752 (100 edges),
# next to both contact lines at once (the scene is symmetric): the contact angle reaches pi
# and the interface folds onto the dry rod.  t_max = 7 keeps the runs short.
SHORT = {"drop.wetted_length": 4.0, "numerics.t_max": 7.0, "numerics.n_edges": 100}


def _roof(z_roof):
    """A rod: a flat wet part [0, 2] on the x axis, up a wall at x = 2, back over the drop
    as a flat roof at height z_roof (nodes every 0.05)."""
    h = 0.05
    flat = [(x, 0.0) for x in np.arange(0.0, 2.0, h)]
    wall = [(2.0, z) for z in np.arange(0.0, z_roof, h)]
    roof = [(x, z_roof) for x in np.arange(2.0, -0.5 - 1e-9, -h)]
    x = np.array(flat + wall + roof)
    return x, len(flat) + len(wall)


@pytest.mark.parametrize("area, above, below", [(0.6, 0.3, 0.1), (0.1, 0.05, 0.02),
                                                (1.2, 0.7, 0.02), (0.35, 0.01, 0.01)])
def test_locate_touch_of_a_roof_coming_down_closed_form(area, above, below):
    """A flat roof lowered onto the cap: the touch is where the roof reaches the top of the
    drawn interface (its top segment, at v = +-1/(K-1) of the arc, in closed form)."""
    tau, s_tau, _c, _lam, _k = cap_geometry(area, 2.0)
    k = INTERFACE_POINTS
    v = 1.0 / (k - 1)  # the top segment of the drawn arc joins v = -1/(k-1) and +1/(k-1)
    top = (math.cos(tau * v) - math.cos(tau)) / s_tau  # times d/2 = 1
    x_hi, i_roof = _roof(top + above)
    x_lo = x_hi.copy()
    x_lo[i_roof:, 1] -= above + below  # the roof only (the wall stretches: geometry only)
    s_nodes = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(x_hi, axis=0).T))])
    cap = np.array([area, 0.0, 2.0, 1.0])
    assert interface_crossings(x_hi, s_nodes, cap).size == 0
    assert interface_crossings(x_lo, s_nodes, cap).size == 2
    t = locate_interface_touch(x_hi, x_lo, 10.0, 11.0, s_nodes, cap)
    # the roof is at the top at theta = above / (above + below)
    assert t.time == pytest.approx(10.0 + above / (above + below), abs=1e-9)
    assert t.time_bracket[1] - t.time_bracket[0] < 1e-11
    # the touched point: above x = 1 (the apex), on the roof
    s_apex = s_nodes[i_roof] + 1.0
    assert t.s == pytest.approx(s_apex, abs=1e-9)
    # the flat roof meets the flat top segment of the drawn arc: it crosses the two
    # segments beside it at its ends, which are 2 sin(tau v) / sin(tau) apart
    assert t.s_spread == pytest.approx(2.0 * math.sin(tau * v) / s_tau, abs=1e-9)


def test_locate_touch_refuses_a_bracket_without_a_change():
    x, i_roof = _roof(2.0)
    s_nodes = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(x, axis=0).T))])
    with pytest.raises(ValueError, match="no crossing"):
        locate_interface_touch(x, x, 0.0, 1.0, s_nodes, np.array([0.6, 0.0, 2.0, 1.0]))


@pytest.fixture(scope="module")
def ignore_runs():
    base = load_scene("supp-fig5", SHORT)
    dt = impact_settings(base)["dt"]
    return {
        "dt": run_impact(base),
        "dt/2": run_impact(base.with_overrides({"numerics.dt": dt / 2})),
        "n200": run_impact(base.with_overrides({"numerics.n_edges": 200})),
    }


def _same_up_to_mirror(s, s_ref, L):
    return min(abs(s - s_ref), abs((L - s) - s_ref))


def test_touch_time_converges_in_dt_and_n(ignore_runs):
    """Measured: t = 5.7521727 (dt), 5.7521730 (dt/2); 5.7522, 5.7449, 5.7431 at 100, 200,
    400 edges (second order: the differences shrink by 4.0); S beyond S2 = 4.3 by 0.0084
    (the first drawn segment of the interface), the same at both dt."""
    L = 4.6
    a, b, c = (ignore_runs[k].interface_touches[0] for k in ("dt", "dt/2", "n200"))
    for t in (a, b, c):
        assert t["kind"] == "contact angle" and t["side"] in ("s1", "s2")
        lo, hi = t["step_bracket"]
        assert lo < t["time"] <= hi  # inside the step where the crossing shows
    assert abs(a["time"] - b["time"]) < 1e-6  # the step is converged
    assert _same_up_to_mirror(b["s"], a["s"], L) < 1e-6
    assert abs(a["time"] - 5.7522) < 1e-3
    # resolution: an O(h^2) shift (7.3e-3 from 100 to 200 edges, 1.8e-3 from 200 to 400)
    assert 1e-3 < abs(a["time"] - c["time"]) < 1.5e-2
    assert _same_up_to_mirror(c["s"], a["s"], L) < 1e-4
    # the located touch lies before the first frame that shows the crossing
    r = ignore_runs["dt"]
    assert r.interface_crossing_time - FRAME_SPACING < a["time"] <= r.interface_crossing_time


def test_ignore_is_the_paper_model_bit_for_bit(ignore_runs):
    """Under "ignore" the trajectory is that of one plain simulate() call with the scene's
    effects (the touch is located by re-runs beside it), and the key's default."""
    scene = load_scene("supp-fig5", SHORT)
    assert scene.drop.interface_contact == "ignore"
    st = impact_settings(scene)
    eff = build_effects(scene)
    n = st["n_edges"]
    x0 = np.zeros((n + 1, 2))
    x0[:, 0] = np.linspace(0.0, 4.6, n + 1)
    rod = Rod(x0, np.zeros_like(x0), np.full(n, 4.6 / n), 1.0, 1.0)  # straight, at rest
    ref = simulate(rod, eff.effects, method=st["method"],
                   dt=st["dt"], t_end=st["t_max"],
                   frames=min(MAX_FRAMES, int(st["t_max"] / FRAME_SPACING) + 1),
                   events=eff.events,
                   rest=RestCriterion(st["rest_kinetic"], st["rest_time"]))
    r = ignore_runs["dt"]
    assert np.array_equal(r.simulation.positions, ref.positions)
    assert np.array_equal(r.simulation.energies["total"], ref.energies["total"])
    t = r.interface_touches[0]
    assert t["action"].startswith("flagged") and r.interface_contact == "ignore"
    assert "interface touches the rod at t = 5.752" in r.message
    explicit = load_scene("supp-fig5", {**SHORT, "drop.interface_contact": "ignore"})
    assert explicit.digest() == scene.digest()
    assert load_scene("supp-fig5", {**SHORT, "drop.interface_contact": "wet"}).digest() != \
        scene.digest()


@pytest.fixture(scope="module")
def wet_run():
    return run_impact(load_scene("supp-fig5", {**SHORT, "numerics.t_max": 6.0,
                                               "drop.interface_contact": "wet"}))


def _wet_area(x, s_nodes, cap):
    """The drop's area: the wet polygon (numpy shoelace) plus the cap r^2 (phi - sin phi)/2."""
    s1, s2 = cap[1], cap[2]
    p1 = np.array([np.interp(s1, s_nodes, x[:, 0]), np.interp(s1, s_nodes, x[:, 1])])
    p2 = np.array([np.interp(s2, s_nodes, x[:, 0]), np.interp(s2, s_nodes, x[:, 1])])
    inner = x[(s_nodes > s1) & (s_nodes < s2)]
    poly = np.vstack([p1, inner, p2]) - p1
    a0 = 0.5 * np.sum(poly[:-1, 0] * poly[1:, 1] - poly[1:, 0] * poly[:-1, 1])
    g = np.zeros_like(x)
    _e, tau, kappa = capillary_energy_and_gradient(x, s_nodes, s1, s2, cap[0], cap[3], g)
    r = 1.0 / kappa
    a1 = 0.5 * r * r * (2 * tau - math.sin(2 * tau))
    return a0 + a1


def test_wet_moves_the_contact_line_to_the_touched_point_and_keeps_the_area(wet_run,
                                                                           ignore_runs):
    r, ref = wet_run, ignore_runs["dt"]
    jumps = [t for t in r.interface_touches if t["action"] == "wetted"]
    assert len(jumps) >= 2
    first = jumps[0]
    # the same first touch as under "ignore" (the runs agree up to it)
    t_ign = ref.interface_touches[0]
    assert first["time"] == pytest.approx(t_ign["time"], abs=1e-9)
    assert _same_up_to_mirror(first["s"], t_ign["s"], 4.6) < 1e-9
    # the contact line on the touched side is now the touched point; the other unchanged
    k = "s1" if first["side"] == "s1" else "s2"
    other = "s2" if k == "s1" else "s1"
    assert first[k] == first["s"] and first[other] == pytest.approx({"s1": 0.3, "s2": 4.3}[other])
    # each jump advances the line outwards (the liquid wets, never dewets)
    s1 = [t["s1"] for t in jumps]
    s2 = [t["s2"] for t in jumps]
    assert np.all(np.diff(s1) <= 0) and np.all(np.diff(s2) >= 0)
    # the events of the run are these jumps, fired at the first step with the crossing
    ev = [e for e in r.simulation.events_fired]
    assert len(ev) == len(jumps)
    assert ev[0][0] == first["jump_time"] and first["step_bracket"][1] == first["jump_time"]
    # the area is A = 1.5 on every frame, before and after the jumps, to round-off
    sim = r.simulation
    s_nodes = np.linspace(0.0, 4.6, sim.positions.shape[1])
    cap = np.array([1.5, 0.3, 4.3, 1.0])
    fired = list(ev)
    n_after = 0
    for t, x in zip(sim.times, sim.positions, strict=True):
        while fired and fired[0][0] <= t + 1e-12:
            _t, _name, j, val = fired.pop(0)
            cap[j] = val
        n_after += t > first["jump_time"]
        assert _wet_area(x, s_nodes, cap) == pytest.approx(1.5, abs=1e-12)
    assert n_after > 0
    # no frame after the jumps shows the interface through the rod
    assert r.interface_crossing_time is None


def test_wet_energy_accounting(wet_run):
    """Each jump reports the capillary energy before and after (the cap on the new contact
    lines, same state): the liquid wetting the dry rod releases energy here; the energy
    audit restarts at each jump like at any event, and finds no rise."""
    jumps = [t for t in wet_run.interface_touches if t["action"] == "wetted"]
    for t in jumps:
        assert t["energy_jump"] == pytest.approx(
            t["capillary_energy_after"] - t["capillary_energy_before"], abs=0.0)
        assert t["energy_jump"] < 0.0
    assert wet_run.energy_rise < 1e-3
    assert "contact-line jumps" in wet_run.message


@pytest.mark.parametrize("value", ["soak", 3, True, ""])
def test_bad_interface_contact_values_refused(value):
    with pytest.raises(SceneError) as err:
        load_scene("supp-fig5", {"drop.interface_contact": value})
    assert err.value.key == "drop.interface_contact"
    assert "expected one of ignore, wet" in str(err.value)


def test_bad_interface_contact_on_the_command_line(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = main(["impact", "supp-fig5", "--set", "drop.interface_contact=soak", "--out",
                 str(tmp_path / "out")])
    assert code == 2
    err = capsys.readouterr().err
    assert "drop.interface_contact: got 'soak'; expected one of ignore, wet" in err
    assert not (tmp_path / "out").exists()


def test_scene_file_key_and_summary(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text('[rod]\nlength = 4.6\n[drop]\narea = 1.5\nwetted_length = 4.0\n'
                 'interface_contact = "wet"\n')
    sc = load_scene(f)
    assert sc.drop.interface_contact == "wet"
    assert sc.summary()["drop"]["interface_contact"] == "wet"
    f.write_text('[rod]\nlength = 4.6\n[drop]\narea = 1.5\nwetted_length = 4.0\n'
                 'interface_contact = "Wet"\n')
    with pytest.raises(SceneError, match="drop.interface_contact: got 'Wet'"):
        load_scene(f)


def test_wet_leaves_a_touch_of_the_wet_part_alone():
    """The strip of Fig 3 at x = 2, Delta = 2: the interface first crosses the wet part
    itself, next to S1 (t = 0.2466 at 120 edges), where there is nothing to wet: under
    "wet" it is flagged and the run is the "ignore" run, bit for bit."""
    ov = {"drop.wetted_length": 2.0, "effects.damping": 0.1, "numerics.t_max": 1.0,
          "numerics.n_edges": 120}
    a = run_impact(load_scene("fig3-strip", ov))
    b = run_impact(load_scene("fig3-strip", {**ov, "drop.interface_contact": "wet"}))
    ta, tb = a.interface_touches[0], b.interface_touches[0]
    assert ta["side"] == tb["side"] == "wet"
    assert tb["action"] == "flagged: the touched point is on the wet part"
    assert ta["time"] == tb["time"] == pytest.approx(0.2466, abs=1e-3)
    assert 11.3 < ta["s"] < 11.35  # S1 = 11.3
    assert np.array_equal(a.simulation.positions, b.simulation.positions)
