"""The strip's static window at x = 2 ... 6 l_eg at three resolutions, with observed orders.

    python3 benchmarks/strip_convergence.py [--x 2 3 4 5 6] [--n 143 214 286] [--out DIR]

For each x and n, every branch in Delta over [0.5, min(2.2, 1.95 x)] is traced
(:func:`elastocap.strip.trace.trace_contact_branches`, no refinement) and recorded:

* ``deposition_end``: the end of the stable, open, admissible stretch of the branch traced
  up from the deposition at the lowest seed (Delta = 0.6): the smallest Delta at which the
  state the drop lands on stops existing or being stable (a contact fold, a smooth fold or
  a kind change), with how it ends: where the deposited state is lost.
  This is the static prediction of the phase diagram: beyond it a quasi-static spreading
  cannot stay on the state it was deposited on.
* ``open_max`` / ``encapsulated_min``: the window over every traced branch.

Each quantity is printed at the three n with the observed order p of v(n) = v + C n^-p
(through three values; NaN when the differences do not shrink monotonically) and the
Richardson estimate of the error of the finest value. Writes ``strip_convergence.json``
after each (x, n) (resumable: a finished (x, n) is not recomputed).
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--x", type=float, nargs="+", default=[2.0, 3.0, 4.0, 5.0, 6.0])
    ap.add_argument("--n", type=int, nargs=3, default=[143, 214, 286])
    ap.add_argument("--out", default="out/strip_convergence")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    path = os.path.join(a.out, "strip_convergence.json")
    data = json.load(open(path)) if os.path.exists(path) else {"runs": []}
    done = {(r["x"], r["n"]) for r in data["runs"]}
    sp = load_scene("fig3-strip").spreading
    for x in a.x:
        for n in a.n:
            if (x, n) in done:
                continue
            sc = load_scene("fig3-strip", {"drop.distance_from_end": x})
            t = time.perf_counter()
            bs = trace_contact_branches(sc, prange=(0.5, min(2.2, 1.95 * x)), n=n,
                                        refine=False)
            w = bs.results["window"]
            run = {"x": x, "n": n, "wall_time_s": time.perf_counter() - t,
                   "deposition_end": open_branch_end(bs),
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
    n1, n2, n3 = a.n
    print(f"| x | quantity | n = {n1} | n = {n2} | n = {n3} | order | error of finest | "
          "We^1/2 |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for x in a.x:
        runs = {r["n"]: r for r in data["runs"] if r["x"] == x}
        if not all(n in runs for n in a.n):
            continue
        for key in ("deposition_end", "open_max", "encapsulated_min"):
            vals = [runs[n][key]["value"] for n in a.n]
            vals = [float(v) if v is not None else math.nan for v in vals]
            p, err = observed_order(a.n, vals)
            ws = sp.we_sqrt(vals[-1]) if math.isfinite(vals[-1]) else math.nan
            hows = [_short(runs[n][key]) for n in a.n]
            print(f"| {x:g} | {key} | " + " | ".join(f"{v:.4f} {h}" for v, h in
                                                     zip(vals, hows, strict=True))
                  + f" | {p:.2f} | {err:.1e} | {ws:.2f} |")
    print("\nHow each value ends: sf smooth fold, cf contact fold (cf= stable on both "
          "sides: the branch turns back at an active-set event), kc kind change, sl "
          "stability lost, ia inadmissible, tp turning point not located, rg the range's "
          "end, be the branch ended otherwise.")


def _short(end):
    """A short tag of how an end was found (table cells)."""
    how = str(end.get("how") or "")
    tag = {"smooth fold": "sf", "smooth_fold": "sf", "contact fold": "cf",
           "contact_fold": "cf", "kind change": "kc", "kind_change": "kc",
           "stability lost": "sl", "stability_lost": "sl", "inadmissible": "ia",
           "range": "rg",
           "turning point (not located)": "tp"}.get(how, "be")
    return tag + ("=" if end.get("stable_both_sides") else "")


if __name__ == "__main__":
    main()
