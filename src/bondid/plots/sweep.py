"""One-at-a-time parameter sweep: cost against scale factor for every parameter.

The most influential parameters (largest cost range over the sweep) are coloured and listed in
the legend in rank order; the rest are drawn grey. With a 3-D cost array there is one panel
per direction (e.g. excitation direction).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..exceptions import DataError
from ._common import font_scale, new_figure, save_png, style_axes

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.figure import Figure


def rank_parameters(costs: np.ndarray, top: int) -> np.ndarray:
    """Indices of the ``top`` parameters with the largest cost range, most influential first.

    Args:
        costs: shape ``(n_params, n_scales)``; NaN entries are ignored.
        top: how many to return (fewer if there are fewer parameters).
    """
    c = np.asarray(costs, dtype=float)
    finite = np.isfinite(c)
    hi = np.where(finite, c, -np.inf).max(axis=1)
    lo = np.where(finite, c, np.inf).min(axis=1)
    spread = np.where(finite.any(axis=1), hi - lo, -1.0)
    order = np.argsort(-spread, kind="stable")
    return order[: max(0, min(top, c.shape[0]))]


def _colors(n: int) -> list[tuple[float, float, float, float]]:
    """``n`` distinct non-grey colours: tab10-like dark shades first, then light ones."""
    from matplotlib import colormaps

    t20, t20b = colormaps["tab20"], colormaps["tab20b"]
    grey = (14, 15)
    palette = [t20(i) for i in range(0, 20, 2) if i not in grey]
    palette += [t20(i) for i in range(1, 20, 2) if i not in grey]
    palette += [t20b(i) for i in range(0, 20, 2)]
    return [palette[k % len(palette)] for k in range(n)]


def build_sweep(
    scales: np.ndarray,
    costs: np.ndarray,
    *,
    param_names: Sequence[str],
    title: str | None = None,
    top: int = 20,
    direction_names: Sequence[str] | None = None,
    log: bool | None = None,
) -> Figure:
    """Build the sweep figure (see :func:`plot_sweep`) without saving it.

    Highlighted lines carry the parameter name as their label (and ``gid``
    ``"top:<name>"``); grey lines have ``gid`` ``"rest:<name>"``.
    """
    s, c = _sweep_arrays(scales, costs, len(param_names))
    n_p, n_dir = len(param_names), c.shape[0]
    if direction_names is None:
        direction_names = [f"direction {k + 1}" for k in range(n_dir)] if n_dir > 1 else [""]
    if len(direction_names) != n_dir:
        raise DataError(
            f"sweep plot: {len(direction_names)} direction names for {n_dir} directions"
        )
    finite = c[np.isfinite(c)]
    if log is None:
        log = bool(finite.size and finite.min() > 0 and finite.max() / finite.min() > 30)
    k_top = max(0, min(top, n_p))
    fig = new_figure(11.5, max(4.8, 4.6 * n_dir))
    for d in range(n_dir):
        ax = fig.add_subplot(n_dir, 1, d + 1)
        ranked = rank_parameters(c[d], k_top)
        _draw_lines(ax, s, c[d], ranked, param_names)
        ax.axvline(1.0, color="0.3", linewidth=0.8, linestyle=":", zorder=0)
        if log:
            ax.set_yscale("log")
        ax.set_xlim(float(s.min()), float(s.max()))
        style_axes(ax)
        ax.tick_params(labelsize=9.5)
        ax.set_ylabel("cost", fontsize=11)
        if d == n_dir - 1:
            ax.set_xlabel("scale factor on the nominal value", fontsize=11)
        head, rest = direction_names[d], n_p - k_top
        sub = f"top {k_top} of {n_p} parameters by cost range" + (
            f" ({rest} others in grey)" if rest else ""
        )
        ax.set_title(f"{head}: {sub}" if head else sub, fontsize=11, loc="left")
        if k_top:
            _rank_legend(ax, [param_names[p] for p in ranked])
    if title:
        fig.suptitle(title, fontsize=13)
    return fig


def _sweep_arrays(scales: np.ndarray, costs: np.ndarray, n_p: int) -> tuple[np.ndarray, np.ndarray]:
    """``scales`` ``(n_scales,)`` and ``costs`` as ``(n_directions, n_params, n_scales)``."""
    s = np.asarray(scales, dtype=float)
    c = np.asarray(costs, dtype=float)
    if c.ndim == 2:
        c = c[None]
    if c.ndim != 3 or c.shape[1:] != (n_p, s.size) or s.ndim != 1:
        raise DataError(
            f"sweep plot: costs have shape {np.shape(costs)}, expected (n_params, n_scales) = "
            f"{(n_p, s.size)} or (n_directions, n_params, n_scales)"
        )
    return s, c


def _draw_lines(
    ax: Any, s: np.ndarray, c: np.ndarray, ranked: np.ndarray, param_names: Sequence[str]
) -> None:
    """One panel's lines: the ``ranked`` parameters coloured (best on top), the rest grey."""
    k_top = len(ranked)
    top_set = set(ranked.tolist())
    for p in range(len(param_names)):
        if p not in top_set:
            ax.plot(
                s, c[p], color="0.72", linewidth=0.8, zorder=1,
                label="_nolegend_", gid=f"rest:{param_names[p]}",
            )  # fmt: skip
    colors = _colors(k_top)
    for rank, p in reversed(list(enumerate(ranked))):  # best-ranked drawn on top
        ax.plot(
            s, c[p], color=colors[rank], linewidth=1.9, zorder=3 + k_top - rank,
            linestyle="-" if rank < 9 else ("--" if rank < 18 else ":"),
            marker="o" if s.size <= 15 else None, markersize=3.5,
            label=param_names[p], gid=f"top:{param_names[p]}",
        )  # fmt: skip


def _rank_legend(ax: Any, names: list[str]) -> None:
    """The legend right of the panel, listing ``names`` (the highlighted lines) in rank order."""
    fs = font_scale(len(names), full=10, small=30)
    handles, labs = ax.get_legend_handles_labels()
    order = [labs.index(name) for name in names]
    ax.legend(
        [handles[i] for i in order],
        [labs[i] for i in order],
        loc="center left",
        bbox_to_anchor=(1.01, 0.5),
        fontsize=fs,
        frameon=False,
        ncols=1 if len(names) <= 22 else 2,
        title="rank order",
        title_fontsize=fs,
    )


def plot_sweep(
    scales: np.ndarray,
    costs: np.ndarray,
    *,
    param_names: Sequence[str],
    path: str | os.PathLike[str],
    title: str | None = None,
    top: int = 20,
    direction_names: Sequence[str] | None = None,
    log: bool | None = None,
) -> Path:
    """Draw cost against the scale factor of each parameter (one-at-a-time sweep), save a PNG.

    Args:
        scales: scale factors applied to each parameter's nominal value, shape
            ``(n_scales,)``, dimensionless (e.g. ``0.5 .. 1.5``; 1 is marked).
        costs: cost for each parameter and scale, shape ``(n_params, n_scales)``, or
            ``(n_directions, n_params, n_scales)`` for one panel per direction.
        param_names: ``n_params`` names.
        path: output ``.png`` file, written atomically.
        title: figure title.
        top: how many parameters to highlight per panel, ranked by cost range
            ``max − min`` over the sweep; the others are drawn grey.
        direction_names: panel names for 3-D ``costs``.
        log: log cost axis; default when all costs are positive and span > 30×.

    Returns:
        ``path`` as a :class:`~pathlib.Path`.
    """
    fig = build_sweep(
        scales,
        costs,
        param_names=param_names,
        title=title,
        top=top,
        direction_names=direction_names,
        log=log,
    )
    return save_png(fig, path)
