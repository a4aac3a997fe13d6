"""Work-precision of the dynamics: error against wall time over N (edges) and dt.

Three measured errors (run: ``python3 benchmarks/wp_dynamics.py [--fast] [--only PART]``):

1. ``shape``: the damped supp-fig5 impact at Delta = 2.5 (built-in damping 0.2) comes to
   rest on the flat branch; error of the final measure M against the statics equilibrium at
   the same Delta (LGL N = 40, converged to round-off).
2. ``frequency``: relative error of the clamped-free first-mode angular frequency against
   Euler-Bernoulli (``dynamics.reference.euler_bernoulli_omega``), measured as in
   ``tests/dynamics/test_dyn_validation.py`` but with dt as a fraction of the bound.
3. ``threshold``: the selection threshold Delta* of supp-fig5 (damping 0.2), found by
   bisection on Delta for the flip open -> encapsulated, against the finest affordable
   resolution (200 edges, dt = 1/4 of the bound).

dt is given as a fraction of the explicit bound ``dynamics.stable_dt`` (0.5 is the default
of ``elastocap impact``). Times: one run each for the impacts (seconds long, the machine is
shared: +-10 %), median of 3 for the frequency runs; numba compilation excluded (warm-up).
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np
from wp_common import IMG, OUT, load_record, median_time, save_record, table, wp_plot

from dynamics import Clamp, euler_bernoulli_omega, simulate, stable_dt
from dynamics.reference import crossing_period
from elastocap.impact import run_impact
from elastocap.scene import load_scene

SHAPE_DELTA = 2.5
#: Bisection bracket for Delta*: below the static fold (3.4698) nothing can encapsulate;
#: 3.62 encapsulates at every resolution measured. Width / 2^9 = 2.5e-4.
THRESHOLD_BRACKET = (3.47, 3.60)
THRESHOLD_TOL = 2.6e-4
GRID = [(50, 0.5), (50, 0.25), (100, 0.5), (100, 0.25), (200, 0.5), (200, 0.25)]
REFERENCE = (200, 0.25)


def _scene(delta, n, frac):
    base = load_scene("supp-fig5", {"drop.wetted_length": delta, "numerics.n_edges": n})
    dt_max = stable_dt(np.full(n, base.rod.length / n), 1.0, base.rod.bending_modulus)
    return base.with_overrides({"numerics.dt": frac * dt_max})


def _warmup():
    # compile (or load from cache) the capillary + damping stepper once
    run_impact(load_scene("supp-fig5", {"numerics.n_edges": 20, "numerics.t_max": 0.5}))


# --------------------------------------------------------------------------- 1. final shape
def statics_measure(delta=SHAPE_DELTA, N=40):
    """M of the flat-branch equilibrium at ``delta`` (LGL N = 40: round-off converged)."""
    from elastocap.statics.branches import newton, problem_for

    P = problem_for(load_scene("supp-fig5", {"drop.wetted_length": delta}), N=N)
    u = newton(P, np.concatenate([0.5 * np.pi * 0.3 * P.xi, [0.0]]), delta, 1e-13)
    return P.observables(u, delta)["measure"]


#: numerics.rest_kinetic values of the shape study: the default 1e-6 stops the damped run
#: while it still creeps (error ~2e-3 whatever N); 1e-14 reaches the discretization error.
REST_LEVELS = (1e-6, 1e-10, 1e-14)


def shape_rows(grid, rest_levels=REST_LEVELS):
    ref = statics_measure()
    rows = []
    for n, frac in grid:
        for rk in rest_levels if frac == 0.5 else rest_levels[:1]:
            sc = _scene(SHAPE_DELTA, n, frac).with_overrides({"numerics.rest_kinetic": rk})
            r = run_impact(sc)
            rows.append(
                {
                    "n": n,
                    "frac": frac,
                    "rest": rk,
                    "M": r.final_measure,
                    "error": abs(r.final_measure - ref),
                    "time": r.wall_time_s,
                    "t_end": r.t_end,
                    "steps": r.steps,
                    "status": r.status,
                }
            )
    return {"reference_M": ref, "rows": rows}


# --------------------------------------------------------------------------- 2. frequency
def frequency_error(n_edges, frac, kind="clamped-free", periods=5, amplitude=1e-4):
    """(relative first-mode frequency error, wall time of the run) at dt = frac * bound.

    Set-up of ``tests/dynamics/test_dyn_validation.first_mode_frequency_error`` (the mode
    shape and the rod builder are imported from there); only dt differs.
    """
    from dyn_helpers import rod_from_angles
    from test_dyn_validation import _mode

    L = 1.0
    omega = euler_bernoulli_omega(kind, L, 1.0, 1.0)
    h = L / (n_edges - 0.5)
    s = (np.arange(n_edges + 1) - 0.5) * h
    phi = _mode(kind, np.clip(s, 0.0, None), L)
    theta = amplitude * np.diff(phi) / h
    theta[0] = 0.0
    effects = (Clamp(0, (s[0], 0.0), angle=0.0),)
    rod = rod_from_angles(theta, h, origin=(s[0], 0.0))
    T = 2 * np.pi / omega
    dt = frac * stable_dt(rod.edge_len, 1.0, 1.0)

    def run():
        return simulate(rod, effects, dt=dt, t_end=periods * T, frames=periods * 120)

    wall, r = median_time(run, repeat=3)
    assert r.success, r.message
    q = (r.positions[:, :, 1] * (rod.mass * phi)).sum(axis=1)
    q -= q.mean()
    period = crossing_period(r.times, q)
    return abs(2 * np.pi / period / omega - 1.0), wall


def frequency_rows(ns, fracs):
    rows = []
    for n in ns:
        for frac in fracs:
            err, wall = frequency_error(n, frac)
            rows.append({"n": n, "frac": frac, "error": err, "time": wall})
    return {"rows": rows}


# --------------------------------------------------------------------------- 3. threshold
def outcome(delta, n, frac):
    r = run_impact(_scene(delta, n, frac))
    return r.outcome == "encapsulated", r.wall_time_s


def threshold(n, frac, bracket=THRESHOLD_BRACKET, tol=THRESHOLD_TOL):
    """Delta* by bisection: (midpoint, half-width, runs, total wall time [s]).

    The bracket's ends are checked first; a bracket that does not flip is reported as
    (nan, ...) rather than bisected.
    """
    lo, hi = bracket
    wall = 0.0
    ok_lo, w1 = outcome(lo, n, frac)
    ok_hi, w2 = outcome(hi, n, frac)
    wall += w1 + w2
    runs = 2
    if ok_lo or not ok_hi:
        return math.nan, math.nan, runs, wall
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        enc, w = outcome(mid, n, frac)
        wall += w
        runs += 1
        lo, hi = (lo, mid) if enc else (mid, hi)
    return 0.5 * (lo + hi), 0.5 * (hi - lo), runs, wall


def threshold_rows(grid):
    rows = []
    for n, frac in grid:
        d, hw, runs, wall = threshold(n, frac)
        rows.append(
            {
                "n": n,
                "frac": frac,
                "delta_star": d,
                "half_width": hw,
                "runs": runs,
                "time": wall,
                "time_per_run": wall / runs,
            }
        )
        print(f"  threshold n={n} dt={frac}: {d:.5f} +- {hw:.1e} ({wall:.0f} s)", flush=True)
    ref = next((r for r in rows if (r["n"], r["frac"]) == REFERENCE), rows[-1])
    for r in rows:
        r["error"] = abs(r["delta_star"] - ref["delta_star"]) if r is not ref else None
    return {
        "reference": [ref["n"], ref["frac"]],
        "reference_delta_star": ref["delta_star"],
        "rows": rows,
    }


# --------------------------------------------------------------------------- report
def _series(rows, key="error"):
    out = []
    for frac in sorted({r["frac"] for r in rows}, reverse=True):
        rs = [r for r in rows if r["frac"] == frac]
        out.append(
            {
                "label": rf"$\Delta t$ = {frac:g} $\times$ stability bound",
                "time": [r["time"] for r in rs],
                "error": [r[key] for r in rs],
                "notes": [f"$N$ = {r['n']}" for r in rs],
            }
        )
    return out


def report(rec, plot=True):
    if "shape" in rec:
        s = rec["shape"]
        print(
            f"\n## final shape: supp-fig5 impact at Δ = {SHAPE_DELTA} to rest, M against "
            f"the statics M = {s['reference_M']:.8f}"
        )
        print(
            table(
                s["rows"],
                [
                    ("n", "N (edges)", "d"),
                    ("frac", "dt / bound", "g"),
                    ("rest", "rest_kinetic", ".0e"),
                    ("M", "final M", ".6f"),
                    ("error", "error", ".1e"),
                    ("t_end", "t at rest", ".1f"),
                    ("time", "wall [s]", ".2f"),
                    ("steps", "steps", "d"),
                ],
            )
        )
        series = []
        for rk in sorted({r.get("rest", 1e-6) for r in s["rows"]}, reverse=True):
            rs = [r for r in s["rows"] if r.get("rest", 1e-6) == rk and r["frac"] == 0.5]
            series.append(
                {
                    "label": rf"rest at $E_k$ < {rk:.0e}, "
                             r"$\Delta t$ = 0.5 $\times$ stability bound",
                    "time": [r["time"] for r in rs],
                    "error": [r["error"] for r in rs],
                    "notes": [f"$N$ = {r['n']}" for r in rs],
                }
            )
        if plot:
            wp_plot(
                IMG / "wp-dynamics-shape.png",
                series,
                rf"final measure $M$ of the $\Delta$ = {SHAPE_DELTA} impact against the statics",
            )
    if "frequency" in rec:
        f = rec["frequency"]
        print("\n## clamped-free first-mode frequency (relative error vs Euler-Bernoulli)")
        print(
            table(
                f["rows"],
                [
                    ("n", "N (edges)", "d"),
                    ("frac", "dt / bound", "g"),
                    ("error", "rel. error", ".1e"),
                    ("time", "wall [s]", ".3f"),
                ],
            )
        )
        if plot:
            wp_plot(
                IMG / "wp-dynamics-frequency.png",
                _series(f["rows"]),
                "clamped-free first-mode frequency (5 periods)",
            )
    if "threshold" in rec:
        th = rec["threshold"]
        n_ref, f_ref = th["reference"]
        print(
            f"\n## selection threshold Δ* (damping 0.2), reference N = {n_ref}, dt = "
            f"{f_ref:g} x bound: Δ* = {th['reference_delta_star']:.5f}"
        )
        # Richardson (O(h^2), measured ratio 4.3 from 50 to 100 edges) from the two finest
        by = {(r["n"], r["frac"]): r["delta_star"] for r in th["rows"]}
        if (100, 0.5) in by and (200, 0.5) in by:
            rich = by[(200, 0.5)] + (by[(200, 0.5)] - by[(100, 0.5)]) / 3.0
            th["richardson"] = rich
            print(f"Richardson extrapolation (100, 200 edges): Δ* = {rich:.5f}")
            for r in th["rows"]:
                r["error_richardson"] = abs(r["delta_star"] - rich)
        print(
            table(
                th["rows"],
                [
                    ("n", "N (edges)", "d"),
                    ("frac", "dt / bound", "g"),
                    ("delta_star", "Δ*", ".5f"),
                    ("half_width", "± bisection", ".1e"),
                    ("error", "error vs reference", ".1e"),
                    ("error_richardson", "error vs Richardson", ".1e"),
                    ("runs", "runs", "d"),
                    ("time_per_run", "s / impact", ".2f"),
                    ("time", "bisection [s]", ".0f"),
                ],
            )
        )
        key = "error_richardson" if "richardson" in th else "error"
        if plot:
            wp_plot(
                IMG / "wp-dynamics-threshold.png",
                _series([r for r in th["rows"] if r.get(key) is not None], key),
                r"error of $\Delta^*$ (against Richardson of 100 and 200 edges), supp-fig5",
                xlabel="wall time of the bisection [s]",
            )


def main(fast=False, only=None):
    _warmup()
    rec = {}
    parts = [only] if only else ["frequency", "shape", "threshold"]
    for part in parts:
        t = time.perf_counter()
        if part == "frequency":
            rec[part] = frequency_rows(
                [10, 20] if fast else [10, 20, 40, 80], [0.5] if fast else [0.5, 0.25]
            )
        elif part == "shape":
            rec[part] = shape_rows([(50, 0.5)] if fast else GRID)
        elif part == "threshold":
            rec[part] = threshold_rows([(50, 0.5)] if fast else GRID)
        print(f"[{part}: {time.perf_counter() - t:.0f} s]", flush=True)
        if not fast:
            save_record(f"dynamics-{part}", rec[part])
    report(rec, plot=not fast)
    return rec


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fast", action="store_true", help="one coarse level of each (smoke run)")
    ap.add_argument("--only", choices=["frequency", "shape", "threshold"])
    ap.add_argument("--plot", action="store_true", help="redraw from out/wp/*.json only")
    a = ap.parse_args()
    if a.plot:
        parts = [k for k in ("frequency", "shape", "threshold")
                 if (OUT / f"dynamics-{k}.json").is_file()]
        if not parts:
            sys.exit(f"wp_dynamics --plot: no record in {OUT}; run it without --plot first")
        report({k: load_record(f"dynamics-{k}") for k in parts})
    else:
        main(a.fast, a.only)
