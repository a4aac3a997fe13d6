"""Dynamics overlaid on the bifurcation diagram: which equilibrium branch each impact reaches.

For each wetted length Delta an impact is run; its encapsulation measure M(t) is drawn as a
path at that Delta (time running upward along a short slanted segment) and its final state
is classified by the nearest stable equilibrium at the same Delta: distance between the
tangent-angle profiles theta(s) - mean(theta) of the final rod and of each stable static
equilibrium (rotations removed), root mean square over the rod.
"""

from __future__ import annotations

import math
import time

import numpy as np

from elastocap.impact import run_impact
from elastocap.scene import Scene, SceneError
from elastocap.statics.branches import BranchSet, solve_on_run, stable_runs, trace_branches

__all__ = ["classify_final_state", "parse_range", "run_overlay", "stable_equilibria"]


def parse_range(text: str, option: str) -> np.ndarray:
    """``LO:HI:N`` -> N values from LO to HI (N = 1: just LO)."""
    parts = str(text).split(":")
    try:
        lo, hi, n = float(parts[0]), float(parts[1]), int(parts[2])
        if len(parts) != 3:
            raise ValueError
    except (ValueError, IndexError):
        raise SceneError(option, text, "expected LO:HI:N, e.g. 2.5:4.5:5") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi and n >= 1):
        raise SceneError(option, text, "expected finite LO <= HI and N >= 1")
    return np.linspace(lo, hi, n) if n > 1 else np.array([lo])


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
        reached = classify_final_state(bs, float(d), res.simulation.positions[-1])
        runs.append(
            {
                "wetted_length": float(d),
                "outcome": res.outcome,
                "final_measure": res.final_measure,
                "branch_reached": None if reached is None else reached["label"],
                "branch_measure": None if reached is None else reached["measure"],
                "shape_distance": None if reached is None else reached["distance"],
                "t_end": res.t_end,
                "status": res.status,
                "decided_after_crossing": res.decided_after_crossing,
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
