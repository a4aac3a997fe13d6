"""Sweep grids: LO:HI:N parsing (errors by message), x in units of l_eg, We^1/2 -> Delta by
the spreading law, and points skipped with a stated reason."""

import numpy as np
import pytest

from elastocap.scene import SceneError, load_scene
from elastocap.sweep import SkippedPoint, SweepPoint, grid_points, make_point, parse_range
from elastocap.sweep.grid import length_unit

STRIP = load_scene("fig3-strip")


def test_parse_range_values():
    np.testing.assert_array_equal(parse_range("1:3:5", "--x"), [1.0, 1.5, 2.0, 2.5, 3.0])
    np.testing.assert_array_equal(parse_range("2:2:1", "--x"), [2.0])
    np.testing.assert_array_equal(parse_range("-1e-1:0.1:3", "--we"), [-0.1, 0.0, 0.1])


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("1:3", r"--x: got '1:3'; expected LO:HI:N"),
        ("a:3:4", r"--x: got 'a:3:4'; expected LO:HI:N"),
        ("1:3:2.5", r"N = '2.5' is not an integer"),
        ("1:3:0", r"N = 0 < 1"),
        ("3:1:4", r"LO = 3 > HI = 1"),
        ("1:3:1", r"N = 1 needs LO = HI"),
        ("nan:3:4", r"finite numbers"),
    ],
)
def test_parse_range_refuses_by_message(text, match):
    with pytest.raises(ValueError, match=match):
        parse_range(text, "--x")


def test_length_unit_is_l_eg_from_the_scene():
    assert length_unit(STRIP) == (1.0, "l_eg")
    # B = 8, mu = 1, g = 1: l_eg = (B / mu g)^(1/3) = 2
    sc = load_scene("fig3-strip", {"rod.bending_modulus": 8.0})
    leg, unit = length_unit(sc)
    assert unit == "l_eg" and leg == pytest.approx(2.0, rel=1e-15)
    p = make_point(sc, 1.5, wetted_length=1.0)
    assert p.x == pytest.approx(3.0, rel=1e-15) and p.x_over_leg == 1.5
    assert length_unit(load_scene("supp-fig5")) == (1.0, "scene")


def test_we_sqrt_converts_to_delta_by_the_spreading_law():
    p = make_point(STRIP, 2.0, we_sqrt=2.0)
    spr = STRIP.spreading
    # Delta = Delta0 + 2 R 0.32 We^1/2 with R = 0.4429, Delta0 = 0.5943 (scene units)
    assert p.wetted_length == pytest.approx(0.5943 + 2 * 0.4429 * 0.32 * 2.0, rel=1e-14)
    assert spr.we_sqrt(p.wetted_length) == pytest.approx(2.0, rel=1e-14)
    q = make_point(STRIP, 2.0, wetted_length=p.wetted_length)
    assert q.we_sqrt == pytest.approx(2.0, rel=1e-14)
    sc = STRIP.with_overrides(p.overrides())
    assert sc.distance_from_end == pytest.approx(2.0) and sc.drop.wetted_length == p.wetted_length


def test_points_leaving_the_rod_are_skipped_with_the_reason():
    # x = 0.2: Delta = 1.16 puts S2 = L - 0.2 + 0.58 beyond L
    p = make_point(STRIP, 0.2, wetted_length=1.16)
    assert isinstance(p, SkippedPoint)
    assert "wet interval [S1, S2] = [13.52, 14.68] leaves the rod [0, L = 14.3]" in p.reason
    assert "Delta = -0.5 <= 0" in make_point(STRIP, 2.0, wetted_length=-0.5).reason
    assert "> L = 14.3" in make_point(STRIP, 7.0, wetted_length=15.0).reason
    # x = 14.0 near S = 0: S1 = 0.3 - Delta / 2 < 0 for Delta = 1
    assert "leaves the rod" in make_point(STRIP, 14.0, wetted_length=1.0).reason
    pts, skipped = grid_points(STRIP, [0.2, 2.0], deltas=[1.16, 2.0])
    assert [(s.x, s.wetted_length) for s in skipped] == [(0.2, 1.16), (0.2, 2.0)]
    assert all(isinstance(p, SweepPoint) for p in pts) and len(pts) == 2


def test_we_sweep_needs_a_spreading_law():
    with pytest.raises(SceneError, match=r"spreading: got None; a We\^1/2 sweep needs"):
        make_point(load_scene("supp-fig5"), 1.0, we_sqrt=1.0)
