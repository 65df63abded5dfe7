"""Shared plumbing of the plotting layer: figure creation and atomic PNG output.

matplotlib is imported lazily inside the functions, so importing :mod:`bondid.plots` costs
nothing; no pyplot global state is used (each figure owns an Agg canvas).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from ..atomic import atomic_path
from ..exceptions import ConfigError

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.figure import Figure

DEFAULT_DPI = 130


def new_figure(
    width_in: float,
    height_in: float,
    *,
    layout: Literal["constrained", "tight"] | None = "constrained",
) -> Figure:
    """A new matplotlib ``Figure`` of ``width_in`` × ``height_in`` inches with an Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), layout=layout)
    FigureCanvasAgg(fig)
    return fig


def save_png(fig: Figure, path: str | os.PathLike[str], *, dpi: int = DEFAULT_DPI) -> Path:
    """Write ``fig`` as a PNG to ``path`` atomically and return the path.

    Raises:
        ConfigError: when ``path`` does not end in ``.png``.
    """
    target = Path(path)
    if target.suffix.lower() != ".png":
        raise ConfigError(f"{target}: plot output must be a .png file")
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi, facecolor="white")
    return target


def font_scale(n_rows: int, *, full: int = 20, small: int = 80) -> float:
    """Font size (pt) for tick labels of a plot with ``n_rows`` labelled rows: 10 → 6.5."""
    if n_rows <= full:
        return 10.0
    if n_rows >= small:
        return 6.5
    return 10.0 - 3.5 * (n_rows - full) / (small - full)


def style_axes(ax: Any) -> None:
    """Light grid and de-emphasised spines, shared by every plot."""
    ax.grid(True, which="major", color="0.85", linewidth=0.6)
    ax.grid(True, which="minor", color="0.93", linewidth=0.4)
    ax.set_axisbelow(True)
