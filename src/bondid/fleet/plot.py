"""The fleet's strip plot: one row per parameter, every machine's value relative to the median.

matplotlib is imported lazily (through :mod:`bondid.plots._common`); no pyplot state.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..plots._common import font_scale, new_figure, save_png, style_axes
from .aggregate import MAD_TO_STD, ROBUST_Z

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.figure import Figure

STRIP_PNG = "fleet_strip.png"
_JITTER = 0.18


def build_strip(
    parameters: Sequence[Mapping[str, Any]],
    rows: Sequence[Mapping[str, Any]],
    *,
    title: str | None = None,
) -> Figure:
    """Strip plot: x = value / fleet median − 1 (%), one row per parameter, outliers in red
    and labelled with the machine id; grey ticks mark ± the robust threshold (3.5 robust std).

    Args:
        parameters: per-parameter statistics (``name``, ``median``, ``mad``).
        rows: machine × parameter rows (``machine``, ``parameter``, ``value``, ``outlier``).
    """
    names = [str(p["name"]) for p in parameters]
    fig = new_figure(8.0, 1.0 + 0.45 * max(len(names), 1))
    ax = fig.add_subplot(1, 1, 1)
    rng = np.random.default_rng(0)  # fixed jitter: the same data draw the same picture
    for i, p in enumerate(parameters):
        med = float(p["median"])
        if med == 0:
            continue
        pts = [r for r in rows if r.get("parameter") == p["name"] and r.get("value") is not None]
        rel = np.array([100 * (float(r["value"]) / med - 1) for r in pts])
        out = np.array([bool(r.get("outlier")) for r in pts], dtype=bool)
        y = i + rng.uniform(-_JITTER, _JITTER, rel.size)
        ax.scatter(rel[~out], y[~out], s=14, color="C0", alpha=0.7, linewidths=0)
        ax.scatter(rel[out], y[out], s=30, color="C3", zorder=3)
        for r, xv, yv in zip(pts, rel, y, strict=True):
            if r.get("outlier"):
                ax.annotate(
                    str(r["machine"]), (xv, yv), xytext=(4, 4), textcoords="offset points",
                    fontsize=8, color="C3",
                )  # fmt: skip
        thr = 100 * ROBUST_Z * MAD_TO_STD * float(p["mad"]) / abs(med)
        ax.plot([-thr, -thr], [i - 0.3, i + 0.3], color="0.55", linewidth=1)
        ax.plot([thr, thr], [i - 0.3, i + 0.3], color="0.55", linewidth=1)
    ax.axvline(0.0, color="0.3", linewidth=0.8)
    ax.margins(x=0.08)  # room for the outliers' labels
    ax.set_yticks(range(len(names)), names, fontsize=font_scale(len(names)))
    ax.set_ylim(len(names) - 0.5, -0.5)
    ax.set_xlabel("value relative to the fleet median [%]")
    style_axes(ax)
    ax.set_title(
        title or f"Fleet: {len(names)} parameters (red: outliers; grey ticks: ± threshold)",
        fontsize=10,
    )
    return fig


def plot_strip(
    parameters: Sequence[Mapping[str, Any]],
    rows: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
) -> Path:
    """Write :func:`build_strip` as a PNG (atomically) and return the path."""
    return save_png(build_strip(parameters, rows, title=title), path)
