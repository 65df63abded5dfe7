"""Bode grids of FRF matrices: one magnitude-over-phase cell per channel ``OUT.IN``."""

from __future__ import annotations

import math
import os
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..data.quantity import QUANTITIES
from ..exceptions import ChannelError, DataError
from ._common import new_figure, save_png, style_axes
from .units import channel_unit, magnitude_label

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.figure import Figure

#: Colours of model curves, in order (measured data is drawn in grey/black).
MODEL_COLORS: tuple[str, ...] = (
    "#1f77b4",
    "#d62728",
    "#2ca02c",
    "#ff7f0e",
    "#9467bd",
    "#17becf",
    "#8c564b",
    "#e377c2",
)

_KIND_STYLE: dict[str, dict[str, Any]] = {
    "measured": {"color": "0.55", "linewidth": 2.4, "alpha": 0.7, "zorder": 2},
    "reference": {"color": "0.55", "linewidth": 1.0, "linestyle": "--", "zorder": 2},
    "model": {"linewidth": 1.5, "zorder": 3},
    "noise": {"color": "0.3", "linewidth": 1.1, "linestyle": ":", "zorder": 2},
}


@dataclass
class Curve:
    """One FRF matrix to draw on the Bode grid.

    Attributes:
        label: legend text.
        H: complex FRF, shape ``(n_out, n_in, n_freq)``, NaN for channels it lacks.
        style: matplotlib ``Line2D`` keyword overrides (``color``, ``linewidth``, ...).
        freq_hz: its own frequency grid, shape ``(n_freq,)``, Hz; None = the plot's grid.
        kind: ``"measured"`` (thin grey line), ``"model"`` (coloured line),
            ``"reference"`` (grey dashed) or ``"noise"`` (a noise level, e.g. the estimated
            noise floor: dotted dark grey, magnitude only); chooses the default style.
    """

    label: str
    H: np.ndarray
    style: dict[str, Any] = field(default_factory=dict)
    freq_hz: np.ndarray | None = None
    kind: str = "model"


#: the Bode grid's fixed margins and gaps (inches): room for the axis labels and tick labels
#: (left, between columns), the cells' titles (top, between rows), the frequency label and
#: the legend (bottom), the figure's title
_LEFT_IN, _RIGHT_IN, _TOP_IN, _TITLE_IN = 0.85, 0.3, 0.3, 0.35
_BOTTOM_IN, _WSPACE_IN, _HSPACE_IN = 0.95, 0.85, 0.75


def _wrap_phase_deg(freq: np.ndarray, H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Phase in degrees in [-180, 180], with NaN breaks inserted at the ±180° jumps."""
    ph = np.degrees(np.angle(H))
    ph[~np.isfinite(H)] = np.nan
    jumps = np.flatnonzero(np.abs(np.diff(ph)) > 180.0)
    if jumps.size == 0:
        return freq, ph
    f_mid = np.sqrt(freq[jumps] * freq[jumps + 1])
    return np.insert(freq, jumps + 1, f_mid), np.insert(ph, jumps + 1, np.nan)


def magnitude_db(H: np.ndarray) -> np.ndarray:
    """``20 log10 |H|`` in dB, NaN where ``H`` is NaN or exactly zero; same shape as ``H``."""
    mag = np.abs(np.asarray(H))
    with np.errstate(divide="ignore", invalid="ignore"):
        db = 20.0 * np.log10(np.where(mag > 0, mag, np.nan))
    return db


def _grid(
    outputs: Sequence[str], inputs: Sequence[str], channels: Sequence[str] | None
) -> tuple[int, int, list[tuple[int, int] | None]]:
    """Rows, columns and the ``(i_out, i_in)`` shown in each cell (row-major)."""
    if channels is None:
        cells: list[tuple[int, int] | None] = [
            (a, b) for a in range(len(outputs)) for b in range(len(inputs))
        ]
        return len(outputs), len(inputs), cells
    picked: list[tuple[int, int] | None] = []
    for name in channels:
        out, _, inp = str(name).rpartition(".")
        if out not in outputs or inp not in inputs:
            valid = ", ".join(f"{o}.{i}" for o in outputs for i in inputs)
            raise ChannelError(f"Bode plot: no channel {name!r}; valid: {valid}")
        picked.append((list(outputs).index(out), list(inputs).index(inp)))
    if not picked:
        raise ChannelError("Bode plot: 'channels' is empty; give at least one OUT.IN")
    ncols = 2 if len(picked) in (2, 4) else min(len(picked), 3)
    nrows = math.ceil(len(picked) / ncols)
    return nrows, ncols, picked


def build_bode(
    freq_hz: np.ndarray,
    curves: Sequence[Curve],
    *,
    outputs: Sequence[str],
    inputs: Sequence[str],
    title: str | None = None,
    quantity: str = "receptance",
    units: Mapping[str, Any] | None = None,
    channels: Sequence[str] | None = None,
    left_out: Collection[str] = (),
) -> Figure:
    """Build the Bode grid figure (see :func:`plot_bode`) without saving it.

    Each cell has two axes, magnitude above phase, so the figure holds ``2 × n_cells``
    axes in row-major cell order (magnitude, phase, magnitude, phase, ...).
    """
    if quantity not in QUANTITIES:
        raise DataError(f"Bode plot: unknown quantity {quantity!r}; valid: {', '.join(QUANTITIES)}")
    if not curves:
        raise DataError("Bode plot: no curves given; pass at least one Curve")
    data = _curve_arrays(freq_hz, curves, len(outputs), len(inputs))
    styles = _curve_styles(curves)
    nrows, ncols, cells = _grid(outputs, inputs, channels)
    width, height = max(6.5, 5.3 * ncols), max(4.8, 4.1 * nrows + 0.9)
    # A fixed layout in inches: matplotlib's constrained layout measures every tick label of
    # every axis and took most of a fit's plotting time on a 3 × 3 grid (18 axes).
    fig = new_figure(width, height, layout=None)
    top = _TOP_IN + (_TITLE_IN if title else 0.0)
    cell_w = (width - _LEFT_IN - _RIGHT_IN - (ncols - 1) * _WSPACE_IN) / ncols
    cell_h = (height - top - _BOTTOM_IN - (nrows - 1) * _HSPACE_IN) / nrows
    outer = fig.add_gridspec(
        nrows, ncols, left=_LEFT_IN / width, right=1.0 - _RIGHT_IN / width,
        bottom=_BOTTOM_IN / height, top=1.0 - top / height,
        wspace=_WSPACE_IN / cell_w, hspace=_HSPACE_IN / cell_h,
    )  # fmt: skip
    f_range = (min(float(np.nanmin(f)) for f, _ in data), max(float(np.nanmax(f)) for f, _ in data))
    share = None
    for k, cell in enumerate(cells):
        r, col = divmod(k, ncols)
        sub = outer[r, col].subgridspec(2, 1, height_ratios=[3, 2], hspace=0.0)
        ax_m = fig.add_subplot(sub[0], sharex=share)
        share = share or ax_m
        ax_p = fig.add_subplot(sub[1], sharex=share)
        assert cell is not None
        a, b = cell
        name = f"{outputs[a]}.{inputs[b]}"
        muted = name in left_out
        ax_m.set_title(
            f"{name}  (left out of the fit)" if muted else name,
            fontsize=11, fontweight="normal" if muted else "bold", pad=4,
            color="0.5" if muted else "black",
        )  # fmt: skip
        any_data = _draw_channel(ax_m, ax_p, cell, data, curves, styles, muted)
        unit = channel_unit(units, outputs[a], inputs[b], quantity)
        _style_cell(ax_m, ax_p, f_range, magnitude_label(quantity, unit))
        if r == nrows - 1 or k + ncols >= len(cells):
            ax_p.set_xlabel("frequency [Hz]", fontsize=9.5)
        if not any_data:
            _mark_no_data(ax_m, ax_p)
        elif muted:
            _mark_left_out(ax_m, ax_p)
    _legend(fig, curves, styles, bool(left_out))
    if title:
        fig.suptitle(title, fontsize=13, y=1.0 - 0.1 / fig.get_figheight(), va="top")
    return fig


def _curve_arrays(
    freq_hz: np.ndarray, curves: Sequence[Curve], n_out: int, n_in: int
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each curve's ``(freq (n_freq,) Hz, H (n_out, n_in, n_freq))``, shapes checked."""
    f0 = np.asarray(freq_hz, dtype=float)
    data: list[tuple[np.ndarray, np.ndarray]] = []
    for c in curves:
        f = f0 if c.freq_hz is None else np.asarray(c.freq_hz, dtype=float)
        H = np.asarray(c.H, dtype=complex)
        if f.ndim != 1 or H.shape != (n_out, n_in, f.size):
            raise DataError(
                f"Bode plot: curve {c.label!r} has H shape {H.shape}, expected "
                f"(n_out, n_in, n_freq) = {(n_out, n_in, f.size)}"
            )
        data.append((f, H))
    return data


def _curve_styles(curves: Sequence[Curve]) -> list[dict[str, Any]]:
    """Line styles: the kind's default, model curves coloured in turn, the curve's overrides."""
    styles: list[dict[str, Any]] = []
    n_model = 0
    for c in curves:
        st = dict(_KIND_STYLE.get(c.kind, _KIND_STYLE["model"]))
        if c.kind not in ("measured", "reference", "noise") and "color" not in c.style:
            st["color"] = MODEL_COLORS[n_model % len(MODEL_COLORS)]
            n_model += 1
        st.update(c.style)
        styles.append(st)
    return styles


def _draw_channel(
    ax_m: Any,
    ax_p: Any,
    cell: tuple[int, int],
    data: list[tuple[np.ndarray, np.ndarray]],
    curves: Sequence[Curve],
    styles: list[dict[str, Any]],
    muted: bool = False,
) -> bool:
    """Draw channel ``cell = (i_out, i_in)`` of every curve that has data there (noise
    curves: magnitude only; ``muted``: faded, a channel left out of the fit); True when a
    curve other than a noise level had data."""
    a, b = cell
    any_data = False
    for (f, H), c, st in zip(data, curves, styles, strict=True):
        h = H[a, b]
        if not np.any(np.isfinite(h)):
            continue
        if muted:
            st = {**st, "alpha": 0.35 * float(st.get("alpha", 1.0))}
        any_data = any_data or c.kind != "noise"
        ax_m.plot(f, magnitude_db(h), label=c.label, **st)
        if c.kind == "noise":
            continue
        fp, ph = _wrap_phase_deg(f, h)
        ax_p.plot(fp, ph, label=c.label, **st)
    return any_data


def _style_cell(ax_m: Any, ax_p: Any, f_range: tuple[float, float], mag_label: str) -> None:
    """Log frequency axis over ``f_range`` (Hz), phase ticks every 90°, axis labels."""
    from matplotlib.ticker import FixedLocator

    ax_m.set_xscale("log")
    ax_m.set_xlim(*f_range)
    ax_p.set_ylim(-195, 195)
    ax_p.yaxis.set_major_locator(FixedLocator([-180, -90, 0, 90, 180]))
    for ax in (ax_m, ax_p):
        style_axes(ax)
        ax.tick_params(labelsize=8.5)
    ax_m.tick_params(labelbottom=False)
    ax_m.set_ylabel(mag_label, fontsize=9)
    ax_p.set_ylabel("phase [°]", fontsize=9)


def _mark_left_out(ax_m: Any, ax_p: Any) -> None:
    """Grey a cell whose channel the fit left out (below the noise floor)."""
    for ax in (ax_m, ax_p):
        ax.set_facecolor("0.93")
    ax_m.text(
        0.5, 0.08, "left out of the fit", transform=ax_m.transAxes,
        ha="center", va="bottom", fontsize=9, color="0.35", style="italic", gid="left-out",
    )  # fmt: skip


def _mark_no_data(ax_m: Any, ax_p: Any) -> None:
    """Shade a cell where no curve has data and write "no data" in it."""
    for ax in (ax_m, ax_p):
        ax.set_facecolor("0.96")
        ax.tick_params(labelleft=False)
    ax_m.text(
        0.5, 0.5, "no data", transform=ax_m.transAxes, ha="center", va="center",
        fontsize=13, color="0.45", style="italic", gid="no-data",
    )  # fmt: skip


#: the legend's line on channel names
CHANNEL_KEY = "cell OUT.IN: response at OUT to the excitation at IN"


def _legend(
    fig: Figure, curves: Sequence[Curve], styles: list[dict[str, Any]], left_out: bool = False
) -> None:
    """One legend below the grid, a line per curve, then what a cell's name means (and
    a grey patch for channels left out of the fit, when there are)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list[Any] = [Line2D([], [], **st) for st in styles]
    labels = [c.label for c in curves]
    handles.append(Line2D([], [], linestyle="none"))
    labels.append(CHANNEL_KEY)
    if left_out:
        handles.append(Patch(facecolor="0.93", edgecolor="0.6"))
        labels.append("channel left out of the fit")
    fig.legend(
        handles,
        labels,
        loc="lower center",
        bbox_to_anchor=(0.5, 0.05 / fig.get_figheight()),
        ncols=min(len(labels), 6),
        fontsize=10,
        frameon=False,
    )


def noise_curve(sigma: np.ndarray, label: str = "estimated noise") -> Curve:
    """A :class:`Curve` of a noise level ``sigma`` ``(n_out, n_in, n_freq)`` (units of ``H``)."""
    return Curve(label, np.asarray(sigma, dtype=float).astype(complex), kind="noise")


def plot_bode(
    freq_hz: np.ndarray,
    curves: Sequence[Curve],
    *,
    outputs: Sequence[str],
    inputs: Sequence[str],
    path: str | os.PathLike[str],
    title: str | None = None,
    quantity: str = "receptance",
    units: Mapping[str, Any] | None = None,
    channels: Sequence[str] | None = None,
    left_out: Collection[str] = (),
) -> Path:
    """Draw FRF matrices as an ``n_out × n_in`` grid of Bode cells and save a PNG.

    Args:
        freq_hz: frequency grid, shape ``(n_freq,)``, Hz (curves may bring their own).
        curves: the FRF matrices to overlay, each ``H`` of shape ``(n_out, n_in, n_freq)``.
        outputs: response joint names (grid rows), length ``n_out``.
        inputs: excited joint names (grid columns), length ``n_in``.
        path: output ``.png`` file, written atomically.
        title: figure title.
        quantity: ``receptance``, ``mobility`` or ``accelerance`` of the curves (labels the
            axes: ``accelerance [dB re 1 (m/s²)/N]``; convert the curves to it first).
        units: joint -> ``'m'`` / ``'rad'`` (or ``'N'`` / ``'N·m'``, or a
            ``(response, excitation)`` pair) to label magnitudes as ``dB re 1 m/N``.
        channels: optional subset ``['OUT.IN', ...]``, drawn compactly (≤ 3 cells per row).
        left_out: channels ``OUT.IN`` the fit left out: their cells are greyed and labelled.

    Magnitude is ``20 log10 |H|`` (dB); phase is in degrees wrapped to [-180, 180].
    A cell where no curve has data is shaded and marked "no data".

    Returns:
        ``path`` as a :class:`~pathlib.Path`.
    """
    fig = build_bode(
        freq_hz,
        curves,
        outputs=outputs,
        inputs=inputs,
        title=title,
        quantity=quantity,
        units=units,
        channels=channels,
        left_out=left_out,
    )
    return save_png(fig, path)
