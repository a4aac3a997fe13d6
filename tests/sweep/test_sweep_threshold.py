"""The threshold of a line (its first change from open) is what verification
checks, on bracketed lines and on lines that change again above it; --every-level checks a
bracket that holds at each finer level; the sweep's resolution represents its smallest
Delta; a run the impact refuses is recorded failed with the reason, its worker alive.
Run functions whose true boundary at each resolution is known (sweep_fakes)."""

import math
import pickle
from concurrent.futures import ThreadPoolExecutor

import pytest
import sweep_fakes as fk

from elastocap.impact import MIN_WET_EDGES
from elastocap.scene import load_scene
from elastocap.sweep import run_sweep, sweep_resolutions
from elastocap.sweep.grid import grid_points
from elastocap.sweep.tasks import run_impact_task

STRIP = load_scene("fig3-strip", {"numerics.accuracy": "draft"})
SPR = STRIP.spreading
L = 14.3
WE = [0.5, 1.5, 2.5, 3.5]


@pytest.fixture
def pool():
    with ThreadPoolExecutor(2) as ex:
        yield ex


def test_every_level_catches_a_bracket_that_holds_once_and_then_moves(tmp_path, pool):
    kw = dict(we_sqrts=WE, refine_tol=0.02, executor=pool, run_fn=fk.late_shift_run,
              verify_levels=2)
    # x = 3: threshold 2.53 below 150 edges, 2.23 from 150 on; levels 78, 117, 176 edges
    once = run_sweep(STRIP, [3.0], store=tmp_path / "a.sqlite", **kw)
    assert [r.n_edges for r in once.resolutions] == [78, 117, 176]
    (b,) = once.boundary
    assert b.verification["status"] == "holds" and b.verified is True
    assert len(b.verification["checks"]) == 1  # a held bracket is not looked at again
    every = run_sweep(STRIP, [3.0], store=tmp_path / "b.sqlite", verify_every_level=True, **kw)
    (b,) = every.boundary
    v = b.verification
    assert [c["result"] for c in v["checks"]] == ["holds", "moved"]
    assert [c["against"] for c in v["checks"]] == [1, 2]
    assert v["checks"][1]["level"] == 0  # the level-0 bracket, checked at level 2
    assert v["status"] == "moved" and b.verified is False and b.level == 2
    assert b.low < 2.23 <= b.high and b.high - b.low <= 0.02
    assert v["shift"] == pytest.approx(-0.3, abs=0.02)
    assert every.to_dict()["verify_every_level"] is True
    # a bracket that holds at every level is checked at each (x = 1: 1.53 at every level)
    kw["run_fn"] = fk.coarse_shift_run
    steady = run_sweep(STRIP, [1.0], store=tmp_path / "c.sqlite", verify_every_level=True,
                       **kw)
    (b,) = steady.boundary
    assert [c["result"] for c in b.verification["checks"]] == ["holds", "holds"]
    assert b.verification["status"] == "holds" and b.verified is True and b.level == 0


def test_the_threshold_is_verified_below_undecided_runs(tmp_path, pool):
    # x = 1: open below 1.53 (1.83 under 100 edges), encapsulated 1.2 above, undecided beyond
    res = run_sweep(STRIP, [1.0], we_sqrts=WE, store=tmp_path / "s.sqlite", refine_tol=0.02,
                    executor=pool, run_fn=fk.crossing_above_run, verify_levels=2)
    (b,) = res.boundary
    v = b.verification
    # the line as a whole is not decided at level 0 (its top runs are undecided)
    assert v["brackets"][0]["status"] == "undecided"
    assert v["checked"].startswith("threshold")
    assert [c["result"] for c in v["checks"]] == ["moved", "holds"]
    assert v["status"] == "holds-at-finer" and b.verified is True and b.level == 1
    assert b.threshold_low < 1.53 <= b.threshold_high and b.threshold_high - b.threshold_low <= 0.02
    assert v["shift"] == pytest.approx(-0.3, abs=0.02)
    # the level-0 threshold, as the first bracket
    lo0, hi0 = v["brackets"][0]["low"], v["brackets"][0]["high"]
    assert lo0 < 1.83 <= hi0


def test_a_first_change_to_undecided_is_the_threshold_of_leaving_open(tmp_path, pool):
    # open below 1.53, undecided up to 1.83, encapsulated above, at every resolution
    res = run_sweep(STRIP, [1.0, 2.0], we_sqrts=WE, store=tmp_path / "s.sqlite",
                    refine_tol=0.05, executor=pool, run_fn=fk.undecided_band_run,
                    verify_levels=1)
    for b in res.boundary:
        assert b.status == "undecided" and b.threshold_to == "undecided"
        assert b.threshold_low < 1.53 <= b.threshold_high
        assert b.threshold_high - b.threshold_low <= 0.05
        assert b.verification["status"] == "holds" and b.verified is True
    # a line that never leaves open has no threshold: not verified
    res = run_sweep(STRIP, [1.0], we_sqrts=[0.5, 1.0], store=tmp_path / "o.sqlite",
                    refine_tol=0.05, executor=pool, run_fn=fk.undecided_band_run,
                    verify_levels=1)
    (b,) = res.boundary
    assert b.status == "all-open" and b.threshold_low is None and b.verified is False
    assert b.verification["status"] == "not-applicable"


def test_the_resolution_gives_the_smallest_delta_its_minimum_of_wet_edges():
    # draft at We^1/2 = 0.5 ... 1: the preset's 8 edges per Delta at Delta(1) = 0.877 give
    # 131 edges; 50 at most at We^1/2 <= 4 ... but a sweep up to 4 has the preset's edges at
    # Delta(4) = 1.73 (67) and its smallest Delta(0.5) = 0.736 needs 4 * 14.3 / 0.736
    pts, _ = grid_points(STRIP, [3.0], we_sqrts=[0.5, 4.0])
    (r,) = sweep_resolutions(STRIP, pts)
    need = math.ceil(MIN_WET_EDGES * L / SPR.delta(0.5))
    assert need == 78 and max(50, math.ceil(8 * L / SPR.delta(4.0))) == 67
    assert r.n_edges == need
    # a wide sweep whose preset count is larger keeps the preset's
    pts, _ = grid_points(STRIP, [3.0], we_sqrts=[1.0, 2.0])
    (r,) = sweep_resolutions(STRIP, pts)
    assert r.n_edges == max(50, math.ceil(8 * L / SPR.delta(2.0)))


def test_a_run_the_impact_refuses_comes_back_as_a_picklable_error():
    # SceneError has its own constructor: in a plain interpreter it does not unpickle, and a
    # process pool then takes the worker for dead (measured: BrokenProcessPool); the task
    # re-raises it as a RuntimeError, which does
    scene = STRIP.with_overrides({"drop.distance_from_end": 3.0,
                                  "drop.wetted_length": SPR.delta(0.5),
                                  "numerics.n_edges": 67})
    with pytest.raises(RuntimeError, match="SceneError: numerics.n_edges: got 67") as info:
        run_impact_task(scene.name, scene.to_json())
    back = pickle.loads(pickle.dumps(info.value))
    assert "at least 4 are needed" in str(back) or "n_edges >= 78" in str(back)


def test_an_undecided_run_is_undecided_under_the_companion_criterion_too(tmp_path, pool):
    kw = dict(we_sqrts=WE, store=tmp_path / "s.sqlite", refine_tol=0.05, executor=pool,
              run_fn=fk.companion_decides_undecided_run, verify_levels=1)
    paper = run_sweep(STRIP, [1.0], **kw)
    comp = run_sweep(STRIP, [1.0], criterion="companion_outcome", **kw)
    for res in (paper, comp):
        (b,) = res.boundary
        # open below 1.53, then the undecided band: the threshold leads into undecided runs
        assert b.threshold_to == "undecided" and b.threshold_low < 1.53 <= b.threshold_high
        assert b.verification["status"] == "holds"
    # the companion's final-shape verdicts on undecided runs are not disagreements
    assert comp.to_dict()["counts"]["disagreements"] == 0
    assert comp.computed == 0  # the paper's sweep ran everything the companion needs
