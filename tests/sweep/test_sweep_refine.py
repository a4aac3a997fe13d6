"""Sweep orchestration and boundary refinement with cheap fake run functions on a thread
pool (any concurrent.futures.Executor works): brackets against a known threshold, resume
without re-running, non-monotonic lines detected, failed runs reported and retried."""

import io
import json
import shutil
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import sweep_fakes as fk

from elastocap.scene import load_scene
from elastocap.sweep import TextProgress, classify_line, run_sweep
from elastocap.sweep.refine import Transition

STRIP = load_scene("fig3-strip", {"numerics.accuracy": "draft"})
SPR = STRIP.spreading


def _point(scene_json):
    d = json.loads(scene_json)["drop"]
    return d["distance_from_end"], SPR.we_sqrt(d["wetted_length"])


def _result(enc: bool) -> dict:
    o = "encapsulated" if enc else "open"
    return {"outcome": o, "companion_outcome": o, "final_measure": float(enc),
            "status": "completed", "steps": 1, "t_end": 1.0, "wall_time_s": 0.0}


CALLS = []


def threshold_run(scene_name, scene_json):
    """Encapsulated iff We^1/2 > 1.03 + 0.5 x (x in l_eg = scene units here)."""
    x, w = _point(scene_json)
    CALLS.append((x, w))
    return _result(w > 1.03 + 0.5 * x)


threshold_run.runner = "fake-threshold"


def band_run(scene_name, scene_json):
    """Encapsulated only for 1.2 < We^1/2 < 2.1 at every x: a non-monotonic line."""
    _, w = _point(scene_json)
    return _result(1.2 < w < 2.1)


band_run.runner = "fake-band"

FAIL_ONCE = set()
_lock = threading.Lock()


def flaky_run(scene_name, scene_json):
    """Raises the first time it sees We^1/2 = 2 (a worker crash), then behaves."""
    x, w = _point(scene_json)
    with _lock:
        if abs(w - 2.0) < 1e-12 and (x, w) not in FAIL_ONCE:
            FAIL_ONCE.add((x, w))
            raise RuntimeError("worker lost")
    return _result(w > 1.0 + 0.5 * x)


flaky_run.runner = "fake-flaky"


@pytest.fixture
def pool():
    with ThreadPoolExecutor(2) as ex:
        yield ex


def test_classify_line():
    assert classify_line([], []) == ("no-runs", [])
    assert classify_line([2, 1], ["open", "open"]) == ("all-open", [])
    assert classify_line([2, 1], ["encapsulated"] * 2) == ("all-encapsulated", [])
    assert classify_line([3, 1, 2], ["encapsulated", "open", "open"]) == (
        "bracketed", [Transition(2, 3, "open", "encapsulated")])
    status, tr = classify_line([1, 2, 3], ["open", "encapsulated", "open"])
    assert status == "non-monotonic" and [(t.low, t.high) for t in tr] == [(1, 2), (2, 3)]
    assert classify_line([1, 2], ["encapsulated", "open"])[0] == "non-monotonic"
    with pytest.raises(ValueError, match="value 1 has two different outcomes"):
        classify_line([1, 1], ["open", "encapsulated"])
    with pytest.raises(ValueError, match="outcome: got 'maybe' at 1"):
        classify_line([1], ["maybe"])


def test_refinement_brackets_the_known_threshold_and_resume_runs_nothing(tmp_path, pool):
    xs, wes, tol = [1.0, 2.0, 3.0], [0.5, 1.5, 2.5, 3.5], 0.01
    CALLS.clear()
    res = run_sweep(STRIP, xs, we_sqrts=wes, store=tmp_path / "s.sqlite", refine_tol=tol,
                    executor=pool, run_fn=threshold_run)
    assert res.failed == [] and res.skipped == []
    assert [b.status for b in res.boundary] == ["bracketed"] * 3
    for b in res.boundary:
        wc = 1.03 + 0.5 * b.x
        assert b.we_sqrt_low < wc <= b.we_sqrt_high  # the bracket holds the threshold
        assert b.we_sqrt_high - b.we_sqrt_low <= tol and b.converged
        # grid bracket width 1 halved until <= 0.01: 7 halvings
        assert b.refinement_runs == 7
        assert b.wetted_length_low == pytest.approx(SPR.delta(b.we_sqrt_low), rel=1e-14)
    assert res.computed == 12 + 21 == len(CALLS) == len(res.runs)
    # the same sweep again: everything from the store, nothing run, same boundary
    CALLS.clear()
    again = run_sweep(STRIP, xs, we_sqrts=wes, store=tmp_path / "s.sqlite", refine_tol=tol,
                      executor=pool, run_fn=threshold_run)
    assert CALLS == [] and again.computed == 0 and again.cached == 33
    assert [(b.low, b.high) for b in again.boundary] == [(b.low, b.high) for b in res.boundary]
    assert all(r["cached"] for r in again.runs)


def test_non_monotonic_line_is_reported_and_each_change_refined(tmp_path, pool):
    res = run_sweep(STRIP, [2.0], we_sqrts=[0.5, 1.0, 1.5, 2.0, 2.5, 3.0],
                    store=tmp_path / "s.sqlite", refine_tol=0.02, executor=pool,
                    run_fn=band_run)
    (b,) = res.boundary
    assert b.status == "non-monotonic" and b.low is None and b.high is None
    assert [(t.outcome_low, t.outcome_high) for t in b.transitions] == [
        ("open", "encapsulated"), ("encapsulated", "open")]
    lo, hi = b.transitions
    assert lo.low < 1.2 <= lo.high and hi.low < 2.1 <= hi.high
    assert lo.width <= 0.02 and hi.width <= 0.02 and b.converged
    d = res.to_dict()["boundary"][0]
    assert d["we_sqrt_low"] is None and d["status"] == "non-monotonic"


def test_all_open_and_all_encapsulated_lines(tmp_path, pool):
    res = run_sweep(STRIP, [1.0, 6.0], we_sqrts=[2.0, 3.0], store=tmp_path / "s.sqlite",
                    refine_tol=0.1, executor=pool, run_fn=threshold_run)
    enc, opn = res.boundary  # x = 1: threshold 1.53; x = 6: threshold 4.03
    assert (enc.status, enc.low, enc.high) == ("all-encapsulated", None, 2.0)
    assert (opn.status, opn.low, opn.high) == ("all-open", 3.0, None)
    assert res.computed == 4  # nothing to bisect


def test_failed_runs_are_reported_not_stored_and_retried(tmp_path, pool):
    FAIL_ONCE.clear()
    store = tmp_path / "s.sqlite"
    res = run_sweep(STRIP, [1.0, 2.0], we_sqrts=[1.0, 2.0, 3.0], store=store,
                    executor=pool, run_fn=flaky_run)
    assert len(res.failed) == 2 and res.computed == 4
    assert {f["x_over_leg"] for f in res.failed} == {1.0, 2.0}
    assert "RuntimeError: worker lost" in res.failed[0]["error"]
    again = run_sweep(STRIP, [1.0, 2.0], we_sqrts=[1.0, 2.0, 3.0], store=store,
                      executor=pool, run_fn=flaky_run)
    assert again.failed == [] and again.computed == 2 and again.cached == 4


def test_delta_sweep_skips_points_off_the_rod_and_reports_progress(tmp_path, pool):
    buf = io.StringIO()
    res = run_sweep(STRIP, [0.3, 2.0], deltas=[0.5, 1.0], store=tmp_path / "s.sqlite",
                    executor=pool, run_fn=threshold_run, progress=TextProgress(buf, every=0))
    # x = 0.3: Delta = 1.0 reaches S2 = L + 0.2
    assert [(s.x_over_leg, s.wetted_length) for s in res.skipped] == [(0.3, 1.0)]
    assert "leaves the rod" in res.skipped[0].reason
    assert len(res.runs) == 3 and res.variable == "wetted_length"
    lines = buf.getvalue().splitlines()
    assert lines[0].startswith("sweep: 1/3 runs") and lines[-1].startswith("sweep: 3/3 runs")
    rep = res.to_dict()
    assert rep["counts"] == {"runs": 3, "computed": 3, "cached": 0, "skipped": 1, "failed": 0,
                             "undecided": 0, "disagreements": 0, "verification": None,
                             "self_contact": None,
                             "outcomes": {"open": 3, "encapsulated": 0, "undecided": 0}}
    json.dumps(rep)  # plain data


def test_counts_say_in_how_many_runs_the_rod_touched_itself():
    from elastocap.sweep.engine import run_counts

    def row(steps):
        return {"outcome": "open", "companion_outcome": "open", "contact_steps": steps}

    assert run_counts([row(None), row(None)], 2, 0, 0, 0)["self_contact"] is None
    # a store written before the column existed reads None; a thickness without a touch, 0
    assert run_counts([row(0), row(12), row(None), row(3)], 4, 0, 0, 0)["self_contact"] == 2
    assert run_counts([row(0)], 1, 0, 0, 0)["self_contact"] == 0


def test_progress_kinds(capsys):
    from elastocap.sweep import NoProgress, TqdmProgress, make_progress

    assert isinstance(make_progress("none"), NoProgress)
    assert isinstance(make_progress("text"), TextProgress)
    assert isinstance(make_progress("auto"), TextProgress)  # stderr is not a terminal here
    bar = make_progress("tqdm")
    assert isinstance(bar, TqdmProgress)
    bar(1, 3, "grid")
    bar(4, 5, "refine")  # the total grows as refinement adds runs
    assert (bar._bar.n, bar._bar.total) == (4, 5)
    bar.close()
    assert "4/5" in capsys.readouterr().err
    with pytest.raises(ValueError, match="--progress: got 'bars'; expected one of none"):
        make_progress("bars")


def companion_disagrees_run(scene_name, scene_json):
    """Lab-frame threshold at We^1/2 = 1.53 + 0.5 x; companion threshold 0.3 lower."""
    x, w = _point(scene_json)
    r = _result(w > 1.53 + 0.5 * x)
    r["companion_outcome"] = "encapsulated" if w > 1.23 + 0.5 * x else "open"
    return r


companion_disagrees_run.runner = "fake-companion"


def test_boundary_of_the_companion_criterion(tmp_path, pool):
    kw = dict(we_sqrts=[0.5, 1.5, 2.5, 3.5], store=tmp_path / "s.sqlite", refine_tol=0.01,
              executor=pool, run_fn=companion_disagrees_run)
    lab = run_sweep(STRIP, [1.0], **kw)
    comp = run_sweep(STRIP, [1.0], criterion="companion_outcome", **kw)
    (b1,), (b2,) = lab.boundary, comp.boundary
    assert b1.low < 2.03 <= b1.high and b2.low < 1.73 <= b2.high
    assert comp.to_dict()["criterion"] == "companion_outcome"
    assert lab.to_dict()["counts"]["disagreements"] >= 1
    with pytest.raises(ValueError, match="criterion: got 'both'"):
        run_sweep(STRIP, [1.0], criterion="both", **kw)


def other_code_run(scene_name, scene_json):
    """A worker whose code differs from the sweep's (a stale cluster worker)."""
    r = threshold_run(scene_name, scene_json)
    r["code_digest"] = "0123456789abcdef"
    return r


other_code_run.runner = "fake-threshold"
other_code_run.code_digest = "fedcba9876543210"


def edited_run(scene_name, scene_json):
    """threshold_run after a source edit: same runner name, another code digest."""
    return threshold_run(scene_name, scene_json)


edited_run.runner = "fake-threshold"
edited_run.code_digest = "aaaaaaaaaaaaaaaa"


def test_code_identity_is_part_of_the_key_and_checked(tmp_path, pool):
    from elastocap.sweep import ResultStore
    from elastocap.sweep.tasks import code_fingerprint, run_impact_task

    store = tmp_path / "s.sqlite"
    kw = dict(we_sqrts=[1.0, 3.0], store=store, executor=pool)
    stale = run_sweep(STRIP, [1.0], run_fn=other_code_run, **kw)
    assert stale.computed == 0 and len(stale.failed) == 2
    err = stale.failed[0]["error"]
    assert "the worker runs elastocap" in err and "code 0123456789abcdef" in err
    assert "install the same code on every worker" in err
    assert run_sweep(STRIP, [1.0], run_fn=threshold_run, **kw).computed == 2
    # after an edit nothing stored is reused, and nothing is lost either
    assert run_sweep(STRIP, [1.0], run_fn=edited_run, **kw).computed == 2
    assert run_sweep(STRIP, [1.0], run_fn=edited_run, **kw).computed == 0
    with ResultStore(store) as st:
        assert sorted(r["code_digest"] for r in st.rows()) == ["", ""] + ["a" * 16] * 2
    assert run_impact_task.code_digest() == code_fingerprint()
    assert len(code_fingerprint()) == 16


def test_code_fingerprint_covers_the_impact_code_only():
    from elastocap.sweep.tasks import code_files, code_fingerprint

    names = set(code_files())
    # the impact, its drop and capillary model, the stepper, the criteria, the scene
    assert {"elastocap.impact", "elastocap.capillary", "elastocap.drop", "elastocap.criteria",
            "elastocap.scene", "dynamics", "dynamics.rattle", "dynamics.effects"} <= names
    assert not {n for n in names if n.startswith("elastocap.sweep") or n == "elastocap.cli"}
    assert code_fingerprint() == code_fingerprint()
    assert code_fingerprint(("elastocap.units",)) != code_fingerprint(("elastocap.drop",))


def test_a_tolerance_below_float_spacing_stops_at_float_resolution(tmp_path, pool):
    res = run_sweep(STRIP, [1.0], we_sqrts=[1.5, 1.6], store=tmp_path / "s.sqlite",
                    refine_tol=1e-300, executor=pool, run_fn=threshold_run)
    (b,) = res.boundary
    # the bracket closes on the threshold 1.53 to adjacent doubles, then stops
    assert b.status == "bracketed" and b.high == np.nextafter(b.low, 2.0)
    assert b.low < 1.53 + 1e-15 and b.high > 1.53 - 1e-15
    assert not b.converged and "float resolution" in b.notes[0]
    assert b.refinement_runs < 60  # 0.1 / 2^k reaches double spacing (2e-16) by k ~ 49


def _plain(obj, where="result"):
    """Every value of ``obj`` is plain Python data (exact types, no numpy scalar)."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            assert type(k) is str, (where, k)
            _plain(v, f"{where}.{k}")
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            _plain(v, f"{where}[{i}]")
    else:
        assert obj is None or type(obj) in (str, int, float, bool), (where, type(obj))


def test_numpy_scalars_and_arrays_are_accepted_and_the_result_is_plain(tmp_path, pool):
    from elastocap.sweep.executors import check_workers

    assert check_workers(np.int64(2)) == 2 and type(check_workers(np.int64(2))) is int
    with pytest.raises(ValueError, match="--workers"):
        check_workers(np.float64(2.0))
    res = run_sweep(STRIP, np.array([1.0, 2.0]), we_sqrts=np.linspace(0.5, 3.5, 4),
                    store=tmp_path / "s.sqlite", refine_tol=np.float64(0.3),
                    workers=np.int64(1), verify_levels=np.int64(0), executor=pool,
                    run_fn=threshold_run)
    d = res.to_dict()
    assert d["refine_tolerance"] == 0.3 and type(d["refine_tolerance"]) is float
    _plain(d)
    plain = run_sweep(STRIP, [1.0, 2.0], we_sqrts=[0.5, 1.5, 2.5, 3.5],
                      store=tmp_path / "s.sqlite", refine_tol=0.3, executor=pool,
                      run_fn=threshold_run)
    assert [(b.low, b.high) for b in plain.boundary] == [(b.low, b.high) for b in res.boundary]


def _plotted(fig):
    """What a phase diagram draws: each line's label and data (markers in any order)."""
    ax = fig.axes[0]
    return sorted((ln.get_label(), sorted(np.asarray(ln.get_xydata()).round(12).tolist()))
                  for ln in ax.lines)


def test_a_bare_store_redraws_the_same_diagram_without_running(tmp_path, pool, monkeypatch,
                                                                capsys):
    import elastocap.impact
    import elastocap.sweep.tasks
    from elastocap.cli import main
    from elastocap.sweep.engine import report_from_store
    from elastocap.sweep.plot import plot_phase_diagram

    store = tmp_path / "s.sqlite"
    res = run_sweep(STRIP, [1.0, 2.0, 3.0], we_sqrts=[0.5, 1.5, 2.5, 3.5], store=store,
                    executor=pool, run_fn=threshold_run)

    def forbidden(*a, **k):
        raise AssertionError("an impact was run")

    monkeypatch.setattr(elastocap.impact, "run_impact", forbidden)
    monkeypatch.setattr(elastocap.sweep.tasks, "run_impact_task", forbidden)
    rebuilt = report_from_store(store)
    assert [(b["x"], b["status"], b["low"], b["high"]) for b in rebuilt["boundary"]] == [
        (b.x, b.status, b.low, b.high) for b in res.boundary]
    assert _plotted(plot_phase_diagram(rebuilt)) == _plotted(plot_phase_diagram(res))
    # the counts of the live report, every run now from the store
    live = res.to_dict()["counts"]
    assert rebuilt["counts"] == {**live, "computed": 0, "cached": live["runs"]}
    assert rebuilt["x_unit_value"] == res.to_dict()["x_unit_value"]
    # the command: no sweep.json beside the store, the figure drawn from the store alone
    monkeypatch.chdir(tmp_path)
    assert main(["plot", "s.sqlite", "--out", "re"]) == 0
    assert (tmp_path / "re" / "phase-diagram.png").stat().st_size > 1000
    assert main(["plot", "missing.sqlite"]) == 2
    # a damaged row is refused as a sweep.json's would be, and nothing is drawn
    shutil.copy(store, tmp_path / "d.sqlite")
    fk.execute_sql(tmp_path / "d.sqlite", "UPDATE runs SET final_measure = 1e999 WHERE id = "
                   "(SELECT MIN(id) FROM runs)")
    capsys.readouterr()
    assert main(["plot", "d.sqlite", "--out", "d"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("elastocap: error: PATH: ") and "final_measure = inf" in err, err
    assert not (tmp_path / "d").exists()
