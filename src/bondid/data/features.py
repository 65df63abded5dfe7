"""Resonances and anti-resonances found in measured data alone, for keeping the lines near them.

Peaks and dips of each channel's magnitude in dB, smoothed over a few lines
(±:data:`SMOOTH_REL` of the frequency, at most ±:data:`SMOOTH_MAX` lines), with a prominence
of at least :data:`PROMINENCE_DB` and an estimated signal-to-noise ratio of at least
:data:`PEAK_SNR_DB` at a peak and :data:`DIP_SNR_DB` at a dip (a dip lost in the noise floor
carries nothing). Each comes with the lines within :data:`WIDTHS` half-power half-widths of
it (:mod:`bondid.data.reduce` keeps them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: smoothing of the magnitude before the search: ±SMOOTH_REL × f, at most ±SMOOTH_MAX lines
SMOOTH_REL = 2e-3
SMOOTH_MAX = 16
#: the prominence [dB] of a peak or dip of the smoothed magnitude that counts
PROMINENCE_DB = 6.0
#: estimated SNR [dB] at a peak / at a dip for it to count
PEAK_SNR_DB = 10.0
DIP_SNR_DB = 0.0
#: the lines kept around a feature: within this many half-power half-widths of it, the
#: half-width taken within MIN_HALF_REL … MAX_HALF_REL of its frequency (the 3 dB width of a
#: dip next to a resonance comes out narrower than its damping says, and the dip between two
#: modes of a cross channel is broad without being a zero)
WIDTHS = 3.0
MIN_HALF_REL = 0.005
MAX_HALF_REL = 0.05
_HALF_POWER_DB = 10.0 * math.log10(2.0)


@dataclass(frozen=True)
class Feature:
    """A resonance (``kind "resonance"``) or anti-resonance found in one channel.

    Attributes:
        kind: ``"resonance"`` or ``"anti-resonance"``.
        channel: ``OUT.IN``.
        index: the line of the extremum (index into the file's frequencies).
        f_hz: its frequency [Hz].
        half_width_hz: the half-power half-width [Hz].
        prominence_db: of the smoothed magnitude [dB].
        lo, hi: the lines kept around it, ``lo ≤ index ≤ hi`` (inclusive).
    """

    kind: str
    channel: str
    index: int
    f_hz: float
    half_width_hz: float
    prominence_db: float
    lo: int
    hi: int


def _smoothed_db(freq_hz: np.ndarray, H: np.ndarray) -> np.ndarray:
    """``10 log10 |H|²`` ``(n,)`` averaged over ±:data:`SMOOTH_REL` of each frequency (at
    most ±:data:`SMOOTH_MAX` lines; a running sum, linear in the lines)."""
    db = 10.0 * np.log10(np.maximum(np.abs(H) ** 2, 1e-300))
    n = db.size
    k = np.arange(n)
    lf = np.log(freq_hz)
    lo = np.maximum(np.searchsorted(lf, lf + math.log1p(-SMOOTH_REL)), k - SMOOTH_MAX)
    hi = np.minimum(np.searchsorted(lf, lf + math.log1p(SMOOTH_REL), side="right"),
                    k + SMOOTH_MAX + 1)  # fmt: skip
    csum = np.concatenate([[0.0], np.cumsum(db - db.mean())])
    return np.asarray((csum[hi] - csum[lo]) / (hi - lo) + db.mean())


def _at(freq_hz: np.ndarray, pos: float) -> float:
    """Frequency at a fractional line position (linear between lines)."""
    return float(np.interp(pos, np.arange(freq_hz.size), freq_hz))


def channel_features(
    freq_hz: np.ndarray, H: np.ndarray, snr_db: np.ndarray, channel: str = ""
) -> list[Feature]:
    """The resonances and anti-resonances of one channel (module docstring, step 1).

    Args:
        freq_hz: ``(n,)`` Hz, increasing.
        H: complex ``(n,)``.
        snr_db: estimated SNR per line ``(n,)`` [dB] (NaN: unknown, counts as enough).
        channel: its name, for the result.

    Returns:
        The features, lowest frequency first.
    """
    from scipy.signal import find_peaks, peak_widths

    n = freq_hz.size
    if n < 5:
        return []
    x = _smoothed_db(freq_hz, H)
    snr = np.where(np.isnan(snr_db), np.inf, snr_db)
    out: list[Feature] = []
    for sign, kind, need in ((1.0, "resonance", PEAK_SNR_DB), (-1.0, "anti-resonance", DIP_SNR_DB)):
        y = sign * x
        peaks, props = find_peaks(y, prominence=PROMINENCE_DB)
        for p, prom, lb, rb in zip(
            peaks, props["prominences"], props["left_bases"], props["right_bases"], strict=True
        ):
            if snr[p] < need:
                continue
            data = (np.array([prom]), np.array([lb]), np.array([rb]))
            _, _, left, right = peak_widths(
                y, [p], rel_height=_HALF_POWER_DB / prom, prominence_data=data
            )
            f_l, f_r = _at(freq_hz, float(left[0])), _at(freq_hz, float(right[0]))
            f0 = float(freq_hz[p])
            half = min(max(0.5 * (f_r - f_l), MIN_HALF_REL * f0), MAX_HALF_REL * f0)
            lo = int(np.searchsorted(freq_hz, freq_hz[p] - WIDTHS * half, side="left"))
            hi = int(np.searchsorted(freq_hz, freq_hz[p] + WIDTHS * half, side="right")) - 1
            out.append(Feature(kind, channel, int(p), float(freq_hz[p]), half, float(prom),
                               min(lo, int(p)), max(hi, int(p))))  # fmt: skip
    out.sort(key=lambda f: f.index)
    return out
