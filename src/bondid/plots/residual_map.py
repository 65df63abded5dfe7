"""Residual map: the dB error of each channel against frequency, as a diverging image."""

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


def _log_edges(freq_hz: np.ndarray) -> np.ndarray:
    """Cell edges (n_freq + 1,) around log-spaced centres ``freq_hz`` (Hz, increasing)."""
    lf = np.log10(freq_hz)
    if lf.size == 1:
        return 10.0 ** np.array([lf[0] - 0.01, lf[0] + 0.01])
    mid = 0.5 * (lf[1:] + lf[:-1])
    return 10.0 ** np.concatenate(([2 * lf[0] - mid[0]], mid, [2 * lf[-1] - mid[-1]]))


def symmetric_limit(residual_db: np.ndarray, percentile: float = 99.0) -> float:
    """Colour limit ``v`` (dB) for the range ``[-v, v]``: the ``percentile`` of ``|residual|``.

    A percentile rather than the maximum keeps a single anti-resonance spike from washing out
    the rest of the map; values beyond it saturate (the colour bar shows arrows).
    """
    finite = np.abs(residual_db[np.isfinite(residual_db)])
    if finite.size == 0:
        return 1.0
    v = float(np.percentile(finite, percentile))
    return v if v > 0 else max(float(finite.max()), 1.0)


def build_residual_map(
    freq_hz: np.ndarray,
    residual_db: np.ndarray,
    *,
    channels: Sequence[str],
    title: str | None = None,
    bands: Sequence[tuple[float, float]] | None = None,
    vmax: float | None = None,
    cbar_label: str = "residual [dB]",
) -> Figure:
    """Build the residual-map figure (see :func:`plot_residual_map`) without saving it."""
    from matplotlib import colormaps

    f = np.asarray(freq_hz, dtype=float)
    r = np.asarray(residual_db, dtype=float)
    if f.ndim != 1 or f.size == 0 or np.any(f <= 0) or np.any(np.diff(f) <= 0):
        raise DataError("residual map: freq_hz must be 1-D, positive and strictly increasing (Hz)")
    if r.shape != (len(channels), f.size):
        raise DataError(
            f"residual map: residual_db has shape {r.shape}, expected "
            f"(n_channels, n_freq) = {(len(channels), f.size)}"
        )
    v = float(vmax) if vmax is not None else symmetric_limit(r)
    n = len(channels)
    fs = font_scale(n)
    fig = new_figure(11.0, min(2.2 + 0.32 * n, 24.0))
    ax = fig.add_subplot()
    cmap = colormaps["RdBu_r"].with_extremes(bad="0.82")
    mesh = ax.pcolormesh(
        _log_edges(f),
        np.arange(n + 1),
        np.ma.masked_invalid(r),
        cmap=cmap,
        vmin=-v,
        vmax=v,
        shading="flat",
        rasterized=True,
    )
    ax.set_xscale("log")
    ax.set_ylim(n, 0)  # first channel on top
    ax.set_yticks(np.arange(n) + 0.5, list(channels), fontsize=fs)
    ax.tick_params(axis="x", labelsize=9)
    ax.set_xlabel("frequency [Hz]", fontsize=10)
    ax.set_ylabel("channel (OUT.IN)", fontsize=10)
    if n > 1:
        ax.hlines(np.arange(1, n), *ax.get_xlim(), colors="white", linewidth=0.6)
    if bands:
        _draw_bands(ax, f, bands, n)
    _mark_empty_rows(ax, r, fs)
    cbar = fig.colorbar(mesh, ax=ax, extend=_extend(r, v), pad=0.015, fraction=0.05, aspect=30)
    cbar.set_label(cbar_label, fontsize=10)
    cbar.ax.tick_params(labelsize=9)
    ax.set_title(title or "Residual per channel", fontsize=12, pad=16 if bands else 6)
    return fig


def _draw_bands(ax: Any, f: np.ndarray, bands: Sequence[tuple[float, float]], n: int) -> None:
    """Dashed lines at the band edges inside the map and tags ``B1``, ``B2``, ... above it."""
    lo_f, hi_f = _log_edges(f)[[0, -1]]
    edges = sorted({float(e) for band in bands for e in band})
    inner = [e for e in edges if lo_f < e < hi_f]
    ax.vlines(inner, 0, n, colors="black", linewidth=0.9, linestyles="--")
    for k, (a, b) in enumerate(bands):
        centre = float(np.sqrt(max(a, lo_f) * min(b, hi_f)))
        ax.text(
            centre, 1.004, f"B{k + 1}", transform=ax.get_xaxis_transform(),
            ha="center", va="bottom", fontsize=8.5, color="0.2", clip_on=False,
        )  # fmt: skip
    ax.set_xlim(lo_f, hi_f)


def _mark_empty_rows(ax: Any, r: np.ndarray, fontsize: float) -> None:
    """Write "no data" across the rows (channels) without a finite residual."""
    for k in np.flatnonzero(~np.any(np.isfinite(r), axis=1)).tolist():
        ax.text(
            0.5, k + 0.5, "no data", transform=ax.get_yaxis_transform(),
            ha="center", va="center", fontsize=fontsize, color="0.35", style="italic",
        )  # fmt: skip


def _extend(r: np.ndarray, v: float) -> str:
    """The colour bar's ``extend``: arrows on the sides where residuals pass ``±v``."""
    above = bool(np.nanmax(r, initial=-np.inf) > v)
    below = bool(np.nanmin(r, initial=np.inf) < -v)
    return {(True, True): "both", (True, False): "max", (False, True): "min"}.get(
        (above, below), "neither"
    )


def plot_residual_map(
    freq_hz: np.ndarray,
    residual_db: np.ndarray,
    *,
    channels: Sequence[str],
    path: str | os.PathLike[str],
    title: str | None = None,
    bands: Sequence[tuple[float, float]] | None = None,
    vmax: float | None = None,
    cbar_label: str = "residual [dB]",
) -> Path:
    """Draw the dB residual of each channel against frequency as an image and save a PNG.

    Args:
        freq_hz: frequencies, shape ``(n_freq,)``, Hz, strictly increasing.
        residual_db: dB error per channel, shape ``(n_channels, n_freq)``
            (e.g. ``20 log10 |H_model| − 20 log10 |H_measured|``); NaN is drawn grey.
        channels: row labels ``OUT.IN``, length ``n_channels`` (first row on top).
        path: output ``.png`` file, written atomically.
        title: figure title.
        bands: frequency bands ``[(f_lo, f_hi), ...]`` in Hz; their edges are drawn as dashed
            vertical lines and each band is tagged ``B1``, ``B2``, ... under the axis.
        vmax: colour limit in dB (the map spans ``[-vmax, vmax]``, centred at 0); default
            the 99th percentile of ``|residual_db|``.
        cbar_label: colour-bar label (say which way the difference goes).

    Returns:
        ``path`` as a :class:`~pathlib.Path`.
    """
    fig = build_residual_map(
        freq_hz,
        residual_db,
        channels=channels,
        title=title,
        bands=bands,
        vmax=vmax,
        cbar_label=cbar_label,
    )
    return save_png(fig, path)
