"""The bifurcation diagram of a BranchSet: measure against the parameter, with shape insets.

Stable parts solid, unstable dashed, inadmissible points (the rod or the interface crossing)
greyed, folds as filled circles, branch points as squares, Maxwell points as diamonds.
"""

from __future__ import annotations

import numpy as np

from elastocap.statics.shape import full_shape

__all__ = ["draw_shape", "plot_branch_set"]

_COLORS = [
    "tab:blue",
    "tab:red",
    "tab:green",
    "tab:purple",
    "tab:orange",
    "tab:brown",
    "tab:pink",
    "tab:olive",
    "tab:cyan",
]


def draw_shape(ax, problem, u, p, color="k", drop_color="tab:blue", ground=False):
    """Draw the rod, the drop (filled) and its interface on ``ax`` (equal aspect)."""
    shp = full_shape(problem, u, p)
    rod, iface = shp["rod"], shp["interface"]
    # the drop region: interface from x1 to x2, then the wet rod back from x2 to x1
    s = shp["s"]
    prm = problem.params_at(p)
    s1 = prm["center"] - 0.5 * prm["delta"]
    s2 = prm["center"] + 0.5 * prm["delta"]
    wet = rod[(s >= s1 - 1e-12) & (s <= s2 + 1e-12)]
    poly = np.vstack([iface, wet[::-1]])
    ax.fill(poly[:, 0], poly[:, 1], color=drop_color, alpha=0.35, lw=0)
    ax.plot(iface[:, 0], iface[:, 1], color=drop_color, lw=0.8)
    ax.plot(rod[:, 0], rod[:, 1], color=color, lw=1.6, solid_capstyle="round")
    ax.set_aspect("equal")
    ax.axis("off")


def _segments(p, y, stable, admissible):
    """Split a branch into runs of equal (stable, admissible) flags."""
    runs = []
    start = 0
    for i in range(1, len(p) + 1):
        if i == len(p) or stable[i] != stable[start] or admissible[i] != admissible[start]:
            j = min(i, len(p) - 1)
            runs.append((start, j, bool(stable[start]), bool(admissible[start])))
            start = i
    return runs


def plot_branch_set(bs, path=None, y="measure", insets=4, title=None):
    """Plot a :class:`~elastocap.statics.branches.BranchSet`; save to ``path`` if given.

    Parameters
    ----------
    y : str
        Observable on the vertical axis (default the encapsulation measure).
    insets : int
        Number of equilibrium shapes drawn as insets (on stable, admissible points).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8.0, 5.6), dpi=130)
    for b, (br, lab) in enumerate(zip(bs.branches, bs.labels, strict=True)):
        if not len(br):
            continue
        col = _COLORS[b % len(_COLORS)]
        yv = br.observables[y]
        stable = br.stability == 0
        adm = br.observables.get("admissible", np.ones(len(br))) > 0.5
        first = True
        for i, j, st, ad in _segments(br.p, yv, stable, adm):
            ax.plot(
                br.p[i : j + 1],
                yv[i : j + 1],
                ls="-" if st else "--",
                color=col if ad else "0.6",
                lw=2.0 if st else 1.2,
                label=lab if first else None,
            )
            first = False
    for f in bs.folds:
        ax.plot(f["value"], f["measure"], "X", color="k", ms=7, zorder=5)
        ax.annotate(
            f"fold Δ={f['value']:.8f}",
            (f["value"], f["measure"]),
            textcoords="offset points",
            xytext=(-10, -16),
            fontsize=7,
            ha="right",
        )
    for bp in bs.branch_points:
        ax.plot(bp["value"], bp["measure"], "s", mfc="w", mec="k", ms=6, zorder=5)
    for m in bs.maxwell_points:
        for meas in m["measures"]:
            ax.plot(m["value"], meas, "D", color="tab:orange", ms=5, zorder=5)
        ax.axvline(m["value"], color="tab:orange", lw=0.6, ls=":")
    ax.set_xlabel(_axis_label(bs.parameter))
    ax.set_ylabel("encapsulation measure  (θ(L) − θ(0)) / π" if y == "measure" else y)
    ax.set_title(
        title or f"{bs.scene.name}: equilibria (solid stable, dashed unstable, grey inadmissible)",
        fontsize=9,
    )
    ax.grid(alpha=0.25)
    ax.legend(fontsize=7, loc="upper left")
    _add_insets(fig, ax, bs, y, insets)
    if path is not None:
        fig.savefig(path, bbox_inches="tight")
    return fig


def _axis_label(parameter):
    return {
        "drop.wetted_length": "wetted length Δ",
        "drop.area": "drop area A",
        "drop.line_tension": "line tension γ",
        "rod.bending_modulus": "bending modulus B",
        "rod.length": "rod length L",
        "drop.center": "drop centre",
        "drop.distance_from_end": "distance from the end x",
    }.get(parameter, parameter)


def _add_insets(fig, ax, bs, y, n):
    """Shapes on stable admissible points spread over the branches."""
    if n <= 0:
        return
    cands = []
    for b, br in enumerate(bs.branches):
        if br.u is None or not len(br):
            continue
        ok = (br.stability == 0) & (br.observables.get("admissible", np.ones(len(br))) > 0.5)
        idx = np.flatnonzero(ok)
        if idx.size:
            for i in idx[np.linspace(0, idx.size - 1, min(3, idx.size)).astype(int)]:
                cands.append((b, int(i)))
    if not cands:
        return
    # pick n spread in (p, y)
    pts = np.array([[bs.branches[b].p[i], bs.branches[b].observables[y][i]] for b, i in cands])
    span = np.ptp(pts, axis=0) + 1e-12
    chosen = [0]
    while len(chosen) < min(n, len(cands)):
        d = np.min([np.hypot(*((pts - pts[c]) / span).T) for c in chosen], axis=0)
        chosen.append(int(np.argmax(d)))
    problem = bs.problem
    for k, c in enumerate(chosen):
        b, i = cands[c]
        br = bs.branches[b]
        x0, y0 = pts[c]
        ax_in = ax.inset_axes([0.02 + 0.245 * k, 0.62 if k % 2 else 0.05, 0.2, 0.3])
        draw_shape(ax_in, problem, br.u[i], float(br.p[i]), color=_COLORS[b % len(_COLORS)])
        ax_in.set_title(f"{br.p[i]:.2f}", fontsize=6)
        ax.annotate(
            "",
            xy=(x0, y0),
            xycoords="data",
            xytext=(0.5, 0.5),
            textcoords=ax_in.transAxes,
            arrowprops={"arrowstyle": "-", "color": "0.5", "lw": 0.5},
        )

