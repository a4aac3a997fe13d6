"""Scenes: built-ins load, overrides validate, every kind of bad input gets a clear error."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from elastocap.scene import SceneError, build_scene, builtin_scene_names, load_scene, parse_override


def test_builtins_load_with_paper_values():
    assert {"supp-fig5", "fig3-strip", "fig3-experiment"} <= set(builtin_scene_names())
    s = load_scene("supp-fig5")
    assert (s.rod.length, s.drop.area, s.drop.wetted_length) == (4.6, 1.5, 2.5)
    assert s.drop.center == pytest.approx(2.3)
    assert s.effects.names() == ("damping",)
    assert s.effects.damping == 0.2  # an explicit choice: README, "Supplementary Fig 5"
    f = load_scene("fig3-strip")
    assert (f.rod.length, f.drop.area, f.drop.line_tension) == (14.3, 0.36, 40.0)
    assert f.effects.names() == ("gravity", "ground")
    assert f.distance_from_end == pytest.approx(2.0)
    assert f.spreading.we_sqrt(f.spreading.delta(1.7)) == pytest.approx(1.7, rel=1e-14)


def test_overrides_and_position_choice():
    s = load_scene("supp-fig5", ["drop.wetted_length=4", "drop.area=1.0"])
    assert s.drop.wetted_length == 4.0 and s.drop.area == 1.0
    f = load_scene("fig3-strip", {"drop.center": 10.0})  # replaces distance_from_end
    assert f.distance_from_end == pytest.approx(4.3)
    assert load_scene("supp-fig5").digest() == load_scene("supp-fig5").digest()
    assert load_scene("supp-fig5").digest() != s.digest()


def _base():
    return {"rod": {"length": 4.0}, "drop": {"area": 1.0, "wetted_length": 2.0}}


@pytest.mark.parametrize(
    ("patch", "key", "fragment"),
    [
        ({"rod": {"lenght": 4.0}}, "rod.lenght", "Did you mean 'length'?"),
        ({"drop": {"area": 1.0}}, "drop.wetted_length", "missing"),
        ({"rod": {"length": "long"}}, "rod.length", "expected a number"),
        ({"rod": {"length": -4.0}}, "rod.length", "expected a number > 0"),
        ({"rod": {"length": 0.0}}, "rod.length", "expected a number > 0"),
        ({"drop": {"area": 0.0, "wetted_length": 2.0}}, "drop.area", "> 0"),
        ({"drop": {"area": math.nan, "wetted_length": 2.0}}, "drop.area", "not NaN or inf"),
        ({"drop": {"area": math.inf, "wetted_length": 2.0}}, "drop.area", "not NaN or inf"),
        (
            {"drop": {"area": 1.0, "wetted_length": 5.0}},
            "drop.wetted_length",
            "<= rod.length = 4.0",
        ),
        (
            {"drop": {"area": 1.0, "wetted_length": 2.0, "center": 0.5}},
            "drop.center",
            "must lie inside [0, rod.length",
        ),
        (
            {"drop": {"area": 1.0, "wetted_length": 2.0, "distance_from_end": 0.2}},
            "drop.distance_from_end",
            "must lie inside",
        ),
        (
            {"drop": {"area": 1.0, "wetted_length": 2.0, "center": 2.0, "distance_from_end": 2.0}},
            "drop.center",
            "not both",
        ),
        ({"effects": {"ground": 1}}, "effects.ground", "true or false"),
        ({"effects": {"gravity": -1.0}}, "effects.gravity", ">= 0"),
        ({"effects": {"gravty": 1.0}}, "effects.gravty", "Did you mean 'gravity'?"),
        ({"numerics": {"accuracy": "best"}}, "numerics.accuracy", "draft, default, publication"),
        ({"numerics": {"n_edges": 10.5}}, "numerics.n_edges", "whole number"),
        ({"dorp": {}}, "dorp", "Did you mean 'drop'?"),
        (
            {"drop": {"area": 1.0, "wetted_length": 2.0, "events": [{"time": 1.0}]}},
            "drop.events[0]",
            "needs a new 's1' and/or 's2'",
        ),
        (
            {"drop": {"area": 1.0, "wetted_length": 2.0, "events": [{"time": 1.0, "s2": 9.0}]}},
            "drop.events[0].s2",
            "<= rod.length",
        ),
        (
            {"drop": {"area": 1.0, "wetted_length": 2.0, "events": [{"time": 1.0, "s2": 0.5}]}},
            "drop.events[0]",
            "s1 < s2",
        ),
    ],
)
def test_bad_input_names_key_value_and_allowed(patch, key, fragment):
    data = _base()
    for sec, vals in patch.items():
        if sec in data and isinstance(vals, dict) and sec != "drop":
            data[sec] = {**vals}
        else:
            data[sec] = vals
    with pytest.raises(SceneError) as info:
        build_scene(data)
    assert info.value.key == key
    assert fragment in str(info.value)
    assert str(info.value).startswith(f"{key}: got ")


def test_bad_overrides():
    with pytest.raises(SceneError, match="expected KEY=VALUE"):
        load_scene("supp-fig5", ["drop.area"])
    with pytest.raises(SceneError, match=r"drop.aera: got 1; unknown key.*Did you mean 'area'"):
        load_scene("supp-fig5", ["drop.aera=1"])
    with pytest.raises(SceneError, match="expected SECTION.KEY"):
        load_scene("supp-fig5", ["area=1"])
    with pytest.raises(SceneError, match=r"not a built-in scene .* Did you mean 'supp-fig5'"):
        load_scene("supp-fig6")
    assert parse_override("effects.ground=true") == ("effects.ground", True)
    assert parse_override("numerics.accuracy=draft") == ("numerics.accuracy", "draft")


def test_bad_toml_file(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[rod\nlength = 1")
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(p)


def test_experiment_section_excludes_rod():
    with pytest.raises(SceneError, match="either \\[experiment\\] or \\[rod\\]"):
        load_scene("fig3-experiment", {"rod.length": 3.0})
    with pytest.raises(SceneError, match="experiment.drop_radius: got 0.003; .*covers 1.2 mm "
                       "to 1.85 mm") as err:
        load_scene("fig3-experiment", {"experiment.drop_radius": 3e-3})
    assert err.value.key == "experiment.drop_radius"  # the key at fault, not the section


def test_a_refused_derived_key_names_the_experiment_inputs_it_follows_from():
    """The user of an [experiment] scene never wrote drop.wetted_length: its refusal says
    which of the inputs they wrote it follows from."""
    with pytest.raises(SceneError) as err:
        load_scene("fig3-experiment", {"experiment.impact_speed": 9000.0})
    assert err.value.key == "drop.wetted_length"
    assert "(derived from [experiment]: impact_speed = 9000.0, drop_radius = " in str(err.value)
    with pytest.raises(SceneError) as err:
        load_scene("fig3-experiment", {"experiment.impact_distance": 1.0})
    assert err.value.key == "drop.distance_from_end"
    assert "(derived from [experiment]: impact_distance = 1.0" in str(err.value)
    # a key the user wrote is named as it was, with no note
    with pytest.raises(SceneError) as err:
        load_scene("fig3-experiment", {"drop.interface_contact": "splash"})
    assert "derived from" not in str(err.value)


def test_experiment_bending_modulus_and_youngs_modulus_together_are_refused():
    """Which B was meant is not knowable: bending_modulus with E and nu is refused (the
    thickness alone may go with bending_modulus: it sets the rod's contact)."""
    base = {"experiment.youngs_modulus": 1e6, "experiment.thickness": 55e-6,
            "experiment.poisson_ratio": 0.5}
    with pytest.raises(SceneError, match="youngs_modulus and poisson_ratio given too") as err:
        load_scene("fig3-experiment", base)  # its bending_modulus is set
    assert err.value.key == "experiment.bending_modulus"
    assert load_scene("fig3-experiment", {"experiment.thickness": 55e-6}).rod.thickness > 0


@given(
    length=st.floats(allow_nan=True, allow_infinity=True),
    area=st.floats(allow_nan=True, allow_infinity=True),
    delta=st.floats(allow_nan=True, allow_infinity=True),
)
def test_fuzzed_scenes_either_valid_or_clear_error(length, area, delta):
    data = {"rod": {"length": length}, "drop": {"area": area, "wetted_length": delta}}
    try:
        s = build_scene(data)
    except SceneError as err:
        assert err.key.split(".")[0] in ("rod", "drop")
        assert "got" in str(err)
    else:
        assert 0 < s.drop.wetted_length <= s.rod.length
        assert all(math.isfinite(v) for v in (s.rod.length, s.drop.area, s.drop.s1, s.drop.s2))


def test_digest_depends_on_values_not_on_how_they_are_typed():
    a = load_scene("supp-fig5", ["numerics.t_max=40"])
    b = load_scene("supp-fig5", ["numerics.t_max=40.0"])
    c = load_scene("supp-fig5", ["numerics.t_max=41"])
    d = load_scene("supp-fig5", ["drop.center=2.3"])  # the default, written out
    assert a.digest() == b.digest() != c.digest()
    assert d.digest() == load_scene("supp-fig5").digest()


def test_rod_thickness_key():
    # off by default and absent from the digest; in scene units; refused beyond L/10
    base = load_scene("supp-fig5")
    assert base.rod.thickness == 0.0
    assert load_scene("supp-fig5", ["rod.thickness=0"]).digest() == base.digest()
    s = load_scene("supp-fig5", ["rod.thickness=0.02"])
    assert s.rod.thickness == 0.02 and s.digest() != base.digest()
    for bad, frag in (("-0.1", "expected"), ("0.5", "thickness <= 0.1 x rod.length = 0.46")):
        with pytest.raises(SceneError, match=r"rod\.thickness: got") as err:
            load_scene("supp-fig5", [f"rod.thickness={bad}"])
        assert frag in str(err.value)
    # an [experiment] gives it as h / l_eg (its length unit); without h, contact stays off
    exp = load_scene("fig3-experiment")
    assert exp.rod.thickness == 0.0
    e = load_scene("fig3-experiment", ["experiment.bending_modulus=2.178e-8",
                                        "experiment.thickness=1e-4"])
    leg = e.experiment.l_eg
    assert math.isclose(e.rod.thickness, 1e-4 / leg, rel_tol=1e-12)


def test_every_toolkit_error_pickles_with_its_fields():
    """A worker's refusal crosses a process boundary (the sweep's pool, dask) intact."""
    import pickle

    from continuation import JacobianError
    from dynamics.cache import CacheError
    from elastocap.io import OutputError
    from elastocap.scene import SceneError
    from elastocap.statics.branches import StaticsError
    from elastocap.sweep.store import StoreError

    for err in (SceneError("drop.area", 1e300, "expected 0 < area < 10"),
                OutputError("--out", "/x", "expected a writable folder")):
        back = pickle.loads(pickle.dumps(err))
        assert type(back) is type(err) and str(back) == str(err)
        assert (back.key, back.value, back.allowed) == (err.key, err.value, err.allowed)
    for cls in (StaticsError, StoreError, JacobianError, CacheError):
        back = pickle.loads(pickle.dumps(cls("what went wrong")))
        assert type(back) is cls and str(back) == "what went wrong"


def test_a_scene_and_its_data_cannot_be_changed():
    """``data`` is what a scene was built from and what its runs record: read-only, nested
    tables and arrays too, through copies and pickles; a caller's dict changed later does
    not change the scene."""
    import copy
    import json
    import pickle

    from elastocap.scene import build_scene, load_scene

    sc = load_scene("supp-fig5")
    for change in (lambda d: d.__setitem__("name", "x"), lambda d: d["rod"].update(length=9.0),
                   lambda d: d["drop"].pop("area"), lambda d: d.clear(),
                   lambda d: d.setdefault("effects", {})):
        with pytest.raises(TypeError, match="a Scene is immutable"):
            change(sc.data)
    for other in (copy.deepcopy(sc.data), copy.copy(sc.data), pickle.loads(pickle.dumps(sc)).data):
        with pytest.raises(TypeError):
            other["rod"]["length"] = 9.0
        assert other == sc.data
    raw = json.loads(sc.to_json())
    raw["drop"]["events"] = [{"time": 0.5, "s2": 3.5}]
    ev = build_scene(raw, "ev")
    raw["rod"]["length"] = 9.0
    raw["drop"]["events"].append({"time": 1.0, "s2": 3.6})
    assert ev.rod.length == 4.6 and ev.data["rod"]["length"] == 4.6
    assert len(ev.data["drop"]["events"]) == 1
    with pytest.raises(TypeError):
        ev.data["drop"]["events"].append({"time": 1.0})
    assert ev.with_overrides({"effects.damping": 0.3}).rod.length == 4.6
    assert json.loads(ev.to_json()) == json.loads(json.dumps(ev.data))
