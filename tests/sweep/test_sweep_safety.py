"""Sweeps that do not mislead: a killed worker's runs are retried or recorded as failed with
the reason, lines with failed or undecided runs are never reported decided, two sweeps on
one store never compute the same run, killing a sweep ends its workers, refused input
writes nothing (no store, no -wal / -shm)."""

import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import sweep_fakes as fk

from elastocap.scene import load_scene
from elastocap.sweep import ResultStore, run_sweep
from elastocap.sweep.store import StoreError

STRIP = load_scene("fig3-strip", {"numerics.accuracy": "draft"})
HERE = Path(__file__).parent
ROOT = HERE.parents[1]


@pytest.fixture
def pool():
    with ThreadPoolExecutor(2) as ex:
        yield ex


def _env(**kw):
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(HERE), str(ROOT)]), **kw}


# ------------------------------------------------------------------ undecided and failed lines
def test_undecided_is_a_class_of_its_own_in_store_counts_and_refinement(tmp_path, pool):
    res = run_sweep(STRIP, [1.0, 2.0], we_sqrts=[1.0, 2.0, 3.0], store=tmp_path / "s.sqlite",
                    refine_tol=0.01, executor=pool, run_fn=fk.undecided_band_run)
    for b in res.boundary:
        assert b.status == "undecided" and b.decided_status == "bracketed"
        # both edges of the undecided band [1.53, 1.83) bisected to 0.01
        (t1, t2) = b.transitions
        assert (t1.outcome_low, t1.outcome_high) == ("open", "undecided")
        assert (t2.outcome_low, t2.outcome_high) == ("undecided", "encapsulated")
        assert t1.low < 1.53 <= t1.high and t1.width <= 0.01
        assert t2.low < 1.83 <= t2.high and t2.width <= 0.01
        assert b.low == t1.low and b.high == t2.high  # the decided runs' bracket
        assert b.undecided and all(u["reason"] == "the bundle crossed itself before coming "
                                   "to rest" for u in b.undecided)
    rep = res.to_dict()
    n_und = sum(r["outcome"] == "undecided" for r in rep["runs"])
    assert rep["counts"]["undecided"] == rep["counts"]["outcomes"]["undecided"] == n_und > 2
    with ResultStore(tmp_path / "s.sqlite") as st:
        rows = [r for r in st.rows() if r["outcome"] == "undecided"]
    assert len(rows) == n_und and {r["reason"] for r in rows} == {
        "the bundle crossed itself before coming to rest"}


def test_a_line_with_an_undecided_or_failed_run_is_never_all_open(tmp_path, pool):
    kw = dict(we_sqrts=[1.0, 2.0, 3.0], refine_tol=0.1, executor=pool)
    und = run_sweep(STRIP, [3.0], store=tmp_path / "u.sqlite",
                    run_fn=fk.open_but_one_undecided_run, **kw)
    (b,) = und.boundary
    assert b.status == "undecided" and b.decided_status == "all-open"
    assert b.undecided == [{"value": 2.0, "reason": "not at rest at t_max"}]
    fail = run_sweep(STRIP, [3.0], store=tmp_path / "f.sqlite",
                     run_fn=fk.open_but_one_raises_run, **kw)
    (b,) = fail.boundary
    assert b.status == "failed" and b.decided_status == "all-open" and b.failed == [2.0]
    (f,) = fail.failed
    assert f["error"] == "FloatingPointError: NaN in the positions at step 12"
    with ResultStore(tmp_path / "f.sqlite") as st:
        (rec,) = st.failures()
        assert rec["error"] == f["error"] and rec["attempts"] == 1 and rec["we_sqrt"] == 2.0
        assert st.count() == 2 and st.claims() == []


def test_a_killed_worker_is_replaced_and_its_run_retried(tmp_path, monkeypatch):
    monkeypatch.setenv("SWEEP_FAKE_DIR", str(tmp_path))
    res = run_sweep(STRIP, [3.0], we_sqrts=[1.0, 2.0, 3.0, 3.5], store=tmp_path / "s.sqlite",
                    workers=2, run_fn=fk.kills_worker_once_run)
    assert (tmp_path / "killed-3-2").exists()  # the first attempt did kill its worker
    assert res.failed == [] and res.computed == 4
    assert res.boundary[0].status == "all-open"
    with ResultStore(tmp_path / "s.sqlite") as st:
        assert st.count() == 4 and st.failures() == [] and st.claims() == []


def test_a_run_that_always_kills_its_worker_is_recorded_failed(tmp_path, monkeypatch):
    monkeypatch.setenv("SWEEP_FAKE_DIR", str(tmp_path))
    res = run_sweep(STRIP, [3.0], we_sqrts=[1.0, 2.0, 3.0, 3.5], store=tmp_path / "s.sqlite",
                    workers=2, run_fn=fk.kills_worker_always_run)
    (f,) = res.failed
    assert f["we_sqrt"] == pytest.approx(2.0)
    assert "the worker process died while running it, alone in the pool, 3 times" in f["error"]
    assert "BrokenProcessPool" in f["error"] and f["attempts"] == 3
    # the other three runs, in flight with it at the first crash, were not blamed
    assert res.computed == 3
    assert (res.boundary[0].status, res.boundary[0].failed) == ("failed", [2.0])
    with ResultStore(tmp_path / "s.sqlite") as st:
        (rec,) = st.failures()
        assert rec["attempts"] == 3 and "died" in rec["error"]


# ------------------------------------------------------------------------------- claims
def test_claims_lease_and_takeover(tmp_path):
    with ResultStore(tmp_path / "s.sqlite") as st:
        key = ("v", "r", "c")
        stored, mine, theirs = st.claim(["a", "b"], *key, owner="me", lease_s=60)
        assert (stored, mine, theirs) == ({}, {"a", "b"}, set())
        assert st.claim(["a"], *key, owner="other", lease_s=60) == ({}, set(), {"a"})
        # a claim whose process is gone (same host) is taken over at once
        st._con.execute("UPDATE claims SET pid = 2147483646 WHERE scene_digest = 'a'")
        assert st.claim(["a"], *key, owner="other", lease_s=60)[1] == {"a"}
        # a claim of a live process elsewhere is taken over when its lease expires
        st._con.execute("UPDATE claims SET host = 'elsewhere', lease_until = 0 "
                        "WHERE scene_digest = 'b'")
        assert st.claim(["b"], *key, owner="other", lease_s=60)[1] == {"b"}
        st.release("other")
        assert st.claims() == []
        assert socket.gethostname()


SHARED = textwrap.dedent(
    """
    import json, os, sys, time
    from concurrent.futures import ThreadPoolExecutor
    from pathlib import Path
    import sweep_fakes as fk
    from elastocap.impact import impact_settings  # imported before the start signal
    from elastocap.scene import load_scene
    from elastocap.sweep import run_sweep
    scene = load_scene("fig3-strip", {"numerics.accuracy": "draft"})
    go = Path(sys.argv[2])
    Path(f"{go}-ready-{os.getpid()}").write_text("")
    while not go.exists():  # both sweeps start together
        time.sleep(0.01)
    with ThreadPoolExecutor(2) as ex:
        res = run_sweep(scene, [1.0, 2.0, 3.0], we_sqrts=[0.5, 1.5, 2.5, 3.5],
                        store=sys.argv[1], refine_tol=0.1, executor=ex,
                        run_fn=fk.logged_slow_run)
    print(json.dumps({"computed": res.computed, "cached": res.cached,
                      "boundary": [[b.low, b.high] for b in res.boundary]}))
    """
)


def test_two_sweeps_on_one_store_never_compute_the_same_run(tmp_path):
    store, log = tmp_path / "shared.sqlite", tmp_path / "runs.log"
    ResultStore(store).close()  # both start on an existing store
    env = _env(SWEEP_FAKE_LOG=str(log))
    go = tmp_path / "go"
    procs = [subprocess.Popen([sys.executable, "-c", SHARED, str(store), str(go)], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    deadline = time.monotonic() + 120
    while len(list(tmp_path.glob("go-ready-*"))) < 2 and time.monotonic() < deadline:
        time.sleep(0.02)
    go.write_text("")
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1] for o in outs]
    reps = [json.loads(o[0]) for o in outs]
    lines = log.read_text().splitlines()
    points = [tuple(ln.split()[1:]) for ln in lines]
    assert len(points) == len(set(points))  # no run computed twice
    assert len({ln.split()[0] for ln in lines}) == 2  # both sweeps did work
    with ResultStore(store) as st:
        assert st.count() == len(points) and st.claims() == []
    assert sum(r["computed"] for r in reps) == len(points)
    assert reps[0]["boundary"] == reps[1]["boundary"]
    for r in reps:
        assert r["computed"] + r["cached"] == len(points)


# -------------------------------------------------------------------- killing the sweep
KILLABLE = textwrap.dedent(
    """
    import sys
    import sweep_fakes as fk
    from elastocap.scene import load_scene
    from elastocap.sweep import run_sweep
    if __name__ == "__main__":
        scene = load_scene("fig3-strip", {"numerics.accuracy": "draft"})
        run_sweep(scene, [3.0], we_sqrts=[1.0, 2.0, 3.0], store=sys.argv[1], workers=2,
                  run_fn=getattr(fk, sys.argv[2]))
    """
)


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
@pytest.mark.parametrize("run", ["sleeping_run", "gil_holding_run"])
def test_killing_the_sweep_ends_its_workers(tmp_path, run, sig):
    """The orchestrator alone is killed (not its process group), while its workers sleep in
    Python or compute in compiled code that holds the GIL (a time stepper does, for a whole
    run): no worker outlives it by more than a few seconds."""
    script = tmp_path / "killable.py"
    script.write_text(KILLABLE)
    proc = subprocess.Popen([sys.executable, str(script), str(tmp_path / "s.sqlite"), run],
                            env=_env(SWEEP_FAKE_DIR=str(tmp_path)), stderr=subprocess.PIPE)
    pids = []
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and len(pids) < 2:
            pids = [int(p.name.split("-")[1]) for p in tmp_path.glob("worker-*")]
            time.sleep(0.05)
        assert len(pids) == 2, proc.stderr.read1().decode() if proc.poll() else "timeout"
        time.sleep(0.5)  # both workers inside the run
        proc.send_signal(sig)  # the orchestrator only, not its process group
        proc.wait(timeout=30)
        deadline = time.monotonic() + 10
        alive = pids
        while alive and time.monotonic() < deadline:
            alive = [p for p in pids if _alive(p)]
            time.sleep(0.1)
        assert alive == [], "workers outlived their sweep"
    finally:
        if proc.poll() is None:
            proc.kill()
        for p in pids:
            if _alive(p):
                os.kill(p, signal.SIGKILL)
        proc.stderr.close()


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie (dead, not yet reaped by init) counts as gone
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(") ")[1][0] != "Z"
    except FileNotFoundError:
        return False


# ----------------------------------------------------------------- refused input writes nothing
def test_a_store_at_another_resolution_is_refused_and_left_untouched(tmp_path, pool):
    store = tmp_path / "s.sqlite"
    run_sweep(STRIP, [3.0], we_sqrts=[1.0, 2.0], store=store, executor=pool,
              run_fn=fk.coarse_shift_run)
    before = store.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.sqlite"]
    # a wider We range: its largest Delta gives fewer edges
    with pytest.raises(StoreError, match=r"made at n_edges = 99, dt = .*this sweep runs at "
                       r"n_edges = 67.*--set numerics.n_edges=99"):
        run_sweep(STRIP, [3.0], we_sqrts=[1.0, 4.0], store=store, executor=pool,
                  run_fn=fk.coarse_shift_run)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.sqlite"]  # no -wal, no -shm
    assert store.read_bytes() == before
    # the same resolution, asked for explicitly, adds to the store
    res = run_sweep(STRIP.with_overrides({"numerics.n_edges": 99}), [3.0],
                    we_sqrts=[1.0, 4.0], store=store, executor=pool, run_fn=fk.coarse_shift_run)
    assert res.cached == 1 and res.computed == 1


def test_the_command_refuses_another_resolution_with_exit_2_and_writes_nothing(tmp_path,
                                                                                capsys):
    from elastocap.sweep.__main__ import main

    store = tmp_path / "s.sqlite"
    with ResultStore(store) as st:
        st.ensure_resolution({"n_edges": 12, "dt": 0.5, "integrator": "rattle"})
    before = store.read_bytes()
    code = main(["fig3-strip", "--x", "1:2:2", "--we", "1:2:2", "--store", str(store),
                 "--out", str(tmp_path / "o"), "--accuracy", "draft"])
    err = capsys.readouterr().err
    assert code == 2 and "--store: store" in err and "made at n_edges = 12" in err
    assert err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.sqlite"]
    assert store.read_bytes() == before


def test_a_sweep_at_the_top_level_of_a_script_a_worker_imports_is_refused():
    """A spawned worker runs the main script again as ``__mp_main__``: a local pool opened
    there is refused at once (it would wait for the runs its parent has claimed)."""
    from elastocap.sweep.executors import WorkerStartError, check_not_importing_main

    check_not_importing_main()  # a test function: not a script's top level
    code = compile("check_not_importing_main()", "script.py", "exec")
    with pytest.raises(WorkerStartError, match='if __name__ == "__main__":'):
        exec(code, {"__name__": "__mp_main__",
                    "check_not_importing_main": check_not_importing_main})
    exec(code, {"__name__": "__main__", "check_not_importing_main": check_not_importing_main})
