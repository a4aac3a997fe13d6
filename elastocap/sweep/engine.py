"""Phase-diagram sweeps of impacts: grid, store, executor, boundary refinement, verification.

The orchestrator (:class:`Sweep`) owns the store, the executor and the progress meter;
runs happen in workers through a run function (:mod:`elastocap.sweep.tasks`) and come back
as plain data; the orchestrator writes each to the store in its own transaction as it
arrives. Nothing here prints.

**One resolution per sweep.** Every run of a sweep uses the same discretization, chosen
once (:func:`sweep_resolutions`): the edges the scene's accuracy preset gives the largest
wetted length Delta of the sweep (or ``numerics.n_edges`` when the scene sets it), and the
time step that follows from them. It is written into every run's scene, recorded in the
store (a store refuses a sweep at another resolution) and in every row. Finer *levels*
exist only for verification: level k has ceil(1.5 n_{k-1}) edges and at most half the time
step of level k - 1. A bracket is always made of runs of one level.

**Refinement** (Antkowiak et al. 2011, Fig 3d: one critical We^1/2 per x): for every x line
the computed outcomes are classified (:func:`elastocap.sweep.refine.classify_line`); each
outcome change, to or from "undecided" included, is bisected in the line variable until its
bracket is narrower than the tolerance. Midpoints of all lines are run together, one round
per halving, so a round keeps every worker busy. Midpoints are deterministic (exact
halves), so a resumed refinement finds its earlier runs in the store.

**Verification** (``verify_levels`` >= 1): each line's *threshold*, its first outcome
change when that is open -> encapsulated (the whole line on a bracketed line; also on a
line that changes again above it, to undecided or back to open), is checked by re-running
its two ends at the next level. If both keep their outcomes the threshold *holds*. If not,
it *moved*: the finer level walks outward from the bracket over the values the line has
already run until the outcome changes, bisects that to the tolerance, and reports the
shift of the bracket midpoint. With ``verify_levels`` = K > 1 a moved line's new bracket is
verified at the following level, and so on, until it holds or level K is reached (K <=
:data:`MAX_LEVELS`; level k costs about 1.5^(3k) a run with the explicit stepper); with
``verify_every_level`` a bracket that holds is checked again at each following level too.

**Failures.** A run that raised is recorded as failed with the reason (store table
``failures``, and the report). When a local worker process dies (killed, out of memory),
the pool is replaced and the runs that were in flight are retried one at a time, so the
run that kills its worker is identified; it is recorded failed after
:data:`WORKER_RETRIES` retries. A line with a failed run is reported "failed", never
"all-open". Two sweeps sharing a store claim runs before computing them (see
:mod:`elastocap.sweep.store`): a run is never computed twice.
"""

from __future__ import annotations

import contextlib
import json
import math
import numbers
import os
import socket
import time
import uuid
from collections import deque
from concurrent.futures import FIRST_COMPLETED, BrokenExecutor, Executor, wait
from dataclasses import dataclass, field
from pathlib import Path

from elastocap._version import __version__
from elastocap.scene import Scene
from elastocap.sweep.executors import SweepExecutor, check_workers, open_executor
from elastocap.sweep.grid import SkippedPoint, SweepPoint, grid_points, length_unit, make_point
from elastocap.sweep.progress import NoProgress, Progress
from elastocap.sweep.refine import (
    ENC,
    OPEN,
    UND,
    Boundary,
    classify_line,
    decided_status,
    first_threshold,
)
from elastocap.sweep.store import OUTCOMES, ResultStore, StoreError
from elastocap.sweep.tasks import RESULT_KEYS, run_impact_task, runner_name

__all__ = [
    "MAX_LEVELS",
    "Resolution",
    "Sweep",
    "SweepResult",
    "check_sweep_resources",
    "report_from_store",
    "run_sweep",
    "sweep_resolutions",
]

#: Scene keys every sweep point sets (a --set of one of them would be silently replaced).
SWEPT_KEYS = ("drop.distance_from_end", "drop.wetted_length", "drop.center")
#: From one resolution level to the next: edges times this (rounded up) ...
LEVEL_EDGE_FACTOR = 1.5
#: ... and the time step times at most this.
LEVEL_DT_FACTOR = 0.5
#: Most verification levels a sweep may add (level 4: 5.1x the edges, about 130x the cost
#: of a run with the explicit stepper): a bound on what ``--converge`` may spend.
MAX_LEVELS = 4
#: Seconds a claim on an in-flight run lasts unless renewed (renewed every third of it): a
#: sweep killed without cleaning up blocks its runs for at most this long (less on one
#: host, where a claim of a dead process is taken over at once).
LEASE_S = 60.0
#: Seconds between looks at the store for runs another sweep has claimed.
POLL_S = 0.25
#: Times a run whose worker process died is retried (alone in the pool) before it is
#: recorded as failed.
WORKER_RETRIES = 2


@dataclass(frozen=True)
class Resolution:
    """The discretization of one level of a sweep.

    Attributes
    ----------
    level : int
        0: the sweep's own resolution; k >= 1: the k-th verification level.
    n_edges : int
        Edges of the rod (``numerics.n_edges`` of every run at this level).
    dt : float
        Time step (the automatic one unless ``dt_explicit``).
    dt_explicit : bool
        ``numerics.dt`` is set to ``dt`` in the runs' scenes (else left automatic: the
        stepper's automatic step at ``n_edges``, which is ``dt``).
    integrator : str
    """

    level: int
    n_edges: int
    dt: float
    dt_explicit: bool
    integrator: str

    def overrides(self) -> dict:
        over = {"numerics.n_edges": self.n_edges}
        if self.dt_explicit:
            over["numerics.dt"] = self.dt
        return over

    def to_dict(self) -> dict:
        return dict(vars(self))


def sweep_resolutions(scene: Scene, points, levels: int = 0) -> list[Resolution]:
    """The resolution of a sweep over ``points`` and its ``levels`` verification levels.

    Level 0: ``numerics.n_edges`` if the scene sets it, else the edges the scene's accuracy
    preset gives the point of largest wetted length Delta
    (:func:`elastocap.impact.impact_settings`), raised where needed so that the smallest
    Delta spans ``MIN_WET_EDGES`` edges (the impact refuses fewer); the time step is then the
    scene's
    ``numerics.dt``, or the automatic one for those edges (the same for every point: it
    depends on the edge length and the rod only). Level k: ceil(1.5 n_{k-1}) edges and
    dt_k = min(automatic dt at n_k, dt_{k-1} / 2).
    """
    from elastocap.impact import MIN_WET_EDGES, impact_settings

    if not points:
        raise ValueError("sweep: no point to run (every requested point was skipped)")
    widest = max(points, key=lambda p: p.wetted_length)
    base = scene.with_overrides(widest.overrides())
    num = scene.numerics
    # the preset's edges at the largest Delta, and enough for the smallest Delta to span
    # the impact's minimum of wet edges (else its runs would be refused)
    narrowest = min(p.wetted_length for p in points)
    n_wet = math.ceil(MIN_WET_EDGES * scene.rod.length / narrowest * (1.0 - 1e-12))
    n = num.n_edges or max(impact_settings(base)["n_edges"], n_wet)
    with _edge_cause(scene, points, 0):
        st = impact_settings(base.with_overrides({"numerics.n_edges": n}))
    out = [Resolution(0, int(n), float(st["dt"]), bool(num.dt), num.integrator)]
    for k in range(1, levels + 1):
        prev = out[-1]
        nk = math.ceil(LEVEL_EDGE_FACTOR * prev.n_edges)
        with _edge_cause(scene, points, k):
            auto = float(impact_settings(
                base.with_overrides({"numerics.n_edges": nk, "numerics.dt": 0.0}))["dt"])
        target = LEVEL_DT_FACTOR * prev.dt
        if auto <= target and not num.dt:
            out.append(Resolution(k, nk, auto, False, num.integrator))
        else:
            out.append(Resolution(k, nk, min(auto, target), True, num.integrator))
    return out


def _sweep_edge_key(scene: Scene, points, level: int) -> tuple[str, object, str] | None:
    """The input that sets the edges (and so the automatic dt) of a sweep's ``level``:
    (key, value, note), or None when the scene's own keys do (its ``numerics.n_edges``, or
    the preset's edges at a Delta that needs no more)."""
    from elastocap.impact import ACCURACY_EDGES, MIN_WET_EDGES, edge_count

    num = scene.numerics
    option = "--delta/--we"
    if level > 0:
        return ("--converge", level, f"level {level} runs {LEVEL_EDGE_FACTOR:g}^{level} x the "
                "sweep's edges (use fewer levels)")
    if num.n_edges:
        return None
    narrowest = min(points, key=lambda p: p.wetted_length)
    widest = max(points, key=lambda p: p.wetted_length)
    d_min, d_max = narrowest.wetted_length, widest.wetted_length
    n_wet = math.ceil(MIN_WET_EDGES * scene.rod.length / d_min * (1.0 - 1e-12))
    n_preset = edge_count(scene.with_overrides(widest.overrides()))
    if n_wet > n_preset:
        return ("drop.wetted_length", d_min,
                f"the sweep's smallest Delta ({option}) sets {n_wet:.6g} edges for every run "
                f"({MIN_WET_EDGES} across it; use a larger one)")
    if n_preset > ACCURACY_EDGES[num.accuracy]:
        return ("drop.wetted_length", d_max,
                f"the sweep's largest Delta ({option}) sets {n_preset:.6g} edges for every run "
                "(use larger values)")
    return None


@contextlib.contextmanager
def _edge_cause(scene: Scene, points, level: int):
    """Re-raise a refusal of the sweep's own ``numerics.n_edges`` (or of the dt it sets for
    a verification level) naming the sweep input that caused it (:func:`_sweep_edge_key`)."""
    from elastocap.scene import SceneError

    try:
        yield
    except SceneError as err:
        own = {"numerics.n_edges": scene.numerics.n_edges, "numerics.dt": scene.numerics.dt}
        cause = _sweep_edge_key(scene, points, level)
        if cause is None or err.key not in own or (own[err.key] and level == 0):
            raise
        key, value, note = cause
        raise SceneError(key, value, f"{note}; there, {err.allowed}") from None


def check_sweep_resources(scene: Scene, points, resolutions, force: bool = False) -> dict:
    """Refuse a sweep whose runs would exceed the resource limits of one impact
    (:func:`elastocap.cli_args.check_resources`: memory, time steps), unless ``force``.

    Checked at the sweep's resolution and the finest of the plan, at its smallest and its
    largest Delta;
    the refusal (:class:`~elastocap.scene.SceneError`) names the sweep input that makes the
    runs large (the smallest Delta of ``--delta``/``--we``, ``--converge``), or the scene
    key. Returns the estimate of the most expensive of the checked runs.
    """
    from elastocap.cli_args import impact_estimate
    from elastocap.scene import SceneError

    for p in points:  # every grid point is a scene: refused here, not run as failures
        try:
            scene.with_overrides(p.overrides())
        except SceneError as err:
            raise SceneError(err.key, err.value,
                             f"{err.allowed} (at the sweep's point x = {p.x_over_leg:g}, Delta "
                             f"= {p.wetted_length:.6g})") from None
    narrowest = min(points, key=lambda p: p.wetted_length)
    widest = max(points, key=lambda p: p.wetted_length)
    worst = None
    # the sweep's own level first: a refusal there is not the verification's doing
    for res, p in ((r, p) for r in {0: resolutions[0], 1: resolutions[-1]}.values()
                   for p in (narrowest, widest)):
        est = impact_estimate(scene.with_overrides({**p.overrides(), **res.overrides()}))
        refusal = est["invalid"] or (None if force else est["refusal"])
        if refusal is not None:
            key, value, allowed = refusal
            own = {"numerics.n_edges": scene.numerics.n_edges,
                   "numerics.dt": scene.numerics.dt}
            cause = _sweep_edge_key(scene, points, res.level)
            if cause is not None and key in own and (res.level > 0 or not own[key]):
                ckey, cvalue, note = cause
                raise SceneError(ckey, cvalue, f"{note}; {allowed}")
            raise SceneError(key, value, allowed)
        if worst is None or est["memory_bytes"] > worst["memory_bytes"]:
            worst = est
    return worst


@dataclass
class SweepResult:
    """Everything a sweep produced (plain data; :meth:`to_dict` is the ``--json`` report).

    ``runs`` holds one dict per requested point (grid, refinement, verification), each with
    the point (``x`` in the sweep's x unit, ``x_scene``, ``we_sqrt``, ``wetted_length``),
    its resolution (``level``, ``n_edges``, ``dt``), the stored result columns, ``stage``
    ("grid", "refine" or "verify") and ``cached`` (found in the store rather than computed
    by this sweep).
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
    resolutions: list[Resolution] = field(default_factory=list)
    verify_levels: int = 0
    overrides: list[str] = field(default_factory=list)
    verify_every_level: bool = False

    def to_dict(self) -> dict:
        def bnd(b: Boundary) -> dict:
            d = b.to_dict()
            d["x"] = b.x_over_leg
            d["x_scene"] = b.x
            del d["x_over_leg"]
            return d

        verification = None
        if self.verify_levels:
            verification = {}
            for b in self.boundary:
                s = (b.verification or {}).get("status", "not-applicable")
                verification[s] = verification.get(s, 0) + 1
        return {
            "scene": self.scene_name,
            "version": self.version,
            "variable": self.variable,
            "x_unit": self.x_unit,
            "x_unit_value": self.x_unit_value,
            "criterion": self.criterion,
            "refine_tolerance": self.refine_tolerance,
            "resolution": self.resolutions[0].to_dict() if self.resolutions else None,
            "levels": [r.to_dict() for r in self.resolutions],
            "verify_levels": self.verify_levels,
            "verify_every_level": self.verify_every_level,
            "overrides": list(self.overrides),
            "store": self.store,
            "executor": self.executor,
            "counts": run_counts(self.runs, self.computed, self.cached, len(self.skipped),
                                 len(self.failed), verification),
            "wall_time_s": self.wall_time_s,
            "runs": self.runs,
            "skipped": [s.to_dict() for s in self.skipped],
            "failed": self.failed,
            "boundary": [bnd(b) for b in self.boundary],
        }


_REPORT_SKIP = ("final_positions", "x", "x_over_leg", "we_sqrt", "wetted_length", "scene_json",
                "settings_json", "id")


def _row_for_report(point: SweepPoint, row: dict, stage: str, cached: bool) -> dict:
    out = {
        "x": point.x_over_leg,
        "x_scene": point.x,
        "we_sqrt": point.we_sqrt,
        "wetted_length": point.wetted_length,
        "stage": stage,
        "cached": cached,
    }
    out.update({k: v for k, v in row.items() if k not in _REPORT_SKIP})
    return out


@dataclass(eq=False)  # hashed by identity: lines are dict keys
class _Line:
    """What a sweep knows about one x line, per resolution level."""

    x_over_leg: float
    rows: dict[int, dict[float, dict]] = field(default_factory=dict)
    failed: dict[int, set] = field(default_factory=dict)
    stopped: dict[int, set] = field(default_factory=dict)
    notes: dict[int, list] = field(default_factory=dict)
    refinement_runs: int = 0

    def at(self, level: int) -> dict[float, dict]:
        return self.rows.setdefault(level, {})

    def note(self, level: int, text: str) -> None:
        self.notes.setdefault(level, []).append(text)


class Sweep:
    """Runs batches of sweep points through an executor into a store.

    Parameters
    ----------
    scene : Scene
        The base scene; each point overrides ``drop.distance_from_end`` and
        ``drop.wetted_length``, each level ``numerics.n_edges`` (and ``numerics.dt``).
    store : ResultStore
    executor : SweepExecutor or concurrent.futures.Executor
        A bare executor is assumed to have ``slots`` workers (and cannot be restarted).
    resolutions : list of Resolution
        Level 0 and the verification levels (:func:`sweep_resolutions`).
    run_fn : callable, optional
        ``run_fn(scene_name, scene_json) -> dict`` (:mod:`elastocap.sweep.tasks`); default
        a real impact.
    progress : Progress, optional
    slots : int, optional
        Workers behind a bare executor (default 2).
    variable : "we_sqrt" or "wetted_length"
    criterion : "outcome" (the paper's) or "companion_outcome"
    """

    def __init__(
        self,
        scene: Scene,
        store: ResultStore,
        executor,
        resolutions: list[Resolution],
        *,
        run_fn=run_impact_task,
        progress: Progress | None = None,
        slots: int = 2,
        variable: str = "we_sqrt",
        criterion: str = "outcome",
    ):
        if isinstance(executor, Executor):
            executor = SweepExecutor(executor, slots, type(executor).__name__)
        self.scene = scene
        self.store = store
        self.executor = executor
        self.levels = resolutions
        self.run_fn = run_fn
        self.runner = runner_name(run_fn)
        self.progress = progress or NoProgress()
        self.variable = variable
        self.criterion = criterion
        self.version = __version__
        code = getattr(run_fn, "code_digest", None)
        self.code_digest = code() if callable(code) else (code or "")
        self.owner = f"{socket.gethostname()}:{os.getpid()}:{uuid.uuid4().hex[:12]}"
        self.lease_s = LEASE_S
        self.computed = 0
        self.cached = 0
        self.failed: list[dict] = []
        self.report_rows: list[dict] = []
        self.lines: dict[float, _Line] = {}
        self._done = 0
        self._total = 0

    def _tick(self, note: str) -> None:
        self._done += 1
        self.progress(self._done, self._total, note)

    # ------------------------------------------------------------------------- running
    def _key(self):
        return self.version, self.runner, self.code_digest

    def _fail(self, point: SweepPoint, res: Resolution, scene, digest, stage, error, attempts):
        self.failed.append({**point.to_dict(), "stage": stage, "level": res.level,
                            "n_edges": res.n_edges, "error": error, "attempts": attempts})
        self.store.record_failure({
            "scene_digest": digest, "version": self.version, "code_digest": self.code_digest,
            "runner": self.runner, "scene_name": scene.name, "x": point.x,
            "x_over_leg": point.x_over_leg, "we_sqrt": point.we_sqrt,
            "wetted_length": point.wetted_length, "level": res.level, "error": error,
            "attempts": attempts}, owner=self.owner)
        self._tick(f"{stage}: FAILED")

    def _check_result(self, res, level: Resolution) -> None:
        missing = [k for k in ("outcome", "companion_outcome", "status") if k not in res]
        if missing:
            raise ValueError(f"run function returned no {', '.join(missing)}")
        for k in ("outcome", "companion_outcome"):
            if res[k] not in OUTCOMES:
                raise ValueError(f"run function returned {k} {res[k]!r}; expected one of "
                                 f"{', '.join(OUTCOMES)}")
        theirs = (res.get("version", self.version), res.get("code_digest", self.code_digest))
        if theirs != (self.version, self.code_digest):
            raise RuntimeError(
                f"the worker runs elastocap {theirs[0]} (code {theirs[1]}), this "
                f"sweep {self.version} (code {self.code_digest}): install the "
                "same code on every worker (or restart the workers after an edit)"
            )
        n = res.get("n_edges")
        if n is not None and int(n) != level.n_edges:
            raise RuntimeError(f"the run used {n} edges, the sweep's level {level.level} is "
                               f"{level.n_edges}: the run function ignores numerics.n_edges")

    def run_points(self, items, stage: str = "grid") -> list[dict | None]:
        """Run (or find in the store) each (point, resolution); return its report row, None
        if it failed.

        Runs are claimed in the store first; runs another live sweep has claimed are
        waited for, not computed. Each new result is written in its own transaction as soon
        as it arrives. Items sharing a scene digest run once.
        """
        items = list(items)
        scenes = [self.scene.with_overrides({**p.overrides(), **r.overrides()})
                  for p, r in items]
        digests = [s.digest() for s in scenes]
        self._total += len(items)
        first: dict[str, int] = {}
        for i, d in enumerate(digests):
            first.setdefault(d, i)
        version, runner, code = self._key()
        stored = self.store.get_many(list(first), version, runner, code)
        result_rows: dict[str, dict] = dict(stored)
        found = set(stored)
        for _ in stored:
            self._tick(f"{stage}: stored")
        # runs are claimed as they are submitted (not all at once), so that two sweeps on
        # one store share the work instead of one of them waiting for the other
        queue = deque(first[d] for d in first if d not in stored)
        held: set[str] = set()
        waiting: set[str] = set()
        suspects: deque[int] = deque()
        crashes: dict[str, int] = {}
        resubmitted: set[int] = set()
        isolated: set[int] = set()
        pending: dict = {}
        ex = self.executor
        last_renew = last_poll = time.monotonic()
        try:
            while queue or pending or waiting or suspects:
                # after a crash, the runs that were in flight are retried one at a time
                isolate = bool(suspects) or any(i in isolated for i in pending.values())
                src, limit = (suspects, 1) if isolate else (queue, ex.max_in_flight)
                if not isolate and queue and len(pending) < limit:
                    want = [queue.popleft() for _ in range(min(len(queue),
                                                               limit - len(pending)))]
                    got, mine, theirs = self.store.claim([digests[i] for i in want], version,
                                                         runner, code, self.owner, self.lease_s)
                    for d, row in got.items():  # stored by another sweep meanwhile
                        result_rows[d] = row
                        found.add(d)
                        self._tick(f"{stage}: stored by another sweep")
                    waiting |= theirs
                    held |= mine
                    queue.extendleft(reversed([i for i in want if digests[i] in mine]))
                    src = queue
                while src and len(pending) < limit and (isolate or digests[src[0]] in held):
                    i = src.popleft()
                    if isolate:
                        isolated.add(i)
                    sc = scenes[i]
                    try:
                        fut = ex.executor.submit(self.run_fn, sc.name, sc.to_json())
                    except Exception as err:  # a broken pool refuses new work
                        if isinstance(err, BrokenExecutor) and i not in resubmitted and \
                                ex.restart():
                            resubmitted.add(i)
                            src.appendleft(i)
                            continue
                        p, r = items[i]
                        self._fail(p, r, sc, digests[i], stage,
                                   f"{type(err).__name__}: {err}", 1)
                        held.discard(digests[i])
                        continue
                    pending[fut] = i
                if pending:
                    done, _ = wait(list(pending), timeout=POLL_S, return_when=FIRST_COMPLETED)
                else:
                    time.sleep(POLL_S)
                    done = set()
                crashed, broken = [], None
                for fut in done:
                    i = pending.pop(fut)
                    d, (p, r), sc = digests[i], items[i], scenes[i]
                    try:
                        res = fut.result()
                    except BrokenExecutor as err:
                        crashed.append(i)
                        broken = err
                        continue
                    except Exception as err:  # a run that raised: recorded, not retried
                        self._fail(p, r, sc, d, stage, f"{type(err).__name__}: {err}", 1)
                        held.discard(d)
                        continue
                    try:
                        self._check_result(res, r)
                    except Exception as err:
                        self._fail(p, r, sc, d, stage, f"{type(err).__name__}: {err}", 1)
                        held.discard(d)
                        continue
                    row = self._store_row(res, p, r, sc, d)
                    result_rows[d] = row
                    held.discard(d)
                    self.computed += 1
                    self._tick(f"{stage}: {row['outcome']}")
                if broken is not None:
                    # every future of a broken pool fails: all in flight are suspects
                    crashed += list(pending.values())
                    pending.clear()
                    alone = len(crashed) == 1 and crashed[0] in isolated
                    for i in crashed:
                        d = digests[i]
                        if alone:
                            crashes[d] = crashes.get(d, 0) + 1
                        if crashes.get(d, 0) > WORKER_RETRIES:
                            p, r = items[i]
                            self._fail(
                                p, r, scenes[i], d, stage,
                                f"the worker process died while running it, alone in the pool, "
                                f"{crashes[d]} times ({type(broken).__name__}: {broken}); "
                                "it kills its worker (memory? a crash in compiled code? "
                                "a script that starts the sweep outside "
                                "`if __name__ == \"__main__\":`, which each spawned worker "
                                "runs again?)",
                                crashes[d])
                            held.discard(d)
                        else:
                            suspects.append(i)
                    if suspects and not ex.restart():
                        for i in suspects:
                            p, r = items[i]
                            self._fail(p, r, scenes[i], digests[i], stage,
                                       f"{type(broken).__name__}: {broken}; the executor "
                                       "cannot be restarted", 1)
                            held.discard(digests[i])
                        suspects.clear()
                now = time.monotonic()
                if waiting and (now - last_poll >= POLL_S or not (pending or queue)):
                    last_poll = now
                    got, mine2, theirs2 = self.store.claim(sorted(waiting), version, runner,
                                                           code, self.owner, self.lease_s)
                    for d, row in got.items():
                        result_rows[d] = row
                        found.add(d)
                        self._tick(f"{stage}: stored by another sweep")
                    for d in mine2:  # the other sweep died or gave up: ours now
                        queue.appendleft(first[d])
                        held.add(d)
                    waiting = set(theirs2)
                if held and now - last_renew >= self.lease_s / 3.0:
                    last_renew = now
                    self.store.renew(sorted(held), version, runner, code, self.owner,
                                     self.lease_s)
        finally:
            if held:
                self.store.release(self.owner)
        self.cached += len(found)
        for i, d in enumerate(digests):
            if first[d] != i:
                self._tick(f"{stage}: duplicate")
        out: list[dict | None] = []
        for i, ((p, _), d) in enumerate(zip(items, digests, strict=True)):
            row = result_rows.get(d)
            cached = d in found or first[d] != i
            rep = None if row is None else _row_for_report(p, row, stage, cached)
            out.append(rep)
            if rep is not None:
                self.report_rows.append(rep)
        return out

    def _store_row(self, res: dict, p: SweepPoint, r: Resolution, sc, d: str) -> dict:
        row = {k: res.get(k) for k in RESULT_KEYS}
        if row["outcome"] == UND and not row.get("reason"):
            row["reason"] = res.get("message") or "the run function gave no reason"
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
            level=r.level,
            n_edges=r.n_edges if row.get("n_edges") is None else int(row["n_edges"]),
            dt=r.dt if row.get("dt") is None else float(row["dt"]),
        )
        if not self.store.put(row, owner=self.owner):  # stored first elsewhere: use theirs
            row = self.store.get(d, self.version, self.runner, self.code_digest) or row
        return row

    def _run_on_lines(self, wanted, level: int, stage: str):
        """Run [(line, value)] at ``level``; record rows / failures on the lines; return the
        rows (None: failed or skipped)."""
        res = self.levels[level]
        items, where = [], []
        out: list[dict | None] = [None] * len(wanted)
        for j, (ln, v) in enumerate(wanted):
            p = make_point(self.scene, ln.x_over_leg, **{self.variable: v})
            if isinstance(p, SkippedPoint):  # cannot happen inside the grid's range
                ln.note(level, f"{self.variable} = {v!r} skipped: {p.reason}")
                continue
            items.append((p, res))
            where.append(j)
        rows = self.run_points(items, stage)
        for j, row in zip(where, rows, strict=True):
            ln, v = wanted[j]
            if row is None:
                ln.failed.setdefault(level, set()).add(v)
            else:
                ln.at(level)[v] = row
            out[j] = row
        return out

    # -------------------------------------------------------------------------- analysis
    def outcome_of(self, row: dict) -> str:
        """The run's outcome under the sweep's criterion (the companion one read by
        :func:`elastocap.criteria.companion_reading`: rows stored before the run function
        applied it hold its raw reading). The rule inlined: importing elastocap.criteria
        would load numba, which the orchestrator never needs."""
        return UND if row["outcome"] == UND else row[self.criterion]

    def _classify(self, ln: _Line, level: int):
        rows = ln.at(level)
        vals = sorted(rows)
        return classify_line(vals, [self.outcome_of(rows[v]) for v in vals])

    def bisect(self, lines: list[_Line], level: int, tol: float | None, stage: str) -> None:
        """Halve every outcome change of ``lines`` at ``level`` until narrower than ``tol``."""
        if tol is None:
            return
        while True:
            wanted = []
            for ln in lines:
                stopped = ln.stopped.setdefault(level, set())
                for t in self._classify(ln, level)[1]:
                    if t.width <= tol or (t.low, t.high) in stopped:
                        continue
                    mid = 0.5 * (t.low + t.high)
                    if not t.low < mid < t.high:  # tol below the float spacing: stop here
                        ln.note(level, f"bracket [{t.low!r}, {t.high!r}] at float resolution")
                        stopped.add((t.low, t.high))
                        continue
                    wanted.append((ln, mid, t))
            if not wanted:
                return
            rows = self._run_on_lines([(ln, mid) for ln, mid, _ in wanted], level, stage)
            for (ln, mid, t), row in zip(wanted, rows, strict=True):
                ln.refinement_runs += 1
                if row is None:
                    ln.stopped[level].add((t.low, t.high))
                    if mid in ln.failed.get(level, ()):
                        ln.note(level, f"run failed at {self.variable} = {mid!r}; bisection "
                                "stopped")

    def boundary(self, ln: _Line, level: int, tol: float | None) -> Boundary:
        """The line's boundary from its runs at ``level``."""
        rows = ln.at(level)
        vals = sorted(rows)
        outs = [self.outcome_of(rows[v]) for v in vals]
        status, trans = classify_line(vals, outs)
        dstat = decided_status(vals, outs)
        failed = sorted(ln.failed.get(level, ()))
        res = self.levels[level]
        b = Boundary(
            x_over_leg=ln.x_over_leg,
            x=ln.x_over_leg * length_unit(self.scene)[0],
            variable=self.variable,
            status="failed" if failed else status,
            transitions=trans,
            tolerance=tol,
            refinement_runs=ln.refinement_runs,
            notes=list(ln.notes.get(level, [])),
            decided_status=dstat,
            level=level,
            n_edges=res.n_edges,
            dt=res.dt,
            undecided=[{"value": v, "reason": rows[v].get("reason")}
                       for v, o in zip(vals, outs, strict=True) if o == UND],
            failed=failed,
        )
        opens = [v for v, o in zip(vals, outs, strict=True) if o == OPEN]
        encs = [v for v, o in zip(vals, outs, strict=True) if o == ENC]
        if dstat == "bracketed":
            b.low, b.high = max(opens), min(encs)
        elif dstat == "all-open":
            b.low = max(opens)
        elif dstat == "all-encapsulated":
            b.high = min(encs)
        thr = first_threshold(trans)
        if thr is not None and not failed:
            b.threshold_low, b.threshold_high = thr.low, thr.high
            b.threshold_to = thr.outcome_high
        b.converged = bool(
            tol is not None
            and trans
            and all(t.width <= tol for t in trans)
            and not b.notes
            and not failed
        )
        return b

    # ------------------------------------------------------------------------ verification
    def _probe(self, moving: dict, level: int) -> None:
        """Walk each moved line outward at ``level`` over the values it ran at coarser
        levels until the outcome changes (``moving``: line -> "down" or "up")."""
        while moving:
            wanted = []
            for ln, direction in list(moving.items()):
                fine = ln.at(level)
                known = sorted({v for k in range(level) for v in ln.at(k)})
                if direction == "down":
                    cand = [v for v in known if v < min(fine)]
                    nxt = cand[-1] if cand else None
                else:
                    cand = [v for v in known if v > max(fine)]
                    nxt = cand[0] if cand else None
                if nxt is None:
                    del moving[ln]
                    continue
                wanted.append((ln, nxt))
            if not wanted:
                return
            rows = self._run_on_lines(wanted, level, "verify")
            for (ln, _), row in zip(wanted, rows, strict=True):
                # down: on while the runs do not stay open; up: on while they do
                if row is None or ((self.outcome_of(row) == OPEN) == (moving[ln] == "down")):
                    del moving[ln]  # found the change (or a failed run)

    def verify(self, lines: list[_Line], tol: float | None, max_level: int,
               every_level: bool = False) -> dict:
        """Verify each line's level-0 bracket at level 1, and (``max_level`` > 1) a moved
        line's new bracket at the next level, up to ``max_level``. ``every_level``: a
        bracket that holds is checked again at the next level too, up to ``max_level``
        (it "holds" only if it holds at every level checked).

        Returns
        -------
        dict line -> (Boundary to report, verification dict)
        """
        out = {}
        b0 = {ln: self.boundary(ln, 0, tol) for ln in lines}
        active = []
        for ln, b in b0.items():
            if b.threshold_low is not None:
                active.append(ln)
                out[ln] = (b, {"status": "pending", "checks": [], "brackets": [
                    self._bracket_dict(b)], "shift": None, "holds_at_level": None,
                    "checked": "bracket" if b.status == "bracketed" else
                    f"threshold (first change from open, to {b.threshold_to}; the line "
                    f"is {b.status})"})
            else:
                b.verified = False
                out[ln] = (b, {"status": "not-applicable", "checks": [], "brackets": [],
                               "shift": None, "holds_at_level": None,
                               "reason": f"line is {b.status}, no change from open "
                               "(no threshold)"})
        level = 0
        while active and level < max_level:
            fine = level + 1
            wanted = []
            for ln in active:
                b = out[ln][0]
                wanted += [(ln, b.threshold_low), (ln, b.threshold_high)]
            rows = self._run_on_lines(wanted, fine, "verify")
            moving, nxt = {}, []
            for j, ln in enumerate(active):
                b, info = out[ln]
                lo_row, hi_row = rows[2 * j], rows[2 * j + 1]
                lo_o = None if lo_row is None else self.outcome_of(lo_row)
                hi_o = None if hi_row is None else self.outcome_of(hi_row)
                res = self.levels[fine]
                check = {"level": b.level, "against": fine, "n_edges": res.n_edges,
                         "dt": res.dt,
                         "low": b.threshold_low, "high": b.threshold_high,
                         "low_outcome": lo_o,
                         "high_outcome": hi_o}
                # the threshold is the first change from open: it holds while its low end
                # stays open and its high end does not (encapsulated, or undecided where it
                # was undecided); a high end that turns undecided from encapsulated is not
                # a decided check
                to = b.threshold_to
                if lo_o is None or hi_o is None:
                    check["result"] = "failed"
                elif lo_o == OPEN and hi_o == to:
                    check["result"] = "holds"
                elif lo_o == OPEN and hi_o != OPEN:
                    check["result"] = "undecided" if hi_o == UND else "holds"
                elif lo_o != OPEN and hi_o == OPEN:
                    check["result"] = "reversed"
                else:
                    check["result"] = "moved"
                    moving[ln] = "down" if lo_o != OPEN else "up"
                info["checks"].append(check)
                if check["result"] == "holds":
                    if info["holds_at_level"] is None:
                        info["holds_at_level"] = b.level
                    info["status"] = ("holds" if info["holds_at_level"] == 0
                                      else "holds-at-finer")
                    b.verified = True
                    if every_level:
                        nxt.append(ln)
                else:
                    info["holds_at_level"] = None
                    if check["result"] != "moved":
                        info["status"] = check["result"]
                        b.verified = False
            self._probe(dict(moving), fine)
            moved = list(moving)
            self.bisect(moved, fine, tol, "verify")
            for ln in moved:
                b_old, info = out[ln]
                bf = self.boundary(ln, fine, tol)
                info["brackets"].append(self._bracket_dict(bf))
                bf.verified = False
                if bf.threshold_low is not None:
                    info["status"] = "moved"
                    info["shift"] = (0.5 * (bf.threshold_low + bf.threshold_high)
                                     - 0.5 * (b0[ln].threshold_low + b0[ln].threshold_high))
                    nxt.append(ln)
                else:
                    info["status"] = f"moved, {bf.status} at level {fine}"
                    info["shift"] = None
                out[ln] = (bf, info)
            active = nxt
            level = fine
        for b, info in out.values():
            b.verification = info
        return out

    @staticmethod
    def _bracket_dict(b: Boundary) -> dict:
        return {"level": b.level, "n_edges": b.n_edges, "dt": b.dt, "status": b.status,
                "low": b.threshold_low, "high": b.threshold_high, "to": b.threshold_to}


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


def check_verify_levels(levels, minimum: int = 0) -> int:
    """``levels`` as an integer ``minimum`` ... MAX_LEVELS (refused by message otherwise;
    0 means no verification)."""
    if (isinstance(levels, bool) or not isinstance(levels, numbers.Integral)
            or not minimum <= levels <= MAX_LEVELS):
        raise ValueError(f"--converge: got {levels!r}; expected an integer from 1 to "
                         f"{MAX_LEVELS} (verification levels, each 1.5x the edges)")
    return int(levels)


def plan_sweep(scene: Scene, xs, *, we_sqrts=None, deltas=None, verify_levels: int = 0):
    """The points, skipped points and resolutions of a sweep, computed without running or
    writing anything (the command refuses bad input with them before any file exists)."""
    _check_scene(scene)
    check_verify_levels(verify_levels)
    points, skipped = grid_points(scene, list(xs), we_sqrts=we_sqrts, deltas=deltas)
    if not points and skipped:
        s = skipped[0]
        raise ValueError(
            f"{'--delta' if deltas is not None else '--we'}: got no point to run; all "
            f"{len(skipped)} points of the grid are skipped, e.g. x = {s.x_over_leg:.6g}, "
            f"Delta = {s.wetted_length:.6g}: {s.reason}")
    return points, skipped, sweep_resolutions(scene, points, verify_levels)


def store_resolution(resolutions: list[Resolution], scene: Scene | None = None) -> dict:
    """What a store records of a sweep's resolution (its level 0) and, given ``scene``, of
    its scene (:func:`store_scene`)."""
    r = resolutions[0]
    out = {"n_edges": r.n_edges, "dt": r.dt, "integrator": r.integrator,
           "rule": "numerics.n_edges, else the accuracy preset's edges at the sweep's "
                   "largest Delta; the automatic dt at those edges"}
    if scene is not None:
        out["scene"] = store_scene(scene)
    return out


def store_scene(scene: Scene) -> dict:
    """Every validated value of a sweep's scene (``section.key``, from
    :meth:`~elastocap.scene.Scene.canonical`) but those the sweep sets at each point
    (:data:`SWEPT_KEYS`) and the resolution's (``numerics.n_edges``, ``numerics.dt``,
    recorded apart): a store holds the runs of one scene."""
    out = {}
    for sec, values in scene.canonical().items():
        for k, v in (values or {}).items():
            key = f"{sec}.{k}"
            if key not in SWEPT_KEYS and key not in ("numerics.n_edges", "numerics.dt"):
                out[key] = v
    return json.loads(json.dumps(out, default=str))  # as the store reads it back


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
    verify_levels: int = 0,
    verify_every_level: bool = False,
    overrides=(),
    force: bool = False,
) -> SweepResult:
    """Sweep impacts over (x, We^1/2) or (x, Delta), refine and verify the boundary.

    Parameters
    ----------
    scene : Scene
        Base scene (e.g. ``load_scene("fig3-strip")``); its numerics apply to every run,
        with the sweep's one resolution (:func:`sweep_resolutions`).
    xs : sequence of float
        x in units of l_eg = (B / (mu g))^(1/3) (scene units if the scene has no gravity).
    we_sqrts, deltas : sequence of float
        Exactly one: We^1/2 values (converted to Delta by the scene's spreading law) or
        wetted lengths Delta (scene units).
    store : ResultStore or path
        The SQLite store; runs already in it (same scene digest, version and runner) are
        not run again. A store made at another resolution is refused.
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
    verify_levels : int
        0: no verification; 1: ``--verify`` (each bracket's ends re-run at 1.5x the edges
        and half the time step); K > 1: ``--converge K`` (a moved bracket is located and
        verified again at the next level, up to level K).
    verify_every_level : bool
        With ``verify_levels`` = K: a bracket that holds is checked again at the next
        level too, up to level K, so that every bracket is checked at K finer levels
        (``--converge K --every-level``). A bracket holds only if it holds at each.
    overrides : sequence of str
        The ``--set`` overrides the scene was made with (recorded in the report).
    force : bool
        Run even when a run is estimated above the resource limits of one impact
        (:func:`check_sweep_resources`; refused otherwise, before anything is written).

    Returns
    -------
    SweepResult
    """
    t0 = time.perf_counter()
    # numbers of any numeric type (numpy scalars and arrays too) as plain Python numbers:
    # the result is plain data
    xs = [_real(v, "--x") for v in xs]
    we_sqrts = None if we_sqrts is None else [_real(v, "--we") for v in we_sqrts]
    deltas = None if deltas is None else [_real(v, "--delta") for v in deltas]
    refine_tol = None if refine_tol is None else _real(refine_tol, "--refine")
    verify_levels = check_verify_levels(verify_levels)
    if workers is not None:
        workers = check_workers(workers)
    if criterion not in ("outcome", "companion_outcome"):
        raise ValueError(f"criterion: got {criterion!r}; expected 'outcome' or 'companion_outcome'")
    if refine_tol is not None and not (refine_tol > 0.0 and math.isfinite(refine_tol)):
        raise ValueError(f"--refine: got {refine_tol!r}; expected a finite number > 0")
    variable = "we_sqrt" if deltas is None else "wetted_length"
    points, skipped, levels = plan_sweep(scene, xs, we_sqrts=we_sqrts, deltas=deltas,
                                         verify_levels=verify_levels)
    check_sweep_resources(scene, points, levels, force)
    if not isinstance(store, ResultStore):
        # a bad file, or one made at another resolution, is refused before any write
        ResultStore.check(store, store_resolution(levels, scene))
    progress = progress or NoProgress()
    args = (scene, xs, variable, points, skipped, levels, run_fn, progress, refine_tol,
            criterion, verify_levels, bool(verify_every_level), list(overrides), t0)
    try:
        if executor is None:
            with open_executor(workers, scheduler) as ex, _opened(store) as st:
                return _run(st, ex, *args)
        with _opened(store) as st:
            return _run(st, executor, *args)
    finally:
        progress.close()


def run_counts(runs, computed: int, cached: int, skipped: int, failed: int,
               verification=None) -> dict:
    """The ``counts`` of a sweep report: runs, how many were computed or taken from the
    store, skipped, failed, undecided, each outcome, the runs both criteria decide
    differently (an undecided run is undecided under both), the runs in which the rod
    touched itself (``self_contact``; None when no run had a thickness) and the
    verification verdicts."""
    outcomes = {o: sum(r["outcome"] == o for r in runs) for o in OUTCOMES}
    with_thickness = [r for r in runs if r.get("contact_steps") is not None]
    return {
        "runs": len(runs), "computed": computed, "cached": cached, "skipped": skipped,
        "failed": failed, "undecided": outcomes[UND], "outcomes": outcomes,
        "disagreements": sum(r["outcome"] != r["companion_outcome"]
                             and UND not in (r["outcome"], r["companion_outcome"])
                             for r in runs),
        "self_contact": (sum(r["contact_steps"] > 0 for r in with_thickness)
                         if with_thickness else None),
        "verification": verification,
    }


def report_from_store(store) -> dict:
    """The report of a sweep (the shape of :meth:`SweepResult.to_dict`) rebuilt from its
    store alone, without running anything: every stored run of the store's latest version,
    the failures, and each x line classified from its runs at the sweep's own level
    (:func:`~elastocap.sweep.refine.classify_line`: a bracket where the outcome changes once
    from open to encapsulated), with the ``counts`` of those runs. What a store does not
    record is left empty: ``overrides`` (None), the verification verdicts (``verified`` is
    False), the skipped points (an empty list), each line's thresholds under the
    frame-independent criterion."""
    from elastocap.sweep.refine import classify_line

    st = store if isinstance(store, ResultStore) else ResultStore.reader(store)
    try:
        rows = st.rows()
        failures = st.failures()
        resolution = st.resolution()
    finally:
        if st is not store:
            st.close()
    if not rows:
        raise ValueError(f"PATH: got {str(store)!r}; the store holds no run to draw")
    version = rows[-1]["version"]
    rows = [r for r in rows if r["version"] == version]
    import json

    from elastocap.scene import build_scene

    scene = build_scene(json.loads(rows[0]["scene_json"]), rows[0]["scene_name"])
    runs = []
    for r in rows:
        out = {"x": r["x_over_leg"], "x_scene": r["x"], "we_sqrt": r["we_sqrt"],
               "wetted_length": r["wetted_length"], "stage": "stored", "cached": True}
        out.update({k: v for k, v in r.items() if k not in _REPORT_SKIP})
        runs.append(out)
    level0 = [r for r in runs if not r.get("level")]
    variable = ("we_sqrt" if level0 and all(r["we_sqrt"] is not None for r in level0)
                else "wetted_length")
    boundary = []
    for x in sorted({r["x"] for r in level0}):
        line = [r for r in level0 if r["x"] == x]
        status, trans = classify_line([r[variable] for r in line],
                                      [r["outcome"] for r in line])
        b = {"x": x, "status": status, "low": None, "high": None, "level": 0,
             "verified": False, "verification": None,
             "transitions": [t.to_dict() for t in trans]}
        if status == "bracketed":
            (t,) = trans
            b["low"], b["high"] = t.low, t.high
            for key in ("we_sqrt", "wetted_length"):
                lo = next(r[key] for r in line if r[variable] == t.low)
                hi = next(r[key] for r in line if r[variable] == t.high)
                b[f"{key}_low"], b[f"{key}_high"] = lo, hi
        boundary.append(b)
    unit_value, unit = length_unit(scene)
    failed = [dict(f) for f in failures if f.get("version") == version]
    return {
        "scene": rows[0]["scene_name"], "version": version, "variable": variable,
        "x_unit": unit, "x_unit_value": unit_value, "criterion": "outcome",
        "resolution": resolution, "verify_levels": 0,
        "counts": run_counts(runs, 0, len(runs), 0, len(failed)),
        "runs": runs, "boundary": boundary, "failed": failed, "skipped": [],
        "overrides": None, "store": str(store),
    }


def _real(value, key: str) -> float:
    """A real number of any numeric type (int, float, numpy scalar) as a Python float."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{key}: got {value!r}; expected a number")
    return float(value)


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


def _run(store, executor, scene, xs, variable, points, skipped, levels, run_fn, progress,
         refine_tol, criterion, verify_levels, every_level, overrides, t0) -> SweepResult:
    try:
        store.ensure_resolution(store_resolution(levels, scene))
    except StoreError as err:
        raise ValueError(f"--store: {err}") from None
    sw = Sweep(scene, store, executor, levels, run_fn=run_fn, progress=progress,
               variable=variable, criterion=criterion)
    lines = {float(x): _Line(float(x)) for x in xs}
    for p in points:
        lines[p.x_over_leg].at(0)
    rows = sw.run_points([(p, levels[0]) for p in points], "grid")
    for p, r in zip(points, rows, strict=True):
        ln = lines[p.x_over_leg]
        if r is None:
            ln.failed.setdefault(0, set()).add(getattr(p, variable))
        else:
            ln.at(0)[getattr(p, variable)] = r
    ordered = [lines[x] for x in sorted(lines)]
    # a line whose grid has a failed run is not refined further on a guess
    sw.bisect([ln for ln in ordered if not ln.failed.get(0)], 0, refine_tol, "refine")
    if verify_levels:
        found = sw.verify(ordered, refine_tol, verify_levels, every_level)
        boundaries = [found[ln][0] for ln in ordered]
    else:
        boundaries = [sw.boundary(ln, 0, refine_tol) for ln in ordered]
    for b in boundaries:
        _boundary_both_units(b, scene)
        if b.verification:
            for br in b.verification["brackets"]:
                for k in ("low", "high"):
                    tmp = Boundary(b.x_over_leg, b.x, variable, "", low=br["low"],
                                   high=br["high"])
                    _boundary_both_units(tmp, scene)
                    br[f"we_sqrt_{k}"] = getattr(tmp, f"we_sqrt_{k}")
    unit_value, unit = length_unit(scene)
    return SweepResult(
        scene_name=scene.name,
        variable=variable,
        x_unit=unit,
        x_unit_value=unit_value,
        runs=sw.report_rows,
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
        resolutions=levels,
        verify_levels=verify_levels,
        verify_every_level=every_level and bool(verify_levels),
        overrides=overrides,
    )
