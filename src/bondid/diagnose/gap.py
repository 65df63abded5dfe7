"""Where the sim-to-real gap lies: the spec's ``db_rms`` in total, per channel and per band.

The gap figure (spec §4) is the root-mean-square over all used channels and frequencies of

    (20 / ln 10) · |ln(H_meas / H_model)|        (complex logarithm, phase wrapped to (−π, π])

pooled over every data set given. It is computed with :func:`bondid.cost.residuals.residual`
(kind ``complex_log``), the same residual the fit minimises. A point counts when both the
measured and the model value are finite and non-zero. By default every point weighs the same;
``weighting="coherence"`` weighs each squared point error by the measured coherence (off by
default, so that the figure is the spec's plain RMS).

The residual map (:attr:`GapReport.residual_db`) is the signed magnitude error
``20·log10|H_model| − 20·log10|H_meas|`` in dB: positive where the model is above the data.
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..cost.residuals import DB, residual
from ..data.measurement import FrfData
from ..exceptions import DataError
from ..jsonsafe import number
from ..modes.bands import Feature, Span, automatic_bands

WEIGHTINGS: tuple[str, ...] = ("none", "coherence")
#: smallest relative half-width of a gap band around a feature
GAP_BAND_HALFWIDTH = 0.15
#: fewest frequencies a gap band may hold (so that it can be scored)
GAP_BAND_MIN_POINTS = 3


def gap_bands(
    freq_hz: np.ndarray,
    features: Sequence[Feature],
    *,
    min_halfwidth: float = GAP_BAND_HALFWIDTH,
    min_points: int = GAP_BAND_MIN_POINTS,
) -> list[Span]:
    """The ``by_band`` bands of the gap: :func:`bondid.modes.bands.automatic_bands` around
    the ``features`` (measured resonances with their damping, anti-resonances) as plain spans.

    Each feature at ``f`` gets the window ``[f/(1+h), f·(1+h)]``, ``h = max(2ζ,
    min_halfwidth, 1.5 grid steps)``; overlapping windows merge, the gaps between them are
    bands of their own, and a band holding fewer than ``min_points`` frequencies is merged
    into a neighbour, so every band can be scored.

    Args:
        freq_hz: measured frequencies ``(n_freq,)`` [Hz], increasing.
        features: :class:`~bondid.modes.bands.Feature` list (those outside the data range
            are ignored).
        min_halfwidth: smallest relative half-width ``h`` of a feature window.
        min_points: fewest frequencies a band may hold.

    Returns:
        ``[(f_lo, f_hi), ...]`` in Hz, contiguous (each ``f_hi`` is the next ``f_lo``), from
        ``freq_hz[0]`` to ``freq_hz[-1]``.

    Raises:
        DataError: empty or non-increasing ``freq_hz``.
    """
    f = np.asarray(freq_hz, dtype=float)
    if f.ndim != 1 or f.size == 0 or np.any(np.diff(f) <= 0):
        raise DataError("gap_bands: freq_hz must be 1-D, non-empty and increasing (Hz)")
    bands = automatic_bands(features, f, min_halfwidth=min_halfwidth, min_points=min_points)
    # tile the range: a band left out for holding no frequency leaves no hole
    edges = [float(f[0]), *(b.f_hi_hz for b in bands[:-1]), float(f[-1])]
    return list(itertools.pairwise(edges))


def band_mask(freq_hz: np.ndarray, band: tuple[float, float], last: bool) -> np.ndarray:
    """Boolean ``(n_freq,)``: ``f_lo ≤ f < f_hi`` (``≤ f_hi`` for the last band)."""
    f = np.asarray(freq_hz, dtype=float)
    return (f >= band[0]) & ((f <= band[1]) if last else (f < band[1]))


@dataclass
class GapReport:
    """The gap between measured and model FRFs.

    Attributes:
        db_rms: the spec's figure over all used channels, frequencies and data sets [dB].
        by_channel: ``OUT.IN`` → db_rms of that channel (pooled over data sets) [dB].
        by_band: ``[{"f_lo_hz", "f_hi_hz", "db_rms", "n_points"}, ...]`` in band order
            (``db_rms`` is NaN for a band with no used point).
        residual_db: ``(n_rows, n_freq)`` signed magnitude error
            ``20 log10|H_model| − 20 log10|H_meas|`` [dB], NaN where unused.
        channels: row labels of ``residual_db`` (``OUT.IN``; with several data sets
            ``OUT.IN #k``, k = 1-based data-set index).
        freq_hz: ``(n_freq,)`` the map's frequencies [Hz] (the first data set's; other data
            sets' rows are interpolated onto them in log-frequency when their grids differ).
        mag_db_rms: RMS of the magnitude-only error [dB] over the same points.
        n_points: number of (channel, frequency) points used.
        weighting: ``"none"`` or ``"coherence"``.
    """

    db_rms: float
    by_channel: dict[str, float]
    by_band: list[dict[str, float]]
    residual_db: np.ndarray
    channels: list[str]
    freq_hz: np.ndarray = field(default_factory=lambda: np.zeros(0))
    mag_db_rms: float = float("nan")
    n_points: int = 0
    weighting: str = "none"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict with the spec's keys ``db_rms``, ``by_channel``, ``by_band``
        (the map itself is left out: it is drawn as a PNG)."""
        num = number
        return {
            "db_rms": num(self.db_rms),
            "mag_db_rms": num(self.mag_db_rms),
            "by_channel": {k: num(v) for k, v in self.by_channel.items()},
            "by_band": [
                {k: (num(v) if k != "n_points" else int(v)) for k, v in b.items()}
                for b in self.by_band
            ],
            "n_points": int(self.n_points),
            "weighting": self.weighting,
        }

    def to_json(self) -> str:
        """:meth:`to_dict` as indented JSON text."""
        return json.dumps(self.to_dict(), indent=2) + "\n"


def _rms(sq: np.ndarray, w: np.ndarray) -> float:
    total = float(np.sum(w))
    return float(np.sqrt(np.sum(sq * w) / total)) if total > 0 else float("nan")


def gap_report(
    data: FrfData | Sequence[FrfData],
    model_H: np.ndarray | Sequence[np.ndarray],
    bands: Sequence[tuple[float, float]] | None = None,
    *,
    channels: Sequence[str] | None = None,
    by_file: Mapping[str, Sequence[str]] | None = None,
    weighting: str = "none",
) -> GapReport:
    """The gap (spec ``db_rms``) in total, per channel and per band.

    Args:
        data: one measured data set or several (e.g. several operating points).
        model_H: the model FRF of each data set, ``(n_out, n_in, n_freq)`` complex, aligned
            with that data set's ``outputs``, ``inputs`` and ``freq_hz`` and in its quantity.
        bands: ``[(f_lo, f_hi), ...]`` [Hz] for ``by_band`` (e.g. :func:`gap_bands`);
            default one band over the whole range.
        channels: ``OUT.IN`` names to use (default every channel present in the data).
        by_file: per data file (its ``source``), the channels used there instead (a channel
            informative at one operating point only is counted there only).
        weighting: ``"none"`` (the spec's figure) or ``"coherence"``.

    Returns:
        :class:`GapReport`.

    Raises:
        DataError: model and data shapes differ, unknown weighting, or no usable point.
    """
    sets, models = _paired(data, model_H)
    if weighting not in WEIGHTINGS:
        raise DataError(f"gap_report: unknown weighting {weighting!r}; valid: none, coherence")
    f_map = sets[0].freq_hz
    if bands is None:
        bands = [(min(float(d.freq_hz[0]) for d in sets), max(float(d.freq_hz[-1]) for d in sets))]
    bands = [(float(lo), float(hi)) for lo, hi in bands]
    use = list(channels) if channels is not None else _all_channels(sets)

    points: list[_Points] = []
    per_channel: dict[str, list[_Points]] = {c: [] for c in use}
    rows, labels = [], []
    for k, (d, Hs) in enumerate(zip(sets, models, strict=True)):
        here = by_file.get(d.source or "", use) if by_file else use
        for c in (c for c in use if c in here):
            pts = _channel_points(d, Hs, c, weighting)
            if pts is None:
                continue
            points.append(pts)
            per_channel[c].append(pts)
            rows.append(_on_grid(pts.mag, d.freq_hz, f_map))
            labels.append(c if len(sets) == 1 else f"{c} #{k + 1}")
    if not points or float(np.sum(np.concatenate([p.w for p in points]))) == 0.0:
        raise DataError("gap_report: no channel has a usable (finite, non-zero) point")
    w_cat = np.concatenate([p.w for p in points])
    return GapReport(
        db_rms=_pooled_rms(points),
        by_channel={c: _pooled_rms(v) for c, v in per_channel.items() if v},
        by_band=_band_table(points, bands),
        residual_db=np.vstack(rows),
        channels=labels,
        freq_hz=f_map.copy(),
        mag_db_rms=_rms(np.concatenate([p.mag_sq for p in points]), w_cat),
        n_points=int(np.count_nonzero(w_cat)),
        weighting=weighting,
    )


@dataclass
class _Points:
    """The gap's points of one channel of one data set, each ``(n_freq,)``: squared complex-log
    error ``sq`` and squared magnitude error ``mag_sq`` [dB²] (0 where unused), weight ``w``
    (0 where unused), signed magnitude error ``mag`` [dB] (NaN where unused), at ``freq_hz``."""

    sq: np.ndarray
    w: np.ndarray
    mag_sq: np.ndarray
    mag: np.ndarray
    freq_hz: np.ndarray


def _paired(
    data: FrfData | Sequence[FrfData], model_H: np.ndarray | Sequence[np.ndarray]
) -> tuple[list[FrfData], list[np.ndarray]]:
    """The data sets and their model FRFs as two lists of one length, each model FRF of its
    data set's shape (DataError otherwise)."""
    sets = [data] if isinstance(data, FrfData) else list(data)
    models = [model_H] if isinstance(model_H, np.ndarray) and model_H.ndim == 3 else model_H
    arrays = [np.asarray(m, dtype=complex) for m in models]
    if not sets or len(arrays) != len(sets):
        raise DataError(f"gap_report: {len(sets)} data set(s) but {len(arrays)} model FRF array(s)")
    for k, (d, Hs) in enumerate(zip(sets, arrays, strict=True)):
        if Hs.shape != d.H.shape:
            raise DataError(
                f"gap_report: {d.source or f'data set {k + 1}'}: model FRF has shape "
                f"{Hs.shape}, expected {d.H.shape}"
            )
    return sets, arrays


def _all_channels(sets: Sequence[FrfData]) -> list[str]:
    """Every channel present in any of ``sets``, in order of first appearance."""
    names: list[str] = []
    for d in sets:
        names += [c for c in d.channels if c not in names]
    return names


def _channel_points(d: FrfData, Hs: np.ndarray, channel: str, weighting: str) -> _Points | None:
    """The points of ``channel`` (``OUT.IN``) in data set ``d`` against the model FRF ``Hs``
    (None when ``d`` lacks the channel). A point is used when both values are finite and
    non-zero; with ``weighting="coherence"`` its weight is the measured coherence."""
    out, _, inp = channel.rpartition(".")
    if out not in d.outputs or inp not in d.inputs:
        return None
    a, b = d.outputs.index(out), d.inputs.index(inp)
    hm, hs = d.H[a, b], Hs[a, b]
    ok = np.isfinite(hm) & np.isfinite(hs) & (hm != 0) & (hs != 0)
    r = np.full((2, hm.size), np.nan)
    if np.any(ok):
        r[:, ok] = residual("complex_log", hs[ok], hm[ok])
    w = ok.astype(float)
    if weighting == "coherence" and d.coherence is not None:
        coh = d.coherence[a, b]
        w = w * np.where(np.isfinite(coh), np.clip(coh, 0.0, 1.0), 1.0)
    return _Points(
        sq=np.where(ok, r[0] ** 2 + r[1] ** 2, 0.0),
        w=w,
        mag_sq=np.where(ok, r[0] ** 2, 0.0),
        mag=np.where(ok, r[0], np.nan),  # r[0] = DB·ln|Hs/Hm|: model above data > 0
        freq_hz=d.freq_hz,
    )


def _on_grid(mag: np.ndarray, freq_hz: np.ndarray, f_map: np.ndarray) -> np.ndarray:
    """``mag`` (at ``freq_hz``) on the map's grid ``f_map``: as is when the grids agree, else
    interpolated in log-frequency over its finite points (all NaN with fewer than two)."""
    if freq_hz.shape == f_map.shape and np.allclose(freq_hz, f_map):
        return mag
    good = np.isfinite(mag)
    if np.count_nonzero(good) < 2:
        return np.full(f_map.shape, np.nan)
    return np.interp(np.log(f_map), np.log(freq_hz[good]), mag[good])


def _pooled_rms(points: Sequence[_Points]) -> float:
    """Weighted RMS of the complex-log error over every point of ``points``."""
    return _rms(np.concatenate([p.sq for p in points]), np.concatenate([p.w for p in points]))


def _band_table(points: Sequence[_Points], bands: Sequence[Span]) -> list[dict[str, float]]:
    """``by_band`` rows: per band (half-open, the last closed) its RMS and used points."""
    table = []
    for j, band in enumerate(bands):
        masks = [band_mask(p.freq_hz, band, j == len(bands) - 1) for p in points]
        s = np.concatenate([p.sq[m] for p, m in zip(points, masks, strict=True)])
        w = np.concatenate([p.w[m] for p, m in zip(points, masks, strict=True)])
        table.append(
            {
                "f_lo_hz": band[0],
                "f_hi_hz": band[1],
                "db_rms": _rms(s, w),
                "n_points": int(np.count_nonzero(w)),
            }
        )
    return table


__all__ = ["DB", "WEIGHTINGS", "GapReport", "band_mask", "gap_bands", "gap_report"]


def missing_mode_hints(
    by_dataset: list[list[dict[str, Any]]], tol: float = 0.02
) -> tuple[float, ...]:
    """Frequencies [Hz] of the measured modes the refitted model lacks (status ``missing``),
    over all data sets, merged within a relative ``tol``, ascending."""
    found = sorted(
        float(r["f_measured_hz"])
        for rows in by_dataset
        for r in rows
        if r.get("status") == "missing" and r.get("f_measured_hz")
    )
    out: list[float] = []
    for f in found:
        if not out or f > out[-1] * (1.0 + tol):
            out.append(f)
    return tuple(out)


def worst_matched_modes(
    by_dataset: list[list[dict[str, Any]]], n: int = 3, tol: float = 0.02
) -> tuple[float, ...]:
    """Frequencies [Hz] of the measured modes the refitted model pairs worst (largest
    ``(1 − MAC) + |df_rel|/0.2``, the pairing's own cost), over all data sets, merged within
    a relative ``tol``, worst first, at most ``n``: where a spring the model lacks may have
    bent a paired mode away from the measured one."""
    rows = [
        r for rows in by_dataset for r in rows
        if r.get("status") == "paired" and r.get("f_measured_hz")
    ]  # fmt: skip

    def cost(r: dict[str, Any]) -> float:
        mac = r.get("mac")
        df = r.get("df_rel")
        return (1.0 - float(mac if mac is not None else 0.0)) + abs(float(df or 0.0)) / 0.2

    out: list[float] = []
    for r in sorted(rows, key=cost, reverse=True):
        f = float(r["f_measured_hz"])
        if all(abs(f / g - 1.0) > tol for g in out):
            out.append(f)
        if len(out) == n:
            break
    return tuple(out)
