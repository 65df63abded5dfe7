"""Realistic measurement error for synthetic FRFs, with a matching coherence."""

from __future__ import annotations

import math

import numpy as np

from ..exceptions import ConfigError
from ._common import frf_arrays
from .quantity import QUANTITIES, quantity_factor


def _complex_normal(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Circular complex Gaussian samples with E|e|^2 = 1."""
    z = rng.standard_normal((2, *shape))
    return (z[0] + 1j * z[1]) / math.sqrt(2.0)


def _response_level(mag: np.ndarray, freq: np.ndarray, octaves: float = 0.5) -> np.ndarray:
    """Per output and frequency: the level of that sensor's strongest channel, smoothed over
    ±``octaves`` (geometric mean), shape ``(n_out, 1, n_freq)``.

    Excitation is shaped in a real test so each sensor's response stays in range; the sensor
    noise then follows the response envelope, which fills in the anti-resonance dips.
    """
    level = np.log(np.maximum(mag.max(axis=1), 1e-300))  # (n_out, n_freq)
    logf = np.log2(freq)
    out = np.empty_like(level)
    lo = np.searchsorted(logf, logf - octaves)
    hi = np.searchsorted(logf, logf + octaves, side="right")
    csum = np.concatenate([np.zeros((level.shape[0], 1)), np.cumsum(level, axis=1)], axis=1)
    out = (csum[:, hi] - csum[:, lo]) / (hi - lo)
    return np.exp(out)[:, None, :]


FLOOR_REFS: tuple[str, ...] = ("channel", "output", "response", "median")


def _floor_level(mag: np.ndarray, freq: np.ndarray, floor_ref: str) -> np.ndarray:
    """The reference level of the floor, broadcastable to ``mag`` ``(n_out, n_in, n_freq)``."""
    if floor_ref == "response":
        return _response_level(mag, freq)
    if floor_ref == "median":
        return np.median(mag, axis=2, keepdims=True)
    peak = mag.max(axis=2, keepdims=True)
    if floor_ref == "output":
        peak = np.broadcast_to(peak.max(axis=1, keepdims=True), peak.shape)
    return peak


def add_measurement_noise(
    H: np.ndarray,
    freq_hz: np.ndarray,
    *,
    rel: float = 0.02,
    floor_db: float | None = -60.0,
    rng: np.random.Generator | int | None,
    floor_ref: str = "channel",
    quantity: str = "receptance",
    floor_quantity: str | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Add measurement error to exact FRFs and estimate the coherence it implies.

    The error model is ``H_noisy = H (1 + rel·e1) + sigma·e2`` with ``e1``, ``e2``
    independent circular complex Gaussians of unit variance, and ``sigma`` an additive
    noise floor ``floor_db`` dB below the peak ``|H|`` of each channel (``floor_ref=
    "channel"``) or of each output row (``floor_ref="output"``: one sensor noise for all
    inputs, so weak cross-terms drown). Anti-resonances and weak channels are thus noisy.
    The coherence is the signal-to-noise estimate ``gamma^2 = S / (S + N)`` with
    ``S = |H|^2`` and ``N = rel^2 |H|^2 + sigma^2`` (0 where a channel is exactly zero).

    Args:
        H: exact FRF, complex, shape ``(n_out, n_in, n_freq)`` (any quantity, SI units).
            NaN channels (absent) stay NaN.
        freq_hz: frequencies, shape ``(n_freq,)``, Hz.
        rel: relative error (standard deviation of ``|e1|`` times ``rel``), >= 0.
        floor_db: noise floor in dB relative to the peak; None or -inf for no floor.
        rng: a numpy Generator or a seed (same seed, same noise).
        floor_ref: what the floor refers to: ``"channel"`` (default, its peak), ``"output"``
            (the peak of the sensor's row) or ``"response"`` (the sensor's strongest channel
            at each frequency, smoothed over ±½ octave: noise that follows the response
            envelope, so weak cross-terms and anti-resonance dips are noisy) or ``"median"``
            (the channel's median ``|H|``: a flat floor ``floor_db`` below it, e.g. -40 for
            a harsh floor).
        quantity: the quantity of ``H`` (receptance, mobility or accelerance).
        floor_quantity: the quantity in which the floor is flat (and its reference is
            taken): None = ``quantity``; ``"accelerance"`` on receptance data gives a floor
            ∝ 1/ω² (an accelerometer's flat noise).

    Returns:
        ``(H_noisy, coherence)``: complex ``(n_out, n_in, n_freq)`` and real in 0..1 of
        the same shape (NaN where ``H`` is NaN). With ``rel = 0`` and no floor, ``H_noisy``
        equals ``H`` and the coherence is 1.
    """
    H, freq = frf_arrays(H, freq_hz, "add_measurement_noise")
    fq = _check_options(rel, floor_db, floor_ref, quantity, floor_quantity)
    gen = np.random.default_rng(rng)
    absent = np.isnan(H)
    if rel == 0 and (floor_db is None or floor_db == -math.inf):
        return H.copy(), np.where(absent, np.nan, 1.0)
    mag = np.where(absent, 0.0, np.abs(H))
    sigma = _floor_sigma(mag, freq, floor_db, floor_ref, (quantity, fq))
    e1 = _complex_normal(gen, H.shape)
    e2 = _complex_normal(gen, H.shape)
    H_noisy = H * (1.0 + rel * e1) + sigma * e2
    H_noisy[absent] = np.nan + 1j * np.nan
    coherence = _snr_coherence(mag**2, rel, sigma)
    coherence[absent] = np.nan
    return H_noisy, coherence


def _floor_sigma(
    mag: np.ndarray,
    freq: np.ndarray,
    floor_db: float | None,
    floor_ref: str,
    quantities: tuple[str, str],
) -> np.ndarray:
    """The floor's standard deviation, broadcastable to ``mag`` ``(n_out, n_in, n_freq)``:
    ``floor_db`` below the reference level taken in the floor's quantity (zero: no floor).

    ``quantities`` is ``(quantity of mag, quantity in which the floor is flat)``.
    """
    if floor_db is None or floor_db == -math.inf:
        return np.zeros((*mag.shape[:2], 1))
    quantity, fq = quantities
    gain = np.abs(quantity_factor(freq, fq) / quantity_factor(freq, quantity))
    return _floor_level(mag * gain, freq, floor_ref) * 10.0 ** (floor_db / 20.0) / gain


def _check_options(
    rel: float, floor_db: float | None, floor_ref: str, quantity: str, floor_quantity: str | None
) -> str:
    """Raise :class:`ConfigError` on an invalid option; return the floor's quantity."""
    if not (math.isfinite(rel) and rel >= 0):
        raise ConfigError(f"noise: relative error {rel!r} is invalid; give a finite value >= 0")
    if floor_db is not None and (math.isnan(floor_db) or floor_db == math.inf):
        raise ConfigError(f"noise: floor {floor_db!r} dB is invalid; give a finite value or None")
    if floor_ref not in FLOOR_REFS:
        raise ConfigError(
            f"noise: floor_ref {floor_ref!r} is invalid; valid: {', '.join(FLOOR_REFS)}"
        )
    fq = quantity if floor_quantity is None else floor_quantity
    for what, q in (("quantity", quantity), ("floor_quantity", fq)):
        if q not in QUANTITIES:
            raise ConfigError(f"noise: {what} {q!r} is invalid; valid: {', '.join(QUANTITIES)}")
    return fq


def _snr_coherence(S: np.ndarray, rel: float, sigma: np.ndarray) -> np.ndarray:
    """The coherence ``S / (S + N)`` of signal power ``S = |H|^2`` under the noise model,
    ``N = rel^2 S + sigma^2`` (0 where ``S + N`` is 0), in 0..1; shapes broadcast."""
    N = (rel**2) * S + sigma**2
    total = S + N
    with np.errstate(invalid="ignore", divide="ignore"):
        coherence = np.where(total > 0, S / np.where(total > 0, total, 1.0), 0.0)
    return np.clip(coherence, 0.0, 1.0)
