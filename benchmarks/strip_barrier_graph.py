"""Lowest barriers over every traced branch (elastocap.strip.barrier.barrier_graph), n = 143.

For x = 3 and 4 l_eg, all branches in Delta are traced (elastocap.strip.trace),
then at each Delta of the table every minimum and saddle they cross is listed with the
saddles' connections and the lowest (minimax) barrier of each open minimum. Prints the
table the README quotes and, for comparison, the string method's barrier
(elastocap.strip.barrier.barrier) at the same (x, Delta, n). About 5-10 min on 2 shared cores.

    python3 benchmarks/strip_barrier_graph.py [--n 143] [--fast]
"""

from __future__ import annotations

import argparse
import time

from elastocap.scene import load_scene
from elastocap.strip.barrier import barrier, barrier_graph
from elastocap.strip.model import discrete_strip_for
from elastocap.strip.trace import trace_contact_branches

CASES = {3.0: (0.9, 1.1, 1.25), 4.0: (1.1, 1.4)}
FAST = {3.0: (1.1,)}


def main(n=143, fast=False):
    cases = FAST if fast else CASES
    n = 60 if fast else n
    print(f"{'x':>4} {'Delta':>6} {'minima (E, kind)':42s} {'saddles (E: joins)':40s} "
          f"{'lowest barrier':>15} {'string':>9}")
    for x, deltas in cases.items():
        t0 = time.perf_counter()
        sc = load_scene("fig3-strip", {"drop.distance_from_end": x, "numerics.n_edges": n})
        bs = trace_contact_branches(sc, refine=False)
        t_trace = time.perf_counter() - t0
        for d in deltas:
            g = barrier_graph(bs, d)
            ref = barrier(discrete_strip_for(sc, n).with_(delta=d))
            mins = ", ".join(f"{m['energy']:.4f} {'enc' if m['encapsulated'] else 'open'}"
                             for m in g.minima)
            sads = ", ".join(f"{s['energy']:.4f}: {s['joins'][0]}-{s['joins'][1]}"
                             for s in g.saddles)
            low = min((b["barrier"] for b in g.barriers), default=float("nan"))
            print(f"{x:4g} {d:6.3g} {mins:42s} {sads:40s} {low:15.6f} "
                  f"{ref.barrier:9.6f} ({ref.status})")
        print(f"     (x = {x:g}: trace {t_trace:.0f} s)")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=143)
    ap.add_argument("--fast", action="store_true")
    a = ap.parse_args()
    main(a.n, a.fast)
