"""Branches of strip equilibria (fig3-strip) in one parameter, their folds and fold curves.

Search (as :mod:`elastocap.statics.branches`): on a few values of the parameter, Newton
from a family of lifted, wrapped seed shapes, deflated against the solutions already
known there; every new solution is continued both ways; folds are located exactly and
their discretization error estimated at a finer resolution.

Contact topology. :class:`~elastocap.strip.problem.StripProblem` has one topology: flat on
[0, s_c], lifted on [s_c, L] with s_c < S1. A branch is stopped (and the stop reported in
``endpoints``) when it leaves that topology:

* ``touchdown``: some point of the lifted part reaches the ground (z < 0 beyond s_c): the
  free end or the tail lands (the paper's "floppy" shapes), or the wrapped part touches.
* ``lift_off_at_S1``: the lift-off point reaches the contact line S1 (the drop's
  footprint would rest on the ground).

Torque balance on the lifted part (it receives only a vertical force at s_c, the drop's
forces are self-equilibrated) requires its centre of mass to lie above the lift-off
point: the strip must fold back over. So this topology holds the wrapped (encapsulated)
states and the saddles next to them, never the open state (the flat strip with the drop
resting on it needs a second contact: not handled).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from continuation import (
    Branch,
    ContinuationSettings,
    continue_branch,
    locate_fold,
)
from elastocap._version import __version__
from elastocap.scene import Scene, SceneError
from elastocap.statics.branches import BranchSet, newton
from elastocap.statics.spectral import lgl_interp_matrix
from elastocap.strip.problem import PARAMETERS, StripProblem
from elastocap.strip.shape import lowest_point

__all__ = [
    "STRIP_N",
    "StripBranchSet",
    "strip_problem_for",
    "trace_strip_branches",
]

#: LGL intervals per segment per accuracy preset. Measured (tests/strip, README text):
#: the lift-off point of the wrapped state at x = 2, Delta = 1.16 converges spectrally,
#: error 2.5e-9 at N = 8, 2e-10 at N = 12, round-off at N = 16.
STRIP_N = {"draft": 10, "default": 14, "publication": 20}
# A branch stops when the dry lifted length S1 - s_c falls below this fraction of Delta:
# the lift-off point reaches the drop (another topology).
_DRY_STOP = 1e-3
# Contact lines closer than this fraction of Delta end a branch: the cap degenerates (d and
# A1 -> 0 together on the index-2 branch of fig3-strip near Delta = 2.13, where the step
# collapses to 1e-6 below a chord of 1.5e-2 Delta). 1e-2 stops before; that end of the
# branch is inadmissible anyway (the strip crosses itself).
_CHORD_STOP = 1e-2
# Search grid and seeds: 5 parameter values x 30 seeds find the wrapped branch of
# fig3-strip at every x tried (0.8 ... 5); the seeds differ in the turning of the wet part
# (the wrap), of the tail, and in the dry lifted length.
_SEARCH_GRID = 5
_SEED_WRAP = (0.5 * math.pi, math.pi, 1.25 * math.pi)
_SEED_TAIL = (0.0, 0.6)
_SEED_DRY = (0.1, 0.4, 1.0, 2.0, 3.5)
# Newton tolerance on residuals of order gamma (~40): 1e-9 absolute is 2.5e-11 relative,
# reached in 2-3 iterations from the tangent predictor.
_NEWTON_TOL = 1e-9


_STOPS = ("touchdown", "lift_off_at_S1", "contact_lines_meet")


def _check_scene(scene: Scene) -> None:
    if not (scene.effects.gravity > 0.0 and scene.effects.ground):
        raise SceneError(
            "effects",
            {"gravity": scene.effects.gravity, "ground": scene.effects.ground},
            "the strip statics needs gravity > 0 and ground = true (for the free rod use "
            "elastocap.statics.branches.trace_branches)",
        )


def strip_problem_for(scene: Scene, parameter="drop.wetted_length", N=None) -> StripProblem:
    """The lifted-strip problem of a scene with gravity and ground."""
    _check_scene(scene)
    if parameter not in PARAMETERS:
        raise SceneError("--param", parameter, f"expected one of {', '.join(PARAMETERS)}")
    if N is None:
        N = scene.numerics.cheb_points or STRIP_N[scene.numerics.accuracy]
    d = scene.drop
    try:
        return StripProblem(
            N,
            scene.rod.length,
            scene.distance_from_end,
            d.wetted_length,
            d.area,
            d.line_tension,
            scene.rod.bending_modulus,
            scene.rod.mass_per_length * scene.effects.gravity,
            0.0,
            parameter,
        )
    except ValueError as exc:
        raise SceneError("drop.distance_from_end", scene.distance_from_end, str(exc)) from None


@dataclass
class StripBranchSet(BranchSet):
    """Branches of the strip in one parameter, with folds and topology endpoints.

    The fields of :class:`elastocap.statics.branches.BranchSet`; ``endpoints`` also carry the
    topology changes (``touchdown``, ``lift_off_at_S1``); ``problem`` is a StripProblem.
    ``branch_points`` and ``maxwell_points`` stay empty (not searched for here).
    """

    def summary(self) -> dict:
        """Plain data for ``--json``, with what this solver does not compute."""
        return {**super().summary(), "not_handled": NOT_HANDLED}


#: What the strip statics does not compute (also in every summary).
NOT_HANDLED = (
    "only the topology 'flat on [0, s_c], lifted on [s_c, L], s_c < S1'; branches stop when "
    "the lifted part touches the ground (touchdown: floppy shapes, free end landing) or the "
    "lift-off point reaches S1; the open state (drop resting on the strip on the ground) "
    "needs a second contact and is not computed"
)


def _settings(scene, lo, hi, max_steps=None) -> ContinuationSettings:
    span = hi - lo
    # ds_max 3% of the range: smooth curves; folds are located exactly, not read off steps
    return ContinuationSettings(
        ds0=0.01 * span,
        ds_min=1e-9 * span,
        ds_max=0.03 * span,
        max_steps=max_steps or min(scene.numerics.max_steps, 400),
        p_min=lo,
        p_max=hi,
        direction=0,
        newton_tol=_NEWTON_TOL,
        max_turn=0.2,
        check_jacobian=False,
    )


def _events(problem: StripProblem, grid_p=()):
    def touchdown(u, p):
        problem._with_p(p)
        return lowest_point(problem, u)

    def dry(u, p):
        problem._with_p(p)
        return (problem.s1 - float(u[-1])) - _DRY_STOP * problem.params["delta"]

    def chord(u, p):
        problem._with_p(p)
        th = problem.full_theta(u)[problem._slices()[1]]
        d = problem._wet.state(np.concatenate([th, [0.0]])).d
        return d - _CHORD_STOP * problem.params["delta"]

    ev = {"touchdown": touchdown, "lift_off_at_S1": dry, "contact_lines_meet": chord}
    for k, pk in enumerate(grid_p):
        ev[f"grid{k}"] = lambda u, p, pk=pk: p - pk
    return ev


def seeds(problem: StripProblem, wraps=_SEED_WRAP, tails=_SEED_TAIL, drys=_SEED_DRY):
    """Seed states: theta rising on the dry lifted part, turning by ``wrap`` on the wet part
    (the drop wrapped), turning by ``tail`` more on the tail; lift-off ``dry`` before S1."""
    out = []
    for dry in drys:
        s_c = problem.s1 - dry * problem.params["delta"]
        if s_c <= 0.0:
            continue
        for wrap in wraps:
            for tail in tails:
                u = np.zeros(problem.n)
                u[-1] = s_c
                st = problem.state(u)
                s = st.s
                t1 = 0.3 * np.clip((s - s_c) / (problem.s1 - s_c), 0.0, 1.0) ** 2
                t2 = wrap * np.clip((s - problem.s1) / problem.params["delta"], 0.0, 1.0)
                ell3 = problem.params["L"] - problem.s2
                t3 = tail * np.clip((s - problem.s2) / ell3, 0.0, 1.0)
                u[:-1] = (t1 + t2 + t3)[1:]
                out.append(u)
    return out


def _same(u, v, tol=1e-6):
    return float(np.max(np.abs(u - v))) <= tol


def _valid(problem, u) -> bool:
    """A solution in the handled topology: lift-off before S1 and no touchdown."""
    return (problem.s1 - float(u[-1])) > _DRY_STOP * problem.params["delta"] and (
        lowest_point(problem, u) > 0.0
    )


def trace_strip_branches(
    scene: Scene,
    parameter: str = "drop.wetted_length",
    prange=None,
    *,
    N=None,
    grid: int = _SEARCH_GRID,
    error_estimates: bool = True,
    max_steps: int | None = None,
) -> StripBranchSet:
    """Every lifted-strip branch of ``scene`` (gravity + ground) in ``parameter``.

    Parameters
    ----------
    scene : Scene
        A scene with gravity and a ground, e.g. ``fig3-strip``.
    parameter : str
        ``drop.wetted_length`` (default), ``drop.distance_from_end``, ``drop.area`` or
        ``drop.line_tension``.
    prange : (lo, hi), optional
        Default for Delta: (0.3, min(2.2, 1.95 x)) (the drop stays off the free end);
        otherwise 0.5x to 2x the scene's value.
    N : int or (int, int, int), optional
        LGL intervals per segment (default :data:`STRIP_N` of the accuracy preset).
    grid : int
        Parameter values of the seed search.
    error_estimates : bool
        Relocate each fold at N + max(6, N/2) to estimate its discretization error.

    Returns
    -------
    StripBranchSet
    """
    t0 = time.perf_counter()
    problem = strip_problem_for(scene, parameter, N)
    p_scene = problem.get(parameter)
    x_end = scene.distance_from_end
    if prange is None:
        if parameter == "drop.wetted_length":
            prange = (0.3, min(2.2, 1.95 * x_end))
        else:
            prange = (0.5 * p_scene, 2.0 * p_scene)
    lo, hi = float(prange[0]), float(prange[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
        raise SceneError("--range", list(prange), "expected two finite numbers 0 < LO < HI")
    if parameter == "drop.wetted_length" and hi >= 2.0 * x_end:
        raise SceneError(
            "--range", [lo, hi], f"expected HI < 2 x = {2.0 * x_end} (the drop off the free end)"
        )
    settings = _settings(scene, lo, hi, max_steps)
    grid_p = np.linspace(lo, hi, grid + 2)[1:-1]
    events = _events(problem, grid_p)
    stop_on = ["touchdown", "lift_off_at_S1", "contact_lines_meet"]
    known: dict[int, list] = {k: [] for k in range(len(grid_p))}
    result = StripBranchSet(scene, parameter, (lo, hi), problem)

    def record(br: Branch) -> bool:
        for sp in br.points("event"):
            if sp.name.startswith("grid") and sp.u is not None:
                k = int(sp.name[4:])
                if any(_same(sp.u, v, 1e-5) for v in known[k]):
                    return False  # it runs through a known solution: a known branch
        for sp in br.points("event"):
            if sp.name.startswith("grid") and sp.u is not None:
                known[int(sp.name[4:])].append(sp.u)
        return True

    for k, pk in enumerate(grid_p):
        problem.set(parameter, pk)
        for seed in seeds(problem):
            problem.set(parameter, pk)
            # 40 iterations: damped steps of <= 0.5 rad from seeds up to ~4 rad away
            u = newton(problem, seed, pk, _NEWTON_TOL, max_iter=40, deflate=known[k])
            if u is None or any(_same(u, v, 1e-5) for v in known[k]):
                continue
            problem.set(parameter, pk)
            if not _valid(problem, u):
                continue
            br = trim_branch(
                continue_branch(problem, u, pk, settings, events=events, stop_on=stop_on),
                problem,
            )
            known[k].append(u)
            if len(br) and record(br):
                result.branches.append(br)
                result.labels.append(f"branch {len(result.branches) - 1}")
    _collect(result, error_estimates)
    result.metadata = {
        "scene": scene.data,
        "scene_name": scene.name,
        "parameter": parameter,
        "range": [lo, hi],
        "N": list(problem.Ns),
        "nodes": "lgl",
        "newton_tol": _NEWTON_TOL,
        "locate_tol": settings.locate_tol,
        "search_grid": [float(v) for v in grid_p],
        "seeds": len(_SEED_WRAP) * len(_SEED_TAIL) * len(_SEED_DRY),
        "model": "lifted strip on [s_c, L], flat on [0, s_c] (elastocap.strip)",
        "not_handled": NOT_HANDLED,
        "version": __version__,
        "wall_time_s": time.perf_counter() - t0,
    }
    return result


def _event_valid(problem, sp) -> bool:
    """An event found on a valid state (not on a step past another terminal event)."""
    if problem is None or sp.u is None:
        return True
    problem.set(problem.parameter, sp.p)
    dry = problem.s1 - float(sp.u[-1])
    return dry > 0.0 and lowest_point(problem, sp.u) > -1e-6


def trim_branch(br: Branch, problem: StripProblem | None = None) -> Branch:
    """The branch without the points past its terminal events.

    The driver keeps the step that crosses a terminal event; past ``lift_off_at_S1`` the
    first segment has a negative length and past ``touchdown`` the strip is below the
    ground, so those points (and special points found on them) are dropped.
    """
    if not len(br):
        return br
    ok = (br.observables["dry_length"] > 0.0) & (br.observables["lowest_point"] > -1e-9)
    if ok.all():
        return br
    idx = np.flatnonzero(ok)
    if not idx.size:
        return br
    # the longest contiguous run of valid points
    runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
    run = max(runs, key=len)
    a, b = int(run[0]), int(run[-1]) + 1

    def cut(v):
        return None if v is None else v[a:b]

    sps = []
    for sp in br.special_points:
        if sp.kind == "endpoint":
            k = a if sp.index <= a else b - 1
            sps.append(dataclasses.replace(sp, index=k - a, p=float(br.p[k]), u=cut(br.u)[k - a]
                                           if br.u is not None else sp.u))
        elif a <= sp.index <= b and (sp.kind != "event" or _event_valid(problem, sp)):
            sps.append(dataclasses.replace(sp, index=min(max(sp.index, a), b - 1) - a))
    return Branch(
        p=br.p[a:b], u=cut(br.u), tangent=cut(br.tangent), ds=br.ds[a:b],
        newton_iterations=br.newton_iterations[a:b], stability=br.stability[a:b],
        observables={k: v[a:b] for k, v in br.observables.items()}, special_points=sps,
        status=br.status, message=br.message, parameter=br.parameter, metadata=br.metadata,
    )


def _stability_change(br: Branch, idx: int) -> str:
    a = int(br.stability[max(idx - 1, 0)])
    b = int(br.stability[min(idx, len(br) - 1)])
    return f"{a}->{b}"


def refine_state(problem: StripProblem, u, N2) -> tuple[StripProblem, np.ndarray]:
    """The state u interpolated segment by segment onto a problem with N2 intervals."""
    fine = problem.copy(N=N2)
    th = problem.full_theta(u)
    out = [np.zeros(1)]
    for k, sl in enumerate(problem._slices()):
        Mi = lgl_interp_matrix(problem.Ns[k], fine.xi[k])
        out.append((Mi @ th[sl])[1:])
    return fine, np.concatenate(out[1:] + [[u[-1]]])


def fold_error(problem: StripProblem, sp) -> float:
    """|p_N - p_N2| with N2 = N + max(6, N/2) per segment: the fold relocated finer."""
    N2 = tuple(n + max(6, n // 2) for n in problem.Ns)
    problem.set(problem.parameter, sp.p)
    fine, u2 = refine_state(problem, sp.u, N2)
    fsp = locate_fold(fine, u2, sp.p)
    if not fsp.located:
        return math.nan
    return abs(fsp.p - sp.p)


def _collect(result: StripBranchSet, error_estimates: bool) -> None:
    problem, par = result.problem, result.parameter
    for b, br in enumerate(result.branches):
        for sp in br.special_points:
            obs = {}
            if sp.u is not None:
                problem.set(par, sp.p)
                obs = problem.observables(sp.u, sp.p)
            if sp.kind == "fold":
                err = fold_error(problem, sp) if (error_estimates and sp.located) else math.nan
                result.folds.append(
                    {
                        "value": float(sp.p),
                        "measure": float(obs.get("measure", math.nan)),
                        "energy": float(obs.get("energy", math.nan)),
                        "lift_off": float(obs.get("lift_off", math.nan)),
                        "stability_change": _stability_change(br, sp.index),
                        "error_estimate": err,
                        "located": bool(sp.located),
                        "branch": b,
                    }
                )
            elif sp.kind == "event" and sp.name in _STOPS and not (
                obs.get("dry_length", 1.0) > 0.0 and obs.get("lowest_point", 0.0) > -1e-6
            ):
                continue  # found on a step past another terminal event
            elif sp.kind == "endpoint" or (sp.kind == "event" and sp.name in _STOPS):
                kind = sp.name if sp.kind == "event" else "endpoint"
                reason = {
                    "touchdown": "the lifted strip touches the ground (another contact "
                    "topology: not handled)",
                    "lift_off_at_S1": "the lift-off point reaches the contact line S1 (the "
                    "drop's footprint on the ground: not handled)",
                    "contact_lines_meet": "the contact lines meet (the strip closes round "
                    "the drop; the cap is undefined)",
                }.get(kind, br.message)
                result.endpoints.append(
                    {
                        "value": float(sp.p),
                        "kind": kind,
                        "measure": float(obs.get("measure", math.nan)),
                        "energy": float(obs.get("energy", math.nan)),
                        "reason": reason,
                        "branch": b,
                    }
                )
    result.folds.sort(key=lambda f: f["value"])
