"""Phase-diagram sweeps of impacts (Antkowiak et al. 2011, Fig 3d), resumable and parallel.

Over (x, We^1/2) -- x in units of l_eg, We^1/2 converted to Delta by the scene's spreading
law -- or over (x, Delta); points whose wet interval leaves the rod are skipped with the
reason. Results land in one SQLite store (:class:`ResultStore`), one row per run, keyed by
(scene digest, package version, code digest, runner), so a re-run or a resumed sweep never
repeats or duplicates a run, and an edit of the physics code never reuses stale results.
Runs go through any :class:`concurrent.futures.Executor`: a spawn-context process pool
locally (one numba thread per worker) or a dask cluster. Each x line's
boundary is bisected to a tolerance; non-monotonic lines are detected and reported.

Quick use::

    from elastocap.scene import load_scene
    from elastocap.sweep import run_sweep, plot_phase_diagram

    scene = load_scene("fig3-strip", {"numerics.accuracy": "draft"})
    res = run_sweep(scene, [1, 2, 3], we_sqrts=[0.5, 1.5, 2.5], store="sweep.sqlite",
                    refine_tol=0.05, workers=2)
    plot_phase_diagram(res, "phase.png")
    df = load("sweep.sqlite")  # the runs as a pandas DataFrame (the 'export' extra)

Every run of a sweep uses one discretization (:func:`sweep_resolutions`), recorded in the
store; ``verify_levels=1`` re-runs every boundary bracket at 1.5x the edges and half the
time step and reports whether it holds (see :mod:`elastocap.sweep.engine`).
"""

from elastocap.sweep.engine import (
    MAX_LEVELS,
    Resolution,
    Sweep,
    SweepResult,
    check_sweep_resources,
    report_from_store,
    run_sweep,
    sweep_resolutions,
)
from elastocap.sweep.executors import MissingExtraError, SweepExecutor, open_executor
from elastocap.sweep.export import export_runs, load
from elastocap.sweep.grid import SkippedPoint, SweepPoint, grid_points, make_point, parse_range
from elastocap.sweep.plot import load_experiments, plot_phase_diagram
from elastocap.sweep.progress import NoProgress, TextProgress, TqdmProgress, make_progress
from elastocap.sweep.refine import Boundary, Transition, classify_line
from elastocap.sweep.store import ResultStore, StoreError
from elastocap.sweep.tasks import run_impact_task

__all__ = [
    "MAX_LEVELS",
    "Boundary",
    "Resolution",
    "export_runs",
    "load",
    "sweep_resolutions",
    "MissingExtraError",
    "NoProgress",
    "ResultStore",
    "SkippedPoint",
    "StoreError",
    "Sweep",
    "SweepExecutor",
    "SweepPoint",
    "SweepResult",
    "TextProgress",
    "Transition",
    "TqdmProgress",
    "check_sweep_resources",
    "classify_line",
    "grid_points",
    "load_experiments",
    "make_point",
    "make_progress",
    "open_executor",
    "parse_range",
    "plot_phase_diagram",
    "report_from_store",
    "run_impact_task",
    "run_sweep",
]
