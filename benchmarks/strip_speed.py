"""Speed of `elastocap branches fig3-strip` (every branch, every contact topology).

    python3 benchmarks/strip_speed.py [--x 2] [--n N] [--no-refine] [--profile]
                                      [--baseline SRC]

Times :func:`elastocap.strip.trace.trace_contact_branches` at the scene's default resolution
(n = 198 edges, refined run at 1.5 n for the error estimates) for each drop position x, as
`elastocap branches fig3-strip --set drop.distance_from_end=X` runs it, and prints the wall
time and the CPU time of the process (on a shared machine the CPU time is the comparable
number), the number of continuation steps, of contact events and the window with its error
estimate. ``--profile`` prints the 25 most expensive functions (cProfile, cumulative).
``--baseline SRC`` also runs the same trace from another source tree (e.g. ``git archive
main elastocap continuation dynamics | tar -x -C /tmp/base``) in a subprocess at the same
time, and prints the ratios of the CPU and wall times.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import subprocess
import sys
import time

from elastocap.scene import load_scene
from elastocap.strip.trace import trace_contact_branches

_ONE = """
import json, sys, time
from elastocap.scene import load_scene
try:
    from elastocap.strip.trace import trace_contact_branches
except ImportError:
    from elastocap.strip.contact_branches import trace_contact_branches
x, n, refine = float(sys.argv[1]), sys.argv[2], sys.argv[3] == "1"
sc = load_scene("fig3-strip", {"drop.distance_from_end": x})
t, c = time.perf_counter(), time.process_time()
bs = trace_contact_branches(sc, n=None if n == "None" else int(n), refine=refine)
w = bs.window
print(json.dumps({"wall": time.perf_counter() - t, "cpu": time.process_time() - c,
                  "open_max": w["open_max"]["value"],
                  "encapsulated_min": w["encapsulated_min"]["value"]}))
"""


def baseline(src, x, n, refine):
    """The same trace from the source tree ``src`` in a subprocess (started now)."""
    env = {**os.environ, "PYTHONPATH": os.path.abspath(src)}
    return subprocess.Popen([sys.executable, "-c", _ONE, str(x), str(n), "1" if refine else "0"],
                            env=env, cwd="/", stdout=subprocess.PIPE, text=True)


def run(x, n=None, refine=True):
    sc = load_scene("fig3-strip", {"drop.distance_from_end": float(x)})
    t, c = time.perf_counter(), time.process_time()
    bs = trace_contact_branches(sc, n=n, refine=refine)
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    steps = sum(len(s.delta) for br in bs.branches for s in br.segments)
    w = bs.window
    print(f"x = {x:g}: n = {bs.n} (refined {bs.metadata['n_edges_refined']}), "
          f"{len(bs.branches)} traced directions, {steps} points, {len(bs.events)} events, "
          f"{wall:.1f} s wall, {cpu:.1f} s CPU; open_max {w['open_max']['value']} ± "
          f"{w['open_max']['error_estimate']:.2g}, encapsulated_min "
          f"{w['encapsulated_min']['value']} ± {w['encapsulated_min']['error_estimate']:.2g}",
          flush=True)
    return wall, cpu


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--x", type=float, nargs="+", default=[2.0])
    ap.add_argument("--n", type=int, default=None)
    ap.add_argument("--no-refine", action="store_true")
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--baseline", metavar="SRC", default=None)
    a = ap.parse_args()
    for x in a.x:
        if a.baseline:
            proc = baseline(a.baseline, x, a.n, not a.no_refine)
            wall, cpu = run(x, a.n, not a.no_refine)
            b = json.loads(proc.communicate()[0].strip().splitlines()[-1])
            print(f"  baseline ({a.baseline}): {b['wall']:.1f} s wall, {b['cpu']:.1f} s CPU, "
                  f"open_max {b['open_max']}, encapsulated_min {b['encapsulated_min']}; "
                  f"speed-up {b['cpu'] / cpu:.2f}x CPU, {b['wall'] / wall:.2f}x wall",
                  flush=True)
        elif a.profile:
            pr = cProfile.Profile()
            pr.enable()
            run(x, a.n, not a.no_refine)
            pr.disable()
            pstats.Stats(pr, stream=sys.stdout).sort_stats("cumulative").print_stats(25)
        else:
            run(x, a.n, not a.no_refine)


if __name__ == "__main__":
    main()
