"""The outcome of an impact, decided in one place (elastocap.criteria.impact_verdict), on
hand-made verdict sequences whose answer is known."""

import numpy as np
import pytest

from elastocap.criteria import FREE_ROD, frame_verdicts, impact_verdict
from elastocap.scene import load_scene

T = np.arange(11.0)  # frames at t = 0 ... 10


def _v(enc, **kw):
    args = dict(criterion="c", encapsulated=enc, times=T, success=True, at_rest=True,
                t_max=10.0, rise_ok=True, rise_note="", rod_crossing_time=None,
                rest_advice="raise numerics.t_max, or add damping")
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


# -------------------------------------------------------------- a margin still swinging

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from elastocap.criteria import swing_range  # noqa: E402

FRAME_DT = 0.05


def _damped(m, a, decay, omega, t_end):
    t = np.arange(0.0, t_end, FRAME_DT)
    return t, m + a * np.exp(-decay * t) * np.cos(omega * t)


@settings(max_examples=200, deadline=None)
@given(m=st.floats(-1.0, 1.0), a=st.floats(0.05, 2.0), q=st.floats(0.2, 0.8),
       omega=st.floats(0.5, 3.0), cut=st.floats(0.0, 1.0))
def test_a_swing_read_on_the_wrong_side_of_the_threshold_is_seen(m, a, q, omega, cut):
    """A damped oscillation m + a e^(-g t) cos(w t) (each half-period keeps a fraction q
    of the amplitude) read at any time after its third turn: whenever the last value and
    the rest value m lie on opposite sides of 0 (the reading would be wrong), the swing's
    range covers 0.  Its Aitken limit is m to the frame sampling's accuracy."""
    decay = -np.log(q) * omega / np.pi
    half = np.pi / omega
    t, y = _damped(m, a, decay, omega, (3.0 + 3.0 * cut) * half + 2 * FRAME_DT)
    last = y[-1]
    if abs(last) < 1e-9 or abs(m) < 1e-9:
        return
    sw = swing_range(t, y)
    if np.sign(last) != np.sign(m) and abs(m - last) > 1e-9:
        assert sw is not None and sw.lo < 0.0 < sw.hi, (sw, last)
    if sw is not None and sw.limit is not None:
        # the turns are sampled at frames (measured on 2000 random swings: at most
        # 4.6e-4 a, median 1.3e-5 a)
        assert abs(sw.limit - m) < 2e-3 * a + 1e-9, (sw.limit, m)


@settings(max_examples=100, deadline=None)
@given(m=st.floats(-1.0, 1.0), a=st.floats(-2.0, 2.0), rate=st.floats(0.05, 3.0),
       noise=st.floats(0.0, 1e-6), seed=st.integers(0, 2**16))
def test_a_creep_across_the_threshold_is_no_swing(m, a, rate, noise, seed):
    """A monotone approach m + a e^(-r t) (overdamped creep), with wiggles far below the
    margin left at the end: never read as swinging, whichever side of 0 it started."""
    t = np.arange(0.0, 30.0, FRAME_DT)
    y = m + a * np.exp(-rate * t)
    y += noise * np.random.default_rng(seed).standard_normal(t.size) * min(1.0, abs(m))
    if abs(y[-1]) < 1e-3:
        return
    assert swing_range(t, y) is None


def test_a_swing_that_died_out_long_ago_is_no_swing():
    # three turns about m = 0.2, then a creep for ten half-periods: the time since the
    # last turn is far beyond twice the half-period
    t, y = _damped(0.2, 1.0, 0.5, 2.0, 4.0)
    t2 = np.arange(t[-1] + FRAME_DT, 40.0, FRAME_DT)
    y2 = -0.3 + (y[-1] + 0.3) * np.exp(-(t2 - t[-1]))
    assert swing_range(np.r_[t, t2], np.r_[y, y2]) is None


def test_the_verdict_names_a_swing_across_the_threshold():
    t, y = _damped(0.3, 1.0, 0.1, 1.0, 3.0 * np.pi + 0.1)  # read just after a turn below 0
    assert y[-1] < 0.0 and y[-1] > y[-2]
    v = _v(y < 0.0, times=t, margins=y)
    assert v.outcome == "undecided" and "was still swinging across 0" in v.reason
    assert "extrapolates to rest at +0.3" in v.reason
    # the same frames without margins (a caller that has none) are decided
    assert _v(y < 0.0, times=t).outcome == "encapsulated"


def test_the_swing_half_period_is_given_when_the_swing_is_the_only_reason():
    """run_impact repeats a run with a longer rest test only when the swing alone left it
    undecided: a repeat cannot settle a verdict taken after a self-crossing."""
    t, y = _damped(0.3, 1.0, 0.1, 1.0, 3.0 * np.pi + 0.1)
    alone = _v(y < 0.0, times=t, margins=y)
    assert alone.swing_half_period == pytest.approx(np.pi, rel=0.05)
    crossed = _v(y < 0.0, times=t, margins=y, rod_crossing_time=float(t[1]))
    assert crossed.outcome == "undecided" and crossed.swing_half_period is None
    assert _v(ENC_FROM_4).swing_half_period is None
