"""Fig 3d with rod self-contact: the strip's phase diagram when it cannot pass through
itself (:mod:`elastocap.paper_figures.fig3d` with ``contact=True``: the thickness
``FIG3D_THICKNESS`` and the final time ``FIG3D_CONTACT_T_MAX``; the grid and refinement of
Fig 3d, every threshold checked at ``FIG3D_CONTACT_LEVELS`` finer levels)."""

from __future__ import annotations

from pathlib import Path

from elastocap.paper_figures import fig3d


def main(out_dir, fast: bool = False, workers: int | None = None,
         accuracy: str | None = None) -> list[Path]:
    """Writes ``fig3d-contact.png``, ``fig3d-contact.json`` and the store
    ``fig3d-contact-ACCURACY.sqlite`` (see :func:`elastocap.paper_figures.fig3d.main`)."""
    return fig3d.main(out_dir, fast, workers, accuracy, contact=True)
