"""All branches of the strip on the ground in Delta, every contact topology
(elastocap.strip.contact_branches; the command `elastocap branches fig3-strip`).

Checked against independent computations: the string method's saddle and the descent's
open state (elastocap.strip.mep), the contact-point geometry (a kink sits where a contact
point is on a node), the cap model (the chord at the end of a wrapped branch). Tolerances
are written next to each assertion."""

from __future__ import annotations

import json

import numpy as np
import pytest

from continuation import ContinuationSettings
from elastocap.cli import main
from elastocap.scene import SceneError, load_scene
from elastocap.strip.contact_branches import trace_contact_branches
from elastocap.strip.discrete import DiscreteStrip, discrete_strip_for, solve_equilibrium
from elastocap.strip.discrete_branches import _CHORD_STOP, _DEFAULTS, trace_discrete_branch
from elastocap.strip.mep import barrier, open_state, wrapped_state

L, A, GAMMA = 14.3, 0.36, 40.0




@pytest.fixture(scope="module")
def x3():
    """All branches at x = 3, n = 60, without refinement (~5 s)."""
    sc = load_scene("fig3-strip", {"drop.distance_from_end": 3.0, "numerics.n_edges": 60})
    return trace_contact_branches(sc, refine=False)


def _states_at(bs, delta):
    """Every traced state whose segment crosses ``delta``, Newton-solved there exactly."""
    S = DiscreteStrip(bs.n, L, bs.scene.distance_from_end, delta, A, GAMMA)
    out = []
    for br in bs.branches:
        for seg in br.segments:
            d = seg.delta
            for i in range(d.size - 1):
                if d[i] != d[i + 1] and (d[i] - delta) * (d[i + 1] - delta) <= 0.0:
                    j = i if abs(d[i] - delta) < abs(d[i + 1] - delta) else i + 1
                    eq = solve_equilibrium(S, seg.u[j], active=seg.active, tol=1e-11)
                    assert eq.success
                    out.append((int(seg.index[j]), eq))
    return S, out


def test_unstable_branch_passes_through_the_string_method_saddle(x3):
    # The index-1 branch traced by continuation and the saddle found by the string method
    # + Newton (mep.barrier) are independent computations of the same state.
    S, states = _states_at(x3, 1.1)
    b = barrier(S)
    assert b.status == "ok" and b.saddle.index == 1
    saddles = [eq for idx, eq in states if idx == 1]
    opens = [eq for idx, eq in states if idx == 0
             and np.max(np.abs(eq.u - b.open.u)) < 1e-6]
    assert saddles and opens
    # same states to Newton's round-off (measured 5e-15 and 4e-13)
    assert min(np.max(np.abs(eq.u - b.saddle.u)) for eq in saddles) < 1e-10
    assert min(np.max(np.abs(eq.u - b.open.u)) for eq in opens) < 1e-10
    # so the barrier read off the branches is the string method's (0.92459 at n = 60)
    sad = min(saddles, key=lambda eq: np.max(np.abs(eq.u - b.saddle.u)))
    assert abs((sad.energy - opens[0].energy) - b.barrier) < 1e-10
    assert abs(b.barrier - 0.9245913) < 1e-6


def test_window_at_x3_is_bistable_and_its_ends_are_special_points(x3):
    w = x3.window
    assert w["bistable"]
    # the open state ends at a contact fold where the index goes 0 -> 1 (nonsmooth fold)
    top = w["open_max"]["value"]
    f = [f for f in x3.folds if abs(f["value"] - top) < 1e-12]
    assert f and f[0]["kind"] == "contact" and f[0]["stability_change"] == [0, 1]
    # every traced point at Delta = 1.1 is an equilibrium of one of three kinds: the open
    # minimum, the saddle, the encapsulated minimum (lower in energy at this Delta)
    S, states = _states_at(x3, 1.1)
    assert sorted({idx for idx, _eq in states}) == [0, 1]
    e_open = [eq.energy for idx, eq in states if idx == 0 and abs(eq.u[-1]) < 1.0]
    e_enc = [eq.energy for idx, eq in states if idx == 0 and eq.u[-1] > 2.0]
    e_sad = [eq.energy for idx, eq in states if idx == 1]
    # measured 47.588 (encapsulated) < 49.620 (open) < 50.544 (saddle)
    assert e_open and e_enc and e_sad
    assert max(e_enc) < min(e_open) < min(e_sad)
    # the summary lists every branch, with their ends
    summ = x3.summary()
    assert summ["parameter"] == "drop.wetted_length" and len(summ["branches"]) >= 2
    assert all(b["status"] in ("parameter_bound", "contact_lines_meet")
               for b in summ["branches"]), [b["message"] for b in summ["branches"]]


def test_corners_where_a_contact_point_crosses_a_node_are_passed():
    # x = 2, n = 60: S2 sits on node 53 at Delta = 2 (53 h - (L - x)) = 0.663333...; the
    # branch has a corner there (the capillary force's slope in Delta jumps). Before the
    # corner was an event, the corrector stalled there and the trace ended (step_too_small).
    S = DiscreteStrip(60, L, 2.0, 0.68, A, GAMMA)
    eq = open_state(S)
    st = ContinuationSettings(**{**_DEFAULTS, "direction": -1, "max_steps": 2000})
    br = trace_discrete_branch(S, eq, (0.3, 1.0), st, restart=True, max_segments=200)
    assert br.status == "parameter_bound", br.message
    kinks = [s.event for s in br.segments if s.event is not None
             and s.event.kind == "contact_point_on_node"]
    assert kinks
    h = L / 60
    k_expected = 2.0 * (53 * h - (L - 2.0))
    assert any(abs(k.delta - k_expected) < 1e-10 for k in kinks), [k.delta for k in kinks]
    c0 = L - 2.0
    for k in kinks:
        # one contact point, S1 = c0 - Delta/2 or S2 = c0 + Delta/2 at the located Delta,
        # sits on node k.node (arclength; measured ~1e-13); value is that offset
        s1, s2 = c0 - 0.5 * k.delta, c0 + 0.5 * k.delta
        off = min(abs(s1 - k.node * h), abs(s2 - k.node * h))
        assert off < 1e-10 and abs(k.value) < 1e-10, (k.delta, k.node, off)
    assert all(k.kind != "contact_point_on_node" for k in br.events)


def test_downward_restart_and_the_end_where_the_strip_wraps_the_drop():
    # Traced down from the folded strip, the chain goes through touch-downs (a restarted
    # segment used to be sent back up: continue_branch reversed the given tangent for
    # direction -1) and reaches the deposition's branch; traced up, it ends where the
    # contact lines close around the drop.
    S = DiscreteStrip(60, L, 2.0, 1.6, A, GAMMA)
    eq = wrapped_state(S)
    down = trace_discrete_branch(S, eq, (0.5, 2.2),
                                 ContinuationSettings(**{**_DEFAULTS, "direction": -1,
                                                         "max_steps": 2000}),
                                 restart=True, max_segments=400)
    assert down.status == "parameter_bound", down.message
    assert all(np.all(np.diff(s.delta[:2]) < 0) for s in down.segments[:3])
    up = trace_discrete_branch(S, eq, (0.5, 2.2),
                               ContinuationSettings(**{**_DEFAULTS, "max_steps": 2000}),
                               restart=True, max_segments=400)
    assert up.status == "contact_lines_meet", up.message
    end = up.events[-1]
    s_end = S.with_(delta=end.delta)
    # the chord at the located end is the stop value (length; Brent to ~1e-12)
    assert abs(s_end.chord(end.u) - _CHORD_STOP * end.delta) < 1e-9
    # the deposition at small Delta lies on the same chain (one branch, no bistability
    # at x = 2 for this n: the open state turns into the encapsulated one)
    S0 = S.with_(delta=0.6)
    dep = open_state(S0)
    close = []
    for seg in down.segments:
        for d, u in zip(seg.delta, seg.u, strict=True):
            if abs(d - 0.6) < 0.02:
                e = solve_equilibrium(S0, u, active=seg.active, tol=1e-11)
                close.append(np.max(np.abs(e.u - dep.u)))
    assert close and min(close) < 1e-8


def test_cli_branches_fig3_strip_traces_with_contact(tmp_path, capsys):
    out = tmp_path / "br"
    argv = ["branches", "fig3-strip", "--set", "drop.distance_from_end=2", "--set",
            "numerics.n_edges=40", "--json", "--out", str(out)]
    assert main(argv) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["solver"].startswith("discrete strip")
    assert rep["folds"] and rep["events"] > 10
    md = rep["metadata"]
    assert md["n_edges"] == 40 and md["n_edges_refined"] == 60 and md["version"]
    # the window ends carry a discretization error estimate from the refined run
    for key in ("open_max", "encapsulated_min"):
        v = rep["window"][key]
        assert v["value"] is not None and np.isfinite(v["error_estimate"])
        assert abs(v["value"] - v["value_refined"]) == pytest.approx(v["error_estimate"])
    files = [out / f for f in ("branches.json", "branches.png", "branch_0.npz")]
    assert all(f.exists() for f in files)
    with np.load(out / "branch_0.npz") as z:
        meta = json.loads(str(z["metadata"]))
        assert meta["scene"]["drop"]["distance_from_end"] == 2.0
        assert z["u"].shape[0] == z["delta"].shape[0] == z["index"].shape[0]
    # the same numbers twice (reproducible)
    again = trace_contact_branches(load_scene("fig3-strip", {
        "drop.distance_from_end": 2.0, "numerics.n_edges": 40}), refine=False)
    vals = sorted(f["value"] for f in again.folds)
    assert np.allclose(vals, sorted(f["value"] for f in rep["folds"]), rtol=0, atol=1e-12)


@pytest.mark.parametrize(("over", "rng", "key"), [
    ({}, (1.0, 0.5), "--range"),
    ({"drop.distance_from_end": 1.0}, (0.5, 2.5), "--range"),
])
def test_bad_range_is_refused_by_name(over, rng, key):
    sc = load_scene("fig3-strip", over)
    with pytest.raises(SceneError) as e:
        trace_contact_branches(sc, prange=rng, refine=False)
    assert key in str(e.value)


def test_discrete_strip_for_keeps_the_scene_resolution():
    sc = load_scene("fig3-strip", {"numerics.n_edges": 40})
    assert discrete_strip_for(sc).n == 40


def test_lowest_barriers_is_the_minimax_over_saddle_paths():
    from elastocap.strip.barrier_graph import lowest_barriers

    # minima: 0 open (E 0), 1 open (E 1), 2 encapsulated (E -5), 3 open, isolated (E 2);
    # saddles: 0-1 at 3, 1-2 at 2, 0-2 at 10, one with a failed descent (-1) at 0.5
    got = lowest_barriers([0.0, 1.0, -5.0, 2.0], [False, False, True, False],
                          [(3.0, 0, 1), (2.0, 1, 2), (10.0, 0, 2), (0.5, 3, -1)])
    by = {g["minimum"]: g for g in got}
    assert by[0]["barrier"] == 3.0 and by[0]["via"] == 0  # 0 -> 1 -> 2 beats 0 -> 2
    assert by[1]["barrier"] == 1.0 and by[1]["via"] == 1
    assert by[3]["barrier"] == float("inf") and by[3]["via"] == -1
    assert 2 not in by


def test_barrier_graph_agrees_with_the_string_method(x3):
    from elastocap.strip.barrier_graph import barrier_graph

    g = barrier_graph(x3, 1.1)
    # at x = 3, Delta = 1.1, n = 60 the traced branches cross one open minimum, one
    # encapsulated minimum and one saddle joining them
    assert [m["encapsulated"] for m in g.minima] == [True, False]
    assert len(g.saddles) == 1 and sorted(g.saddles[0]["joins"]) == [0, 1]
    (b,) = g.barriers
    S = DiscreteStrip(60, L, 3.0, 1.1, A, GAMMA)
    ref = barrier(S)
    # the string method's barrier (0.9245913, an independent path search) to round-off
    assert abs(b["barrier"] - ref.barrier) < 1e-10
