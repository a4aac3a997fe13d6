"""The outcome of an impact, decided in one place (elastocap.criteria.impact_verdict), on
hand-made verdict sequences whose answer is known."""

import numpy as np
import pytest

from elastocap.criteria import FREE_ROD, frame_verdicts, impact_verdict
from elastocap.scene import load_scene

T = np.arange(11.0)  # frames at t = 0 ... 10


def _v(enc, **kw):
    args = dict(criterion="c", encapsulated=enc, times=T, success=True, at_rest=True,
                t_max=10.0, rise_ok=True, rise_note="", rod_crossing_time=None)
    args.update(kw)
    return impact_verdict(**args)


ENC_FROM_4 = np.arange(11) >= 4  # open, then encapsulated for good from t = 4


def test_decided_run_reads_the_last_verdict_and_when_it_settled():
    v = _v(ENC_FROM_4)
    assert (v.outcome, v.decision_time, v.reason, v.at_rest) == ("encapsulated", 4.0, None, True)
    flicker = ENC_FROM_4.copy()
    flicker[6] = False  # back to open at t = 6, encapsulated again from t = 7
    assert _v(flicker).decision_time == 7.0
    assert _v(np.zeros(11, bool)).outcome == "open" and _v(np.zeros(11, bool)).decision_time == 0


def test_not_at_rest_is_undecided():
    v = _v(ENC_FROM_4, at_rest=False)
    assert v.outcome == "undecided" and not v.at_rest
    assert v.reason == ("would read encapsulated, but the run did not come to rest by t_max = "
                        "10 (raise numerics.t_max, or add damping)")


def test_failed_energy_audit_is_undecided():
    v = _v(ENC_FROM_4, rise_ok=False, rise_note="the total energy rose by 3")
    assert v.outcome == "undecided"
    assert "energy audit failed: the total energy rose by 3" in v.reason


@pytest.mark.parametrize("t_cross, outcome", [(4.5, "encapsulated"), (4.0, "undecided"),
                                              (2.0, "undecided")])
def test_verdict_settled_after_a_self_crossing_is_undecided(t_cross, outcome):
    v = _v(ENC_FROM_4, rod_crossing_time=t_cross)
    assert v.outcome == outcome
    if outcome == "undecided":
        assert f"after the rod crossed itself at t = {t_cross:.4g}" in v.reason


def test_numerical_failure_is_failed_not_undecided():
    assert _v(ENC_FROM_4, success=False).outcome == "failed"
    assert _v(np.zeros(0, bool), times=np.zeros(0)).outcome == "failed"


def test_all_reasons_are_given_together():
    v = _v(ENC_FROM_4, at_rest=False, rise_ok=False, rise_note="x", rod_crossing_time=1.0)
    assert v.reason.count(";") == 2


def test_frame_verdicts_of_the_two_criteria():
    # lab frame (a ground): encapsulated iff x(L) < x(S_c); a flat strip, then one whose
    # free end lies behind the impact centre
    sc = load_scene("fig3-strip")
    L, n = sc.rod.length, 10
    s = np.linspace(0.0, L, n + 1)
    flat = np.stack([s, np.zeros_like(s)], axis=1)
    folded = flat.copy()
    folded[-1, 0] = sc.drop.center - 1.0
    crit, enc, q = frame_verdicts(sc, np.stack([flat, folded]), s, None)
    assert "lab frame" in crit and enc.tolist() == [False, True]
    assert q[0] == pytest.approx(L - sc.drop.center) and q[1] == pytest.approx(-1.0)
    # free rod: M > 1
    crit, enc, _ = frame_verdicts(load_scene("supp-fig5"), np.zeros((3, 4, 2)), None,
                                  [0.3, 1.0, 1.2])
    assert crit == FREE_ROD and enc.tolist() == [False, False, True]
