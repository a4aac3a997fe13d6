"""Supplementary Fig 6: equilibria of supp-fig5 (A = 1.5, L = 4.6, no gravity) against Delta."""

from __future__ import annotations

from pathlib import Path

from elastocap.io import write_json
from elastocap.paper_figures import record
from elastocap.scene import load_scene
from elastocap.statics.branches import trace_branches
from elastocap.statics.plot import plot_branch_set


def main(out_dir, fast: bool = False) -> list[Path]:
    """Trace every branch of supp-fig5 and draw the diagram.

    ``fast`` uses the draft resolution (12 LGL intervals; folds to ~1e-5).
    Writes ``supp-fig6.png`` and ``supp-fig6.json`` (the special points).
    """
    out = Path(out_dir)
    overrides = {"numerics.accuracy": "draft"} if fast else None
    scene = load_scene("supp-fig5", overrides)
    bs = trace_branches(scene, error_estimates=not fast)
    png = out / "supp-fig6.png"
    plot_branch_set(
        bs,
        png,
        title=r"Supplementary Fig 6: $A/\ell_{ec}^2 = 1.5$, $L/\ell_{ec} = 4.6$",
    )
    js = out / "supp-fig6.json"
    write_json(
        js,
        record(
            {
                "folds": bs.folds,
                "branch_points": bs.branch_points,
                "maxwell_points": bs.maxwell_points,
            },
            scene,
            N=bs.metadata["N"],
            newton_tol=bs.metadata["newton_tol"],
        ),
        indent=2,
    )
    return [png, js]
