"""Energy barrier of the strip of Fig 3: table over x and Delta, convergence in n, timings.

    python3 benchmarks/strip_barrier.py [--fast] [--out DIR] [--n N] [--n-fine M]

Writes ``strip_barrier.json`` (one record per (x, Delta)) and prints a table; about 5 min on
2 shared cores (``--fast``: one point, 10 s). The string method with Newton refinement
(:func:`elastocap.strip.barrier.barrier`) at n edges; the three states carried to n_fine.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

from threadpoolctl import threadpool_limits

from elastocap.scene import load_scene
from elastocap.strip.barrier import barrier, kinetic_energy
from elastocap.strip.model import DiscreteStrip, flat_energy, is_encapsulated
from elastocap.strip.solve import minimize_energy, prolong, refine

L, AREA, GAMMA = 14.3, 0.36, 40.0


def barrier_row(sc, x, d, n, n_fine=None):
    """Barrier at (x, Delta) with a string at n edges, optionally carried to n_fine."""
    t = time.perf_counter()
    S = DiscreteStrip(n, L, x, d, AREA, GAMMA)
    r = barrier(S)
    row = {k: v for k, v in r.summary().items() if k != "ends"}
    row["time"] = time.perf_counter() - t
    if n_fine and r.status == "ok":
        t = time.perf_counter()
        Sf = S.with_(n=n_fine)
        sad = refine(S, r.saddle, Sf)
        op = minimize_energy(Sf, prolong(S, r.open.u, Sf))
        wr = minimize_energy(Sf, prolong(S, r.wrapped.u, Sf))
        row["fine"] = {
            "n": n_fine, "e_open": op.energy, "e_saddle": sad.energy, "e_wrapped": wr.energy,
            "barrier": sad.energy - op.energy, "saddle_index": sad.index,
            "ok": bool(sad.success and sad.index == 1 and op.index == 0 and wr.index == 0
                       and not is_encapsulated(Sf, op.u) and is_encapsulated(Sf, wr.u)),
            "time": time.perf_counter() - t,
        }
    we = sc.spreading.we_sqrt(d)
    row["we_sqrt"] = we
    row["kinetic"] = kinetic_energy(sc, max(we, 0.0) ** 2)
    row["e_flat"] = flat_energy(AREA, GAMMA, d)
    return row


def main(out_dir="out/strip_barrier", fast=False, n=143, n_fine=429):
    """Table of barriers; returns the rows.

    n = 143 (h = 0.1): with x a multiple of 0.5 and Delta of 0.1, the contact lines sit at
    nodes or at mid-edge, and stay there at n_fine = 3 n (the error constant of the
    second-order convergence depends on where they sit in their edge).
    """
    os.makedirs(out_dir, exist_ok=True)
    sc = load_scene("fig3-strip")
    if fast:
        pts = [(3.0, 1.1)]
        n_fine = None
    else:
        pts = ([(1.5, 0.9), (2.0, 0.9)] + [(3.0, d) for d in (0.8, 0.9, 1.0, 1.1, 1.2, 1.25)]
               + [(4.0, d) for d in (0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5)])
    rows = []
    for x, d in pts:
        row = barrier_row(sc, x, d, n, n_fine)
        rows.append(row)
        fine = row.get("fine", {})
        print(f"x={x:4.1f} D={d:4.2f} n={n} {row['status']:>16s} E_open={row['e_open']:9.4f} "
              f"E_sad={row['e_saddle']:9.4f} E_wr={row['e_wrapped']:9.4f} "
              f"barrier={row['barrier']:8.4f} (n={fine.get('n', '-')}: "
              f"{fine.get('barrier', float('nan')):8.4f}) Ek={row['kinetic']:7.2f} "
              f"t={row['time']:5.1f}s", flush=True)
    with open(os.path.join(out_dir, "strip_barrier.json"), "w") as f:
        json.dump({"rows": rows}, f, indent=1)
    return rows


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--fast", action="store_true")
    ap.add_argument("--out", default="out/strip_barrier")
    ap.add_argument("--n", type=int, default=143)
    ap.add_argument("--n-fine", type=int, default=429)
    a = ap.parse_args()
    with threadpool_limits(limits=1, user_api="blas"):
        main(a.out, a.fast, a.n, a.n_fine)
    sys.exit(0)
