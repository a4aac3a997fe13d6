"""Branch as data: events, bounds, callbacks, save/load round trip, plotting."""

import json

import matplotlib
import numpy as np
import pytest

import continuation as C
from continuation.examples import BRATU_FOLD, Bratu

matplotlib.use("Agg")

S = C.ContinuationSettings(ds0=0.05, ds_max=0.5, max_steps=60, p_min=0.0, p_max=4.0)


def test_event_located_and_terminal_event_stops():
    prob = Bratu(16, "fd")

    def umax_is_one(u, p):
        return float(np.max(u)) - 1.0

    br = C.continue_branch(prob, np.zeros(15), 0.0, S, events={"umax1": umax_is_one})
    ev = br.points("event")
    assert len(ev) == 1 and ev[0].name == "umax1" and ev[0].located
    assert abs(np.max(ev[0].u) - 1.0) < 1e-10  # Brent in arclength, Newton tol 1e-10
    assert np.max(np.abs(prob.residual(ev[0].u, ev[0].p))) < 1e-9
    # Terminal: the run stops right after the event.
    b2 = C.continue_branch(prob, np.zeros(15), 0.0, S, events=[umax_is_one],
                           stop_on=["umax_is_one"])
    assert b2.status == C.STOPPED and b2.points("event")[0].index == len(b2) - 1
    assert "umax_is_one" in b2.message


def test_terminal_event_on_the_step_cut_back_onto_the_bound_stops_the_run():
    # the step that crosses the event also overshoots p_max: it is cut back onto the bound,
    # and the event, between its start and the bound, still ends the run as terminal
    prob = Bratu(16, "fd")

    def umax_is_one(u, p):
        return float(np.max(u)) - 1.0

    free = C.continue_branch(prob, np.zeros(15), 0.0, S, events=[umax_is_one],
                             stop_on=["umax_is_one"])
    ev = free.points("event")[0]
    p_end = free.p[ev.index]  # the end of the step that crosses the event
    assert free.p[ev.index - 1] < ev.p < p_end
    p_max = 0.5 * (ev.p + p_end)
    br = C.continue_branch(prob, np.zeros(15), 0.0, S.replace(p_max=p_max),
                           events=[umax_is_one], stop_on=["umax_is_one"])
    assert br.p[-1] == p_max  # the step was cut back onto the bound
    assert br.status == C.STOPPED and "umax_is_one" in br.message
    e2 = br.points("event")
    assert len(e2) == 1 and e2[0].index == len(br) - 1
    assert abs(e2[0].p - ev.p) < 1e-9 and abs(np.max(e2[0].u) - 1.0) < 1e-10


def test_bound_is_hit_exactly_and_callback_can_stop():
    prob = Bratu(16)
    br = C.continue_branch(prob, np.zeros(15), 0.0, S.replace(p_max=2.0))
    assert br.status == C.PARAMETER_BOUND and br.p[-1] == 2.0
    assert np.max(np.abs(prob.residual(br.u[-1], 2.0))) < 1e-10
    seen = []

    def cb(info):
        seen.append(info["step"])
        return info["step"] < 5

    b2 = C.continue_branch(prob, np.zeros(15), 0.0, S, callback=cb)
    assert b2.status == C.STOPPED and len(b2) == 6 and seen == [1, 2, 3, 4, 5]


def test_store_states_false_keeps_observables_and_special_states():
    br = C.continue_branch(Bratu(16), np.zeros(15), 0.0, S.replace(store_states=False))
    assert br.u is None and br.tangent is None
    assert br.observables["u_max"].shape == br.p.shape
    assert br.folds[0].u.shape == (15,) and abs(br.folds[0].p - BRATU_FOLD) < 2e-9


def test_save_is_atomic_a_failed_write_leaves_the_old_files(tmp_path, monkeypatch):
    br = C.continue_branch(Bratu(16, "fd"), np.zeros(15), 0.0, S)
    path = br.save(tmp_path / "bratu")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}

    def half_written(f, **arrays):
        f.write(b"PK\x03\x04 cut")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", half_written)
    with pytest.raises(OSError, match="disk full"):
        br.save(path)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before  # no temp left


def test_save_load_round_trip(tmp_path):
    br = C.continue_branch(Bratu(16, "fd"), np.zeros(15), 0.0, S)
    path = br.save(tmp_path / "bratu")
    assert path.suffix == ".npz" and path.with_suffix(".json").exists()
    summary = json.loads(path.with_suffix(".json").read_text())
    assert summary["metadata"]["problem"] == "bratu-fd-16"
    assert summary["metadata"]["settings"]["newton_tol"] == 1e-10
    assert summary["metadata"]["version"]
    b2 = C.Branch.load(path)
    assert np.array_equal(b2.p, br.p) and np.array_equal(b2.u, br.u)
    assert np.array_equal(b2.stability, br.stability)
    assert np.array_equal(b2.observables["u_max"], br.observables["u_max"])
    assert [s.kind for s in b2.special_points] == [s.kind for s in br.special_points]
    f1, f2 = br.folds[0], b2.folds[0]
    assert f1.p == f2.p and np.array_equal(f1.u, f2.u)
    assert np.array_equal(f1.data["kernel"], f2.data["kernel"])
    assert b2.status == br.status and b2.message == br.message
    # the whole branch, every field, arrays by value: == compares results as data
    assert b2 == br and b2.folds[0] == br.folds[0]
    b2.folds[0].u[3] += 1e-12
    assert b2 != br and b2.folds[0] != br.folds[0]
    assert br.folds[0] != br.folds[0].p  # another type: not equal, no error
    # Incomplete files are refused by naming what is missing.
    np.savez(tmp_path / "bad.npz", p=br.p)
    with pytest.raises(ValueError, match=r"missing arrays \['ds', 'metadata_json'"):
        C.Branch.load(tmp_path / "bad.npz")


def test_plot_stable_solid_unstable_dashed():
    import matplotlib.pyplot as plt

    br = C.continue_branch(Bratu(16, "fd"), np.zeros(15), 0.0, S)
    fig, ax = plt.subplots()
    br.plot(ax, y="u_max", label="Bratu")
    styles = [ln.get_linestyle() for ln in ax.lines if len(ln.get_xdata()) > 1]
    assert styles == ["-", "--"]  # lower branch stable, upper unstable
    markers = [ln.get_marker() for ln in ax.lines if len(ln.get_xdata()) == 1]
    assert "o" in markers  # the fold
    assert ax.get_xlabel() == "p" and ax.get_ylabel() == "u_max"
    with pytest.raises(ValueError, match="not an observable"):
        br.plot(ax, y="nope")
    plt.close(fig)
