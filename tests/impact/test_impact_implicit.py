"""The impact run with the implicit stepper (numerics.integrator = "implicit"): the same
outcomes and final shapes as RATTLE on supp-fig5, refused with a ground."""

import pytest

from elastocap.impact import run_impact
from elastocap.scene import SceneError, load_scene


@pytest.mark.parametrize("delta, outcome", [(2.5, "open"), (4.0, "encapsulated")])
def test_implicit_matches_rattle_on_supp_fig5(delta, outcome):
    runs = {
        integ: run_impact(
            load_scene("supp-fig5", {"drop.wetted_length": delta, "numerics.integrator": integ})
        )
        for integ in ("rattle", "implicit")
    }
    imp, ref = runs["implicit"], runs["rattle"]
    assert imp.outcome == ref.outcome == outcome
    assert imp.status == "at_rest" and imp.settings["integrator"] == "implicit"
    # dt = 1/400 of the first free-free period: 17x RATTLE's step at 100 edges
    assert imp.settings["dt"] > 15 * ref.settings["dt"]
    # measured: 6.7e-5 (Delta = 2.5) and 2.3e-4 (Delta = 4), the rest criterion's level
    assert abs(imp.final_measure - ref.final_measure) < 1e-3
    assert imp.energy_rise < 1e-3
    for a, b in (
        (imp.rod_crossing_time, ref.rod_crossing_time),
        (imp.interface_crossing_time, ref.interface_crossing_time),
    ):
        assert (a is None) == (b is None)
        if a is not None:
            assert abs(a - b) <= 0.06  # one frame (0.05) plus a step


def test_implicit_with_a_ground_is_refused_clearly():
    with pytest.raises(SceneError, match=r"^numerics.integrator: got 'implicit'.*ground"):
        load_scene("fig3-strip", {"numerics.integrator": "implicit"})
    allowed = r"^numerics.integrator: got .euler.; expected one of rattle, implicit"
    with pytest.raises(SceneError, match=allowed):
        load_scene("supp-fig5", {"numerics.integrator": "euler"})
