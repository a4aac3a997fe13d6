"""The phase-diagram plot: what is drawn (counted), experimental points from a CSV, and the
CSV's errors by message."""

import numpy as np
import pytest

from elastocap.sweep import load_experiments, plot_phase_diagram


def _report():
    runs = []
    for x in (1.0, 2.0):
        for w in (0.5, 1.5, 2.5):
            enc = w > 1.0 + 0.5 * x
            o = "encapsulated" if enc else "open"
            runs.append({"x": x, "we_sqrt": w, "wetted_length": 1.0 + w, "outcome": o,
                         "companion_outcome": o})
    runs[-1]["companion_outcome"] = "open"  # one disagreement, at (2.0, 2.5)
    boundary = [
        {"x": 1.0, "status": "bracketed", "we_sqrt_low": 1.4, "we_sqrt_high": 1.6,
         "wetted_length_low": 2.4, "wetted_length_high": 2.6, "transitions": []},
        {"x": 2.0, "status": "bracketed", "we_sqrt_low": 1.9, "we_sqrt_high": 2.2,
         "wetted_length_low": 2.9, "wetted_length_high": 3.2, "transitions": []},
    ]
    return {"scene": "fig3-strip", "version": "0", "x_unit": "l_eg", "variable": "we_sqrt",
            "runs": runs, "boundary": boundary}


def _line(ax, label):
    return next(ln for ln in ax.get_lines() if ln.get_label() == label)


def test_markers_boundary_and_disagreements(tmp_path):
    fig = plot_phase_diagram(_report(), tmp_path / "p.png")
    ax = fig.axes[0]
    opn, enc = _line(ax, "not encapsulated (4)"), _line(ax, "encapsulated (2)")
    assert len(opn.get_xdata()) == 4 and opn.get_markerfacecolor() == "none"
    assert len(enc.get_xdata()) == 2
    dis = _line(ax, "frame-independent criterion disagrees (1)")
    assert list(dis.get_xdata()) == [2.5] and list(dis.get_ydata()) == [2.0]
    # boundary through the bracket midpoints, half-widths as error bars
    (eb,) = ax.containers
    np.testing.assert_allclose(np.asarray(eb.lines[0].get_xdata(), float), [1.5, 2.05])
    np.testing.assert_allclose(np.asarray(eb.lines[0].get_ydata(), float), [1.0, 2.0])
    segs = eb.lines[2][0].get_segments()
    np.testing.assert_allclose([s[1][0] - s[0][0] for s in segs], [0.2, 0.3])
    assert ax.get_ylabel() == r"$x/\ell_{eg}$" and "We" in ax.get_xlabel()
    assert (tmp_path / "p.png").stat().st_size > 1000
    assert eb.get_label() == "threshold (not verified: run with --verify) (2 lines)"
    assert not [ln for ln in ax.get_lines() if ln.get_label().startswith("undecided")]


def test_undecided_failed_verified_and_the_overrides_in_the_title():
    rep = _report()
    rep["runs"][1].update(outcome="undecided", companion_outcome="undecided")
    rep["runs"].append({**rep["runs"][0], "level": 1, "outcome": "encapsulated"})
    rep["failed"] = [{"x_over_leg": 2.0, "we_sqrt": 3.0, "wetted_length": 4.0, "level": 0,
                      "error": "BrokenProcessPool"}]
    rep["boundary"][0].update(status="undecided", decided_status="bracketed")
    rep["boundary"][1].update(verified=True)
    rep.update(verify_levels=1, overrides=["numerics.accuracy=draft", "effects.damping=0.1"],
               resolution={"n_edges": 77, "dt": 0.0125}, criterion="outcome")
    ax = plot_phase_diagram(rep).axes[0]
    und = _line(ax, "undecided (1)")
    assert (list(und.get_xdata()), list(und.get_ydata())) == ([1.5], [1.0])
    assert _line(ax, "not encapsulated (3)") and _line(ax, "encapsulated (2)")  # level 0 only
    fl = _line(ax, "failed, no result (1)")
    assert (list(fl.get_xdata()), list(fl.get_ydata())) == ([3.0], [2.0])
    labels = {c.get_label(): c for c in ax.containers}
    ver = labels["threshold, verified (holds at a finer level) (1 line)"]
    np.testing.assert_allclose(np.asarray(ver.lines[0].get_ydata(), float), [2.0])
    unc = labels["decided runs' bracket; line has undecided/failed runs (1 line)"]
    np.testing.assert_allclose(np.asarray(unc.lines[0].get_ydata(), float), [1.0])
    title = ax.get_title()
    assert "scene settings numerics.accuracy = draft, effects.damping = 0.1" in title
    assert r"77 edges, $\Delta t$ = 0.0125" in title and "verified to level 1" in title
    assert "+ 1 verification runs" in title


def test_experimental_points_from_csv(tmp_path):
    csv = tmp_path / "exp.csv"
    csv.write_text("x_over_leg,we_sqrt,outcome,note\n1.0,2.0,encapsulated,a\n2,1,open,\n"
                   "3,2.5,enc,\n")
    exps = load_experiments(csv)
    assert exps == [
        {"x_over_leg": 1.0, "we_sqrt": 2.0, "outcome": "encapsulated"},
        {"x_over_leg": 2.0, "we_sqrt": 1.0, "outcome": "open"},
        {"x_over_leg": 3.0, "we_sqrt": 2.5, "outcome": "encapsulated"},
    ]
    ax = plot_phase_diagram(_report(), experiments=csv).axes[0]
    assert len(_line(ax, "experiment: encapsulated").get_xdata()) == 2
    assert len(_line(ax, "experiment: open").get_xdata()) == 1


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("x,we_sqrt,outcome\n1,2,open\n", r"missing column\(s\) x_over_leg"),
        ("x_over_leg,we_sqrt,outcome\n1,fast,open\n", r"line 2: x_over_leg and we_sqrt must"),
        ("x_over_leg,we_sqrt,outcome\n1,2,open\n1,2,maybe\n", r"line 3: outcome 'maybe'"),
        ("x_over_leg,we_sqrt,outcome\n1,nan,open\n", r"line 2: .* must be finite, got 1.0, nan"),
        ("x_over_leg,we_sqrt,outcome\n1,2,open\ninf,2,open\n", r"line 3: .* must be finite"),
    ],
)
def test_bad_experiment_csv_by_message(tmp_path, text, match):
    p = tmp_path / "e.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=match):
        load_experiments(p)


def test_thresholds_into_undecided_other_changes_and_the_companion_criterion():
    rep = _report()
    # x = 2: open up to 1.9, undecided from 2.2 (a threshold into undecided runs), then a
    # change back to open between the runs at 2.5 and 3.0, which is not the threshold
    rep["runs"][5].update(outcome="undecided", companion_outcome="undecided")
    rep["runs"].append({**rep["runs"][3], "we_sqrt": 3.0})
    rep["boundary"][1].update(
        status="undecided", decided_status="all-open", threshold_low=1.9, threshold_high=2.2,
        threshold_to="undecided", verified=True,
        transitions=[{"low": 1.9, "high": 2.2, "outcome_low": "open",
                      "outcome_high": "undecided"},
                     {"low": 2.4, "high": 2.5, "outcome_low": "undecided",
                      "outcome_high": "open"}])
    rep.update(verify_levels=2, verify_every_level=True)
    comp = _report()
    comp["boundary"][0].update(we_sqrt_low=1.2, we_sqrt_high=1.3, verified=False)
    comp.update(verify_levels=2)
    ax = plot_phase_diagram(rep, companion=comp).axes[0]
    labels = {c.get_label(): c for c in ax.containers}
    ver = labels["threshold, verified (holds at every finer level) (1 line)"]
    np.testing.assert_allclose(np.asarray(ver.lines[0].get_xdata(), float), [2.05])
    unv = labels["threshold, NOT verified (1 line)"]
    np.testing.assert_allclose(np.asarray(unv.lines[0].get_xdata(), float), [1.5])
    und = _line(ax, "threshold into undecided runs, no encapsulation below (1 line)")
    np.testing.assert_allclose([und.get_xdata(), und.get_ydata()], [[2.05], [2.0]])
    other = _line(ax, "other outcome change on the line (1)")
    np.testing.assert_allclose([other.get_xdata()[0], other.get_ydata()[0]], [2.75, 2.0])
    cv = labels["frame-independent criterion: threshold, NOT verified (2 lines)"]
    np.testing.assert_allclose(np.asarray(cv.lines[0].get_xdata(), float), [1.25, 2.05])
    assert "every bracket at every level" in ax.get_title()
