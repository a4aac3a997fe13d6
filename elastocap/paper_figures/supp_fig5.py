"""Supplementary Fig 5: time sequences at Delta = 2.5 (open) and 4 (encapsulated)."""

from __future__ import annotations

from pathlib import Path

from elastocap.frames import frame_strip
from elastocap.impact import run_impact
from elastocap.io import write_json
from elastocap.paper_figures import record
from elastocap.scene import load_scene


def main(out_dir, fast: bool = False) -> list[Path]:
    """Writes ``supp-fig5a.png``, ``supp-fig5b.png`` and ``supp-fig5.json`` (outcomes)."""
    out = Path(out_dir)
    files, summary = [], {}
    for tag, delta in (("a", 2.5), ("b", 4.0)):
        over = {"drop.wetted_length": delta}
        if fast:
            over["numerics.accuracy"] = "draft"
        scene = load_scene("supp-fig5", over)
        res = run_impact(scene)
        png = out / f"supp-fig5{tag}.png"
        frame_strip(
            res,
            scene,
            png,
            k=8,
            title=rf"Supplementary Fig 5{tag}: $\Delta$ = {delta:g}, "
            f"damping {scene.effects.damping:g}: {res.outcome}",
        )
        files.append(png)
        summary[tag] = {"wetted_length": delta, **res.to_dict()}
    js = out / "supp-fig5.json"
    write_json(js, record(summary, scene, fast=fast), indent=1)
    return [*files, js]
