"""Pseudo-arclength branches of the discrete strip at a fixed contact set, with active-set
events (elastocap.strip.discrete_branches). Tolerances are written next to each assertion."""

from __future__ import annotations

import numpy as np
import pytest

from elastocap.strip.discrete import DiscreteStrip, solve_equilibrium
from elastocap.strip.discrete_branches import trace_discrete_branch
from elastocap.strip.mep import continue_in_delta, open_state
from elastocap.strip.windows import branch_window

L, A, GAMMA = 14.3, 0.36, 40.0




@pytest.fixture(scope="module")
def x3():
    """The open state at x = 3, Delta = 1.25, n = 100, traced up in Delta over three
    segments (~1 s): lift-off of node 53, lift-off of node 79 (where Delta turns back),
    touch-down of node 53."""
    S = DiscreteStrip(100, L, 3.0, 1.25, A, GAMMA)
    eq = open_state(S)
    br = trace_discrete_branch(S, eq, (1.0, 1.4), restart=True, max_segments=3)
    return S, eq, br


def test_traced_points_are_equilibria_and_match_natural_continuation(x3):
    S, eq, br = x3
    seg = br.segments[0]
    assert np.array_equal(seg.active, eq.active)
    assert seg.delta.size >= 5 and np.all(np.diff(seg.delta) > 0.0)
    for d, u, r in zip(seg.delta, seg.u, seg.reactions, strict=True):
        s = S.with_(delta=d)
        e = solve_equilibrium(s, u, active=seg.active)
        # Newton from a traced point stops at its first iteration: the point is a KKT point
        # to round-off (relative residual; measured ~1e-13)
        assert e.success and e.iterations == 1 and e.residual < 1e-9, (d, e.residual)
        assert np.max(np.abs(e.u - u)) < 1e-12
        assert np.max(np.abs(e.reactions - r)) < 1e-9 * S.q * S.h * S.n
    # natural-parameter continuation visiting the traced Deltas (before the event) finds
    # the same states (measured agreement ~1e-12)
    inner = seg.delta[1:-1]
    nat = continue_in_delta(S, eq, inner)
    got = {round(d, 14): e for d, e in nat}
    matched = 0
    for d, u in zip(seg.delta[1:-1], seg.u[1:-1], strict=True):
        e = got.get(round(d, 14))
        if e is not None:
            assert np.max(np.abs(e.u - u)) < 1e-8, d
            assert np.array_equal(e.active, seg.active)
            matched += 1
    assert matched == inner.size
    # energies of the traced branch are those of the states
    exact = [S.with_(delta=d).energy(u) for d, u in zip(seg.delta, seg.u, strict=True)]
    assert np.allclose(seg.energy, exact, rtol=0, atol=1e-12)
    # the fixed-set index along the stable first segment is 0
    assert np.all(seg.index == 0) and np.all(seg.index_strong == 0)


def test_active_set_events_are_located_consistently(x3):
    S, eq, br = x3
    assert [(e.kind, e.node) for e in br.events] == [
        ("lift_off", 53), ("lift_off", 79), ("touch_down", 53)]
    for e in br.events:
        # reaction (force; q h = 0.143) or gap (length) at the located event: round-off
        assert abs(e.value) < 1e-8, (e.kind, e.node, e.value)
        s = S.with_(delta=e.delta)
        assert s.heights(e.u).min() > -1e-10
    # the event Deltas (measured 1.288236482, 1.301729538, 1.296971785)
    d = [e.delta for e in br.events]
    assert abs(d[0] - 1.288236482) < 1e-8 and abs(d[1] - 1.301729538) < 1e-8
    assert abs(d[2] - 1.296971785) < 1e-8
    # segments join at the events: each next segment starts at its event's state
    for a, b in zip(br.segments[:-1], br.segments[1:], strict=True):
        assert b.delta[0] == a.event.delta
        assert np.max(np.abs(b.u[0] - a.event.u)) < 1e-10
        k = a.event.node
        assert b.active[k] != a.active[k]
        assert np.sum(b.active != a.active) == 1
    # past the first lift-off, node 53 rises (a contact equilibrium again)
    s2 = br.segments[1]
    z53 = [S.with_(delta=dd).heights(u)[53]
           for dd, u in zip(s2.delta[1:], s2.u[1:], strict=True)]
    assert min(z53) > 0.0
    assert np.min(s2.reactions[:-1][:, s2.active]) >= -1e-10


def test_end_of_the_open_branch_lies_in_the_natural_window(x3):
    S, _eq, br = x3
    w = branch_window(S, check_beyond=False)
    # At n = 100 the open branch ends where node 79 (under the drop) lifts off and Delta
    # turns back: a nonsmooth fold, the index going 0 -> 1 (no smooth fold of a fixed-set
    # branch there).
    assert len(br.turning_points) == 1
    tp = br.turning_points[0]
    assert tp["node"] == 79 and tp["kind"] == "lift_off"
    assert tp["index"] == (0, 1)
    # inside the natural continuation's 1e-3 bracket [open_max, open_failed]
    # (measured: 1.3015503 < 1.3017295 < 1.3023073)
    assert w.open_end == "no_convergence"
    assert w.open_max < tp["delta"] < w.open_failed, (w.open_max, tp["delta"], w.open_failed)
    assert w.open_failed - w.open_max <= 1e-3 + 1e-12
    # the segment past it is the unstable branch, heading down in Delta
    s3 = br.segments[2]
    assert np.all(np.diff(s3.delta) < 0.0) and np.all(s3.index == 1)
    assert not br.folds  # no smooth fold on these segments


def test_bad_input_is_rejected_by_message():
    S = DiscreteStrip(20, L, 3.0, 1.1, A, GAMMA)
    eq = solve_equilibrium(S, np.zeros(S.size), max_iter=1)
    with pytest.raises(ValueError, match="state: got status"):
        trace_discrete_branch(S, eq, (1.0, 1.2))
