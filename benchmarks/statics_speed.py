"""Statics speed and work-precision on supp-fig5 (run: python3 benchmarks/statics_speed.py).

1. The whole supplementary Fig 6 diagram (search, every branch, every fold located, error
   estimates) per resolution: median wall time of 5 runs after a warm-up (numba compiled),
   continuation steps, time per step.
2. Fold location error against wall time for both node families (error against the LGL
   value at N = 48).
Prints tables; the README quotes them.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from wp_common import median_time  # noqa: E402  (also puts tests/statics on the path)

from elastocap.scene import load_scene  # noqa: E402
from elastocap.statics.branches import trace_branches  # noqa: E402


def main():
    print("## whole supp-fig5 diagram (search + all branches + folds + error estimates)")
    print("| N (LGL) | branches | fold Δ | error estimate | median wall [s] | steps | ms/step |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for N in (16, 24, 40):
        scene = load_scene("supp-fig5", {"numerics.cheb_points": N})
        t, bs = median_time(lambda scene=scene: trace_branches(scene), repeat=5)
        steps = sum(len(b) for b in bs.branches)
        f = bs.folds[0]
        print(f"| {N} | {len(bs.branches)} | {f['value']:.12f} | {f['error_estimate']:.1e} | "
              f"{t:.3f} | {steps} | {1e3 * t / steps:.2f} |")
    from test_statics_convergence import _fold_at

    ref = _fold_at(48, "lgl")
    print("\n## fold error against wall time (one fold location from a nearby point)")
    print("| nodes | N | fold error | median wall [ms] |")
    print("|---|---:|---:|---:|")
    for nodes in ("lgl", "chebyshev"):
        for N in (8, 12, 16, 20, 24, 32, 48):
            t, f = median_time(lambda N=N, nodes=nodes: _fold_at(N, nodes), repeat=5)
            print(f"| {nodes} | {N} | {abs(f - ref):.1e} | {1e3 * t:.1f} |")


if __name__ == "__main__":
    main()
