"""Strip statics (fig3-strip) speed and accuracy (run: python3 benchmarks/strip_speed.py).

1. trace_strip_branches at x = 2 per resolution: median wall time of 3 runs after a
   warm-up, continuation steps, the window's event values.
2. Lift-off point s_c of the wrapped state (x = 2, Delta = 1.16) against N per segment,
   error against N = 28: spectral convergence.
Prints tables; the README text quotes them.
"""


import numpy as np
from wp_common import median_time

from elastocap.scene import load_scene
from elastocap.statics.branches import newton
from elastocap.strip.branches import refine_state, seeds, strip_problem_for, trace_strip_branches


def main():
    scene = load_scene("fig3-strip", {"drop.distance_from_end": 2.0})
    print("| N | time | steps | lift_off_at_S1 | touchdown |")
    print("|---:|---:|---:|---:|---:|")
    for N in (12, 14, 20):
        t, bs = median_time(lambda N=N: trace_strip_branches(scene, N=N))
        steps = sum(len(b) for b in bs.branches)
        ev = {e["kind"]: e["value"] for e in bs.endpoints if e["kind"] != "endpoint"}
        print(f"| {N} | {t:.2f} s | {steps} | {ev.get('lift_off_at_S1', np.nan):.10f} | "
              f"{ev.get('touchdown', np.nan):.10f} |")
    sc = load_scene("fig3-strip", {"drop.distance_from_end": 2.0, "drop.wetted_length": 1.16})
    P16 = strip_problem_for(sc, N=16)
    u16 = next(v for v in (newton(P16, s, 1.16, 1e-12, max_iter=40) for s in seeds(P16))
               if v is not None and v[-1] < P16.s1)

    def lift_off(N):
        P = strip_problem_for(sc, N=N)
        _, v = refine_state(P16, u16, (N, N, N))
        return newton(P, v, 1.16, 1e-12, max_iter=40)[-1]

    ref = lift_off(28)
    print("\n| N per segment | s_c error |")
    print("|---:|---:|")
    for N in (4, 6, 8, 10, 12, 14, 16):
        print(f"| {N} | {abs(lift_off(N) - ref):.1e} |")
    print(f"\ns_c(N=28) = {ref:.13f}")


if __name__ == "__main__":
    main()
