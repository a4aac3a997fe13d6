"""Every bad input gets the one-line error: key, value, what is allowed, exit code 2, and
nothing is written. Resource guards refuse a run estimated above the documented limits."""

import math
import os

import numpy as np
import pytest

from elastocap.cli import main
from elastocap.cli_args import MEMORY_LIMIT, STEPS_LIMIT, impact_estimate
from elastocap.scene import SceneError, load_scene

BIG = "1" + "0" * 400


def _files(path):
    return sorted(str(p.relative_to(path)) for p in path.rglob("*"))


@pytest.fixture
def inputs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "deep.toml").write_text("a = " + "[" * 3000 + "]" * 3000 + "\n")
    (tmp_path / "latin1.toml").write_bytes(b"name = \"caf\xe9\"\n[rod]\nlength = 4.6\n")
    (tmp_path / "exp.toml").write_text(
        "effects = 3\n[experiment]\ndrop_radius = 1.55e-3\nareal_mass = 0.0518\n"
        "length = 7e-3\nimpact_distance = 3e-3\nbending_modulus = 1e-6\n"
    )
    ev = ("[rod]\nlength = 4.6\n[drop]\narea = 1.5\nwetted_length = 2.5\n[effects]\n"
          "damping = 0.2\n[[drop.events]]\ntime = {t}\ns1 = 0.8\n")
    (tmp_path / "ev.toml").write_text(ev.format(t=1.0))
    (tmp_path / "evlate.toml").write_text(ev.format(t=100.0))
    (tmp_path / "evtwice.toml").write_text(ev.format(t=1.0) + "[[drop.events]]\ntime = 1.0\n"
                                           "s1 = 0.9\n")
    (tmp_path / "folder").mkdir()
    return tmp_path


# (argv, the key the message starts with, a fragment of what is allowed)
CASES = [
    (["show", "supp-fig5", "--set", f"rod.length={BIG}"], "rod.length", "finite number"),
    (["show", "supp-fig5", "--set", f"numerics.n_edges={BIG}"], "numerics.n_edges", "<= 2147"),
    (["show", "supp-fig5", "--set", "drop.area=1" + "0" * 5000], "drop.area", "too many digits"),
    (["show", "supp-fig5", "--set", "drop.area=" + "[" * 3000 + "]" * 3000], "drop.area",
     "nested too deeply"),
    (["show", "deep.toml"], "scene", "nested too deeply"),
    (["show", "latin1.toml"], "scene", "not UTF-8 text (byte 0xe9"),
    (["show", "exp.toml"], "effects", "expected a table"),
    (["folds", "supp-fig5", "--check", "folder"], "--check", "this is a folder"),
    (["impact", "supp-fig5", "--set", "numerics.n_edges=10000000"], "numerics.n_edges", "GB"),
    (["impact", "supp-fig5", "--set", "numerics.t_max=1e-308"], "numerics.t_max", "t_max >= "),
    (["impact", "supp-fig5", "--set", "drop.wetted_length=1e-6"], "drop.wetted_length",
     "7.36e+07 edges"),
    (["impact", "supp-fig5", "--set", "numerics.dt=1e-10"], "numerics.dt", "time steps"),
    (["impact", "supp-fig5", "--set", "numerics.t_max=1e12"], "numerics.t_max", "time steps"),
    (["overlay", "supp-fig5", "--delta", "1e-6:3:2"], "drop.wetted_length", "GB"),
    (["branches", "supp-fig5", "--set", "numerics.cheb_points=100000"],
     "numerics.cheb_points", "4 <= cheb_points <= 128"),
    (["demo", "--set", "numerics.dt=1e-10"], "numerics.dt", "time steps"),
    (["overlay", "supp-fig5"], "the following arguments are required: --delta", ""),
    (["impact", "supp-fig5", "--frames", "1"], "--frames", "from 2 to 200"),
    (["impact", "supp-fig5", "--set", "effects.gravity=0.5"], "effects.gravity",
     "fall freely and never come to rest"),
    (["show", "supp-fig5", "--set", "rod.thickness=0.4600001"], "rod.thickness",
     "thickness <= 0.1 x rod.length = 0.46"),
    # the bound quoted is one the refused key accepts (tests/impact/test_impact_rest.py)
    (["impact", "supp-fig5", "--accuracy", "draft", "--set", "drop.wetted_length=4", "--set",
      "numerics.dt=0.003809"], "numerics.dt", "use dt <= 0.003808 or 0"),
    (["impact", "supp-fig5", "--accuracy", "draft", "--set", "drop.wetted_length=4", "--set",
      "numerics.n_edges=2"], "numerics.n_edges", "run with the automatic dt: n_edges = 6"),
    # refused before any progress line: one line on stderr
    (["branches", "supp-fig5", "--progress", "text", "--range", "3", "2"], "--range",
     "LO < HI"),
    (["folds", "supp-fig5", "--progress", "text", "--range", "0", "5"], "--range",
     "0 < LO < HI <= rod.length"),
    (["branches", "fig3-strip", "--progress", "text", "--param", "drop.area"], "--param",
     "drop.wetted_length only"),
    # a range's ends are held to what --set accepts, and Delta to the drop model's range
    (["folds", "supp-fig5", "--range", "1e-300", "1"], "--range",
     "drop.area / Delta^2 <= 1e+12"),
    (["folds", "supp-fig5", "--set", "drop.wetted_length=1e-300"], "drop.wetted_length",
     "Delta >= 1.225e-06 is needed"),
    (["branches", "supp-fig5", "--param", "drop.area", "--range", "1", "1e6"], "--range",
     "drop.area / l_ec^2 <= 1000"),
    (["folds", "supp-fig5", "--param", "drop.line_tension", "--range", "1e-300", "1e300"],
     "--range", "rod.length / l_ec <= 20"),
    # the strip's statics: Delta below the drop model's range, an absurd edge count
    (["folds", "fig3-strip", "--accuracy", "draft", "--range", "1e-9", "1e-8"], "--range",
     "expected LO >= 6e-07: the drop model is checked for drop.area / Delta^2 <= 1e+12"),
    (["folds", "fig3-strip", "--set", "drop.wetted_length=1e-300"], "drop.wetted_length",
     "the statics would need about inf GB"),
    # a refusal of a key the command did not set says which --set it follows from
    (["impact", "supp-fig5", "--set", "rod.length=1e300"], "drop.wetted_length",
     "(with --set rod.length=1e300)"),
    # conflicting inputs: which one was meant is not knowable
    (["show", "supp-fig5", "--set", "drop.center=2", "--set", "drop.distance_from_end=2"],
     "drop.distance_from_end", "give either drop.center or drop.distance_from_end"),
    (["show", "supp-fig5", "--set", "drop.area=1", "--set", "drop.area=2"], "drop.area",
     "set twice (also to 1)"),
    (["impact", "supp-fig5", "--accuracy", "draft", "--set", "numerics.accuracy=publication"],
     "--accuracy", "--set numerics.accuracy=publication says otherwise"),
    (["impact", "supp-fig5", "--out", ""], "--out", "expected a folder"),
    # a rest threshold above a percent of the capillary energy reads a moving rod at rest
    (["impact", "supp-fig5", "--set", "numerics.rest_kinetic=1e9"], "numerics.rest_kinetic",
     "0 < rest_kinetic <= 0.01"),
    # a sweep refuses a grid point whose scene is invalid, or an event after t_max, before
    # its store exists (not as failed runs)
    (["sweep", "ev.toml", "--x", "2:4.2:2", "--delta", "0.5:0.6:2", "--accuracy", "draft",
      "--out", "sw"], "drop.events[0]", "(at the sweep's point x = 4.2, Delta = 0.5)"),
    (["sweep", "evlate.toml", "--x", "2:4.2:2", "--delta", "0.5:0.6:2", "--set",
      "numerics.t_max=20", "--out", "sw"], "drop.events", "event after numerics.t_max = 20"),
    (["show", "evtwice.toml"], "drop.events", "two events at time 1 both set s1"),
    # strong damping: the capped dt needs too many steps (named), never an OverflowError
    (["impact", "supp-fig5", "--set", "effects.damping=1e160"], "effects.damping",
     "capped by the damping"),
    (["sweep", "fig3-strip", "--x", "1:2:2", "--we", "1:2:2", "--set", "effects.damping=1e300"],
     "effects.damping", "less damping"),
    (["impact", "supp-fig5", "--set", "numerics.rest_time=1e300"], "numerics.rest_time",
     "underflows"),
    (["sweep", "fig3-strip", "--x", "1:2:2", "--we=-1:2:2"], "--we", "We^1/2 >= 0"),
    # a worker is a process of its own: thousands of them are a typing error
    (["sweep", "fig3-strip", "--x", "1:2:2", "--we", "1:2:2", "--workers", "100000"],
     "--workers", "4 per core of the"),
    (["sweep", "fig3-strip", "--x", "1:2:2", "--we", "-1:2:2"], "argument --we",
     "written with '='"),
    # sweeps: every run estimated up front at the plan's finest resolution
    (["sweep", "fig3-strip", "--x", "1:2:2", "--delta", "1:2:2", "--set", "numerics.dt=1e-6"],
     "numerics.dt", "2e+08 time steps"),
    (["sweep", "fig3-strip", "--x", "1:2:2", "--delta", "1e-3:2:2"], "drop.wetted_length",
     "smallest Delta (--delta/--we) sets 57200 edges"),
    (["sweep", "fig3-strip", "--x", "1:2:2", "--delta", "1:2:2", "--converge", "4", "--set",
      "numerics.n_edges=3000"], "--converge", "7.16e+08 time steps"),
    (["sweep", "fig3-strip", "--x", "1:2:2", "--delta", "1:2:2", "--set",
      "numerics.n_edges=10000000"], "numerics.n_edges", "3.1e+14 time steps"),
]


@pytest.mark.parametrize("argv,key,allowed", CASES, ids=[" ".join(c[0])[:60] for c in CASES])
def test_one_line_error_exit_2_nothing_written(inputs, capsys, argv, key, allowed):
    before = _files(inputs)
    assert main(argv) == 2
    cap = capsys.readouterr()
    assert cap.out == ""
    assert cap.err.startswith(f"elastocap: error: {key}"), cap.err
    assert allowed in cap.err
    assert cap.err.count("\n") == 1 and len(cap.err) < 400
    assert _files(inputs) == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads a file whatever its mode")
def test_unreadable_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    p = tmp_path / "s.toml"
    p.write_text("[rod]\nlength = 1\n")
    p.chmod(0)
    assert main(["show", "s.toml"]) == 2
    err = capsys.readouterr().err
    assert "scene: got 's.toml'; cannot read the file (Permission denied)" in err


def test_unreadable_file_simulated(tmp_path, monkeypatch, capsys):
    """The same refusal when reading raises (simulated: root reads a mode-000 file)."""
    from pathlib import Path

    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.toml").write_text("[rod]\nlength = 1\n")

    def denied(self):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(Path, "read_bytes", denied)
    assert main(["show", "s.toml"]) == 2
    err = capsys.readouterr().err
    assert err == (
        "elastocap: error: scene: got 's.toml'; cannot read the file (Permission denied)\n"
    )


def test_force_lifts_a_resource_refusal_but_not_an_impossible_run(capsys):
    from elastocap.cli_args import check_resources

    sc = load_scene("supp-fig5", {"numerics.dt": 1e-6})  # 2e8 steps: forceable
    with pytest.raises(SceneError, match="numerics.dt"):
        check_resources(sc, "impact")
    assert check_resources(sc, "impact", force=True)["steps"] == pytest.approx(2e8)
    with pytest.raises(SceneError, match="numerics.dt"):  # 2e12 steps: never
        check_resources(load_scene("supp-fig5", {"numerics.dt": 1e-10}), "impact", True)
    with pytest.raises(SceneError, match="numerics.t_max"):
        check_resources(load_scene("supp-fig5", {"numerics.t_max": 1e-308}), "impact", True)


def test_memory_estimate_against_a_real_run():
    """The estimate covers what a run stores: its trajectory arrays (positions, velocities,
    energies), counted after a real run at a small resolution."""
    from elastocap.impact import run_impact

    sc = load_scene("supp-fig5", {"numerics.t_max": 2.0, "numerics.accuracy": "draft"})
    est = impact_estimate(sc)
    sim = run_impact(sc).simulation
    stored = sim.positions.nbytes + sim.velocities.nbytes
    stored += sum(e.nbytes for e in sim.energies.values())
    assert est["n_edges"] == sim.positions.shape[1] - 1
    assert est["frames"] == sim.positions.shape[0]
    assert stored <= est["memory_bytes"] <= 3 * stored + 1e6
    assert est["steps"] == pytest.approx(sim.t_final / sim.dt, rel=0.05)


def test_limits_are_the_documented_ones():
    assert MEMORY_LIMIT == 2 * 1024**3 and STEPS_LIMIT == 10**8
    # the built-in scenes at every preset are well inside the limits
    for name in ("supp-fig5", "fig3-strip", "fig3-experiment"):
        for acc in ("draft", "default", "publication"):
            est = impact_estimate(load_scene(name, {"numerics.accuracy": acc}))
            assert est["refusal"] is None and est["steps"] < STEPS_LIMIT / 10


# ------------------------------------------------------------------------------- the API
def test_api_accepts_numpy_scalars():
    a = load_scene("supp-fig5", {"numerics.n_edges": np.int64(50), "drop.area": np.float32(1.5),
                                 "effects.ground": np.bool_(False)})
    b = load_scene("supp-fig5", {"numerics.n_edges": 50, "drop.area": 1.5,
                                 "effects.ground": False})
    assert a.numerics.n_edges == 50 and type(a.numerics.n_edges) is int
    assert a.digest() == b.digest()
    assert a.to_json() == b.to_json()  # numpy values saved as plain JSON


def test_negative_zero_keys_like_zero():
    a = load_scene("supp-fig5", {"effects.damping": -0.0})
    b = load_scene("supp-fig5", {"effects.damping": 0.0})
    assert math.copysign(1.0, a.effects.damping) == 1.0
    assert a.digest() == b.digest()


def test_sweep_force_lifts_a_resource_refusal(monkeypatch):
    """--force reaches the sweep: the 2e8-step plan is refused without it and accepted with
    it (the run itself is not started: run_sweep is replaced)."""
    import elastocap.sweep.engine as engine
    from elastocap.sweep.engine import check_sweep_resources, plan_sweep

    sc = load_scene("fig3-strip", {"numerics.dt": 1e-6})
    points, _, res = plan_sweep(sc, [1.0, 2.0], deltas=[1.0, 2.0])
    with pytest.raises(SceneError, match="numerics.dt"):
        check_sweep_resources(sc, points, res)
    assert check_sweep_resources(sc, points, res, force=True)["steps"] == pytest.approx(2e8)
    # the API refuses as the command does, before the store exists
    with pytest.raises(SceneError, match="numerics.dt"):
        engine.run_sweep(sc, [1.0, 2.0], deltas=[1.0, 2.0], store="never.sqlite")
    assert not os.path.exists("never.sqlite")
    seen = {}

    def fake_run_sweep(*a, **kw):
        seen.update(kw)
        raise SystemExit(0)

    monkeypatch.setattr(engine, "run_sweep", fake_run_sweep)
    with pytest.raises(SystemExit):
        main(["sweep", "fig3-strip", "--x", "1:2:2", "--delta", "1:2:2", "--set",
              "numerics.dt=1e-6", "--force", "--out", os.devnull + "-not-used"])
    assert seen["force"] is True


def test_dt_refusal_names_the_cause():
    """The automatic dt of many edges is refused naming what set the edges: Delta when it
    raised the preset's count, numerics.n_edges when set; the rod only at the preset's."""
    from elastocap.impact import impact_settings

    with pytest.raises(SceneError) as err:  # Delta raises the edges -> dt tiny
        impact_settings(load_scene("supp-fig5", {"drop.wetted_length": 1e-4,
                                                 "numerics.t_max": 1e9}))
    assert err.value.key == "drop.wetted_length" and err.value.value == 1e-4
    with pytest.raises(SceneError) as err:
        impact_settings(load_scene("supp-fig5", {"numerics.n_edges": 200000,
                                                 "numerics.t_max": 1e6}))
    assert err.value.key == "numerics.n_edges"
    with pytest.raises(SceneError) as err:  # preset edges, a stiff rod: the rod's doing
        impact_settings(load_scene("supp-fig5", {"rod.bending_modulus": 1e12}))
    assert err.value.key == "rod.bending_modulus"


def test_ctrl_c_is_one_line_and_exit_130(monkeypatch, capsys):
    import elastocap.cli as cli

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setitem(cli.COMMANDS, "show", (interrupted, cli.COMMANDS["show"][1]))
    assert main(["show", "supp-fig5"]) == 130
    err = capsys.readouterr().err
    assert err == "elastocap: interrupted\n"


def test_folds_check_refuses_a_reference_of_another_scene_or_a_broken_one(tmp_path, capsys):
    import json

    ref = {"scene": "fig3-strip", "parameter": "drop.wetted_length",
           "folds": [{"value": 3.4697947515685, "stability_change": "1->0"}]}
    cases = [({**ref}, "made for scene 'fig3-strip', this run is scene 'supp-fig5'"),
             ({**ref, "scene": "supp-fig5", "parameter": "drop.area"},
              "made for parameter 'drop.area'"),
             ({"folds": [{"value": float("nan")}]}, "finite numeric 'value'")]
    for k, (data, fragment) in enumerate(cases):
        path = tmp_path / f"ref{k}.json"
        path.write_text(json.dumps(data))
        assert main(["folds", "supp-fig5", "--check", str(path)]) == 2
        err = capsys.readouterr().err
        assert err.startswith("elastocap: error: --check: got") and fragment in err, err
        assert err.count("\n") == 1
    assert main(["folds", "supp-fig5", "--rtol", "1e-6"]) == 2
    assert "it is the tolerance of --check FILE" in capsys.readouterr().err


def test_a_fold_between_other_stability_indices_does_not_match():
    from elastocap.testing import FoldMismatch, assert_folds, compare_folds

    found = [{"value": 3.4697947515685, "stability_change": "1->0"}]
    ok, table = compare_folds(found, [{"value": 3.4697947515685, "stability_change": "2->1"}])
    assert not ok and "STABILITY" in table and "1->0 in this run, 2->1 in the reference" in table
    # the same fold traced the other way (another rod length) reads "0->1": the same fold
    assert compare_folds(found, [{"value": 3.4697947515685, "stability_change": "0->1"}])[0]
    assert compare_folds(found, [{"value": 3.4697947515685}])[0]  # not recorded: not compared
    for bad in (float("nan"), -1.0, 0.0, True, "1e-8"):
        with pytest.raises(ValueError, match="rtol: got"):
            assert_folds(found, found, rtol=bad)
    with pytest.raises(FoldMismatch):
        assert_folds(found, [{"value": 3.47}])


def test_a_linear_algebra_failure_is_a_numerical_failure_not_bad_input(monkeypatch, capsys):
    """numpy's LinAlgError is a ValueError, but not the user's: exit 1 with what to try."""
    import elastocap.cli as cli

    def fail(args):
        raise np.linalg.LinAlgError("SVD did not converge")

    monkeypatch.setattr(cli, "_load", fail)  # what `show` calls first
    assert main(["show", "supp-fig5"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("elastocap: error: numerical failure in a linear solve of `show`: "
                          "SVD did not converge. Try another resolution")
