"""Frame strips of an impact run, like the paper's Figs 4 and 5: rod, drop, ground."""

from __future__ import annotations

import numpy as np

from elastocap.drop import capillary_energy_and_gradient
from elastocap.geometry import arc_points
from elastocap.impact import ImpactResult

__all__ = ["frame_strip"]


def interface_points(x, s_nodes, area, s1, s2, gamma):
    """Drop interface points (k, 2) of a rod configuration."""
    g = np.zeros_like(x)
    _e, tau, _k = capillary_energy_and_gradient(x, s_nodes, s1, s2, area, gamma, g)
    p1 = np.array([np.interp(s1, s_nodes, x[:, 0]), np.interp(s1, s_nodes, x[:, 1])])
    p2 = np.array([np.interp(s2, s_nodes, x[:, 0]), np.interp(s2, s_nodes, x[:, 1])])
    return arc_points(p1, p2, tau, 80), tau


def _settle_time(times, measures, tol=0.15):
    """First time after which the measure stays within ``tol`` of its final value."""
    far = np.flatnonzero(np.abs(measures - measures[-1]) > tol)
    if far.size == 0:
        return times[-1]
    return times[min(far[-1] + 1, len(times) - 1)]


def _scale_bar(scene, width):
    """A round length near a fifth of the panel width, and its label in the scene's unit."""
    target = 0.2 * width
    bar = max(v for v in (0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0) if v <= max(target, 0.1))
    if scene.effects.gravity > 0:
        unit = r"$\ell_{eg}$"  # units g = mu = B = 1
    elif scene.drop.line_tension == 1.0 and scene.rod.bending_modulus == 1.0:
        unit = r"$\ell_{ec}$"  # units B = gamma = 1
    else:
        unit = "length unit"
    return bar, f"{bar:g} {unit}"


def _frame_indices(times, k, t_show):
    """Indices of k frames evenly spread over [0, t_show] (first and last included)."""
    targets = np.linspace(times[0], t_show, k)
    return sorted({int(np.argmin(np.abs(times - t))) for t in targets})


def frame_strip(
    result: ImpactResult,
    scene,
    path=None,
    k: int = 8,
    crop: float | None = None,
    title: str | None = None,
):
    """Draw ``k`` frames of an impact side by side (same scale in every panel).

    Parameters
    ----------
    result : ImpactResult
        From :func:`elastocap.impact.run_impact`.
    scene : Scene
        The scene of the run (drop area, contact lines, events, ground).
    k : int
        Number of frames, spread over the motion: from t = 0 until the encapsulation
        measure has settled within 0.15 of its final value (plus 50%).
    crop : float, optional
        Show only the part of the rod within this arclength of the free end S = L (the
        paper shows "only a fraction of the strip"); default: the whole rod, or
        x + Delta + 2 for scenes with a ground.
    """
    from elastocap.figure import new_figure

    sim = result.simulation
    times, pos = sim.times, sim.positions
    n = pos.shape[1] - 1
    L = scene.rod.length
    s_nodes = np.linspace(0.0, L, n + 1)
    if crop is None and scene.effects.ground:
        crop = min(L, scene.distance_from_end + scene.drop.wetted_length + 2.0)
    keep = s_nodes >= (L - crop) if crop else np.ones(n + 1, bool)
    t_show = min(times[-1], 1.5 * _settle_time(times, result.measure_history))
    idx = _frame_indices(times, k, t_show)
    cap = np.array([scene.drop.area, scene.drop.s1, scene.drop.s2, scene.drop.line_tension])
    fired = list(sim.events_fired)
    panels = []
    for i in idx:
        while fired and fired[0][0] <= times[i] + 1e-12:
            _, _, j, val = fired.pop(0)
            cap[j] = val
        x = pos[i]
        iface, _tau = interface_points(x, s_nodes, cap[0], cap[1], cap[2], cap[3])
        wet = (s_nodes >= cap[1]) & (s_nodes <= cap[2])
        p1 = np.array([np.interp(cap[1], s_nodes, x[:, 0]), np.interp(cap[1], s_nodes, x[:, 1])])
        p2 = np.array([np.interp(cap[2], s_nodes, x[:, 0]), np.interp(cap[2], s_nodes, x[:, 1])])
        drop = np.vstack([iface, p2[None], x[wet][::-1], p1[None]])
        panels.append((times[i], x[keep], drop, iface))
    allpts = np.vstack([np.vstack([r, d]) for _, r, d, _ in panels])
    lo, hi = allpts.min(axis=0), allpts.max(axis=0)
    pad = 0.05 * max(hi - lo) + 1e-9
    if scene.effects.ground:
        lo[1] = min(lo[1], -0.1 * (hi[1] - lo[1] + 1e-9))
    w = hi[0] - lo[0] + 2 * pad
    hgt = hi[1] - lo[1] + 2 * pad
    ncol = min(len(panels), 4)
    nrow = -(-len(panels) // ncol)
    pw = 2.4  # inches a panel
    fig = new_figure((pw * ncol, nrow * (pw * min(hgt / w, 1.2) + 0.3) + 0.3))
    axes = fig.subplots(nrow, ncol, squeeze=False)
    bar, unit = _scale_bar(scene, w)
    for a in axes.flat[len(panels):]:
        a.axis("off")
    for k, (ax, (t, rod, drop, iface)) in enumerate(zip(axes.flat, panels, strict=False)):
        ax.fill(drop[:, 0], drop[:, 1], color="tab:blue", alpha=0.35, lw=0)
        ax.plot(iface[:, 0], iface[:, 1], color="tab:blue", lw=0.8)
        ax.plot(rod[:, 0], rod[:, 1], color="k", lw=1.5, solid_capstyle="round")
        if scene.effects.ground:
            ax.axhline(0.0, color="0.4", lw=0.8)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"$t$ = {t:.2f}", fontsize=8, loc="left", pad=2)
        if k == 0:  # the same scale in every panel: one bar, in the first
            # top right, where the first frame (the rod flat, at rest) leaves room
            x0 = hi[0] + pad - 0.05 * w - bar
            y0 = hi[1] + pad - 0.1 * hgt
            ax.plot([x0, x0 + bar], [y0, y0], color="k", lw=2.0, solid_capstyle="butt")
            ax.text(x0 + 0.5 * bar, y0 - 0.03 * hgt, unit, ha="center", va="top", fontsize=7)
    fig.suptitle(
        title or rf"{scene.name}: $\Delta$ = {scene.drop.wetted_length:.3g}, "
        f"outcome {result.outcome}",
        fontsize=9,
    )
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, bbox_inches="tight")
    return fig
