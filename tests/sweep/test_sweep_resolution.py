"""One resolution per sweep, and --verify: every run of a sweep has the edges the accuracy
preset gives the sweep's largest Delta (computed here from the preset's rule, not by the
code under test), brackets never mix levels, and verification against run functions whose
true boundary at each resolution is known."""

import json
import math
from concurrent.futures import ThreadPoolExecutor

import pytest
import sweep_fakes as fk
from hypothesis import given, settings
from hypothesis import strategies as st

from elastocap.scene import load_scene
from elastocap.sweep import ResultStore, run_sweep, sweep_resolutions
from elastocap.sweep.grid import grid_points

STRIP = load_scene("fig3-strip", {"numerics.accuracy": "draft"})
SPR = STRIP.spreading
L = 14.3


@pytest.fixture
def pool():
    with ThreadPoolExecutor(2) as ex:
        yield ex


def _draft_edges(delta):
    # the draft preset: at least 50 edges and 8 across the wet part (elastocap.impact)
    return max(50, math.ceil(8 * L / delta))


def test_the_resolution_is_the_presets_at_the_largest_delta(tmp_path, pool):
    wes = [0.5, 1.5, 2.5]
    res = run_sweep(STRIP, [1.0, 2.0, 3.0], we_sqrts=wes, store=tmp_path / "s.sqlite",
                    refine_tol=0.05, executor=pool, run_fn=fk.coarse_shift_run)
    n0 = _draft_edges(SPR.delta(2.5))
    assert n0 == 88  # Delta = 1.303: ceil(114.4 / 1.303); 156 at We^1/2 = 0.5
    with ResultStore(tmp_path / "s.sqlite") as st:
        rows = st.rows()
        assert st.resolution()["n_edges"] == n0
    assert len(rows) == len(res.runs) > 9  # grid and refinement
    assert {json.loads(r["scene_json"])["numerics"]["n_edges"] for r in rows} == {n0}
    assert {r["n_edges"] for r in rows} == {n0} and {r["level"] for r in rows} == {0}
    # one time step too: the bending bound at h = L / n0 times the ground fraction 0.7
    # (independent: dt_max = c h^2 sqrt(mu / B) scales as h^2)
    dts = {r["dt"] for r in rows}
    assert len(dts) == 1
    (lv,) = res.resolutions
    n_big = _draft_edges(SPR.delta(0.5))
    fine = sweep_resolutions(STRIP, grid_points(STRIP, [3.0], we_sqrts=[0.5])[0])[0]
    assert fine.n_edges == n_big
    assert lv.dt / fine.dt == pytest.approx((n_big / n0) ** 2, rel=1e-12)
    assert res.to_dict()["resolution"]["n_edges"] == n0


def test_numerics_n_edges_overrides_the_rule_and_levels_grow_by_1_5():
    pts, _ = grid_points(STRIP, [3.0], we_sqrts=[1.0, 2.0])
    levels = sweep_resolutions(STRIP.with_overrides({"numerics.n_edges": 64}), pts, 3)
    assert [lv.n_edges for lv in levels] == [64, 96, 144, 216]
    for a, b in zip(levels[:-1], levels[1:], strict=True):
        # explicit stepper: the automatic step at 1.5x the edges is (1/1.5)^2 = 0.44 of the
        # coarser one, already below half: left automatic
        assert b.dt == pytest.approx(a.dt / 2.25, rel=1e-12) and not b.dt_explicit
    imp = sweep_resolutions(STRIP.with_overrides({"numerics.integrator": "implicit"}), pts, 2)
    # the implicit step need not shrink with the edges by itself: at most half
    assert imp[1].dt <= 0.5 * imp[0].dt * (1 + 1e-12)
    assert imp[2].dt <= 0.5 * imp[1].dt * (1 + 1e-12)
    with pytest.raises(ValueError, match="--converge: got 9; expected an integer from 1 to 4"):
        run_sweep(STRIP, [3.0], we_sqrts=[1.0], store="never.sqlite", verify_levels=9)


def test_verify_holds_where_the_boundary_does_not_depend_on_the_resolution(tmp_path, pool):
    res = run_sweep(STRIP, [1.0], we_sqrts=[0.5, 1.5, 2.5], store=tmp_path / "s.sqlite",
                    refine_tol=0.05, executor=pool, run_fn=fk.coarse_shift_run,
                    verify_levels=1)
    (b,) = res.boundary
    assert b.status == "bracketed" and b.verified is True and b.level == 0
    v = b.verification
    assert v["status"] == "holds" and v["shift"] is None
    (chk,) = v["checks"]
    n0 = res.resolutions[0].n_edges
    assert chk["n_edges"] == math.ceil(1.5 * n0) and chk["dt"] <= 0.5 * res.resolutions[0].dt
    assert (chk["low"], chk["high"]) == (b.low, b.high)
    assert (chk["low_outcome"], chk["high_outcome"]) == ("open", "encapsulated")
    ver = [r for r in res.runs if r["stage"] == "verify"]
    assert len(ver) == 2 and {r["level"] for r in ver} == {1}
    with ResultStore(tmp_path / "s.sqlite") as st:  # verification runs in the same store
        assert sorted(r["level"] for r in st.rows()).count(1) == 2
    assert res.to_dict()["counts"]["verification"] == {"holds": 1}


def test_verify_reports_how_far_a_bracket_moves(tmp_path, pool):
    # x = 3: threshold 2.53 + 0.3 at n < 100 (level 0, 73 edges), 2.53 from level 1 on
    res = run_sweep(STRIP, [3.0], we_sqrts=[0.5, 1.5, 2.5, 3.5], store=tmp_path / "s.sqlite",
                    refine_tol=0.02, executor=pool, run_fn=fk.coarse_shift_run,
                    verify_levels=1)
    (b,) = res.boundary
    v = b.verification
    assert v["status"] == "moved" and b.verified is False
    lo0, hi0 = v["brackets"][0]["low"], v["brackets"][0]["high"]
    assert lo0 < 2.83 <= hi0 and hi0 - lo0 <= 0.02  # the level-0 boundary
    assert b.level == 1 and b.low < 2.53 <= b.high and b.high - b.low <= 0.02
    assert v["shift"] == pytest.approx(-0.3, abs=0.02)
    # the finer bracket is made of level-1 runs only, the coarse one of level-0 runs only
    by_level = {}
    for r in res.runs:
        by_level.setdefault(r["level"], set()).add(r["n_edges"])
    assert by_level == {0: {res.resolutions[0].n_edges}, 1: {res.resolutions[1].n_edges}}


def test_converge_refines_the_resolution_until_the_bracket_holds(tmp_path, pool):
    kw = dict(we_sqrts=[0.5, 1.5, 2.5, 3.5], refine_tol=0.02, executor=pool)
    res = run_sweep(STRIP, [1.0, 3.0], store=tmp_path / "s.sqlite",
                    run_fn=fk.coarse_shift_run, verify_levels=3, **kw)
    one, three = res.boundary
    assert one.verification["status"] == "holds" and one.level == 0
    # x = 3 moves from level 0 to 1, then holds at level 2: reported at level 1, verified
    v = three.verification
    assert v["status"] == "holds-at-finer" and v["holds_at_level"] == 1
    assert three.verified is True and three.level == 1
    assert three.low < 2.53 <= three.high
    assert [c["result"] for c in v["checks"]] == ["moved", "holds"]
    # a boundary that moves at every level is reported not verified, at the finest level
    creep = run_sweep(STRIP, [3.0], store=tmp_path / "c.sqlite", run_fn=fk.creeping_run,
                      verify_levels=2, **kw)
    (b,) = creep.boundary
    assert b.verified is False and b.verification["status"] == "moved" and b.level == 2
    n2 = creep.resolutions[2].n_edges
    assert b.low < 2.53 + 40.0 / n2 <= b.high
    assert [c["result"] for c in b.verification["checks"]] == ["moved", "moved"]


def test_lines_without_one_bracket_are_marked_not_verified(tmp_path, pool):
    res = run_sweep(STRIP, [3.0], we_sqrts=[0.5, 1.0], store=tmp_path / "s.sqlite",
                    executor=pool, run_fn=fk.coarse_shift_run, verify_levels=1)
    (b,) = res.boundary
    assert b.status == "all-open" and b.verified is False
    assert b.verification["status"] == "not-applicable"
    assert "all-open" in b.verification["reason"]


class _ShiftedThreshold:
    """Encapsulated iff We^1/2 > a + b x + s * [n_edges < n_cut]: a known boundary at every
    resolution (a callable object: a thread pool needs no pickling)."""

    runner = "fake-shifted-threshold"

    def __init__(self, a, b, s, n_cut):
        self.a, self.b, self.s, self.n_cut = a, b, s, n_cut
        self.runner = f"fake-shifted-{a!r}-{b!r}-{s!r}-{n_cut}"

    def threshold(self, x, n):
        return self.a + self.b * x + (self.s if n < self.n_cut else 0.0)

    def __call__(self, scene_name, scene_json):
        x, w, n = fk.point(scene_json)
        return fk.threshold(x, w, self.threshold(x, n))


@settings(max_examples=8, deadline=None)
@given(a=st.floats(0.8, 1.6), b=st.floats(0.0, 0.5), s=st.floats(-0.6, 0.6),
       tol=st.sampled_from([0.02, 0.05, 0.1]))
def test_verification_finds_the_known_boundary_at_each_resolution(tmp_path_factory, a, b, s,
                                                                  tol):
    fn = _ShiftedThreshold(a, b, s, n_cut=100)  # level 0 has 73 edges, level 1 110
    wes = [0.5, 1.25, 2.0, 2.75, 3.5]
    with ThreadPoolExecutor(2) as ex:
        res = run_sweep(STRIP, [1.0, 3.0], we_sqrts=wes, refine_tol=tol, executor=ex,
                        store=tmp_path_factory.mktemp("h") / "s.sqlite", run_fn=fn,
                        verify_levels=1)
    n0, n1 = res.resolutions[0].n_edges, res.resolutions[1].n_edges
    assert n0 < 100 <= n1
    for bd in res.boundary:
        t0, t1 = fn.threshold(bd.x, n0), fn.threshold(bd.x, n1)
        v = bd.verification
        if not 0.5 < t0 < 3.5:  # outside the grid: no bracket to verify
            assert v["status"] == "not-applicable" and bd.verified is False
            continue
        lo0, hi0 = v["brackets"][0]["low"], v["brackets"][0]["high"]
        assert lo0 < t0 + 1e-9 and t0 - 1e-9 <= hi0 and hi0 - lo0 <= tol
        if lo0 < t1 - 1e-9 and t1 + 1e-9 < hi0:  # the finer boundary inside the bracket
            assert v["status"] == "holds" and bd.verified is True
        elif abs(t1 - lo0) > 1e-9 and abs(t1 - hi0) > 1e-9 and 0.5 < t1 < 3.5:
            assert v["status"] == "moved" and bd.verified is False and bd.level == 1
            assert bd.low < t1 + 1e-9 and t1 - 1e-9 <= bd.high and bd.high - bd.low <= tol
            assert v["shift"] == pytest.approx(t1 - t0, abs=tol)
