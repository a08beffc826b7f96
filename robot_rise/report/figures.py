"""Matplotlib figures for the report: a figure on the Agg canvas, its PNG bytes, subplot grids, the end-of-trajectory mark.

Object API with the Agg canvas only: no pyplot, no global backend change.
"""

from __future__ import annotations

import io
import math
from typing import Any

from robot_rise.sim.player import Recording

__all__ = ["PLOT_DPI", "new_figure", "png_bytes", "grid_shape", "mark_trajectory_end"]

PLOT_DPI = 90  # resolution of every plot [dots per inch]


def new_figure(width_in: float, height_in: float) -> Any:
    """A matplotlib ``Figure`` of ``width_in`` x ``height_in`` [inch] on its own Agg canvas, constrained layout."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=PLOT_DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def png_bytes(fig: Any) -> bytes:
    """``fig`` as PNG bytes at :data:`PLOT_DPI`."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=PLOT_DPI)
    return buf.getvalue()


def grid_shape(n: int, cols: int = 5) -> tuple[int, int]:
    """(rows, columns) of a grid holding ``n`` subplots, at most ``cols`` a row."""
    return math.ceil(n / cols), min(cols, n)


def mark_trajectory_end(ax: Any, rec: Recording) -> None:
    """A dotted vertical line where the trajectory ends and the hold begins."""
    ax.axvline(rec.trajectory_end_s, color="0.5", lw=0.8, ls=":")
