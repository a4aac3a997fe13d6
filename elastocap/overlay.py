"""Dynamics overlaid on the bifurcation diagram: which equilibrium branch each impact reaches.

For each wetted length Delta an impact is run; its encapsulation measure M(t) is drawn as a
path at that Delta (time running upward along a short slanted segment) and its final state
is classified by the nearest stable equilibrium at the same Delta: distance between the
tangent-angle profiles theta(s) - mean(theta) of the final rod and of each stable static
equilibrium (rotations removed), root mean square over the rod. The run reaches that
equilibrium only when it came to rest within ``REACH_DISTANCE`` of it
(:func:`reached_equilibrium`); otherwise the nearest one is still reported, with the reason.
"""

from __future__ import annotations

import time

import numpy as np

from elastocap.impact import run_impact
from elastocap.scene import Scene
from elastocap.statics.branches import BranchSet, solve_on_run, stable_runs, trace_branches

__all__ = ["REACH_DISTANCE", "classify_final_state", "reached_equilibrium",
           "run_overlay", "stable_equilibria"]

#: Largest shape distance (RMS tangent-angle difference, rad) between a run's final rod and
#: a stable equilibrium for the run to have reached it. The final states of the supp-fig5
#: overlay lie 1.6e-4 to 5.6e-3 from their equilibria (100 edges against the spectral
#: statics), draft runs (50 edges) 6.5e-4 to 6.1e-3; the two stable families at one Delta lie
#: 1 rad and more apart.
REACH_DISTANCE = 0.05


def stable_equilibria(bs: BranchSet, delta: float) -> list[dict]:
    """Every stable equilibrium at ``delta`` (Newton-corrected on the traced branches)."""
    out = []
    P = bs.problem
    for b, br in enumerate(bs.branches):
        if br.u is None:
            continue
        for i, j in stable_runs(br):
            lo, hi = sorted((br.p[i], br.p[j]))
            if not lo <= delta <= hi:
                continue
            u = solve_on_run(P, br, i, j, delta)
            if u is None:
                continue
            obs = P.observables(u, delta)
            if any(
                abs(obs["measure"] - e["measure"]) < 1e-7
                and abs(obs["asymmetry"] - e["asymmetry"]) < 1e-7
                for e in out
            ):
                continue
            out.append(
                {
                    "branch": b,
                    "label": bs.labels[b],
                    "u": u,
                    "measure": obs["measure"],
                    "asymmetry": obs["asymmetry"],
                    "energy": obs["energy"],
                    "admissible": bool(obs["admissible"]),
                }
            )
    return out


def _static_angles(P, u, s):
    """theta at arclengths s of the whole rod (straight dry arms)."""
    prm = P.params
    s1 = prm["center"] - 0.5 * prm["delta"]
    xi = np.clip(2.0 * (s - s1) / prm["delta"] - 1.0, -1.0, 1.0)
    return P.interp_matrix(xi) @ u[: P.N + 1]


def classify_final_state(bs: BranchSet, delta: float, x_final: np.ndarray, equilibria=None):
    """Nearest stable equilibrium (by shape) to a final rod configuration (n+1, 2).

    Returns (equilibrium dict with an added ``distance``, or None if there is none).
    """
    eqs = stable_equilibria(bs, delta) if equilibria is None else equilibria
    if not eqs:
        return None
    P = bs.problem.with_(**{bs.parameter: delta})
    e = np.diff(x_final, axis=0)
    phi = np.unwrap(np.arctan2(e[:, 1], e[:, 0]))
    L = P.params["L"]
    s_mid = (np.arange(len(phi)) + 0.5) * L / len(phi)
    best = None
    for eq in eqs:
        th = _static_angles(P, eq["u"], s_mid)
        d = float(np.sqrt(np.mean(((phi - phi.mean()) - (th - th.mean())) ** 2)))
        if best is None or d < best["distance"]:
            best = {**{k: v for k, v in eq.items() if k != "u"}, "distance": d}
    return best


def reached_equilibrium(bs: BranchSet, delta: float, result, equilibria=None) -> dict:
    """The stable equilibrium an impact run (:class:`~elastocap.impact.ImpactResult`) ended
    on: ``branch_reached`` (its label, or None), ``branch_measure`` and ``shape_distance``
    of the nearest admissible stable equilibrium (``equilibria``: those to compare with,
    default every admissible stable one at ``delta``), and ``reach_note``, why none was
    reached (None when one was): no such equilibrium at ``delta``, the run did not come to
    rest, or its final shape lies further than :data:`REACH_DISTANCE` from every one."""
    if equilibria is None:
        # a state that crosses itself (inadmissible) is no state a rod can rest in
        equilibria = [e for e in stable_equilibria(bs, delta) if e["admissible"]]
    near = classify_final_state(bs, delta, result.simulation.positions[-1], equilibria)
    if near is None:
        return {"branch_reached": None, "branch_measure": None, "shape_distance": None,
                "nearest_branch": None,
                "reach_note": f"no admissible stable equilibrium at Delta = {delta:g}"}
    note = None
    if not result.at_rest:
        note = f"the run did not come to rest ({result.status})"
    elif near["distance"] > REACH_DISTANCE:
        note = (f"the final shape lies {near['distance']:.3g} rad (RMS) from the nearest "
                f"stable equilibrium ({near['label']}), more than {REACH_DISTANCE:g}: "
                "the run rests away from every equilibrium the statics traced")
    return {"branch_reached": None if note else near["label"],
            "branch_measure": near["measure"], "shape_distance": near["distance"],
            "nearest_branch": near["label"], "reach_note": note}


def run_overlay(scene: Scene, deltas, out_dir=None, bs: BranchSet | None = None):
    """Impacts at each Delta, classified against the statics; optional PNG + JSON output.

    Returns
    -------
    dict with ``runs`` (per Delta: outcome, final measure, branch reached, distance...),
    ``branch_set``, ``results`` (the :class:`~elastocap.impact.ImpactResult` of each run)
    and, when ``out_dir`` is given, ``files``.
    """
    t0 = time.perf_counter()
    if bs is None:
        bs = trace_branches(scene, error_estimates=False)
    runs = []
    results = []
    for d in deltas:
        sc = scene.with_overrides({"drop.wetted_length": float(d)})
        res = run_impact(sc)
        runs.append(
            {
                "wetted_length": float(d),
                "outcome": res.outcome,
                "final_measure": res.final_measure,
                **reached_equilibrium(bs, float(d), res),
                "t_end": res.t_end,
                "status": res.status,
                "decided_after_crossing": res.decided_after_crossing,
                "undecided_reason": res.undecided_reason,
            }
        )
        results.append(res)
    out = {
        "runs": runs,
        "branch_set": bs,
        "results": results,
        "wall_time_s": time.perf_counter() - t0,
    }
    if out_dir is not None:
        from elastocap.io import OutputFolder

        folder = OutputFolder(out_dir, f"overlay-{scene.name}", key="out_dir")
        png = folder.savefig(
            lambda path: plot_overlay(bs, runs, results, path), f"overlay-{scene.name}.png"
        )
        out["files"] = [str(png)]
    return out


def plot_overlay(bs, runs, results, path):
    """The statics diagram with each run's M(t) drawn up to its Delta, final states marked.

    Each path runs left to right in time over a short slant that ends at the run's Delta, so
    the final marker sits exactly at the Delta of the run.
    """
    from matplotlib.lines import Line2D

    from elastocap.statics.plot import plot_branch_set

    extra = [
        Line2D([], [], color="k", lw=0.6, alpha=0.6, label="impact: M(t), time left to right"),
        Line2D([], [], ls="", marker="o", ms=7, mfc="k", mec="k", label="● at rest: encapsulated"),
        Line2D([], [], ls="", marker="o", ms=7, mfc="w", mec="k", label="○ at rest: open"),
    ]
    fig = plot_branch_set(
        bs, None, insets=0, title=f"{bs.scene.name}: impacts on the equilibria", extra_legend=extra
    )
    ax = fig.axes[0]
    span = bs.prange[1] - bs.prange[0]
    for run, res in zip(runs, results, strict=True):
        t = res.simulation.times
        m = res.measure_history
        slant = -0.04 * span * (1.0 - t / max(t[-1], 1e-12))
        enc = run["outcome"] == "encapsulated"
        ax.plot(run["wetted_length"] + slant, m, color="k", lw=0.6, alpha=0.6)
        ax.plot(
            run["wetted_length"],
            m[-1],
            "o",
            ms=7,
            mfc="k" if enc else "w",
            mec="k",
            zorder=6,
        )
    _move_fold_labels_below(ax, results)
    fig.savefig(path, bbox_inches="tight")
    return fig


def _move_fold_labels_below(ax, results):
    """Each fold's label moves below every M(t) trace, ending at the fold's Delta: beside
    the fold it would sit on the traces."""
    if not results:
        return
    low = min(float(np.min(res.measure_history)) for res in results)
    labels = sorted((t for t in ax.texts if t.get_text().startswith("fold") and hasattr(t, "xy")),
                    key=lambda t: t.xy[0])
    for k, txt in enumerate(labels):  # staggered, as beside the folds
        x = txt.xy[0]
        txt.xy = (x, low)
        txt.set_position((0, -4 - 11 * k))
        txt.set_horizontalalignment("right")  # clear of a Maxwell line right of the fold
