"""The encapsulation criteria on synthetic final shapes of the fig3-strip scene (L = 14.3,
x = 2, Delta = 1.3: S1 = 11.65, S_c = 12.3, S2 = 12.95): a flat strip, a strip whose end is
folded over the drop, and the same shapes moved rigidly. The lab-frame (paper) test flips
when the shape is turned over; the companion test must not."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from elastocap.criteria import (
    companion_outcome,
    final_contact_lines,
    lab_frame_outcome,
    point_and_tangent,
)
from elastocap.scene import load_scene

SCENE = load_scene("fig3-strip", {"drop.distance_from_end": 2.0, "drop.wetted_length": 1.3})
L, S1, SC = 14.3, 11.65, 12.3
N_EDGES = 143  # h = 0.1: S1 = 11.65 and S_c = 12.3 fall inside edges or on nodes alike


def shape(turn_after_s1: float) -> np.ndarray:
    """Nodes (N+1, 2) of a strip flat on z = 0 up to S1, then a circular arc turning by
    ``turn_after_s1`` radians (counterclockwise: up and back over the drop) up to S = L."""
    s = np.linspace(0.0, L, N_EDGES + 1)
    kappa = turn_after_s1 / (L - S1)
    # (cos theta, sin theta) integrated on each edge by the trapezoid rule on 40
    # sub-intervals (error ~ (kappa h / 40)^2 h ~ 1e-8 per edge: the shape need not be exact)
    x = np.zeros((len(s), 2))
    for i in range(len(s) - 1):
        a, b = s[i], s[i + 1]
        pts = np.linspace(a, b, 41)
        th = np.where(pts < S1, 0.0, kappa * (pts - S1))
        x[i + 1] = x[i] + np.array([np.trapezoid(np.cos(th), pts), np.trapezoid(np.sin(th), pts)])
    return x


def rigid(x: np.ndarray, angle: float, shift=(0.0, 0.0), about: int = 0) -> np.ndarray:
    """Rotate nodes ``about:`` by ``angle`` about node ``about`` and translate all by shift."""
    c, s = math.cos(angle), math.sin(angle)
    R = np.array([[c, -s], [s, c]])
    y = x.copy()
    y[about:] = (x[about:] - x[about]) @ R.T + x[about]
    return y + np.asarray(shift)


FLAT = shape(0.0)
FOLDED = shape(1.2 * math.pi)  # the end comes back over the drop: x(L) < x(S_c)
LIFTED = shape(0.4 * math.pi)  # the end lifts but does not come back


def test_flat_strip_is_open_for_both_with_measure_one():
    lab, comp = lab_frame_outcome(FLAT, SCENE), companion_outcome(FLAT, SCENE)
    assert lab.outcome == comp.outcome == "open"
    # (x(L) - x(S_c)) / x = (14.3 - 12.3) / 2 = 1 for a flat strip
    assert lab.measure == pytest.approx(1.0, abs=1e-12)
    assert comp.measure == pytest.approx(1.0, abs=1e-12)
    assert comp.turning == pytest.approx(0.0, abs=1e-12)


def test_folded_end_is_encapsulated_for_both():
    lab, comp = lab_frame_outcome(FOLDED, SCENE), companion_outcome(FOLDED, SCENE)
    assert lab.outcome == comp.outcome == "encapsulated"
    # the base enters the drop along +x: both read the same number, up to the tilt of the
    # edge holding S1 (half of it lies on the arc: angle 0.05 kappa = 0.07 rad, cos-error
    # and sin-lever ~ 0.01)
    assert comp.measure == pytest.approx(lab.measure, abs=0.02)
    assert comp.measure < -0.1
    # turning from S1 to L, 1.2 pi on the curve, is measured between edge chords: from the
    # chord of the edge holding S1 (mean angle kappa 0.05^2 / 2 / h) to the last chord
    # (theta(L) - kappa h / 2)
    kappa, h = 1.2 * math.pi / (L - S1), L / N_EDGES
    expected = (1.2 * math.pi - kappa * h / 2 - kappa * 0.05**2 / 2 / h) / math.pi
    assert comp.turning == pytest.approx(expected, abs=1e-6)


def test_lifted_end_is_open_for_both():
    assert lab_frame_outcome(LIFTED, SCENE).outcome == "open"
    assert companion_outcome(LIFTED, SCENE).outcome == "open"


def test_folded_shape_turned_over_flips_the_lab_test_but_not_the_companion():
    turned = rigid(FOLDED, math.pi, shift=(25.0, 3.0))
    assert lab_frame_outcome(FOLDED, SCENE).outcome == "encapsulated"
    assert lab_frame_outcome(turned, SCENE).outcome == "open"  # the paper's test flips
    comp0, comp1 = companion_outcome(FOLDED, SCENE), companion_outcome(turned, SCENE)
    assert comp1.outcome == "encapsulated"
    assert comp1.measure == pytest.approx(comp0.measure, abs=1e-12)
    assert comp1.turning == pytest.approx(comp0.turning, abs=1e-12)


def test_bundle_alone_flipped_over_keeps_the_companion_verdict():
    """The wet part and the free end rotate as one piece about the contact line S1 (a
    wrapped bundle that lifts off and flips over); the base stays on the ground."""
    k1 = int(np.searchsorted(np.linspace(0, L, N_EDGES + 1), S1)) - 1  # node before S1
    flipped = rigid(FOLDED, math.pi, about=k1)
    assert lab_frame_outcome(flipped, SCENE).outcome == "open"
    comp = companion_outcome(flipped, SCENE)
    assert comp.outcome == "encapsulated"
    assert comp.measure == pytest.approx(companion_outcome(FOLDED, SCENE).measure, abs=1e-12)


@given(
    angle=st.floats(-math.pi, math.pi),
    dx=st.floats(-50, 50),
    dz=st.floats(-50, 50),
    turn=st.floats(0.0, 1.9 * math.pi),
)
def test_companion_is_invariant_under_rigid_motions(angle, dx, dz, turn):
    x = shape(turn)
    a, b = companion_outcome(x, SCENE), companion_outcome(rigid(x, angle, (dx, dz)), SCENE)
    # positions up to |x| ~ 65: round-off of the rotation ~ 1e-14 relative
    assert b.measure == pytest.approx(a.measure, abs=1e-11)
    if abs(a.measure) > 1e-9:
        assert a.outcome == b.outcome


def test_point_and_tangent_interpolates_inside_an_edge():
    p, t = point_and_tangent(FLAT, 11.65, L)
    assert p == pytest.approx([11.65, 0.0], abs=1e-12)
    assert t == pytest.approx([1.0, 0.0], abs=1e-12)


def test_contact_lines_follow_the_drop_events():
    sc = load_scene("fig3-strip", {"drop.distance_from_end": 2.0, "drop.wetted_length": 1.3})
    assert final_contact_lines(sc) == pytest.approx((11.65, 12.95))
    data = sc.data | {"drop": sc.data["drop"] | {"events": [{"time": 1.0, "s1": 11.0}]}}
    from elastocap.scene import build_scene

    assert final_contact_lines(build_scene(data)) == pytest.approx((11.0, 12.95))


@pytest.mark.parametrize(
    ("positions", "match"),
    [
        (np.zeros((3, 3)), r"shape \(n \+ 1, 2\).*got shape \(3, 3\)"),
        (np.array([[0.0, 0.0], [np.nan, 0.0]]), "NaN or inf"),
    ],
)
def test_bad_positions_are_refused_by_message(positions, match):
    with pytest.raises(ValueError, match=match):
        companion_outcome(positions, SCENE)
