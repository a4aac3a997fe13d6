"""RATTLE time stepper specialised to the effects present, and :func:`simulate`.

Integrator
----------
One step of size ``dt`` (Andersen 1983, "RATTLE"; Leimkuhler & Reich 2004, sec. 7.2),
with damping split around it (Strang):

1. damping effects: exact decay of ``v`` over ``dt/2``;
2. half kick ``v_h = v + dt/2 M^-1 F(x)``; drift ``x* = x + dt v_h``;
3. constraint effects, stage 0 (clamps, ground hold coordinates of ``x*``);
4. SHAKE: project ``x*`` onto the edge lengths (Newton + tridiagonal solves), starting
   from ``x* + W G^T lam`` with ``lam`` the previous step's multipliers (the constraint
   forces change little in a step: the same root in fewer updates, 2 instead of 3 on
   fig3-strip); ``v_h = (x_new - x)/dt``;
5. forces at ``x_new``; half kick ``v = v_h + dt/2 W F(x_new)``;
6. constraint effects, stage 1; RATTLE velocity projection (``G v = 0``);
7. damping effects over ``dt/2``.

Without damping and contact the map is symplectic and time-reversible, so the energy
error stays bounded, O(dt**2), over long runs (``tests/dynamics/test_energy.py``).

Specialisation
--------------
For each distinct tuple of effect kernels the module generates the source of a stepper
(``_forces``, ``prepare``, ``run``) that calls exactly those kernels, writes it to a cache
directory and imports it, so that numba's on-disk cache (``cache=True``) works on it and
a second process loads the compiled loop instead of compiling it.  An absent effect costs
nothing, and all the steps between two output frames or events run inside one compiled
call (no Python per step), as does the recording of the output frames
(``run_frames``: positions and energies written into preallocated arrays; Python only
between events).  Measured (``benchmarks/dynamics_speed.py``, 200 edges): the generated
bending-only stepper runs at 0.92-1.03x the time of a hand-written RATTLE loop with the
same kernels (noise level); a force effect adds 0-3% (gravity, loads, an external
kernel), damping 12%, a constraint effect (ground, clamp) 4-5%; a Python call per step
would add 3.1 us/step (1.6x at 100 edges), a Python call and a recorded frame every 58
steps (supp-fig5) 0.4 us/step.  The loops over all coordinates run on flat views of the
(n, 2) arrays: numba indexes an (n, 2) array with a run-time row stride, which keeps a
loop scalar.  ``run`` hands its arrays on as borrowed references (an intrinsic drops the
reference-counted owner: the caller holds the arrays for the whole call) and ``_step``,
``_forces`` are inlined into it: numba counts the references of every array argument of
a call with atomic operations, and a call of ``_step`` with its 23 arrays cost 170-180 ns
(measured; fig3-strip 8.3 -> 7.9 us a step; inlining alone did not pay).  The solvers
and the bending kernel are called with the flat views (``shake_flat``,
``velocity_projection_flat``, ``bending_force_add_flat``): a reshape per call is a C call.
Not chosen: a generic loop over a tuple of first-class functions (indirect calls, not
cacheable by numba).  Cold compile of one stepper ~7-30 s, warm load ~0.5 s.

Where the time of an impact run goes (issue 5, measured with cycle counters around each
part of the step on supp-fig5 and fig3-strip): SHAKE 42%, the velocity projection 18%,
bending 13-14%, the external forces (capillary, gravity) 11-14%, damping 8% (supp-fig5),
contact, kicks and bookkeeping ~10% (fig3-strip); outside the loop, the crossing checks
and measures of ``elastocap.impact`` take ~2%.  Section 3b of
``benchmarks/dynamics_speed.py`` times the runs (``--baseline REV`` beside a revision).

Generated modules live in the private, content-addressed cache of :mod:`dynamics.cache`.
"""

from __future__ import annotations

import importlib
import json
import math
import time
from dataclasses import dataclass, field

import numba
import numpy as np

from .bending import BENDING_WORK_ROWS
from .cache import dependency_digest, load_module
from .constraints import SHAKE_FINAL, new_work
from .effects import KINDS
from .rod import Rod, kinetic_energy

__all__ = [
    "Event",
    "RestCriterion",
    "SimulationResult",
    "simulate",
    "stable_dt",
    "DT_BOUND_C",
    "compile_stepper",
]

#: Explicit stability constant of velocity Verlet for DER bending:
#: ``dt_max = DT_BOUND_C * h_min**2 * sqrt(mu / B)``.  Linear analysis of the discrete
#: beam (stencil [1, -4, 6, -4, 1] / h**4, highest mode omega = 4 sqrt(B/mu) / h**2, Verlet
#: stable for omega dt < 2) gives C = 0.5.  Measured by bisection on free rods of 25, 100,
#: 200, 400 edges with random small perturbations (energy growth over 3e4 steps): the
#: threshold is C = 0.5000-0.5019.  Curvature stiffens DER bending by sec**2(psi/2)
#: (1.1 at a turning angle of 0.6 rad per edge), hence a 10% margin: C = 0.45.  Accuracy
#: usually asks for less (the energy error grows as dt**2, see the tests).
DT_BOUND_C = 0.45

#: A step whose SHAKE projection fails (typically a violent contact: a whip-like tip
#: moving a large fraction of an edge per step) is rejected and retried as 2, 4, 8, 16
#: substeps; 4 halvings cover a 16x local velocity excess and keep a hopeless run short.
MAX_HALVINGS = 4

#: Rounds of "re-apply constraint effects, project again" after the first projection: a
#: projection can push a free node slightly through the ground (seen: 3e-4 for a rod
#: slapping the ground); one round fixes it in practice, the second is a safety margin.
CONTACT_ROUNDS = 2

#: Statuses: code -> (name, message template)
_STATUS = {
    0: ("completed", "reached t_end"),
    1: ("at_rest", "stopped at rest: kinetic energy below {thr:g} for {dur:g} time units"),
    2: ("shake_failed", "inextensibility projection (SHAKE) did not converge"),
    3: ("non_finite", "non-finite state (NaN/inf)"),
}


def stable_dt(edge_len, mu, B):
    """Explicit stability bound of the bending force, ``DT_BOUND_C h_min**2 sqrt(mu/B)``.

    Parameters
    ----------
    edge_len : array_like, shape (n_edges,)
        Rest edge lengths (length units).
    mu : float
        Mass per unit length.
    B : float
        Bending modulus; ``B == 0`` gives ``inf``.

    Returns
    -------
    float
        Largest accepted time step (time units).
    """
    if B == 0:
        return math.inf
    h = float(np.min(edge_len))
    return DT_BOUND_C * h * h * math.sqrt(mu / B)


# ----------------------------------------------------------------------------- events


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


# ----------------------------------------------------------------------------- result


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
        ``"completed"``, ``"at_rest"``, ``"shake_failed"`` or ``"non_finite"``.
    success : bool
        True for ``"completed"`` and ``"at_rest"``.
    message : str
        What happened and, on failure, where (time, node/edge, quantity) and what to try.
    steps : int
    t_final : float
    constraint_error_max : float
        Largest relative edge-length error after projection over the run.
    shake_iterations_max, shake_iterations_mean : float
        Newton iterations per step of the position projection.
    rejected_steps : int
        Steps whose projection failed and were retried with substeps (see
        ``MAX_HALVINGS``); ``max_halvings`` is the deepest halving that was needed.
    wall_time : float
        Seconds spent in the time loop (compilation excluded).
    compile_time : float
        Seconds spent generating/loading/compiling the stepper in this call.
    events_fired : list of (time, effect, param_index, value)
    dt : float
    """

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    energies: dict
    status: str
    success: bool
    message: str
    steps: int
    t_final: float
    constraint_error_max: float
    shake_iterations_max: float
    shake_iterations_mean: float
    rejected_steps: int
    max_halvings: int
    wall_time: float
    compile_time: float
    dt: float
    events_fired: list = field(default_factory=list)

    def to_dict(self) -> dict:
        """Scalar diagnostics as a JSON-serialisable dict (no arrays)."""
        return {
            "status": self.status,
            "success": self.success,
            "message": self.message,
            "steps": self.steps,
            "t_final": self.t_final,
            "dt": self.dt,
            "constraint_error_max": self.constraint_error_max,
            "shake_iterations_max": self.shake_iterations_max,
            "shake_iterations_mean": self.shake_iterations_mean,
            "rejected_steps": self.rejected_steps,
            "max_halvings": self.max_halvings,
            "wall_time": self.wall_time,
            "compile_time": self.compile_time,
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
        if context is not None:
            arrays["context"] = np.array(json.dumps(context))
        np.savez(path, meta=np.array(json.dumps(self.to_dict())), **arrays)

    @staticmethod
    def load_npz_context(path) -> dict | None:
        """The ``context`` dict a file was saved with (None if it has none)."""
        with np.load(path, allow_pickle=False) as f:
            return json.loads(str(f["context"])) if "context" in f.files else None

    @classmethod
    def load_npz(cls, path) -> SimulationResult:
        """Load a file written by :meth:`save_npz`; refuses incomplete files by name."""
        with np.load(path, allow_pickle=False) as f:
            missing = [k for k in ("meta", "times", "positions", "velocities")
                       if k not in f.files]
            if missing:
                raise ValueError(f"{path}: not a SimulationResult file, missing {missing}")
            meta = json.loads(str(f["meta"]))
            energies = {k[len("energy__"):]: f[k] for k in f.files if k.startswith("energy__")}
            times, pos, vel = f["times"], f["positions"], f["velocities"]
        meta.pop("n_frames", None)
        meta["events_fired"] = [tuple(e) for e in meta["events_fired"]]
        return cls(times=times, positions=pos, velocities=vel, energies=energies, **meta)


# ----------------------------------------------------------------------------- codegen


def _kernel_ref(effect):
    """(module, name) through which the generated module imports an effect's kernel."""
    k = getattr(effect, "kernel", None)
    k = getattr(k, "__func__", k)  # a dispatcher read through an instance is a bound method
    if k is None or not hasattr(k, "py_func"):
        raise TypeError(
            f"effect {getattr(effect, 'name', effect)!r}: kernel must be a numba "
            f"njit(cache=True) dispatcher, got {type(k).__name__}"
        )
    mod, name = k.__module__, k.__name__
    ok = False
    if mod != "__main__":
        try:
            ok = getattr(importlib.import_module(mod), name, None) is k
        except ImportError:
            ok = False
    if not ok:
        raise ValueError(
            f"effect {effect.name!r}: kernel {mod}.{name} is not importable by that name; "
            "define it at module level of an importable module (not in __main__ or inside "
            "a function) so the generated stepper can import and cache it"
        )
    return mod, name


#: The intrinsic through which the generated ``run()`` passes its arrays on as borrowed
#: references (no reference count: run's caller holds them for the whole call; with _step
#: and _forces inlined into run, nothing escapes it; the cost it removes is measured in
#: the module docstring).  Written against numba's lowering API
#: (``numba.core.cgutils``): if a numba release changes it, :func:`simulate` falls back to
#: the plain stepper with a warning.
_BORROWED_SOURCE = [
    "@intrinsic",
    "def _borrowed(typingctx, arr):",
    "    # the same array without its reference-counted owner (meminfo): valid while",
    "    # the caller holds the array; reference counting it is then a no-op",
    "    if not isinstance(arr, types.Array):",
    "        return None",
    "",
    "    def codegen(context, builder, sig, args):",
    "        src = context.make_array(arr)(context, builder, value=args[0])",
    "        dst = context.make_array(arr)(context, builder)",
    "        dst.meminfo = cgutils.get_null_value(dst.meminfo.type)",
    "        dst.parent = cgutils.get_null_value(dst.parent.type)",
    "        dst.nitems = src.nitems",
    "        dst.itemsize = src.itemsize",
    "        dst.data = src.data",
    "        dst.shape = src.shape",
    "        dst.strides = src.strides",
    "        return dst._getvalue()",
    "",
    "    return arr(arr), codegen",
    "",
    "",
]


def _generate_source(refs, borrowed=True):
    """Source of a stepper module for ``refs = [(kind, module, name), ...]``.

    ``borrowed``: ``run`` hands its arrays on without reference counting, through an
    intrinsic written against numba's lowering API (``numba.core.cgutils``, internal to
    numba); ``False`` gives the plain module, the fallback when that API changes.

    Layout of the generated functions' arguments: ``x, v`` (n, 2) the state; ``A`` the
    (7, n, 2) node work arrays (forces F, prediction xn, half-step velocity vh, inverse
    masses winv in force this step, and three backups for rejected steps); ``cw`` the
    constraint work array and ``lam`` the SHAKE multipliers of the last step (padded, see
    :mod:`dynamics.constraints`); ``bw`` the bending work array.  The loops over all
    coordinates run on flat views (``*f``, made once per ``run`` call): numba indexes an
    (n, 2) array with a run-time row stride, which keeps a loop scalar.
    """
    imports, P = [], []
    forces, damps, cons = [], [], []
    for j, (kind, mod, name) in enumerate(refs):
        alias = f"_k{j}"
        imports.append(f"from {mod} import {name} as {alias}")
        P.append(f"p{j}")
        {"force": forces, "damping": damps, "constraint": cons}[kind].append((alias, f"p{j}"))
    pargs = "".join(", " + p for p in P)
    final = repr(SHAKE_FINAL)
    fargs = "".join(", " + p for _, p in forces)
    # node arrays of _step: 2-D (for the kernels) and flat views (for the loops)
    nodes = "F, xn, vh, winv, Ff, xnf, vhf, winvf, xf, vf, winv0f"
    L = []
    L.append("# Generated by dynamics.stepper: a RATTLE stepper specialised to its effects.")
    L.append("# Do not edit; the file name is a hash of this text and of the kernels' sources.")
    L.append("import numba")
    L.append("import numpy as np")
    L.append("from dynamics.bending import bending_force_add_flat")
    L.append("from dynamics.constraints import (constraint_error, shake, shake_flat,"
             " velocity_projection, velocity_projection_flat)")
    L.append("from dynamics.rod import kinetic_energy")
    if borrowed:
        L.append("from numba import types")
        L.append("from numba.core import cgutils")
        L.append("from numba.extending import intrinsic")
    L += imports
    L.append("")
    L.append("")
    if borrowed:
        L += _BORROWED_SOURCE
    L.append("@numba.njit(cache=True, inline=\"always\")")
    L.append(f"def _forces(x, xf, v, t, edge_len, mass, B, F, Ff, energy, bw{fargs}):")
    L.append("    for j in range(Ff.shape[0]):")
    L.append("        Ff[j] = 0.0")
    L.append("    energy[0] = bending_force_add_flat(xf, edge_len, B, Ff, bw)")
    for k, (alias, p) in enumerate(forces):
        L.append(f"    energy[{k + 1}] = {alias}(x, v, t, {p}, edge_len, mass, F)")
    L.append("")
    L.append("")
    L.append("@numba.njit(cache=True)")
    L.append(f"def prepare(x, v, t, edge_len, winv0, A, cw, lam{pargs}):")
    L.append("    xn = A[1]")
    L.append("    winv = A[3]")
    L.append("    xn[:, :] = x")
    L.append("    winv[:, :] = winv0")
    for alias, p in cons:
        L.append(f"    {alias}(xn, v, t, {p}, edge_len, winv, 0)")
    L.append("    lam[:] = 0.0")
    L.append("    err, it, edge, err0 = shake(x, xn, winv, edge_len, cw, lam, False)")
    L.append("    lam[:] = 0.0")
    L.append("    x[:, :] = xn")
    for alias, p in cons:
        L.append(f"    {alias}(x, v, t, {p}, edge_len, winv, 1)")
    L.append("    velocity_projection(x, v, winv, cw)")
    L.append("    return constraint_error(x, edge_len)")
    L.append("")
    L.append("")
    L.append("@numba.njit(cache=True, inline=\"always\")")
    L.append(f"def _step(x, v, t, dt, edge_len, mass, winv0, B, {nodes}, cw, lam, bw, energy,"
             f" diag{pargs}):")
    L.append("    nc = xf.shape[0]")
    L.append("    half = 0.5 * dt")
    L.append("    t1 = t + dt")
    for alias, p in damps:
        L.append(f"    {alias}(x, v, t, {p}, edge_len, mass, half)")
    L.append("    for j in range(nc):")
    L.append("        vhf[j] = vf[j] + half * winv0f[j] * Ff[j]")
    L.append("        xnf[j] = xf[j] + dt * vhf[j]")
    L.append("        winvf[j] = winv0f[j]")
    for alias, p in cons:
        L.append(f"    {alias}(xn, vh, t1, {p}, edge_len, winv, 0)")
    # SHAKE starts from the drift moved by the previous step's multipliers (a predictor of
    # the constraint forces); the root is the same, only the iteration count changes
    L.append(f"    err, it, edge, err0 = shake_flat(xf, xnf, winvf, edge_len, cw, lam, True,"
             f" {final})")
    L.append("    if it < 0:")
    L.append("        # the predictor can mislead after an abrupt change (an impact): retry from")
    L.append("        # the plain drift before rejecting the step")
    L.append("        for j in range(nc):")
    L.append("            xnf[j] = xf[j] + dt * vhf[j]")
    L.append("            winvf[j] = winv0f[j]")
    for alias, p in cons:
        L.append(f"        {alias}(xn, vh, t1, {p}, edge_len, winv, 0)")
    L.append("        lam[:] = 0.0")
    L.append(f"        err, it, edge, err0 = shake_flat(xf, xnf, winvf, edge_len, cw, lam,"
             f" False, {final})")
    L.append("    if it == 0:")
    L.append("        # the prediction needed no update: its multipliers may be stale (a rod at")
    L.append("        # rest would keep being moved by them at round-off level); start the")
    L.append("        # next step from the plain drift")
    L.append("        lam[:] = 0.0")
    L.append("    if err0 > diag[0]:")
    L.append("        diag[0] = err0")
    L.append("    if it < 0:")
    L.append("        diag[4] = edge")
    L.append("        diag[5] = err")
    L.append("        return 2")
    if cons:
        # the projection may push a free node through a unilateral constraint (ground):
        # re-apply the constraints to the projected positions and project again (a
        # no-op when no new coordinate got held: protocol: a constraint kernel holds
        # (zeroes winv of) every coordinate it sets)
        L.append(f"    for _round in range({CONTACT_ROUNDS}):")
        L.append("        held = 0")
        L.append("        for j in range(nc):")
        L.append("            held += winvf[j] == 0.0")
        for alias, p in cons:
            L.append(f"        {alias}(xn, vh, t1, {p}, edge_len, winv, 0)")
        L.append("        for j in range(nc):")
        L.append("            held -= winvf[j] == 0.0")
        L.append("        if held == 0:")
        L.append("            break")
        L.append("        err, it2, edge, err1 = shake_flat(xf, xnf, winvf, edge_len, cw, lam,"
             " False, 0.0)")
        L.append("        if it2 < 0:")
        L.append("            diag[4] = edge")
        L.append("            diag[5] = err")
        L.append("            return 2")
        L.append("        it += it2")
    L.append("    if it > diag[2]:")
    L.append("        diag[2] = it")
    L.append("    diag[3] += it")
    L.append("    inv_dt = 1.0 / dt")
    L.append("    for j in range(nc):")
    L.append("        vhf[j] = (xnf[j] - xf[j]) * inv_dt")
    L.append("        xf[j] = xnf[j]")
    L.append(f"    _forces(x, xf, vh, t1, edge_len, mass, B, F, Ff, energy, bw{fargs})")
    L.append("    for j in range(nc):")
    L.append("        vf[j] = vhf[j] + half * winvf[j] * Ff[j]")
    for alias, p in cons:
        L.append(f"    {alias}(x, v, t1, {p}, edge_len, winv, 1)")
    # SHAKE has just split winvf into the work array (constraint kernels change winv at
    # stage 0 only)
    L.append("    velocity_projection_flat(xf, vf, winvf, cw, True)")
    for alias, p in damps:
        L.append(f"    {alias}(x, v, t1 - half, {p}, edge_len, mass, half)")
    L.append("    return 0")
    L.append("")
    L.append("")
    L.append("@numba.njit(cache=True)")
    L.append(f"def run(x, v, t0, dt, n_steps, edge_len, mass, winv0, B, A, cw, lam, bw, energy,"
             f" diag, rest{pargs}):")
    if borrowed:
        for a in "x, v, edge_len, mass, winv0, A, cw, lam, bw, energy, diag, rest".split(", ") + P:
            L.append(f"    {a} = _borrowed({a})")
    L.append("    nc = x.size")
    L.append("    Af = A.reshape(A.shape[0], nc)")
    L.append("    xf = x.reshape(nc)")
    L.append("    vf = v.reshape(nc)")
    L.append("    winv0f = winv0.reshape(nc)")
    L.append("    F = A[0]")
    L.append("    xn = A[1]")
    L.append("    vh = A[2]")
    L.append("    winv = A[3]")
    L.append("    Ff = Af[0]")
    L.append("    xnf = Af[1]")
    L.append("    vhf = Af[2]")
    L.append("    winvf = Af[3]")
    L.append("    xbf = Af[4]")
    L.append("    vbf = Af[5]")
    L.append("    fbf = Af[6]")
    L.append(f"    _forces(x, xf, v, t0, edge_len, mass, B, F, Ff, energy, bw{fargs})")
    L.append("    status = 0")
    L.append("    steps = 0")
    L.append("    for s in range(n_steps):")
    L.append("        t = t0 + s * dt")
    if damps:  # only damping touches v before the projection can fail
        L.append("        for j in range(nc):")
        L.append("            vbf[j] = vf[j]")
    L.append(f"        st = _step(x, v, t, dt, edge_len, mass, winv0, B, {nodes}, cw, lam, bw,"
             f" energy, diag{pargs})")
    L.append("        if st == 2:")
    L.append("            # rejected step: retry as 2, 4, ... 2**MAX_HALVINGS substeps, without")
    L.append("            # the multiplier predictor (it scales with the step squared)")
    L.append("            for j in range(nc):")
    if damps:
        L.append("                vf[j] = vbf[j]")
    L.append("                xbf[j] = xf[j]")
    L.append("                vbf[j] = vf[j]")
    L.append("                fbf[j] = Ff[j]")
    L.append(f"            for level in range(1, {MAX_HALVINGS} + 1):")
    L.append("                diag[6] += 1")
    L.append("                sub = 2 ** level")
    L.append("                h = dt / sub")
    L.append("                st = 0")
    L.append("                lam[:] = 0.0")
    L.append("                for j in range(sub):")
    L.append(f"                    st = _step(x, v, t + j * h, h, edge_len, mass, winv0, B,"
             f" {nodes}, cw, lam, bw, energy, diag{pargs})")
    L.append("                    if st != 0:")
    L.append("                        break")
    L.append("                if st == 0:")
    L.append("                    if level > diag[7]:")
    L.append("                        diag[7] = level")
    L.append("                    break")
    L.append("                for j in range(nc):")
    L.append("                    xf[j] = xbf[j]")
    L.append("                    vf[j] = vbf[j]")
    L.append("                    Ff[j] = fbf[j]")
    L.append("            lam[:] = 0.0")
    L.append("            if st != 0:")
    L.append("                status = 2")
    L.append("                break")
    L.append("        steps += 1")
    L.append("        ke = kinetic_energy(mass, v)")
    L.append("        if not np.isfinite(ke + np.sum(energy)):")
    L.append("            status = 3")
    L.append("            worst = 0")
    L.append("            for i in range(x.shape[0]):")
    L.append("                if not (np.isfinite(v[i, 0]) and np.isfinite(v[i, 1])")
    L.append("                        and np.isfinite(x[i, 0]) and np.isfinite(x[i, 1])):")
    L.append("                    worst = i")
    L.append("                    break")
    L.append("            diag[4] = worst")
    L.append("            break")
    L.append("        if rest[0] > 0.0:")
    L.append("            if ke < rest[0]:")
    L.append("                rest[2] += dt")
    L.append("                if rest[2] >= rest[1]:")
    L.append("                    status = 1")
    L.append("                    break")
    L.append("            else:")
    L.append("                rest[2] = 0.0")
    L.append("    err0, edge = constraint_error(x, edge_len)")
    L.append("    if err0 > diag[0]:")
    L.append("        diag[0] = err0")
    L.append("    return status, steps")
    L.append("")
    L.append("")
    L.append("@numba.njit(cache=True)")
    L.append(f"def run_frames(x, v, t0, dt, step, stops, record, pos, ens, rec_steps, nrec,"
             f" edge_len, mass, winv0, B, A, cw, lam, bw, energy, diag, rest{pargs}):")
    L.append("    # run to each stop in turn (one run call per stop, as a Python loop over run")
    L.append("    # would do) and record the frames flagged in ``record``")
    L.append("    status = 0")
    L.append("    for k in range(stops.shape[0]):")
    L.append("        if stops[k] > step:")
    L.append("            status, done = run(x, v, t0 + step * dt, dt, stops[k] - step, edge_len,"
             " mass, winv0, B, A, cw, lam, bw, energy, diag, rest" + pargs + ")")
    L.append("            step += done")
    L.append("            if status != 0:")
    L.append("                break")
    L.append("        if record[k]:")
    L.append("            for i in range(x.shape[0]):")
    L.append("                pos[nrec, i, 0] = x[i, 0]")
    L.append("                pos[nrec, i, 1] = x[i, 1]")
    L.append("            ens[nrec, 0] = kinetic_energy(mass, v)")
    L.append("            for i in range(energy.shape[0]):")
    L.append("                ens[nrec, i + 1] = energy[i]")
    L.append("            rec_steps[nrec] = step")
    L.append("            nrec += 1")
    L.append("    return status, step, nrec")
    L.append("")
    return "\n".join(L)


def _depends(refs):
    """:func:`dynamics.cache.dependency_digest` of what a generated stepper uses: the
    ``dynamics`` kernels and the effect kernels' modules with what they use."""
    return dependency_digest(["dynamics.bending", "dynamics.constraints", "dynamics.effects",
                              "dynamics.rod", *(mod for _, mod, _ in refs)])


_MODULES: dict = {}


def compile_stepper(effects=(), borrowed=True):
    """Return the generated stepper module for these effects (generate/import if needed).

    Parameters
    ----------
    effects : sequence of effect objects
        Only their ``kind`` and ``kernel`` matter (order included).
    borrowed : bool, optional
        Hand arrays on without reference counting (``_BORROWED_SOURCE``); ``False`` gives
        the plain stepper (the same numbers, ~5% slower).

    Returns
    -------
    module
        With numba functions ``run``, ``prepare`` and ``_forces``.  Compilation happens
        lazily at the first call (loaded from numba's cache when available).
    """
    refs = []
    for e in effects:
        if e.kind not in KINDS:
            raise ValueError(
                f"effect {e.name!r}: kind must be one of {KINDS}, got {e.kind!r}"
            )
        refs.append((e.kind, *_kernel_ref(e)))
    key = (tuple(refs), borrowed)
    if key in _MODULES:
        return _MODULES[key]
    src = _generate_source(key[0], borrowed)
    try:
        module = load_module("rattle", src, _depends(key[0]))
    except (ImportError, AttributeError) as err:
        if not borrowed:
            raise
        module = _plain_fallback(effects, err)
    _MODULES[key] = module
    return module


def _plain_fallback(effects, err):
    """The plain stepper, with a warning, when numba refuses the borrowed-array intrinsic."""
    import warnings

    warnings.warn(
        f"dynamics: numba {numba.__version__} refused the stepper's borrowed-array intrinsic "
        f"({type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}); using "
        "the plain stepper: the same results, about 5% slower a step",
        RuntimeWarning,
        stacklevel=3,
    )
    return compile_stepper(effects, borrowed=False)


# ----------------------------------------------------------------------------- simulate


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


def _frame_steps(frames, t_end, dt):
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
    idx = np.unique(np.rint(times / dt).astype(np.int64))
    return idx


def _validate_run(rod, effects, events, dt, t_end):
    """Check the arguments shared by the steppers; return ``dt, t_end, effects, ev`` with
    ``ev`` the events as sorted ``(step, effect, param index, value)``."""
    if not isinstance(rod, Rod):
        raise TypeError(f"rod must be a dynamics.Rod, got {type(rod).__name__}")
    dt = float(dt)
    t_end = float(t_end)
    if not (dt > 0 and np.isfinite(dt)):
        raise ValueError(f"dt must be > 0 and finite, got dt = {dt!r}")
    if not (t_end >= 0 and np.isfinite(t_end)):
        raise ValueError(f"t_end must be >= 0 and finite, got t_end = {t_end!r}")
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


def _schedule(frames, t_end, dt, ev):
    """Steps where a run stops: ``n_total``, the sorted stops (frames, events, the end) and
    the set of frame steps."""
    n_total = int(math.ceil(t_end / dt - 1e-9))
    fidx = _frame_steps(frames, t_end, dt)
    fidx = fidx[(fidx >= 0) & (fidx <= n_total)]
    stops = sorted(set(fidx.tolist()) | {k for k, *_ in ev} | {n_total})
    return n_total, stops, set(fidx.tolist())


def _result(times, pos, ens, force_names, v, n, status_name, status, msg, step, t_final, diag,
            wall, compile_time, dt, fired):
    """The :class:`SimulationResult` of a run (``diag`` in the steppers' common layout)."""
    # lists of per-frame values, or arrays with one row per frame
    if len(times):
        E = np.asarray(ens)
        energies = {"kinetic": E[:, 0]}
        for k, nm in enumerate(force_names):
            energies[nm] = E[:, k + 1]
        energies["total"] = E.sum(axis=1)
    else:
        energies = {k: np.zeros(0) for k in ["kinetic", *force_names, "total"]}
    return SimulationResult(
        times=np.array(times),
        positions=np.asarray(pos).reshape(len(pos), n, 2),
        velocities=v.copy(),
        energies=energies,
        status=status_name,
        success=status in (0, 1),
        message=msg,
        steps=step,
        t_final=t_final,
        constraint_error_max=float(diag[0]),
        shake_iterations_max=float(diag[2]),
        shake_iterations_mean=float(diag[3] / step) if step else 0.0,
        rejected_steps=int(diag[6]),
        max_halvings=int(diag[7]),
        wall_time=wall,
        compile_time=compile_time,
        dt=dt,
        events_fired=fired,
    )


def simulate(rod, effects=(), *, dt, t_end, frames=None, events=(), rest=None, t0=0.0,
             check_dt=True):
    """Integrate an inextensible planar rod with RATTLE under the given effects.

    Parameters
    ----------
    rod : Rod
        Initial state and material (not modified).
    effects : sequence of effect objects
        Built-in effects from :mod:`dynamics.effects` or any object following the effect
        protocol described there; names must be unique.  Bending (modulus ``rod.B``) is
        always included.  The effects' ``params`` arrays are used in place: events write
        into them, so pass fresh effect objects to repeat a run.
    dt : float
        Time step (time units); must not exceed :func:`stable_dt` unless
        ``check_dt=False``.
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
    check_dt : bool, optional
        Refuse a ``dt`` above the explicit stability bound of bending (default True).

    Returns
    -------
    SimulationResult
        Failures (SHAKE not converging, non-finite state) are reported in ``status`` and
        ``message``, not raised; the frames up to the failure are kept.
    """
    dt, t_end, effects, ev = _validate_run(rod, effects, events, dt, t_end)
    dt_max = stable_dt(rod.edge_len, rod.mu, rod.B)
    if check_dt and dt > dt_max:
        h = float(rod.edge_len.min())
        raise ValueError(
            f"dt = {dt:.4g} exceeds the explicit stability bound of bending "
            f"dt_max = C h**2 sqrt(mu/B) = {dt_max:.4g} (C = {DT_BOUND_C}, h = min edge "
            f"length = {h:.4g}, mu = {rod.mu:.4g}, B = {rod.B:.4g}). Use dt <= {dt_max:.4g}, "
            "or fewer edges (dt_max grows as h**2)."
        )

    n_total, stops, fset = _schedule(frames, t_end, dt, ev)
    stops = np.array(stops, dtype=np.int64)
    record = np.array([k in fset for k in stops.tolist()], dtype=np.bool_)

    # compile (or load) the specialised stepper
    tc = time.perf_counter()
    mod = compile_stepper(effects)
    params = tuple(e.params for e in effects)
    n_forces = sum(e.kind == "force" for e in effects)
    force_names = ["bending"] + [e.name for e in effects if e.kind == "force"]

    x = rod.x.copy()
    v = rod.v.copy()
    n = x.shape[0]
    edge_len = rod.edge_len.copy()
    mass = rod.mass
    winv0 = np.empty((n, 2))
    winv0[:, 0] = 1.0 / mass
    winv0[:, 1] = 1.0 / mass
    A = np.zeros((7, n, 2))
    cw = new_work(n - 1)
    lam = np.zeros(n + 1)
    bw = np.zeros((BENDING_WORK_ROWS, n))
    energy = np.zeros(1 + n_forces)
    diag = np.zeros(8)
    rest_arr = np.zeros(3)
    if rest is not None:
        rest_arr[0] = rest.kinetic_energy
        rest_arr[1] = rest.duration
    work = (edge_len, mass, winv0, rod.B, A, cw, lam, bw, energy, diag, rest_arr)
    mod.prepare(x, v, t0, edge_len, winv0, A, cw, lam, *params)
    try:
        mod.run(x, v, t0, dt, 0, *work, *params)  # compiles, or loads numba's cache
    except numba.core.errors.NumbaError as err:
        mod = _plain_fallback(effects, err)
        mod.run(x, v, t0, dt, 0, *work, *params)

    # frames are written by the compiled loop (one row per frame, one spare for the final
    # state of a run that stops at rest)
    pos = np.empty((int(record.sum()) + 1, n, 2))
    ens = np.empty((pos.shape[0], 1 + energy.size))
    rec_steps = np.empty(pos.shape[0], dtype=np.int64)
    mod.run_frames(x, v, t0, dt, 0, stops[:0], record[:0], pos, ens, rec_steps, 0, *work,
                   *params)
    compile_time = time.perf_counter() - tc

    fired = []
    step = 0
    status = 0
    nrec = 0
    events_left = list(ev)
    tw = time.perf_counter()
    i = 0
    while i < stops.size:
        # all the stops up to the next event in one compiled call
        j = stops.size - 1
        if events_left:
            j = min(j, i + int(np.searchsorted(stops[i:], events_left[0][0])))
        status, step, nrec = mod.run_frames(x, v, t0, dt, step, stops[i:j + 1],
                                            record[i:j + 1], pos, ens, rec_steps, nrec, *work,
                                            *params)
        if status != 0:
            break
        fired_now = False
        while events_left and events_left[0][0] <= step:
            _, eff, k, val = events_left.pop(0)
            eff.params[k] = val
            fired.append((t0 + step * dt, eff.name, k, val))
            fired_now = True
        if fired_now:
            # re-evaluate forces and energies with the new parameters
            mod.run(x, v, t0 + step * dt, dt, 0, *work, *params)
        i = j + 1
    wall = time.perf_counter() - tw

    t_final = t0 + step * dt
    name, msg = _STATUS[status]
    if status == 1:
        msg = msg.format(thr=rest.kinetic_energy, dur=rest.duration) + f" at t = {t_final:g}"
        if nrec == 0 or rec_steps[nrec - 1] != step:
            pos[nrec] = x
            ens[nrec, 0] = kinetic_energy(mass, v)
            ens[nrec, 1:] = energy
            rec_steps[nrec] = step
            nrec += 1
    elif status == 2:
        msg = (f"{msg} at t = {t_final + dt:g} (step {step + 1}): relative edge-length "
               f"residual {diag[5]:.3g} at edge {int(diag[4])} after the iteration cap, even "
               f"with {2**MAX_HALVINGS} substeps. "
               f"The predicted motion per step is too large: try a smaller dt (now {dt:g}, "
               f"stability bound {dt_max:.4g}) or check the forces for a blow-up.")
    elif status == 3:
        msg = (f"{msg} at t = {t_final:g} (step {step}) at node {int(diag[4])}: the "
               f"integration blew up. Try a smaller dt (now {dt:g}, stability bound of "
               f"bending {dt_max:.4g}); stiff external forces need their own dt limit.")
    else:
        msg = f"{msg} ({step} steps of dt = {dt:g})"
    if diag[6] and status != 2:
        msg += (f"; {int(diag[6])} rejected step(s) retried with up to "
                f"{2 ** int(diag[7])} substeps (fast local motion: a smaller dt avoids this)")
    times = [t0 + k * dt for k in rec_steps[:nrec].tolist()]
    return _result(times, pos[:nrec], ens[:nrec], force_names, v, n, name, status, msg, step,
                   t_final, diag, wall, compile_time, dt, fired)
