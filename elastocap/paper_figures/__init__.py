"""The paper's figures, one module each with ``main(out_dir, fast=False) -> list[Path]``.

The scripts in the repository's ``figures/`` folder call these; ``elastocap figures`` runs
them all. Each returns the files it wrote and asserts nothing itself: the tests run every
figure in fast mode and check one key number.
"""

from __future__ import annotations

from importlib import import_module
from pathlib import Path

#: figure name -> module (relative to this package)
FIGURES = {
    "supp-fig6": "supp_fig6",
    "bistability": "bistability",
    "supp-fig5": "supp_fig5",
    "overlay": "overlay",
    "energy-barrier": "energy_barrier",
    "fig3d": "fig3d",
    "fig3d-contact": "fig3d_contact",
    "fig4-fig5": "fig4_fig5",
    "strip-bistability": "strip_bistability",
    "contact-comparison": "contact_comparison",
}


def record(data: dict | list, scene, **settings) -> dict:
    """A figure's JSON record: its data plus what made it (package version, the scene's
    resolved input and validated numerics, and any settings the figure adds)."""
    from elastocap._version import __version__
    from elastocap.jsonutil import jsonable

    made_by = {"elastocap": __version__, "scene": scene.data,
               "numerics": vars(scene.numerics), **settings}
    body = data if isinstance(data, dict) else {"data": data}
    return jsonable({"made_by": made_by, **body})


def run_figures(out_dir, only: str | None = None, fast: bool = False) -> dict:
    """Run every figure (or ``only`` one) into ``out_dir``; return name -> written paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = {}
    for name, mod in FIGURES.items():
        if only and name != only:
            continue
        written[name] = import_module(f"elastocap.paper_figures.{mod}").main(out, fast=fast)
    return written
