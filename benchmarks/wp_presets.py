"""What each accuracy preset (numerics.accuracy = draft | default | publication) costs.

Statics: the whole supp-fig5 diagram (search, 5 branches, folds located with their error
estimates) per preset: median wall time of 3 after a warm-up, the fold's true error against
``FOLD_REF`` (tests/statics/test_statics_convergence.py) and its reported error estimate.
Dynamics: one supp-fig5 impact at Delta = 4 (encapsulates) per preset, its wall time and
final measure; the Delta* error of the preset's resolution from the threshold bisection of
``wp_dynamics.py`` (out/wp/dynamics-threshold.json; measured here if absent).

Run: ``python3 benchmarks/wp_presets.py``.
"""

from __future__ import annotations

import math

from wp_common import OUT, load_record, median_time, save_record, table

from elastocap.impact import impact_settings, run_impact
from elastocap.scene import load_scene
from elastocap.statics.branches import ACCURACY_N, trace_branches

PRESETS = ("draft", "default", "publication")


def statics_rows(repeat=3):
    from test_statics_convergence import FOLD_REF

    rows = []
    for acc in PRESETS:
        scene = load_scene("supp-fig5", {"numerics.accuracy": acc})
        t, bs = median_time(lambda scene=scene: trace_branches(scene), repeat=repeat)
        (fold,) = bs.folds
        rows.append(
            {
                "preset": acc,
                "N": ACCURACY_N[acc],
                "fold": fold["value"],
                "error": abs(fold["value"] - FOLD_REF),
                "estimate": fold["error_estimate"],
                "time": t,
                "branches": len(bs.branches),
            }
        )
    return rows


def dynamics_rows():
    import wp_dynamics

    path = OUT / "dynamics-threshold.json"
    th = load_record("dynamics-threshold") if path.exists() else None
    rich = None
    if th is not None:
        # O(h^2) Richardson from 100 and 200 edges (as in wp_dynamics.report)
        by = {(r["n"], r["frac"]): r["delta_star"] for r in th["rows"]}
        if (100, 0.5) in by and (200, 0.5) in by:
            rich = by[(200, 0.5)] + (by[(200, 0.5)] - by[(100, 0.5)]) / 3.0
    rows = []
    for acc in PRESETS:
        scene = load_scene("supp-fig5", {"numerics.accuracy": acc, "drop.wetted_length": 4.0})
        st = impact_settings(scene)
        run_impact(load_scene("supp-fig5", {"numerics.n_edges": 20, "numerics.t_max": 0.5}))
        r = run_impact(scene)
        row = {
            "preset": acc,
            "n": st["n_edges"],
            "frac": st["dt"] / st["dt_max"],
            "impact_time": r.wall_time_s,
            "M": r.final_measure,
            "t_end": r.t_end,
        }
        # the preset's resolution near Delta* (3.53): same edges rule as impact_settings
        n_star = impact_settings(scene.with_overrides({"drop.wetted_length": 3.53}))["n_edges"]
        match = None
        if th is not None:
            match = next((x for x in th["rows"] if x["n"] == n_star and x["frac"] == 0.5), None)
        if match is None:
            d, hw, runs, wall = wp_dynamics.threshold(n_star, 0.5)
            match = {"delta_star": d, "half_width": hw, "time": wall, "error": None}
        row.update(
            {
                "delta_star": match["delta_star"],
                "bisection_time": match["time"],
                "delta_star_error": None if rich is None else abs(match["delta_star"] - rich),
                "reference": rich,
            }
        )
        rows.append(row)
    return rows


def main(fast=False):
    s = statics_rows(repeat=1 if fast else 3)
    print("\n## presets: statics (whole supp-fig5 diagram)")
    print(
        table(
            s,
            [
                ("preset", "preset", "s"),
                ("N", "LGL N", "d"),
                ("fold", "fold Δ", ".12f"),
                ("error", "true error", ".1e"),
                ("estimate", "reported estimate", ".1e"),
                ("time", "diagram [s]", ".2f"),
            ],
        )
    )
    if fast:
        return {"statics": s}
    d = dynamics_rows()
    ref = d[0]["reference"]
    print(
        "\n## presets: dynamics (impact at Δ = 4; Δ* error against the Richardson value "
        + ("?" if ref is None else f"{ref:.5f}")
        + " of 100/200 edges)"
    )
    for r in d:
        if r["delta_star_error"] is None:
            r["delta_star_error"] = math.nan
    print(
        table(
            d,
            [
                ("preset", "preset", "s"),
                ("n", "edges", "d"),
                ("frac", "dt / bound", "g"),
                ("impact_time", "impact Δ=4 [s]", ".2f"),
                ("M", "final M", ".5f"),
                ("delta_star", "Δ*", ".5f"),
                ("delta_star_error", "Δ* error", ".1e"),
                ("bisection_time", "Δ* bisection [s]", ".0f"),
            ],
        )
    )
    save_record("presets", {"statics": s, "dynamics": d})
    return {"statics": s, "dynamics": d}


if __name__ == "__main__":
    import sys

    main("--fast" in sys.argv)
