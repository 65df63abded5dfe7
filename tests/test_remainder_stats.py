"""The pieces under describe_remainder: the excess figures against the diagnosis' own gap and
noise level, the false-alarm rate of a fit's test on pure noise, the rank-one drive update,
and the words."""

from __future__ import annotations

import math

import numpy as np
from scipy.special import exp1
from test_remainder_systems import FREQ, measured, receptance, system

from bondid.cost.noise_level import expected_log_error, expected_sq_db
from bondid.diagnose.gap import gap_report
from bondid.diagnose.remainder import words
from bondid.diagnose.remainder.context import Context, Settings
from bondid.diagnose.remainder.drive import candidates as drive_candidates
from bondid.diagnose.remainder.excess import excess_figures
from bondid.diagnose.remainder.residual import Points, build_residual, log_ratio
from bondid.diagnose.remainder.stats import fit_points

#: agreement with the peers' figures [dB]
PEER_DB = 1e-9
#: Monte-Carlo agreement (400 000 draws): absolute in units of the std, relative
MC_ABS, MC_REL = 0.01, 0.02
#: the rank-one drive update against the direct inverse (relative)
RANK_ONE_REL = 1e-8


def test_excess_figures_match_the_gap_and_the_noise_level_of_the_diagnosis():
    M, K, D = system()
    H = receptance(M, K, D)
    d = measured(H * 1.05, 2)
    ex = excess_figures(build_residual([d], [H]))
    gap = gap_report(d, H, weighting="coherence")
    assert abs(ex.db_rms - gap.db_rms) < PEER_DB
    for p in ex.by_channel:
        assert abs(p.db_rms - gap.by_channel[p.name]) < PEER_DB
    # the noise level: the weights' N/S through bondid.cost.noise_level, weighted alike
    sq = expected_sq_db(d, weighting="coherence", basis="weights")
    w = d.coherence
    assert abs(ex.noise_db - math.sqrt(np.sum(w * sq) / np.sum(w))) < PEER_DB


def test_the_noise_mean_log_error_matches_monte_carlo():
    """``E ln|1 + u| = ½ E₁(1/v)`` and ``E|ln(1 + u)|²`` (bondid.cost.noise_level) for u
    complex Gaussian: the centring of the residual rests on both."""
    rng = np.random.default_rng(3)
    for v in (0.01, 1.0, 100.0):
        u = np.sqrt(v / 2) * (rng.standard_normal(400_000) + 1j * rng.standard_normal(400_000))
        e = np.log(1 + u)
        assert abs(np.mean(e.real) - 0.5 * exp1(1 / v)) < MC_ABS * max(1.0, np.std(e.real))
        assert abs(np.mean(np.abs(e) ** 2) / expected_log_error(v) - 1) < MC_REL


def test_log_ratio_is_the_principal_complex_log():
    rng = np.random.default_rng(0)
    a = rng.standard_normal(500) + 1j * rng.standard_normal(500)
    b = rng.standard_normal(500) + 1j * rng.standard_normal(500)
    np.testing.assert_allclose(log_ratio(a, b), np.log(a / b), rtol=0, atol=1e-12)


def _noise_points(rng: np.random.Generator, n: int, offset: float) -> Points:
    """``n`` points of unit model with noise of varied N/S (some near the floor) and a
    measured gain ``e^offset``."""
    v = np.exp(rng.uniform(np.log(1e-4), np.log(3.0), n))
    u = np.sqrt(v / 2) * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    Hs = np.ones(n, complex)
    s = 2j * np.pi * np.geomspace(1, 1000, n)
    z = np.zeros(n, int)
    mu = 0.5 * exp1(1 / v)  # the noise's mean log error
    return Points(z, z, z, np.arange(n), s, np.exp(offset) * (1 + u), Hs, 1 / (1 + v),
                  expected_log_error(v) - mu**2, mu)  # fmt: skip


def _gain_p(pts: Points) -> float:
    fit = fit_points(pts, lambda th: pts.Hs * np.exp(th[0]), np.array([0.0]))
    assert fit is not None
    return fit.p_value


def test_a_fit_on_pure_noise_is_significant_no_more_often_than_its_p_value_says():
    rng = np.random.default_rng(7)
    p = np.array([_gain_p(_noise_points(rng, 300, 0.0)) for _ in range(400)])
    for alpha in (0.01, 0.05, 0.2):
        # at most the nominal rate, with three binomial standard deviations of slack
        assert np.mean(p < alpha) <= alpha + 3 * math.sqrt(alpha * (1 - alpha) / p.size)


def test_a_real_offset_is_significant():
    """0.87 dB on 300 points whose noise ranges from −40 dB to 5 dB above the signal."""
    rng = np.random.default_rng(8)
    assert _gain_p(_noise_points(rng, 300, 0.1)) < 1e-6


def test_the_drive_update_is_the_inverse_with_a_spring_to_ground():
    """Noise-free: the drive finding's corrected model equals the receptance of the machine
    with the spring and damper, to rounding."""
    M, K, D = system()
    H = receptance(M, K, D)
    K2, D2 = K.copy(), D.copy()
    K2[0, 0] += 2500.0
    D2[0, 0] += 5.0
    truth = receptance(M, K2, D2)
    d = measured(truth, 0, rel=1e-6, floor_db=-200.0)
    res = build_residual([d], [H])
    cand = next(c for c in drive_candidates(res, Context([d], [H], Settings(modes=False)))
                if c.key.endswith("drive x"))  # fmt: skip
    corrected = cand.corrected(res)[0]
    assert np.max(np.abs(corrected / truth - 1)) < 1e-4  # the fit, on 1e-6 noise
    finding = cand.describe(cand.significance(res.excess(), res.weight, 1e-8))
    assert abs(finding.stiffness / 2500.0 - 1) < 1e-4
    # the update itself, at the true values
    s = 2j * np.pi * FREQ
    dz = 2500.0 + 5.0 * s
    update = H - H[:, [0], :] * dz * H[[0], :, :] / (1 + dz * H[0, 0])
    np.testing.assert_allclose(update, truth, rtol=RANK_ONE_REL)
    assert "N/m" in finding.text and "N·m/rad" not in finding.text
    # the same drive named rotary: its units follow
    ctx = Context([d], [H], Settings(modes=False, rotary=("x",)))
    rot = next(c for c in drive_candidates(res, ctx) if c.key.endswith("drive x"))
    text = rot.describe(rot.significance(res.excess(), res.weight, 1e-8)).text
    assert "N·m/rad" in text


def test_words():
    assert words.hz(1100.0) == "1.10 kHz"
    assert words.hz(164.2) == "164 Hz"
    assert words.seconds(85e-6) == "85 µs"
    assert words.si(4100.0, "N/m") == "4.1 kN/m"
    assert words.names(["x", "y", "z"]) == "x, y and z"
    assert words.side_phrase("output", ["y"]) == "output row y"
