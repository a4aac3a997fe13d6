"""The RATTLE method of :func:`dynamics.simulate` (``method="rattle"``): an explicit,
symplectic stepper specialised to the effects present.

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
   fig3-strip); a node the ground holds that the multipliers would lift above it from
   its drift is released (the ground pushes, it never pulls) and, as where the
   projection pushed a free node through the ground, the step is projected again;
   ``v_h = (x_new - x)/dt``;
5. forces at ``x_new``; half kick ``v = v_h + dt/2 W F(x_new)``;
6. constraint effects, stage 1; RATTLE velocity projection (``G v = 0``);
7. damping effects over ``dt/2``.

Without damping and contact the map is symplectic and time-reversible, so the energy
error stays bounded, O(dt**2), over long runs (``tests/dynamics/test_energy.py``).

Specialisation
--------------
For each distinct tuple of effect kernels the method renders :data:`_TEMPLATE` (the
stepper's functions ``_prepare``, ``_step``, ``run``, ``_refresh`` and ``run_frames``,
plain Python) with the dispatch functions that call exactly those kernels
(:func:`dynamics.codegen.render`, the mechanism both methods use) and loads it from the
cache of :mod:`dynamics.cache`, so that numba's on-disk cache (``cache=True``) works on it
and a second process loads the compiled loop instead of compiling it. An absent effect
costs nothing, and all the steps between two output frames or events run inside one
compiled call (no Python per step), as does the
recording of the output frames
(``run_frames``: positions and energies written into preallocated arrays; Python only
between events).  Measured (``benchmarks/dynamics_speed.py``, 200 edges): the generated
bending-only stepper runs at 0.92-1.03x the time of a hand-written RATTLE loop with the
same kernels (noise level); a force effect adds 0-3% (gravity, loads, an external
kernel), damping 12%, a constraint effect (ground, clamp) 4-5%; a Python call per step
would add 3.1 us/step (1.6x at 100 edges), a Python call and a recorded frame every 58
steps (supp-fig5) 0.4 us/step.  The loops over all coordinates run on flat views of the
(n, 2) arrays: numba indexes an (n, 2) array with a run-time row stride, which keeps a
loop scalar.  ``_step``, ``_forces`` and the dispatch functions are inlined into ``run``,
and ``run``, ``_prepare`` and ``_refresh`` into ``run_frames``, the module's one compiled
entry (``_step`` has one call site, which the rejected-step retries share: the loop is
compiled once, and no second entry compiles the inlined dispatch again);
the calls of the solver kernels still count the references of their array arguments
(numba does it with atomic operations: a call with 23 arrays cost 170-180 ns, measured), a
cost the stepper pays because it uses numba's public API only.  The solvers
and the bending kernel are called with the flat views (``shake_flat``,
``velocity_projection_flat``, ``bending_force_add_flat``): a reshape per call is a C call.
Not chosen: kernels called through numba's first-class functions (indirect calls: no
shorter compile, measured in docs/guide/time-stepping.md, "Compile cost").  Cold compile
of one stepper ~7-30 s, warm load ~0.5 s.

Where the time of an impact run goes (measured with cycle counters around each
part of the step on supp-fig5 and fig3-strip): SHAKE 42%, the velocity projection 18%,
bending 13-14%, the external forces (capillary, gravity) 11-14%, damping 8% (supp-fig5),
contact, kicks and bookkeeping ~10% (fig3-strip); outside the loop, the crossing checks
and measures of ``elastocap.impact`` (numpy) take 7% of a supp-fig5 impact, under 1% of
a fig3-strip one (``benchmarks/compile_speed.py --classification``).  Section 3b of
``benchmarks/dynamics_speed.py`` times the runs (``--baseline REV`` beside a revision).

Generated modules live in the private, content-addressed cache of :mod:`dynamics.cache`.
"""

from __future__ import annotations

import math

import numpy as np

from . import constraints
from .bending import BENDING_WORK_ROWS
from .cache import is_compiled, load_module
from .codegen import compile_estimate, kernel_ref, render, stepper_depends
from .constraints import SHAKE_FINAL, new_work
from .contact import (
    NO_CONTACT_WORK,
    check_self_contact,
    contact_failure,
    contact_stats,
    new_contact_work,
)
from .effects import KINDS, is_ground, is_self_contact
from .rod import kinetic_energy

__all__ = ["DT_BOUND_C", "Run", "compile_stepper", "stable_dt"]

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


# ----------------------------------------------------------------------------- codegen


#: The method's own imports in its generated module.
_IMPORTS = """\
from dynamics.bending import bending_force_add_flat
from dynamics.constraints import constraint_error, shake_flat, velocity_projection_flat
from dynamics.contact import contact_positions, contact_velocities
from dynamics.rod import kinetic_energy
"""

#: Modes of the generated ``run_frames``, the module's one compiled entry: run to the
#: stops, project the initial state, evaluate forces and energies (after an event).
RUN, PREPARE, REFRESH = 0, 1, 2

#: Body of the generated module (:func:`dynamics.codegen.render`, which generates the
#: effects' dispatch functions ``_external_forces``, ``_damp``, ``_constrain`` and the flags
#: before it; ``$pargs`` / ``$fargs`` stand for the effects' parameter arrays).
_TEMPLATE = """
@numba.njit(cache=True, inline="always")
def _forces(x, xf, v, t, edge_len, mass, B, F, Ff, energy, bw$fargs):
    for j in range(Ff.shape[0]):
        Ff[j] = 0.0
    energy[0] = bending_force_add_flat(xf, edge_len, B, Ff, bw)
    _external_forces(x, v, t, edge_len, mass, F, energy$fargs)


@numba.njit(cache=True, inline="always")
def _hold(x, v, t, edge_len, winv, stage$pargs):
    _constrain(x, v, t, edge_len, winv, stage$pargs)
    _ground(x, v, t, edge_len, winv, stage$pargs)


@numba.njit(cache=True, inline="always")
def _release(xf, xnf, vhf, winvf, winv0f, lam, dt, z0):
    # the ground holds a node it would pull: its kernel held the node's vertical
    # coordinate where the drift took it below z0, and the edges' multipliers of the
    # projection lift it above z0 from its drift. Such a node is released (no adhesion:
    # the ground's reaction is compressive); returns how many.
    n = xf.shape[0] // 2
    freed = 0
    for i in range(n):
        jz = 2 * i + 1
        if winvf[jz] != 0.0 or winv0f[jz] == 0.0 or winvf[jz - 1] == 0.0 or xnf[jz] != z0:
            continue
        dz = 0.0
        if i > 0:
            dz += (xf[jz] - xf[jz - 2]) * lam[i]
        if i < n - 1:
            dz -= (xf[jz + 2] - xf[jz]) * lam[i + 1]
        if xf[jz] + dt * vhf[jz] + winv0f[jz] * dz > z0:
            winvf[jz] = winv0f[jz]
            freed += 1
    return freed


@numba.njit(cache=True, inline="always")
def _project_again(xf, xnf, winvf, edge_len, cw, lam, diag):
    # one more projection of the step's positions (a round of the unilateral
    # constraints), counted; returns its iterations, negative on failure (recorded)
    diag[1] += 1
    err, it2, edge, err1 = shake_flat(xf, xnf, winvf, edge_len, cw, lam, np.bool_(False),
                                      0.0)
    if it2 < 0:
        diag[4] = edge
        diag[5] = err
    return it2


@numba.njit(cache=True, inline="always")
def _prepare(x, v, t, edge_len, winv0, A, cw, lam$pargs):
    xn = A[1]
    winv = A[3]
    _copy2(xn, x)
    _copy2(winv, winv0)
    _hold(xn, v, t, edge_len, winv, 0$pargs)
    lam[:] = 0.0
    # the flat kernels with the argument types of ``_step``'s calls (flags as np.bool_,
    # not literals): one compiled specialisation of each serves both
    nc = x.size
    err, it, edge, err0 = shake_flat(x.reshape(nc), xn.reshape(nc), winv.reshape(nc),
                                     edge_len, cw, lam, np.bool_(False), SHAKE_FINAL)
    lam[:] = 0.0
    _copy2(x, xn)
    _hold(x, v, t, edge_len, winv, 1$pargs)
    velocity_projection_flat(x.reshape(nc), v.reshape(nc), winv.reshape(nc), cw,
                             np.bool_(False))
    return constraint_error(x, edge_len)


@numba.njit(cache=True, inline="always")
def _step(x, v, t, dt, edge_len, mass, winv0, B, F, xn, vh, winv, Ff, xnf, vhf, winvf, xf,
          vf, winv0f, cw, lam, bw, energy, diag, ck$pargs):
    nc = xf.shape[0]
    half = 0.5 * dt
    t1 = t + dt
    _damp(x, v, t, edge_len, mass, half$pargs)
    for j in range(nc):
        vhf[j] = vf[j] + half * winv0f[j] * Ff[j]
        xnf[j] = xf[j] + dt * vhf[j]
        winvf[j] = winv0f[j]
    _hold(xn, vh, t1, edge_len, winv, 0$pargs)
    # SHAKE starts from the drift moved by the previous step's multipliers (a predictor
    # of the constraint forces); the root is the same, only the iteration count changes
    err, it, edge, err0 = shake_flat(xf, xnf, winvf, edge_len, cw, lam, np.bool_(True),
                                     SHAKE_FINAL)
    if it < 0:
        # the predictor can mislead after an abrupt change (an impact): retry from
        # the plain drift before rejecting the step
        for j in range(nc):
            xnf[j] = xf[j] + dt * vhf[j]
            winvf[j] = winv0f[j]
        _hold(xn, vh, t1, edge_len, winv, 0$pargs)
        lam[:] = 0.0
        err, it, edge, err0 = shake_flat(xf, xnf, winvf, edge_len, cw, lam,
                                         np.bool_(False), SHAKE_FINAL)
    freed = 0
    if HAS_GROUND and it >= 0:
        # read before a stale predictor is dropped: a rod at rest is held by the ground
        # with the multipliers of the predictor alone
        freed = _release(xf, xnf, vhf, winvf, winv0f, lam, dt, _ground_height(t1$pargs))
    if it == 0:
        # the prediction needed no update: its multipliers may be stale (a rod at
        # rest would keep being moved by them at round-off level); start the
        # next step from the plain drift
        lam[:] = 0.0
    if err0 > diag[0]:
        diag[0] = err0
    if it < 0:
        diag[4] = edge
        diag[5] = err
        diag[8] = 0.0
        return 2
    if HAS_GROUND and freed > 0:
        # project the drift again with the released nodes free: from the held solution
        # (where they sit on the ground and every edge has its length) the projection
        # would not move them, and they would stay on the ground with the velocity of
        # their kick, lifted by nothing (a node stuck at the lift-off point)
        z0 = _ground_height(t1$pargs)
        n_nodes = nc // 2
        free = np.zeros(n_nodes, np.bool_)
        for i in range(n_nodes):
            jz = 2 * i + 1
            free[i] = xnf[jz] == z0 and winvf[jz] != 0.0 and winvf[jz - 1] != 0.0
        for j in range(nc):
            xnf[j] = xf[j] + dt * vhf[j]
            winvf[j] = winv0f[j]
        _hold(xn, vh, t1, edge_len, winv, 0$pargs)
        for i in range(n_nodes):
            if free[i]:
                jz = 2 * i + 1
                xnf[jz] = xf[jz] + dt * vhf[jz]
                winvf[jz] = winv0f[jz]
        lam[:] = 0.0
        it2 = _project_again(xf, xnf, winvf, edge_len, cw, lam, diag)
        if it2 < 0:
            return 2
        it += it2
    if HAS_CONSTRAINTS or HAS_GROUND:
        # the projection may push a free node through a unilateral constraint (ground):
        # re-apply the constraints to the projected positions and project again (a no-op
        # when no new coordinate got held: protocol: a constraint kernel holds (zeroes
        # winv of) every coordinate it sets; a node the ground would pull after that
        # waits a step to be released)
        for _round in range(CONTACT_ROUNDS):
            held = 0
            for j in range(nc):
                held += winvf[j] == 0.0
            _hold(xn, vh, t1, edge_len, winv, 0$pargs)
            for j in range(nc):
                held -= winvf[j] == 0.0
            if held == 0:
                break
            it2 = _project_again(xf, xnf, winvf, edge_len, cw, lam, diag)
            if it2 < 0:
                return 2
            it += it2
    if HAS_CONTACT:
        # self-contact: project onto the edge lengths and the non-penetration constraints
        # linearised at the old positions (a no-op while no pair is within reach)
        if contact_positions(x, xn, winv, edge_len, lam, _contact_thickness(t1$pargs),
                             np.inf, ck) < 0:
            diag[8] = 1.0
            return 2
    if it > diag[2]:
        diag[2] = it
    diag[3] += it
    inv_dt = 1.0 / dt
    for j in range(nc):
        vhf[j] = (xnf[j] - xf[j]) * inv_dt
        xf[j] = xnf[j]
    _forces(x, xf, vh, t1, edge_len, mass, B, F, Ff, energy, bw$fargs)
    for j in range(nc):
        vf[j] = vhf[j] + half * winvf[j] * Ff[j]
    _hold(x, v, t1, edge_len, winv, 1$pargs)
    # SHAKE has just split winvf into the work array (constraint kernels change winv at
    # stage 0 only)
    velocity_projection_flat(xf, vf, winvf, cw, np.bool_(True))
    if HAS_CONTACT:
        # restitution 0 where the rod touches itself (an unsettled active set leaves the
        # velocities of its last round and is counted)
        cvs = contact_velocities(x, v, winv, edge_len, _contact_thickness(t1$pargs), dt, 1.0,
                                 False, False, ck)
        if cvs < -1:
            # a non-finite velocity: a contact failure, not a silent NaN
            diag[8] = 1.0
            return 2
        if cvs < 0:
            diag[9] += 1.0
    _damp(x, v, t1 - half, edge_len, mass, half$pargs)
    return 0


@numba.njit(cache=True, inline="always")
def run(x, v, t0, dt, n_steps, edge_len, mass, winv0, B, A, cw, lam, bw, energy, diag,
        rest, ck$pargs):
    nc = x.size
    Af = A.reshape(A.shape[0], nc)
    xf = x.reshape(nc)
    vf = v.reshape(nc)
    winv0f = winv0.reshape(nc)
    F = A[0]
    xn = A[1]
    vh = A[2]
    winv = A[3]
    Ff = Af[0]
    xnf = Af[1]
    vhf = Af[2]
    winvf = Af[3]
    xbf = Af[4]
    vbf = Af[5]
    fbf = Af[6]
    _forces(x, xf, v, t0, edge_len, mass, B, F, Ff, energy, bw$fargs)
    status = 0
    steps = 0
    for s in range(n_steps):
        t = t0 + s * dt
        if HAS_DAMPING:  # only damping touches v before the projection can fail
            for j in range(nc):
                vbf[j] = vf[j]
        # the step as 1 substep; if rejected, retried as 2, 4, ... 2**MAX_HALVINGS
        # substeps from the state before it, without the multiplier predictor (it scales
        # with the step squared).  One call site of ``_step`` (inlined): the loop is
        # compiled once.
        level = 0
        while True:
            sub = 2 ** level
            h = dt / sub
            st = 0
            for j in range(sub):
                st = _step(x, v, t + j * h, h, edge_len, mass, winv0, B, F, xn, vh, winv,
                           Ff, xnf, vhf, winvf, xf, vf, winv0f, cw, lam, bw, energy, diag,
                           ck$pargs)
                if st != 0:
                    break
            if st == 0:
                break
            if level == 0:
                # the state before the step (a failed step moves no position or force)
                for j in range(nc):
                    if HAS_DAMPING:
                        vf[j] = vbf[j]
                    xbf[j] = xf[j]
                    vbf[j] = vf[j]
                    fbf[j] = Ff[j]
            else:
                for j in range(nc):
                    xf[j] = xbf[j]
                    vf[j] = vbf[j]
                    Ff[j] = fbf[j]
            if level == MAX_HALVINGS:
                break
            level += 1
            diag[6] += 1
            lam[:] = 0.0
        if level > 0:
            if st == 0 and level > diag[7]:
                diag[7] = level
            lam[:] = 0.0
            if st != 0:
                status = 2
                break
        steps += 1
        ke = kinetic_energy(mass, v)
        if not np.isfinite(ke + np.sum(energy)):
            status = 3
            worst = 0
            for i in range(x.shape[0]):
                if not (np.isfinite(v[i, 0]) and np.isfinite(v[i, 1])
                        and np.isfinite(x[i, 0]) and np.isfinite(x[i, 1])):
                    worst = i
                    break
            diag[4] = worst
            break
        if _at_rest(ke, dt, rest):
            status = 1
            break
    _record_constraint_error(x, edge_len, diag)
    return status, steps


@numba.njit(cache=True, inline="always")
def _refresh(x, v, t, edge_len, mass, B, A, bw, energy, diag$pargs):
    # forces and energies at the current state (after an event changed parameters): what
    # a ``run`` of 0 steps does
    nc = x.size
    _forces(x, x.reshape(nc), v, t, edge_len, mass, B, A[0], A.reshape(A.shape[0], nc)[0],
            energy, bw$fargs)
    _record_constraint_error(x, edge_len, diag)


@numba.njit(cache=True)
def run_frames(mode, x, v, t0, dt, step, stops, record, pos, ens, rec_steps, nrec, edge_len,
               mass, winv0, B, A, cw, lam, bw, energy, diag, rest, ck$pargs):
    # the module's one compiled entry (each entry would compile the kernels' inlined
    # dispatch again): mode PREPARE projects the initial state, REFRESH evaluates forces
    # and energies at step ``step``, RUN runs to each stop in turn (one run call per stop,
    # as a Python loop over run would do) and records the frames flagged in ``record``
    if mode == PREPARE:
        _prepare(x, v, t0, edge_len, winv0, A, cw, lam$pargs)
        return 0, step, nrec
    if mode == REFRESH:
        _refresh(x, v, t0 + step * dt, edge_len, mass, B, A, bw, energy, diag$pargs)
        return 0, step, nrec
    status = 0
    for k in range(stops.shape[0]):
        if stops[k] > step:
            status, done = run(x, v, t0 + step * dt, dt, stops[k] - step, edge_len, mass,
                               winv0, B, A, cw, lam, bw, energy, diag, rest, ck$pargs)
            step += done
            if status != 0:
                break
        if record[k]:
            for i in range(x.shape[0]):
                pos[nrec, i, 0] = x[i, 0]
                pos[nrec, i, 1] = x[i, 1]
            ens[nrec, 0] = kinetic_energy(mass, v)
            for i in range(energy.shape[0]):
                ens[nrec, i + 1] = energy[i]
            rec_steps[nrec] = step
            nrec += 1
    return status, step, nrec
"""


def _generate_source(refs):
    """Source of a RATTLE stepper module for ``refs = [(kind, module, name, native), ...]``
    (``native`` ``"contact"`` for the self-contact, True for the ground, else False)
    (:func:`dynamics.codegen.render` of :data:`_TEMPLATE`).

    Layout of the generated functions' arguments: ``x, v`` (n, 2) the state; ``A`` the
    (7, n, 2) node work arrays (forces F, prediction xn, half-step velocity vh, inverse
    masses winv in force this step, and three backups for rejected steps); ``cw`` the
    constraint work array and ``lam`` the SHAKE multipliers of the last step (padded, see
    :mod:`dynamics.constraints`); ``bw`` the bending work array.  The loops over all
    coordinates run on flat views (``*f``, made once per ``run`` call): numba indexes an
    (n, 2) array with a run-time row stride, which keeps a loop scalar.
    """
    imports = (_IMPORTS + f"SHAKE_FINAL = {SHAKE_FINAL!r}\nCONTACT_ROUNDS = {CONTACT_ROUNDS}\n"
               f"MAX_HALVINGS = {MAX_HALVINGS}\nRUN, PREPARE, REFRESH = {RUN}, {PREPARE}, "
               f"{REFRESH}\n")
    return render(_TEMPLATE, [(kind, mod, name, None, native)
                              for kind, mod, name, native in refs], imports)


_MODULES: dict = {}


def _check_ground(effect, effects) -> bool:
    """Whether RATTLE handles ``effect`` as the ground: its kernel holds and stops, and
    the stepper releases the nodes it would pull (one ground, height at params[0])."""
    if not is_ground(effect):
        return False
    if int(effect.ground_height_param) != 0:
        raise ValueError(f"effect {effect.name!r}: the ground's height must be params[0]; "
                         f"got ground_height_param = {effect.ground_height_param!r}")
    if sum(is_ground(e) for e in effects) > 1:
        raise ValueError(f"effect {effect.name!r}: RATTLE handles one ground; got "
                         f"{sum(is_ground(e) for e in effects)} ground effects")
    return True


def compile_stepper(effects=()):
    """Return the generated RATTLE stepper module for these effects (generate/import if
    needed).

    Parameters
    ----------
    effects : sequence of effect objects
        Only their ``kind`` and ``kernel`` matter (order included).

    Returns
    -------
    module
        With the numba function ``run_frames(mode, ...)``: the time loop (mode
        :data:`RUN`), the initial projection (:data:`PREPARE`) and the forces and energies
        after an event (:data:`REFRESH`).
        Compilation happens lazily at the first call (loaded from numba's cache when
        available).
    """
    refs = []
    for e in effects:
        if e.kind not in KINDS:
            raise ValueError(
                f"effect {e.name!r}: kind must be one of {KINDS}, got {e.kind!r}"
            )
        refs.append((e.kind, *kernel_ref(e),
                     check_self_contact(e, effects) or _check_ground(e, effects)))
    key = tuple(refs)
    if key not in _MODULES:
        _MODULES[key] = load_module("rattle", _generate_source(key), stepper_depends(key))
    return _MODULES[key]


#: Compile time of a new RATTLE stepper when the package's kernels are cached, the base of
#: the estimate the driver announces before a first compile
#: (:func:`dynamics.codegen.compile_estimate` adds what is not cached, and self-contact):
#: measured (benchmarks/compile_speed.py, CPU, 2 shared cores) 4.6 s bending only and
#: 5.6 s with four effects; 6.7 s (wall) for supp-fig5's two, 8.8 s for fig3-strip's four.
COMPILE_BASE_S = 5.0
COMPILE_PER_EFFECT_S = 2.0


class Run:
    """A RATTLE run in progress (the method protocol of :mod:`dynamics.driver`).

    Options: ``check_dt`` (default True) refuses a ``dt`` above :func:`stable_dt`.
    """

    @property
    def status_names(self):
        if self.diag[8]:
            return {2: ("contact_failed", "self-contact projection did not converge")}
        return {2: ("shake_failed", "inextensibility projection (SHAKE) did not converge")}

    def __init__(self, rod, effects, dt, t0, rest, check_dt=True):
        self.dt_max = stable_dt(rod.edge_len, rod.mu, rod.B)
        if check_dt and dt > self.dt_max:
            h = float(rod.edge_len.min())
            raise ValueError(
                f"dt = {dt:.4g} exceeds the explicit stability bound of bending "
                f"dt_max = C h**2 sqrt(mu/B) = {self.dt_max:.4g} (C = {DT_BOUND_C}, h = min "
                f"edge length = {h:.4g}, mu = {rod.mu:.4g}, B = {rod.B:.4g}). Use dt <= "
                f"{self.dt_max:.4g}, or fewer edges (dt_max grows as h**2), or "
                "method='midpoint'."
            )
        self.dt, self.t0 = dt, t0
        self.effects = effects
        self.label = "+".join(e.name for e in effects) or "bending"
        self.mod = compile_stepper(effects)
        self.params = tuple(e.params for e in effects)
        self.force_names = [e.name for e in effects if e.kind == "force"]
        self.n_energies = 1 + len(self.force_names)
        self.x = rod.x.copy()
        self.v = rod.v.copy()
        n = self.x.shape[0]
        self.mass = rod.mass
        winv0 = np.empty((n, 2))
        winv0[:, 0] = 1.0 / self.mass
        winv0[:, 1] = 1.0 / self.mass
        self.edge_len = rod.edge_len.copy()
        self.energy = np.zeros(self.n_energies)
        self.contact = any(is_self_contact(e) for e in effects)
        # the self-contact's work arrays (NO_CONTACT_WORK without it: its code is compiled out)
        self.ck = new_contact_work(self.edge_len) if self.contact else NO_CONTACT_WORK
        # diag: [0] largest constraint error, [1] contact rounds, [2] most iterations,
        # [3] iteration sum, [4] failing edge/node, [5] its residual, [6] rejected steps,
        # [7] deepest halving, [8] the failing projection was the self-contact's,
        # [9] unsettled self-contact velocity stages
        self.diag = np.zeros(10)
        rest_arr = np.zeros(3)
        if rest is not None:
            rest_arr[0] = rest.kinetic_energy
            rest_arr[1] = rest.duration
        self.work = (self.edge_len, self.mass, winv0, rod.B, np.zeros((7, n, 2)),
                     new_work(n - 1), np.zeros(n + 1), np.zeros((BENDING_WORK_ROWS, n)),
                     self.energy, self.diag, rest_arr, self.ck)

    def compiled(self) -> bool:
        return is_compiled(self.mod, ("run_frames",))

    def compile_estimate(self) -> float:
        return compile_estimate(COMPILE_BASE_S, COMPILE_PER_EFFECT_S, self.effects,
                                ((constraints, ("shake_flat", "velocity_projection_flat")),))

    def _entry(self, mode, step=0, stops=None, record=None, pos=None, ens=None,
               rec_steps=None, nrec=0):
        if stops is None:  # PREPARE, REFRESH: no stops, no frames (arrays of the types)
            stops, record = np.zeros(0, np.int64), np.zeros(0, np.bool_)
            pos, ens = np.empty((1, self.x.shape[0], 2)), np.empty((1, 1 + self.n_energies))
            rec_steps = np.empty(1, np.int64)
        return self.mod.run_frames(mode, self.x, self.v, self.t0, self.dt, step, stops,
                                   record, pos, ens, rec_steps, nrec, *self.work,
                                   self.params)

    def warm(self):
        """Project the initial state and evaluate its forces (compiles or loads the
        module's one entry, ``run_frames``)."""
        self._entry(PREPARE)
        self.after_event(0)

    def advance(self, step, stops, record, pos, ens, rec_steps, nrec):
        return self._entry(RUN, step, stops, record, pos, ens, rec_steps, nrec)

    def after_event(self, step):
        # re-evaluate forces and energies with the new parameters
        self._entry(REFRESH, step)

    def frame(self, pos, ens, rec_steps, nrec, step):
        pos[nrec] = self.x
        ens[nrec, 0] = kinetic_energy(self.mass, self.v)
        ens[nrec, 1:] = self.energy
        rec_steps[nrec] = step
        return nrec + 1

    def contact_forces(self):
        """Self-contact forces on the nodes, mean over the last step (None without it)."""
        return self.ck.forces.copy() if self.contact else None

    def failure(self, status, step, t_final):
        d, dt = self.diag, self.dt
        name, msg = self.status_names.get(status, (None, "non-finite state (NaN/inf)"))
        if status == 2 and d[8]:
            return contact_failure(self.ck, t_final + dt, step + 1, dt, 2**MAX_HALVINGS)
        if status == 2:
            return (f"{msg} at t = {t_final + dt:g} (step {step + 1}): relative edge-length "
                    f"residual {d[5]:.3g} at edge {int(d[4])} after the iteration cap, even "
                    f"with {2**MAX_HALVINGS} substeps. The predicted motion per step is too "
                    f"large: try a smaller dt (now {dt:g}, stability bound "
                    f"{self.dt_max:.4g}) or check the forces for a blow-up.")
        return (f"{msg} at t = {t_final:g} (step {step}) at node {int(d[4])}: the "
                f"integration blew up. Try a smaller dt (now {dt:g}, stability bound of "
                f"bending {self.dt_max:.4g}); stiff external forces need their own dt limit.")

    def stats(self) -> dict:
        d = self.diag
        out = {"rejected_steps": int(d[6]), "max_halvings": int(d[7]),
               "iterations_max": float(d[2]), "iterations_sum": float(d[3]),
               "contact_rounds": int(d[1]), "constraint_error": float(d[0])}
        if self.contact:
            out.update(contact_stats(self.ck, int(d[9])))
        return out
