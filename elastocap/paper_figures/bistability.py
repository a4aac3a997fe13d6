"""Bistability map of supp-fig5: the fold in Delta continued in the drop area A."""

from __future__ import annotations

from pathlib import Path

from elastocap.io import write_json
from elastocap.paper_figures import record
from elastocap.scene import load_scene
from elastocap.statics.bistability import admissible_curve, fold_curves, plot_bistability


def main(out_dir, fast: bool = False) -> list[Path]:
    """Writes ``bistability.png`` and ``bistability.json`` (the fold curve A -> Delta, inside
    the admissible region Delta <= L, as drawn)."""
    out = Path(out_dir)
    scene = load_scene("supp-fig5", {"numerics.accuracy": "draft"} if fast else None)
    bs, curves = fold_curves(scene, "drop.area", (0.2, 3.0), ds_max=0.1 if fast else 0.05)
    png = out / "bistability.png"
    plot_bistability(scene, bs, curves, "drop.area", png)
    js = out / "bistability.json"
    data = {"curves": []}
    for c in curves:
        q, d, extrema = admissible_curve(bs.problem, c, "drop.area")
        data["curves"].append({"area": q.tolist(), "delta": d.tolist(),
                               "extrema": [list(e) for e in extrema]})
    write_json(js, record(data, scene, N=bs.metadata["N"]), indent=1)
    return [png, js]
