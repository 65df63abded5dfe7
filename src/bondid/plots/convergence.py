"""Convergence plot: cost per iteration of one or several (multistart) optimisation runs."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..exceptions import DataError
from ._common import new_figure, save_png, style_axes

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.figure import Figure

#: With more runs than this, runs are drawn as thin grey lines without a legend entry each.
LEGEND_MAX_RUNS = 10


def as_runs(costs: np.ndarray | Sequence[Sequence[float]] | Sequence[float]) -> list[np.ndarray]:
    """Normalise ``costs`` to a list of 1-D float arrays, one per run (lengths may differ)."""
    if isinstance(costs, np.ndarray):
        if costs.ndim == 1:
            return [costs.astype(float)]
        if costs.ndim == 2:
            return [np.asarray(row, dtype=float) for row in costs]
        raise DataError(f"convergence plot: costs has {costs.ndim} dimensions; expected 1 or 2")
    items = list(costs)
    if items and all(np.ndim(np.asarray(c)) == 0 for c in items):
        return [np.asarray(items, dtype=float)]
    runs = [np.asarray(c, dtype=float).ravel() for c in items]
    if not runs or any(r.size == 0 for r in runs):
        raise DataError("convergence plot: every run needs at least one cost value")
    return runs


def build_convergence(
    costs: np.ndarray | Sequence[Sequence[float]] | Sequence[float],
    *,
    labels: Sequence[str] | None = None,
    title: str | None = None,
) -> Figure:
    """Build the convergence figure (see :func:`plot_convergence`) without saving it."""
    from matplotlib.ticker import MaxNLocator

    runs = as_runs(costs)
    if labels is not None and len(labels) != len(runs):
        raise DataError(
            f"convergence plot: {len(labels)} labels for {len(runs)} runs; give one per run"
        )
    finals = np.array([r[np.isfinite(r)][-1] if np.any(np.isfinite(r)) else np.inf for r in runs])
    best = int(np.argmin(finals))
    positive = all(np.all(r[np.isfinite(r)] > 0) for r in runs)
    fig = new_figure(8.0, 5.0)
    ax = fig.add_subplot()
    _draw_runs(ax, runs, labels, best)
    if positive:
        ax.set_yscale("log")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlim(0, max(r.size for r in runs) - 1 or 1)
    style_axes(ax)
    ax.set_xlabel("iteration", fontsize=11)
    ax.set_ylabel("cost", fontsize=11)
    ax.tick_params(labelsize=9.5)
    _mark_final(ax, float(finals[best]), positive)
    if len(runs) > 1 or labels is not None:
        ax.legend(fontsize=9, loc="upper right", framealpha=0.9)
    ax.set_title(title or "Convergence", fontsize=12)
    return fig


def _draw_runs(ax: Any, runs: list[np.ndarray], labels: Sequence[str] | None, best: int) -> None:
    """One line per run, the ``best`` thick and on top; with more than
    :data:`LEGEND_MAX_RUNS` runs the others are thin grey lines under one legend entry."""
    many = len(runs) > LEGEND_MAX_RUNS
    for k, r in enumerate(runs):
        it = np.arange(r.size)
        name = labels[k] if labels is not None else (f"run {k + 1}" if len(runs) > 1 else "cost")
        if k == best and len(runs) > 1:
            continue  # drawn last, on top
        if many:
            ax.plot(it, r, color="0.6", linewidth=0.9, alpha=0.8, label="_nolegend_")
        else:
            ax.plot(
                it,
                r,
                color=f"C{k % 10}",
                linewidth=1.4,
                label=name,
                marker="." if r.size < 40 else "",
            )
    if len(runs) > 1:
        r = runs[best]
        name = labels[best] if labels is not None else f"run {best + 1}"
        ax.plot(
            np.arange(r.size), r, color="black" if many else f"C{best % 10}", linewidth=2.4,
            label=f"{name} (best)", zorder=4, marker="." if r.size < 40 else "",
        )  # fmt: skip
    if many:
        ax.plot([], [], color="0.6", linewidth=0.9, label=f"other {len(runs) - 1} runs")


def _mark_final(ax: Any, fin: float, positive: bool) -> None:
    """A dotted line at the best final cost ``fin``, labelled at the left under the line."""
    ax.axhline(fin, color="0.3", linewidth=0.8, linestyle=":", zorder=1)
    # room under the best final value for its label, at the left where costs are still high
    lo, hi = ax.get_ylim()
    if positive:
        ax.set_ylim(min(lo, fin / (hi / fin) ** 0.08), hi)
    else:
        ax.set_ylim(min(lo, fin - 0.08 * (hi - lo)), hi)
    ax.annotate(
        f"best final cost {fin:.4g}", xy=(0.0, fin), xycoords=("axes fraction", "data"),
        xytext=(6, -3), textcoords="offset points", ha="left", va="top", fontsize=9,
        color="0.2",
    )  # fmt: skip


def plot_convergence(
    costs: np.ndarray | Sequence[Sequence[float]] | Sequence[float],
    *,
    path: str | os.PathLike[str],
    labels: Sequence[str] | None = None,
    title: str | None = None,
) -> Path:
    """Draw cost against iteration (log y when every cost is positive) and save a PNG.

    Args:
        costs: one run as a 1-D sequence ``(n_iter,)``, or several runs (multistart) as a
            2-D array ``(n_runs, n_iter)`` or a list of 1-D sequences of different lengths.
            Cost is dimensionless (whatever the objective returns).
        path: output ``.png`` file, written atomically.
        labels: one legend label per run.
        title: figure title.

    The run with the lowest final cost is drawn thick and on top, with a dotted line at its
    final value; with more than :data:`LEGEND_MAX_RUNS` runs the others are thin grey lines.

    Returns:
        ``path`` as a :class:`~pathlib.Path`.
    """
    return save_png(build_convergence(costs, labels=labels, title=title), path)
