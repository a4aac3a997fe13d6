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

import numpy as np

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


#: Offsets (points) tried in turn for a point label, nearest first.
_LABEL_OFFSETS = [(4, 4), (4, -10), (-4, 4), (-4, -10), (8, -3), (-8, -3), (0, 9), (0, -14),
                  (12, 8), (-12, 8), (12, -14), (-12, -14), (16, -3), (-16, -3), (0, 16),
                  (0, -22), (20, 12), (-20, 12), (20, -18), (-20, -18)]


def _overlaps(bb, others, pad=1.0) -> bool:
    return any(bb.x0 < o.x1 + pad and o.x0 < bb.x1 + pad and bb.y0 < o.y1 + pad
               and o.y0 < bb.y1 + pad for o in others)


def _line_samples(ax, step_px=1.5):
    """Points every ``step_px`` pixels along every line drawn on ``ax`` (display space)."""
    out = []
    for ln in ax.get_lines():
        if ln.get_linestyle() in ("None", "", " ") or not ln.get_visible():
            continue
        xy = ax.transData.transform(np.column_stack([ln.get_xdata(), ln.get_ydata()]))
        for a, b in zip(xy[:-1], xy[1:], strict=True):
            k = max(2, int(np.hypot(*(b - a)) / step_px) + 1)
            out.append(a + np.linspace(0.0, 1.0, k)[:, None] * (b - a))
    return np.vstack(out) if out else np.zeros((0, 2))


def _crosses(bb, samples, pad=1.0) -> bool:
    return bool(np.any((samples[:, 0] > bb.x0 - pad) & (samples[:, 0] < bb.x1 + pad)
                       & (samples[:, 1] > bb.y0 - pad) & (samples[:, 1] < bb.y1 + pad)))


def place_point_labels(ax, items, fontsize=7):
    """Annotate points so that no label overlaps another label, a marker, a line or the axes
    edge.

    ``items``: (x, y, text, color) in data coordinates. Each label takes the first offset of
    ``_LABEL_OFFSETS`` where it is clear; a label with no clear place is dropped rather than
    drawn over another (the tables beside the figures carry every number). Returns the
    labels drawn.
    """
    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    marker_boxes = []
    from matplotlib.transforms import Bbox

    for x, y, _txt, _c in items:
        px, py = ax.transData.transform((x, y))
        marker_boxes.append(Bbox([[px - 3, py - 3], [px + 3, py + 3]]))
    frame = ax.get_window_extent(renderer)
    samples = _line_samples(ax)
    placed, boxes = [], []
    for x, y, txt, color in items:
        for dx, dy in _LABEL_OFFSETS:
            ha = "left" if dx > 0 else "right" if dx < 0 else "center"
            a = ax.annotate(txt, (x, y), xytext=(dx, dy), textcoords="offset points",
                            fontsize=fontsize, color=color, ha=ha, va="bottom")
            bb = a.get_window_extent(renderer)
            inside = (bb.x0 >= frame.x0 and bb.x1 <= frame.x1 and bb.y0 >= frame.y0
                      and bb.y1 <= frame.y1)
            if (inside and not _overlaps(bb, boxes) and not _overlaps(bb, marker_boxes, 0.0)
                    and not _crosses(bb, samples)):
                placed.append(a)
                boxes.append(bb)
                break
            a.remove()
    return placed


def _log_ticks(axis, lo, hi):
    """Plain numbers on a log axis; 1-2-5 ticks when it spans less than two decades."""
    import math

    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    decades = math.log10(hi / lo) if lo > 0 and hi > lo else 3.0
    if decades < 2.0:
        axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def wp_plot(
    path: Path, series: list[dict], title: str, xlabel="wall time [s]", ylabel="error"
) -> Path:
    """Log-log error against wall time; ``series``: dicts with label, time, error, notes.

    Point labels (``notes``) are placed where they overlap nothing; the legend sits outside
    the axes, so it hides no point.
    """
    from elastocap.figure import new_figure

    fig = new_figure((7.4, 4.2), dpi=110)
    ax = fig.add_subplot()
    items, ts, es = [], [], []
    for k, s in enumerate(series):
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
        color = f"C{k % 10}"
        ax.loglog(t, e, "o-", label=s["label"], ms=4, color=color)
        ts += t
        es += e
        items += [(ti, ei, str(ni), color) for ti, ei, ni in zip(t, e, n, strict=True) if ni]
    if ts:
        ax.set_xlim(min(ts) / 1.25, max(ts) * 1.25)
        ax.set_ylim(min(es) / 2.5, max(es) * 2.5)
        _log_ticks(ax.xaxis, *ax.get_xlim())
        _log_ticks(ax.yaxis, *ax.get_ylim())
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    ax.grid(True, which="minor", alpha=0.1)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    fig.tight_layout()
    place_point_labels(ax, items)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    return path
