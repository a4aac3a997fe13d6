"""Implicit-midpoint stepper vs RATTLE, side by side (not a test).

Prints, in one run on the same machine:

1. supp-fig5 impacts (100 edges, drop area 1.5, damping 0.2, built as
   ``elastocap.impact.run_impact`` builds them) at Delta = 2.5, 3.50, 3.55, 4.0: RATTLE at
   the impact run's default step and at half of it, and ``simulate(method="midpoint")`` at
   dt = k x the explicit bound ``stable_dt`` for k = 1, 4, 16, 64, 128: steps, wall time
   (median of repeats, interleaved), Newton iterations and factorisations per step, final
   measure M = (theta(L) - theta(0))/pi, its difference from RATTLE, the largest
   difference of M(t) on common frames (t <= 50, before either run stops), outcome;
2. the selection threshold Delta* by bisection on [3.50, 3.55] with RATTLE and with the
   implicit stepper at k = 16 and 64;
3. an undamped released wavy rod (40 edges, t = 200): relative energy error and drift;
4. wall time against N of a short supp-fig5 impact (RATTLE's N**3 against N);
5. Delta* from the implicit stepper at a fixed dt = 0.0152 at 100, 200, 400 edges;
6. whole impacts through ``elastocap.impact.run_impact`` (the CLI's path): fig3-strip
   damped (``effects.damping = 0.1``, as Fig 3d) and undamped (the scene as shipped),
   supp-fig5 at Delta = 2.5 and 4; RATTLE, and the implicit stepper at its automatic dt
   as it was (no force stiffness in the Newton matrix, a refactorisation at every contact
   change), with the drop's stiffness, and with both the stiffness and the low-rank
   contact updates (the default): wall time (median of interleaved repeats), steps, Newton
   iterations and factorisations per step, rejected steps, outcome, final measure M, end
   position x(L), energy rise;
7. fig3-strip at larger implicit steps (4, 8, 16, 32 x the explicit bound, the default
   stepper), against RATTLE and the implicit stepper at 2x: is a larger automatic dt
   usable with a ground (``elastocap.impact.IMPLICIT_GROUND_BOUND_MULTIPLE``)?

Usage: ``python benchmarks/dynamics_implicit.py [--fast] [--only 6,7]``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

from dynamics import Damping, RestCriterion, Rod, simulate, stable_dt
from elastocap import impact as _impact
from elastocap.capillary import Capillary
from elastocap.geometry import turning_measure
from elastocap.scene import load_scene

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests", "dynamics"))
from dyn_helpers import rod_from_angles, simulate_midpoint  # noqa: E402

L, AREA, GAMMA, DAMPING, N_EDGES = 4.6, 1.5, 1.0, 0.2, 100
#: RATTLE's step in the impact run (fraction of the explicit bound), read from elastocap
RATTLE_FRACTION = _impact.DT_FRACTION
FRAME_DT = 0.5


def impact_rod(n=N_EDGES):
    x0 = np.zeros((n + 1, 2))
    x0[:, 0] = np.linspace(0.0, L, n + 1)
    return Rod(x0, np.zeros_like(x0), np.full(n, L / n), 1.0, 1.0)


def run(delta, method, k, n=N_EDGES, t_max=200.0, dt=None):
    """One supp-fig5 impact; ``method`` "rattle" (k = fraction of the bound) or
    "implicit" (k = multiple of the bound), unless ``dt`` is given."""
    rod = impact_rod(n)
    effects = (Capillary(AREA, L / 2 - delta / 2, L / 2 + delta / 2, GAMMA),
               Damping(DAMPING))
    dt = dt or k * stable_dt(rod.edge_len, rod.mu, rod.B)
    frames = np.arange(0.0, t_max + 1e-9, FRAME_DT)
    rest = RestCriterion(1e-6 * GAMMA * delta, 1.0)
    f = simulate if method == "rattle" else simulate_midpoint
    t = time.perf_counter()
    r = f(rod, effects, dt=dt, t_end=t_max, frames=frames, rest=rest)
    wall = time.perf_counter() - t
    M = np.array([turning_measure(p) for p in r.positions])
    return r, M, wall


def row(label, r, M, walls, ref_M=None, ref_hist=None, ref_times=None):
    Mf = M[-1]
    dM = "" if ref_M is None else f"{Mf - ref_M:+.1e}"
    traj = ""
    if ref_hist is not None:
        m = min(len(ref_hist), len(M))
        tt = r.times[:m]
        sel = tt <= 50.0
        traj = f"{np.max(np.abs(M[:m][sel] - ref_hist[:m][sel])):.1e}"
    it = r.stats["iterations_mean"]
    fac = getattr(r, "jacobians", None)
    fac = "" if fac is None else f"{fac / max(r.steps, 1):.2f}"
    out = "encaps" if Mf > 1 else "open"
    print(f"{label:16s} {r.dt:8.2e} {r.steps:7d} {np.median(walls):7.3f} {it:5.2f} {fac:>5s} "
          f"{Mf:9.5f} {dM:>8s} {traj:>8s} {r.t_final:6.1f} {out:7s} {r.status}")


def bench_impacts(deltas, ks, repeat):
    print("\n== 1. supp-fig5 impacts, 100 edges (wall: median of "
          f"{repeat}, interleaved; RATTLE at {RATTLE_FRACTION} x bound is the reference)")
    hdr = (f"{'stepper':16s} {'dt':>8s} {'steps':>7s} {'wall s':>7s} {'it':>5s} {'fac':>5s} "
           f"{'M final':>9s} {'dM':>8s} {'dM(t)':>8s} {'t_end':>6s} outcome")
    for delta in deltas:
        print(f"\n-- Delta = {delta}")
        print(hdr)
        cases = [("rattle", RATTLE_FRACTION), ("rattle", RATTLE_FRACTION / 2)]
        cases += [("implicit", k) for k in ks]
        res = {c: None for c in cases}
        walls = {c: [] for c in cases}
        for _ in range(repeat):
            for c in cases:
                r, M, w = run(delta, *c)
                res[c] = (r, M)
                walls[c].append(r.stats["run_time"])
        ref_r, ref_M = res[cases[0]]
        for c in cases:
            r, M = res[c]
            label = f"RATTLE {c[1]:.3g}xb" if c[0] == "rattle" else f"implicit {c[1]:g}xb"
            if c == cases[0]:
                row(label, r, M, walls[c])
            else:
                row(label, r, M, walls[c], ref_M[-1], ref_M)


def bisect(method, k, lo=3.50, hi=3.55, steps=10, n=N_EDGES, dt=None):
    t = time.perf_counter()
    n_runs = 0
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        r, M, _ = run(mid, method, k, n=n, dt=dt)
        n_runs += 1
        if not r.success:
            return math.nan, math.nan, n_runs, time.perf_counter() - t
        if M[-1] > 1.0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi), 0.5 * (hi - lo), n_runs, time.perf_counter() - t


def bench_threshold(ks, steps):
    print(f"\n== 2. threshold Delta* by bisection on [3.50, 3.55], {steps} runs each "
          "(README: RATTLE 100 edges 3.52726, Richardson 3.52624)")
    for method, k in [("rattle", RATTLE_FRACTION)] + [("implicit", k) for k in ks]:
        d, pm, nr, w = bisect(method, k, steps=steps)
        label = f"RATTLE {k:.3g}xb" if method == "rattle" else f"implicit {k:g}xb"
        print(f"{label:16s} Delta* = {d:.5f} +- {pm:.1e}   {nr} runs {w:6.2f} s "
              f"({w / nr:.3f} s/run)   vs Richardson {d - 3.52624:+.1e}")


def bench_threshold_refined(steps, dt=0.0152):
    print(f"\n== 5. Delta* with the implicit stepper at a fixed dt = {dt} under refinement in N "
          "(README, RATTLE: 50 -> 3.52979, 100 -> 3.52726, 200 -> 3.52649 at 8.7 s/impact; "
          "Richardson 3.52624)")
    for n in (100, 200, 400):
        b = stable_dt(np.full(n, L / n), 1.0, 1.0)
        d, pm, nr, w = bisect("implicit", None, lo=3.51, hi=3.54, steps=steps, n=n, dt=dt)
        print(f"N = {n:3d} ({dt / b:4.0f}x bound)  Delta* = {d:.5f} +- {pm:.1e}  {nr} runs "
              f"{w:6.2f} s ({w / nr:.3f} s/run)   vs Richardson {d - 3.52624:+.1e}")


def wavy_rod(n=40, amp=0.3):
    h = 4.6 / n
    s = (np.arange(n) + 0.5) * h
    return rod_from_angles(amp * np.sin(2 * np.pi * s / 4.6), h)


def bench_energy(ks, t_end):
    print(f"\n== 3. undamped released wavy rod (40 edges, amplitude 0.3), t = {t_end:g}: "
          "max |E - E0| / E_bend(0), drift = mean of last tenth - first tenth")
    rod = wavy_rod()
    b = stable_dt(rod.edge_len, 1.0, 1.0)
    r = simulate(rod, (), dt=0.9 * b, t_end=t_end, frames=1001)
    E = r.energies["total"]
    sc = r.energies["bending"][0]
    print(f"RATTLE 0.9xb     {r.steps:7d} steps {r.stats['run_time']:6.3f} s  err "
          f"{np.abs(E - E[0]).max() / sc:.2e}  drift "
          f"{abs(E[-100:].mean() - E[:100].mean()) / sc:.1e}  "
          f"constraint {r.stats['constraint_error']:.1e}")
    for k in ks:
        r = simulate_midpoint(rod, (), dt=k * b, t_end=t_end, frames=1001)
        E = r.energies["total"]
        print(f"implicit {k:4g}xb  {r.steps:7d} steps {r.stats['run_time']:6.3f} s  err "
              f"{np.abs(E - E[0]).max() / sc:.2e}  drift "
              f"{abs(E[-100:].mean() - E[:100].mean()) / sc:.1e}  "
              f"constraint {r.stats['constraint_error']:.1e}  it {r.stats['iterations_mean']:.2f}")


def bench_scaling(t_end=10.0):
    print(f"\n== 4. wall time vs N, supp-fig5 impact at Delta = 4 to t = {t_end:g} "
          "(RATTLE at its impact step, implicit at a fixed dt = 0.02)")
    for n in (50, 100, 200, 400):
        rod = impact_rod(n)
        eff = lambda: (Capillary(AREA, L / 2 - 2, L / 2 + 2, GAMMA), Damping(DAMPING))  # noqa: E731
        b = stable_dt(rod.edge_len, 1.0, 1.0)
        line = f"N = {n:4d}: "
        if n <= 200:
            r = simulate(rod, eff(), dt=RATTLE_FRACTION * b, t_end=t_end, frames=2)
            line += f"RATTLE {r.steps:7d} steps {r.stats['run_time']:7.3f} s | "
        r = simulate_midpoint(rod, eff(), dt=0.02, t_end=t_end, frames=2)
        line += (f"implicit {r.steps:5d} steps {r.stats['run_time']:6.3f} s "
                 f"({0.02 / b:.0f}x bound, {r.stats['iterations_mean']:.2f} it/step)")
        print(line)


#: The implicit stepper's variants of section 6: (label, keyword arguments).
IMPLICIT_VARIANTS = (
    ("implicit, as before", dict(stiffness=False, contact_updates=False)),
    ("implicit +stiffness", dict(stiffness=True, contact_updates=False)),
    ("implicit +contact upd", dict(stiffness=True, contact_updates=True)),
)


def impact_run(scene, overrides, integrator, kwargs=None, dt_multiple=None):
    """One ``run_impact`` with the midpoint method's options ``kwargs`` and optionally
    dt = multiple x dt_max."""
    ov = dict(overrides, **{"numerics.integrator": integrator})
    if dt_multiple is not None:
        ov["numerics.dt"] = dt_multiple * _impact.impact_settings(load_scene(scene, ov))["dt_max"]
    return _impact.run_impact(load_scene(scene, ov), **(kwargs or {}))


def impact_row(label, res, walls, ref=None):
    s = res.simulation
    fac = getattr(s, "jacobians", None)
    fac = "" if fac is None else f"{fac / max(s.steps, 1):.2f}"
    dM = "" if ref is None else f"{res.final_measure - ref.final_measure:+.1e}"
    print(f"{label:23s} {res.settings['dt']:8.2e} {s.steps:7d} {np.median(walls):7.2f} "
          f"{s.stats['iterations_mean']:5.2f} {fac:>5s} {s.stats['rejected_steps']:5d} "
          f"{res.outcome:12s} {res.final_measure:9.5f} {dM:>8s} {res.end_position:9.4f} "
          f"{res.energy_rise:8.1e} {res.t_end:6.1f} {res.status}")


IMPACT_HDR = (f"{'stepper':23s} {'dt':>8s} {'steps':>7s} {'wall s':>7s} {'it':>5s} "
              f"{'fac':>5s} {'rej':>5s} {'outcome':12s} {'M final':>9s} {'dM':>8s} "
              f"{'x(L)':>9s} {'rise':>8s} {'t_end':>6s} status")

#: The impacts of section 6: (label, scene, overrides).
IMPACTS = (
    ("fig3-strip damped 0.1", "fig3-strip", {"effects.damping": 0.1}),
    ("fig3-strip undamped", "fig3-strip", {}),
    ("supp-fig5 Delta 2.5", "supp-fig5", {"drop.wetted_length": 2.5}),
    ("supp-fig5 Delta 4", "supp-fig5", {"drop.wetted_length": 4.0}),
)


def bench_whole_impacts(repeat, cases=IMPACTS):
    print(f"\n== 6. whole impacts (run_impact), automatic dt, wall: median of {repeat} "
          "interleaved; dM against RATTLE; it = Newton iterations a step, fac = "
          "factorisations a step, rej = rejected steps")
    for label, scene, ov in cases:
        print(f"\n-- {label}")
        print(IMPACT_HDR)
        variants = [("RATTLE", "rattle", None)] + [
            (lab, "implicit", kw) for lab, kw in IMPLICIT_VARIANTS]
        res, walls = {}, {v[0]: [] for v in variants}
        for _ in range(repeat):
            for lab, integ, kw in variants:
                res[lab] = impact_run(scene, ov, integ, kw)
                walls[lab].append(res[lab].simulation.stats["run_time"])
        for lab, _, _ in variants:
            impact_row(lab, res[lab], walls[lab], None if lab == "RATTLE" else res["RATTLE"])


def bench_ground_dt(repeat, multiples=(2, 4, 8, 16, 32)):
    print("\n== 7. fig3-strip at larger implicit steps (numerics.dt = k x dt_max, the "
          f"default implicit stepper; wall: median of {repeat}); the automatic dt is now "
          f"{_impact.IMPLICIT_GROUND_BOUND_MULTIPLE:g} x dt_max")
    for label, scene, ov in IMPACTS[:2]:
        print(f"\n-- {label}")
        print(IMPACT_HDR)
        variants = [("RATTLE", "rattle", None)] + [(f"implicit {k:g}x", "implicit", k)
                                                   for k in multiples]
        res, walls = {}, {v[0]: [] for v in variants}
        for _ in range(repeat):
            for lab, integ, k in variants:
                res[lab] = impact_run(scene, ov, integ, {}, k)
                walls[lab].append(res[lab].simulation.stats["run_time"])
        for lab, _, _ in variants:
            impact_row(lab, res[lab], walls[lab], None if lab == "RATTLE" else res["RATTLE"])


def main(fast=False, only=None):
    print(f"RATTLE impact step: {RATTLE_FRACTION} x bound; explicit bound at 100 edges "
          f"{stable_dt(np.full(N_EDGES, L / N_EDGES), 1, 1):.3e}")
    only = set(only or range(1, 8))
    # compile / load every stepper once
    run(2.5, "rattle", RATTLE_FRACTION, t_max=0.1)
    run(2.5, "implicit", 16, t_max=0.1)
    ks = (4, 16, 64) if fast else (1, 4, 16, 64, 128)
    if 1 in only:
        bench_impacts((2.5, 4.0) if fast else (2.5, 3.50, 3.55, 4.0), ks, 1 if fast else 3)
    if 2 in only:
        bench_threshold((16, 64), 4 if fast else 10)
    if 3 in only:
        bench_energy((4, 16, 64), 60.0 if fast else 200.0)
    if not fast and 4 in only:
        bench_scaling()
    if not fast and 5 in only:
        bench_threshold_refined(10)
    if 6 in only or 7 in only:
        for _, scene, ov in IMPACTS:  # compile / load
            impact_run(scene, {**ov, "numerics.t_max": 0.1}, "rattle")
            impact_run(scene, {**ov, "numerics.t_max": 0.1}, "implicit")
    if 6 in only:
        bench_whole_impacts(1 if fast else 3, IMPACTS[::2] if fast else IMPACTS)
    if 7 in only:
        bench_ground_dt(1 if fast else 3, (4, 16) if fast else (2, 4, 8, 16, 32))


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fast", action="store_true")
    ap.add_argument("--only", default="", help="comma-separated section numbers, e.g. 6,7")
    a = ap.parse_args()
    main(fast=a.fast, only=[int(v) for v in a.only.split(",") if v] or None)
