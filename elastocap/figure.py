"""Matplotlib figures that touch no process-wide state.

Every figure of the toolkit is made here: a :class:`matplotlib.figure.Figure` with its own
Agg canvas. Nothing calls ``matplotlib.use`` and nothing goes through ``pyplot``, so a
user's backend, interactive session and open figures are left as they were, and no figure
stays alive in pyplot's registry after it is saved.
"""

from __future__ import annotations


def new_figure(figsize=(8.0, 5.6), dpi: int = 130):
    """A figure of ``figsize`` inches at ``dpi``, with its own Agg canvas (renderer for
    ``tight_layout`` and ``savefig``). Returns the :class:`matplotlib.figure.Figure`."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig
