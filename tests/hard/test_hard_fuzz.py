"""Fuzzing the scene input through the command line (in-process) and the API.

Invalid scenes always get the clear error: exit code 2, nothing on stdout, one stderr line
starting with the key and naming the value; the API raises SceneError with the same key.
Valid scenes never give a NaN silently: ``show --json`` derived quantities are finite, and
a quick ``folds`` on small random supp-fig5 variants gives folds with finite values (or
says clearly why a fold is not located). Profile: tests/conftest.py (derandomized).
"""

import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from elastocap.cli import main
from elastocap.scene import SceneError, build_scene, load_scene

pos = st.floats(1e-6, 1e3, allow_nan=False, allow_infinity=False)


@st.composite
def valid_geometry(draw):
    L = draw(st.floats(0.1, 50.0))
    delta = draw(st.floats(1e-3, 1.0)) * L
    center = delta / 2 + draw(st.floats(0.0, 1.0)) * (L - delta)
    center = min(max(center, delta / 2), L - delta / 2)
    return {
        "rod.length": L,
        "drop.wetted_length": delta,
        "drop.center": center,
        "drop.area": draw(pos),
        "drop.line_tension": draw(st.floats(1e-3, 1e3)),
        "rod.bending_modulus": draw(st.floats(1e-3, 1e3)),
    }


def _argv(cmd, over, extra=()):
    argv = [cmd, "supp-fig5"]
    for k, v in over.items():
        argv += ["--set", f"{k}={v!r}" if isinstance(v, float) else f"{k}={v}"]
    return argv + list(extra)


def _numbers(obj, path=""):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _numbers(v, f"{path}.{k}")
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _numbers(v, f"{path}[{i}]")
    elif isinstance(obj, int | float) and not isinstance(obj, bool):
        yield path, float(obj)
    elif isinstance(obj, str) and obj.lower() in ("nan", "inf", "-inf", "infinity"):
        yield path, float(obj)


@settings(max_examples=40)
@given(valid_geometry())
def test_valid_scene_show_json_is_finite(over):
    import contextlib
    import io

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(_argv("show", over, ["--json"]))
    assert code == 0, err.getvalue()
    data = json.loads(out.getvalue())
    bad = [(p, v) for p, v in _numbers(data["derived"]) if not math.isfinite(v)]
    assert not bad, (over, bad)
    # the API agrees with the CLI
    assert load_scene("supp-fig5", over).drop.center == pytest.approx(data["drop"]["center"])


def _invalid_cases():
    """(key, value as typed on the command line, value as the error names it)."""
    num_keys = st.sampled_from(
        [
            "drop.area",
            "rod.length",
            "drop.wetted_length",
            "drop.line_tension",
            "rod.bending_modulus",
            "rod.mass_per_length",
        ]
    )
    nonpos = st.one_of(st.floats(-1e6, 0.0), st.just(-0.0))
    return st.one_of(
        st.tuples(num_keys, nonpos).map(lambda kv: (kv[0], repr(kv[1]), repr(kv[1]))),
        st.tuples(num_keys, st.sampled_from(["nan", "inf", "-inf"])).map(
            lambda kv: (kv[0], kv[1], repr(float(kv[1])))
        ),
        st.tuples(num_keys, st.sampled_from(["true", "'abc'", "[1, 2]"])).map(
            lambda kv: (kv[0], kv[1], {"true": "True", "'abc'": "'abc'", "[1, 2]": "[1, 2]"}[kv[1]])
        ),
        st.tuples(
            st.sampled_from(["effects.damping", "effects.gravity", "numerics.dt"]),
            st.floats(-1e3, -1e-9),
        ).map(lambda kv: (kv[0], repr(kv[1]), repr(kv[1]))),
        st.tuples(
            st.sampled_from(["numerics.n_edges", "numerics.max_steps"]),
            st.sampled_from(["1.5", "-3", "'x'"]),
        ).map(lambda kv: (kv[0], kv[1], {"1.5": "1.5", "-3": "-3", "'x'": "'x'"}[kv[1]])),
        st.tuples(st.just("numerics.accuracy"), st.sampled_from(["'fast'", "3", "'Draft'"])).map(
            lambda kv: (kv[0], kv[1], {"'fast'": "'fast'", "3": "3", "'Draft'": "'Draft'"}[kv[1]])
        ),
        # geometry out of range: the wet interval leaves the rod, Delta > L
        st.floats(1e-6, 10.0).map(lambda e: ("drop.wetted_length", repr(4.6 + e), repr(4.6 + e))),
        st.floats(1e-6, 2.0).map(lambda e: ("drop.center", repr(1.25 - e), repr(1.25 - e))),
    )


@settings(max_examples=60)
@given(_invalid_cases())
def test_invalid_scene_exit_2_naming_key_and_value(case):
    import contextlib
    import io

    key, typed, named = case
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["show", "supp-fig5", "--set", f"{key}={typed}", "--json"])
    msg = err.getvalue()
    assert code == 2, msg
    assert out.getvalue() == ""
    assert msg.count("\n") == 1
    assert msg.startswith(f"elastocap: error: {key}: got "), msg
    assert named in msg, (named, msg)


@settings(max_examples=40)
@given(_invalid_cases())
def test_invalid_scene_api_raises_scene_error_with_the_key(case):
    import tomllib

    key, typed, _named = case
    data = json.loads(json.dumps(load_scene("supp-fig5").data))
    sec, k = key.split(".")
    value = tomllib.loads(f"v = {typed}")["v"]
    data.setdefault(sec, {})[k] = value
    if key == "drop.wetted_length":
        data["drop"].pop("center", None)
    with pytest.raises(SceneError) as exc:
        build_scene(data, "fuzz")
    assert exc.value.key == key
    assert str(exc.value).startswith(f"{key}: got ")


@settings(max_examples=6)
@given(area=st.floats(0.8, 2.5), length=st.floats(3.0, 6.0))
def test_quick_folds_on_random_supp_fig5_variants(area, length):
    """Draft statics on random (A, L): every reported fold has a finite value inside the
    range and a finite measure; its error estimate is finite, or the fold says why not."""
    import contextlib
    import io

    over = {"drop.area": area, "rod.length": length, "drop.wetted_length": 0.5 * length}
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(_argv("folds", over, ["--accuracy", "draft", "--json"]))
    assert code == 0, err.getvalue()
    rep = json.loads(out.getvalue())
    lo, hi = rep["range"]
    for f in rep["folds"]:
        assert isinstance(f["value"], float) and lo <= f["value"] <= hi, f
        if not f["located"]:  # bracketed only: it must say why
            assert f.get("message"), f
            continue
        assert isinstance(f["measure"], float) and math.isfinite(f["measure"]), f
        # a listed fold carries a numeric error estimate (one the finer resolution does
        # not confirm is listed under "unlocated" with its reason)
        est = f["error_estimate"]
        assert isinstance(est, float) and math.isfinite(est), f


# ---------------------------------------------------------------------------------------------
# extremes: tiny and huge numbers, huge integers. The CLI either refuses with the one-line
# error naming the key (the one the API's validation or resource estimate names), exit 2,
# nothing written; or the run is estimated inside the documented limits.
def _log_uniform(lo_exp, hi_exp):
    return st.floats(lo_exp, hi_exp).map(lambda e: 10.0**e)


_EXTREME = st.one_of(
    st.tuples(st.just("numerics.dt"), st.one_of(_log_uniform(-308, -2), st.just(5e-324))),
    st.tuples(st.just("numerics.t_max"), _log_uniform(-308, 300)),
    st.tuples(st.just("numerics.n_edges"), st.integers(1, 2**70)),
    st.tuples(st.just("drop.wetted_length"), _log_uniform(-300, 0.6)),
    st.tuples(st.just("numerics.cheb_points"), st.integers(0, 2**40)),
    st.tuples(st.just("drop.area"), st.integers(10**300, 10**400)),
    st.tuples(st.just("rod.bending_modulus"), _log_uniform(-300, 300)),
)


@settings(max_examples=80)
@given(st.lists(_EXTREME, min_size=1, max_size=3, unique_by=lambda kv: kv[0]),
       st.sampled_from(["impact", "branches"]))
def test_extremes_refused_by_key_or_inside_the_limits(tmp_path_factory, over, cmd):
    import contextlib
    import io

    from elastocap.cli_args import MEMORY_LIMIT, STEPS_LIMIT, check_resources

    over = dict(over)
    expect_key = None
    try:
        scene = load_scene("supp-fig5", over)
        est = check_resources(scene, "impact" if cmd == "impact" else "statics")
    except SceneError as err:
        expect_key = err.key
    if expect_key is None:  # accepted: the estimate is finite and inside the limits
        assert est["memory_bytes"] <= MEMORY_LIMIT
        if cmd == "impact":
            assert math.isfinite(est["steps"]) and 1 <= est["steps"] <= STEPS_LIMIT
        return
    work = tmp_path_factory.mktemp("fuzz")
    out, err = io.StringIO(), io.StringIO()
    argv = [cmd, "supp-fig5", "--out", str(work / "o")]
    for k, v in over.items():
        argv += ["--set", f"{k}={v!r}"]
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    msg = err.getvalue()
    assert code == 2, msg
    assert out.getvalue() == ""
    assert msg.count("\n") == 1 and len(msg) < 400, msg
    assert msg.startswith(f"elastocap: error: {expect_key}: got "), (expect_key, msg)
    assert list(work.iterdir()) == []


def _range_text(lo, ratio, n):
    return f"{lo!r}:{lo * ratio!r}:{n}"


_DELTA_RANGE = st.tuples(_log_uniform(-300, 0.7), st.floats(1.0, 1e3), st.integers(1, 3))


def _expected_refusal(cmd, over, rng):
    """The key the library refuses the command's inputs with (None: accepted), from the
    library's own checks: the scene, the range, and the resource estimates."""
    from elastocap.cli_args import check_resources
    from elastocap.sweep.engine import check_sweep_resources, plan_sweep
    from elastocap.sweep.grid import parse_range

    try:
        if cmd == "sweep":
            deltas = parse_range(_range_text(*rng), "--delta")
            scene = load_scene("fig3-strip", over)
            points, _, res = plan_sweep(scene, [1.0, 2.0], deltas=deltas)
            check_sweep_resources(scene, points, res)
        elif cmd == "overlay":
            scene = load_scene("supp-fig5", over)
            deltas = parse_range(_range_text(*rng), "--delta")
            if len({f"{d:.6g}" for d in deltas}) < len(deltas):  # frames named by Delta
                return "--delta"
            if deltas.max() > scene.rod.length:
                return "--delta"
            for d in (deltas.min(), deltas.max()):
                check_resources(scene.with_overrides({"drop.wetted_length": float(d)}),
                                "impact")
            check_resources(scene, "statics")
        else:  # demo
            scene = load_scene("supp-fig5", over)
            check_resources(scene, "statics")
            check_resources(scene, "impact")
    except SceneError as err:
        return err.key
    except ValueError as err:  # a range refused by its option
        return str(err).split(":")[0]
    return None


@settings(max_examples=60, deadline=None)
@given(st.lists(_EXTREME, min_size=0, max_size=2, unique_by=lambda kv: kv[0]),
       _DELTA_RANGE, st.sampled_from(["sweep", "overlay", "demo"]))
def test_extremes_of_sweep_overlay_demo_refused_by_key(tmp_path_factory, over, rng, cmd):
    """Extreme --set values and ranges: the command refuses with the one-line error naming
    the key the library names, exit 2, nothing written. Accepted inputs are not run (they
    could be long): the library's estimate has admitted them inside the limits."""
    import contextlib
    import io

    over = dict(over)
    if cmd == "sweep":  # set by the sweep on every point
        over.pop("drop.wetted_length", None)
    expect_key = _expected_refusal(cmd, over, rng)
    if expect_key is None:
        return
    work = tmp_path_factory.mktemp("fuzz")
    argv = [cmd, "fig3-strip" if cmd == "sweep" else "supp-fig5", "--out", str(work / "o")]
    if cmd == "sweep":
        argv += ["--x", "1:2:2", "--delta", _range_text(*rng), "--store", str(work / "s.sq")]
    elif cmd == "overlay":
        argv += ["--delta", _range_text(*rng)]
    for k, v in over.items():
        argv += ["--set", f"{k}={v!r}"]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    msg = err.getvalue()
    assert code == 2, (argv, msg)
    assert out.getvalue() == ""
    assert msg.count("\n") == 1 and len(msg) < 400, msg
    assert msg.startswith(f"elastocap: error: {expect_key}: got "), (expect_key, msg)
    assert list(work.iterdir()) == []
