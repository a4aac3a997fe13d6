"""The phase diagram of a sweep, drawn like Antkowiak et al. 2011, Fig 3d.

Open circles: open (not encapsulated); filled dots: encapsulated (the paper's criterion);
a red ring: the companion criterion (:mod:`elastocap.criteria`) disagrees. The boundary is
drawn through the refined brackets' midpoints with the half-width as a horizontal error
bar. x/l_eg on the vertical axis, We^1/2 (or Delta) on the horizontal one. Optional
experimental points (a CSV with columns x_over_leg, we_sqrt, outcome) as squares.
"""

from __future__ import annotations

import csv
from pathlib import Path

__all__ = ["load_experiments", "plot_phase_diagram"]

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
    runs = rep["runs"]
    use_we = bool(runs) and all(r.get("we_sqrt") is not None for r in runs)
    hkey = "we_sqrt" if use_we else "wetted_length"
    fig = Figure(figsize=(8.0, 4.8), dpi=130)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for outcome, style in (("open", {"mfc": "none"}), ("encapsulated", {"mfc": "k"})):
        pts = [r for r in runs if r["outcome"] == outcome]
        ax.plot(
            [r[hkey] for r in pts],
            [r["x"] for r in pts],
            "o",
            mec="k",
            ms=4.5,
            ls="none",
            label="not encapsulated" if outcome == "open" else "encapsulated",
            **style,
        )
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
    bx, by, berr = [], [], []
    for b in rep["boundary"]:
        lo, hi = b.get(f"{hkey}_low"), b.get(f"{hkey}_high")
        if b["status"] == "bracketed" and lo is not None and hi is not None:
            bx.append(0.5 * (lo + hi))
            berr.append(0.5 * (hi - lo))
            by.append(b["x"])
    if bx:
        ax.errorbar(
            bx,
            by,
            xerr=berr,
            color="tab:blue",
            lw=1.2,
            capsize=2.5,
            label="boundary (bracket midpoint ± half-width)",
        )
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
    ax.set_title(
        title or f"{rep['scene']}: phase diagram ({len(runs)} runs, elastocap {rep['version']})",
        fontsize=9,
    )
    ax.grid(alpha=0.25)
    # outside the axes, on the right: a legend inside would hide points of the diagram
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    if path is not None:
        fig.savefig(path, bbox_inches="tight")
    return fig
