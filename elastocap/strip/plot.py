"""Drawing strip branches: the encapsulation measure against the parameter, with shapes."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from elastocap.strip.shape import strip_full_shape

__all__ = ["plot_strip_branch_set"]


def plot_strip_branch_set(bs, path=None, y="measure", insets=3):
    """Branches of a :class:`~elastocap.strip.branches.StripBranchSet` (solid stable,
    dashed unstable), topology endpoints (o), folds (x), and a few shapes on the ground.

    Returns the matplotlib figure; writes it to ``path`` when given.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, axs) = plt.subplots(1, 2, figsize=(10, 4), gridspec_kw={"width_ratios": [3, 2]})
    for b, br in enumerate(bs.branches):
        if not len(br):
            continue
        yv = br.observables[y]
        stable = br.stability == 0
        for mask, ls in ((stable, "-"), (~stable, "--")):
            yy = np.where(mask, yv, np.nan)
            ax.plot(br.p, yy, ls, color=f"C{b % 10}", label=bs.labels[b] if ls == "-" else None)
    for f in bs.folds:
        ax.plot(f["value"], f["measure"], "kx")
    for e in bs.endpoints:
        if e["kind"] != "endpoint":
            ax.plot(e["value"], e["measure"], "o", mfc="none", color="k")
            ax.annotate(e["kind"], (e["value"], e["measure"]), fontsize=7)
    ax.set_xlabel(bs.parameter)
    ax.set_ylabel(y)
    ax.set_title(f"{bs.scene.name}: lifted-strip equilibria (o: topology change)", fontsize=9)
    pr = bs.problem
    saved = dict(pr.params)
    for b, br in enumerate(bs.branches):
        for i in np.linspace(0, len(br) - 1, min(insets, len(br))).astype(int):
            pr.set(bs.parameter, float(br.p[i]))
            shp = strip_full_shape(pr, br.u[i])
            rod, iface = shp["rod"], shp["interface"]
            axs.plot(rod[:, 0], rod[:, 1], color=f"C{b % 10}", lw=1)
            axs.plot(iface[:, 0], iface[:, 1], color="tab:blue", lw=0.7)
    pr.params.update(saved)
    axs.axhline(0.0, color="0.5", lw=0.8)
    axs.set_xlim(-3, 2.5)
    axs.set_aspect("equal")
    axs.set_title("shapes (lift-off point at x = 0)", fontsize=9)
    fig.tight_layout()
    if path is not None:
        fig.savefig(Path(path), dpi=110)
    return fig
