"""Newton iterations of the implicit stepper in whole impacts, with and without the drop's
stiffness in the Newton matrix (the ``stiffness`` hook of elastocap.capillary.Capillary):
fewer iterations, the same converged steps."""

import numpy as np
import pytest

from dynamics.midpoint import NEWTON_TOL_X
from elastocap import impact
from elastocap.scene import load_scene


def _run(scene, overrides, dt_multiple, stiffness):
    ov = dict(overrides, **{"numerics.integrator": "implicit"})
    ov["numerics.dt"] = dt_multiple * impact.impact_settings(load_scene(scene, ov))["dt_max"]
    return impact.run_impact(load_scene(scene, ov), stiffness=stiffness)


# (scene, overrides, dt / dt_max, measured mean iterations a step with / without the drop's
# stiffness): fig3-strip's landing and first roll (gamma = 40, a ground, t <= 3, 160 steps)
# and an encapsulating supp-fig5 impact run to rest (1075 steps)
CASES = [
    ("fig3-strip", {"effects.damping": 0.1, "numerics.t_max": 3.0}, 8, 9.81, 12.22),
    ("supp-fig5", {"drop.wetted_length": 4.0}, 64, 6.10, 11.62),
]


@pytest.mark.parametrize("scene, overrides, k, it_on, it_off", CASES)
def test_drop_stiffness_cuts_newton_iterations_not_the_solution(scene, overrides, k, it_on,
                                                                 it_off):
    on = _run(scene, overrides, k, True)
    off = _run(scene, overrides, k, False)
    s_on, s_off = on.simulation, off.simulation
    assert s_on.success and s_off.success
    assert s_on.steps == s_off.steps
    assert s_on.stats["rejected_steps"] == s_off.stats["rejected_steps"] == 0
    # the low-rank part was used: the drop's missing stiffness would slow the simplified
    # Newton to a rate above LOWRANK_MIN_RATE at these steps
    assert s_on.stats["stiffness_lowrank"] > 0 and s_off.stats["stiffness_lowrank"] == 0
    # deterministic counts (the same machine code every run); 0.3 leaves room for another
    # compiler's round-off to tip a step's count by one now and then
    assert s_on.stats["iterations_mean"] == pytest.approx(it_on, abs=0.3)
    assert s_off.stats["iterations_mean"] == pytest.approx(it_off, abs=0.3)
    # the converged steps do not depend on the Newton matrix: each step is solved to
    # NEWTON_TOL_X h (7e-15 on fig3-strip, 5e-15 on supp-fig5), which the contact and
    # capillary dynamics amplify over the run; measured 1.0e-10 and 1.2e-11
    assert np.abs(s_on.positions - s_off.positions).max() < 1e5 * NEWTON_TOL_X
    assert on.outcome == off.outcome
    assert abs(on.final_measure - off.final_measure) < 1e-8
