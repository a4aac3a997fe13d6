"""The static bistability band of the strip of Fig 3 on the axes of the dynamic Fig 3d.

For each drop position x / l_eg, the discrete strip on the ground (``elastocap.strip``)
gives, by continuation in Delta bisected to 1e-3 (:func:`elastocap.strip.windows.window_at`):

* ``open_max``: where the open branch (a quasi-static deposition, continued up) ends;
* ``wrapped_min``: where the encapsulated branch (the folded strip, continued down) ends.

Both are mapped to We^(1/2) with the scene's spreading law, (Delta - Delta0) / (2 R c), and
drawn over the runs and the boundary of the damped dynamic phase diagram read from
``docs/img/fig3d.json`` (``elastocap figures --only fig3d``); without that file the static
band is drawn alone and the title says so. Each x is computed at two resolutions; an end
whose two values differ by more than ``TOL_DELTA`` (or whose branch ended differently) is
drawn hollow and listed in the JSON under ``unsettled``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from elastocap.paper_figures import record
from elastocap.scene import load_scene
from elastocap.strip._blas import blas_threads
from elastocap.strip.discrete import discrete_strip_for
from elastocap.strip.windows import window_at

#: Two resolutions whose ends differ by more than this (in Delta, units of l_eg) leave the
#: end unsettled: 0.01 is 0.035 in We^(1/2) for fig3-strip, half the bracket width (0.0625)
#: of the dynamic boundary in fig3d.json, so a settled end is finer than the boundary.
TOL_DELTA = 0.01
#: Full mode: x / l_eg and the two resolutions. n = 143 is h = 0.1 l_eg (the benchmark's
#: resolution); n = 286 halves h. Measured on 2 shared cores: 1-6 s per x at n = 143,
#: 10-45 s at n = 286.
FULL_X = (1.25, 1.5, 1.75, 2.0, 2.5, 3.0, 3.5, 4.0)
FULL_N = (143, 286)
#: Fast mode (the tests): one x, coarse. ~1 s.
FAST_X = (1.5,)
FAST_N = (50, 100)
#: Delta scanned (l_eg): 0.5 is below Delta0 = 0.594 of fig3-strip (We^(1/2) < 0: no
#: impact spreads less), 2.2 is We^(1/2) = 5.7, beyond the dynamic sweep's 4.
D_LO, D_HI = 0.5, 2.2
_ROOT = Path(__file__).resolve().parents[2]


def _default_fig3d() -> Path:
    return _ROOT / "docs" / "img" / "fig3d.json"


def _shown(path: Path) -> str:
    """The path as recorded: relative to the repository when inside it (reproducible)."""
    try:
        return str(Path(path).resolve().relative_to(_ROOT))
    except ValueError:
        return str(path)


def compute(scene, xs, ns, tol=TOL_DELTA) -> list[dict]:
    """Windows at each x and resolution, mapped to We^(1/2); one :func:`summarize` record
    per x."""
    template = discrete_strip_for(scene, ns[-1])
    rows = []
    with blas_threads(1):
        for x in xs:
            ws = [window_at(template, x, n, d_lo=D_LO, d_hi=D_HI).to_dict() for n in ns]
            rows.append(summarize(x, ws, scene.spreading, tol))
    return rows


def summarize(x, windows: list[dict], spreading, tol=TOL_DELTA) -> dict:
    """One x: ``x``, ``n`` (the resolutions), ``windows`` (as given, coarse to fine), and
    from the finest: ``open_max``, ``wrapped_min`` (Delta), their ``*_we_sqrt``, how each
    ended (``open_end``, ``wrapped_end``) and ``open_settled`` / ``wrapped_settled``: the
    two finest resolutions agree within ``tol`` (after raising both to Delta0: below it
    every impact finds the state), the branch ended the same way, and no fresh state of
    that kind exists just beyond the end (``*_beyond``); ``open_change`` /
    ``wrapped_change``: the difference compared.
    """
    row = {"x": float(x), "n": [w["n"] for w in windows], "windows": windows}
    fine = windows[-1]
    coarse = windows[-2] if len(windows) > 1 else None
    d0 = spreading.delta0
    for side, key in (("open", "open_max"), ("wrapped", "wrapped_min")):
        v, end = fine[key], fine[f"{side}_end"]
        row[key] = v
        row[f"{key}_we_sqrt"] = spreading.we_sqrt(v) if math.isfinite(v) else math.nan
        row[f"{side}_end"] = end
        if coarse is None:
            row[f"{side}_change"], row[f"{side}_settled"] = math.nan, False
            continue
        ch = abs(max(v, d0) - max(coarse[key], d0))
        both_low = v < d0 and coarse[key] < d0
        row[f"{side}_change"] = ch
        row[f"{side}_settled"] = bool(
            ch <= tol and end != "seed_failed" and fine[f"{side}_beyond"] is not True
            and (both_low or coarse[f"{side}_end"] == end))
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
            (op, "tab:red", ">", "static: open state ends (n = {n})"),
            (wr, "tab:green", "<", "static: encapsulated state begins (n = {n})")):
        if not pts:
            continue
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "-", color=color, lw=1.0, alpha=0.7)
        k = 0
        for w, x, settled, reached in pts:
            if reached:  # the branch reached the scanned range's end: no end to mark
                continue
            ax.plot(w, x, marker, color=color, ms=7, mec=color,
                    mfc=color if settled else "white", mew=1.3,
                    label=lab.format(n=rows[0]["n"][-1]) if k == 0 else None)
            k += 1
    ax.plot([], [], "s", mfc="white", mec="0.3", ms=6,
            label=f"hollow: unsettled (n = {rows[0]['n'][-2] if len(rows[0]['n']) > 1 else '-'}"
                  f" vs {rows[0]['n'][-1]} differ > {TOL_DELTA} in Δ)")


def main(out_dir, fast: bool = False, fig3d: str | Path | None = None) -> list[Path]:
    """Writes ``strip_bistability.png`` and ``strip_bistability.json``.

    Parameters
    ----------
    out_dir : str or Path
    fast : bool
        One x at coarse resolution (~1 s) instead of the full grid (~5 min).
    fig3d : str or Path, optional
        The dynamic phase diagram's JSON; default ``docs/img/fig3d.json`` of the repository.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from elastocap.sweep import plot_phase_diagram

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene = load_scene("fig3-strip")
    sp = scene.spreading
    xs, ns = (FAST_X, FAST_N) if fast else (FULL_X, FULL_N)
    rows = compute(scene, xs, ns)

    path = Path(fig3d) if fig3d is not None else _default_fig3d()
    dyn = json.loads(path.read_text()) if path.is_file() else None
    what = (f"static window (discrete strip, n = {ns[-2]} and {ns[-1]}, Δ bisected to 1e-3) "
            "→ We$^{1/2}$ by the spreading law")
    if dyn is not None:
        title = (f"Fig 3d (model, damped, from {path.name}) with the {what}")
        fig = plot_phase_diagram(dyn, None, title=title)
        ax = fig.axes[0]
    else:
        title = f"{what}; no dynamic diagram ({path} absent): static band alone"
        fig = Figure(figsize=(8.0, 4.8), dpi=130)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        ax.set_xlabel("We$^{1/2}$")
        ax.set_ylabel("x / ℓ_eg")
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.25)
    _draw_static(ax, rows, sp, w_min=0.0)
    # the dynamic sweep's range; a band running off the right edge continues beyond it
    w_hi = max((r["we_sqrt"] for r in dyn["runs"] if r.get("we_sqrt") is not None),
               default=4.0) if dyn is not None else 4.0
    ax.set_xlim(0.0, w_hi + 0.2)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    ax.set_title(title, fontsize=8)
    png = out / "strip_bistability.png"
    fig.savefig(png, bbox_inches="tight")

    unsettled = [{"x": r["x"], "end": side, "n": r["n"], "change": r[f"{side}_change"],
                  "ends": [w[f"{side}_end"] for w in r["windows"]],
                  "another_state_beyond": [w[f"{side}_beyond"] for w in r["windows"]]}
                 for r in rows for side in ("open", "wrapped") if not r[f"{side}_settled"]]
    data = {
        "rows": rows,
        "unsettled": unsettled,
        "tolerance_delta": TOL_DELTA,
        "spreading": {"drop_radius": sp.drop_radius, "delta0": sp.delta0,
                      "coefficient": sp.coefficient},
        "dynamic_diagram": _shown(path) if dyn is not None else None,
        "notes": [
            "open_max: last Delta where the open branch (deposition at Delta = 0.6, continued "
            "up) is stable; wrapped_min: the same for the encapsulated branch (fold at "
            "Delta = 1.6, continued down). Both to 1e-3 in Delta.",
            "open_end / wrapped_end: how the branch ended (elastocap.strip.mep.END_REASONS); "
            f"scan_limit: it reached Delta = {D_LO} or {D_HI}. A wrapped_min below Delta0 "
            "(We^(1/2) < 0) is drawn at We^(1/2) = 0: every impact finds that state.",
            "open_beyond / wrapped_beyond (per window): a fresh deposition / fold 2e-3 beyond "
            "the end still gives a stable state of that kind, i.e. another branch exists.",
            f"settled: the two resolutions agree within {TOL_DELTA} in Delta (both raised to "
            "Delta0), the branch ended the same way (or both lie below Delta0), and no fresh "
            "state of that kind exists just beyond the end at the finer n; a necessary "
            "check, not a proof of convergence.",
        ],
    }
    js = out / "strip_bistability.json"
    js.write_text(json.dumps(record(data, scene, fast=fast, x=list(xs), n=list(ns),
                                    d_range=[D_LO, D_HI]), indent=1))
    return [png, js]
