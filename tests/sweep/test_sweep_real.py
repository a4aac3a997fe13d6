"""End-to-end sweeps of real impacts (fig3-strip, draft accuracy, short t_max): the local
spawn pool, a sweep killed by SIGKILL and resumed, and a dask LocalCluster. The physics is
whatever run_impact returns; these tests check that the machinery records it faithfully."""

import json
import os
import signal
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

from elastocap.criteria import companion_outcome
from elastocap.impact import run_impact
from elastocap.scene import load_scene
from elastocap.sweep import ResultStore, open_executor, run_sweep
from elastocap.sweep.executors import worker_info
from elastocap.sweep.tasks import code_fingerprint

# draft and t_max = 8: each impact ~0.05 s once compiled, outcomes of both kinds on this grid
OVERRIDES = {"numerics.accuracy": "draft", "numerics.t_max": 8.0}
SCENE = load_scene("fig3-strip", OVERRIDES)


def _table(store_path) -> dict:
    with ResultStore(store_path) as st:
        return {r["scene_digest"]: (r["outcome"], r["companion_outcome"], r["final_measure"],
                                    r["companion_measure"], r["steps"], r["t_end"], r["status"],
                                    r["reason"], r["level"], r["n_edges"], r["dt"])
                for r in st.rows()}


def test_local_workers_have_one_numba_thread():
    with open_executor(workers=2) as ex:
        infos = [f.result() for f in [ex.executor.submit(worker_info) for _ in range(4)]]
    assert ex.slots == 2 and ex.description == "local pool, 2 workers"
    assert {i["NUMBA_NUM_THREADS"] for i in infos} == {"1"}
    assert {i["numba_threads"] for i in infos} == {1}
    assert os.getpid() not in {i["pid"] for i in infos}


def test_real_sweep_records_what_run_impact_returns(tmp_path):
    res = run_sweep(SCENE, [2.0, 4.0], we_sqrts=[1.0, 3.0], store=tmp_path / "s.sqlite",
                    workers=2)
    assert res.failed == [] and res.computed == 4 and len(res.runs) == 4
    with ResultStore(tmp_path / "s.sqlite") as st:
        rows = st.rows(positions=True)
    assert len(rows) == 4
    # one point re-run here, in-process: the stored row is that run, field by field
    r = next(r for r in rows if r["x"] == 2.0 and r["we_sqrt"] == 3.0)
    # one resolution for the sweep: the draft preset at the largest Delta (We^1/2 = 3,
    # Delta = 1.4447): ceil(8 L / Delta) = ceil(79.19) = 80 edges, on every run
    assert {q["n_edges"] for q in rows} == {80} and res.resolutions[0].n_edges == 80
    sc = SCENE.with_overrides({"drop.distance_from_end": 2.0,
                               "drop.wetted_length": SCENE.spreading.delta(3.0),
                               "numerics.n_edges": 80})
    assert sc.digest() == r["scene_digest"] and json.loads(r["scene_json"]) == sc.data
    direct = run_impact(sc)
    assert (r["outcome"], r["final_measure"], r["steps"], r["t_end"], r["status"]) == (
        direct.outcome, direct.final_measure, direct.steps, direct.t_end, direct.status)
    assert r["reason"] == direct.undecided_reason
    # t_max = 8 stops these runs before rest: each stored undecided row says why
    assert all(q["reason"] for q in rows if q["outcome"] == "undecided")
    assert r["rod_crossing_time"] == direct.rod_crossing_time
    assert (r["n_edges"], r["dt"]) == (direct.settings["n_edges"], direct.settings["dt"])
    np.testing.assert_array_equal(r["final_positions"], direct.simulation.positions[-1])
    comp = companion_outcome(r["final_positions"], sc)
    # an undecided run is undecided under the companion criterion too; its measure is kept
    assert r["companion_measure"] == comp.measure
    assert r["companion_outcome"] == (comp.outcome if direct.outcome != "undecided"
                                      else "undecided")
    assert any(q["outcome"] == "undecided" for q in rows)
    assert all(q["companion_outcome"] == "undecided" for q in rows
               if q["outcome"] == "undecided")
    assert r["version"] and r["runner"] == "impact" and r["wall_time_s"] > 0


SWEEP_ARGS = ["fig3-strip", "--x", "1:4:4", "--we", "0.5:3:6", "--workers", "2",
              "--refine", "0.3", "--progress", "none",
              "--set", "numerics.accuracy='draft'", "--set", "numerics.t_max=40.0"]


def _sweep_cmd(store, out):
    return [sys.executable, "-m", "elastocap.sweep", *SWEEP_ARGS, "--store", str(store),
            "--out", str(out), "--json"]


def test_killed_sweep_resumes_without_loss_or_duplicates(tmp_path):
    """SIGKILL a real sweep (its whole process group: orchestrator and workers) once it has
    stored a few runs; resume it; the final table equals an uninterrupted run's."""
    code_before = code_fingerprint()
    store = tmp_path / "killed.sqlite"
    err_log = (tmp_path / "killed.stderr").open("w")
    proc = subprocess.Popen(_sweep_cmd(store, tmp_path / "o1"), stdout=subprocess.DEVNULL,
                            stderr=err_log, start_new_session=True)
    stored_at_kill = 0
    try:
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline and proc.poll() is None:
            if store.exists():
                try:
                    with ResultStore(store) as st:
                        stored_at_kill = st.count()
                except Exception:  # the file may be in creation
                    stored_at_kill = 0
                if stored_at_kill >= 5:
                    break
            time.sleep(0.02)
        assert proc.poll() is None, "the sweep finished before it could be killed"
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        err_log.close()
    assert proc.returncode == -signal.SIGKILL, (tmp_path / "killed.stderr").read_text()
    with ResultStore(store) as st:
        assert st.integrity() == "ok"
        after_kill = st.count()
        # no half-written row: every required column is filled
        for r in st.rows():
            assert r["outcome"] in ("open", "encapsulated", "undecided")
            assert r["status"] and r["created_utc"] and (r["outcome"] != "undecided"
                                                         or r["reason"])
    assert after_kill >= stored_at_kill >= 5

    resumed = subprocess.run(_sweep_cmd(store, tmp_path / "o2"), capture_output=True, text=True,
                             timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    rep = json.loads(resumed.stdout)
    fresh = subprocess.run(_sweep_cmd(tmp_path / "fresh.sqlite", tmp_path / "o3"),
                           capture_output=True, text=True, timeout=300)
    assert fresh.returncode == 0, fresh.stderr
    rep_fresh = json.loads(fresh.stdout)

    code_after = code_fingerprint()
    assert code_after == code_before, (
        "elastocap/dynamics sources were edited during this test (code digest "
        f"{code_before} -> {code_after}): runs before and after are different runs; rerun")
    killed_table, fresh_table = _table(store), _table(tmp_path / "fresh.sqlite")
    assert killed_table == fresh_table  # nothing lost, nothing extra, same numbers
    assert rep["counts"]["computed"] + after_kill == len(fresh_table)
    assert rep["counts"]["cached"] == after_kill
    with ResultStore(store) as st:
        n, distinct = st._con.execute(
            "SELECT COUNT(*), COUNT(DISTINCT scene_digest) FROM runs").fetchone()
    assert n == distinct == len(fresh_table) >= 24
    assert rep["boundary"] == rep_fresh["boundary"]


@pytest.mark.filterwarnings(
    # distributed's LocalCluster closes its comms after the event loop in some versions,
    # leaving ResourceWarnings about sockets it owns; not ours
    "ignore::ResourceWarning"
)
def test_dask_local_cluster_gives_the_local_results(tmp_path):
    distributed = pytest.importorskip("distributed")
    xs, wes = [1.5, 3.0], [0.8, 2.4]
    local = run_sweep(SCENE, xs, we_sqrts=wes, store=tmp_path / "local.sqlite", workers=2,
                      refine_tol=0.4)
    with warnings.catch_warnings():
        # dask may warn that the scheduler's port differs or that a worker's memory limit is
        # unset in a container; configuration chatter unrelated to the sweep
        warnings.filterwarnings("ignore", category=UserWarning, module="distributed")
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                      dashboard_address=None) as cluster:
            remote = run_sweep(SCENE, xs, we_sqrts=wes, store=tmp_path / "dask.sqlite",
                               scheduler=cluster.scheduler_address, refine_tol=0.4)
    assert remote.executor.startswith("dask cluster tcp://")
    assert remote.computed == local.computed == len(local.runs) >= 4
    assert _table(tmp_path / "dask.sqlite") == _table(tmp_path / "local.sqlite")
    assert [b.to_dict() for b in remote.boundary] == [b.to_dict() for b in local.boundary]


@pytest.mark.slow
def test_two_real_sweeps_share_one_store_at_once(tmp_path):
    """Two sweeps with overlapping grids (x = 2, 3 shared) write one store concurrently: the
    union of their runs, each once, and the file sound."""
    store = tmp_path / "shared.sqlite"
    cmds = []
    for k, xr in enumerate(("1:3:3", "2:4:3")):
        args = ["fig3-strip", "--x", xr, "--we", "0.5:3:4", "--workers", "1", "--progress",
                "none", "--set", "numerics.accuracy='draft'", "--set", "numerics.t_max=20.0",
                "--store", str(store), "--out", str(tmp_path / f"o{k}"), "--json"]
        cmds.append([sys.executable, "-m", "elastocap.sweep", *args])
    procs = [subprocess.Popen(c, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for c in cmds]
    outs = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1] for o in outs]
    reps = [json.loads(o[0]) for o in outs]
    with ResultStore(store) as st:
        assert st.integrity() == "ok"
        n, distinct = st._con.execute(
            "SELECT COUNT(*), COUNT(DISTINCT scene_digest) FROM runs").fetchone()
    assert n == distinct == 4 * 4  # x = 1, 2, 3, 4 times 4 values of We^1/2
    # each shared point was computed by one sweep and found (or lost the race) by the other
    assert sum(r["counts"]["computed"] for r in reps) >= 16
