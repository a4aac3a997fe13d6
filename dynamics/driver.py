"""One driver for every time-stepping method: :func:`simulate`, in the manner of scipy's
``solve_ivp``.

``simulate(rod, effects, method="rattle" | "midpoint", dt=..., t_end=...)`` validates the
run, builds its schedule (output frames, events, the end), asks the method for a stepper
specialised to the effects (compiled once per effect combination, see
:mod:`dynamics.cache`), runs the steps between two stops inside one compiled call, fires
the events between those calls, and returns one :class:`SimulationResult` whose ``stats``
mapping names the diagnostics of every method.

A method is a module with a class ``Run``:

``Run(rod, effects, dt, t0, rest, **options)``
    Checks the method-specific options, builds the work arrays and loads the generated
    stepper (``Run.module``, with ``Run.label``, e.g. ``"gravity+ground+capillary"``).
``run.warm()``
    Compiles (or loads from numba's cache) without changing the state.
``run.advance(step, stops, record, pos, ens, rec_steps, nrec) -> (status, step, nrec)``
    Runs to each stop in turn and records the flagged frames (positions, kinetic energy,
    then the energies of bending and of each force effect).
``run.after_event(step)``
    Called after events changed effect parameters at ``step``.
``run.frame(pos, ens, rec_steps, nrec, step)``
    Records the current state as a frame.
``run.failure(status, step, t_final) -> str``
    The message of a failed run (where, what, what to try).
``run.stats() -> dict``
    The method's counters (see :data:`STATS_KEYS`).
``run.contact_forces() -> ndarray or None``
    The self-contact forces of the last step (None without a self-contact).

Built-in methods: ``"rattle"`` (:mod:`dynamics.rattle`, explicit, symplectic) and
``"midpoint"`` (:mod:`dynamics.midpoint`, the constrained implicit midpoint rule).
"""

from __future__ import annotations

import contextlib
import functools
import json
import logging
import math
import os
import secrets
import time
import zipfile
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from .cache import compile_lock
from .codegen import cold_kernel_groups
from .rod import Rod

__all__ = [
    "Event",
    "METHODS",
    "RestCriterion",
    "STATS_KEYS",
    "SimulationResult",
    "simulate",
]

#: The logger through which the driver announces a compilation (a library never prints;
#: the command line shows this logger's INFO messages on stderr).
log = logging.getLogger("dynamics")

#: Statuses: code -> (name, message); the methods give the failure messages.
STATUS = {
    0: ("completed", "reached t_end"),
    1: ("at_rest", "stopped at rest: kinetic energy below {thr:g} for {dur:g} time units"),
    2: ("step_failed", "a step did not converge"),
    3: ("non_finite", "non-finite state (NaN/inf)"),
}

#: Keys of ``SimulationResult.stats`` that every method fills:
#:
#: ``steps`` accepted steps; ``rejected_steps`` steps retried as substeps;
#: ``max_halvings`` deepest halving needed; ``iterations_max`` / ``iterations_mean``
#: Newton iterations a step (RATTLE: of the SHAKE projection; midpoint: of the implicit
#: step); ``contact_rounds`` extra rounds caused by contact changes (RATTLE: re-projections
#: after a node got held; midpoint: re-solves after a change of the held set);
#: ``constraint_error`` largest relative edge-length error after a step;
#: ``compile_time`` seconds generating/loading/compiling the stepper in this call;
#: ``run_time`` seconds in the time loop.  Methods add their own keys (midpoint:
#: ``jacobians``, ``pivoted_factorisations``, ``stiffness_lowrank``, ``contact_updates``,
#: ``stiffness_dropped``).
STATS_KEYS = ("steps", "rejected_steps", "max_halvings", "iterations_max", "iterations_mean",
              "contact_rounds", "constraint_error", "compile_time", "run_time")


def _methods():
    from . import midpoint, rattle

    return {"rattle": rattle, "midpoint": midpoint}


#: Names of the built-in methods.
METHODS = ("rattle", "midpoint")


@dataclass(frozen=True)
class Event:
    """At time ``time`` set parameter ``param`` of effect ``effect`` to ``value``.

    Parameters
    ----------
    time : float
        Event time; it fires at the first step boundary ``t_j >= time`` (within
        ``1e-9 dt``), after the output frame at that time, if any, is recorded.
    effect : str
        Name of the target effect.
    param : int or str
        Index into ``effect.params`` or a name from ``effect.param_names``.
    value : float
        New value.
    """

    time: float
    effect: str
    param: int | str
    value: float


@dataclass(frozen=True)
class RestCriterion:
    """Stop once the kinetic energy stays below ``kinetic_energy`` for ``duration``.

    Parameters
    ----------
    kinetic_energy : float
        Threshold (energy units), > 0.  A useful scale is a small fraction of the energy
        injected, e.g. ``1e-8 * mu * L * U**2``.
    duration : float
        Time (time units) during which the kinetic energy must stay below the threshold,
        >= 0; checked every step inside the compiled loop.
    """

    kinetic_energy: float
    duration: float

    def __post_init__(self):
        if not self.kinetic_energy > 0:
            raise ValueError(
                f"RestCriterion.kinetic_energy must be > 0, got {self.kinetic_energy!r}"
            )
        if not self.duration >= 0:
            raise ValueError(f"RestCriterion.duration must be >= 0, got {self.duration!r}")


@dataclass
class SimulationResult:
    """Trajectory snapshots, energies and diagnostics of :func:`simulate`.

    Attributes
    ----------
    times : ndarray, shape (n_frames,)
        Frame times (step boundaries ``t0 + j dt``).
    positions : ndarray, shape (n_frames, n_nodes, 2)
        Node positions at the frames.
    velocities : ndarray, shape (n_nodes, 2)
        Velocities at the last frame.
    energies : dict of str -> ndarray, shape (n_frames,)
        ``"kinetic"``, ``"bending"`` and one entry per force effect (its potential);
        ``"total"`` is their sum.
    status : str
        ``"completed"``, ``"at_rest"``, the method's failure (``"shake_failed"``,
        ``"newton_failed"``) or ``"non_finite"``.
    success : bool
        True for ``"completed"`` and ``"at_rest"``.
    message : str
        What happened and, on failure, where (time, node/edge, quantity) and what to try.
    method : str
    t_final : float
    dt : float
    stats : dict
        Named diagnostics (:data:`STATS_KEYS` and the method's own keys).
    events_fired : list of (time, effect, param_index, value)
    contact_forces : ndarray, shape (n_nodes, 2), or None
        With a :class:`~dynamics.SelfContact`: the self-contact force on every node, the
        mean over the last step (force units; they sum to zero); None without one.
    """

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    energies: dict
    status: str
    success: bool
    message: str
    method: str
    t_final: float
    dt: float
    stats: dict
    events_fired: list = field(default_factory=list)
    contact_forces: np.ndarray | None = None

    def __eq__(self, other) -> bool:
        # field by field, arrays by value with NaN equal to NaN (the generated == would ask
        # an array for its truth value and raise): a saved and loaded result equals itself
        if type(other) is not type(self):
            return NotImplemented
        return all(_same_value(getattr(self, f.name), getattr(other, f.name))
                   for f in fields(self))

    __hash__ = None

    @property
    def steps(self) -> int:
        """Accepted steps (``stats["steps"]``)."""
        return int(self.stats["steps"])

    def to_dict(self) -> dict:
        """Scalar diagnostics as a JSON-serialisable dict (no arrays)."""
        return {
            "status": self.status,
            "success": self.success,
            "message": self.message,
            "method": self.method,
            "t_final": self.t_final,
            "dt": self.dt,
            "stats": dict(self.stats),
            "events_fired": [list(e) for e in self.events_fired],
            "n_frames": int(self.times.size),
        }

    def save_npz(self, path, context=None):
        """Save arrays and the diagnostics (as JSON metadata) to ``path``.

        ``context`` (a JSON-serialisable dict, e.g. the scene, resolution and package
        version of the run) is stored beside them as ``context`` and read back by
        :func:`load_npz_context`.
        """
        arrays = {"times": self.times, "positions": self.positions,
                  "velocities": self.velocities}
        for k, e in self.energies.items():
            arrays["energy__" + k] = e
        if self.contact_forces is not None:
            arrays["contact_forces"] = self.contact_forces
        if context is not None:
            arrays["context"] = np.array(json.dumps(context))
        # to a temporary file beside it, renamed into place (never half a file); the name
        # gets ".npz" when it has none, as numpy.savez gives it
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        tmp = path.with_name(f".{path.name}.tmp-{secrets.token_hex(6)}")
        try:
            with open(tmp, "xb") as f:  # the user's usual file mode (umask)
                np.savez(f, meta=np.array(json.dumps(self.to_dict())), **arrays)
            os.replace(tmp, path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise

    @staticmethod
    def load_npz_context(path) -> dict | None:
        """The ``context`` dict a file was saved with (None if it has none)."""
        with _readable(path), open(path, "rb") as fh, np.load(fh, allow_pickle=False) as f:
            return json.loads(str(f["context"])) if "context" in f.files else None

    @classmethod
    def load_npz(cls, path) -> SimulationResult:
        """Load a file written by :meth:`save_npz`; refuses incomplete files by name."""
        with _readable(path), open(path, "rb") as fh, np.load(fh, allow_pickle=False) as f:
            missing = [k for k in ("meta", "times", "positions", "velocities")
                       if k not in f.files]
            if missing:
                raise ValueError(f"{path}: not a SimulationResult file, missing {missing}")
            meta = json.loads(str(f["meta"]))
            energies = {k[len("energy__"):]: f[k] for k in f.files if k.startswith("energy__")}
            times, pos, vel = f["times"], f["positions"], f["velocities"]
            cf = f["contact_forces"] if "contact_forces" in f.files else None
        absent = [k for k in ("status", "success", "message", "method", "t_final", "dt",
                              "stats", "events_fired") if k not in meta]
        if absent:
            raise ValueError(f"{path}: metadata lacks {absent}")
        if not (times.ndim == 1 and pos.ndim == 3 and pos.shape[0] == times.size
                and pos.shape[2] == 2 and vel.shape == pos.shape[1:]):
            raise ValueError(f"{path}: inconsistent arrays: times {times.shape}, positions "
                             f"{pos.shape}, velocities {vel.shape} (expected (F,), (F, n, 2) "
                             "and (n, 2))")
        if meta.get("n_frames") not in (None, times.size):
            raise ValueError(f"{path}: {times.size} frames where the metadata says "
                             f"{meta['n_frames']}")
        meta.pop("n_frames", None)
        meta["events_fired"] = [tuple(e) for e in meta["events_fired"]]
        return cls(times=times, positions=pos, velocities=vel, energies=energies,
                   contact_forces=cf, **meta)


@contextlib.contextmanager
def _readable(path):
    """A file numpy cannot read (truncated, not a zip, a damaged member) as a ValueError
    naming it."""
    try:
        yield
    except (EOFError, zipfile.BadZipFile, json.JSONDecodeError) as err:
        raise ValueError(f"{path}: not a readable .npz file ({type(err).__name__}: "
                         f"{err})") from None


def _same_value(a, b) -> bool:
    """Equality of result data: arrays by shape and elements (NaN equal to NaN), dicts,
    lists and tuples item by item (a tuple equals a list: JSON keeps no tuples)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        if a is None or b is None:
            return a is b
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same_value(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same_value(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b)


# ----------------------------------------------------------------------------- checks


def _resolve_param(effect, param):
    names = tuple(getattr(effect, "param_names", ()) or ())
    if isinstance(param, str):
        if param not in names:
            raise ValueError(
                f"event on effect {effect.name!r}: unknown parameter {param!r}; "
                f"known names are {names}"
            )
        return names.index(param)
    j = int(param)
    if not 0 <= j < effect.params.size:
        raise ValueError(
            f"event on effect {effect.name!r}: parameter index {j} out of range "
            f"[0, {effect.params.size})"
        )
    return j


def frame_steps(frames, t_end: float, dt: float) -> np.ndarray:
    """The steps ``k`` (times ``k dt``) at which :func:`simulate` records a frame: ``frames``
    as :func:`simulate` takes it (None for 101, a count >= 2 spread evenly over
    ``[0, t_end]``, or the times themselves), each time rounded to the nearest step, sorted,
    without repeats, and within the run's ``ceil(t_end / dt)`` steps."""
    if frames is None:
        frames = 101
    if np.isscalar(frames):
        nf = int(frames)
        if nf < 2:
            raise ValueError(f"frames must be >= 2 when given as a count, got {frames!r}")
        times = np.linspace(0.0, t_end, nf)
    else:
        times = np.asarray(frames, dtype=np.float64).ravel()
        if times.size == 0 or np.any(times < 0) or np.any(times > t_end * (1 + 1e-12)):
            raise ValueError(
                f"frame times must lie in [0, t_end = {t_end:g}], got min "
                f"{times.min() if times.size else None}, max "
                f"{times.max() if times.size else None}"
            )
    steps = np.unique(np.rint(times / dt).astype(np.int64))
    return steps[(steps >= 0) & (steps <= int(math.ceil(t_end / dt - 1e-9)))]


#: Most steps one run may take (an underflowing dt is refused before it starts: at the
#: measured 5-8 us a step of an impact, 1e11 steps are about a week).
MAX_STEPS = 10**11


def validate_run(rod, effects, events, dt, t_end):
    """Check the arguments shared by the methods; return ``dt, t_end, effects, ev`` with
    ``ev`` the events as sorted ``(step, effect, param index, value)``."""
    if not isinstance(rod, Rod):
        raise TypeError(f"rod must be a dynamics.Rod, got {type(rod).__name__}")
    dt = float(dt)
    t_end = float(t_end)
    if not (dt > 0 and np.isfinite(dt)):
        raise ValueError(f"dt must be > 0 and finite, got dt = {dt!r}")
    if not (t_end >= 0 and np.isfinite(t_end)):
        raise ValueError(f"t_end must be >= 0 and finite, got t_end = {t_end!r}")
    if t_end / dt > MAX_STEPS:
        raise ValueError(f"dt = {dt!r} would take {t_end / dt:.3g} steps to t_end = "
                         f"{t_end:g}; at most {MAX_STEPS:.0e} are allowed")
    effects = tuple(effects)
    names = [e.name for e in effects]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"effect names must be unique; repeated: {dup}")
    for e in effects:
        p = getattr(e, "params", None)
        if not (isinstance(p, np.ndarray) and p.dtype == np.float64 and p.ndim == 1
                and p.flags.c_contiguous):
            raise TypeError(
                f"effect {e.name!r}: params must be a 1-D C-contiguous float64 ndarray, got "
                f"{type(p).__name__} {getattr(p, 'dtype', '')} {getattr(p, 'shape', '')}"
            )
    by_name = dict(zip(names, effects, strict=True))
    ev = []
    for e in events:
        if e.effect not in by_name:
            raise ValueError(f"event at t = {e.time:g}: no effect named {e.effect!r}; "
                             f"effects are {names}")
        if not 0 <= e.time <= t_end:
            raise ValueError(f"event time {e.time!r} outside [0, t_end = {t_end:g}]")
        j = _resolve_param(by_name[e.effect], e.param)
        k = int(math.ceil(e.time / dt - 1e-9))
        ev.append((k, by_name[e.effect], j, float(e.value)))
    ev.sort(key=lambda r: r[0])
    return dt, t_end, effects, ev


def schedule(frames, t_end, dt, ev):
    """Steps where a run stops: ``n_total``, the sorted stops (frames, events, the end) and
    the set of frame steps."""
    n_total = int(math.ceil(t_end / dt - 1e-9))
    fidx = frame_steps(frames, t_end, dt)
    stops = sorted(set(fidx.tolist()) | {k for k, *_ in ev} | {n_total})
    return n_total, stops, set(fidx.tolist())


# ----------------------------------------------------------------------------- simulate


def simulate(rod, effects=(), *, method="rattle", dt, t_end, frames=None, events=(),
             rest=None, t0=0.0, **options):
    """Integrate an inextensible planar rod under the given effects.

    Parameters
    ----------
    rod : Rod
        Initial state and material (not modified).
    effects : sequence of effect objects
        Built-in effects from :mod:`dynamics.effects` or any object following the effect
        protocol described there; names must be unique.  Bending (modulus ``rod.B``) is
        always included.  The effects' ``params`` arrays are used in place: events write
        into them, so pass fresh effect objects to repeat a run.
    method : {"rattle", "midpoint"}
        ``"rattle"`` (:mod:`dynamics.rattle`): explicit, symplectic, ``dt`` bounded by
        :func:`dynamics.stable_dt`.  ``"midpoint"`` (:mod:`dynamics.midpoint`): the
        constrained implicit midpoint rule, ``dt`` set by accuracy only (force and damping
        effects, at most one ground, and the self-contact).
    dt : float
        Time step (time units).
    t_end : float
        Duration of the run (time units), measured from ``t0``.
    frames : int or array_like, optional
        Number of equally spaced output frames on ``[0, t_end]`` (default 101), or the
        frame times relative to ``t0`` (rounded to the nearest step boundary).
    events : sequence of Event, optional
        Parameter changes at given times (relative to ``t0``).
    rest : RestCriterion, optional
        Stop early once the rod is at rest; the final state is then appended as a frame.
    t0 : float, optional
        Initial time (passed to the kernels).
    **options
        The method's own options: RATTLE ``check_dt`` (refuse a ``dt`` above the
        stability bound, default True); midpoint ``jacobian_age``, ``tol_x``, ``tol_c``,
        ``stiffness``, ``contact_updates`` (:class:`dynamics.midpoint.Run`).

    Returns
    -------
    SimulationResult
        Failures (a step not converging, a non-finite state) are reported in ``status``
        and ``message``, not raised; the frames up to the failure are kept.
    """
    methods = _methods()
    if method not in methods:
        raise ValueError(f"method: got {method!r}; expected one of {tuple(methods)}")
    dt, t_end, effects, ev = validate_run(rod, effects, events, dt, t_end)
    n_total, stops, fset = schedule(frames, t_end, dt, ev)
    stops = np.array(stops, dtype=np.int64)
    record = np.array([k in fset for k in stops.tolist()], dtype=np.bool_)

    tc = time.perf_counter()
    run = methods[method].Run(rod, effects, dt, t0, rest, **options)
    if run.compiled():
        run.warm()
    else:
        def waiting():
            log.info("waiting for another process compiling the %s stepper for %s",
                     method, run.label)

        with contextlib.ExitStack() as held:
            # kernels that other steppers share (self-contact's): while numba's cache lacks
            # them, one process compiles them and the others wait, then load them; these
            # locks come before the stepper's, in every process
            for group in cold_kernel_groups(run.effects):
                held.enter_context(compile_lock(group, on_wait=functools.partial(
                    log.info, "waiting for another process compiling the %s kernels",
                    group)))
            held.enter_context(compile_lock(run.mod, on_wait=waiting))
            if not run.compiled():
                log.info("compiling the %s stepper for %s: once, about %.0f s", method,
                         run.label, run.compile_estimate())
            run.warm()
    compile_time = time.perf_counter() - tc

    n = rod.n_nodes
    # frames are written by the compiled loop (one row per frame, one spare for the final
    # state of a run that stops at rest or fails)
    pos = np.empty((int(record.sum()) + 1, n, 2))
    ens = np.empty((pos.shape[0], 1 + run.n_energies))
    rec_steps = np.empty(pos.shape[0], dtype=np.int64)
    fired = []
    step = status = nrec = 0
    events_left = list(ev)
    tw = time.perf_counter()
    i = 0
    while i < stops.size:
        # all the stops up to the next event in one compiled call
        j = stops.size - 1
        if events_left:
            j = min(j, i + int(np.searchsorted(stops[i:], events_left[0][0])))
        status, step, nrec = run.advance(step, stops[i:j + 1], record[i:j + 1], pos, ens,
                                         rec_steps, nrec)
        if status != 0:
            break
        fired_now = False
        while events_left and events_left[0][0] <= step:
            _, eff, k, val = events_left.pop(0)
            eff.params[k] = val
            fired.append((t0 + step * dt, eff.name, k, val))
            fired_now = True
        if fired_now:
            run.after_event(step)
        i = j + 1
    wall = time.perf_counter() - tw

    t_final = t0 + step * dt
    name, msg = run.status_names.get(status, STATUS[status])
    if status == 1:
        msg = msg.format(thr=rest.kinetic_energy, dur=rest.duration) + f" at t = {t_final:g}"
    elif status in (2, 3):
        msg = run.failure(status, step, t_final)
    else:
        msg = f"{msg} ({step} steps of dt = {dt:g})"
    if status in (1, 2) and (nrec == 0 or rec_steps[nrec - 1] != step):
        nrec = run.frame(pos, ens, rec_steps, nrec, step)
    stats = run.stats()
    if stats["rejected_steps"] and status != 2:
        msg += (f"; {stats['rejected_steps']} rejected step(s) retried with up to "
                f"{2 ** stats['max_halvings']} substeps (fast local motion: a smaller dt "
                "avoids this)")
    stats.update(steps=step, compile_time=compile_time, run_time=wall)
    stats["iterations_mean"] = stats.pop("iterations_sum") / step if step else 0.0
    force_names = ["bending", *run.force_names]
    times = np.array([t0 + k * dt for k in rec_steps[:nrec].tolist()])
    if nrec:
        E = ens[:nrec]
        energies = {"kinetic": E[:, 0]}
        for k, nm in enumerate(force_names):
            energies[nm] = E[:, k + 1]
        energies["total"] = E.sum(axis=1)
    else:
        energies = {k: np.zeros(0) for k in ["kinetic", *force_names, "total"]}
    return SimulationResult(
        times=times,
        positions=pos[:nrec].copy(),
        velocities=run.v.copy(),
        energies=energies,
        status=name,
        success=status in (0, 1),
        message=msg,
        method=method,
        t_final=t_final,
        dt=dt,
        stats=stats,
        events_fired=fired,
        contact_forces=run.contact_forces(),
    )
