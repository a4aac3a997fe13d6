"""The strip's static window at x = 2 ... 6 l_eg at three or more resolutions, with
observed orders.

    python3 benchmarks/strip_convergence.py [--x 2 3 4 5 6] [--n 143 214 286 ...]
        [--range LO HI] [--spreading] [--out DIR]

For each x and n, every branch in Delta over [0.5, min(2.2, 1.95 x)] (or ``--range``) is
traced (:func:`elastocap.strip.trace.trace_contact_branches`, no refinement; with
``--spreading`` also the spreading past the deposited state's end) and recorded:

* ``deposition_end``: the end of the stable, open, admissible stretch of the branch traced
  up from the deposition at the lowest seed (Delta = 0.6): the smallest Delta at which the
  state the drop lands on stops existing or being stable (a contact fold, a smooth fold or
  a kind change), with how it ends: where the deposited state is lost.
  This is the static prediction of the phase diagram: beyond it a quasi-static spreading
  cannot stay on the state it was deposited on.
* ``open_max`` / ``encapsulated_min``: the window over every traced branch.

* ``spreading`` (with ``--spreading``): where the spreading, followed through its jumps,
  stops being open (``open_branch_end(bs)["spreading"]``).

Each quantity is printed at every n with the observed order p of v(n) = v + C n^-p
(through the last three values; NaN when the differences do not shrink monotonically) and
the Richardson estimate of the error of the finest value; with four or more n, also the
least-squares fit v + C/n over the last four values (first order): its limit and largest
residual. Writes ``strip_convergence.json`` after each (x, n, range) (resumable: a finished
one is not recomputed).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

from scipy.optimize import brentq

from elastocap.scene import load_scene
from elastocap.strip.trace import open_branch_end, trace_contact_branches


def observed_order(ns, vals):
    """p and the Richardson error of the finest value through three (n, v)."""
    n1, n2, n3 = ns
    v1, v2, v3 = vals
    if not all(isinstance(v, float) and math.isfinite(v) for v in vals):
        return math.nan, math.nan
    a, b = v1 - v2, v2 - v3
    if a == 0.0 or b == 0.0 or a * b < 0.0 or abs(b) >= abs(a):
        return math.nan, math.nan
    q = a / b

    def f(p):
        return (n1**-p - n2**-p) / (n2**-p - n3**-p) - q

    try:
        p = brentq(f, 0.05, 8.0)
    except ValueError:
        return math.nan, math.nan
    err = b * n3**-p / (n2**-p - n3**-p)
    return p, abs(err)


def range_for(x, given=None):
    """The Delta range traced at x: ``given`` (--range), else [0.5, min(2.2, 1.95 x)]."""
    return tuple(given) if given else (0.5, min(2.2, 1.95 * x))


def first_order_limit(ns, vals):
    """The limit and the largest residual of the least-squares fit v + C / n."""
    import numpy as np

    v = np.asarray(vals, dtype=float)
    if not np.all(np.isfinite(v)):
        return math.nan, math.nan
    A = np.column_stack([np.ones(len(ns)), 1.0 / np.asarray(ns, dtype=float)])
    c = np.linalg.lstsq(A, v, rcond=None)[0]
    return float(c[0]), float(np.max(np.abs(v - A @ c)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--x", type=float, nargs="+", default=[2.0, 3.0, 4.0, 5.0, 6.0])
    ap.add_argument("--n", type=int, nargs="+", default=[143, 214, 286])
    ap.add_argument("--range", type=float, nargs=2, default=None, metavar=("LO", "HI"))
    ap.add_argument("--spreading", action="store_true")
    ap.add_argument("--out", default="out/strip_convergence")
    a = ap.parse_args()
    if len(a.n) < 3:
        ap.error(f"--n: got {a.n}; expected three or more resolutions")
    os.makedirs(a.out, exist_ok=True)
    path = os.path.join(a.out, "strip_convergence.json")
    data = json.load(open(path)) if os.path.exists(path) else {"runs": []}
    def key(r):
        return r["x"], r["n"], range_for(r["x"], r.get("range")), bool(r.get("spreading"))

    done = {key(r) for r in data["runs"]}
    sp = load_scene("fig3-strip").spreading
    for x in a.x:
        prange = range_for(x, a.range)
        for n in a.n:
            if (x, n, prange, a.spreading) in done:
                continue
            sc = load_scene("fig3-strip", {"drop.distance_from_end": x})
            t = time.perf_counter()
            bs = trace_contact_branches(sc, prange=prange, n=n, refine=False,
                                        spreading=a.spreading)
            w = bs.results["window"]
            end = open_branch_end(bs)
            run = {"x": x, "n": n, "range": list(prange), "spreading": a.spreading,
                   "wall_time_s": time.perf_counter() - t,
                   "deposition_end": {k: v for k, v in end.items()
                                      if k not in ("past_loss", "spreading")},
                   "spreading_end": end.get("spreading"),
                   "past_loss": end.get("past_loss"),
                   "open_max": w["open_max"], "encapsulated_min": w["encapsulated_min"],
                   "bistable": w["bistable"], "width": w["width"],
                   "branches": [{k: b[k] for k in ("label", "range", "end_status")}
                                for b in bs.summary()["branches"]],
                   "folds": [{k: f[k] for k in ("value", "kind", "stability_change",
                                                "encapsulated", "admissible", "branch")}
                             for f in bs.folds]}
            data["runs"].append(run)
            with open(path + ".tmp", "w") as f:
                json.dump(data, f, indent=1, default=float)
            os.replace(path + ".tmp", path)
            de = run["deposition_end"]
            print(f"x = {x:g}, n = {n}: deposition end {de['value']} ({de['how']}), "
                  f"open_max {w['open_max']['value']} ({w['open_max']['how']}), "
                  f"encapsulated_min {w['encapsulated_min']['value']} "
                  f"({w['encapsulated_min']['how']}), {run['wall_time_s']:.0f} s",
                  file=sys.stderr, flush=True)
    heads = " | ".join(f"n = {n}" for n in a.n)
    print(f"| x | quantity | {heads} | order | error of finest | first-order limit "
          "(residual) | We^1/2 |")
    print("|---|---|" + "---:|" * len(a.n) + "---:|---:|---:|---:|")
    keys = ("deposition_end", "open_max", "encapsulated_min") + \
        (("spreading_end",) if a.spreading else ())
    for x in a.x:
        prange = range_for(x, a.range)
        runs = {r["n"]: r for r in data["runs"]
                if key(r) == (x, r["n"], prange, a.spreading)}
        if not all(n in runs for n in a.n):
            continue
        for q in keys:
            ends = [runs[n][q] or {} for n in a.n]
            vals = [float(e["value"]) if e.get("value") is not None else math.nan
                    for e in ends]
            p, err = observed_order(a.n[-3:], vals[-3:])
            lim, res = first_order_limit(a.n[-4:], vals[-4:]) if len(a.n) >= 4 else \
                (math.nan, math.nan)
            ws = sp.we_sqrt(vals[-1]) if math.isfinite(vals[-1]) else math.nan
            hows = [_short(e) for e in ends]
            print(f"| {x:g} | {q} | " + " | ".join(f"{v:.4f} {h}" for v, h in
                                                   zip(vals, hows, strict=True))
                  + f" | {p:.2f} | {err:.1e} | {lim:.4f} ({res:.0e}) | {ws:.2f} |")
    print("\nHow each value ends: sf smooth fold, cf contact fold (cf= stable on both "
          "sides: the branch turns back at an active-set event), kc kind change, sl "
          "stability lost, ia inadmissible, tp turning point not located, rg the range's "
          "end, je / ji a jump to an encapsulated / self-crossing state (the spreading), be "
          "the branch ended otherwise (or the spreading was not followed to an end).")


def _short(end):
    """A short tag of how an end was found (table cells)."""
    how = str(end.get("how") or "")
    tag = {"smooth fold": "sf", "smooth_fold": "sf", "contact fold": "cf",
           "contact_fold": "cf", "kind change": "kc", "kind_change": "kc",
           "stability lost": "sl", "stability_lost": "sl", "inadmissible": "ia",
           "range": "rg", "jump to an encapsulated state": "je",
           "jump to an inadmissible state": "ji",
           "turning point (not located)": "tp"}.get(how, "be")
    return tag + ("=" if end.get("stable_both_sides") else "")


if __name__ == "__main__":
    main()
