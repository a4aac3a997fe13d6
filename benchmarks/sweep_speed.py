"""Speed of a phase-diagram sweep (not a test): a grid of >= 400 fig3-strip impacts plus
boundary refinement on a local pool, into a fresh store.

Prints impacts per second per core, total wall time (goal: < 10 minutes on 2 cores), the
median and 90th percentile of one run's time (inside the worker), and the pool efficiency
(sum of run times / (wall time x workers)). The numba cache is used as a user would find it
(warm unless the sources changed).

Usage: ``python benchmarks/sweep_speed.py [--workers 2] [--nx 20] [--nwe 20]
[--accuracy draft] [--t-max T] [--refine 0.02] [--fast]``.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections import Counter
from pathlib import Path

from elastocap.scene import load_scene
from elastocap.sweep import ResultStore, make_progress, run_sweep


def main(workers=2, nx=20, nwe=20, accuracy="draft", t_max=None, refine=0.02, fast=False,
         progress="text"):
    if fast:  # a smoke run of the script itself
        nx, nwe, t_max, refine = 3, 3, 5.0, 0.5
    overrides = {"numerics.accuracy": accuracy}
    if t_max is not None:
        overrides["numerics.t_max"] = float(t_max)
    scene = load_scene("fig3-strip", overrides)
    # x/l_eg in [1, 8] and We^1/2 in [0.5, 4]: the region of the paper's Fig 3d; every
    # point's wet interval lies inside the strip (Delta <= 1.73 < 2 x)
    xs = [1.0 + 7.0 * i / (nx - 1) for i in range(nx)] if nx > 1 else [2.0]
    wes = [0.5 + 3.5 * j / (nwe - 1) for j in range(nwe)] if nwe > 1 else [2.0]
    with tempfile.TemporaryDirectory() as tmp:
        store = Path(tmp) / "bench.sqlite"
        t0 = time.perf_counter()
        res = run_sweep(scene, xs, we_sqrts=wes, store=store, refine_tol=refine,
                        workers=workers, progress=make_progress(progress))
        wall = time.perf_counter() - t0
        with ResultStore(store) as st:
            times = sorted(r["wall_time_s"] for r in st.rows())
    n = res.computed
    grid = sum(r["stage"] == "grid" for r in res.runs)
    print(f"scene fig3-strip, accuracy {accuracy}, t_max {scene.numerics.t_max:g}, "
          f"{res.executor}")
    print(f"impacts: {n} ({grid} grid {nx}x{nwe}, {n - grid} refinement to a We^1/2 "
          f"bracket <= {refine}), {len(res.failed)} failed")
    print(f"total wall time: {wall:.1f} s ({wall / 60:.2f} min; goal < 10 min)")
    print(f"impacts per second per core: {n / wall / workers:.3f}")
    print(f"per run (inside the worker): median {statistics.median(times):.3f} s, "
          f"90th percentile {times[int(0.9 * (len(times) - 1))]:.3f} s, max {times[-1]:.3f} s")
    print(f"pool efficiency: {sum(times) / (wall * workers):.2f} (run time / wall x workers)")
    statuses = Counter(r["status"] for r in res.runs)
    lines = Counter(b.status for b in res.boundary)
    print(f"run statuses: {dict(statuses)}; boundary lines: {dict(lines)}; criteria disagree "
          f"on {sum(r['outcome'] != r['companion_outcome'] for r in res.runs)} runs")
    return {"impacts": n, "wall_s": wall, "per_core_per_s": n / wall / workers,
            "median_run_s": statistics.median(times)}


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--nx", type=int, default=20)
    ap.add_argument("--nwe", type=int, default=20)
    ap.add_argument("--accuracy", default="draft", choices=("draft", "default", "publication"))
    ap.add_argument("--t-max", type=float, default=None, help="default: the scene's (200)")
    ap.add_argument("--refine", type=float, default=0.02)
    ap.add_argument("--fast", action="store_true")
    ap.add_argument("--progress", default="text", choices=("none", "text", "tqdm"))
    a = ap.parse_args()
    main(a.workers, a.nx, a.nwe, a.accuracy, a.t_max, a.refine, a.fast, a.progress)
