"""Every equilibrium branch of a free-rod scene: search, continuation, special points.

The search is :class:`continuation.BranchSearch` (deflated multi-start continuation; its
docstring states why it is complete and what it could miss). This module supplies the
physics: the problem (:class:`~elastocap.statics.wet_elastica.WetElasticaProblem`, whose
``seeds(p)`` are shapes chosen from the wet part's geometry), the *admissible region* of
the continued key (where the wet interval lies on the rod and both dry arms have
non-negative length; the search range is clipped to it and branches end on it with a named
endpoint), and the honest reporting of special points: a fold is listed only when it was
located, is transversal (not a branch point) and was relocated at a finer resolution, with
that difference as its error estimate; everything else goes to ``unlocated`` with the
reason and what to try. The search runs two ways: from the problem's seeds and, for the
wetted length, from every crossing of the scene's area by the fold curves (in the drop
area) of the folds found, so that the folds the fold curves cross are found too.
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.optimize import brentq

from continuation import (
    Branch,
    BranchSearch,
    ContinuationSettings,
    SearchSettings,
    deflated_newton,
    fold_crossings,
    locate_fold,
)
from elastocap._version import __version__
from elastocap.branchset import BranchModel, BranchSet
from elastocap.scene import Scene, SceneError
from elastocap.statics.wet_elastica import PARAMETERS, WetElasticaProblem

__all__ = [
    "ACCURACY_N",
    "BranchSet",
    "StaticsError",
    "check_statics_scene",
    "admissible_range",
    "find_folds",
    "newton",
    "problem_for",
    "solve_on_run",
    "stable_runs",
    "trace_branches",
]

#: LGL intervals on the wet part per accuracy preset. Measured on supp-fig5 (README,
#: "Statics accuracy"): fold error 1.4e-9 at N = 16, 2e-14 at N = 24, round-off at N = 40.
ACCURACY_N = {"draft": 16, "default": 24, "publication": 40}
# Contact lines closer than this fraction of Delta end a branch: the chord direction, and so
# the cap, is undefined when they meet.
_CHORD_STOP = 1e-3
#: Interior sample values of the search (the range ends and the scene's own value are
#: samples too); see continuation.BranchSearch for the argument.
SEARCH_SAMPLES = 3
#: A located fold whose transversality |psi . F_p| / (|psi| |F_p|) is below this is a
#: branch point (F_p in the range of F_u), not a fold. Simple folds of this problem measure
#: 1e-3..1 (supp-fig5: 0.2); a branch point measures round-off (1e-12).
FOLD_TRANSVERSALITY = 1e-6


#: Dimensionless ranges the free-rod statics resolves at its resolutions (N <= 128):
#: rod length over l_ec = sqrt(B/gamma) (boundary layers of width l_ec on a wet part of up
#: to L need N ~ L/l_ec points; at L = 1000 l_ec the default N = 24 gives stability
#: indices of 10 and more: unresolved) and drop area over l_ec^2 (any small area is fine:
#: A = 1e-9 gives the flat rod to O(A), tests/hard; 1e4 runs cleanly; 1e300 overflows the
#: cap geometry).
RESOLVED = {"rod.length": (1e-2, 20.0), "drop.area": (0.0, 1e3)}
#: Largest drop area over the square of the wetted length: the range over which the drop
#: model (the circular cap on its chord) is checked against a 60-digit solution
#: (tests/test_drop.py: |A1|/d^2 up to 1e12); a smaller Delta divides by zero in the
#: cap's derivatives (from Delta = 1e-100 on supp-fig5).
DROP_AREA_OVER_DELTA2_MAX = 1e12


class StaticsError(RuntimeError):
    """A numerical failure of the statics (no branch found, ...); the message diagnoses it."""


def check_statics_scene(scene: Scene) -> None:
    """Refuse (SceneError naming the key and the range) a scene the free-rod statics cannot
    resolve: gravity or a ground, or a rod length or drop area outside the resolved ranges."""
    if scene.effects.gravity > 0.0 or scene.effects.ground:
        raise SceneError(
            "effects",
            {"gravity": scene.effects.gravity, "ground": scene.effects.ground},
            "statics handles the free rod without gravity or ground; set effects.gravity=0 "
            "and effects.ground=false (the contact statics of the strip scene is not built yet)",
        )
    _check_resolved(scene)


def _check_resolved(scene: Scene) -> None:
    lec = math.sqrt(scene.rod.bending_modulus) / math.sqrt(scene.drop.line_tension)
    for key, value, scale, unit in (("rod.length", scene.rod.length, lec, "l_ec"),
                                    ("drop.area", scene.drop.area, lec * lec, "l_ec^2")):
        lo, hi = RESOLVED[key]
        ratio = value / scale if scale > 0.0 else math.inf
        if not (math.isfinite(ratio) and lo <= ratio <= hi):
            low = f"{lo:g} <= " if lo > 0 else ""
            raise SceneError(
                key, value,
                f"the free-rod statics resolves {low}{key} / {unit} <= {hi:g} (l_ec = "
                f"sqrt(B/gamma) = {lec:.6g}; here the ratio is {ratio:.3g}): rescale the "
                "scene or change B or gamma")
    d = scene.drop
    delta2 = d.wetted_length * d.wetted_length
    if d.area > DROP_AREA_OVER_DELTA2_MAX * delta2:
        ratio = d.area / delta2 if delta2 > 0.0 else math.inf
        raise SceneError(
            "drop.wetted_length", d.wetted_length,
            f"the drop model is checked for drop.area / Delta^2 <= "
            f"{DROP_AREA_OVER_DELTA2_MAX:g} (here {ratio:.3g}): "
            f"Delta >= {math.sqrt(d.area / DROP_AREA_OVER_DELTA2_MAX):.4g} is needed")


def problem_for(
    scene: Scene, parameter: str = "drop.wetted_length", N: int | None = None, nodes="lgl"
) -> WetElasticaProblem:
    """The discretized equilibrium problem of a scene, continued in ``parameter``."""
    check_statics_scene(scene)
    if parameter not in PARAMETERS:
        raise SceneError("--param", parameter, f"expected one of {', '.join(PARAMETERS)}")
    if N is None:
        N = scene.numerics.cheb_points or ACCURACY_N[scene.numerics.accuracy]
    if N < 4:
        raise SceneError("numerics.cheb_points", N, "expected at least 4 intervals")
    d = scene.drop
    return WetElasticaProblem(
        N,
        d.wetted_length,
        d.area,
        d.line_tension,
        scene.rod.bending_modulus,
        scene.rod.length,
        d.center,
        parameter,
        nodes,
    )


def newton(problem, u, p, tol=1e-11, max_iter=40, deflate=(), max_step=0.5):
    """Damped, optionally deflated Newton at fixed p (:func:`continuation.deflated_newton`
    on the problem's ``deflation_indices``); the solution, or None if it did not converge."""
    idx = getattr(problem, "deflation_indices", None)
    if idx is None and hasattr(problem, "N"):
        idx = slice(0, problem.N + 1)
    res = deflated_newton(problem, u, p, deflate, tol=tol, max_iter=max_iter,
                          max_step=max_step, indices=idx)
    return res.u if res.converged else None


def admissible_range(scene: Scene, parameter: str) -> tuple[float, float, str, str]:
    """The values of ``parameter`` (others as in the scene) for which the wet interval
    [S1, S2] lies on the rod [0, L] (both dry arms of non-negative length) and every
    length and modulus is positive.

    Returns
    -------
    (lo, hi, lo_name, hi_name)
        ``hi`` may be ``inf``; the names say which condition each end is.
    """
    L, c, D = scene.rod.length, scene.drop.center, scene.drop.wetted_length
    if parameter == "drop.wetted_length":
        hi = 2.0 * min(c, L - c)
        name = ("S1 = 0 and S2 = L: the wet interval covers the rod" if abs(c - 0.5 * L)
                <= 1e-12 * L else ("S1 = 0: the wet interval reaches the rod's end S = 0"
                                   if c < L - c else
                                   "S2 = L: the wet interval reaches the rod's end S = L"))
        return 0.0, hi, "Delta = 0: no wet interval", name
    if parameter == "drop.center":
        return (0.5 * D, L - 0.5 * D, "S1 = 0: the wet interval reaches the rod's end S = 0",
                "S2 = L: the wet interval reaches the rod's end S = L")
    if parameter == "drop.distance_from_end":
        return (0.5 * D, L - 0.5 * D, "S2 = L: the wet interval reaches the rod's end S = L",
                "S1 = 0: the wet interval reaches the rod's end S = 0")
    if parameter == "rod.length":
        return (c + 0.5 * D, math.inf, "S2 = L: the wet interval reaches the rod's end S = L",
                "")
    return 0.0, math.inf, f"{parameter} = 0", ""


def _rebuild_problem(scene: Scene, meta: dict) -> WetElasticaProblem:
    return problem_for(scene, meta["parameter"], meta["N"], meta["nodes"])


def _plot(bs, path=None):
    from elastocap.statics.plot import plot_branch_set

    return plot_branch_set(bs, path)


def contact_note(scene: Scene) -> str:
    """What this model leaves out of a scene with a thickness ("" without one): the
    spectral free rod has no contact."""
    d = scene.rod.thickness
    if not d:
        return ""
    return (f"rod.thickness = {d:g} is not in this model (the spectral free rod, no contact):"
            " states whose dry tails cross are flagged inadmissible; the equilibria with the "
            "rod in contact with itself: elastocap.strip.freerod (docs/guide/statics-search"
            ".md, 'Equilibria with rod self-contact')")


def report_lines(bs) -> list[str]:
    """The free rod's report: one line per located fold, branch point, equal-energy point,
    end on the admissible boundary and unlocated point."""
    out = [f"{bs.scene.name}: {len(bs.branches)} branches in {bs.parameter} over "
           f"[{bs.prange[0]:.6g}, {bs.prange[1]:.6g}] (N={bs.metadata['N']}, "
           f"{bs.metadata['wall_time_s']:.2f} s)"]
    for key in ("range_note", "contact_note"):
        note = bs.metadata.get(key)
        if note:
            out.append(f"  note: {note}")
    for f in bs.folds:
        err = f.get("error_estimate")
        err = "(not estimated)" if err is None else f"± {err:.1e}"
        out.append(f"  fold          {f['value']:.12f}  {err}  measure "
                   f"{f['measure']:+.6f}  stability {f['stability_change']}")
    for b in bs.branch_points:
        out.append(f"  branch point  {b['value']:.12f}            measure {b['measure']:+.6f}  "
                   f"stability {b['stability_change']}")
    for m in bs.maxwell_points:
        out.append(f"  equal energy  {m['value']:.12f}            measures "
                   + ", ".join(f"{v:+.6f}" for v in m["measures"]))
    for e in bs.endpoints:
        if e.get("kind") == "admissible_boundary":
            out.append(f"  branch end    {e['value']:.12f}            on the admissible "
                       f"boundary: {e['reason']}")
    for u in bs.unlocated:
        out.append(f"  NOT LOCATED   {u['kind']} near {u['value']:.6g}: {u['reason']}; "
                   f"{u['what_to_try']}")
    return out


#: The free rod as a model of :class:`elastocap.branchset.BranchSet`.
FREE_ROD = BranchModel("free_rod", _rebuild_problem, _plot, report_lines)


def _settings(scene: Scene, lo: float, hi: float, span: float) -> ContinuationSettings:
    # ds_max = 2% of the range: fine enough to see every fold of supp-fig5 and to draw
    # smooth curves; folds are then located exactly, not read off the steps.
    return ContinuationSettings(
        ds0=0.01 * span,
        ds_min=1e-9 * span,
        ds_max=0.02 * span,
        max_steps=scene.numerics.max_steps,
        p_min=lo,
        p_max=hi,
        direction=0,
        newton_tol=scene.numerics.newton_tol,
        max_turn=0.2,
        check_jacobian=False,
    )


def check_trace_request(scene: Scene, parameter: str = "drop.wetted_length",
                        prange=None) -> None:
    """Raise the :class:`SceneError` that :func:`trace_branches` would raise for this scene,
    parameter and range, without tracing: for a caller that checks its input before it
    reports progress."""
    problem = problem_for(scene, parameter)
    _resolve_range(scene, parameter, prange, problem.get(parameter))


def _resolve_range(scene: Scene, parameter: str, prange, p_scene: float):
    """The search range: the requested (or default) range clipped to the admissible region.

    Returns (lo, hi, note, lo_name, hi_name); the names are set for an end that is the
    admissible boundary (a branch ending there ends on it).
    """
    a_lo, a_hi, lo_name, hi_name = admissible_range(scene, parameter)
    L = scene.rod.length
    if prange is None:
        if parameter == "drop.wetted_length":
            prange = (0.02 * L, L)
        else:
            prange = (0.5 * p_scene, 2.0 * p_scene)
        user = False
    else:
        user = True
    lo, hi = float(prange[0]), float(prange[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise SceneError("--range", list(prange), "expected two finite numbers LO < HI")
    if parameter == "drop.wetted_length" and user and (lo <= 0.0 or hi > L * (1 + 1e-12)):
        raise SceneError("--range", [lo, hi], f"expected 0 < LO < HI <= rod.length = {L}")
    if hi <= a_lo or lo >= a_hi:
        raise SceneError(
            "--range", [lo, hi],
            f"expected a range that meets the admissible region of {parameter}, "
            f"({a_lo:.10g}, {a_hi:.10g}) ({lo_name}; {hi_name or 'unbounded above'})")
    note = ""
    names = ["", ""]
    if lo <= a_lo:
        lo = a_lo + 1e-3 * (hi - a_lo) if a_lo == 0.0 else a_lo
        names[0] = lo_name
    if hi >= a_hi:
        hi = a_hi
        names[1] = hi_name
    if (lo, hi) != (float(prange[0]), float(prange[1])):
        note = (f"range [{prange[0]:.10g}, {prange[1]:.10g}] clipped to the admissible "
                f"region: [{lo:.10g}, {hi:.10g}]")
    if not lo < hi:
        raise SceneError("--range", list(prange), "the admissible part of the range is empty")
    if user:  # the ends must be scenes the statics takes, as --set would check them
        for end in (lo, hi):
            try:
                _check_resolved(scene.with_overrides({parameter: end}))
            except SceneError as err:
                raise SceneError("--range", list(prange),
                                 f"at {parameter} = {end:.10g}: {err}") from None
    return lo, hi, note, names[0], names[1]


def _events(problem: WetElasticaProblem):
    def contact_lines_meet(u, p):
        S = problem.state(u, p)
        return S.d - _CHORD_STOP * S.params["delta"]

    def admissibility(u, p):
        # +1/2 admissible, -1/2 not: the sign change is located to the bisection tolerance
        return problem.observables(u, p)["admissible"] - 0.5

    return {"contact_lines_meet": contact_lines_meet, "admissibility": admissibility}


def _fold_curve_starts(problem, folds, q_param, q0, settings, q_range, p_bounds):
    """Points at q = q0 of the fold curves (in ``q_param``) through the located folds."""
    base = problem.with_(parameter="drop.wetted_length")

    def family(q):
        return base.with_(**{q_param: q})

    fs = ContinuationSettings(
        ds0=0.01, ds_max=0.05, max_steps=800, p_min=q_range[0], p_max=q_range[1],
        direction=0, newton_tol=settings.newton_tol, check_jacobian=False)
    starts, curves = [], []
    for sp in folds:
        try:
            pts, fc = fold_crossings(family, sp, q0, q0, fs, parameter=q_param,
                                     p_bounds=p_bounds)
        except ValueError:
            continue
        curves.append(fc)
        for u, p in pts:
            if settings.p_min <= p <= settings.p_max:
                starts.append((u, p))
    return starts, curves


def trace_branches(
    scene: Scene,
    parameter: str = "drop.wetted_length",
    prange: tuple[float, float] | None = None,
    *,
    N: int | None = None,
    nodes: str = "lgl",
    samples: int = SEARCH_SAMPLES,
    error_estimates: bool = True,
    fold_curve_seeds: bool = True,
) -> BranchSet:
    """Every equilibrium branch of ``scene`` in ``parameter`` over ``prange``.

    Parameters
    ----------
    scene : Scene
        A scene without gravity or ground.
    parameter : str
        Scene key continued (``drop.wetted_length``, ``drop.area``, ``drop.line_tension``,
        ``rod.bending_modulus``, ``rod.length``, ``drop.center``, ``drop.distance_from_end``).
    prange : (lo, hi), optional
        Default for Delta: (0.02 L, L); otherwise 0.5x to 2x the scene's value. Clipped to
        the admissible region (:func:`admissible_range`); the clipping is noted in the
        metadata and a branch that reaches a clipped end ends there with a named endpoint.
    N : int, optional
        LGL intervals on the wet part (default from ``numerics``).
    samples : int
        Interior sample values of the search (:class:`continuation.SearchSettings`).
    error_estimates : bool
        Relocate each fold at a finer resolution to estimate its discretization error (a
        fold that cannot be relocated is then reported as unlocated). Without it, folds
        carry ``error_estimate = None``.
    fold_curve_seeds : bool
        For ``drop.wetted_length``: continue every located fold in the drop area and start
        the search again from every crossing of the scene's area (the folds the fold
        curves cross are then found even when no seed reaches their branch).

    Returns
    -------
    BranchSet

    Raises
    ------
    SceneError
        Bad input (a range outside the admissible region, a scene with gravity, ...).
    StaticsError
        No branch was found (the message says what was tried and what to try).
    """
    t0 = time.perf_counter()
    problem = problem_for(scene, parameter, N, nodes)
    p_scene = problem.get(parameter)
    lo, hi, clip_note, lo_name, hi_name = _resolve_range(scene, parameter, prange, p_scene)
    span = hi - lo
    settings = _settings(scene, lo, hi, span)
    events = _events(problem)
    p_start = p_scene if lo <= p_scene <= hi else 0.5 * (lo + hi)
    u_flat = np.zeros(problem.N + 2)
    search = BranchSearch(
        problem, settings,
        SearchSettings(samples=samples, sample_values=(p_start,), max_newton=25,
                       newton_tol=settings.newton_tol, match_radius=0.2),
        starts=[(u_flat, p_start)], events=events, stop_on=["contact_lines_meet"],
        parameter=parameter)
    res = search.run()
    curves = []
    n_fold_starts = 0
    if fold_curve_seeds and parameter == "drop.wetted_length":
        # located folds, not pitchfork tips (a turn in the step of a branch point, which
        # _collect_special_points reports as the branch point): their curve in the area
        # would be a curve of pitchforks
        folds = [sp for br in res.branches for sp in br.folds
                 if sp.located and sp.index not in {q.index for q in br.branch_points}]
        q0 = problem.get("drop.area")
        starts, curves = _fold_curve_starts(problem, _distinct(folds), "drop.area", q0,
                                            settings, (0.25 * q0, 4.0 * q0), (lo, hi))
        fresh = [(u, p) for u, p in starts
                 if not any(abs(p - sp.p) <= 1e-8 * (1 + abs(p)) for sp in folds)]
        n_fold_starts = len(fresh)
        if fresh:
            search.extend(fresh)
    if not res.branches:
        st = res.stats
        raise StaticsError(
            f"no equilibrium branch of {scene.name} found in {parameter} over "
            f"[{lo:.10g}, {hi:.10g}]: the flat start and {st['seeds_tried']} deflated seeds "
            f"at {len(res.samples)} sample values all failed (newton_tol="
            f"{settings.newton_tol:.1e}, N={problem.N}). "
            + ("; ".join(st["notes"][:3]) + ". " if st["notes"] else "")
            + "Try a looser numerics.newton_tol (the default is 1e-11), another "
            "numerics.cheb_points, or a narrower --range.")
    result = BranchSet(scene, parameter, (lo, hi), problem)
    result.branches = res.branches
    for k, o in enumerate(res.origins):
        result.labels.append("primary" if o["how"] == "start" and o.get("start") == 0
                             and k == 0 else f"branch {k}")
    _collect_special_points(result, error_estimates, (lo_name, hi_name))
    result.metadata = {
        "model": "free_rod",
        "scene": scene.data,
        "scene_name": scene.name,
        "parameter": parameter,
        "range": [lo, hi],
        "range_note": clip_note,
        "contact_note": contact_note(scene),
        "admissible_region": list(admissible_range(scene, parameter)[:2]),
        "N": problem.N,
        "nodes": nodes,
        "newton_tol": settings.newton_tol,
        "locate_tol": settings.locate_tol,
        "search": {**res.to_dict(), "fold_curve_starts": n_fold_starts,
                   "fold_curves": len(curves)},
        "error_estimates": bool(error_estimates),
        # the dry arms are straight and unloaded: these keys only move them
        "equilibrium_independent_of_parameter": parameter
        in ("rod.length", "drop.center", "drop.distance_from_end"),
        "version": __version__,
        "wall_time_s": time.perf_counter() - t0,
    }
    return result


def _distinct(folds):
    out = []
    for sp in folds:
        if not any(abs(sp.p - o.p) <= 1e-8 * (1 + abs(sp.p))
                   and np.max(np.abs(sp.u - o.u)) < 1e-6 for o in out):
            out.append(sp)
    return out


def _stability_change(br: Branch, idx: int) -> str:
    a = int(br.stability[max(idx - 1, 0)])
    b = int(br.stability[min(idx, len(br) - 1)])
    return f"{a}->{b}"


def _fold_error(problem: WetElasticaProblem, sp) -> tuple[float | None, str]:
    """|p_N - p_N2| with N2 = N + max(8, N/2): the fold relocated at a finer resolution.

    For spectral convergence the finer value is far more accurate, so this difference
    estimates (slightly over-estimates) the error of the value reported at N. Returns
    (estimate, "") or (None, reason).
    """
    N2 = problem.N + max(8, problem.N // 2)
    fine = problem.with_(N=N2)
    Mi = problem.interp_matrix(fine.xi)
    th = Mi @ sp.u[: problem.N + 1]
    u2 = np.concatenate([th, [0.0]])
    v = sp.data.get("kernel")
    v2 = None
    if v is not None and len(v) >= problem.N + 1:
        v2 = np.concatenate([Mi @ np.asarray(v)[: problem.N + 1], [0.0]])
    fine_sp = locate_fold(fine, u2, sp.p, v=v2)
    if not fine_sp.located:
        return None, (f"the fold did not relocate at the finer resolution N={N2} "
                      f"({fine_sp.data.get('message', '')})")
    return abs(fine_sp.p - sp.p), ""


def _transversality(problem, u, p, kernel) -> float:
    """|psi . F_p| / (|psi| |F_p|) at a singular point (psi: left null vector of F_u).

    Non-zero at a fold (F_p is not in the range of F_u), zero at a branch point.
    """
    J = problem.jacobian(u, p)
    Fp = problem.dfdp(u, p)
    nFp = float(np.linalg.norm(Fp))
    if nFp == 0.0:
        return 0.0
    # the left null vector of F_u: the smallest left singular vector
    Uu, _sv, _ = np.linalg.svd(J)
    psi = Uu[:, -1]
    return abs(float(psi @ Fp)) / nFp


def _obs(problem, sp):
    return problem.observables(sp.u, sp.p) if sp.u is not None else {}


def _num(v):
    """A float, or None for NaN/inf (JSON numbers are numbers or null)."""
    v = float(v)
    return v if math.isfinite(v) else None


def _collect_special_points(result: BranchSet, error_estimates: bool, end_names) -> None:
    problem = result.problem
    lo, hi = result.prange
    unlocated = []
    for b, br in enumerate(result.branches):
        for sp in br.special_points:
            obs = _obs(problem, sp)
            meas = _num(obs.get("measure", math.nan))
            if sp.kind == "fold":
                entry = {"value": float(sp.p), "measure": meas,
                         "energy": _num(obs.get("energy", math.nan)),
                         "stability_change": _stability_change(br, sp.index),
                         "located": True, "branch": b}
                reason, hint = "", ""
                tip = any(q.kind == "branch_point" and q.index == sp.index
                          for q in br.special_points)
                if tip:
                    # p turns in the same step as a branch point: a pitchfork seen from its
                    # bifurcating branch (fold and branch point in one), not a fold
                    reason = ("a branch point, not a fold: the branch turns in the same step "
                              "as it crosses a branch point (a pitchfork seen from its "
                              "bifurcating branch)")
                    hint = "the branch point is located on the branch it bifurcates from"
                    entry["kind"] = "branch_point"
                elif not sp.located:
                    reason = ("the fold was bracketed but its Newton did not converge: "
                              + sp.data.get("message", "no message"))
                    hint = ("try a finer numerics.cheb_points or a narrower --range around "
                            f"{sp.p:.6g}")
                else:
                    tr = _transversality(problem, sp.u, sp.p, sp.data.get("kernel"))
                    entry["transversality"] = tr
                    if tr < FOLD_TRANSVERSALITY:
                        reason = (f"the singular point is a branch point, not a fold "
                                  f"(transversality |psi.F_p|/|F_p| = {tr:.1e})")
                        hint = "it is listed with the branch points"
                        result.branch_points.append({
                            "value": float(sp.p), "measure": meas,
                            "stability_change": _stability_change(br, sp.index),
                            "located": True, "branch": b})
                    elif error_estimates:
                        err, why = _fold_error(problem, sp)
                        if err is None:
                            reason = why
                            hint = ("try a finer numerics.cheb_points (e.g. "
                                    f"{problem.N + 16}) or a narrower --range around "
                                    f"{sp.p:.6g}")
                        else:
                            entry["error_estimate"] = err
                    else:
                        entry["error_estimate"] = None
                if reason:
                    unlocated.append({"kind": entry.get("kind", "fold"), "value": float(sp.p),
                                      "measure": meas, "branch": b, "reason": reason,
                                      "what_to_try": hint})
                else:
                    result.folds.append(entry)
            elif sp.kind == "branch_point":
                if not sp.located:
                    unlocated.append({"kind": "branch_point", "value": float(sp.p),
                                      "measure": meas, "branch": b,
                                      "reason": "bracketed by a sign change of the bordered "
                                      "determinant, not located",
                                      "what_to_try": "a finer numerics.cheb_points or a "
                                      "narrower --range"})
                    continue
                result.branch_points.append(
                    {
                        "value": float(sp.p),
                        "measure": meas,
                        "stability_change": _stability_change(br, sp.index),
                        "located": True,
                        "branch": b,
                    }
                )
            elif sp.kind == "event" and sp.name == "admissibility":
                # where the drawn shape starts or stops crossing itself or the interface
                result.admissibility_changes.append(
                    {
                        "value": float(sp.p),
                        "measure": meas,
                        "precision": _num(sp.precision),
                        "branch": b,
                    }
                )
            elif sp.kind == "endpoint" or (sp.kind == "event" and sp.name == "contact_lines_meet"):
                if sp.kind == "event":
                    kind, reason = "contact_lines_meet", "contact lines meet"
                elif sp.p == hi and end_names[1]:
                    kind, reason = "admissible_boundary", end_names[1]
                elif sp.p == lo and end_names[0]:
                    kind, reason = "admissible_boundary", end_names[0]
                elif sp.p in (lo, hi):
                    kind, reason = "range_end", "the end of the search range"
                else:
                    kind, reason = "endpoint", br.message
                result.endpoints.append(
                    {"value": float(sp.p), "measure": meas, "kind": kind, "reason": reason,
                     "branch": b}
                )
    _merge_pitchfork_tips(result, unlocated)
    # dedupe mirror images / the same point reached from two branches
    result.folds = _dedupe(result.folds)
    result.admissibility_changes = _dedupe(result.admissibility_changes)
    result.branch_points = _dedupe(result.branch_points)
    result.unlocated = _dedupe(unlocated)
    result.folds.sort(key=lambda f: f["value"])
    result.maxwell_points = _maxwell_points(result)


def _merge_pitchfork_tips(result: BranchSet, unlocated: list) -> None:
    """A pitchfork seen from its bifurcating branch: that branch turns there (a fold in p
    that is no fold of the scene) and its branch point is degenerate (fold and branch point
    in one), so neither is located well. Where a branch point located on another branch
    lies within the bracket, the points of the bifurcating branch are that branch point:
    they are dropped (the located value is kept)."""
    tips = set()
    for b, br in enumerate(result.branches):
        fold_steps = {sp.index for sp in br.folds}
        for sp in br.branch_points:
            if sp.index in fold_steps:
                tips.add((b, round(float(sp.p), 12)))
    good = [f for f in result.branch_points if (f["branch"], round(f["value"], 12)) not in tips]
    span = result.prange[1] - result.prange[0]

    def near_good(f, width):
        return any(g["branch"] != f["branch"] and abs(g["value"] - f["value"]) <= width
                   for g in good)

    result.branch_points = [
        f for f in result.branch_points
        if (f["branch"], round(f["value"], 12)) not in tips or not near_good(f, 1e-3 * span)]
    keep = []
    for f in unlocated:
        br = result.branches[f["branch"]]
        # the bracketing step's arclength bounds the distance to the point
        width = next((2.0 * max(sp.precision if math.isfinite(sp.precision) else 0.0,
                                 float(br.ds[min(sp.index, len(br) - 1)]))
                      for sp in br.special_points
                      if sp.kind in ("fold", "branch_point") and sp.p == f["value"]), 0.0)
        if not near_good(f, width + 1e-9):
            keep.append(f)
    unlocated[:] = keep


def _dedupe(points):
    out = []
    for f in points:
        if not any(
            abs(f["value"] - g["value"]) <= 1e-8 * max(1.0, abs(g["value"]))
            and abs((f["measure"] or 0.0) - (g["measure"] or 0.0)) <= 1e-6
            and f.get("kind") == g.get("kind")
            for g in out
        ):
            out.append(f)
    return out


def stable_runs(br: Branch):
    """Index ranges [a, b] of consecutive stable points along which p is monotone."""
    runs = []
    n = len(br)
    i = 0
    while i < n:
        if br.stability[i] != 0:
            i += 1
            continue
        j = i
        while j + 1 < n and br.stability[j + 1] == 0:
            if j > i and (br.p[j + 1] - br.p[j]) * (br.p[j] - br.p[j - 1]) < 0:
                break
            j += 1
        if j > i:
            runs.append((i, j))
        i = j + 1
    return runs


def solve_on_run(problem, br, i, j, p):
    """The state of branch ``br`` at parameter ``p`` within the monotone run [i, j]."""
    ps = br.p[i : j + 1]
    order = np.argsort(ps)
    ps = ps[order]
    us = br.u[i : j + 1][order]
    k = int(np.clip(np.searchsorted(ps, p), 1, len(ps) - 1))
    w = 0.0 if ps[k] == ps[k - 1] else (p - ps[k - 1]) / (ps[k] - ps[k - 1])
    return newton(problem, (1 - w) * us[k - 1] + w * us[k], p, 1e-12)


def _energy_gap(problem, run_a, run_c, p):
    ua = solve_on_run(problem, *run_a, p)
    uc = solve_on_run(problem, *run_c, p)
    if ua is None or uc is None:
        return math.nan
    return problem.energy(ua, p) - problem.energy(uc, p)


def _maxwell_points(result: BranchSet) -> list:
    """Parameter values where two stable equilibria have equal energy (the global minimum
    passes from one branch to the other), located by Brent on Newton-corrected energies."""
    problem = result.problem
    runs = [
        (b, (br, i, j))
        for b, br in enumerate(result.branches)
        if br.u is not None
        for i, j in stable_runs(br)
    ]
    out = []
    for a in range(len(runs)):
        for c in range(a + 1, len(runs)):
            (ba, ra), (bc, rc) = runs[a], runs[c]
            pa = ra[0].p[ra[1] : ra[2] + 1]
            pc = rc[0].p[rc[1] : rc[2] + 1]
            lo, hi = max(pa.min(), pc.min()), min(pa.max(), pc.max())
            if not lo < hi:
                continue
            samples = np.linspace(lo, hi, 9)
            vals = [_energy_gap(problem, ra, rc, p) for p in samples]
            finite = [v for v in vals if math.isfinite(v)]
            if finite and max(abs(v) for v in finite) < 1e-9:
                continue  # mirror images: equal energies everywhere
            for k in range(len(samples) - 1):
                v0, v1 = vals[k], vals[k + 1]
                if not (math.isfinite(v0) and math.isfinite(v1) and v0 * v1 < 0):
                    continue
                pm = brentq(
                    lambda p, ra=ra, rc=rc: _energy_gap(problem, ra, rc, p),
                    samples[k],
                    samples[k + 1],
                    xtol=1e-13,
                    rtol=1e-14,
                )
                ua = solve_on_run(problem, *ra, pm)
                uc = solve_on_run(problem, *rc, pm)
                out.append(
                    {
                        "value": float(pm),
                        "energy": float(problem.energy(ua, pm)),
                        "branches": [ba, bc],
                        "measures": [
                            float(problem.observables(ua, pm)["measure"]),
                            float(problem.observables(uc, pm)["measure"]),
                        ],
                    }
                )
    return out


def find_folds(scene: Scene, parameter: str = "drop.wetted_length", prange=None, **kw) -> list:
    """The located folds of every branch (see :func:`trace_branches`; the points that could
    not be located are in ``trace_branches(...).unlocated``)."""
    return trace_branches(scene, parameter, prange, **kw).folds
