"""Phase-diagram sweeps of impacts: grid, store, executor and boundary refinement.

The orchestrator (:class:`Sweep`) owns the store, the executor and the progress meter;
runs happen in workers through a run function (:mod:`elastocap.sweep.tasks`) and come back
as plain data; the orchestrator writes each to the store in its own transaction as it
arrives. Nothing here prints.

Refinement (Antkowiak et al. 2011, Fig 3d: one critical We^1/2 per x): for every x line the
computed outcomes are classified (:func:`elastocap.sweep.refine.classify_line`); each
outcome change is bisected in the line variable until its bracket is narrower than the
tolerance. Midpoints of all lines are run together, one round per halving, so a round keeps
every worker busy. Midpoints are deterministic (exact halves), so a resumed refinement finds
its earlier runs in the store.
"""

from __future__ import annotations

import contextlib
import math
import time
from concurrent.futures import FIRST_COMPLETED, Executor, wait
from dataclasses import dataclass
from pathlib import Path

from elastocap._version import __version__
from elastocap.scene import Scene
from elastocap.sweep.executors import SweepExecutor, open_executor
from elastocap.sweep.grid import SkippedPoint, SweepPoint, grid_points, length_unit, make_point
from elastocap.sweep.progress import NoProgress, Progress
from elastocap.sweep.refine import Boundary, classify_line
from elastocap.sweep.store import ResultStore
from elastocap.sweep.tasks import RESULT_KEYS, run_impact_task, runner_name

__all__ = ["Sweep", "SweepResult", "run_sweep"]

#: Scene keys every sweep point sets (a --set of one of them would be silently replaced).
SWEPT_KEYS = ("drop.distance_from_end", "drop.wetted_length", "drop.center")


@dataclass
class SweepResult:
    """Everything a sweep produced (plain data; :meth:`to_dict` is the ``--json`` report).

    ``runs`` holds one dict per requested point (grid first, then refinement), each with the
    point (``x`` in the sweep's x unit, ``x_scene``, ``we_sqrt``, ``wetted_length``), the
    stored result columns, ``stage`` ("grid" or "refine") and ``cached`` (found in the store
    rather than computed by this sweep).
    """

    scene_name: str
    variable: str
    x_unit: str
    x_unit_value: float
    runs: list[dict]
    skipped: list[SkippedPoint]
    failed: list[dict]
    boundary: list[Boundary]
    computed: int
    cached: int
    wall_time_s: float
    store: str
    executor: str
    version: str = __version__
    refine_tolerance: float | None = None
    criterion: str = "outcome"

    def to_dict(self) -> dict:
        def bnd(b: Boundary) -> dict:
            d = b.to_dict()
            d["x"] = b.x_over_leg
            d["x_scene"] = b.x
            del d["x_over_leg"]
            return d

        return {
            "scene": self.scene_name,
            "version": self.version,
            "variable": self.variable,
            "x_unit": self.x_unit,
            "x_unit_value": self.x_unit_value,
            "criterion": self.criterion,
            "refine_tolerance": self.refine_tolerance,
            "store": self.store,
            "executor": self.executor,
            "counts": {
                "runs": len(self.runs),
                "computed": self.computed,
                "cached": self.cached,
                "skipped": len(self.skipped),
                "failed": len(self.failed),
                "disagreements": sum(r["outcome"] != r["companion_outcome"] for r in self.runs),
            },
            "wall_time_s": self.wall_time_s,
            "runs": self.runs,
            "skipped": [s.to_dict() for s in self.skipped],
            "failed": self.failed,
            "boundary": [bnd(b) for b in self.boundary],
        }


def _row_for_report(point: SweepPoint, row: dict, stage: str, cached: bool) -> dict:
    out = {
        "x": point.x_over_leg,
        "x_scene": point.x,
        "we_sqrt": point.we_sqrt,
        "wetted_length": point.wetted_length,
        "stage": stage,
        "cached": cached,
    }
    for k, v in row.items():
        if k in (
            "final_positions",
            "x",
            "x_over_leg",
            "we_sqrt",
            "wetted_length",
            "scene_json",
            "settings_json",
            "id",
        ):
            continue
        out[k] = v
    return out


class Sweep:
    """Runs batches of sweep points through an executor into a store.

    Parameters
    ----------
    scene : Scene
        The base scene; each point overrides ``drop.distance_from_end`` and
        ``drop.wetted_length``.
    store : ResultStore
    executor : SweepExecutor or concurrent.futures.Executor
        A bare executor is assumed to have ``slots`` workers.
    run_fn : callable, optional
        ``run_fn(scene_name, scene_json) -> dict`` (:mod:`elastocap.sweep.tasks`); default
        a real impact.
    progress : Progress, optional
    slots : int, optional
        Workers behind a bare executor (default 2).
    """

    def __init__(
        self,
        scene: Scene,
        store: ResultStore,
        executor,
        *,
        run_fn=run_impact_task,
        progress: Progress | None = None,
        slots: int = 2,
    ):
        if isinstance(executor, Executor):
            executor = SweepExecutor(executor, slots, type(executor).__name__)
        self.scene = scene
        self.store = store
        self.executor = executor
        self.run_fn = run_fn
        self.runner = runner_name(run_fn)
        self.progress = progress or NoProgress()
        self.version = __version__
        code = getattr(run_fn, "code_digest", None)
        self.code_digest = code() if callable(code) else (code or "")
        self.computed = 0
        self.cached = 0
        self.failed: list[dict] = []
        self._done = 0
        self._total = 0

    def _tick(self, note: str) -> None:
        self._done += 1
        self.progress(self._done, self._total, note)

    def run_points(self, points: list[SweepPoint], stage: str = "grid") -> list[dict | None]:
        """Run (or find in the store) each point; return its report row, None if it failed.

        Each new result is written in its own transaction as soon as it arrives. Points
        sharing a scene digest run once.
        """
        scenes = [self.scene.with_overrides(p.overrides()) for p in points]
        digests = [s.digest() for s in scenes]
        stored = self.store.get_many(digests, self.version, self.runner, self.code_digest)
        self._total += len(points)
        first: dict[str, int] = {}
        for i, d in enumerate(digests):
            first.setdefault(d, i)
        self.cached += sum(d in stored for d in first)
        result_rows: dict[str, dict] = dict(stored)
        for d in digests:
            if d in stored:
                self._tick(f"{stage}: stored")
        todo = [i for d, i in first.items() if d not in stored]
        pending: dict = {}
        queue = list(reversed(todo))
        ex = self.executor
        while queue or pending:
            while queue and len(pending) < ex.max_in_flight:
                i = queue.pop()
                sc = scenes[i]
                try:
                    fut = ex.executor.submit(self.run_fn, sc.name, sc.to_json())
                except Exception as err:  # a broken pool: every later run fails the same way
                    self.failed.append({**points[i].to_dict(), "stage": stage,
                                        "error": f"{type(err).__name__}: {err}"})
                    self._tick(f"{stage}: FAILED")
                    continue
                pending[fut] = i
            if not pending:
                continue
            done, _ = wait(list(pending), return_when=FIRST_COMPLETED)
            for fut in done:
                i = pending.pop(fut)
                d, p, sc = digests[i], points[i], scenes[i]
                try:
                    res = fut.result()
                    missing = [
                        k for k in ("outcome", "companion_outcome", "status") if k not in res
                    ]
                    if missing:
                        raise ValueError(f"run function returned no {', '.join(missing)}")
                    theirs = (res.get("version", self.version),
                              res.get("code_digest", self.code_digest))
                    if theirs != (self.version, self.code_digest):
                        raise RuntimeError(
                            f"the worker runs elastocap {theirs[0]} (code {theirs[1]}), this "
                            f"sweep {self.version} (code {self.code_digest}): install the "
                            "same code on every worker (or restart the workers after an edit)"
                        )
                except Exception as err:  # a run that raised is reported, not stored
                    self.failed.append(
                        {**p.to_dict(), "stage": stage, "error": f"{type(err).__name__}: {err}"}
                    )
                    self._tick(f"{stage}: FAILED")
                    continue
                row = {k: res.get(k) for k in RESULT_KEYS}
                row.update(
                    scene_digest=d,
                    version=self.version,
                    code_digest=self.code_digest,
                    runner=self.runner,
                    scene_name=sc.name,
                    scene_json=sc.to_json(),
                    x=p.x,
                    x_over_leg=p.x_over_leg,
                    we_sqrt=p.we_sqrt,
                    wetted_length=p.wetted_length,
                )
                if not self.store.put(row):  # another sweep stored it first: use theirs
                    row = self.store.get(d, self.version, self.runner, self.code_digest) or row
                result_rows[d] = row
                self.computed += 1
                self._tick(f"{stage}: {row['outcome']}")
        # points repeating an earlier point of the batch are done with it
        for i, d in enumerate(digests):
            if d not in stored and first[d] != i:
                self._tick(f"{stage}: duplicate")
        out: list[dict | None] = []
        for i, (p, d) in enumerate(zip(points, digests, strict=True)):
            row = result_rows.get(d)
            cached = d in stored or first[d] != i
            out.append(None if row is None else _row_for_report(p, row, stage, cached))
        return out

    # -------------------------------------------------------------------------- refinement
    def refine(
        self,
        lines: dict[float, list[dict]],
        variable: str,
        tol: float | None,
        criterion: str = "outcome",
    ) -> tuple[list[Boundary], list[dict]]:
        """Classify each x line and bisect its outcome changes to width ``tol``.

        Parameters
        ----------
        lines : dict x_over_leg -> list of report rows on that line
        variable : "we_sqrt" or "wetted_length"
        tol : float or None
            Bracket width to reach (None: classify only).
        criterion : "outcome" (the paper's) or "companion_outcome"

        Returns
        -------
        boundaries : list of Boundary, one per line (in increasing x)
        rows : list of report rows of the refinement runs
        """
        if tol is not None and not (tol > 0.0 and math.isfinite(tol)):
            raise ValueError(f"--refine: got {tol!r}; expected a finite number > 0")
        boundaries: list[Boundary] = []
        for xl in sorted(lines):
            rows = [r for r in lines[xl] if r is not None]
            vals = [r[variable] for r in rows]
            status, trans = classify_line(vals, [r[criterion] for r in rows])
            b = Boundary(
                x_over_leg=xl,
                x=xl * length_unit(self.scene)[0],
                variable=variable,
                status=status,
                transitions=trans,
                tolerance=tol,
            )
            boundaries.append(b)
        new_rows: list[dict] = []
        if tol is not None:
            active = [(b, t) for b in boundaries for t in b.transitions if t.width > tol]
            while active:
                points, keep = [], []
                for b, t in active:
                    mid = 0.5 * (t.low + t.high)
                    if not t.low < mid < t.high:  # tol below the float spacing: stop here
                        b.notes.append(f"bracket [{t.low!r}, {t.high!r}] at float resolution")
                        continue
                    kw = {variable: mid}
                    p = make_point(self.scene, b.x_over_leg, **kw)
                    if isinstance(p, SkippedPoint):  # cannot happen inside a valid bracket
                        b.notes.append(f"midpoint {mid!r} skipped: {p.reason}")
                        continue
                    points.append(p)
                    keep.append((b, t, mid))
                rows = self.run_points(points, stage="refine")
                active = []
                for (b, t, mid), row in zip(keep, rows, strict=True):
                    b.refinement_runs += 1
                    if row is None:
                        b.notes.append(f"run failed at {variable} = {mid!r}; bisection stopped")
                        continue
                    new_rows.append(row)
                    if row[criterion] == t.outcome_low:
                        t.low = mid
                    else:
                        t.high = mid
                    if t.width > tol:
                        active.append((b, t))
        for b in boundaries:
            if b.status == "bracketed":
                b.low, b.high = b.transitions[0].low, b.transitions[0].high
            elif b.status == "all-open":
                b.low = max(r[variable] for r in lines[b.x_over_leg] if r is not None)
            elif b.status == "all-encapsulated":
                b.high = min(r[variable] for r in lines[b.x_over_leg] if r is not None)
            b.converged = bool(
                tol is not None
                and b.transitions
                and all(t.width <= tol for t in b.transitions)
                and not b.notes
            )
        return boundaries, new_rows


def _boundary_both_units(b: Boundary, scene: Scene) -> None:
    """Attach we_sqrt_low/high and wetted_length_low/high to a boundary (None if unknown)."""
    spr = scene.spreading

    def conv(v, to):
        if v is None:
            return None
        if to == b.variable:
            return v
        if spr is None:
            return None
        return spr.we_sqrt(v) if to == "we_sqrt" else spr.delta(v)

    b.we_sqrt_low = conv(b.low, "we_sqrt")
    b.we_sqrt_high = conv(b.high, "we_sqrt")
    b.wetted_length_low = conv(b.low, "wetted_length")
    b.wetted_length_high = conv(b.high, "wetted_length")


def _check_scene(scene: Scene) -> None:
    if "experiment" in scene.data:
        raise ValueError(
            f"scene {scene.name!r}: an [experiment] scene fixes x and Delta through its SI "
            "inputs; sweep its dimensionless counterpart (e.g. fig3-strip) instead"
        )


def run_sweep(
    scene: Scene,
    xs,
    *,
    we_sqrts=None,
    deltas=None,
    store: ResultStore | str | Path,
    refine_tol: float | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    executor=None,
    run_fn=run_impact_task,
    progress: Progress | None = None,
    criterion: str = "outcome",
) -> SweepResult:
    """Sweep impacts over (x, We^1/2) or (x, Delta), then refine the boundary.

    Parameters
    ----------
    scene : Scene
        Base scene (e.g. ``load_scene("fig3-strip")``); its numerics apply to every run.
    xs : sequence of float
        x in units of l_eg = (B / (mu g))^(1/3) (scene units if the scene has no gravity).
    we_sqrts, deltas : sequence of float
        Exactly one: We^1/2 values (converted to Delta by the scene's spreading law) or
        wetted lengths Delta (scene units).
    store : ResultStore or path
        The SQLite store; runs already in it (same scene digest, version and runner) are
        not run again.
    refine_tol : float, optional
        Bisect each x line's outcome change(s) until the bracket is narrower than this (in
        We^1/2, or in Delta for a Delta sweep). None: grid only.
    workers, scheduler : optional
        Local worker processes (default one per core), or a dask scheduler address.
    executor : SweepExecutor or concurrent.futures.Executor, optional
        Use this executor instead (not shut down here).
    run_fn : callable, optional
        The run function (default: a real impact).
    progress : Progress, optional
    criterion : {"outcome", "companion_outcome"}
        Which criterion the boundary refines (default the paper's).

    Returns
    -------
    SweepResult
    """
    t0 = time.perf_counter()
    if criterion not in ("outcome", "companion_outcome"):
        raise ValueError(f"criterion: got {criterion!r}; expected 'outcome' or 'companion_outcome'")
    _check_scene(scene)
    variable = "we_sqrt" if deltas is None else "wetted_length"
    points, skipped = grid_points(scene, list(xs), we_sqrts=we_sqrts, deltas=deltas)
    if not isinstance(store, ResultStore):
        ResultStore.check(store)  # a bad file is refused before any connection or run
    progress = progress or NoProgress()
    try:
        if executor is None:
            with open_executor(workers, scheduler) as ex, _opened(store) as st:
                return _run(scene, xs, variable, points, skipped, st, ex, run_fn, progress,
                            refine_tol, criterion, t0)
        with _opened(store) as st:
            return _run(scene, xs, variable, points, skipped, st, executor, run_fn, progress,
                        refine_tol, criterion, t0)
    finally:
        progress.close()


@contextlib.contextmanager
def _opened(store):
    """The store itself, or a store opened on a path (and closed after)."""
    if isinstance(store, ResultStore):
        yield store
        return
    st = ResultStore(store)
    try:
        yield st
    finally:
        st.close()


def _run(
    scene,
    xs,
    variable,
    points,
    skipped,
    store,
    executor,
    run_fn,
    progress,
    refine_tol,
    criterion,
    t0,
) -> SweepResult:
    sw = Sweep(scene, store, executor, run_fn=run_fn, progress=progress)
    rows = sw.run_points(points, "grid")
    lines: dict[float, list[dict]] = {float(x): [] for x in xs}
    for p, r in zip(points, rows, strict=True):
        lines[p.x_over_leg].append(r)
    boundaries, refine_rows = sw.refine(lines, variable, refine_tol, criterion)
    for b in boundaries:
        _boundary_both_units(b, scene)
    unit_value, unit = length_unit(scene)
    return SweepResult(
        scene_name=scene.name,
        variable=variable,
        x_unit=unit,
        x_unit_value=unit_value,
        runs=[r for r in rows if r is not None] + refine_rows,
        skipped=skipped,
        failed=sw.failed,
        boundary=boundaries,
        computed=sw.computed,
        cached=sw.cached,
        wall_time_s=time.perf_counter() - t0,
        store=str(store.path),
        executor=sw.executor.description,
        refine_tolerance=refine_tol,
        criterion=criterion,
    )
