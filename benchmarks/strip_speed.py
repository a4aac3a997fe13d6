"""Speed of `elastocap branches fig3-strip` (every branch, every contact topology).

    python3 benchmarks/strip_speed.py [--x 2] [--n N] [--no-refine] [--profile]

Times :func:`elastocap.strip.trace.trace_contact_branches` at the scene's default resolution
(n = 198 edges, refined run at 1.5 n for the error estimates) for each drop position x, as
`elastocap branches fig3-strip --set drop.distance_from_end=X` runs it, and prints the wall
time, the number of continuation steps, of contact events and the window with its error
estimate. ``--profile`` prints the 25 most expensive functions (cProfile, cumulative).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time

from elastocap.scene import load_scene
from elastocap.strip.trace import trace_contact_branches


def run(x, n=None, refine=True):
    sc = load_scene("fig3-strip", {"drop.distance_from_end": float(x)})
    t = time.perf_counter()
    bs = trace_contact_branches(sc, n=n, refine=refine)
    wall = time.perf_counter() - t
    steps = sum(len(s.delta) for br in bs.branches for s in br.segments)
    w = bs.window
    print(f"x = {x:g}: n = {bs.n} (refined {bs.metadata['n_edges_refined']}), "
          f"{len(bs.branches)} traced directions, {steps} points, {len(bs.events)} events, "
          f"{wall:.1f} s; open_max {w['open_max']['value']} ± "
          f"{w['open_max']['error_estimate']:.2g}, encapsulated_min "
          f"{w['encapsulated_min']['value']} ± {w['encapsulated_min']['error_estimate']:.2g}",
          flush=True)
    return wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--x", type=float, nargs="+", default=[2.0])
    ap.add_argument("--n", type=int, default=None)
    ap.add_argument("--no-refine", action="store_true")
    ap.add_argument("--profile", action="store_true")
    a = ap.parse_args()
    for x in a.x:
        if a.profile:
            pr = cProfile.Profile()
            pr.enable()
            run(x, a.n, not a.no_refine)
            pr.disable()
            pstats.Stats(pr, stream=sys.stdout).sort_stats("cumulative").print_stats(25)
        else:
            run(x, a.n, not a.no_refine)


if __name__ == "__main__":
    main()
