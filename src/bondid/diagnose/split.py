"""Data preparation for the diagnosis: receptance, band limits, decimation, held-out split.

Held-out scheme ("checkerboard"): the frequency range is cut into ``n_bands`` bands of equal
log width; data set ``k`` (0-based, one per operating point) trains on the bands whose index
has the parity of ``k`` and holds out the others. With two operating points every band is
trained on at one of them and held out at the other, so a mode's neighbourhood is seen by the
refit while the scoring uses frequencies — and measurement noise — the refit never saw. With a
single data set the bands alternate.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ..data.measurement import FrfData
from ..exceptions import DataError


def subset(ds: FrfData, mask: np.ndarray) -> FrfData:
    """The frequencies of ``ds`` where ``mask`` ``(n_freq,)`` is True."""
    m = np.asarray(mask, bool)
    return replace(
        ds,
        freq_hz=ds.freq_hz[m],
        H=ds.H[:, :, m],
        coherence=None if ds.coherence is None else ds.coherence[:, :, m],
        operating_point=dict(ds.operating_point),
    )


def limit_bands(ds: FrfData, bands: Sequence[tuple[float, float]] | None) -> FrfData:
    """Keep the frequencies inside any of ``bands`` (Hz); raises DataError when none is."""
    out = ds if ds.quantity == "receptance" else ds.to_quantity("receptance")
    if not bands:
        return out
    m = np.zeros(out.freq_hz.size, bool)
    for lo, hi in bands:
        m |= (out.freq_hz >= lo) & (out.freq_hz <= hi)
    if not np.any(m):
        raise DataError(
            f"{ds.source or '<data>'}: no frequency inside --band {list(bands)}; the data span"
            f" {ds.freq_hz[0]:g}–{ds.freq_hz[-1]:g} Hz"
        )
    return subset(out, m)


def decimate(ds: FrfData, n_points: int) -> FrfData:
    """At most ``n_points`` frequencies, the nearest to a log-spaced grid (all when fewer)."""
    f = ds.freq_hz
    if f.size <= n_points:
        return ds
    target = np.geomspace(f[0], f[-1], n_points)
    idx = np.unique(np.abs(np.log(f)[None, :] - np.log(target)[:, None]).argmin(axis=1))
    m = np.zeros(f.size, bool)
    m[idx] = True
    return subset(ds, m)


def band_edges(datasets: Sequence[FrfData], n_bands: int) -> np.ndarray:
    lo = min(float(d.freq_hz[0]) for d in datasets)
    hi = max(float(d.freq_hz[-1]) for d in datasets)
    return np.geomspace(lo, hi * (1 + 1e-12), n_bands + 1)


def holdout_split(
    datasets: Sequence[FrfData], n_bands: int = 16
) -> tuple[list[FrfData], list[FrfData]]:
    """(train, held-out) data sets by the checkerboard scheme of the module docstring."""
    edges = band_edges(datasets, n_bands)
    train, held = [], []
    for k, d in enumerate(datasets):
        band = np.clip(np.searchsorted(edges, d.freq_hz, side="right") - 1, 0, n_bands - 1)
        is_train = (band % 2) == (k % 2)
        if not np.any(is_train) or np.all(is_train):
            raise DataError(f"{d.source or '<data>'}: too few frequencies for a held-out split")
        train.append(subset(d, is_train))
        held.append(subset(d, ~is_train))
    return train, held


#: points below this coherence are noise, not a measurement of the FRF: the gap figures skip them
MIN_POINT_COHERENCE = 0.5


def mask_incoherent(ds: FrfData, threshold: float = MIN_POINT_COHERENCE) -> FrfData:
    """A copy with ``H`` set to NaN where the coherence is below ``threshold`` (for the gap
    figures only: such channels no longer count as present for a fit)."""
    if ds.coherence is None:
        return ds
    H = ds.H.copy()
    H[np.nan_to_num(ds.coherence, nan=1.0) < threshold] = np.nan
    return replace(ds, H=H, operating_point=dict(ds.operating_point))
