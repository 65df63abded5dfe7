"""Anti-resonances of drive-point FRFs and how far the model's are from the measured ones."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..data.measurement import FrfData
from ..exceptions import DataError


def antiresonances(
    freq_hz: np.ndarray,
    H_ii: np.ndarray,
    *,
    min_depth_db: float = 6.0,
    smooth: int = 5,
    trend_octaves: float = 2.0,
) -> list[float]:
    """Anti-resonance frequencies of a drive-point FRF.

    ``20·log10|H|`` is smoothed by a running median of ``smooth`` points (noise spikes), and a
    wide running median over ``trend_octaves`` (the mass/spring line) is subtracted. The
    local minima of what remains whose prominence (scipy ``find_peaks`` on its negative) is
    at least ``min_depth_db`` are the anti-resonances; each is refined by a parabola through
    the three smoothed points around it (in log-frequency).

    Args:
        freq_hz: ``(n_freq,)`` [Hz], increasing.
        H_ii: ``(n_freq,)`` complex drive-point FRF (NaN points are skipped).
        min_depth_db: smallest depth of a dip [dB].
        smooth: running-median length (odd; 1 = none).
        trend_octaves: width of the trend median [octaves].

    Returns:
        Frequencies [Hz], increasing.
    """
    from scipy.ndimage import median_filter
    from scipy.signal import find_peaks

    f = np.asarray(freq_hz, dtype=float)
    h = np.asarray(H_ii)
    if f.shape != h.shape:
        raise DataError(f"antiresonances: freq_hz {f.shape} and H_ii {h.shape} differ")
    ok = np.isfinite(h) & (np.abs(h) > 0)
    f, h = f[ok], h[ok]
    if f.size < 5:
        return []
    mag = 20 * np.log10(np.abs(h))
    sm = median_filter(mag, size=max(1, int(smooth)), mode="nearest")
    per_oct = (f.size - 1) / max(np.log2(f[-1] / f[0]), 1e-12)
    n_tr = max(3, round(trend_octaves * per_oct) | 1)
    trend = median_filter(sm, size=n_tr, mode="nearest")
    idx, _ = find_peaks(-(sm - trend), prominence=min_depth_db)
    lf = np.log(f)
    out = []
    for k in idx:
        if 0 < k < f.size - 1:
            y0, y1, y2 = sm[k - 1], sm[k], sm[k + 1]
            den = y0 - 2 * y1 + y2
            x0, dx = lf[k], 0.5 * (lf[k + 1] - lf[k - 1])
            shift = 0.5 * (y0 - y2) / den if den > 0 else 0.0
            out.append(float(np.exp(x0 + np.clip(shift, -1, 1) * dx)))
        else:
            out.append(float(f[k]))
    return out


def antiresonance_shifts(
    data: FrfData,
    model_H: np.ndarray,
    *,
    tol: float = 0.2,
    channels: Sequence[str] | None = None,
    min_depth_db: float = 6.0,
) -> list[dict[str, Any]]:
    """Measured vs model anti-resonances of every drive-point channel (``a.a``).

    Each measured anti-resonance is paired with the nearest unpaired model one within
    ``tol`` (relative); unpaired ones are listed with the other frequency None.

    Args:
        data: measured FRF.
        model_H: ``(n_out, n_in, n_freq)`` model FRF aligned with ``data``.
        tol: largest relative frequency difference of a pair.
        channels: drive-point channels to use (default every ``a.a`` present).
        min_depth_db: see :func:`antiresonances`.

    Returns:
        ``[{channel, f_measured_hz, f_model_hz, df_rel}]``, ``df_rel =
        (f_model − f_measured) / f_measured`` (None when unpaired).
    """
    Hs = np.asarray(model_H)
    if Hs.shape != data.H.shape:
        raise DataError(
            f"antiresonance_shifts: model FRF has shape {Hs.shape}, expected {data.H.shape}"
        )
    names = [c for c in data.channels if c.split(".")[0] == c.split(".")[-1]]
    if channels is not None:
        names = [c for c in names if c in channels]
    rows: list[dict[str, Any]] = []
    for c in names:
        out, _, inp = c.rpartition(".")
        a, b = data.outputs.index(out), data.inputs.index(inp)
        fm = antiresonances(data.freq_hz, data.H[a, b], min_depth_db=min_depth_db)
        fs = antiresonances(data.freq_hz, Hs[a, b], min_depth_db=min_depth_db)
        free = list(fs)
        for x in fm:
            best = min(free, key=lambda y: abs(y - x), default=None)
            if best is not None and abs(best - x) <= tol * x:
                free.remove(best)
                rows.append(
                    {"channel": c, "f_measured_hz": x, "f_model_hz": best,
                     "df_rel": (best - x) / x}
                )  # fmt: skip
            else:
                rows.append({"channel": c, "f_measured_hz": x, "f_model_hz": None, "df_rel": None})
        for y in free:
            rows.append({"channel": c, "f_measured_hz": None, "f_model_hz": y, "df_rel": None})
    rows.sort(key=lambda r: (r["channel"], r["f_measured_hz"] or r["f_model_hz"]))
    return rows
