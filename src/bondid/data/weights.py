"""Information weights of measured FRF points: how much of each point is signal.

The weight of a point is ``w = Ŝ / (Ŝ + N̂)`` — what the coherence ``γ²`` is for a
measurement with noise — from one of (``weighting``):

* ``"coherence"``: the file's coherence, ``w = γ²`` (1 where a channel has none);
* ``"estimated"``: the noise estimated from the FRF alone (:mod:`.noise_estimate`),
  ``w = 1 / (1 + N̂/Ŝ)``;
* ``"auto"`` (default): where the file gives a coherence, the larger of the two
  noise-to-signal ratios, ``N/S = max(N/S_coh, N/S_est)`` with ``N/S_coh = (1 − γ²)/γ²``,
  and ``w = 1 / (1 + N/S)``: a point counts as signal only as far as both say so; elsewhere
  the estimate alone. (The noise level's prediction takes their geometric mean, the best
  guess of the point's noise: :func:`noise_to_signal` with ``prediction``.) The weights do
  not take the geometric mean: with it, a scatter estimate that misread pure noise as
  signal (the low end of an analyser's linear grid, where the floor windows are sparse)
  outvoted a coherence of 0.002–0.2 from 20 averages: those points kept weights of
  0.7–0.85 with log errors of 30–130 dB, and one of them outweighs hundreds of good points;
* ``"none"``: ``w = 1``.

The estimate is computed once per :class:`FrfData` (on its full grid) and cached on it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..exceptions import ConfigError
from ..jsonsafe import json_safe
from .measurement import FrfData
from .noise_estimate import INFORMATIVE_DB, NoiseEstimate, estimate_noise

WEIGHTINGS: tuple[str, ...] = ("auto", "coherence", "estimated", "none")
RULES = {
    "auto": "w = 1/(1 + N/S), N/S = max(N/S_coherence, N/S_estimated) where the file gives a "
    "coherence (N/S_coherence = (1 - coh)/coh), N/S_estimated elsewhere",
    "coherence": "w = coherence (1 where a channel has none)",
    "estimated": "w = 1/(1 + N/S_estimated), noise estimated from the FRF alone",
    "none": "w = 1",
}
_CACHE = "_bondid_noise_estimate"
_INFORMATIVE_W = 1.0 / (1.0 + 10.0 ** (-INFORMATIVE_DB / 10.0))


def check_weighting(weighting: str, where: str = "weighting") -> str:
    """``weighting`` if valid, else :class:`ConfigError`."""
    if weighting not in WEIGHTINGS:
        raise ConfigError(f"{where}: {weighting!r} is invalid; valid: {', '.join(WEIGHTINGS)}")
    return weighting


def noise_estimate(ds: FrfData) -> NoiseEstimate:
    """The noise estimate of ``ds`` (computed once, cached on the object while ``H`` is the
    same array)."""
    cached = ds.__dict__.get(_CACHE)
    if cached is not None and cached[0] is ds.H:
        return cached[1]
    names = [[f"{o}.{i}" for i in ds.inputs] for o in ds.outputs]
    est = estimate_noise(ds.freq_hz, ds.H, names, where=ds.source or "<data>")
    ds.__dict__[_CACHE] = (ds.H, est)
    return est


def attach_noise_estimate(ds: FrfData, est: NoiseEstimate) -> FrfData:
    """Cache ``est`` on ``ds`` as its noise estimate (``est`` on the same frequencies and
    channels as ``ds``, e.g. the estimate of the full grid at the lines a reduced data set
    kept); returns ``ds``."""
    if est.sigma.shape != ds.H.shape:
        raise ConfigError(
            f"{ds.source or '<data>'}: a noise estimate of shape {est.sigma.shape} does not fit"
            f" data of shape {ds.H.shape}"
        )
    ds.__dict__[_CACHE] = (ds.H, est)
    return ds


def _coherence_ns(coh: np.ndarray) -> np.ndarray:
    c = np.clip(coh, 0.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(c > 0, (1.0 - c) / np.where(c > 0, c, 1.0), np.inf)


def information_weights(ds: FrfData, weighting: str = "auto") -> np.ndarray:
    """Per-point information weights in 0..1.

    Args:
        ds: measured FRFs.
        weighting: one of :data:`WEIGHTINGS` (see the module docstring).

    Returns:
        ``(n_out, n_in, n_freq)`` weights (1 where nothing is known; NaN where ``H`` is NaN).
    """
    check_weighting(weighting)
    shape = ds.H.shape
    coh = ds.coherence if ds.coherence is not None else np.full(shape, np.nan)
    if weighting == "none":
        w = np.ones(shape)
    elif weighting == "coherence":
        w = np.where(np.isfinite(coh), np.clip(coh, 0.0, 1.0), 1.0)
    else:
        ns = noise_estimate(ds).noise_to_signal()
        if weighting == "auto":
            ns = _combine_auto(ns, coh)
        with np.errstate(over="ignore"):
            w = np.where(np.isnan(ns), 1.0, 1.0 / (1.0 + ns))
    w = np.asarray(w, dtype=float)
    w[~np.isfinite(ds.H)] = np.nan
    return w


#: a channel whose median information weight is below this (median SNR below 0 dB: under the
#: noise floor) is left out of a cost unless the user names it (:func:`informative_channels`)
MIN_CHANNEL_WEIGHT = 0.5


def channel_median_weights(
    datasets: Sequence[FrfData], weighting: str = "auto"
) -> dict[str, float]:
    """The median information weight of each present channel ``OUT.IN`` over the finite points
    of every data set that has it (first-seen order; NaN for a channel without a finite
    point)."""
    pools: dict[str, list[np.ndarray]] = {}
    for ds in datasets:
        w = information_weights(ds, weighting)
        present = ds.present
        for a, o in enumerate(ds.outputs):
            for b, i in enumerate(ds.inputs):
                if present[a, b]:
                    col = w[a, b]
                    pools.setdefault(f"{o}.{i}", []).append(col[np.isfinite(col)])
    out = {}
    for c, parts in pools.items():
        vals = np.concatenate(parts)
        out[c] = float(np.median(vals)) if vals.size else float("nan")
    return out


def informative_channels(
    datasets: Sequence[FrfData], weighting: str = "auto", min_weight: float = MIN_CHANNEL_WEIGHT
) -> tuple[list[str], dict[str, float]]:
    """The channels a cost uses when the user names none: every present channel whose median
    information weight (:func:`channel_median_weights`) is at least ``min_weight``; and the
    others with their median weight (``{channel: weight}``). A channel that is mostly noise
    otherwise lets the few of its noise points the estimate takes for signal decide a fit
    (measured: a benchmark bonder whose θ output's floor swamps the x→θ and y→θ channels,
    7 % and 28 % of their points called informative; ``bondid.fit`` on all nine channels
    ended at 1.39× the predicted noise level after every fallback, 132 s; on the six others
    at 0.98×, 29 s). ``weighting`` ``"none"`` keeps every channel."""
    kept: list[str] = []
    out: dict[str, float] = {}
    for c, m in channel_median_weights(datasets, weighting).items():
        if m >= min_weight or not np.isfinite(m):
            kept.append(c)
        else:
            out[c] = m
    return kept, out


def informative_by_file(
    datasets: Sequence[FrfData], weighting: str = "auto", min_weight: float = MIN_CHANNEL_WEIGHT
) -> tuple[dict[str, tuple[str, ...]], dict[str, dict[str, float]], list[str]]:
    """:func:`informative_channels` applied to each data file alone: ``({file: channels
    kept}, {file: {channel left out: median weight}}, notes)``. A file (by its ``source``;
    ``data<i>`` when it has none) none of whose channels is informative keeps every one, and
    a note says so."""
    kept: dict[str, tuple[str, ...]] = {}
    left: dict[str, dict[str, float]] = {}
    notes = []
    for i, ds in enumerate(datasets):
        key = ds.source or f"data{i}"
        keep, out = informative_channels([ds], weighting, min_weight)
        if out and not keep:
            notes.append(
                f"{key}: every channel's median information weight is below {min_weight}"
                " (median SNR below 0 dB): all are fitted; check the data or name channels"
                " with --channels"
            )
            keep, out = list(out), {}
        kept[key] = tuple(keep)
        if out:
            left[key] = out
    return kept, left, notes


def left_out_note(left_out: dict[str, dict[str, float]]) -> str:
    """One line on the channels :func:`informative_by_file` left out, per file ("" when
    none)."""
    if not left_out:
        return ""
    per_channel: dict[str, list[str]] = {}
    for f, chans in left_out.items():
        for c, m in chans.items():
            per_channel.setdefault(c, []).append(f"{m:.2f} in {Path(f).name}")
    each = ", ".join(f"{c} ({'; '.join(v)})" for c, v in per_channel.items())
    return (
        f"channels left out where their median information weight is below {MIN_CHANNEL_WEIGHT}"
        f" (median SNR below 0 dB): {each}; name channels with --channels to use them"
    )


def _combine_auto(ns: np.ndarray, coh: np.ndarray, prediction: bool = False) -> np.ndarray:
    """The ``"auto"`` rule's ``N/S`` where the coherence is finite (module docstring): the
    larger of the estimate's ``ns`` and the coherence's (the weights: a point counts as signal
    only as far as both say so), or their geometric mean (``prediction``: the best guess of
    the point's noise, for predicting the noise level); the coherence's alone where the
    estimate is NaN, the estimate's where there is no coherence (all ``(n_out, n_in,
    n_freq)``)."""
    nc = _coherence_ns(coh)
    with np.errstate(invalid="ignore", over="ignore"):
        both = np.sqrt(nc * ns) if prediction else np.fmax(nc, ns)
    out = np.where(np.isfinite(coh), both, ns)
    return np.where(np.isnan(out) & np.isfinite(coh), nc, out)


def noise_to_signal(ds: FrfData, weighting: str = "auto", prediction: bool = False) -> np.ndarray:
    """Per-point noise-to-signal ratio ``N/S`` behind the weights of ``weighting`` (``w = 1/(1 +
    N/S)``), ``(n_out, n_in, n_freq)``; NaN where nothing is known of the point's noise (its
    weight is then 1): no estimate (a channel with a NaN anywhere or shorter than
    :data:`~bondid.data.noise_estimate.MIN_POINTS`) and no coherence, a channel without
    coherence under ``"coherence"``, everywhere under ``"none"``; NaN where ``H`` is NaN.
    A prediction of the noise level must leave those points out (0 would say they are exact
    and pull the level down).

    ``prediction``: the estimate's part taken with the signal power meant for predicting the
    error at the points that carry weight
    (:meth:`~bondid.data.noise_estimate.NoiseEstimate.noise_to_signal`); the weights
    themselves keep the cautious one. The coherence's part is used as it is."""
    check_weighting(weighting)
    shape = ds.H.shape
    coh = ds.coherence if ds.coherence is not None else np.full(shape, np.nan)
    if weighting == "none":
        ns = np.full(shape, np.nan)
    elif weighting == "coherence":
        c = np.clip(coh, 0.0, 1.0)
        with np.errstate(divide="ignore"):
            ns = np.where(np.isfinite(c), np.where(c > 0, 1.0 / c - 1.0, np.inf), np.nan)
    else:
        ns = noise_estimate(ds).noise_to_signal(prediction=prediction)
        if weighting == "auto":
            ns = _combine_auto(ns, coh, prediction)
    return np.where(np.isfinite(ds.H), ns, np.nan)


def with_weights_as_coherence(ds: FrfData, weighting: str = "auto") -> FrfData:
    """A copy of ``ds`` whose ``coherence`` holds the information weights (the coherence
    analogue), so code that weighs by coherence weighs by information. The noise estimate
    stays cached on the copy."""
    w = information_weights(ds, weighting)
    out = FrfData(
        ds.freq_hz.copy(), ds.outputs, ds.inputs, ds.H, ds.quantity,
        dict(ds.operating_point), w, ds.source,
    )  # fmt: skip
    if weighting in ("auto", "estimated"):
        out.__dict__[_CACHE] = (out.H, noise_estimate(ds))
    return out


def weighting_summary(datasets: list[FrfData], weighting: str) -> dict[str, Any]:
    """What the results files say about the weights: ``{"weighting", "rule",
    "informative_snr_db", "datasets": [{"file", "has_coherence", "channels": [{"channel",
    "rho", "floor_median", "floor_db_below_median", "informative_share",
    "informative_share_weights"}]}]}``. ``floor_*`` and ``rho`` come from the estimate (units
    of ``H`` as in the file); ``informative_share`` is the share of frequencies with estimated
    SNR ≥ 10 dB, ``informative_share_weights`` the share whose weight is ≥ 10/11 (the same
    threshold on the weights actually used)."""
    out: list[dict[str, Any]] = []
    for ds in datasets:
        est = noise_estimate(ds)
        w = information_weights(ds, weighting)
        rows = []
        for c in est.channels:
            o, _, i = c.channel.rpartition(".")
            wc = w[ds.outputs.index(o), ds.inputs.index(i)]
            row = c.as_dict()
            row["informative_share_weights"] = float(np.mean(wc >= _INFORMATIVE_W))
            rows.append(json_safe(row))
        out.append({"file": ds.source, "has_coherence": ds.coherence is not None, "channels": rows})
    return {
        "weighting": weighting,
        "rule": RULES[weighting],
        "informative_snr_db": INFORMATIVE_DB,
        "datasets": out,
    }
