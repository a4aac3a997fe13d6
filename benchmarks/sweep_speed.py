"""Speed of a phase-diagram sweep (not a test): a grid of >= 400 fig3-strip impacts plus
boundary refinement (and, with --verify, verification) on a local pool and/or a real
dask.distributed LocalCluster with the same number of workers, each into a fresh store.
With both executors the rows are compared (they must be identical) and the wall-time ratio
printed.

Prints impacts per second per core, total wall time (goal: < 10 minutes on 2 cores), the
median and 90th percentile of one run's time (inside the worker), and the pool efficiency
(sum of run times / (wall time x workers)). The numba cache is used as a user would find it
(warm unless the sources changed).

Usage: ``python benchmarks/sweep_speed.py [--workers 2] [--nx 20] [--nwe 20]
[--accuracy draft] [--t-max T] [--refine 0.02] [--verify] [--executors local,dask]
[--fast]``; ``--fig3d [--executors local,dask]``: the shipped Fig 3d's sweeps (both
criteria, refinement and every verification level) instead of the grid.
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


def _sweep(scene, xs, wes, refine, workers, progress, verify, executor, fig3d=False):
    """One sweep into a fresh store: (result, wall time, per-run times, table of rows).
    ``fig3d``: the shipped Fig 3d's two sweeps instead (both criteria, its grid, refinement
    and verification levels, the ``default`` preset)."""
    import contextlib

    with tempfile.TemporaryDirectory() as tmp, contextlib.ExitStack() as stack:
        store = Path(tmp) / "bench.sqlite"
        kw = {"workers": workers}
        if executor == "dask":
            import warnings

            from distributed import LocalCluster

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                cluster = stack.enter_context(LocalCluster(
                    n_workers=workers, threads_per_worker=1, processes=True,
                    dashboard_address=None, env={"NUMBA_NUM_THREADS": "1"}))
            kw = {"scheduler": cluster.scheduler_address}
        t0 = time.perf_counter()
        if fig3d:
            from elastocap.paper_figures.fig3d import fig3d_sweeps

            res, _ = fig3d_sweeps(store, "default", **kw)
        else:
            res = run_sweep(scene, xs, we_sqrts=wes, store=store, refine_tol=refine,
                            progress=make_progress(progress), verify_levels=int(verify),
                            **kw)
        wall = time.perf_counter() - t0
        with ResultStore(store) as st:
            rows = st.rows()
    times = sorted(r["wall_time_s"] for r in rows)
    table = {r["scene_digest"]: tuple(r[k] for k in ("outcome", "companion_outcome",
                                                     "final_measure", "steps", "t_end",
                                                     "n_edges", "dt", "level"))
             for r in rows}
    return res, wall, times, table


def main(workers=2, nx=20, nwe=20, accuracy="draft", t_max=None, refine=0.02, fast=False,
         progress="text", verify=False, executors=("local",), fig3d=False):
    if fast:  # a smoke run of the script itself
        nx, nwe, t_max, refine = 3, 3, 5.0, 0.5
    if fig3d:
        from elastocap.paper_figures.fig3d import FIG3D_TOL, fig3d_scene

        scene = fig3d_scene("default")
        accuracy, t_max, refine, nx, nwe = "default", scene.numerics.t_max, FIG3D_TOL, 12, 8
        verify = True  # (its own levels: every-level checks at 1.5x, 2.25x, 3.375x)
    overrides = {"numerics.accuracy": accuracy}
    if t_max is not None:
        overrides["numerics.t_max"] = float(t_max)
    scene = load_scene("fig3-strip", overrides)
    # x/l_eg in [1, 8] and We^1/2 in [0.5, 4]: the region of the paper's Fig 3d; every
    # point's wet interval lies inside the strip (Delta <= 1.73 < 2 x)
    xs = [1.0 + 7.0 * i / (nx - 1) for i in range(nx)] if nx > 1 else [2.0]
    wes = [0.5 + 3.5 * j / (nwe - 1) for j in range(nwe)] if nwe > 1 else [2.0]
    out, tables, walls = {}, {}, {}
    for executor in executors:
        res, wall, times, table = _sweep(scene, xs, wes, refine, workers, progress, verify,
                                         executor, fig3d)
        tables[executor], walls[executor] = table, wall
        n = len(table) if fig3d else res.computed  # fig3d: both criteria's runs
        grid = sum(r["stage"] == "grid" for r in res.runs)
        print(f"--- {executor}: scene fig3-strip, accuracy {accuracy}, t_max "
              f"{scene.numerics.t_max:g}, {res.executor}, "
              f"{res.resolutions[0].n_edges} edges")
        print(f"impacts: {n} ({grid} grid {nx}x{nwe}, {n - grid} refinement to a We^1/2 "
              f"bracket <= {refine}{' and verification' if verify else ''}), "
              f"{len(res.failed)} failed")
        print(f"total wall time: {wall:.1f} s ({wall / 60:.2f} min; goal < 10 min)")
        print(f"impacts per second per core: {n / wall / workers:.3f}")
        print(f"per run (inside the worker): median {statistics.median(times):.3f} s, "
              f"90th percentile {times[int(0.9 * (len(times) - 1))]:.3f} s, max "
              f"{times[-1]:.3f} s")
        print(f"pool efficiency: {sum(times) / (wall * workers):.2f} (run time / wall x "
              "workers)")
        statuses = Counter(r["status"] for r in res.runs)
        lines = Counter(b.status for b in res.boundary)
        print(f"run statuses: {dict(statuses)}; boundary lines: {dict(lines)}; criteria "
              f"disagree on {sum(r['outcome'] != r['companion_outcome'] for r in res.runs)} "
              "runs")
        out[executor] = {"impacts": n, "wall_s": wall, "per_core_per_s": n / wall / workers,
                         "median_run_s": statistics.median(times)}
    if len(tables) == 2:
        a, b = tables.values()
        same = a == b
        print(f"rows identical on both executors: {same} ({len(a)} runs)")
        print(f"wall time dask / local: {walls['dask'] / walls['local']:.2f}")
        out["identical"] = same
    return out[executors[0]] if len(executors) == 1 else out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--nx", type=int, default=20)
    ap.add_argument("--nwe", type=int, default=20)
    ap.add_argument("--accuracy", default="draft", choices=("draft", "default", "publication"))
    ap.add_argument("--t-max", type=float, default=None, help="default: the scene's (200)")
    ap.add_argument("--refine", type=float, default=0.02)
    ap.add_argument("--verify", action="store_true")
    ap.add_argument("--executors", default="local",
                    help="comma-separated: local, dask (a LocalCluster of --workers workers)")
    ap.add_argument("--fast", action="store_true")
    ap.add_argument("--fig3d", action="store_true",
                    help="the shipped Fig 3d's sweeps (elastocap figures --only fig3d) "
                    "instead of the grid options")
    ap.add_argument("--progress", default="text", choices=("none", "text", "tqdm"))
    a = ap.parse_args()
    main(a.workers, a.nx, a.nwe, a.accuracy, a.t_max, a.refine, a.fast, a.progress, a.verify,
         tuple(a.executors.split(",")), a.fig3d)
