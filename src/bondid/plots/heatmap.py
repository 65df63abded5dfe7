"""Labelled heat map, e.g. parameter × band (or parameter × channel) sensitivities."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..exceptions import DataError
from ._common import font_scale, new_figure, save_png

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.figure import Figure

#: Annotate each cell with its value when the map has at most this many cells.
ANNOTATE_MAX_CELLS = 160


def _format(v: float) -> str:
    if not np.isfinite(v):
        return ""
    a = abs(v)
    if a == 0:
        return "0"
    if a >= 1e4 or a < 1e-2:
        return f"{v:.1e}"
    return f"{v:.3g}"


def build_heatmap(
    values: np.ndarray,
    *,
    row_labels: Sequence[str],
    col_labels: Sequence[str],
    title: str | None = None,
    cbar_label: str = "",
    log: bool = False,
) -> Figure:
    """Build the heat-map figure (see :func:`plot_heatmap`) without saving it."""
    v = np.asarray(values, dtype=float)
    n_rows, n_cols = len(row_labels), len(col_labels)
    if v.shape != (n_rows, n_cols):
        raise DataError(
            f"heat map: values have shape {v.shape}, expected (n_rows, n_cols) = "
            f"{(n_rows, n_cols)} from the row and column labels"
        )
    shown, norm, cmap = _colour_scale(v, log)
    fs = font_scale(n_rows)
    longest_row = max((len(s) for s in row_labels), default=1)
    longest_col = max((len(s) for s in col_labels), default=1)
    rotate = longest_col > 4 and n_cols > 3
    width = 2.4 + 0.0095 * fs * longest_row + max(3.5, 0.62 * n_cols)
    height = 1.3 + (0.012 * fs * longest_col if rotate else 0.3) + max(2.5, n_rows * fs * 0.024)
    fig = new_figure(min(width, 22.0), min(height, 30.0))
    ax = fig.add_subplot()
    im = ax.imshow(
        np.ma.masked_invalid(shown), cmap=cmap, norm=norm, aspect="auto", interpolation="nearest"
    )
    _label_cells(ax, row_labels, col_labels, fs, rotate)
    if n_rows * n_cols <= ANNOTATE_MAX_CELLS:
        _annotate(ax, v, cmap, norm, min(fs, 8.5), log)
    cbar = fig.colorbar(im, ax=ax, pad=0.02, fraction=0.05, aspect=min(40, max(15, n_rows // 2)))
    cbar.set_label(cbar_label, fontsize=10)
    cbar.ax.tick_params(labelsize=9)
    if title:
        ax.set_title(title, fontsize=12)
    return fig


def _colour_scale(v: np.ndarray, log: bool) -> tuple[np.ndarray, Any, Any]:
    """``(values to show, norm, colour map)``: log scale over the positive values; else a
    diverging map centred on 0 for signed values, ``viridis`` otherwise; NaN drawn grey."""
    from matplotlib import colormaps
    from matplotlib.colors import LogNorm, Normalize

    finite = v[np.isfinite(v)]
    norm: Any
    if log:
        pos = finite[finite > 0]
        if pos.size == 0:
            raise DataError("heat map: log=True needs positive values; none are positive")
        shown = np.where(v > 0, v, np.nan)
        norm = LogNorm(vmin=float(pos.min()), vmax=float(pos.max()))
        cmap = colormaps["viridis"]
    else:
        shown = v
        lo = float(finite.min()) if finite.size else 0.0
        hi = float(finite.max()) if finite.size else 1.0
        if lo < 0 < hi:  # signed values: diverging map centred on zero
            m = max(-lo, hi)
            norm = Normalize(-m, m)
            cmap = colormaps["RdBu_r"]
        else:
            norm = Normalize(lo, hi if hi > lo else lo + 1.0)
            cmap = colormaps["viridis"]
    return shown, norm, cmap.with_extremes(bad="0.85")


def _label_cells(
    ax: Any, row_labels: Sequence[str], col_labels: Sequence[str], fs: float, rotate: bool
) -> None:
    """Row and column tick labels (columns slanted when ``rotate``), white cell borders."""
    n_rows, n_cols = len(row_labels), len(col_labels)
    ax.set_yticks(np.arange(n_rows), list(row_labels), fontsize=fs)
    ax.set_xticks(np.arange(n_cols), list(col_labels), fontsize=min(fs + 0.5, 10))
    if rotate:
        for lab in ax.get_xticklabels():
            lab.set_rotation(40)
            lab.set_horizontalalignment("right")
            lab.set_rotation_mode("anchor")
    ax.set_xticks(np.arange(n_cols + 1) - 0.5, minor=True)
    ax.set_yticks(np.arange(n_rows + 1) - 0.5, minor=True)
    ax.grid(which="minor", color="white", linewidth=0.8 if n_rows < 40 else 0.4)
    ax.tick_params(which="minor", length=0)
    ax.tick_params(which="major", length=2)


def _annotate(ax: Any, v: np.ndarray, cmap: Any, norm: Any, fontsize: float, log: bool) -> None:
    """Print each finite value (positive ones on a log scale) in its cell, in black or white
    by the cell colour's luminance."""
    for i, j in np.ndindex(v.shape):
        val = v[i, j]
        if not np.isfinite(val) or (log and val <= 0):
            continue
        rgba = np.asarray(cmap(norm(val))).reshape(-1, 4)[0]  # 1 value: (1, 4)
        lum = 0.299 * rgba[0] + 0.587 * rgba[1] + 0.114 * rgba[2]
        ax.text(
            j, i, _format(float(val)), ha="center", va="center",
            fontsize=fontsize, color="black" if lum > 0.5 else "white",
        )  # fmt: skip


def plot_heatmap(
    values: np.ndarray,
    *,
    row_labels: Sequence[str],
    col_labels: Sequence[str],
    path: str | os.PathLike[str],
    title: str | None = None,
    cbar_label: str = "",
    log: bool = False,
) -> Path:
    """Draw a labelled heat map (e.g. parameter × band sensitivity) and save a PNG.

    The figure grows with the number of rows and the tick font shrinks (10 pt up to 20 rows,
    down to 6.5 pt at 80), so ~70 parameters stay readable. Signed values get a diverging
    colour map centred at 0, others ``viridis``; NaN cells are grey; small maps
    (≤ :data:`ANNOTATE_MAX_CELLS` cells) print each value in its cell.

    Args:
        values: shape ``(n_rows, n_cols)``, any unit (say which in ``cbar_label``).
        row_labels: ``n_rows`` labels, first row on top (e.g. parameter names).
        col_labels: ``n_cols`` labels (e.g. band names or channels ``OUT.IN``).
        path: output ``.png`` file, written atomically.
        title: figure title.
        cbar_label: colour-bar label.
        log: logarithmic colour scale; non-positive values are then drawn grey.

    Returns:
        ``path`` as a :class:`~pathlib.Path`.
    """
    fig = build_heatmap(
        values,
        row_labels=row_labels,
        col_labels=col_labels,
        title=title,
        cbar_label=cbar_label,
        log=log,
    )
    return save_png(fig, path)
