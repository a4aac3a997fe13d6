"""Impacts of supp-fig5 drawn on its equilibria: which Delta reaches which branch."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from elastocap.io import write_json
from elastocap.overlay import run_overlay
from elastocap.paper_figures import record
from elastocap.scene import load_scene


def main(out_dir, fast: bool = False) -> list[Path]:
    """Writes ``overlay-supp-fig5.png`` and ``overlay.json`` (the branch each run reaches)."""
    out = Path(out_dir)
    scene = load_scene("supp-fig5", {"numerics.accuracy": "draft"} if fast else None)
    deltas = np.linspace(2.5, 4.5, 3 if fast else 9)
    res = run_overlay(scene, deltas, out)
    js = out / "overlay.json"
    write_json(js, record({"runs": res["runs"]}, scene, fast=fast), indent=1)
    return [Path(f) for f in res["files"]] + [js]
