"""Cheap run functions for sweep tests, importable by spawned workers and subprocesses
(this folder is on their sys.path). Each decides the outcome from the point and the
resolution written into the scene, so tests know the true boundary."""

import json
import math
import os
import signal
import sqlite3
import time
from pathlib import Path

SPREAD_R, SPREAD_D0, SPREAD_C = 0.4429, 0.5943, 0.32  # fig3-strip's spreading law


def point(scene_json):
    """(x, We^1/2, n_edges) of a fig3-strip run."""
    d = json.loads(scene_json)
    delta = d["drop"]["wetted_length"]
    w = (delta - SPREAD_D0) / (2.0 * SPREAD_R * SPREAD_C)
    return d["drop"]["distance_from_end"], w, d["numerics"].get("n_edges", 0)


def result(outcome, reason=None):
    return {"outcome": outcome, "companion_outcome": outcome, "reason": reason,
            "final_measure": 1.0 if outcome == "encapsulated" else 0.0,
            "status": "completed", "steps": 1, "t_end": 1.0, "wall_time_s": 0.0}


def threshold(x, w, thr):
    return result("encapsulated" if w > thr else "open")


def coarse_shift_run(scene_json_name, scene_json):
    """Threshold We^1/2 = 1.03 + 0.5 x, plus 0.3 at fewer than 100 edges for x >= 2: a
    boundary that moves once from the coarsest resolution and then holds."""
    x, w, n = point(scene_json)
    thr = 1.03 + 0.5 * x + (0.3 if (x >= 2.0 and n < 100) else 0.0)
    return threshold(x, w, thr)


coarse_shift_run.runner = "fake-coarse-shift"


def creeping_run(scene_name, scene_json):
    """Threshold 1.03 + 0.5 x + 40 / n_edges: moves at every refinement (never holds to a
    tolerance below the shift, 40 / n - 40 / 1.5 n ~ 0.1 at n ~ 130)."""
    x, w, n = point(scene_json)
    return threshold(x, w, 1.03 + 0.5 * x + 40.0 / n)


creeping_run.runner = "fake-creeping"


def undecided_band_run(scene_name, scene_json):
    """Open below 1.53, undecided in [1.53, 1.83), encapsulated from 1.83 on, at every x."""
    _, w, _ = point(scene_json)
    if w < 1.53:
        return result("open")
    if w < 1.83:
        return result("undecided", "the bundle crossed itself before coming to rest")
    return result("encapsulated")


undecided_band_run.runner = "fake-undecided-band"


def open_but_one_undecided_run(scene_name, scene_json):
    """Open everywhere except We^1/2 = 2 (undecided)."""
    _, w, _ = point(scene_json)
    if abs(w - 2.0) < 1e-9:
        return result("undecided", "not at rest at t_max")
    return result("open")


open_but_one_undecided_run.runner = "fake-open-one-undecided"


def open_but_one_raises_run(scene_name, scene_json):
    """Open everywhere; raises at We^1/2 = 2."""
    _, w, _ = point(scene_json)
    if abs(w - 2.0) < 1e-9:
        raise FloatingPointError("NaN in the positions at step 12")
    return result("open")


open_but_one_raises_run.runner = "fake-open-one-raises"


def _marker(tag, scene_json):
    d = Path(os.environ["SWEEP_FAKE_DIR"])
    x, w, _ = point(scene_json)
    return d / f"{tag}-{x:.6g}-{w:.6g}"


def kills_worker_once_run(scene_name, scene_json):
    """Open everywhere; at We^1/2 = 2 the first attempt kills its own worker (SIGKILL)."""
    _, w, _ = point(scene_json)
    if abs(w - 2.0) < 1e-9:
        m = _marker("killed", scene_json)
        if not m.exists():
            m.write_text(str(os.getpid()))
            os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(0.05)
    return result("open")


kills_worker_once_run.runner = "fake-kills-once"


def kills_worker_always_run(scene_name, scene_json):
    """Open everywhere; at We^1/2 = 2 every attempt kills its worker (counted in files)."""
    _, w, _ = point(scene_json)
    if abs(w - 2.0) < 1e-9:
        m = _marker("attempt", scene_json)
        k = 0
        while m.with_name(f"{m.name}-{k}").exists():
            k += 1
        m.with_name(f"{m.name}-{k}").write_text(str(os.getpid()))
        os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(0.05)
    return result("open")


kills_worker_always_run.runner = "fake-kills-always"


def logged_slow_run(scene_name, scene_json):
    """Threshold 1.03 + 0.5 x; sleeps 0.2 s and appends (pid, point) to a log: two sweeps on
    one store must never compute the same point."""
    x, w, n = point(scene_json)
    time.sleep(0.2)
    with open(os.environ["SWEEP_FAKE_LOG"], "a") as f:
        f.write(f"{os.getpid()} {x!r} {w!r} {n}\n")
    return threshold(x, w, 1.03 + 0.5 * x)


logged_slow_run.runner = "fake-logged-slow"


def sleeping_run(scene_name, scene_json):
    """Writes its worker's pid to SWEEP_FAKE_DIR and sleeps 120 s (killed before that)."""
    Path(os.environ["SWEEP_FAKE_DIR"], f"worker-{os.getpid()}").write_text("")
    time.sleep(120.0)
    return result("open")


sleeping_run.runner = "fake-sleeping"


def _spin(n):
    s = 0.0
    for i in range(n):
        s += math.sin(i * 1e-9)
    return s


def gil_holding_run(scene_name, scene_json):
    """As :func:`sleeping_run`, but busy in compiled code that never releases the GIL (as a
    time stepper is for a whole run), so no Python thread of the worker runs meanwhile."""
    import numba

    spin = numba.njit(_spin)
    spin(10)  # compiled before the pid file says the worker is busy
    Path(os.environ["SWEEP_FAKE_DIR"], f"worker-{os.getpid()}").write_text("")
    spin(10**12)  # about 1000 s: killed before that
    return result("open")


gil_holding_run.runner = "fake-gil-holding"


def late_shift_run(scene_name, scene_json):
    """Threshold We^1/2 = 1.03 + 0.5 x, lowered by 0.3 from 150 edges on: a bracket that
    holds at 1.5x the edges of a coarse sweep and moves at 2.25x."""
    x, w, n = point(scene_json)
    return threshold(x, w, 1.03 + 0.5 * x - (0.3 if n >= 150 else 0.0))


late_shift_run.runner = "fake-late-shift"


def crossing_above_run(scene_name, scene_json):
    """Open below 1.03 + 0.5 x (+ 0.3 under 100 edges), encapsulated up to 1.2 above it,
    undecided (the rod crossed itself) beyond: a threshold with undecided runs above."""
    x, w, n = point(scene_json)
    thr = 1.03 + 0.5 * x + (0.3 if n < 100 else 0.0)
    if w > thr + 1.2:
        return result("undecided", "the rod crossed itself before the verdict settled")
    return threshold(x, w, thr)


crossing_above_run.runner = "fake-crossing-above"



def companion_decides_undecided_run(scene_name, scene_json):
    """As undecided_band_run, but the companion criterion reads the undecided band's final
    shapes as encapsulated (the final state exists; the run is undecided for its own
    reasons, e.g. not at rest)."""
    res = undecided_band_run(scene_name, scene_json)
    if res["outcome"] == "undecided":
        res["companion_outcome"] = "encapsulated"
    return res


companion_decides_undecided_run.runner = "fake-companion-decides-undecided"


def execute_sql(path, sql: str) -> None:
    """Run one SQL statement on an SQLite file and commit (a store tampered with, or
    another database made)."""
    con = sqlite3.connect(path)
    try:
        con.execute(sql)
        con.commit()
    finally:
        con.close()
