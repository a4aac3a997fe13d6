"""elastocap.units reproduces the paper's own numbers (main text and Methods)."""

import math

import pytest

from elastocap import units
from elastocap.scene import load_scene

# The paper's experiment: R = 1.55 mm, h = 55 um, mu = 51.8 g/m^2, gamma = 72 mN/m,
# rho = 1000 kg/m^3, L = 5 cm, w = 2 mm. E and nu are not given; B follows from the quoted
# l_ec = 0.55 mm.
B_PAPER = 0.072 * 0.55e-3**2


def _paper(**kw):
    args = dict(
        drop_radius=1.55e-3,
        areal_mass=51.8e-3,
        length=0.05,
        impact_distance=7e-3,
        bending_modulus=B_PAPER,
    )
    args.update(kw)
    return units.Experiment(**args)


def test_length_scales_match_paper():
    e = _paper()
    assert e.l_gc == pytest.approx(2.7e-3, abs=0.05e-3)  # "l_gc ~ 2.7 mm"
    assert e.l_ec == pytest.approx(0.55e-3, rel=1e-12)  # by construction of B_PAPER
    assert e.l_eg == pytest.approx(3.5e-3, abs=0.05e-3)  # "l_eg ~ 3.5 mm"
    assert 0.05 / e.l_eg == pytest.approx(14.3, abs=0.05)  # "L / l_eg = 14.3"


def test_dimensionless_line_tension_and_area_match_methods():
    dim = _paper().dimensionless()
    assert dim.line_tension == pytest.approx(40.0, rel=0.02)  # "gamma* = 40"
    assert dim.area == pytest.approx(0.36, abs=0.005)  # "A* = 0.36"
    assert dim.gravity == 1.0


def test_bending_modulus_formula():
    B = units.bending_modulus(1.2e6, 55e-6, 0.5)
    assert B == pytest.approx(1.2e6 * 55e-6**3 / (12 * 0.75), rel=1e-15)
    with pytest.raises(ValueError, match=r"poisson_ratio: got 0.7; expected -1 < nu <= 0.5"):
        units.bending_modulus(1e6, 1e-5, 0.7)
    e = units.Experiment(
        drop_radius=1.55e-3,
        areal_mass=0.05,
        length=0.05,
        impact_distance=0.01,
        youngs_modulus=1.2e6,
        thickness=55e-6,
        poisson_ratio=0.5,
    )
    assert e.bending() == pytest.approx(B, rel=1e-15)
    with pytest.raises(ValueError, match="missing: thickness, poisson_ratio"):
        units.Experiment(
            drop_radius=1.55e-3,
            areal_mass=0.05,
            length=0.05,
            impact_distance=0.01,
            youngs_modulus=1e6,
        ).bending()


def test_weber_and_spreading_law_round_trip():
    e = _paper(impact_speed=0.53)
    we = 1000 * 0.53**2 * 1.55e-3 / 0.072
    assert e.weber == pytest.approx(we, rel=1e-15)
    assert e.capillary_velocity == pytest.approx(math.sqrt(0.072 / (1000 * 1.55e-3)), rel=1e-15)
    delta0 = e.quasi_static_spreading()
    delta = e.wetted_length()
    assert (delta - delta0) / (2 * 1.55e-3) == pytest.approx(0.32 * math.sqrt(we), rel=1e-14)
    assert units.weber_from_spreading(delta, 1.55e-3, delta0) == pytest.approx(
        math.sqrt(we), rel=1e-13
    )


def test_delta0_table_interpolation_and_range():
    for r_mm, d_mm in units.DELTA0_TABLE_MM:
        assert units.delta0_for_radius(r_mm * 1e-3) == pytest.approx(d_mm * 1e-3, rel=1e-12)
    assert units.delta0_for_radius(1.55e-3) == pytest.approx(2.08e-3, rel=1e-12)
    with pytest.raises(ValueError, match=r"covers 1.2 mm to 1.85 mm only. Give experiment.delta0"):
        units.delta0_for_radius(2.5e-3)
    e = _paper(drop_radius=2.5e-3, delta0=3e-3)
    assert e.quasi_static_spreading() == 3e-3


def test_builtin_experiment_scene_agrees_with_strip_scene():
    exp = load_scene("fig3-experiment")
    strip = load_scene("fig3-strip")
    assert exp.rod.length == pytest.approx(strip.rod.length, rel=0.002)
    assert exp.drop.line_tension == pytest.approx(strip.drop.line_tension, rel=0.02)
    assert exp.drop.area == pytest.approx(strip.drop.area, rel=0.02)
    assert exp.spreading.drop_radius == pytest.approx(strip.spreading.drop_radius, rel=1e-3)
    assert exp.spreading.delta0 == pytest.approx(strip.spreading.delta0, rel=1e-3)
    assert exp.distance_from_end == pytest.approx(2.0, rel=1e-3)


@pytest.mark.parametrize(
    ("kw", "msg"),
    [
        ({"drop_radius": -1.0}, "drop_radius: got -1.0; expected a finite number > 0"),
        ({"areal_mass": float("nan")}, "areal_mass: got nan; expected a finite number > 0"),
        ({"impact_speed": -0.1}, "impact_speed: got -0.1; expected a finite number >= 0"),
    ],
)
def test_bad_experiment_input(kw, msg):
    with pytest.raises(ValueError, match=msg):
        _paper(**kw).dimensionless()
