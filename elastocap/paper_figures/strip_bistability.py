"""The static bistability band of the strip of Fig 3 on the axes of the dynamic Fig 3d.

For each drop position x / l_eg, every equilibrium branch of the discrete strip on the
ground is traced in Delta with all contact topologies
(:func:`elastocap.strip.trace.trace_contact_branches`: seeds from a deposition
and from the folded strip, pseudo-arclength continuation through lift-offs, touch-downs
and folds, all located), giving

* ``open_max``: the largest Delta of a stable open state (a located fold or contact fold);
* ``wrapped_min``: the smallest Delta of a stable encapsulated state.

Both are mapped to We^(1/2) with the scene's spreading law, (Delta - Delta0) / (2 R c), and
drawn over the runs and the boundary of the damped dynamic phase diagram: a ``fig3d.json``
written by ``elastocap figures --only fig3d`` (the input file ``fig3d``; by default the
``fig3d.json`` in the output folder, which ``elastocap figures`` writes just before this
figure). Nothing is read from the repository, so the figure regenerates from an installed
package; without a dynamic diagram the static band is drawn alone and the title says so.
Each x is computed at two resolutions; an end whose two values differ by more than
``TOL_DELTA`` is drawn hollow and listed in the JSON under ``unsettled``.
"""

from __future__ import annotations

import hashlib
import json
import math
import sys
from pathlib import Path

from elastocap.io import atomic_path, write_json
from elastocap.paper_figures import record
from elastocap.scene import load_scene
from elastocap.strip.trace import trace_contact_branches

#: Two resolutions whose ends differ by more than this (in Delta, units of l_eg) leave the
#: end unsettled: 0.01 is 0.035 in We^(1/2) for fig3-strip, about the bracket width (0.031)
#: of the dynamic boundary in fig3d.json.
TOL_DELTA = 0.01
#: Full mode: x / l_eg and the two resolutions. n = 143 is h = 0.1 l_eg (the benchmark's
#: resolution), 286 is 2x finer. At both, the drop's centre L - x is a node or mid-edge for
#: every x here (x a multiple of 0.05), so the discrete strip is mirror-symmetric about
#: it as the continuous one is while the lifted stretch stays off the ends: the two
#: resolutions see the same symmetric states (at 214 edges they do not, and the branch the
#: deposition follows past the symmetric state's loss of stability depends on how the grid
#: breaks the symmetry: docs/guide/strip.md).
FULL_X = (1.25, 1.5, 1.75, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0)
FULL_N = (143, 286)
#: Fast mode (the tests): one x, coarse. ~5 s.
FAST_X = (1.5,)
FAST_N = (50, 100)
#: Delta scanned (l_eg): 0.5 is below Delta0 = 0.594 of fig3-strip (We^(1/2) < 0: no
#: impact spreads less), 2.2 is We^(1/2) = 5.7, beyond the dynamic sweep's 4.
D_LO, D_HI = 0.5, 2.2


def _dynamic_source(path: Path) -> dict:
    """What the figure drew the dynamic diagram from: file name and content digest."""
    return {"file": path.name, "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}


def compute(scene, xs, ns, tol=TOL_DELTA, progress=True) -> list[dict]:
    """All branches at each x (resolution ``ns[0]``, refined at ``ns[1]``) and the window
    ends mapped to We^(1/2); one :func:`summarize` record per x. ``progress`` prints one
    line per x to stderr."""
    rows = []
    for k, x in enumerate(xs):
        sc = scene.with_overrides({"drop.distance_from_end": float(x)})
        bs = trace_contact_branches(sc, prange=(D_LO, min(D_HI, 1.95 * x)), n=ns[0],
                                    n_refined=ns[1], spreading=True)
        rows.append(summarize(x, bs, scene.spreading, tol))
        if progress:
            r = rows[-1]
            print(f"  strip-bistability {k + 1}/{len(xs)}: x = {x:g}, open_max "
                  f"{r['open_max']:.4f}, wrapped_min {r['wrapped_min']:.4f} "
                  f"({r['wall_time_s']:.0f} s)", file=sys.stderr)
    return rows


def summarize(x, bs, spreading, tol=TOL_DELTA) -> dict:
    """One x: ``x``, ``n`` (the two resolutions), from the refined run ``open_max`` and
    ``wrapped_min`` (Delta) and their ``*_we_sqrt``; ``open_end`` / ``wrapped_end``
    (``"scan_limit"`` when the stable stretch reaches the scanned range's end, else how it
    ends: ``"smooth_fold"``, ``"contact_fold"``, ``"kind_change"``); ``open_change`` /
    ``wrapped_change``: the difference between the two
    resolutions (after raising both to Delta0: below it every impact finds the state) and
    ``open_settled`` / ``wrapped_settled``: it is at most ``tol``; the same for
    ``deposition_end`` (the static prediction: where the state a quasi-static spreading
    lands on, traced up from the deposition at Delta = 0.6, stops existing or being stable,
    :func:`elastocap.strip.trace.open_branch_end`) and ``spreading_end`` (where the
    spreading, followed through its jumps, stops being open: ``spreading`` of the same);
    ``folds``: the located folds at the
    coarse resolution; ``wall_time_s``."""
    w = bs.results["window"]
    lo, hi = bs.prange
    row = {"x": float(x), "n": [bs.metadata["n_edges"], bs.metadata["n_edges_refined"]],
           "folds": [{k: f[k] for k in ("value", "kind", "node", "event", "stability_change",
                                        "encapsulated", "admissible", "error_estimate")}
                     for f in bs.folds],
           "branches": [{k: b[k] for k in ("label", "range", "end_status")}
                        for b in bs.summary()["branches"]],
           "wall_time_s": bs.metadata["wall_time_s"]}
    d0 = spreading.delta0
    ends = (("open", "open_max", w["open_max"]),
            ("wrapped", "wrapped_min", w["encapsulated_min"]),
            ("deposition", "deposition_end", w["open_branch_end"]),
            ("spreading", "spreading_end", w["open_branch_end"].get("spreading")))
    for side, key, end in ends:
        if end is None:
            continue
        coarse, fine = end["value"], end.get("value_refined")
        v = fine if fine is not None else math.nan
        row[key] = v
        row[f"{key}_coarse"] = coarse if coarse is not None else math.nan
        row[f"{key}_we_sqrt"] = spreading.we_sqrt(v) if math.isfinite(v) else math.nan
        how = end.get("how_refined") or end.get("how")
        at_bound = math.isfinite(v) and (abs(v - lo) < 1e-9 or abs(v - hi) < 1e-9)
        # the deposition's and the spreading's end values are row["deposition_end"] and
        # row["spreading_end"]; how they end, "deposition_how" and "spreading_how"
        row[f"{side}_how" if side in ("deposition", "spreading") else f"{side}_end"] = \
            "scan_limit" if at_bound else how
        if coarse is None or fine is None:
            row[f"{side}_change"], row[f"{side}_settled"] = math.nan, False
            continue
        ch = abs(max(fine, d0) - max(coarse, d0))
        row[f"{side}_change"] = ch
        row[f"{side}_settled"] = bool(ch <= tol)
    # where the spreading could not be followed to its end: open at least up to this
    spr = w["open_branch_end"].get("spreading") or {}
    up = spr.get("open_up_to_refined", spr.get("open_up_to"))
    row["spreading_open_up_to"] = up if up is not None else math.nan
    row["spreading_open_up_to_we_sqrt"] = spreading.we_sqrt(up) if up is not None \
        else math.nan
    return row


def _draw_static(ax, rows, sp, w_min):
    """The band and its two ends on ``ax`` (horizontal: We^(1/2), vertical: x)."""
    def ends(key):
        side = key.split("_")[0]
        pts = []
        for r in rows:
            w = r[f"{key}_we_sqrt"]
            if not math.isfinite(w):
                continue
            reached = r[f"{side}_end"] == "scan_limit"
            pts.append((max(w, w_min), r["x"], r[f"{side}_settled"], reached))
        return pts

    op, wr = ends("open_max"), ends("wrapped_min")
    # the band: both states stable between wrapped_min and open_max
    band = [(r["x"], max(r["wrapped_min_we_sqrt"], w_min), r["open_max_we_sqrt"])
            for r in rows if r["open_max_we_sqrt"] > max(r["wrapped_min_we_sqrt"], w_min)]
    for i, (x, lo, hi) in enumerate(band):
        ax.plot([lo, hi], [x, x], "-", color="tab:purple", lw=5, alpha=0.35,
                solid_capstyle="butt", label="static: both states stable" if i == 0 else None)
    for pts, color, marker, lab in (
            (op, "tab:red", ">", "static: open state ends ($n$ = {n})"),
            (wr, "tab:green", "<", "static: encapsulated state begins ($n$ = {n})")):
        if not pts:
            continue
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "-", color=color, lw=1.0, alpha=0.7)
        for w, x, settled, reached in pts:
            if reached:  # the branch reached the scanned range's end: no end to mark
                continue
            ax.plot(w, x, marker, color=color, ms=7, mec=color,
                    mfc=color if settled else "white", mew=1.3)
        # the legend shows the settled (filled) symbol; hollow ones are explained below
        ax.plot([], [], marker, color=color, ms=7, mec=color, mfc=color, mew=1.3, ls="-",
                lw=1.0, label=lab.format(n=rows[0]["n"][-1]))
    for key, marker, color, lab in (
            ("deposition", "D", "k", "static: the deposited open state is lost"),
            ("spreading", "*", "tab:blue", "static prediction: a quasi-static spreading "
             "stops being open")):
        pts = [(max(r[f"{key}_end_we_sqrt"], w_min), r["x"], r[f"{key}_settled"])
               for r in rows if math.isfinite(r.get(f"{key}_end_we_sqrt", math.nan))]
        if not pts:
            continue
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "-", color=color, lw=1.2,
                alpha=0.8)
        for i, (w, x, settled) in enumerate(pts):
            ax.plot(w, x, marker, color=color, ms=6 if marker == "D" else 9,
                    mfc=color if settled else "white", label=lab if i == 0 else None)
    # a spreading followed to no end: open at least up to its last end
    low = [(max(r["spreading_open_up_to_we_sqrt"], w_min), r["x"]) for r in rows
           if not math.isfinite(r.get("spreading_end_we_sqrt", math.nan))
           and math.isfinite(r.get("spreading_open_up_to_we_sqrt", math.nan))]
    for i, (w, x) in enumerate(low):
        ax.plot(w, x, ">", color="tab:blue", ms=7, mfc="white",
                label="spreading open at least to here (not followed further)"
                if i == 0 else None)
    ax.plot([], [], "s", mfc="white", mec="0.3", ms=6,
            label="hollow: unsettled ($n$ = "
                  f"{rows[0]['n'][-2] if len(rows[0]['n']) > 1 else '-'} and {rows[0]['n'][-1]}"
                  f" differ by > {TOL_DELTA} in " + r"$\Delta$)")


def main(out_dir, fast: bool = False, fig3d: str | Path | None = None) -> list[Path]:
    """Writes ``strip_bistability.png`` and ``strip_bistability.json``.

    Parameters
    ----------
    out_dir : str or Path
    fast : bool
        One x at coarse resolution (~5 s) instead of the full grid (~12 min).
    fig3d : str or Path, optional
        The dynamic phase diagram's JSON (``elastocap figures --only fig3d``); default
        ``out_dir/fig3d.json`` when it exists.
    """
    if fig3d is not None and not Path(fig3d).is_file():
        raise FileNotFoundError(f"fig3d: got {str(fig3d)!r}; expected the JSON written by "
                                "elastocap figures --only fig3d")
    scene = load_scene("fig3-strip")
    xs, ns = (FAST_X, FAST_N) if fast else (FULL_X, FULL_N)
    rows = compute(scene, xs, ns)
    return _write(Path(out_dir), scene, rows, fast, xs, ns, fig3d)


def redraw(out_dir, fig3d: str | Path | None = None) -> list[Path]:
    """Redraw the figure over a new dynamic diagram without recomputing the statics.

    The static rows and their settings are read back from ``out_dir``'s
    ``strip_bistability.json`` (written by :func:`main`, which the statics alone make: the
    dynamics do not enter them); the PNG and the JSON are rewritten with ``fig3d``.
    ``python3 -m elastocap.paper_figures.strip_bistability DIR --redraw --fig3d FILE``.
    """
    out = Path(out_dir)
    old = json.loads((out / "strip_bistability.json").read_text())
    made = old["made_by"]
    scene = load_scene("fig3-strip")
    if made["scene"] != scene.data:
        raise ValueError(
            f"{out / 'strip_bistability.json'} was made for another fig3-strip scene "
            f"({made['scene']}); recompute it: elastocap figures --only strip-bistability")
    return _write(out, scene, old["rows"], made["fast"], tuple(made["x"]),
                  tuple(made["n"]), fig3d)


def _write(out: Path, scene, rows, fast, xs, ns, fig3d) -> list[Path]:
    """The PNG and the JSON of :func:`main` from computed ``rows``."""
    from elastocap.figure import new_figure
    from elastocap.sweep import plot_phase_diagram

    out.mkdir(parents=True, exist_ok=True)
    sp = scene.spreading
    path = Path(fig3d) if fig3d is not None else out / "fig3d.json"
    if fig3d is not None and not path.is_file():
        raise FileNotFoundError(f"fig3d: got {str(path)!r}; expected the JSON written by "
                                "elastocap figures --only fig3d")
    dyn = json.loads(path.read_text()) if path.is_file() else None
    what = (f"the static window (discrete strip, every contact topology, $n$ = {ns[0]} and "
            f"{ns[1]}), mapped to " + r"$\mathrm{We}^{1/2}$ by the spreading law")
    if dyn is not None:
        title = f"Fig 3d (model, damped, {path.name})\nwith {what}"
        fig = plot_phase_diagram(dyn, None, title=title)
        ax = fig.axes[0]
    else:
        title = f"{what}; no dynamic diagram ({path} absent): static band alone"
        fig = new_figure((8.0, 4.8))
        ax = fig.add_subplot()
        ax.set_xlabel(r"$\mathrm{We}^{1/2}$")
        ax.set_ylabel(r"$x/\ell_{eg}$")
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.25)
    _draw_static(ax, rows, sp, w_min=0.0)
    # the dynamic sweep's range; a band running off the right edge continues beyond it
    w_hi = max((r["we_sqrt"] for r in dyn["runs"] if r.get("we_sqrt") is not None),
               default=4.0) if dyn is not None else 4.0
    # every drawn end inside (an end below Delta0 is drawn at We^(1/2) = 0, left of which
    # the axis gives room for its marker)
    w_ends = [r[f"{k}_we_sqrt"] for r in rows for k in ("open_max", "wrapped_min")
              if math.isfinite(r[f"{k}_we_sqrt"])]
    ax.set_xlim(-0.15, max([w_hi, *w_ends]) + 0.2)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    ax.set_title(title, fontsize=8)
    png = out / "strip_bistability.png"
    with atomic_path(png) as tmp:
        fig.savefig(tmp, bbox_inches="tight")

    unsettled = [{"x": r["x"], "end": side, "n": r["n"], "change": r[f"{side}_change"],
                  "values": [r[f"{key}_coarse"], r[key]]}
                 for r in rows for side, key in (("open", "open_max"),
                                                 ("wrapped", "wrapped_min"),
                                                 ("deposition", "deposition_end"),
                                                 ("spreading", "spreading_end"))
                 # rows computed without the static prediction have no deposition end
                 if f"{side}_settled" in r and not r[f"{side}_settled"]]
    data = {
        "rows": rows,
        "unsettled": unsettled,
        "tolerance_delta": TOL_DELTA,
        "spreading": {"drop_radius": sp.drop_radius, "delta0": sp.delta0,
                      "coefficient": sp.coefficient},
        "dynamic_diagram": _dynamic_source(path) if dyn is not None else None,
        "notes": [
            "open_max: the largest Delta of a stable, admissible open state on any traced "
            "branch (a located fold or contact fold); wrapped_min: the smallest Delta of a "
            "stable, admissible encapsulated state (the paper's criterion). Values from "
            "the finer resolution; *_coarse from the coarser.",
            f"open_end / wrapped_end: scan_limit when the stable stretch reaches Delta = "
            f"{D_LO} or the range's top (no end inside the range). A wrapped_min below "
            "Delta0 (We^(1/2) < 0) is drawn at We^(1/2) = 0: every impact finds that state.",
            f"settled: the two resolutions agree within {TOL_DELTA} in Delta (both raised "
            "to Delta0); a necessary check, not a proof of convergence. An end can move "
            "between resolutions because the branch reaching it changes (another sequence "
            "of contact changes), not only by the discretization error of one fold.",
        ],
    }
    js = out / "strip_bistability.json"
    write_json(js, record(data, scene, fast=fast, x=list(xs), n=list(ns),
                                    d_range=[D_LO, D_HI]), indent=1)
    return [png, js]


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", metavar="DIR", help="output folder")
    ap.add_argument("--redraw", action="store_true",
                    help="redraw DIR/strip_bistability.png without recomputing the statics")
    ap.add_argument("--fast", action="store_true", help="one x, coarse (the tests)")
    ap.add_argument("--fig3d", default=None,
                    help="the dynamic diagram's JSON (default DIR/fig3d.json if present)")
    a = ap.parse_args()
    paths = redraw(a.out, a.fig3d) if a.redraw else main(a.out, a.fast, a.fig3d)
    print(", ".join(str(p) for p in paths))
