"""Measurement noise estimated from a measured FRF alone (no coherence needed).

Method, per channel (a complex series ``H_k`` at frequencies ``f_k``):

1. **Leave-one-out prediction.** Each point is predicted from its four nearest neighbours
   (two each side inside the grid, one-sided at the ends) by the cubic Lagrange polynomial in
   ``ln f`` on the actual abscissae, so log, linear and non-uniform grids are all handled; on a
   uniform grid this is the 4th-difference predictor. The residual ``r_k = H_k − Σ c_j H_j``
   of independent noise of variance ``σ_k²`` has ``E|r_k|² = σ_k² + Σ c_j² σ_j²`` (the known
   variance factor), while a smooth FRF is cancelled up to its 4th derivative.
2. **Two-component model** ``σ_k² = ρ²|H_k|² + φ(f_k)²``: a relative part ``ρ`` (one per
   channel) and an absolute floor ``φ`` smooth in ``log f``. Both are fitted with medians,
   so the few points where the predictor fails (a sharp resonance between grid lines) do not
   count: ``ρ²`` is a low quantile (:data:`RHO_QUANTILE`) over sliding windows of the window
   medians of ``|r|² / A`` (``A`` = the relative part's variance factor), i.e. the level of
   the windows where the relative part dominates, at most :data:`RHO_MAX` (on the measured
   values a channel of pure noise looks like 100 % relative noise, ``|r|² ∝ |H|²``, as well as
   like a floor; relative noise that large is not a measurement, so the floor is the reading
   kept: otherwise each noise point's own level is its noise, and a noise point that happens
   to lie below its neighbours passes for signal); then in each window (±``OCTAVES``
   octave of :mod:`.noise_floor`, at least ``MIN_HALF`` points each side) ``φ²`` solves
   ``median |r_j|² / (ρ² A_j + φ² v_j) = ln 2`` (the median of an exponential variable is
   ``ln 2`` times its mean), ``φ² = 0`` where the relative part alone explains the scatter.
   A deep anti-resonance in purely relative noise therefore keeps a tiny noise level.
   The floor is capped at :data:`CAP_FACTOR` × the window's lower-quartile ``|H|²`` over the
   lower quartile of pure noise (a floor cannot lie far above what was measured); where the
   grid is sparse (a window had to reach beyond ±``OCTAVES`` octave), also at
   :data:`ENVELOPE_FACTOR` × a power law through the lower half of the window floors over the
   whole channel (slope that of a floor flat in displacement, velocity or acceleration):
   there the lines may not resolve the resonances, and unresolved signal looks like scatter.
   Where the grid's end cuts a window (one-sided), ``φ²`` is continued as the power law
   through the nearest uncut windows: a one-sided median of a sloping floor sits off the
   point (measured on pure noise falling as ``f⁻⁴`` in power: 1.5 dB low at the first
   points, 1 dB high at the last; within 0.25 dB with the continuation).
3. **Signal and SNR.** ``Ŝ = max(P̄ − κ N̂, 0)`` with ``P̄`` the 5-point mean of ``|H|²`` (the
   nearest 5 at the ends, no end value repeated), ``N̂ = σ̂²`` and ``κ =``
   :data:`SIGNAL_MARGIN`; ``SNR = Ŝ / N̂``. The margin ``κ = 4`` (instead of the unbiased 1)
   makes a point of pure noise count as signal only when its 5-point power exceeds 4 N̂:
   ~2e-5 with an exact ``N̂``, 0.1 % measured with the estimate's own scatter (pure noise,
   1000 lines; 0.7 % with ``κ = 3``). Noise-only points must weigh next to
   nothing, as they do with a measured coherence: where the FRF itself lies far below the
   noise (a weak cross-term) such a point's log error is tens of dB against any model, and
   one of them outweighs hundreds of good points. Measured on the 56 benchmark truths
   (``κ`` 3 → 4, with the ends above): the exact model's own weighted held-out score over
   the verdict's predicted noise level had a median 1.15 and 6 of 14 cases above 1.2 in
   files without coherence (3 above 1.5 on the training data) with ``κ = 3``, and a median
   0.96 and 3 of 14 (1 above 1.5 on the training data) with ``κ = 4``.

Noise here is the complex standard deviation of the measured FRF (``E|H_meas − H|² = σ²``),
in the units of ``H``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..exceptions import DataError
from ._common import frf_arrays
from .noise_floor import (
    _LN2,
    _continued_at_ends,
    _power_law_envelope,
    _solve_floor,
    _widened,
    _windows,
    window_quantile,
)

#: quantile over windows of the relative level that sets ρ²
RHO_QUANTILE = 0.1
#: the largest relative noise ρ read from the scatter (module docstring, step 2): a point with
#: relative noise alone would then still have an SNR of 1/ρ² = 14 dB
RHO_MAX = 0.2
#: the floor is capped at CAP_FACTOR × the window's CAP_QUANTILE of |H|² over that of |noise|²
CAP_QUANTILE = 0.25
CAP_FACTOR = 2.0
#: on a sparse grid the floor stays within this factor (power) of a power-law lower envelope
ENVELOPE_FACTOR = 4.0
#: Ŝ = max(P̄ − SIGNAL_MARGIN·N̂, 0), P̄ the mean |H|² over SIGNAL_POINTS neighbouring points ...
SIGNAL_MARGIN = 4.0
SIGNAL_POINTS = 5
#: ... where those points span at most ±SIGNAL_OCTAVES octave (else 3 points: on a sparse grid
#: 5 points smear a lightly damped resonance's peak into its neighbours)
SIGNAL_OCTAVES = 1.0 / 32.0
#: the signal power of a point that carries weight, for predicting its error: P̄ − κ_p N̂.
#: Not the unbiased κ_p = 1: the points kept are those whose P̄ came out above κ N̂, so P̄
#: is biased high among them (with κ = 3: κ_p = 1 gave a predicted noise level 5–15 % low
#: on parameter-error-only truths of the benchmark designs, κ_p = 3 10–30 % high, 2 0.9–1.09×
#: the truth's own score where the estimate finds the noise-only points; with κ = 4 and
#: κ_p = 2 the truth's held-out score over the level has medians 0.93–1.01 per regime)
PREDICTION_MARGIN = 2.0
#: fewer points than this: no estimate (NaN)
MIN_POINTS = 12
#: SNR [dB] from which a point counts as carrying information
INFORMATIVE_DB = 10.0


@dataclass
class ChannelNoise:
    """Summary of one channel's estimated noise.

    Attributes:
        channel: ``OUT.IN``.
        rho: relative noise level ρ (std of the relative error, dimensionless).
        floor_median: median over frequency of the absolute floor φ (units of ``H``).
        floor_db: that floor in dB relative to the channel's median ``|H|``.
        informative: share of the frequencies with estimated SNR ≥ :data:`INFORMATIVE_DB`.
    """

    channel: str
    rho: float
    floor_median: float
    floor_db: float
    informative: float

    def as_dict(self) -> dict[str, float | str]:
        return {
            "channel": self.channel,
            "rho": self.rho,
            "floor_median": self.floor_median,
            "floor_db_below_median": self.floor_db,
            "informative_share": self.informative,
        }


@dataclass
class NoiseEstimate:
    """Estimated noise of a measured FRF set.

    Attributes:
        freq_hz: ``(n_freq,)`` Hz.
        sigma: complex noise standard deviation, ``(n_out, n_in, n_freq)``, units of ``H``
            (NaN where a channel is absent or too short to estimate).
        floor: the absolute part φ, same shape and units.
        snr_db: estimated signal-to-noise ratio ``10 log10(Ŝ/N̂)`` [dB], same shape.
        rho: relative part per channel, ``(n_out, n_in)`` (NaN where absent).
        channels: per present channel summaries.
    """

    freq_hz: np.ndarray
    sigma: np.ndarray
    floor: np.ndarray
    snr_db: np.ndarray
    rho: np.ndarray
    channels: list[ChannelNoise]

    def at(self, idx: np.ndarray) -> NoiseEstimate:
        """The estimate at the frequencies ``idx`` ``(k,)`` (indices into :attr:`freq_hz`);
        the per-channel summaries stay those of the whole grid."""
        i = np.asarray(idx, int)
        return NoiseEstimate(
            self.freq_hz[i], self.sigma[:, :, i], self.floor[:, :, i], self.snr_db[:, :, i],
            self.rho.copy(), list(self.channels),
        )  # fmt: skip

    def noise_to_signal(self, prediction: bool = False) -> np.ndarray:
        """``N̂/Ŝ`` per point, ``(n_out, n_in, n_freq)`` (inf where Ŝ = 0, NaN if absent).

        ``prediction``: with the signal power ``P̄ − κ_p N̂`` (:data:`PREDICTION_MARGIN`)
        instead of the weights' cautious ``P̄ − κN̂`` (:data:`SIGNAL_MARGIN`), i.e.
        ``v/(1 + (κ − κ_p) v)`` of the weights' ``v``, where the point counts as signal at all
        (inf elsewhere, as for the weights): what a prediction of the error at the points that
        carry weight uses (with κ the signal of a point 3 dB above the noise looks like none,
        and the noise level came out 10–20 % high)."""
        with np.errstate(over="ignore"):
            v = 10.0 ** (-self.snr_db / 10.0)
        if not prediction:
            return v
        k = SIGNAL_MARGIN - PREDICTION_MARGIN
        with np.errstate(invalid="ignore", over="ignore"):
            return np.where(np.isfinite(v), v / (1.0 + k * v), v)


def _neighbours(n: int) -> np.ndarray:
    """Indices ``(n, 4)`` of the four points predicting each point."""
    k = np.arange(n)
    centre = np.clip(k, 2, n - 3)
    idx = centre[:, None] + np.array([-2, -1, 1, 2])[None, :]
    # at the ends the point itself would be among them: take the 4 nearest others
    for e in (0, 1, n - 2, n - 1):
        others = [j for j in range(max(0, e - 4), min(n, e + 5)) if j != e]
        others.sort(key=lambda j: (abs(j - e), j))
        idx[e] = sorted(others[:4])
    return idx


def loo_weights(freq_hz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Leave-one-out cubic Lagrange weights in ``ln f``.

    Args:
        freq_hz: ``(n,)`` Hz, strictly increasing, ``n ≥ 5``.

    Returns:
        ``(idx, c)``: neighbour indices and weights, both ``(n, 4)``; the prediction of
        point ``k`` is ``Σ_j c[k, j] H[idx[k, j]]``.
    """
    x = np.log(np.asarray(freq_hz, dtype=float))
    idx = _neighbours(x.size)
    xn = x[idx]  # (n, 4)
    c = np.ones(idx.shape)
    for j in range(4):
        for m in range(4):
            if m != j:
                c[:, j] *= (x - xn[:, m]) / (xn[:, j] - xn[:, m])
    return idx, c


def estimate_channel(freq_hz: np.ndarray, H: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Noise of one channel.

    Args:
        freq_hz: ``(n,)`` Hz, strictly increasing, ``n ≥`` :data:`MIN_POINTS`.
        H: complex ``(n,)``, finite.

    Returns:
        ``(sigma, floor, rho)``: noise std ``(n,)`` and its floor part φ ``(n,)`` (units of
        ``H``), and the relative part ρ.
    """
    idx, c = loo_weights(freq_hz)
    r = H - np.sum(c * H[idx], axis=1)
    p = np.abs(r) ** 2
    mag2 = np.abs(H) ** 2
    c2 = c**2
    A = mag2 + np.sum(c2 * mag2[idx], axis=1)  # relative part's variance factor
    v = 1.0 + c2.sum(axis=1)  # floor's variance factor
    lo, hi = _windows(freq_hz)
    tiny = 1e-300 + 1e-30 * float(np.max(A))
    med = window_quantile(p / np.maximum(A, tiny), lo, hi, 0.5, "midpoint")
    local = med / _LN2  # ρ² if the window were relative-only
    rho2 = min(float(np.quantile(local, RHO_QUANTILE)), RHO_MAX**2)
    phi2 = _solve_floor(p, rho2 * A, v, lo, hi)
    # a floor cannot lie far above what was measured: pure noise has |H|² ~ φ²·Exp(1), whose
    # lower quartile is 0.29 φ²; where the predictor cannot follow the signal (resonances
    # between the lines of a sparse grid) the scatter is signal, not noise
    q = window_quantile(mag2, lo, hi, CAP_QUANTILE, "lower")
    phi2 = np.minimum(phi2, CAP_FACTOR * q / -math.log1p(-CAP_QUANTILE))
    phi2 = _continued_at_ends(freq_hz, phi2, lo, hi)
    wide = _widened(freq_hz, lo, hi)
    if wide.sum() >= MIN_POINTS:
        # the envelope of the sparse part alone: on a linear grid that is the low end, whose
        # floor the dense part's power law, extrapolated by decades, says nothing of
        envelope = _power_law_envelope(freq_hz[wide], phi2[wide], (rho2 * q)[wide])
        phi2[wide] = np.minimum(phi2[wide], ENVELOPE_FACTOR * envelope)
    sigma = np.sqrt(rho2 * mag2 + phi2)
    return sigma, np.sqrt(phi2), math.sqrt(rho2)


def _mean_power(P: np.ndarray, points: int) -> np.ndarray:
    """``points``-point running mean along the last axis: centred, and at the ends the
    ``points`` nearest points (the window shifted inwards, not the end value repeated: a
    repeated end value counts one noisy point several times, and end points of pure noise
    passed for signal ~2× as often as inner ones)."""
    n = P.shape[-1]
    if n <= points:
        return np.repeat(P.mean(axis=-1, keepdims=True), n, axis=-1)
    # the sum of shifted copies, not differences of a running sum: |H|² spans many decades
    # along a channel, and a running sum's differences lose the small values to cancellation
    start = np.clip(np.arange(n) - points // 2, 0, n - points)
    out = np.zeros(P.shape)
    for j in range(points):
        out += P[..., start + j]
    return out / points


def _signal_power(H: np.ndarray, N: np.ndarray, freq_hz: np.ndarray) -> np.ndarray:
    """``Ŝ = max(P̄ − κ N̂, 0)``, ``P̄`` the mean of ``|H|²`` along the last axis over
    :data:`SIGNAL_POINTS` points where they span at most ±:data:`SIGNAL_OCTAVES` octave (a
    dense grid: a resonance peak is not smeared), over 3 elsewhere."""
    P = np.abs(H) ** 2
    h = SIGNAL_POINTS // 2
    lf = np.log2(freq_hz)
    k = np.arange(lf.size)
    span = lf[np.minimum(k + h, lf.size - 1)] - lf[np.maximum(k - h, 0)]
    dense = span <= 2.0 * SIGNAL_OCTAVES
    Pbar = np.where(dense, _mean_power(P, SIGNAL_POINTS), _mean_power(P, 3))
    return np.maximum(Pbar - SIGNAL_MARGIN * N, 0.0)


def estimate_noise(
    freq_hz: np.ndarray,
    H: np.ndarray,
    channel_names: list[list[str]] | None = None,
    where: str = "<data>",
) -> NoiseEstimate:
    """Estimate the measurement noise of every channel from the FRF alone.

    Args:
        freq_hz: ``(n_freq,)`` Hz, strictly increasing (any spacing).
        H: complex FRF ``(n_out, n_in, n_freq)``; a channel NaN anywhere is skipped.
        channel_names: ``[out][in]`` names for the summaries (default ``"a.b"`` indices).
        where: the file, for error messages.

    Returns:
        :class:`NoiseEstimate`. Channels shorter than :data:`MIN_POINTS` frequencies get NaN.
    """
    H, f = frf_arrays(H, freq_hz, f"{where}: estimate_noise")
    if (f.size > 1 and not np.all(np.diff(f) > 0)) or not np.all(f > 0):
        raise DataError(f"{where}: estimate_noise: frequencies must be positive and increasing")
    n_o, n_i, n = H.shape
    sigma = np.full(H.shape, np.nan)
    floor = np.full(H.shape, np.nan)
    rho = np.full((n_o, n_i), np.nan)
    for a in range(n_o):
        for b in range(n_i):
            h = H[a, b]
            if n >= MIN_POINTS and np.all(np.isfinite(h)):
                sigma[a, b], floor[a, b], rho[a, b] = estimate_channel(f, h)
    N = sigma**2
    S = _signal_power(np.where(np.isfinite(H), H, 0.0), np.nan_to_num(N), f)
    with np.errstate(divide="ignore", invalid="ignore"):
        snr_db = 10.0 * np.log10(S / N)
    snr_db[~np.isfinite(sigma)] = np.nan
    snr_db = np.where(np.isfinite(sigma) & (N == 0), np.inf, snr_db)
    summaries = []
    for a in range(n_o):
        for b in range(n_i):
            if not np.isfinite(rho[a, b]):
                continue
            name = channel_names[a][b] if channel_names else f"{a}.{b}"
            fm = float(np.median(floor[a, b]))
            med = float(np.median(np.abs(H[a, b])))
            fdb = 20.0 * math.log10(fm / med) if fm > 0 and med > 0 else -math.inf
            share = float(np.mean(snr_db[a, b] >= INFORMATIVE_DB))
            summaries.append(ChannelNoise(name, float(rho[a, b]), fm, fdb, share))
    return NoiseEstimate(f, sigma, floor, snr_db, rho, summaries)
