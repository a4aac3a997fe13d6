"""Every paper figure runs in fast mode and reproduces its key number (they cannot rot)."""

import json
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from elastocap.cli import main
from elastocap.paper_figures import FIGURES, run_figures


def _boxes_overlap(a, b, pad=0.0) -> bool:
    return a.x0 < b.x1 - pad and b.x0 < a.x1 - pad and a.y0 < b.y1 - pad and b.y0 < a.y1 - pad


def _glyph(handle) -> tuple:
    """What a legend entry's symbol looks like: its kind, colours, marker and line style."""
    from matplotlib.colors import to_rgba

    def rgba(c):
        try:
            return tuple(np.round(to_rgba(c), 3))
        except (ValueError, TypeError):
            return str(c)

    if hasattr(handle, "get_marker"):  # a Line2D
        return ("line", rgba(handle.get_color()), handle.get_marker(),
                rgba(handle.get_markerfacecolor()), rgba(handle.get_markeredgecolor()),
                handle.get_linestyle() if handle.get_linestyle() not in ("None", "") else "",
                round(float(handle.get_linewidth()), 1), handle.get_alpha())
    if hasattr(handle, "get_facecolor"):  # a patch or a collection
        fc = handle.get_facecolor()
        fc = fc[0] if np.ndim(fc) == 2 and len(fc) else fc
        ec = handle.get_edgecolor()
        ec = ec[0] if np.ndim(ec) == 2 and len(ec) else ec
        return (type(handle).__name__, rgba(fc), rgba(ec), str(handle.get_linestyle()))
    return (type(handle).__name__, id(handle))


def _coloured_entries(ax, leg) -> list[str]:
    from matplotlib.colors import to_rgba

    drawn = {to_rgba(ln.get_color()) for ln in ax.get_lines()
             if ln.get_visible() and len(ln.get_xdata()) >= 2 and ln.get_linestyle() != "None"}
    return [t.get_text() for t, h in zip(leg.get_texts(), leg.legend_handles, strict=True)
            if hasattr(h, "get_color") and to_rgba(h.get_color()) in drawn]


def _describe(fig) -> dict:
    """What a reader sees of a figure: its texts with their boxes, legends, axis labels."""
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    axes = []
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        leg = ax.get_legend()
        ticks = {}
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)) if ax.axison else ():
            ticks[name] = [
                t.get_window_extent(r)
                for t in axis.get_ticklabels()
                if t.get_visible() and t.get_text()
            ]
        axes.append(
            {
                "glyphs": [_glyph(h) for h in leg.legend_handles] if leg else [],
                # legend texts whose colour some drawn line of two or more points has
                "coloured": _coloured_entries(ax, leg) if leg else [],
                "texts": [(t.get_text(), t.get_window_extent(r)) for t in ax.texts
                          if t.get_visible() and t.get_text()],
                "legend": [t.get_text() for t in leg.get_texts()] if leg else [],
                "labels": [ax.get_xlabel(), ax.get_ylabel(), ax.get_title(),
                           ax.get_title("left")],
                "ticks": ticks,
            }
        )
    sup = fig._suptitle.get_text() if fig._suptitle is not None else ""
    return {"axes": axes, "suptitle": sup, "size_px": fig.canvas.get_width_height()}


@pytest.fixture(scope="module")
def figs(tmp_path_factory):
    """Every figure in fast mode; each figure is also described as it is saved."""
    from matplotlib.figure import Figure

    out = tmp_path_factory.mktemp("figs")
    seen = {}
    save = Figure.savefig

    def savefig(self, fname, *a, **kw):
        name = Path(str(fname)).name
        # an atomic write saves to ".STEM<mark><hex>.png" and renames it: key by the final name
        m = re.fullmatch(r"\.(.+?)\.tmp-[0-9a-f]+(\.\w+)", name)
        seen[m.group(1) + m.group(2) if m else name] = _describe(self)
        return save(self, fname, *a, **kw)

    import matplotlib
    import matplotlib.pyplot as plt

    def process_wide(*a, **kw):
        raise AssertionError("a figure touched process-wide matplotlib state (pyplot or "
                             "matplotlib.use); use elastocap.figure.new_figure")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Figure, "savefig", savefig)
        for name in ("figure", "subplots", "subplot_mosaic", "gcf", "gca"):
            mp.setattr(plt, name, process_wide)
        mp.setattr(matplotlib, "use", process_wide)
        written = run_figures(out, fast=True)
    return out, written, seen


def test_every_figure_writes_its_files(figs):
    out, written, _ = figs
    assert set(written) == set(FIGURES)
    for paths in written.values():
        for p in paths:
            assert p.stat().st_size > 200


def test_supp_fig6_fold(figs):
    out, _, _ = figs
    folds = json.loads((out / "supp-fig6.json").read_text())["folds"]
    # draft resolution (16 LGL intervals): fold error 1.4e-9 (README convergence table)
    assert len(folds) == 1 and folds[0]["value"] == pytest.approx(3.46979475157, abs=5e-9)


def test_bistability_curve_passes_through_the_fold(figs):
    out, _, _ = figs
    (curve,) = json.loads((out / "bistability.json").read_text())["curves"]
    import numpy as np

    a, d = np.array(curve["area"]), np.array(curve["delta"])
    # on the lower half (before the first extremum of A) Delta(A = 1.5) is the fold of supp-fig5
    k = int(np.argmax(a))
    assert np.interp(1.5, a[: k + 1], d[: k + 1]) == pytest.approx(3.4698, abs=2e-3)
    assert max(a) == pytest.approx(1.7449, abs=2e-3)  # the cusp
    # inside the admissible region Delta <= L = 4.6, ending on its boundary
    assert max(d) <= 4.6 * (1 + 1e-12) and d[-1] == pytest.approx(4.6, abs=1e-9)


def test_supp_fig5_outcomes(figs):
    out, _, _ = figs
    s = json.loads((out / "supp-fig5.json").read_text())
    assert s["a"]["outcome"] == "open" and s["b"]["outcome"] == "encapsulated"


def test_overlay_branch_reached(figs):
    out, _, _ = figs
    runs = json.loads((out / "overlay.json").read_text())["runs"]
    assert [r["branch_reached"] for r in runs][0] == "primary"
    assert runs[0]["outcome"] == "open"
    # the last run (Delta = 4.5 ~ L at draft) rests on the encapsulated branch; its verdict
    # may honestly be "undecided" (the run's undecided_reason says why)
    assert runs[-1]["branch_reached"] != "primary"
    assert runs[-1]["outcome"] in ("encapsulated", "undecided")


def test_figures_cli_rejects_unknown_name(capsys):
    assert main(["figures", "--only", "fig99"]) == 2
    assert "expected one of" in capsys.readouterr().err


def test_fig3d_fast_line(figs):
    out, _, _ = figs
    runs = json.loads((out / "fig3d.json").read_text())["runs"]
    # x = 3 l_eg (draft, damping 0.1): We^1/2 = 1 stays open, 2.5 encapsulates (README Fig 3d)
    got = {r["we_sqrt"]: r["outcome"] for r in runs}
    assert got == {1.0: "open", 2.5: "encapsulated"}


def test_fig3d_contact_fast_line(figs):
    """The same line with rod self-contact (draft): the same outcomes, no run crosses
    itself, and the title and the record name the thickness."""
    out, _, seen = figs
    d = json.loads((out / "fig3d-contact.json").read_text())
    got = {r["we_sqrt"]: r["outcome"] for r in d["runs"]}
    assert got == {1.0: "open", 2.5: "encapsulated"}
    assert all(r["rod_crossing_time"] is None for r in d["runs"])
    assert d["made_by"]["scene"]["rod"]["thickness"] == 0.0157
    fig = seen["fig3d-contact.png"]
    titles = [fig["suptitle"]] + [lab for ax in fig["axes"] for lab in ax["labels"]]
    assert any("self-contact (thickness 0.0157)" in t for t in titles), titles


def test_fig4_floppy_encapsulation(figs):
    out, _, _ = figs
    s = json.loads((out / "fig4_fig5.json").read_text())
    assert s["fig4B"]["outcome"] == "encapsulated" == s["fig4B"]["companion_outcome"]
    # fast mode: the sweep's one level, so nothing confirms the outcome under refinement
    (row,) = s["fig4B"]["levels"]
    assert row["n_edges"] == s["fig4B"]["n_edges"] == s["made_by"]["resolutions"][0]["n_edges"]
    assert s["fig4B"]["settled_from_edges"] is None


def test_an_outcome_settles_only_where_a_refined_run_agrees():
    from elastocap.paper_figures.fig4_fig5 import settled_from

    assert settled_from(["open", "open", "open"]) == 0
    assert settled_from(["encapsulated", "open", "open", "open"]) == 1
    assert settled_from(["open", "open", "encapsulated"]) is None  # the finest alone
    assert settled_from(["open", "undecided", "undecided"]) is None  # never a result
    assert settled_from(["open"]) is None  # no refined run


def test_contact_comparison_fast(figs):
    """Draft edges: contact never acts near Delta*, so the bisection's runs are the same run
    for run; at Delta = 4 the rod without a thickness crosses itself, with one it does not
    and keeps its gap; on the strip (fig4B) the folded layers rest exactly h apart."""
    out, _, _ = figs
    s = json.loads((out / "contact-comparison.json").read_text())
    free, thick = s["delta_star"]
    assert (free["low"], free["high"]) == (thick["low"], thick["high"])
    assert thick["status"] == "bracketed" and thick["max_measure_difference_vs_no_contact"] == 0
    assert 3.50 < free["delta_star"] < 3.55
    rows = {r["config"]: r for r in s["outcomes"]}
    assert rows["no-contact"]["rod_crossing_time"] is not None
    assert rows["d0.1-ignore"]["rod_crossing_time"] is None
    assert rows["d0.1-ignore"]["gap_at_rest_ok"] is True
    strip = {r["config"]: r for r in s["fig4_fig5"]}
    assert strip["contact-ignore"]["gap_at_rest"] == pytest.approx(0.0157, rel=1e-6)
    assert strip["contact-ignore"]["rod_crossing_time"] is None
    assert s["made_by"]["thickness"] == {"supp-fig5": 0.1, "fig3-strip": 0.0157}


def test_energy_barrier_string_and_graph_agree(figs):
    out, _, _ = figs
    d = json.loads((out / "energy_barrier.json").read_text())
    assert d["not_handled"]  # the limits are written into the output, not hidden
    # x = 3, Delta = 1.1, n = 60: the string method's saddle and the lowest barrier over
    # every traced saddle are independent searches; they agree to round-off (0.92459)
    (row,) = d["rows"]
    (g,) = d["graph"]
    assert row["status"] == "ok" and abs(row["barrier"] - g["lowest_barrier"]) < 1e-10


def test_every_json_record_says_what_made_it(figs):
    out, written, _ = figs
    for paths in written.values():
        for p in paths:
            if p.suffix == ".json":
                made = json.loads(p.read_text())["made_by"]
                assert made["elastocap"] and made["scene"]["name"]
                assert "accuracy" in made["numerics"]


# ---- what the figures show (drawing checks) --------------------------------------------


def test_every_figure_was_looked_at(figs):
    _, written, seen = figs
    pngs = {p.name for paths in written.values() for p in paths if p.suffix == ".png"}
    assert pngs <= set(seen), pngs - set(seen)


def test_legends_have_no_duplicate_entries(figs):
    _, _, seen = figs
    for name, d in seen.items():
        for ax in d["axes"]:
            assert len(ax["legend"]) == len(set(ax["legend"])), (name, ax["legend"])


def test_legend_symbols_tell_their_entries_apart(figs):
    """Two legend entries never share a symbol: a reader matches symbol to text."""
    _, _, seen = figs
    for name, d in seen.items():
        for ax in d["axes"]:
            by_glyph: dict = {}
            for text, glyph in zip(ax["legend"], ax["glyphs"], strict=True):
                by_glyph.setdefault(glyph, []).append(text)
            same = [t for t in by_glyph.values() if len(t) > 1]
            assert not same, (name, same)


def test_labels_use_mathtext_not_spelled_out_symbols(figs):
    _, _, seen = figs
    spelled = re.compile(r"\bDelta\b|\btheta\b|l_eg|\bpi\b|We\^|ℓ_")
    for name, d in seen.items():
        strings = [d["suptitle"]]
        for ax in d["axes"]:
            strings += ax["labels"] + ax["legend"] + [t for t, _ in ax["texts"]]
        for s in strings:
            plain = re.sub(r"\$[^$]*\$", " ", s)  # mathtext is what we want
            assert not spelled.search(plain), (name, s)


def test_no_overlapping_texts_or_tick_labels(figs):
    _, _, seen = figs
    for name, d in seen.items():
        for ax in d["axes"]:
            boxes = ax["texts"]
            for i in range(len(boxes)):
                for j in range(i + 1, len(boxes)):
                    assert not _boxes_overlap(boxes[i][1], boxes[j][1], pad=0.5), (
                        name, boxes[i][0], boxes[j][0])
            for ticks in ax["ticks"].values():
                for i in range(len(ticks) - 1):
                    for j in range(i + 1, len(ticks)):
                        assert not _boxes_overlap(ticks[i], ticks[j]), name


def test_branch_diagram_explains_every_marker_and_labels_shapes(figs):
    _, _, seen = figs
    d = seen["supp-fig6.png"]
    main, *panels = d["axes"]
    for entry in ("✕ fold", "□ branch point", "◆ equal energy (Maxwell)", "stable", "unstable",
                  "stable, inadmissible (crossing)", "unstable, inadmissible (crossing)"):
        assert entry in main["legend"], main["legend"]
    # every branch named in the legend is drawn in its colour somewhere
    assert not [t for t in main["legend"] if t.startswith("branch") and t not in main["coloured"]]
    titles = [p["labels"][2] for p in panels if p["labels"][2]]
    assert len(titles) == 4 and all(re.fullmatch(r"\([a-d]\)  Δ = \d\.\d\d", t) for t in titles)
    folds = [t for t, _ in main["texts"] if t.startswith("fold")]
    assert folds and all(re.match(r"fold Δ = \d\.\d{4}( ± \S+)?$", t) for t in folds)
    # each shape panel is marked on the curve by its letter: no leader lines
    assert sorted(t for t, _ in main["texts"] if len(t) == 1) == ["a", "b", "c", "d"]


def test_frame_strips_have_time_stamps_a_scale_bar_and_a_sensible_size(figs):
    _, _, seen = figs
    for name in ("supp-fig5a.png", "supp-fig5b.png", "fig4B.png"):
        d = seen[name]
        w, h = d["size_px"]
        assert 800 <= w <= 1600 and h >= 200 and w / h < 5, (name, w, h)
        stamps = [ax["labels"][3] for ax in d["axes"] if ax["labels"][3]]
        assert len(stamps) >= 4 and all(s.startswith("$t$ = ") for s in stamps), stamps
        bars = [t for ax in d["axes"] for t, _ in ax["texts"] if "ell_" in t]
        assert len(bars) == 1, bars


def _fake_run(delta, m_end, t_end=50.0):
    t = np.linspace(0.0, t_end, 200)
    m = m_end + 0.2 * np.exp(-t / 10) * np.cos(t)
    res = SimpleNamespace(simulation=SimpleNamespace(times=t), measure_history=m)
    run = {"wetted_length": delta, "outcome": "encapsulated" if m_end > 1 else "open"}
    return run, res


def test_overlay_final_markers_sit_at_their_delta(tmp_path):
    from elastocap.overlay import plot_overlay
    from elastocap.scene import load_scene
    from elastocap.statics.branches import trace_branches

    bs = trace_branches(load_scene("supp-fig5", {"numerics.accuracy": "draft"}),
                        error_estimates=False)
    pairs = [_fake_run(2.5, 0.34), _fake_run(4.0, 1.32)]
    fig = plot_overlay(bs, [p[0] for p in pairs], [p[1] for p in pairs], tmp_path / "o.png")
    ax = fig.axes[0]
    finals = [ln for ln in ax.lines if ln.get_marker() == "o" and ln.get_markersize() == 7
              and len(ln.get_xdata()) == 1]
    assert sorted(float(ln.get_xdata()[0]) for ln in finals) == [2.5, 4.0]
    paths = [ln for ln in ax.lines if len(ln.get_xdata()) == 200]
    assert [float(ln.get_xdata()[-1]) for ln in paths] == [2.5, 4.0]  # paths end at Δ
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "● at rest: encapsulated" in labels and "○ at rest: open" in labels
    assert len(labels) == len(set(labels))


def test_work_precision_labels_never_collide(tmp_path):
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    try:
        import wp_common
    finally:
        sys.path.pop(0)
    from matplotlib.figure import Figure

    # crowded like the AUTO comparison: five points within 10 % in time at the floor
    series = [
        {"label": "ours", "time": [0.15, 0.17, 0.18, 0.185, 0.19, 0.195, 0.2],
         "error": [1e-4, 1e-9, 3e-12, 1e-12, 1e-12, 1e-12, 1e-12],
         "notes": ["8", "16", "20", "24", "32", "40", "48"]},
        {"label": "peer", "time": [0.024, 0.0245, 0.025, 0.026, 0.03],
         "error": [3e-3, 2e-3, 1e-4, 1e-6, 1e-8], "notes": ["6", "8", "10", "12", "16"]},
    ]
    seen = {}
    save = Figure.savefig

    def savefig(self, fname, *a, **kw):
        seen["fig"] = _describe(self)
        return save(self, fname, *a, **kw)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Figure, "savefig", savefig)
        wp_common.wp_plot(tmp_path / "wp.png", series, "test")
    (ax,) = seen["fig"]["axes"]
    boxes = [b for _, b in ax["texts"]]
    assert len(boxes) >= 8  # most points keep their label
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            assert not _boxes_overlap(boxes[i], boxes[j])
    for ticks in ax["ticks"].values():
        for i in range(len(ticks)):
            for j in range(i + 1, len(ticks)):
                assert not _boxes_overlap(ticks[i], ticks[j])
