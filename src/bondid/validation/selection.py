"""The channels and bands a command is told to use, against the data: :func:`check_selection`.

Before any work: a channel named twice (``--channels x.x,x.x``), a channel the data do not
hold, and a band holding no frequency line of any data file are refused
(:class:`ConfigError`, exit 2) naming the option, the item and what would be valid. Without
this, a band beside the data ends deep in the cost with "no data to fit" and no option
named.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..data.measurement import FrfData
from ..exceptions import ConfigError


def check_channels(
    channels: Sequence[str] | None, datasets: Sequence[FrfData], option: str = "--channels"
) -> None:
    """Each named channel once, and present in at least one data set."""
    if not channels:
        return
    seen: set[str] = set()
    for ch in channels:
        if ch in seen:
            raise ConfigError(
                f"{option} {','.join(channels)}: {ch} is given twice; valid: each channel once"
            )
        seen.add(ch)
    if not datasets:
        return
    have = sorted({f"{o}.{i}" for ds in datasets for o in ds.outputs for i in ds.inputs})
    for ch in channels:
        if ch not in have:
            raise ConfigError(
                f"{option}: channel {ch!r} is not in the data; valid: {', '.join(have)}"
            )


def check_bands(
    bands: Sequence[tuple[float, float]] | None,
    datasets: Sequence[FrfData],
    option: str = "--band",
) -> None:
    """Each band holds at least one frequency line of some data set."""
    if not bands or not datasets:
        return
    lo = min(float(np.min(ds.freq_hz)) for ds in datasets)
    hi = max(float(np.max(ds.freq_hz)) for ds in datasets)
    for f_lo, f_hi in bands:
        if not any(np.any((ds.freq_hz >= f_lo) & (ds.freq_hz <= f_hi)) for ds in datasets):
            raise ConfigError(
                f"{option} {f_lo:g}:{f_hi:g}: holds no frequency line of the data"
                f" ({lo:.6g}–{hi:.6g} Hz); valid: a band overlapping the measured lines"
            )


def check_selection(
    datasets: Sequence[FrfData],
    *,
    bands: Sequence[tuple[float, float]] | None = None,
    channels: Sequence[str] | None = None,
    band_option: str = "--band",
    channel_option: str = "--channels",
) -> None:
    """:func:`check_channels` and :func:`check_bands`.

    Raises:
        ConfigError: naming the option, the item and what would be valid.
    """
    check_channels(channels, datasets, channel_option)
    check_bands(bands, datasets, band_option)
