"""Work-precision of the statics: fold location error against wall time, both node families.

The fold of supp-fig5 (encapsulated branch) is located from a nearby point by
``tests/statics/test_statics_convergence._fold_at`` (imported, not copied) at each N, for
LGL (Ritz-Galerkin, exact quadrature: spectral) and Chebyshev points with Clenshaw-Curtis
quadrature (algebraic, ~order 6). The error is against ``FOLD_REF`` of the same test module
(LGL at N = 40, 48, 64 agree to 2e-13). Time: median of 5 after a warm-up.

Run: ``python3 benchmarks/wp_statics.py`` (prints the table, writes docs/img/wp-statics.png).
"""

from __future__ import annotations

import argparse

from wp_common import IMG, load_record, median_time, save_record, table, wp_plot

NS = (6, 8, 10, 12, 16, 20, 24, 32, 40, 48, 64)


def rows(ns=NS, nodes_list=("lgl", "chebyshev"), repeat=5):
    from test_statics_convergence import FOLD_REF, _fold_at

    out = []
    for nodes in nodes_list:
        for N in ns:
            t, f = median_time(lambda N=N, nodes=nodes: _fold_at(N, nodes), repeat=repeat)
            out.append({"nodes": nodes, "N": N, "fold": f, "error": abs(f - FOLD_REF), "time": t})
    return {"reference": FOLD_REF, "rows": out}


def main(fast=False):
    rec = rows(ns=(8, 16, 24) if fast else NS, repeat=1 if fast else 5)
    for r in rec["rows"]:
        r["time_ms"] = 1e3 * r["time"]
    if not fast:
        save_record("statics", rec)
    _report_ms(rec, plot=not fast)
    return rec


def _report_ms(rec, plot=True):
    print(
        f"\n## statics: fold location error against wall time (reference {rec['reference']:.14f})"
    )
    print(
        table(
            rec["rows"],
            [
                ("nodes", "nodes", "s"),
                ("N", "N", "d"),
                ("fold", "fold Δ", ".13f"),
                ("error", "error", ".1e"),
                ("time_ms", "wall [ms]", ".1f"),
            ],
        )
    )
    series = []
    for nodes in ("lgl", "chebyshev"):
        rs = [r for r in rec["rows"] if r["nodes"] == nodes]
        series.append(
            {
                "label": "LGL (default)" if nodes == "lgl" else "Chebyshev + CC",
                "time": [r["time"] for r in rs],
                # an error of exactly 0 is drawn at the round-off floor
                "error": [max(r["error"], 1e-16) for r in rs],
                "notes": [f"{r['N']}" for r in rs],
            }
        )
    if plot:
        wp_plot(IMG / "wp-statics.png", series, "supp-fig5 fold location (labels: N)")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fast", action="store_true")
    ap.add_argument("--plot", action="store_true", help="redraw from out/wp/statics.json")
    a = ap.parse_args()
    if a.plot:
        _report_ms(load_record("statics"))
    else:
        main(a.fast)
