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
from elastocap.statics.branches import BranchSet, trace_branches
from elastocap.statics.wet_elastica import PARAMETERS

__all__ = ["fold_curves", "plot_bistability"]


def fold_curves(
    scene: Scene, q_param: str = "drop.area", q_range=(0.2, 3.0), bs=None, ds_max: float = 0.05
):
    """Continue every fold of ``scene`` (in Delta) in the scene key ``q_param``.

    Returns
    -------
    (BranchSet, list of continuation.Branch)
        Each fold curve's ``.p`` is q and ``.observables["p"]`` the fold's Delta.
    """
    if q_param not in PARAMETERS or q_param == "drop.wetted_length":
        raise SceneError(
            "--q",
            q_param,
            "expected a scene key other than drop.wetted_length: "
            + ", ".join(k for k in PARAMETERS if k != "drop.wetted_length"),
        )
    bs = bs or trace_branches(scene, error_estimates=False)
    P = bs.problem
    curves = []
    seen = []
    for br in bs.branches:
        for sp in br.folds:
            if not sp.located or any(abs(sp.p - v) < 1e-8 for v in seen):
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
            curves.append(continue_fold(family, sp, q0, settings, parameter=q_param))
    return bs, curves


def plot_bistability(scene: Scene, bs: BranchSet, curves, q_param: str, path=None):
    """Fold curves in (Delta, q), the region where two stable states coexist shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.8), dpi=130)
    L = scene.rod.length
    for fc in curves:
        d = fc.observables["p"]
        q = fc.p
        ax.fill(
            d,
            q,
            color="tab:green",
            alpha=0.18,
            lw=0,
            label="between the folds: the encapsulated state exists",
        )
        ax.plot(d, q, color="k", lw=1.6, label="fold curve")
        for sp in fc.special_points:
            if sp.kind == "fold":  # a fold of the fold curve: an extremum of q (a cusp)
                dv = sp.u[-1] if sp.u is not None else np.nan
                ax.plot(dv, sp.p, "o", color="tab:red", ms=6, label=f"extremum of {q_param}")
    ax.axvline(L, color="0.4", ls="--", lw=1, label=f"Δ = L = {L:g}")
    q0 = bs.problem.get(q_param)
    ax.axhline(q0, color="tab:blue", ls=":", lw=1, label=f"scene: {q_param} = {q0:g}")
    for f in bs.folds:
        ax.plot(f["value"], q0, "X", color="k", ms=7)
    # beyond Delta = L there is no rod to wet
    ax.set_xlim(0, 1.02 * L)
    ax.set_xlabel("wetted length Δ")
    ax.set_ylabel({"drop.area": "drop area A"}.get(q_param, q_param))
    ax.set_title(f"{scene.name}: bistability map (folds continued in {q_param})", fontsize=9)
    handles, labels = ax.get_legend_handles_labels()
    uniq = dict(zip(labels, handles, strict=True))
    ax.legend(uniq.values(), uniq.keys(), fontsize=7, loc="upper left")
    ax.grid(alpha=0.25)
    if path is not None:
        fig.savefig(path, bbox_inches="tight")
    return fig
