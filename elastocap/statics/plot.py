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


def _legend_handles(bs, drawn_colors, extra=(), grey=(True, False)):
    """One legend entry per drawn branch colour, per line style and per marker kind present;
    ``grey``: the stabilities (True: stable) of the inadmissible segments drawn."""
    from matplotlib.lines import Line2D

    hs = [Line2D([], [], color=col, lw=2.0, label=lab) for lab, col in drawn_colors]
    hs += [
        Line2D([], [], color="k", lw=2.0, ls="-", label="stable"),
        Line2D([], [], color="k", lw=1.2, ls="--", label="unstable"),
    ]
    if True in grey:
        hs.append(Line2D([], [], color="0.6", lw=2.0, ls="-",
                         label="stable, inadmissible (crossing)"))
    if False in grey:
        hs.append(Line2D([], [], color="0.6", lw=1.2, ls="--",
                         label="unstable, inadmissible (crossing)"))
    if bs.folds:
        hs.append(Line2D([], [], ls="", marker="X", color="k", ms=7, label="✕ fold"))
    if bs.branch_points:
        hs.append(Line2D([], [], ls="", marker="s", mfc="w", mec="k", ms=6,
                         label="□ branch point"))
    if bs.maxwell_points:
        hs.append(Line2D([], [], ls=":", marker="D", color="tab:orange", ms=5, lw=0.8,
                         label="◆ equal energy (Maxwell)"))
    return hs + list(extra)


def _fold_labels(ax, folds):
    """Label each fold with its value to 4 decimals, staggered so that labels never overlap."""
    texts = []
    for k, f in enumerate(sorted(folds, key=lambda f: f["value"])):
        err = f.get("error_estimate")
        tail = f" ± {err:.0e}" if err is not None and err == err and err > 0 else ""
        texts.append(
            ax.annotate(
                f"fold Δ = {f['value']:.4f}{tail}",
                (f["value"], f["measure"]),
                textcoords="offset points",
                xytext=(-8, -14 - 11 * k),
                fontsize=7,
                ha="right",
                va="top",
                bbox={"boxstyle": "round,pad=0.15", "fc": "w", "ec": "none", "alpha": 0.8},
            )
        )
    return texts


def plot_branch_set(bs, path=None, y="measure", insets=4, title=None, extra_legend=()):
    """Plot a :class:`~elastocap.statics.branches.BranchSet`; save to ``path`` if given.

    Parameters
    ----------
    y : str
        Observable on the vertical axis (default the encapsulation measure).
    insets : int
        Number of equilibrium shapes drawn below the diagram (on stable, admissible points),
        each marked on its curve by the letter of its panel.
    title : str, optional
    extra_legend : sequence of matplotlib artists
        More legend entries (for what a caller draws on top).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from elastocap.figure import new_figure

    if insets > 0:
        fig = new_figure((8.0, 7.4))
        gs = fig.add_gridspec(2, max(insets, 1), height_ratios=[3.2, 1.0], hspace=0.25)
        ax = fig.add_subplot(gs[0, :])
        inset_axes = [fig.add_subplot(gs[1, k]) for k in range(insets)]
    else:
        fig = new_figure((8.0, 5.6))
        ax = fig.add_subplot()
        inset_axes = []
    drawn = []
    grey = set()  # stabilities of the inadmissible (grey) segments drawn
    for b, (br, lab) in enumerate(zip(bs.branches, bs.labels, strict=True)):
        if not len(br):
            continue
        col = _COLORS[b % len(_COLORS)]
        yv = br.observables[y]
        stable = br.stability == 0
        adm = br.observables.get("admissible", np.ones(len(br))) > 0.5
        coloured = False
        for i, j, st, ad in _segments(br.p, yv, stable, adm):
            ax.plot(
                br.p[i : j + 1],
                yv[i : j + 1],
                ls="-" if st else "--",
                color=col if ad else "0.6",
                lw=2.0 if st else 1.2,
            )
            coloured |= ad and j > i
            if not ad and j > i:
                grey.add(st)
        if coloured:  # a legend entry only for a branch with a visible coloured line
            drawn.append((lab, col))
    for f in bs.folds:
        ax.plot(f["value"], f["measure"], "X", color="k", ms=7, zorder=5)
    _fold_labels(ax, bs.folds)
    for bp in bs.branch_points:
        ax.plot(bp["value"], bp["measure"], "s", mfc="w", mec="k", ms=6, zorder=5)
    for m in bs.maxwell_points:
        for meas in m["measures"]:
            ax.plot(m["value"], meas, "D", color="tab:orange", ms=5, zorder=5)
        ax.axvline(m["value"], color="tab:orange", lw=0.6, ls=":")
    ax.set_xlabel(_axis_label(bs.parameter))
    ax.set_ylabel(
        r"encapsulation measure  $(\theta(L) - \theta(0))/\pi$" if y == "measure" else y
    )
    ax.set_title(title or f"{bs.scene.name}: equilibria", fontsize=9)
    ax.grid(alpha=0.25)
    ax.legend(handles=_legend_handles(bs, drawn, extra_legend, grey), fontsize=7,
              loc="upper left")
    _add_insets(ax, inset_axes, bs, y)
    if path is not None:
        fig.savefig(path, bbox_inches="tight")
    return fig


def _axis_label(parameter):
    return {
        "drop.wetted_length": r"wetted length $\Delta$",
        "drop.area": r"drop area $A$",
        "drop.line_tension": r"line tension $\gamma$",
        "rod.bending_modulus": r"bending modulus $B$",
        "rod.length": r"rod length $L$",
        "drop.center": r"drop centre $S_c$",
        "drop.distance_from_end": r"distance from the end $x$",
    }.get(parameter, parameter)


def _symbol(parameter):
    """The parameter's symbol in plain text, for panel titles such as "Δ = 4.60"."""
    return {
        "drop.wetted_length": "Δ",
        "drop.area": "A",
        "drop.line_tension": "γ",
        "rod.bending_modulus": "B",
        "rod.length": "L",
        "drop.center": "S_c",
        "drop.distance_from_end": "x",
    }.get(parameter, parameter)


def _add_insets(ax, inset_axes, bs, y):
    """Shapes on stable admissible points spread over the branches, in the panels below the
    diagram; each point is marked on its curve by its panel's letter (no leader lines)."""
    n = len(inset_axes)
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
        for a in inset_axes:
            a.axis("off")
        return
    # pick n spread in (p, y)
    pts = np.array([[bs.branches[b].p[i], bs.branches[b].observables[y][i]] for b, i in cands])
    span = np.ptp(pts, axis=0) + 1e-12
    chosen = [0]
    while len(chosen) < min(n, len(cands)):
        d = np.min([np.hypot(*((pts - pts[c]) / span).T) for c in chosen], axis=0)
        chosen.append(int(np.argmax(d)))
    chosen.sort(key=lambda c: tuple(pts[c]))  # panels left to right by parameter
    problem = bs.problem
    name = _symbol(bs.parameter)
    for k, ax_in in enumerate(inset_axes):
        if k >= len(chosen):
            ax_in.axis("off")
            continue
        b, i = cands[chosen[k]]
        br = bs.branches[b]
        x0, y0 = pts[chosen[k]]
        letter = "abcdefghij"[k]
        draw_shape(ax_in, problem, br.u[i], float(br.p[i]), color=_COLORS[b % len(_COLORS)])
        ax_in.set_title(f"({letter})  {name} = {br.p[i]:.2f}", fontsize=7)
        ax.plot(x0, y0, "o", ms=11, mfc="w", mec=_COLORS[b % len(_COLORS)], zorder=6)
        ax.text(x0, y0, letter, ha="center", va="center", fontsize=7, zorder=7)
