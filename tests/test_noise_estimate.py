"""Noise estimated from the FRF alone (bondid.data.noise_estimate) and the information
weights (bondid.data.weights), against synthetic data of the reference bonder whose true
noise is known (the simulator's coherence is S/(S+N) of the very noise it added)."""

from __future__ import annotations

import numpy as np
import pytest

from bondid.cost.problem import CostOptions
from bondid.data.noise import add_measurement_noise
from bondid.data.noise_estimate import estimate_noise
from bondid.data.weights import information_weights, noise_to_signal, weighting_summary
from bondid.exceptions import ConfigError
from bondid.fit import default_bounds, fit
from bondid.fit.outputs import db_rms_report
from bondid.model import UrdfDocument, get_parameters, set_parameter
from bondid.simulate import log_grid, simulate

URDF = "urdf/bonder.urdf"
#: the issue's tolerance: the estimate within this factor of the true noise level ...
FACTOR = 2.0
#: ... wherever the true SNR is below this [dB]
LOW_SNR_DB = 20.0
#: no point with a true SNR at least this [dB] ...
HIGH_SNR_DB = 30.0
#: ... may get an estimated SNR below this [dB] (classed as noise)
NOISE_DB = 10.0
REL = 0.02

REGIMES = {
    # name: (floor dB, floor reference, quantity in which the floor is flat)
    "displacement_floor": (-40.0, "median", None),
    "acceleration_floor": (-40.0, "median", "accelerance"),
    "relative_only": (None, "median", None),
}


@pytest.fixture(scope="module")
def bonder() -> UrdfDocument:
    return UrdfDocument.load(URDF)


def _truth(data, exact):
    """True noise std and SNR [dB] from the simulator's coherence γ² = S/(S+N)."""
    S = np.abs(exact.H) ** 2
    coh = data.coherence
    N = S * (1.0 - coh) / coh
    with np.errstate(divide="ignore"):
        return np.sqrt(N), 10.0 * np.log10(S / N)


def _check(bonder, f, regime, seed):
    floor_db, ref, fq = REGIMES[regime]
    data = simulate(
        bonder, None, f, noise=REL, floor_db=floor_db, seed=seed, floor_ref=ref,
        floor_quantity=fq,
    )  # fmt: skip
    exact = simulate(bonder, None, f, noise=0.0)
    sigma, snr = _truth(data, exact)
    est = estimate_noise(f, data.H)
    ratio = est.sigma / sigma
    low = snr < LOW_SNR_DB
    miss = low & ((ratio > FACTOR) | (ratio < 1.0 / FACTOR))
    called_noise = (snr >= HIGH_SNR_DB) & (est.snr_db < NOISE_DB)
    return low, miss, called_noise, est, data


@pytest.mark.parametrize("regime", sorted(REGIMES))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_estimate_within_factor_two_on_dense_log_grid(bonder, regime, seed) -> None:
    f = log_grid(1.0, 4000.0, 2000)
    low, miss, called_noise, est, _ = _check(bonder, f, regime, seed)
    if regime != "relative_only":
        assert low.sum() > 1000  # the floor really is there
    assert miss.sum() == 0, f"{miss.sum()} of {low.sum()} low-SNR points outside ×{FACTOR}"
    assert called_noise.sum() == 0
    assert np.all(np.abs(est.rho - REL) < 0.25 * REL)  # the relative part is found too


#: sparse grid: where the lines do not resolve the resonances (below ~1 kHz at 66 Hz spacing)
#: the predictor cannot tell signal from noise; the issue's goals are not met there, these
#: shares bound what is known to happen (tools/noise_accuracy.py, seeds 0-2: 11 % of the
#: low-SNR points outside ×2 (seed 0: 5 of 30 under the acceleration floor), at most 1.6 %
#: of the high-SNR points called noise)
SPARSE_MISS_SHARE = 0.2
SPARSE_CALLED_NOISE_SHARE = 0.03


@pytest.mark.parametrize("regime", sorted(REGIMES))
def test_sparse_linear_grid_60_lines(bonder, regime) -> None:
    f = np.linspace(4000.0 / 60, 4000.0, 60)
    low, miss, called_noise, est, _ = _check(bonder, f, regime, 0)
    assert miss.sum() <= SPARSE_MISS_SHARE * max(low.sum(), 1)
    assert called_noise.mean() <= SPARSE_CALLED_NOISE_SHARE
    assert np.all(np.isfinite(est.sigma))


#: an analyser's linear grid (0.5 Hz + 1.25 Hz steps): below ~60 Hz it is sparse in log f.
#: Points of true SNR < 0 dB the estimate calls signal (≥ 10 dB), as a share of them, and
#: low-SNR points outside ×2; measured on seed 0 (acceleration floor / response floor):
#: 30 of 463 and 53 of 1274 / 22 of 770 and 61 of 2890 (with the whole channel's power law
#: capping the sparse end's floor, as before stop 51: 205 of 463 and 212 / 84 and 206)
LINEAR_CALLED_SIGNAL_SHARE = 0.1
LINEAR_MISS_SHARE = 0.06


@pytest.mark.parametrize("regime", ["acceleration_floor", "response_floor"])
def test_the_sparse_low_end_of_a_linear_grid_keeps_noise_as_noise(bonder, regime) -> None:
    f = 0.5 + 1.25 * np.arange(1600)
    regimes = {**REGIMES, "response_floor": (-70.0, "response", None)}
    floor_db, ref, fq = regimes[regime]
    data = simulate(
        bonder, None, f, noise=REL, floor_db=floor_db, seed=0, floor_ref=ref, floor_quantity=fq
    )
    sigma, snr = _truth(data, simulate(bonder, None, f, noise=0.0))
    est = estimate_noise(f, data.H)
    noise = snr < 0.0
    assert noise.sum() > 100  # the floor swamps some points
    called_signal = noise & (est.snr_db >= NOISE_DB)
    assert called_signal.sum() <= LINEAR_CALLED_SIGNAL_SHARE * noise.sum()
    low = snr < LOW_SNR_DB
    ratio = est.sigma / sigma
    miss = low & ((ratio > FACTOR) | (ratio < 1.0 / FACTOR))
    assert miss.sum() <= LINEAR_MISS_SHARE * low.sum()
    assert ((snr >= HIGH_SNR_DB) & (est.snr_db < NOISE_DB)).sum() == 0


def test_short_channel_gets_no_estimate() -> None:
    f = np.linspace(1.0, 10.0, 8)
    est = estimate_noise(f, np.ones((1, 1, 8), complex))
    assert np.all(np.isnan(est.sigma)) and est.channels == []


#: σ recovered from the coherence S/(S + N) (1 − γ² loses digits when γ² is near 1)
ROUND_TRIP = 1e-6


def test_acceleration_and_median_floors_known_answer() -> None:
    f = log_grid(10.0, 1000.0, 50)
    H = np.ones((1, 2, 50), complex) * np.array([1.0, 0.1])[None, :, None]
    _, coh = add_measurement_noise(H, f, rel=0.0, floor_db=-40.0, rng=0, floor_ref="median")
    sigma = np.abs(H) * np.sqrt((1 - coh) / coh)
    np.testing.assert_allclose(sigma, np.abs(H) * 1e-2, rtol=ROUND_TRIP)
    _, coh = add_measurement_noise(
        H, f, rel=0.0, floor_db=-40.0, rng=0, floor_ref="median", floor_quantity="accelerance"
    )
    sigma = np.abs(H) * np.sqrt((1 - coh) / coh)
    w2 = (2 * np.pi * f) ** 2
    # flat in acceleration: σ·ω² constant, 40 dB below the median |ω² H|
    np.testing.assert_allclose(sigma * w2, 1e-2 * np.median(w2) * np.abs(H), rtol=ROUND_TRIP)
    with pytest.raises(ConfigError, match="floor_quantity"):
        add_measurement_noise(H, f, rel=0.0, floor_db=-40.0, rng=0, floor_quantity="force")


def test_weights_follow_the_chosen_rule(bonder) -> None:
    f = log_grid(1.0, 4000.0, 600)
    data = simulate(bonder, None, f, noise=REL, floor_db=-40.0, seed=3, floor_ref="median")
    coh = data.coherence
    assert np.all(information_weights(data, "none") == 1.0)
    np.testing.assert_array_equal(information_weights(data, "coherence"), coh)
    w_est = information_weights(data, "estimated")
    with np.errstate(divide="ignore"):
        ns_est = 1.0 / w_est - 1.0
    ns_coh = (1.0 - coh) / coh
    w_auto = information_weights(data, "auto")
    np.testing.assert_allclose(w_auto, 1.0 / (1.0 + np.maximum(ns_est, ns_coh)), rtol=1e-9)
    # the noise level's prediction takes the geometric mean of the two
    ns_pred = noise_to_signal(data, "auto", prediction=True)
    ns_est_pred = noise_to_signal(data, "estimated", prediction=True)
    np.testing.assert_allclose(ns_pred, np.sqrt(ns_est_pred * ns_coh), rtol=1e-9)
    # the estimated weights agree with the true coherence on the points that matter
    good, bad = coh > 0.99, coh < 0.1
    assert np.median(w_est[good]) > 0.95 and np.median(w_est[bad]) < 0.2
    data.coherence = None
    np.testing.assert_allclose(information_weights(data, "auto"), w_est)
    with pytest.raises(ConfigError, match="valid: auto"):
        information_weights(data, "magic")
    summ = weighting_summary([data], "auto")
    row = summ["datasets"][0]["channels"][0]
    assert summ["weighting"] == "auto" and not summ["datasets"][0]["has_coherence"]
    # a flat floor 40 dB below each channel's median, estimated from the data alone
    assert row["floor_db_below_median"] == pytest.approx(-40.0, abs=3.0)
    assert 0.0 < row["informative_share"] < 1.0


def test_use_coherence_false_means_estimated_weights() -> None:
    assert CostOptions().effective_weighting == "auto"
    assert CostOptions(use_coherence=False).effective_weighting == "estimated"
    assert CostOptions(use_coherence=False, weighting="coherence").effective_weighting == "none"


#: the fit without a coherence column must land this close to the fit with one
PARAM_RTOL = 0.1
DB_RTOL = 0.15


def test_fit_without_coherence_reaches_the_fit_with_it(bonder) -> None:
    """Harsh floor (−40 dB below each channel's median): the estimated weights recover the
    fit that the coherence column gives (parameters and weighted db_rms)."""
    names = ["x_guide_ry.stiffness", "y_guide_rx.stiffness", "z_bearing_ry.stiffness"]
    truth = UrdfDocument.load(URDF)
    for n, v in zip(names, get_parameters(bonder, names), strict=True):
        set_parameter(truth, n, 1.3 * v)
    f = log_grid(1.0, 4000.0, 400)
    data = [
        simulate(truth, op, f, noise=REL, floor_db=-40.0, seed=k, floor_ref="median")
        for k, op in enumerate([{}, {"x": 0.05, "y": -0.03, "z": 0.1}])
    ]
    lo, hi = default_bounds(bonder, names, rel={"stiffness": 0.67})
    yardstick = CostOptions(weighting="coherence")  # the true S/(S+N) of the simulator
    fitted, db = {}, {}
    for label, use in (("with", True), ("without", False)):
        r = fit(bonder, data, names, options=CostOptions(use_coherence=use), lower=lo,
                upper=hi, max_iter=60)  # fmt: skip
        fitted[label] = r.fitted
        db[label] = db_rms_report(bonder, r.document, data, yardstick)["final"]
    np.testing.assert_allclose(fitted["without"], fitted["with"], rtol=PARAM_RTOL)
    np.testing.assert_allclose(fitted["with"], get_parameters(truth, names), rtol=PARAM_RTOL)
    assert db["without"] == pytest.approx(db["with"], rel=DB_RTOL)


def test_fit_json_db_rms_is_the_weighted_figure(bonder) -> None:
    """``db_rms`` = sqrt(Σ w e² / Σ w) with the weights of the cost; the plain RMS kept."""
    f = log_grid(1.0, 4000.0, 300)
    data = [simulate(bonder, None, f, noise=REL, floor_db=-40.0, seed=4, floor_ref="median")]
    other = UrdfDocument.load(URDF)
    set_parameter(other, "z_bearing_ry.stiffness", 3000.0)
    rep = db_rms_report(bonder, other, data, CostOptions())
    Hs = simulate(other, None, f, noise=0.0).H
    L = np.log(data[0].H / Hs)
    e2 = (20.0 / np.log(10.0)) ** 2 * (L.real**2 + L.imag**2)
    w = information_weights(data[0], "auto")
    assert rep["weighting"] == "auto" and "sum(w * e^2)" in rep["definition"]
    assert rep["final"] == pytest.approx(np.sqrt(np.sum(w * e2) / np.sum(w)), rel=1e-9)
    assert rep["unweighted"]["final"] == pytest.approx(np.sqrt(np.mean(e2)), rel=1e-9)
    assert rep["initial"] < rep["final"] < rep["unweighted"]["final"]


#: pure noise: the estimate at the first and last points within this of the truth [dB] (a
#: one-sided window on a sloping floor came out 1.5 dB low at the low end, 1 dB high at the top)
END_BIAS_DB = 0.5
#: pure noise: at most this share of its points may pass for signal (κ = 3 let 0.7 % through)
NOISE_AS_SIGNAL_MAX = 0.003


def _pure_noise(f: np.ndarray, slope: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``(H, sigma)``: a 2×2 set of pure complex Gaussian noise whose std goes as ``f^slope``."""
    rng = np.random.default_rng(seed)
    sigma = 1e-6 * (f / 10.0) ** slope
    z = rng.standard_normal((2, 2, 2, f.size))
    return sigma * (z[0] + 1j * z[1]) / np.sqrt(2.0), sigma


@pytest.mark.parametrize("slope", [-2.0, 0.0, 1.0])
def test_pure_noise_ends_unbiased_and_rarely_signal(slope) -> None:
    """Known answer: on pure noise the estimate's end points are unbiased whatever the floor's
    slope (−2: a flat acceleration floor in receptance), and hardly a point passes for
    signal (such a point's log error against any model is tens of dB)."""
    f = log_grid(1.0, 4000.0, 1000)
    ends, signal, total = [], 0, 0
    for seed in range(30):
        H, sigma = _pure_noise(f, slope, seed)
        est = estimate_noise(f, H)
        r = 10.0 * np.log10(est.sigma**2 / sigma**2).reshape(-1, f.size)
        ends.append(np.concatenate([r[:, :5], r[:, -5:]], axis=1))
        signal += int(np.sum(est.snr_db > -np.inf))
        total += est.snr_db.size
    e = np.concatenate(ends)
    assert abs(np.median(e[:, :5])) < END_BIAS_DB
    assert abs(np.median(e[:, 5:])) < END_BIAS_DB
    assert signal / total < NOISE_AS_SIGNAL_MAX


def test_mean_power_window_shifts_inwards_at_the_ends() -> None:
    """The running mean takes the nearest points at the ends (no end value repeated)."""
    from bondid.data.noise_estimate import _mean_power

    P = np.arange(10.0)[None, :]
    assert np.allclose(_mean_power(P, 5), [[2, 2, 2, 3, 4, 5, 6, 7, 7, 7]])
    assert np.allclose(_mean_power(P, 3), [[1, 1, 2, 3, 4, 5, 6, 7, 8, 8]])
    assert np.allclose(_mean_power(np.ones((2, 3, 4)), 5), 1.0)
