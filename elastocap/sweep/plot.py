"""The phase diagram of a sweep, drawn like Antkowiak et al. 2011, Fig 3d.

Open circles: open (not encapsulated); filled dots: encapsulated (the paper's criterion);
grey triangles: undecided runs, a class of their own (with their count); red crosses: runs
that failed (no result); a red ring: the companion criterion (:mod:`elastocap.criteria`)
disagrees. Only runs at the sweep's own resolution (level 0) are drawn as points. The
boundary is drawn through the brackets' midpoints with the half-width as a horizontal
error bar: blue where ``--verify`` found that the bracket holds, orange where it is not
verified (not checked, moved, or not one bracket), grey where the line has undecided or
failed runs. x/l_eg on the vertical axis, We^1/2 (or Delta) on the horizontal one.
Optional experimental points (a CSV with columns x_over_leg, we_sqrt, outcome) as
squares. The title records the scene, every ``--set`` override and the resolution.
"""

from __future__ import annotations

import csv
from pathlib import Path

__all__ = ["load_experiments", "plot_phase_diagram", "settings_line"]

EXPERIMENT_COLUMNS = ("x_over_leg", "we_sqrt", "outcome")
_OUTCOME_WORDS = {
    "encapsulated": "encapsulated",
    "enc": "encapsulated",
    "1": "encapsulated",
    "open": "open",
    "0": "open",
}


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
        parts.append("--set " + ", ".join(over) if over else "no --set overrides")
    if res:
        parts.append(f"{res['n_edges']} edges, dt {res['dt']:.3g}")
    if rep.get("criterion"):
        parts.append(f"criterion: {rep['criterion']}")
    if rep.get("verify_levels"):
        parts.append(f"verified to level {rep['verify_levels']}")
    return "; ".join(parts)


def plot_phase_diagram(report, path=None, experiments=None, title: str | None = None):
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

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rep = report if isinstance(report, dict) else report.to_dict()
    all_runs = rep["runs"]
    runs = [r for r in all_runs if not r.get("level")]
    use_we = bool(runs) and all(r.get("we_sqrt") is not None for r in runs)
    hkey = "we_sqrt" if use_we else "wetted_length"
    fig = Figure(figsize=(8.0, 4.8), dpi=130)
    FigureCanvasAgg(fig)
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
    dis = [r for r in runs if r["outcome"] != r["companion_outcome"]]
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
            label="companion criterion disagrees",
        )
    verifying = bool(rep.get("verify_levels"))
    groups = {
        "verified": ("tab:blue", "-", "boundary, verified (bracket holds at 1.5x edges)"),
        "unverified": ("tab:orange", "--", "boundary, NOT verified" if verifying
                       else "boundary (not verified: run with --verify)"),
        "uncertain": ("0.5", ":", "decided runs' bracket; line has undecided/failed runs"),
    }
    pts = {k: ([], [], []) for k in groups}
    for b in rep["boundary"]:
        lo, hi = b.get(f"{hkey}_low"), b.get(f"{hkey}_high")
        status = b["status"]
        if lo is None or hi is None:
            continue
        if status == "bracketed":
            g = "verified" if b.get("verified") else "unverified"
        elif status in ("undecided", "failed") and b.get("decided_status") == "bracketed":
            g = "uncertain"
        else:
            continue
        pts[g][0].append(0.5 * (lo + hi))
        pts[g][1].append(b["x"])
        pts[g][2].append(0.5 * (hi - lo))
    for g, (color, ls, label) in groups.items():
        bx, by, berr = pts[g]
        if bx:
            eb = ax.errorbar(bx, by, xerr=berr, color=color, lw=1.2, capsize=2.5,
                             label=f"{label} ({len(bx)})")
            eb[-1][0].set_linestyle(ls)
            eb.lines[0].set_linestyle(ls)
    nonmono = [b for b in rep["boundary"] if b["status"] == "non-monotonic"]
    for b in nonmono:
        for t in b["transitions"]:
            v = 0.5 * (t["low"] + t["high"])
            if hkey != rep["variable"]:
                continue
            ax.plot(v, b["x"], "d", color="tab:orange", ms=5)
    if nonmono:
        ax.plot([], [], "d", color="tab:orange", label="non-monotonic line: outcome changes")
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
