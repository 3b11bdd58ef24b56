"""Matplotlib figures without pyplot (no global state, no display): one place for every plot module."""
from __future__ import annotations

from pathlib import Path

from ...io.paths import output_file

__all__ = ["new_figure", "save_figure"]


def new_figure(width_in: float, height_in: float, dpi: int = 120):
    """A constrained-layout Figure on an Agg canvas (thread-safe: no pyplot)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(width_in, height_in), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig, path: str | Path) -> Path:
    """Write ``fig`` to ``path`` (format from the suffix), creating the folder."""
    p = output_file(path)
    fig.savefig(p)
    return p
