"""Fewer frequency lines for fitting dense data, said in the output.

An analyser writes 10⁴–10⁵ lines per channel; a fit's cost and exact Jacobian grow with every
line, while most lines of a dense grid repeat what their neighbours say. The reduction keeps,
per file:

1. **every line near each resonance and anti-resonance found in the data** (the peaks and
   dips of :mod:`bondid.data.features`): around each, the lines within
   :data:`~bondid.data.features.WIDTHS` half-power half-widths (the width where the
   smoothed magnitude is 3 dB from the extremum, kept within a range of the frequency; on a
   lightly damped mode ``f₀ (1 ± WIDTHS·ζ)``). When these bands hold more than
   :data:`~.lines.FEATURE_SHARE` of the budget, the lines within one half-width come first, then
   the rest of the bands, each tier thinned where it must be, widest runs first (narrow
   bands stay whole; each extremum line is kept);
2. **a log-spaced subset elsewhere**: the lines nearest to a log-spaced grid filling the rest
   of the budget, the first and last line included.

Lines are dropped, never averaged: a kept line is the measured value with its own weight,
and the weights (the information weights of :mod:`bondid.data.weights`) come from the noise
estimated on the full grid, attached to the reduced data set (on the thinned grid the
estimate would see signal change between lines as scatter).

The figures a command reports (``db_rms``, the noise level, modes) are computed on all lines;
only the fit's cost and its Jacobian use the reduced set. The ``--lines`` setting and the
record of what was kept are :mod:`.lines`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from .features import Feature, channel_features
from .lines import AUTO_ABOVE as AUTO_ABOVE
from .lines import AUTO_LINES as AUTO_LINES
from .lines import FEATURE_SHARE, FileReduction, LineReduction, LinesSetting, parse_lines
from .lines import MIN_LINES as MIN_LINES
from .measurement import FrfData
from .weights import attach_noise_estimate, noise_estimate


def _log_spaced(freq_hz: np.ndarray, count: int) -> np.ndarray:
    """The lines nearest to ``count`` log-spaced frequencies over the file's range (unique,
    sorted; linear in the lines)."""
    if count <= 0:
        return np.zeros(0, int)
    lf = np.log(freq_hz)
    target = np.linspace(lf[0], lf[-1], count)
    right = np.clip(np.searchsorted(lf, target), 1, lf.size - 1)
    left = right - 1
    nearest = np.where(target - lf[left] <= lf[right] - target, left, right)
    return np.asarray(np.unique(nearest))


def _mask(spans: Sequence[tuple[int, int]], n: int) -> np.ndarray:
    """Boolean ``(n,)``: the lines inside any inclusive span ``(lo, hi)``."""
    edge = np.zeros(n + 1, int)
    for lo, hi in spans:
        edge[lo] += 1
        edge[hi + 1] -= 1
    return np.asarray(np.cumsum(edge)[:n] > 0)


def _thinned(inside: np.ndarray, room: int) -> np.ndarray:
    """At most ``room`` lines of the mask ``inside`` ``(n,)``: every run of consecutive lines
    keeps at most ``c`` of them, evenly spread, ``c`` the largest that fits (water-filling:
    the narrow runs stay whole, the widest are thinned)."""
    lines = np.flatnonzero(inside)
    if lines.size <= room:
        return lines
    if room <= 0:
        return np.zeros(0, int)
    step = np.diff(np.concatenate([[0], inside.astype(int), [0]]))
    starts, stops = np.flatnonzero(step == 1), np.flatnonzero(step == -1)
    sizes = stops - starts
    if room < sizes.size:  # fewer lines than runs: evenly over all of them
        return lines[np.unique(np.round(np.linspace(0, lines.size - 1, room)).astype(int))]
    srt = np.sort(sizes)
    below = np.concatenate([[0], np.cumsum(srt)])
    c = 1
    for k in range(srt.size):
        c_k = (room - below[k]) // (srt.size - k)
        if c_k < srt[k]:
            c = max(int(c_k), 1)
            break
    parts = [np.zeros(0, int)]
    for a, m in zip(starts, sizes, strict=True):
        take = np.arange(m) if m <= c else np.unique(np.round(np.linspace(0, m - 1, c)))
        parts.append(a + take.astype(int))
    return np.concatenate(parts)


def _feature_lines(features: Sequence[Feature], freq_hz: np.ndarray, cap: int) -> np.ndarray:
    """Sorted lines within the features' bands, at most ``cap`` (and each extremum with its
    neighbours). Beyond the cap the lines within one half-width of a feature (its core) come
    first, then those out to :data:`WIDTHS` half-widths; each tier thinned, when it must be,
    widest runs first (:func:`_thinned`)."""
    n = freq_hz.size
    band = _mask([(f.lo, f.hi) for f in features], n)
    if int(band.sum()) <= cap:
        return np.flatnonzero(band)
    centres = np.unique(np.clip(
        np.array([f.index + d for f in features for d in (-1, 0, 1)], int), 0, n - 1
    ))  # fmt: skip
    core_spans = [
        (int(np.searchsorted(freq_hz, f.f_hz - f.half_width_hz)),
         int(np.searchsorted(freq_hz, f.f_hz + f.half_width_hz, side="right")) - 1)
        for f in features
    ]  # fmt: skip
    core = _mask([(lo, max(lo, hi)) for lo, hi in core_spans], n) & band
    core[centres] = False
    kept = np.union1d(centres, _thinned(core, cap - centres.size))
    shoulder = band & ~core
    shoulder[centres] = False
    return np.asarray(np.union1d(kept, _thinned(shoulder, cap - kept.size)))


def band_mask(freq_hz: np.ndarray, bands: Sequence[tuple[float, float]] | None) -> np.ndarray:
    """Boolean ``(n,)``: the lines inside any of ``bands`` (Hz, inclusive; None: all)."""
    if not bands:
        return np.ones(freq_hz.size, bool)
    m = np.zeros(freq_hz.size, bool)
    for lo, hi in bands:
        m |= (freq_hz >= lo) & (freq_hz <= hi)
    return m


def select_lines(
    ds: FrfData,
    budget: int,
    channels: Sequence[str] | None = None,
    bands: Sequence[tuple[float, float]] | None = None,
) -> FileReduction:
    """At most ``budget`` lines of ``ds`` (module docstring) inside ``bands``; every line
    there when they are no more.

    Args:
        ds: the data set (frequencies ``(n_freq,)`` Hz).
        budget: the most lines to keep (``≥`` :data:`MIN_LINES`).
        channels: the channels ``OUT.IN`` whose features count (default: every present one).
        bands: the bands a cost uses (Hz; None = all): the budget goes to the lines in them
            (lines outside would be dropped by the cost anyway).

    Returns:
        :class:`FileReduction` with the kept lines.
    """
    n = ds.freq_hz.size
    within = band_mask(ds.freq_hz, bands)
    pool = np.flatnonzero(within)
    if pool.size <= budget:
        return FileReduction(ds.source, n, pool, reduced=pool.size < n)
    est = noise_estimate(ds)
    pres = ds.present
    wanted = None if channels is None else set(channels)
    features: list[Feature] = []
    for a, o in enumerate(ds.outputs):
        for b, i in enumerate(ds.inputs):
            name = f"{o}.{i}"
            if pres[a, b] and (wanted is None or name in wanted):
                found = channel_features(ds.freq_hz, ds.H[a, b], est.snr_db[a, b], name)
                features += [f for f in found if within[f.index]]
    near = _feature_lines(features, ds.freq_hz, int(FEATURE_SHARE * budget))
    near = near[within[near]]

    def grid(count: int) -> np.ndarray:
        return np.asarray(np.union1d(near, pool[_log_spaced(ds.freq_hz[pool], count)]))

    # the log grid's lines may fall on the features' lines: refine it while the budget allows
    count = budget - near.size
    kept = grid(count)
    for _ in range(8):
        short = budget - kept.size
        if short <= 0:
            break
        count += short
        trial = grid(count)
        if trial.size > budget:
            break
        kept = trial
    kept = np.union1d(kept, [pool[0], pool[-1]])
    features.sort(key=lambda f: (f.f_hz, f.kind))
    return FileReduction(ds.source, n, kept, tuple(features), int(near.size), True)


def subset_lines(ds: FrfData, kept: np.ndarray) -> FrfData:
    """``ds`` at the lines ``kept`` ``(n_kept,)`` (sorted indices), carrying the noise
    estimated on all of its lines (so its information weights are those of the full grid)."""
    idx = np.asarray(kept, int)
    est = noise_estimate(ds)
    out = replace(
        ds,
        freq_hz=ds.freq_hz[idx],
        H=ds.H[:, :, idx],
        coherence=None if ds.coherence is None else ds.coherence[:, :, idx],
        operating_point=dict(ds.operating_point),
    )
    attach_noise_estimate(out, est.at(idx))
    return out


def reduce_datasets(
    datasets: Sequence[FrfData],
    setting: LinesSetting | str | None = None,
    channels: Sequence[str] | None = None,
    bands: Sequence[tuple[float, float]] | None = None,
) -> tuple[list[FrfData], LineReduction]:
    """The data sets a fit uses under ``--lines`` ``setting``, and what was kept.

    Args:
        datasets: the full data sets (any number of lines each).
        setting: :class:`LinesSetting` or its text (default ``auto``).
        channels: the channels whose resonances count (default: every present one).
        bands: the bands the cost uses (Hz; None = all): the budget counts and keeps the
            lines inside them.

    Returns:
        ``(reduced data sets, LineReduction)``; a data set that keeps every line is returned
        as it is.
    """
    st = setting if isinstance(setting, LinesSetting) else parse_lines(setting)
    out, files = [], []
    for ds in datasets:
        n = ds.freq_hz.size
        budget = st.budget(int(band_mask(ds.freq_hz, bands).sum()))
        if budget is None:
            out.append(ds)
            files.append(FileReduction(ds.source, n, np.arange(n)))
            continue
        red = select_lines(ds, budget, channels, bands)
        out.append(subset_lines(ds, red.kept) if red.reduced else ds)
        files.append(red)
    return out, LineReduction(st, tuple(files))


def reduce_to(ds: FrfData, n_points: int, channels: Sequence[str] | None = None) -> FrfData:
    """``ds`` with at most ``n_points`` lines (:func:`select_lines`; all when it has no
    more), carrying the noise estimated on all lines: a drop-in for a plain log-spaced
    decimation that keeps the lines near every resonance and anti-resonance. Linear in the
    lines."""
    if ds.freq_hz.size <= n_points:
        return ds
    return subset_lines(ds, select_lines(ds, n_points, channels).kept)


def decimate_log(ds: FrfData, n_points: int) -> FrfData:
    """At most ``n_points`` lines of ``ds``, the nearest to a log-spaced grid (all when it has
    no more), carrying the noise estimated on all lines. Linear in the lines (a nearest-line
    search by matrix of grid × lines grows as their product)."""
    if ds.freq_hz.size <= n_points:
        return ds
    return subset_lines(ds, _log_spaced(ds.freq_hz, n_points))
