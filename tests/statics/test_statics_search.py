"""The statics search on scenes next to supp-fig5: admissible region, honest special
points, settings with limits, and agreement with the (Delta, A) fold curve."""

import json
import math

import numpy as np
import pytest
import strict_json
from family import curve_folds

from elastocap.cli import main
from elastocap.scene import SceneError, load_scene
from elastocap.statics.branches import StaticsError, admissible_range, trace_branches
from elastocap.testing import FoldMismatch, assert_folds, compare_folds


def test_small_drop_finds_the_stable_encapsulated_branch_and_its_fold():
    bs = trace_branches(load_scene("supp-fig5", {"drop.area": 1.0}))
    (fold,) = bs.folds
    # on the (Delta, A) fold curve at A = 1.0 (independent two-parameter continuation)
    (ref,) = curve_folds(1.0, 0.092, 4.6)
    assert fold["value"] == pytest.approx(ref, abs=1e-8)
    assert fold["error_estimate"] < 1e-11 and fold["stability_change"] in ("0->1", "1->0")
    assert bs.unlocated == []
    # both pitchforks located, none reported as a fold
    assert sorted(b["value"] for b in bs.branch_points) == pytest.approx(
        [3.5388778973, 4.2463061487], abs=1e-8)
    stable_wrapped = [br for br in bs.branches
                      if np.any((br.stability == 0) & (br.observables["measure"] > 1.0))]
    assert stable_wrapped


def test_off_centre_drop_ends_on_the_admissible_boundary_without_a_fold():
    sc = load_scene("supp-fig5", {"drop.distance_from_end": 1.6})
    assert admissible_range(sc, "drop.wetted_length")[:2] == (0.0, pytest.approx(3.2))
    bs = trace_branches(sc)
    assert bs.folds == [] and bs.unlocated == []
    assert bs.prange[1] == pytest.approx(3.2) and "clipped" in bs.metadata["range_note"]
    (end,) = [e for e in bs.endpoints if e["kind"] == "admissible_boundary"]
    assert end["value"] == pytest.approx(3.2) and "S2 = L" in end["reason"]
    # the fold of the centred drop (3.4698) lies outside: it is not a fold of this scene
    assert all(br.p.max() <= 3.2 + 1e-12 for br in bs.branches)


def test_other_rod_lists_one_fold_and_no_spurious_one():
    bs = trace_branches(load_scene("supp-fig5", {"rod.length": 5.0, "drop.area": 1.2}))
    (fold,) = bs.folds
    (ref,) = curve_folds(1.2, 0.1, 5.0)
    assert fold["value"] == pytest.approx(ref, abs=1e-8)
    assert math.isfinite(fold["error_estimate"]) and fold["error_estimate"] < 1e-11
    assert bs.unlocated == []
    assert not any(abs(f["value"] - 3.8915) < 1e-3 for f in bs.folds)


@pytest.mark.parametrize(("key", "value", "msg"), [
    ("numerics.newton_tol", 1e-15, "1e-12 <= newton_tol <= 1e-6"),
    ("numerics.cheb_points", 100000, "4 <= cheb_points <= 128"),
    ("numerics.cheb_points", 2, "4 <= cheb_points <= 128"),
    ("numerics.max_steps", 3, "10 <= max_steps <= 100000"),
    ("rod.length", 1e300, "rod.length / l_ec <= 20"),
    ("drop.area", 1e300, "drop.area / l_ec^2 <= 1000"),
])
def test_out_of_range_settings_exit_2_and_write_nothing(tmp_path, capsys, key, value, msg):
    out = tmp_path / "o"
    assert main(["branches", "supp-fig5", "--set", f"{key}={value}", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"elastocap: error: {key}: got ") and msg in err, err
    assert not out.exists()


def test_a_search_without_branches_is_a_diagnosed_failure(monkeypatch, capsys):
    import continuation

    monkeypatch.setattr(continuation.BranchSearch, "_starts", lambda self: iter(()))
    monkeypatch.setattr(continuation.BranchSearch, "_seed_round", lambda self, first: iter(()))
    with pytest.raises(StaticsError, match="no equilibrium branch .* Try a looser"):
        trace_branches(load_scene("supp-fig5"))
    assert main(["folds", "supp-fig5"]) == 1
    assert "statics failed: no equilibrium branch" in capsys.readouterr().err


def test_json_has_numbers_or_null_and_check_reports_unlocated(tmp_path, capsys):
    assert main(["folds", "supp-fig5", "--set", "drop.area=1.0", "--json"]) == 0
    out = strict_json.check(capsys.readouterr().out)
    (f,) = out["folds"]
    assert isinstance(f["error_estimate"], float)
    # a reference expecting a fold the new run could not locate fails with the reason
    ok, table = compare_folds(
        [], [{"value": 3.5}], 1e-8,
        [{"kind": "fold", "value": 3.5000001, "reason": "the fold did not relocate",
          "what_to_try": "finer cheb_points"}])
    assert not ok and "UNLOCATED" in table and "the fold did not relocate" in table
    with pytest.raises(FoldMismatch, match="MISSING"):
        assert_folds([], [{"value": 3.5}])
    with pytest.raises(FoldMismatch, match="UNEXPECTED"):
        assert_folds([{"value": 3.5}], [])


def test_problem_is_immutable_and_records_the_key():
    bs = trace_branches(load_scene("supp-fig5"), error_estimates=False)
    P = bs.problem
    before = dict(P.params)
    P2 = P.with_(**{"drop.area": 1.2})
    assert P.params == before and P2.params["area"] == 1.2 and P2 is not P
    assert all(br.parameter == "drop.wetted_length" for br in bs.branches)
    assert json.loads(json.dumps(bs.branches[0].to_dict()))["parameter"] == "drop.wetted_length"
    with pytest.raises(ValueError, match="not a parameter of the wet elastica"):
        P.with_(**{"drop.colour": 1.0})


def test_range_outside_the_admissible_region_is_bad_input():
    sc = load_scene("supp-fig5", {"drop.distance_from_end": 1.6})
    with pytest.raises(SceneError, match=r"--range: .*admissible region"):
        trace_branches(sc, "drop.wetted_length", (3.3, 4.0))


def test_fold_curves_from_the_command_line_pin_the_cusp(tmp_path, capsys, monkeypatch):
    from elastocap.statics import bistability

    drawn = []
    plot = bistability.plot_bistability
    monkeypatch.setattr(bistability, "plot_bistability",
                        lambda *a, **kw: drawn.append(plot(*a, **kw)) or drawn[-1])
    out = tmp_path / "fc"
    args = ["folds", "supp-fig5", "--curve", "drop.area", "1.2", "1.9", "--json"]
    assert main([*args, "--out", str(out)]) == 0
    rep = strict_json.check(capsys.readouterr().out)
    # the file written: the same report, standard JSON, numbers as numbers or null
    saved = strict_json.check((out / "fold-curves-supp-fig5.json").read_text())
    assert saved["cusps"] == rep["cusps"] and saved["curves"] == rep["curves"]
    assert (out / "fold-curves-supp-fig5.png").exists()
    # the cusp of the (Delta, A) fold curve (A = 1.745, where the two folds of A = 1.74 meet)
    cusp = [c for c in rep["cusps"] if abs(c["value"] - 1.745) < 5e-3]
    assert len(cusp) == 1 and cusp[0]["error_estimate"] < 1e-10
    # near the two folds of A = 1.74 (3.5408, 3.5421); the curve is tilted there
    assert abs(cusp[0]["drop.wetted_length"] - 3.541) < 2e-3
    # every curve stays in the admissible region (Delta <= L = 4.6) and ends on it, in the
    # JSON and in the map drawn
    assert all(max(c["drop.wetted_length"]) <= 4.6 * (1 + 1e-12) for c in rep["curves"])
    assert any(c["drop.wetted_length"][-1] == pytest.approx(4.6, abs=1e-9)
               for c in rep["curves"])
    (fig,) = drawn
    (ax,) = fig.axes
    lines = [ln for ln in ax.get_lines() if ln.get_label() == "fold curve"]
    assert lines and all(max(ln.get_xdata()) <= 4.6 * (1 + 1e-12) for ln in lines)
    # the legend explains every line and marker drawn
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert {ln.get_label() for ln in ax.get_lines()} <= set(legend), legend
    assert any("fold of the scene" in t for t in legend)
    assert any("two folds meet" in t for t in legend)
    ref = tmp_path / "ref.json"
    ref.write_text(json.dumps(rep))
    assert main(["folds", "supp-fig5", "--curve", "drop.area", "1.2", "1.9", "--check",
                 str(ref)]) == 0
    assert "all cusps match" in capsys.readouterr().out
    rep["cusps"][0]["value"] *= 1 + 1e-6
    ref.write_text(json.dumps(rep))
    assert main(["folds", "supp-fig5", "--curve", "drop.area", "1.2", "1.9", "--check",
                 str(ref)]) == 1
    assert main(["folds", "supp-fig5", "--curve", "drop.area", "2.0", "3.0"]) == 2
    assert "contains the scene's drop.area = 1.5" in capsys.readouterr().err


def test_a_fold_curve_through_two_folds_of_the_scene_is_listed_once():
    """At A = 1.70, L = 5.919 the folds Delta = 4.799 and 5.628 lie on one fold curve in A
    (joined by the cusp at A = 1.7123): continued from each, it was listed twice. It is
    listed once, and every fold of the scene still lies on a listed curve."""
    import numpy as np

    from elastocap.statics.bistability import admissible_curve, fold_curves

    sc = load_scene("supp-fig5", {"drop.area": 1.70, "rod.length": 5.919,
                                  "drop.wetted_length": 3.282})
    bs, curves = fold_curves(sc, "drop.area", (1.651, 1.74), ds_max=0.02)
    assert len(bs.folds) == 4 and len(curves) == 3
    ends = []
    for fc in curves:
        q, d, _ = admissible_curve(bs.problem, fc, "drop.area")
        ends.append(tuple(sorted([(round(q[0], 8), round(d[0], 6)),
                                  (round(q[-1], 8), round(d[-1], 6))])))
    assert len(set(ends)) == 3
    # on a curve where it crosses A = 1.70, to the resolution of linear interpolation
    # between curve points 0.02 apart (measured 5.5e-3 for 5.628, next to the cusp where the
    # curve turns; the other folds are curve points, 0)
    for f in bs.folds:
        on = []
        for fc in curves:
            q, d, _ = admissible_curve(bs.problem, fc, "drop.area")
            q, d = np.asarray(q), np.asarray(d)
            for i in np.nonzero(np.diff(np.sign(q - 1.70)))[0]:
                w = (1.70 - q[i]) / (q[i + 1] - q[i])
                on.append(abs(d[i] + w * (d[i + 1] - d[i]) - f["value"]))
            on += list(np.abs(d[q == 1.70] - f["value"]))
        assert min(on) < 1e-2, (f["value"], min(on))
