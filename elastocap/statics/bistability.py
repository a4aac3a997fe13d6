"""Bistability maps: folds continued in a second scene parameter (two-parameter continuation).

For the free rod without gravity the equilibria depend on two dimensionless groups only,
Delta/l_ec and A/l_ec^2 (the rod length and the drop's position move the straight dry arms
and nothing else, see wet_elastica), so the fold curve in (Delta, A) is the complete
bistability map of the model. The two stable states coexist between the two halves of the
fold curve (the encapsulated branch appears at the left one); the flat branch has no fold
in the range of supp-fig5, so the shaded region (Delta <= L) is where two stable states
coexist. The encapsulated branch also ends where its contact lines meet (statics stops it
there); that end lies beyond Delta = L for supp-fig5.
"""

from __future__ import annotations

import numpy as np

from continuation import ContinuationSettings, continue_fold
from elastocap.scene import Scene, SceneError
from elastocap.statics.branches import BranchSet, problem_for, trace_branches
from elastocap.statics.wet_elastica import PARAMETERS

__all__ = ["admissible_curve", "fold_curve_report", "fold_curves", "plot_bistability"]


def fold_curves(
    scene: Scene, q_param: str = "drop.area", q_range=(0.2, 3.0), bs=None, ds_max: float = 0.05
):
    """Continue every fold of ``scene`` (in Delta) in the scene key ``q_param``.

    A curve ends where its Delta leaves the admissible region (the wet interval reaches an
    end of the rod): a fold beyond it is not a fold of any scene of the family.

    Returns
    -------
    (BranchSet, list of continuation.Branch)
        Each fold curve's ``.p`` is q and ``.observables["p"]`` the fold's Delta.
    """
    if q_param not in PARAMETERS or q_param == "drop.wetted_length":
        raise SceneError(
            "--curve",
            q_param,
            "expected a scene key other than drop.wetted_length: "
            + ", ".join(k for k in PARAMETERS if k != "drop.wetted_length"),
        )
    bs = bs or trace_branches(scene, error_estimates=False)
    P = bs.problem
    curves = []
    seen = []
    # only the folds the branch set reports (located, transversal, not pitchfork tips)
    honest = [f["value"] for f in bs.folds]
    for br in bs.branches:
        for sp in br.folds:
            if (not sp.located or any(abs(sp.p - v) < 1e-8 for v in seen)
                    or not any(abs(sp.p - v) <= 1e-12 * (1 + abs(v)) for v in honest)):
                continue
            seen.append(sp.p)
            q0 = P.get(q_param)

            def family(q, P=P):
                return P.with_(parameter="drop.wetted_length", **{q_param: q})

            settings = ContinuationSettings(
                ds0=0.01,
                ds_max=ds_max,
                max_steps=2000,
                p_min=q_range[0],
                p_max=q_range[1],
                direction=0,
                newton_tol=scene.numerics.newton_tol,
                check_jacobian=False,
            )
            n = P.N + 2

            def boundary(U, q, n=n):
                # the wet interval must lie on the rod: Delta <= 2 min(centre, L - centre)
                prm = P.with_(**{q_param: q}).params
                return 2.0 * min(prm["center"], prm["L"] - prm["center"]) - U[n]

            fc = continue_fold(family, sp, q0, settings, parameter=q_param,
                               events={"admissible_boundary": boundary},
                               stop_on=["admissible_boundary"])
            # two folds of the scene can lie on one curve (on either side of a cusp): the
            # curve continued from the second has the same two ends, and is not a new one
            if not any(_same_ends(P, q_param, fc, other) for other in curves):
                curves.append(fc)
    return bs, curves


def _same_ends(problem, q_param: str, a, b, rtol: float = 1e-8) -> bool:
    """Whether two fold curves have the same two ends in the admissible region (in either
    order), in (q, Delta): the same curve, continued from two of its folds."""
    def ends(fc):
        q, d, _ = admissible_curve(problem, fc, q_param)
        return [(q[0], d[0]), (q[-1], d[-1])] if len(q) else []

    def close(u, v):
        return all(abs(x - y) <= rtol * (1.0 + abs(y)) for x, y in zip(u, v, strict=True))

    ea, eb = ends(a), ends(b)
    if not ea or not eb:
        return False
    (a0, a1), (b0, b1) = ea, eb
    return (close(a0, b0) and close(a1, b1)) or (close(a0, b1) and close(a1, b0))


def _admissible(problem, q_param: str, q: float, delta: float, rtol: float = 1e-12) -> bool:
    """Whether the wet interval of length ``delta`` lies on the rod at ``q_param = q``."""
    prm = problem.with_(**{q_param: float(q)}).params
    return delta <= 2.0 * min(prm["center"], prm["L"] - prm["center"]) * (1 + rtol)


def admissible_curve(problem, curve, q_param: str):
    """The points of a fold curve (from :func:`fold_curves`) inside the admissible region,
    ending exactly on the located boundary crossing where the curve leaves it.

    The continuation stops one step past the boundary (on the step where the event changes
    sign); that point is dropped and the located crossing put in its place.

    Returns
    -------
    (q, delta, extrema)
        Arrays of the curve parameter and of Delta, and the ``(q, Delta)`` of each located
        extremum of q (a cusp) inside the region.
    """
    q, d = curve.p, curve.observables["p"]
    inside = [_admissible(problem, q_param, qv, dv) for qv, dv in zip(q, d, strict=True)]
    ends = [sp for sp in curve.points("event")
            if sp.name == "admissible_boundary" and sp.located and sp.u is not None]
    qs, ds = [], []
    for i in range(len(q)):
        if i > 0 and inside[i] != inside[i - 1]:
            lo, hi = sorted((float(q[i - 1]), float(q[i])))
            cross = [sp for sp in ends if sp.index in (i - 1, i)
                     and lo - 1e-12 * (1 + abs(lo)) <= sp.p <= hi + 1e-12 * (1 + abs(hi))]
            if cross:
                qs.append(float(cross[0].p))
                ds.append(float(cross[0].u[-1]))
        if inside[i]:
            qs.append(float(q[i]))
            ds.append(float(d[i]))
    extrema = [(float(sp.p), float(sp.u[-1])) for sp in curve.folds
               if sp.located and sp.u is not None
               and _admissible(problem, q_param, sp.p, float(sp.u[-1]))]
    return np.array(qs), np.array(ds), extrema


def plot_bistability(scene: Scene, bs: BranchSet, curves, q_param: str, path=None):
    """Fold curves in (Delta, q) inside the admissible region, and shaded the region between
    each curve and the admissible boundary: where two stable states coexist (for supp-fig5
    the open and the encapsulated one; above the arc from the cusp to the curve's end on
    Delta = L only the encapsulated state is stable, left of the curve only the open one). Returns
    the matplotlib Figure (no pyplot state is touched)."""
    from elastocap.figure import new_figure

    fig = new_figure((6.4, 5.6))
    ax = fig.add_subplot()
    P = bs.problem
    q_name = {"drop.area": "drop area $A$"}.get(q_param, q_param)
    sym = {"drop.area": "A"}.get(q_param, q_param)

    def boundary(q):
        prm = P.with_(**{q_param: float(q)}).params
        return 2.0 * min(prm["center"], prm["L"] - prm["center"])

    q_all = []
    for fc in curves:
        q, d, extrema = admissible_curve(P, fc, q_param)
        if len(q) < 2:
            continue
        q_all += [q.min(), q.max()]
        # the region right of the curve up to the admissible boundary: the curve, then back
        # along the boundary from its last q to its first, then to its first point
        qb = np.linspace(q[-1], q[0], 64)
        db = np.array([boundary(v) for v in qb])
        ax.fill(np.concatenate([d, db]), np.concatenate([q, qb]), color="tab:green",
                alpha=0.18, lw=0, label="two stable states coexist (bistable)")
        ax.plot(d, q, color="k", lw=1.6, label="fold curve")
        for qv, dv in extrema:
            ax.plot(dv, qv, "o", color="tab:red", ms=6,
                    label=f"extremum of ${sym}$ on the curve: two folds meet")
    q0 = P.get(q_param)
    lo, hi = (min(q_all + [q0]), max(q_all + [q0]))
    qb = np.linspace(lo, hi, 64)
    L = scene.rod.length
    ax.plot([boundary(v) for v in qb], qb, color="0.4", ls="--", lw=1,
            label=("admissible boundary: the wet interval reaches a rod end"
                   + (f" ($\\Delta = L = {L:g}$)" if all(abs(boundary(v) - L) < 1e-12 * L
                                                       for v in qb) else "")))
    ax.axhline(q0, color="tab:blue", ls=":", lw=1, label=f"the scene: ${sym} = {q0:g}$")
    for f in bs.folds:
        ax.plot(f["value"], q0, "X", color="k", ms=7,
                label="fold of the scene (one-parameter search)")
    # beyond Delta = L there is no rod to wet
    ax.set_xlim(0, 1.02 * L)
    ax.set_xlabel(r"wetted length $\Delta$")
    ax.set_ylabel(q_name)
    ax.set_title(f"{scene.name}: bistability map (folds continued in {q_param})", fontsize=9)
    handles, labels = ax.get_legend_handles_labels()
    uniq = dict(zip(labels, handles, strict=True))
    # below the axes: the legend covers no curve
    ax.legend(uniq.values(), uniq.keys(), fontsize=7, loc="upper center",
              bbox_to_anchor=(0.5, -0.13), ncol=2, frameon=False)
    ax.grid(alpha=0.25)
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, bbox_inches="tight")
    return fig


def _cusp_error(problem, curve, sp, q_param, settings):
    """|q_cusp(N) - q_cusp(N2)|, N2 = N + max(8, N/2): the cusp relocated on the fold curve
    of the finer discretization (a short fold curve through the cusp at N2). Returns
    (estimate, "") or (None, reason)."""
    from continuation import continue_fold, locate_fold

    N, n = problem.N, problem.N + 2
    N2 = N + max(8, N // 2)
    fine = problem.with_(parameter="drop.wetted_length", N=N2)
    Mi = problem.interp_matrix(fine.xi)
    q_c = float(sp.p)
    # a point of the coarse curve a little away from the cusp (the fold is regular there)
    i = max(sp.index - 2, 0)
    U = curve.u[i]
    q_i = float(curve.p[i])
    u2 = np.concatenate([Mi @ U[: N + 1], [0.0]])
    f2 = locate_fold(fine.with_(**{q_param: q_i}), u2, float(U[n]))
    if not f2.located:
        return None, f"the fold near the cusp did not relocate at N={N2}"
    w = abs(q_c - q_i)
    s2 = settings.replace(p_min=q_c - 4 * w - 1e-3, p_max=q_c + 4 * w + 1e-3, direction=0,
                          ds0=min(settings.ds0, w / 4 + 1e-6),
                          ds_max=min(settings.ds_max, w / 2 + 1e-4),
                          ds_min=min(settings.ds_min, 1e-10))

    def family2(q):
        return fine.with_(**{q_param: q})

    fc2 = continue_fold(family2, f2, q_i, s2, parameter=q_param)
    cands = [c for c in fc2.folds if c.located]
    if not cands:
        return None, f"no cusp on the fold curve at N={N2} near {q_param}={q_c:.6g}"
    best = min(cands, key=lambda c: abs(c.p - q_c))
    return abs(best.p - q_c), ""


def fold_curve_report(scene: Scene, q_param: str, q_range, *, ds_max: float = 0.02,
                      error_estimates: bool = True) -> dict:
    """The fold curves of ``scene`` (folds in Delta continued in ``q_param`` over
    ``q_range``), every cusp (extremum of ``q_param`` on a curve) located with an error
    estimate, as plain data (JSON numbers or null).

    Returns
    -------
    dict
        ``scene``, ``parameter`` (Delta), ``curve_parameter``, ``range``, ``curves`` (one
        per curve: q and Delta arrays, end statuses), ``cusps`` (value of q, Delta,
        error_estimate), ``unlocated`` (cusps not confirmed: reason, what to try),
        ``metadata``; and, under the key ``_objects``, the branch set and curves for
        plotting (not JSON).
    """
    import math
    import time

    from elastocap._version import __version__

    t0 = time.perf_counter()
    lo, hi = float(q_range[0]), float(q_range[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
        raise SceneError("--curve", [q_param, lo, hi], "expected KEY LO HI with 0 < LO < HI")
    if q_param not in PARAMETERS or q_param == "drop.wetted_length":
        fold_curves(scene, q_param)  # raises the clear error
    q0 = problem_for(scene).get(q_param)
    if not lo <= q0 <= hi:
        raise SceneError("--curve", [q_param, lo, hi],
                         f"expected a range that contains the scene's {q_param} = {q0:g} "
                         "(the curves start at the scene's folds)")
    bs, curves = fold_curves(scene, q_param, (lo, hi), ds_max=ds_max)
    P = bs.problem
    settings = ContinuationSettings(ds0=0.01, ds_max=ds_max, max_steps=2000, p_min=lo,
                                    p_max=hi, direction=0,
                                    newton_tol=scene.numerics.newton_tol,
                                    check_jacobian=False)
    cusps, unlocated, out_curves = [], [], []
    for k, fc in enumerate(curves):
        # the points inside the admissible region, ending on the located boundary crossing
        qs, ds, _ = admissible_curve(P, fc, q_param)
        qs, ds = qs.tolist(), ds.tolist()
        ends = [sp for sp in fc.points("event") if sp.name == "admissible_boundary"]
        out_curves.append({
            "points": len(qs),
            curve_key(q_param): qs,
            "drop.wetted_length": ds,
            "end_status": fc.metadata.get("end_status"),
            "admissible_boundary": [
                {curve_key(q_param): float(sp.p), "drop.wetted_length": float(sp.u[-1])}
                for sp in ends if sp.located and sp.u is not None],
        })
        for sp in fc.folds:
            delta = float(sp.u[-1]) if sp.u is not None else None
            if delta is not None:
                prm = P.with_(**{q_param: float(sp.p)}).params
                if delta > 2.0 * min(prm["center"], prm["L"] - prm["center"]):
                    continue  # beyond the admissible region: no cusp of a scene
            entry = {"value": float(sp.p), "drop.wetted_length": delta, "curve": k}
            if not sp.located:
                unlocated.append({**entry, "kind": "cusp", "reason": "bracketed, not located",
                                  "what_to_try": "a smaller ds_max or a narrower range"})
                continue
            if error_estimates:
                err, why = _cusp_error(P, fc, sp, q_param, settings)
                if err is None:
                    unlocated.append({**entry, "kind": "cusp", "reason": why,
                                      "what_to_try": "a finer numerics.cheb_points"})
                    continue
                entry["error_estimate"] = float(err)
            else:
                entry["error_estimate"] = None
            if not any(abs(c["value"] - entry["value"]) <= 1e-8 * (1 + abs(entry["value"]))
                       for c in cusps):
                cusps.append(entry)
    cusps.sort(key=lambda c: c["value"])
    return {
        "scene": scene.name,
        "parameter": "drop.wetted_length",
        "curve_parameter": q_param,
        "range": [lo, hi],
        "folds": bs.folds,
        "cusps": cusps,
        "unlocated": unlocated,
        "curves": out_curves,
        "metadata": {"N": P.N, "newton_tol": scene.numerics.newton_tol, "ds_max": ds_max,
                     "scene": scene.data, "version": __version__,
                     "wall_time_s": time.perf_counter() - t0},
        "_objects": (bs, curves),
    }


def curve_key(q_param: str) -> str:
    return q_param
