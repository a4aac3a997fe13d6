"""The contact-comparison figure's pieces (elastocap.paper_figures.contact_comparison):
a contact run checked by a brute-force distance that the contact solver does not use, the
shape metric against closed forms, the convergence estimate on an exact sequence, and the
run cache's round trip."""

import json
import math

import numpy as np
import pytest

from elastocap.paper_figures import contact_comparison as cc
from elastocap.scene import load_scene


def _scene(thickness, delta=4.0, n=50):
    return load_scene("supp-fig5", {"drop.wetted_length": delta, "rod.thickness": thickness,
                                    "numerics.n_edges": n})


@pytest.fixture(scope="module")
def pair():
    """supp-fig5 at Delta = 4, 50 edges, without and with the experiments' thickness."""
    return cc.run_record(_scene(0.0)), cc.run_record(_scene(cc.THICKNESS["supp-fig5"]))


def test_contact_run_never_crosses_and_keeps_its_gap(pair):
    free, touch = pair
    d = cc.THICKNESS["supp-fig5"]
    # without a thickness the arms pass through each other (README: t = 10.45 at 100 edges;
    # measured 10.448 at 50), their closest approach far below d
    assert free["rod_crossing_time"] == pytest.approx(10.45, abs=0.05)
    assert free["arm_gap_min"] < 0.1 * d
    # with it: the crossing detector finds nothing, contact acted, and the brute-force
    # node-segment distance (not the solver's) stays >= d on every frame (measured
    # d (1 - 8e-15)) and at rest
    assert touch["rod_crossing_time"] is None
    assert touch["self_contact_steps"] > 0
    assert touch["gap_min_frames"] >= d * (1.0 - cc.GAP_RTOL)
    assert touch["gap_at_rest"] >= d * (1.0 - cc.GAP_RTOL)
    assert touch["outcome"] == free["outcome"] == "encapsulated"
    # contact changes the final shape a little (measured M 1.31631 -> 1.31726)
    assert abs(touch["final_measure"] - free["final_measure"]) < 5e-3


def test_shape_difference_closed_forms():
    n, L, k = 64, 4.6, 0.7
    s = np.linspace(0.0, L, n + 1)
    straight = np.column_stack([s, 0.0 * s])
    arc = np.column_stack([np.sin(k * s) / k, (1.0 - np.cos(k * s)) / k])
    # edge angles of the arc are k at the midpoints: RMS of k (s_mid - mean) over n midpoints
    expected = k * L * math.sqrt((1.0 - 1.0 / n**2) / 12.0)
    assert cc.shape_difference(arc, straight) == pytest.approx(expected, rel=1e-12)
    # rotated, reflected and reversed copies are the same shape
    c, sn = math.cos(0.3), math.sin(0.3)
    moved = arc @ np.array([[c, sn], [-sn, c]]) + 2.0
    mirrored = moved[::-1] * np.array([1.0, -1.0])
    assert cc.shape_difference(arc, moved) < 1e-13
    assert cc.shape_difference(arc, mirrored) < 1e-13
    # a coarser copy of the same arc differs by its discretisation only
    coarse = arc[::2]
    assert cc.shape_difference(arc, coarse) < 2e-2 * expected


def test_convergence_recovers_an_exact_second_order_sequence():
    seq = {n: 3.5 + 7.0 / n**2 for n in (100, 200, 400)}
    conv = cc.convergence(seq)
    assert conv["observed_order"] == pytest.approx(2.0, abs=1e-9)
    assert conv["richardson"] == pytest.approx(3.5, abs=1e-12)
    assert conv["error_estimate"] == pytest.approx(7.0 / 400**2, rel=1e-6)
    assert cc.convergence({100: 3.5, 200: None, 400: 3.4})["richardson"] is None


def test_run_cache_round_trips(tmp_path, monkeypatch):
    sc = _scene(0.0, delta=2.5, n=50)
    first = cc.RunCache(tmp_path / "runs.jsonl").run(sc)

    def no_run(scene):
        raise AssertionError("a cached run was computed again")

    monkeypatch.setattr(cc, "run_record", no_run)
    again = cc.RunCache(tmp_path / "runs.jsonl").run(sc)
    assert again == json.loads(json.dumps(first))
    assert again["outcome"] == "open" and len(again["final_positions"]) == 51


def test_impact_reports_what_self_contact_did(pair, tmp_path, capsys):
    """``elastocap impact`` reports the contact's statistics (JSON ``self_contact``, and a
    line of text), those of the run the figure records; none without a thickness; under
    the "wet" interface policy (several runs stitched), the counts of every run made."""
    from elastocap.cli import main

    free, touch = pair
    d = cc.THICKNESS["supp-fig5"]
    args = ["impact", "supp-fig5", "--set", "drop.wetted_length=4.0", "--set",
            "numerics.n_edges=50", "--progress", "none", "--out", str(tmp_path)]
    assert main([*args, "--set", f"rod.thickness={d}", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    c = rep["self_contact"]
    assert c["steps"] == touch["self_contact_steps"] > 0
    assert c["gap_error"] == touch["self_contact_gap_error"] < 1e-6
    assert c["max_active"] >= 1 and c["failures"] == 0 and c["failure"] == ""
    assert main([*args, "--set", f"rod.thickness={d}"]) == 0
    text = capsys.readouterr().out
    assert f"self-contact: touching in {c['steps']} of {rep['steps']} steps" in text
    # only the crossing that happened is flagged, with what the model lacks for it
    assert ("flagged: the drop's interface crosses the rod at t = 5.80004 "
            "(drop.interface_contact = ignore)") in text
    assert "the rod crosses itself" not in text and "None" not in text
    assert main([*args, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["self_contact"] == {}
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "self-contact: touching" not in text
    assert ("the rod crosses itself at t = 10.4483 (without rod.thickness the model has no "
            "self-contact)") in text
    # "wet": the touch is located by re-running parts of the trajectory, and the jump
    # restarts it; the contact's counts are those of every run made
    from elastocap.impact import run_impact

    wet = run_impact(load_scene("supp-fig5", {"drop.wetted_length": 4.0,
                                              "numerics.n_edges": 50, "rod.thickness": d,
                                              "drop.interface_contact": "wet"}))
    stats = wet.simulation.stats
    assert stats["runs"] > 1 and wet.interface_touches
    assert 0 < wet.self_contact["steps"] <= stats["steps_all_runs"]
    assert wet.self_contact["failures"] == 0


def test_a_sweep_row_records_what_self_contact_did(pair):
    """The sweep's run function stores the contact counts of ``ImpactResult.self_contact``
    (those of the figure's record for the same impact), and none without a thickness."""
    from elastocap.sweep.tasks import run_impact_task

    free, touch = pair
    rows = {}
    for name, d in (("free", 0.0), ("touch", cc.THICKNESS["supp-fig5"])):
        scene = _scene(d)
        rows[name] = run_impact_task("supp-fig5", scene.to_json())
    r = rows["touch"]
    assert r["contact_steps"] == touch["self_contact_steps"] > 0
    assert r["contact_gap_error"] == touch["self_contact_gap_error"] < 1e-6
    assert r["contact_max_active"] >= 1
    assert rows["free"]["contact_steps"] is None
    assert rows["free"]["contact_max_active"] is rows["free"]["contact_gap_error"] is None


def test_runs_combine_counts_summed_extremes_largest_and_the_final_runs_rest():
    """An impact of several runs: counts and costs summed over every run, extremes the
    largest, the last failure reason, the rest from the run whose state ends the impact
    (not always the last made); entries no run has stay absent."""
    from elastocap.impact import combined_stats

    def run(steps, touching, most, gap, failure, force):
        return {"steps": steps, "rejected_steps": 1, "contact_rounds": 2, "compile_time": 0.5,
                "run_time": 1.0, "max_halvings": 0, "iterations_max": steps % 5,
                "constraint_error": 1e-15 * steps, "iterations_mean": 2.0 + steps,
                "self_contact_steps": touching, "self_contact_rounds": touching,
                "self_contact_rebuilds": 3, "self_contact_band_solves": 0,
                "self_contact_dense_solves": touching, "self_contact_velocity_unsettled": 0,
                "self_contact_failures": int(bool(failure)), "self_contact_max_active": most,
                "self_contact_gap_error": gap, "self_contact_penetration": 0.1 * most,
                "self_contact_force": force, "self_contact_failure": failure}

    a, b, c = run(100, 40, 3, 1e-9, "", 1.0), run(7, 0, 0, 0.0, "diverged", 2.0), \
        run(50, 5, 1, 1e-12, "", 3.0)
    s = combined_stats([a, b, c], b)
    assert (s["self_contact_steps"], s["self_contact_dense_solves"]) == (45, 45)
    assert (s["self_contact_rebuilds"], s["self_contact_failures"]) == (9, 1)
    assert (s["rejected_steps"], s["contact_rounds"], s["run_time"]) == (3, 6, 3.0)
    assert (s["self_contact_max_active"], s["self_contact_gap_error"]) == (3, 1e-9)
    assert s["constraint_error"] == 1e-13 and s["iterations_max"] == 2
    assert s["self_contact_failure"] == "diverged"
    # the final run's own: its last step's force, its mean iterations, its steps
    assert (s["self_contact_force"], s["iterations_mean"], s["steps"]) == (2.0, 9.0, 7)
    assert (s["runs"], s["steps_all_runs"]) == (3, 157)
    plain = [{k: v for k, v in r.items() if not k.startswith("self_contact")}
             for r in (a, c)]
    assert not any(k.startswith("self_contact") for k in combined_stats(plain, plain[1]))
