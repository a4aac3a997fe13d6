"""Trace every equilibrium branch of supp-fig5, save and draw it, and check its folds.

The task of a user who wants the bifurcation diagram of a scene and a CI check that its folds
do not move: trace, save (``branch_K.npz`` + ``branches.json``), draw, write a reference file
and compare the folds with it.

Run: ``python examples/trace_and_check_folds.py OUT_DIR [--fast]``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from elastocap.scene import load_scene
from elastocap.statics.branches import trace_branches
from elastocap.statics.plot import plot_branch_set
from elastocap.testing import assert_folds


def main(out_dir, fast: bool = False) -> dict:
    """Trace supp-fig5 in the wetted length Delta; return its folds and the files written.

    Parameters
    ----------
    out_dir : str or Path
        Folder for the branches, the figure and the reference file.
    fast : bool
        The ``draft`` preset (16 LGL intervals, fold to ~1e-9) instead of the default (24).

    Returns
    -------
    dict
        ``folds`` (value, error estimate, measure, stability change of each fold), ``files``.
    """
    out = Path(out_dir)
    scene = load_scene("supp-fig5")
    if fast:
        scene = scene.with_overrides({"numerics.accuracy": "draft"})
    bs = trace_branches(scene)  # every branch over Delta in (0.02 L, L), with error estimates
    files = [str(p) for p in bs.save(out / "branches")]
    fig = out / "branches.png"
    plot_branch_set(bs, fig)
    files.append(str(fig))

    # the reference a CI job keeps; any later run is checked against it
    ref = out / "folds-ref.json"
    ref.write_text(json.dumps({"folds": [{"value": f["value"]} for f in bs.folds]}))
    files.append(str(ref))
    assert_folds(bs.folds, ref, rtol=1e-8)

    folds = [
        {k: f[k] for k in ("value", "error_estimate", "measure", "stability_change")}
        for f in bs.folds
    ]
    for f in folds:
        print(f"fold at Delta = {f['value']:.12f} (error estimate {f['error_estimate']:.1e}), "
              f"M = {f['measure']:.4f}, {f['stability_change']}")
    return {"folds": folds, "files": files}


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--fast"]
    main(args[0] if args else "out/example-folds", fast="--fast" in sys.argv[1:])
