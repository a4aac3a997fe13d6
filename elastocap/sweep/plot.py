"""The phase diagram of a sweep, drawn like Antkowiak et al. 2011, Fig 3d.

Open circles: open (not encapsulated); filled dots: encapsulated (the paper's criterion);
grey triangles: undecided runs, a class of their own (with their count); red crosses: runs
that failed (no result); a red ring: the companion criterion (:mod:`elastocap.criteria`)
disagrees; purple diamonds: outcome changes among a line's drawn runs other than its
threshold (to or from undecided, back to open). Only runs at the sweep's own resolution
(level 0) are drawn as points. Each line's *threshold* (its first change, open ->
encapsulated) is drawn through the bracket's midpoint with the half-width as a horizontal
error bar: blue where verification found that it holds, orange where it is not verified (not
checked, moved), grey for a decided bracket on a line whose undecided runs lie below it;
with ``companion=``, the frame-independent criterion's thresholds in green. x/l_eg on the
vertical axis, We^1/2 (or Delta) on the horizontal one.
Optional experimental points (a CSV with columns x_over_leg, we_sqrt, outcome) as
squares. The title records the scene, every ``--set`` override and the resolution.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

__all__ = ["load_experiments", "plot_phase_diagram", "settings_line"]

EXPERIMENT_COLUMNS = ("x_over_leg", "we_sqrt", "outcome")
UNDECIDED = "undecided"
_OUTCOME_WORDS = {
    "encapsulated": "encapsulated",
    "enc": "encapsulated",
    "1": "encapsulated",
    "open": "open",
    "0": "open",
}


def check_report(report, origin: str) -> None:
    """Refuse (ValueError naming ``origin``, the run and the field) a sweep report that
    :func:`plot_phase_diagram` cannot draw faithfully: not a dict with a list of runs, a
    run without a finite x, a non-finite We^1/2 or Delta, an outcome no run can have."""
    from elastocap.jsonutil import is_finite_number as finite
    from elastocap.sweep.store import OUTCOMES

    runs = report.get("runs") if isinstance(report, dict) else None
    if not isinstance(runs, list):
        raise ValueError(f"PATH: {origin}: not a sweep report (no list of runs under 'runs')")

    for k, r in enumerate(runs):
        where = f"PATH: {origin}: runs[{k}]"
        if not isinstance(r, dict):
            raise ValueError(f"{where}: not a run (a JSON object expected)")
        if not finite(r.get("x")):
            raise ValueError(f"{where}: x = {r.get('x')!r}; expected a finite number")
        for key in ("we_sqrt", "wetted_length", "final_measure", "companion_measure"):
            if r.get(key) is not None and not finite(r[key]):
                raise ValueError(f"{where}: {key} = {r[key]!r}; expected a finite number")
        if r.get("we_sqrt") is None and r.get("wetted_length") is None:
            raise ValueError(f"{where}: neither we_sqrt nor wetted_length")
        if r.get("outcome") not in OUTCOMES:
            raise ValueError(f"{where}: outcome = {r.get('outcome')!r}; expected one of "
                             f"{', '.join(OUTCOMES)}")


def load_experiments(path: str | Path) -> list[dict]:
    """Read experimental points: a CSV with a header naming at least x_over_leg, we_sqrt,
    outcome (encapsulated|open, or enc|1 / 0). Errors name the file, line and column."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"--experiments: got {str(path)!r}; no such file")
    out = []
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        header = [h.strip() for h in (reader.fieldnames or [])]
        missing = [c for c in EXPERIMENT_COLUMNS if c not in header]
        if missing:
            raise ValueError(
                f"--experiments {path}: missing column(s) {', '.join(missing)}; "
                f"expected a header with {', '.join(EXPERIMENT_COLUMNS)}"
            )
        for line, raw in enumerate(reader, start=2):
            row = {k.strip(): (v or "").strip() for k, v in raw.items() if k is not None}
            try:
                xv, wv = float(row["x_over_leg"]), float(row["we_sqrt"])
            except ValueError:
                raise ValueError(
                    f"--experiments {path}, line {line}: x_over_leg and we_sqrt "
                    f"must be numbers, got {row['x_over_leg']!r}, "
                    f"{row['we_sqrt']!r}"
                ) from None
            if not (math.isfinite(xv) and math.isfinite(wv)):
                raise ValueError(
                    f"--experiments {path}, line {line}: x_over_leg and we_sqrt must be "
                    f"finite, got {xv!r}, {wv!r}")
            o = _OUTCOME_WORDS.get(row["outcome"].lower())
            if o is None:
                raise ValueError(
                    f"--experiments {path}, line {line}: outcome {row['outcome']!r};"
                    " expected encapsulated or open"
                )
            out.append({"x_over_leg": xv, "we_sqrt": wv, "outcome": o})
    return out


def settings_line(rep: dict) -> str:
    """What a figure of the sweep ``rep`` must say about how it was made: every ``--set``
    override, the resolution and the criterion."""
    over = rep.get("overrides")
    res = rep.get("resolution")
    parts = []
    if over is not None:  # a report of a sweep made before overrides were recorded: silent
        parts.append("scene settings " + ", ".join(o.replace("=", " = ") for o in over)
                     if over else "the scene's own settings")
    if res:
        parts.append(f"{res['n_edges']} edges, " + r"$\Delta t$" + f" = {res['dt']:.3g}")
    if rep.get("criterion"):
        parts.append(f"criterion: {rep['criterion']}")
    if rep.get("verify_levels"):
        parts.append(f"verified to level {rep['verify_levels']}"
                     + (" (every bracket at every level)" if rep.get("verify_every_level")
                        else ""))
    return "; ".join(parts)


def _lines(n: int) -> str:
    return f"{n} line" + ("" if n == 1 else "s")


def _draw_thresholds(ax, rep, hkey, same_var, companion):
    """Each line's threshold (first open -> encapsulated change) as its bracket's midpoint
    with the half-width as error bar, by verification; lines without one but with a
    decided bracket among undecided / failed runs in grey."""
    verifying = bool(rep.get("verify_levels"))
    name = "frame-independent criterion" if companion else "threshold"
    # threshold: the first change from open (to encapsulated, or undecided)
    if companion:
        groups = {
            "verified": ("tab:green", "-", f"{name}: threshold, verified"),
            "unverified": ("tab:green", "--", f"{name}: threshold, NOT verified"),
        }
    else:
        held = ("holds at every finer level" if rep.get("verify_every_level")
                else "holds at a finer level")
        groups = {
            "verified": ("tab:blue", "-", f"threshold, verified ({held})"),
            "unverified": ("tab:orange", "--", "threshold, NOT verified" if verifying
                           else "threshold (not verified: run with --verify)"),
            "uncertain": ("0.5", ":", "decided runs' bracket; line has undecided/failed runs"),
        }
    pts = {k: ([], [], []) for k in groups}
    for b in rep["boundary"]:
        if b["status"] == "bracketed":
            lo, hi = b.get(f"{hkey}_low"), b.get(f"{hkey}_high")
        elif same_var and b.get("threshold_low") is not None:
            lo, hi = b["threshold_low"], b["threshold_high"]
        elif (not companion and b["status"] in ("undecided", "failed")
              and b.get("decided_status") == "bracketed"):
            lo, hi = b.get(f"{hkey}_low"), b.get(f"{hkey}_high")
            if lo is not None and hi is not None:
                pts["uncertain"][0].append(0.5 * (lo + hi))
                pts["uncertain"][1].append(b["x"])
                pts["uncertain"][2].append(0.5 * (hi - lo))
            continue
        else:
            continue
        if lo is None or hi is None:
            continue
        g = "verified" if b.get("verified") else "unverified"
        pts[g][0].append(0.5 * (lo + hi))
        pts[g][1].append(b["x"])
        pts[g][2].append(0.5 * (hi - lo))
    # one thin line through every threshold in x order (the boundary as a curve), then each
    # threshold as its bracket, by verification: no line joins brackets of one group only
    curve = sorted((y, x) for g in ("verified", "unverified") for x, y in zip(pts[g][0], pts[g][1],
                                                                             strict=True))
    if len(curve) > 1:
        ax.plot([c[1] for c in curve], [c[0] for c in curve], "-",
                color="tab:green" if companion else "0.35", lw=0.8, alpha=0.7, zorder=1,
                label=(f"{name}: thresholds joined in x" if companion
                       else "thresholds joined in x"))
    for g, (color, ls, label) in groups.items():
        bx, by, berr = pts[g]
        if bx:
            # the companion's as larger hollow squares under the paper's diamonds
            # verified: a filled marker; not verified: a hollow one (a dashed bar alone
            # would not show in the legend)
            filled = g == "verified"
            eb = ax.errorbar(bx, by, xerr=berr, color=color, lw=2.6 if companion else 1.4,
                             capsize=4 if companion else 3, marker="s" if companion else "D",
                             ms=7 if companion else 4.5, mfc=color if filled else "white",
                             mew=1.2, ls="none", label=f"{label} ({_lines(len(bx))})",
                             zorder=2 if companion else 3, alpha=0.6 if companion else 1.0)
            eb[-1][0].set_linestyle(ls)
    # a threshold into undecided runs: the first impacts that leave open are not decided
    und = [b for b in rep["boundary"] if b.get("threshold_to") == UNDECIDED and same_var
           and b.get("threshold_low") is not None]
    if und and not companion:
        ax.plot([0.5 * (b["threshold_low"] + b["threshold_high"]) for b in und],
                [b["x"] for b in und], "^", ms=8, mfc="none", mec="k", mew=1.2, ls="none",
                label=f"threshold into undecided runs, no encapsulation below "
                f"({_lines(len(und))})")


def plot_phase_diagram(report, path=None, experiments=None, title: str | None = None,
                       companion=None):
    """Draw a sweep's phase diagram.

    Parameters
    ----------
    report : SweepResult or dict
        A sweep result, or its ``to_dict()`` (the ``--json`` report).
    path : str or Path, optional
        Write the figure there (format from the suffix: .png, .pdf).
    experiments : list of dict or path, optional
        Experimental points (see :func:`load_experiments`), drawn only on a We^1/2 axis.
    title : str, optional
    companion : SweepResult or dict, optional
        The same sweep refined and verified with the frame-independent criterion
        (``criterion="companion_outcome"``, same store): its thresholds are drawn too, in
        green.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from elastocap.figure import new_figure

    rep = report if isinstance(report, dict) else report.to_dict()
    if companion is not None and not isinstance(companion, dict):
        companion = companion.to_dict()
    all_runs = rep["runs"]
    runs = [r for r in all_runs if not r.get("level")]
    use_we = bool(runs) and all(r.get("we_sqrt") is not None for r in runs)
    hkey = "we_sqrt" if use_we else "wetted_length"
    fig = new_figure((8.0, 4.8))
    ax = fig.add_subplot()
    classes = (
        ("open", "o", {"mfc": "none", "mec": "k"}, "not encapsulated"),
        ("encapsulated", "o", {"mfc": "k", "mec": "k"}, "encapsulated"),
        ("undecided", "^", {"mfc": "0.6", "mec": "0.3"}, "undecided"),
    )
    for outcome, marker, style, label in classes:
        pts = [r for r in runs if r["outcome"] == outcome]
        if outcome == "undecided" and not pts:
            continue
        ax.plot(
            [r[hkey] for r in pts],
            [r["x"] for r in pts],
            marker,
            ms=4.5,
            ls="none",
            label=f"{label} ({len(pts)})",
            **style,
        )
    failed = [f for f in rep.get("failed", []) if not f.get("level")]
    if failed:
        fkey = hkey if all(f.get(hkey) is not None for f in failed) else "wetted_length"
        ax.plot([f[fkey] for f in failed], [f["x_over_leg"] for f in failed], "x",
                color="tab:red", ms=6, mew=1.5, ls="none", label=f"failed, no result "
                f"({len(failed)})")
    # an undecided run is undecided under both criteria: rings only where both decided
    dis = [r for r in runs if r["outcome"] != r["companion_outcome"]
           and UNDECIDED not in (r["outcome"], r["companion_outcome"])]
    if dis:
        ax.plot(
            [r[hkey] for r in dis],
            [r["x"] for r in dis],
            "o",
            mfc="none",
            mec="tab:red",
            ms=9,
            mew=1.4,
            ls="none",
            label=f"frame-independent criterion disagrees ({len(dis)})",
        )
    same_var = hkey == rep.get("variable", hkey)  # a diagram without runs may omit it
    if companion is not None:
        _draw_thresholds(ax, companion, hkey, same_var, companion=True)
    _draw_thresholds(ax, rep, hkey, same_var, companion=False)
    # every other outcome change of a line among the runs drawn (level 0): to or from
    # undecided, back to open; the first change, when it is from open, is the threshold
    others = []
    by_x: dict = {}
    for r in runs:
        by_x.setdefault(r["x"], []).append((r[hkey], r["outcome"]))
    for x, pairs in by_x.items():
        pairs.sort()
        changes = [(a, b) for (a, oa), (b, ob) in zip(pairs[:-1], pairs[1:], strict=True)
                   if oa != ob]
        if changes and pairs[0][1] == "open":
            changes = changes[1:]
        others += [(0.5 * (a + b), x) for a, b in changes]
    if others:
        ax.plot([o[0] for o in others], [o[1] for o in others], "d", color="tab:purple",
                ms=5, ls="none", label=f"other outcome change on the line ({len(others)})")
    if experiments is not None and use_we:
        exps = experiments if isinstance(experiments, list) else load_experiments(experiments)
        for outcome, style in (("open", {"mfc": "none"}), ("encapsulated", {"mfc": "tab:green"})):
            pts = [e for e in exps if e["outcome"] == outcome]
            ax.plot(
                [e["we_sqrt"] for e in pts],
                [e["x_over_leg"] for e in pts],
                "s",
                mec="tab:green",
                ms=5,
                ls="none",
                label=f"experiment: {outcome}",
                **style,
            )
    ax.set_ylabel(r"$x/\ell_{eg}$" if rep.get("x_unit") == "l_eg" else r"$x$ (scene units)")
    ax.set_xlabel(r"$\mathrm{We}^{1/2}$" if use_we else r"$\Delta$ (scene units)")
    head = title or (f"{rep['scene']}: phase diagram ({len(runs)} runs"
                     + (f" + {len(all_runs) - len(runs)} verification runs"
                        if len(all_runs) > len(runs) else "")
                     + f", elastocap {rep['version']})")
    line = settings_line(rep)
    ax.set_title(head + ("\n" + line if line else ""), fontsize=8)
    ax.grid(alpha=0.25)
    # outside the axes, on the right: a legend inside would hide points of the diagram
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    if path is not None:
        fig.savefig(path, bbox_inches="tight")
    return fig
