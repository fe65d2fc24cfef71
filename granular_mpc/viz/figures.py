"""Shared figure plumbing of :mod:`.plots` and :mod:`.validation_plots`.

Figures never touch pyplot's global state: they are :class:`matplotlib.figure.Figure`
objects rendered by the Agg canvas, so nothing is ever displayed and the caller's backend
is left alone.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from ..exceptions import OutputError

DPI = 120
"""Resolution of the saved PNGs [dots per inch]."""
PALETTE = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
           "#17becf", "#7f7f7f", "#bcbd22")
"""Series colours, in order of use."""
PHASE_LABEL = "stance phase [%]"
"""Axis label of stance-phase plots."""


@dataclass(frozen=True)
class PlotOutput:
    """A drawn figure: where it was saved (None if not saved) and the plotted data."""

    path: Path | None
    data: pd.DataFrame | dict


def new_figure(nrows: int, ncols: int, width: float, height: float):
    """A figure of ``width`` × ``height`` inches with an ``(nrows, ncols)`` array of axes.

    Returns:
        ``(figure, axes)``; ``axes`` is always two-dimensional.
    """
    fig = Figure(figsize=(width, height), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


def save_figure(fig: Figure, out_path: str | Path | None) -> Path | None:
    """Save ``fig`` as PNG (parents created); return the path, or None if not asked.

    Raises:
        OutputError: the file cannot be written.
    """
    if out_path is None:
        return None
    path = Path(out_path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=DPI, format="png")
    except OSError as exc:
        raise OutputError(f"cannot write the figure {path}: {exc.strerror}") from None
    return path


def draw_band(ax, x, centre, lo, hi, *, color, label, ls="-") -> None:
    """A line ``centre`` over ``x`` and a shaded band between ``lo`` and ``hi``."""
    ax.plot(x, centre, color=color, lw=1.8, ls=ls, label=label)
    ax.fill_between(x, lo, hi, color=color, alpha=0.25, lw=0)


__all__ = ["DPI", "PALETTE", "PHASE_LABEL", "PlotOutput", "new_figure", "save_figure",
           "draw_band"]
