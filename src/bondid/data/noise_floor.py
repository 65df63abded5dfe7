"""The absolute noise floor φ² of one channel, window by window (step 2 of
:mod:`bondid.data.noise_estimate`): the windows, the median condition each solves, the sparse
grid's power-law envelope and the continuation at the grid's ends."""

from __future__ import annotations

import math

import numpy as np

#: half-width of the floor windows [octaves]
OCTAVES = 0.25
#: at least this many points each side in a window
MIN_HALF = 8
#: slopes of φ² in log-log a sensor floor can have (flat in displacement, velocity or
#: acceleration, seen as receptance, mobility or accelerance)
FLOOR_SLOPES = (-4.0, -2.0, 0.0, 2.0, 4.0)
_LN2 = math.log(2.0)


def _windows(freq_hz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Window bounds ``lo, hi`` (``hi`` exclusive) per point: ±OCTAVES, ≥ MIN_HALF a side."""
    lf = np.log2(freq_hz)
    n = lf.size
    k = np.arange(n)
    lo = np.minimum(np.searchsorted(lf, lf - OCTAVES), np.maximum(k - MIN_HALF, 0))
    hi = np.maximum(
        np.searchsorted(lf, lf + OCTAVES, side="right"), np.minimum(k + MIN_HALF + 1, n)
    )
    return lo, hi


def window_quantile(
    x: np.ndarray, lo: np.ndarray, hi: np.ndarray, q: float, interpolation: str
) -> np.ndarray:
    """The ``q`` quantile of ``x[lo[k]:hi[k]]`` for every ``k``, ``(n,)``.

    ``lo`` and ``hi`` (``hi`` exclusive, every window non-empty) must not decrease with
    ``k``, as the floor windows do. ``interpolation`` as in NumPy's ``quantile``
    (``"lower"``: element ``⌊q (m − 1)⌋`` of the sorted window of ``m`` points;
    ``"midpoint"``: the mean of elements ``⌊q (m − 1)⌋`` and ``⌈q (m − 1)⌉``). A sliding
    skip list (pandas' rolling quantile): ``O(n log w)`` time and ``O(n)`` memory for windows
    of ``w`` points, where an ``(n, w)`` matrix of the windows grows as ``n²`` on a dense grid
    (100 000 log-spaced lines hold windows of 4 000 points).
    """
    import pandas as pd
    from pandas.api.indexers import BaseIndexer

    bounds = (np.asarray(lo, np.int64), np.asarray(hi, np.int64))

    class _Windows(BaseIndexer):
        def get_window_bounds(
            self,
            num_values: int = 0,
            min_periods: int | None = None,
            center: bool | None = None,
            closed: str | None = None,
            step: int | None = None,
        ) -> tuple[np.ndarray, np.ndarray]:
            return bounds

    rolled = pd.Series(np.asarray(x, dtype=float)).rolling(_Windows(), min_periods=1)
    return np.asarray(rolled.quantile(q, interpolation=interpolation).to_numpy(), dtype=float)


def _solve_floor(
    p: np.ndarray, base: np.ndarray, v: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """Per window, ``φ² ≥ 0`` with ``median p/(base + φ² v) = ln 2``.

    A point's ratio lies above ``ln 2`` exactly while ``φ² < t = (p/ln 2 − base)/v``
    (``v > 0``), so the ``φ²`` at which half of the window's points lie above is an order
    statistic of ``t``: the ``⌈m/2⌉``-th smallest of the window's ``m`` values (the lower
    median), or 0 where that is not positive (the base alone explains the scatter). Kept
    within ``e⁻⁸⁰`` … ``e²`` of ``max p / ln 2`` (the range a search in ``log φ²`` covers).
    """
    t = (p / _LN2 - base) / v
    phi2 = window_quantile(t, lo, hi, 0.5, "lower")
    top = float(np.max(p)) / _LN2 + 1e-300
    return np.where(phi2 > 0, np.clip(phi2, top * math.exp(-80.0), top * math.exp(2.0)), 0.0)


def _widened(freq_hz: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """True where a window had to reach beyond ±OCTAVES to hold MIN_HALF points a side (a
    sparse grid: the lines may not resolve the resonances there)."""
    lf = np.log2(freq_hz)
    lo_o = np.searchsorted(lf, lf - OCTAVES)
    hi_o = np.searchsorted(lf, lf + OCTAVES, side="right")
    return (lo < lo_o) | (hi > hi_o)


def _power_law_envelope(freq_hz: np.ndarray, phi2: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """A power law ``φ² = a f^b`` along the lower half of the window floors.

    ``b`` is one of :data:`FLOOR_SLOPES` — a sensor floor flat in displacement, velocity or
    acceleration seen in any of the three quantities — the one whose lower half of
    ``ln φ² − b ln f`` scatters least; ``ln a`` is that lower half's median. Windows without a
    floor (φ² = 0) enter with ``bound`` (what the relative part leaves room for).
    """
    x = np.log(freq_hz)
    y = np.log(np.maximum(np.where(phi2 > 0, phi2, bound), 1e-300))
    n_low = max(3, y.size // 2)
    best: tuple[float, float, float] | None = None
    for b in FLOOR_SLOPES:
        lower = np.sort(y - b * x)[:n_low]
        spread = float(np.std(lower))
        if best is None or spread < best[0]:
            best = (spread, b, float(np.median(lower)))
    assert best is not None
    return np.asarray(np.exp(best[2] + best[1] * x))


def _continued_at_ends(
    freq_hz: np.ndarray, phi2: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """``φ²`` with the points whose window the grid's end cuts continued as the power law
    through the nearest uncut windows (one window width of them).

    A cut window is one-sided, and the median of a sloping floor then sits off the point: a
    floor falling as ``f⁻⁴`` came out 1.5 dB low over the first points and 1 dB high over
    the last, and pure-noise end points passed for signal several times as often as inner
    ones. Left as it is where the uncut windows next to an end hold a zero floor (the
    relative part alone there) or are too few to draw a line through."""
    n = phi2.size
    k = np.arange(n)
    cut_lo = (lo == 0) & (k - lo < hi - 1 - k - 1)
    cut_hi = (hi == n) & (hi - 1 - k < k - lo - 1)
    x = np.log(freq_hz)
    out = phi2.copy()
    for cut, step in ((cut_lo, 1), (cut_hi, -1)):
        if not cut.any() or cut.all():
            continue
        at = np.flatnonzero(cut)
        edge = int(at.max()) + 1 if step > 0 else int(at.min()) - 1
        ref = k[(~cut_lo) & (~cut_hi) & (np.abs(x - x[edge]) <= 2.0 * OCTAVES * math.log(2.0))]
        ref = ref[(ref - edge) * step >= 0]
        if ref.size < 3 or np.any(phi2[ref] <= 0):
            continue
        b, a = np.polyfit(x[ref], np.log(phi2[ref]), 1)
        out[cut] = np.exp(a + b * x[cut])
    return out
