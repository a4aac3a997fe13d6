"""Shared helpers of the work-precision benchmarks (``benchmarks/wp_*.py``).

Timing (median after a warm-up, so numba compilation is never counted), markdown tables,
log-log work-precision plots, and a small JSON record of every measured table in ``out/wp/``
(so that a plot can be redrawn without re-measuring: ``python3 benchmarks/wp_all.py --plot``).
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IMG = ROOT / "docs" / "img"
OUT = ROOT / "out" / "wp"

# the reference helpers live in the tests; import them rather than copying them
for sub in ("statics", "dynamics"):
    p = str(ROOT / "tests" / sub)
    if p not in sys.path:
        sys.path.insert(0, p)


def median_time(fn, repeat=3, warmup=True):
    """(median wall time [s], last result) of ``fn()`` over ``repeat`` calls."""
    if warmup:
        fn()
    ts, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts), out


def table(rows: list[dict], cols: list[tuple[str, str, str]]) -> str:
    """Markdown table. ``cols``: (key, header, format spec, e.g. ".2e")."""
    head = "| " + " | ".join(h for _k, h, _f in cols) + " |"
    rule = "|" + "|".join("---" if f == "s" else "---:" for _k, _h, f in cols) + "|"
    lines = [head, rule]
    for r in rows:
        cells = []
        for k, _h, f in cols:
            v = r.get(k)
            cells.append("—" if v is None else (str(v) if f == "s" else format(v, f)))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def save_record(name: str, record: dict) -> Path:
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f"{name}.json"
    path.write_text(json.dumps(record, indent=1, default=float))
    return path


def load_record(name: str) -> dict:
    return json.loads((OUT / f"{name}.json").read_text())


def wp_plot(
    path: Path, series: list[dict], title: str, xlabel="wall time [s]", ylabel="error"
) -> Path:
    """Log-log error against wall time; ``series``: dicts with label, time, error, notes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.6, 4.0), dpi=110)
    for s in series:
        pts = [
            (t, e, n)
            for t, e, n in zip(
                s["time"], s["error"], s.get("notes", [""] * len(s["time"])), strict=True
            )
            if e is not None and e > 0 and t is not None
        ]
        if not pts:
            continue
        t, e, n = zip(*pts, strict=True)
        ax.loglog(t, e, "o-", label=s["label"], ms=4)
        for ti, ei, ni in zip(t, e, n, strict=True):
            if ni:
                ax.annotate(
                    str(ni), (ti, ei), fontsize=7, xytext=(3, 3), textcoords="offset points"
                )
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
