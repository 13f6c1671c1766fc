"""Figures without pyplot: matplotlib's object-oriented API on the Agg canvas.

Nothing here touches matplotlib's global state (no ``matplotlib.use``, no pyplot figure
manager), so importing parley in a notebook leaves its inline backend alone. Plugins draw
their policy plots with the same two functions.
"""

from __future__ import annotations

from pathlib import Path

from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


class InlineFigure(Figure):
    """A Figure that Jupyter shows as a PNG by itself (``_repr_png_``), without pyplot or
    ``%matplotlib inline``: parley changes no backend to be seen in a notebook."""

    def _repr_png_(self) -> bytes:
        import io

        buffer = io.BytesIO()
        self.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
        return buffer.getvalue()


def figure(width: float, height: float) -> tuple[Figure, Axes]:
    """A figure of ``width`` x ``height`` inches on an Agg canvas, and its one axes."""
    fig = InlineFigure(figsize=(width, height))
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot()


def save(fig: Figure, path: Path, dpi: int = 130, tight: bool = True) -> None:
    """Lay the figure out and write it (the format follows the file's suffix)."""
    if tight:
        fig.tight_layout()
    fig.savefig(path, dpi=dpi)
