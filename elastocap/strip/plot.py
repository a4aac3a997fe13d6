"""Drawing the strip's branches: energy and turning against Delta, folds, window, shapes."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from elastocap.strip.model import discrete_strip_for, flat_energy, strip_and_interface

__all__ = ["plot_contact_branch_set"]


def plot_contact_branch_set(bs, path=None, insets=3):
    """Branches of a strip's :class:`~elastocap.branchset.BranchSet`.

    Left: energy above the flat state against Delta (solid stable, dashed unstable, grey
    where the strip crosses itself or the interface crosses it), smooth folds (x), contact
    folds (o) and the stable window ends (vertical lines). Middle: the turning theta(L)/pi.
    Right: a few shapes of each branch on the ground. Returns the figure; writes ``path``.
    """
    from elastocap.figure import new_figure

    fig = new_figure((12, 7.5), dpi=100)
    gs = fig.add_gridspec(2, 2, height_ratios=[3, 2])
    ax, am, axs = fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[0, 1]), \
        fig.add_subplot(gs[1, :])
    n = bs.metadata["n_edges"]
    for b, br in enumerate(bs.branches):
        d, pts = br.p, br.observables
        if not d.size:
            continue
        col = f"C{b % 10}"
        stable = br.stability == 0
        ok = pts["admissible"] == 1.0
        for a, key in ((ax, "energy_above_flat"), (am, "measure")):
            y = pts[key]
            for mask, ls, c in ((stable & ok, "-", col), (~stable & ok, "--", col),
                                (~ok, ":", "0.6")):
                a.plot(d, np.where(mask, y, np.nan), ls, color=c, lw=1.2)
    for f in bs.folds:
        mk = "kx" if f["kind"] == "smooth" else "ko"
        ax.plot(f["value"], f["energy"] - _flat(bs, f["value"]), mk, mfc="none", ms=5)
        am.plot(f["value"], f["measure"], mk, mfc="none", ms=5)
    w = bs.results.get("window", {})
    for key, ls in (("open_max", "-."), ("encapsulated_min", ":")):
        v = (w.get(key) or {}).get("value")
        if v is not None:
            for a in (ax, am):
                a.axvline(v, color="k", lw=0.7, ls=ls)
    from matplotlib.lines import Line2D

    ax.set_xlabel(r"wetted length $\Delta$")
    ax.set_ylabel(r"$E - E_\mathrm{flat}$")
    fig.suptitle(f"{bs.scene.name}, " + r"$x$" + f" = {bs.scene.distance_from_end:g}, "
                 + r"$n$" + f" = {n} edges", fontsize=9)
    handles = [Line2D([], [], color=f"C{b % 10}", label=bs.labels[b].replace("Delta", "Δ"))
               for b, br in enumerate(bs.branches) if len(br)]
    handles += [Line2D([], [], color="k", ls="-", label="stable"),
                Line2D([], [], color="k", ls="--", label="unstable"),
                Line2D([], [], color="0.6", ls=":", label="inadmissible (crossing)")]
    kinds = {f["kind"] for f in bs.folds}
    if "smooth" in kinds:
        handles.append(Line2D([], [], ls="", marker="x", color="k", label="✕ smooth fold"))
    if kinds - {"smooth"}:
        handles.append(Line2D([], [], ls="", marker="o", mfc="none", color="k",
                              label="○ contact fold"))
    for key, ls, lab in (("open_max", "-.", "stable open state ends"),
                         ("encapsulated_min", ":", "stable encapsulated state begins")):
        if (w.get(key) or {}).get("value") is not None:
            handles.append(Line2D([], [], color="k", lw=0.7, ls=ls, label=lab))
    ax.legend(handles=handles, fontsize=6, loc="best")
    am.set_xlabel(r"wetted length $\Delta$")
    am.set_ylabel(r"$\theta(L)/\pi$")
    am.set_title(f"stable open up to Δ = {_fmt(w, 'open_max')}, stable encapsulated from "
                 f"Δ = {_fmt(w, 'encapsulated_min')}", fontsize=8)
    strip = discrete_strip_for(bs.scene, n)
    for b, br in enumerate(bs.branches):
        for i in np.linspace(0, len(br) - 1, min(insets, len(br))).astype(int):
            X, iface, _d = strip_and_interface(strip.with_(delta=float(br.p[i])),
                                               br.u[i][: strip.size])
            axs.plot(X[:, 0], X[:, 1], color=f"C{b % 10}", lw=0.8)
            axs.plot(iface[:, 0], iface[:, 1], color="tab:blue", lw=0.5)
    axs.axhline(0.0, color="0.5", lw=0.8)
    L, x = bs.scene.rod.length, bs.scene.distance_from_end
    axs.set_xlim(L - x - 4.0, L + 0.5)
    axs.set_aspect("equal")
    axs.set_title(r"shapes on the ground (impact centre at $L - x$)", fontsize=8)
    fig.tight_layout()
    if path is not None:
        fig.savefig(Path(path), dpi=110)
    return fig


def _flat(bs, delta):
    d = bs.scene.drop
    return flat_energy(d.area, d.line_tension, delta)


def _fmt(w, key):
    v = (w.get(key) or {}).get("value")
    if v is None:
        return "-"
    e = w[key].get("error_estimate")
    return f"{v:.4f}" + (f" ± {e:.1e}" if e is not None and e == e else "")
