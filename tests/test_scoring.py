"""The diagnosis's verdict rule (bondid.diagnose.scoring): the held-out noise reference against
Monte Carlo draws of noise of known level, and the rule's decisions on known cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bondid.cost.problem import CostOptions
from bondid.cost.residuals import DB, check_kind
from bondid.data.measurement import FrfData
from bondid.diagnose import scoring
from bondid.simulate import log_grid

#: draws of the noise
N_DRAWS = 400
#: the mean weighted square of an exact model's error vs the predicted L² (relative)
MEAN_TOL = 0.05
#: the std of that mean square over the draws vs L²/√n (relative; the estimate of a std from
#: 400 draws is good to about 4 %, the exponential approximation of |ln(1 + u)|² adds some)
STD_TOL = 0.25


def _held_out(n_freq: int = 300, seed: int = 0):
    """One data set whose coherence holds known information weights (as in the diagnosis),
    its exact FRF and its noise-to-signal ratios."""
    rng = np.random.default_rng(seed)
    f = log_grid(1.0, 1000.0, n_freq)
    H = (1.0 / (1.0 - (f / 200.0) ** 2 + 0.02j * f / 200.0))[None, None, :] * np.ones((1, 2, 1))
    w = rng.uniform(0.2, 1.0, H.shape)  # SNR from −6 dB up
    w[..., : n_freq // 10] = 1.0 - 1e-6  # a few clean points
    ds = FrfData(f, ["a"], ["p", "q"], H, "receptance", {}, w, "held-out")
    return ds, (1.0 - w) / w


def test_noise_reference_matches_monte_carlo() -> None:
    ds, v = _held_out()
    opts = CostOptions(weighting="coherence")
    ref = scoring.heldout_noise([ds], opts)
    assert ref is not None
    rng = np.random.default_rng(1)
    w = ds.coherence
    ms = []
    for _ in range(N_DRAWS):
        u = np.sqrt(v / 2.0) * (rng.standard_normal(v.shape) + 1j * rng.standard_normal(v.shape))
        e2 = DB**2 * np.abs(np.log1p(u)) ** 2
        ms.append(float(np.sum(w * e2) / np.sum(w)))
    L2 = ref.level_db**2
    assert abs(np.mean(ms) / L2 - 1.0) < MEAN_TOL
    assert abs(np.std(ms) / (L2 / math.sqrt(ref.n_eff)) - 1.0) < STD_TOL


def test_no_reference_for_a_cost_without_noise_model() -> None:
    ds, _ = _held_out()
    for kw in ({"kind": "normalised_complex"}, {"kind": "log_magnitude"}, {"norm": "l1"}):
        opts = CostOptions(weighting="coherence", **kw)  # type: ignore[arg-type]
        check_kind(opts.kind, opts.norm)  # a valid cost, only not modelled
        assert scoring.heldout_noise([ds], opts) is None


REF = scoring.NoiseReference(level_db=1.0, n_eff=400.0)


def test_a_base_at_the_noise_level_accepts_nothing() -> None:
    # even a candidate that scores far below the noise (overfitting) is refused
    t = scoring.tests(0.5, 1.05, 1, REF)
    assert not t["base_above_noise"] and not t["accepted"]


def test_nothing_may_be_accepted_against_a_base_at_the_noise_level() -> None:
    """may_accept is the rule's first condition alone: False only with a noise reference and
    a base at its level; the rule then accepts no candidate at all."""
    assert not scoring.may_accept(1.05, REF) and scoring.may_accept(2.0, REF)
    assert scoring.may_accept(1.05, None) and scoring.may_accept(math.nan, REF)
    assert not any(scoring.tests(s1, 1.05, p, REF)["accepted"] for s1 in (0.1, 0.9) for p in (1, 7))
    assert scoring.may_accept(2.0, REF) == scoring.tests(1.0, 2.0, 1, REF)["base_above_noise"]


def test_a_real_gap_closed_is_accepted() -> None:
    t = scoring.tests(1.02, 2.0, 2, REF)
    assert t["base_above_noise"] and t["significant"] and t["accepted"]
    assert t["lr"] == pytest.approx(400 * (4.0 - 1.02**2))


def test_an_insignificant_improvement_is_refused() -> None:
    # the base well above the noise, the candidate better by 0.1 % of the mean square
    t = scoring.tests(math.sqrt(4.0 * 0.999), 2.0, 1, REF)
    assert t["base_above_noise"] and t["lr"] < t["lr_threshold"] and not t["accepted"]


def test_a_small_share_of_the_excess_is_refused() -> None:
    # significant (LR 400·0.3 = 120) but 10 % of an excess of 3 dB²
    s1 = math.sqrt(4.0 - 0.3)
    t = scoring.tests(s1, 2.0, 1, REF)
    assert t["lr"] > t["lr_threshold"] and t["excess_share"] == pytest.approx(0.1)
    assert not t["accepted"]


def test_an_accepted_refit_must_lower_the_gap_on_all_data() -> None:
    """The rule's last condition: a held-out winner whose weighted gap on all data is not
    lower than its base's is refused, and the reason says so; a lower one stays accepted."""
    t = scoring.tests(1.02, 2.0, 2, REF)
    scoring.refuse_unless_lower(t, 1.5, 1.4)
    assert not t["accepted"] and t["gap_not_lower"]
    assert "not lower than the base's" in scoring.reason(t, 1.02, 2.0)
    t = scoring.tests(1.02, 2.0, 2, REF)
    scoring.refuse_unless_lower(t, 1.3, 1.4)
    assert t["accepted"] and "gap_not_lower" not in t
    t = scoring.tests(0.9, 1.0, 1, None)  # the margins' rule alike
    scoring.refuse_unless_lower(t, 2.0, 1.0)
    assert not t["accepted"] and "not lower" in scoring.reason(t, 0.9, 1.0)


def test_without_reference_the_margins_decide() -> None:
    assert scoring.accept(0.9, 1.0, 1, None)
    assert not scoring.accept(0.97, 1.0, 1, None)
    assert not scoring.accept(math.inf, 1.0, 1, REF)


def test_a_refit_without_a_finite_score_is_refused_with_a_reason():
    """A candidate whose refit failed (score inf) is refused, and the verdict's reason says
    why instead of failing on missing figures."""
    noise = scoring.NoiseReference(1.0, 400.0)
    t = scoring.tests(math.inf, 2.0, 1, noise)
    assert t["accepted"] is False and t["rule"] == "none"
    assert "not finite" in scoring.reason(t, math.inf, 2.0)


# --- the verdict rule on synthetic held-out scores (Monte Carlo) ---------------------------

#: seeded trials per case, and the points of the training and the held-out sets
N_TRIALS = 300
N_POINTS = 400
#: a candidate that adds nothing may be accepted in at most this share of the trials (the
#: rule's own tests would allow ~0.13 % at the noise level and far less for the LR test)
MAX_FALSE_ALARM = 0.01
#: a candidate that removes a real model error must be accepted in at least this share
MIN_POWER = 0.95
#: the points' information weights are uniform in W_MIN..1 (SNR from 6 dB up)
W_MIN = 0.8
#: the real model error: complex-log amplitude [Np] of a bump in log frequency (the base
#: then scores ~1.5x the held-out noise level; at 1 Np, ~1.27x, the base-above-noise test
#: passes in ~63 % of the trials)
ERROR_AMPLITUDE = 1.5


def _bump(f: np.ndarray, f0: float) -> np.ndarray:
    """A smooth bump in ``ln f`` (width 0.3) centred at ``f0``: the shape of a local error."""
    return np.exp(-0.5 * (np.log(f / f0) / 0.3) ** 2)


def _verdicts(
    model_error: float, error_hz: float, candidate_hz: float | tuple[float, ...], seed: int
) -> np.ndarray:
    """Accepted flags of the rule over seeded trials: the base's complex-log error is
    ``model_error · bump(error_hz)``; the candidate adds a complex amplitude (2 parameters) of
    ``bump(f)`` for each ``f`` of ``candidate_hz``, fitted by weighted least squares on the
    training points, as a refit would; both scored on the held-out points with information
    weights and complex Gaussian noise of N/S = (1 − w)/w (what heldout_noise assumes)."""
    rng = np.random.default_rng(seed)
    f = log_grid(1.0, 1000.0, 2 * N_POINTS)
    sets = {"train": f[0::2], "held": f[1::2]}
    w = {k: rng.uniform(W_MIN, 1.0, N_POINTS) for k in sets}
    v = {k: (1.0 - w[k]) / w[k] for k in sets}
    held = FrfData(sets["held"], ["a"], ["p"], np.ones((1, 1, N_POINTS), complex), "receptance",
                   {}, w["held"][None, None, :], "held-out")  # fmt: skip
    ref = scoring.heldout_noise([held], CostOptions(weighting="coherence"))
    assert ref is not None
    n_train = 2 * N_POINTS  # real residuals
    centres = np.atleast_1d(np.asarray(candidate_hz, float))
    n_new = 2 * centres.size
    phi = {k: _bump(x[:, None], centres[None, :]) for k, x in sets.items()}  # (N, n_bumps)
    err = {k: model_error * _bump(x, error_hz) for k, x in sets.items()}
    out = np.empty(N_TRIALS, bool)
    for t in range(N_TRIALS):
        r = {}
        for k in sets:
            g = rng.standard_normal((2, N_POINTS))
            u = np.sqrt(v[k] / 2) * (g[0] + 1j * g[1])
            r[k] = np.log1p(u) + err[k]
        sw = np.sqrt(w["train"])[:, None]
        theta = np.linalg.lstsq(sw * phi["train"], sw[:, 0] * r["train"], rcond=None)[0]

        def rms(res: np.ndarray) -> float:
            return float(DB * np.sqrt(np.sum(w["held"] * np.abs(res) ** 2) / np.sum(w["held"])))

        s0 = scoring.score(rms(r["held"]), n_train, 0)
        s1 = scoring.score(rms(r["held"] - phi["held"] @ theta), n_train, n_new)
        out[t] = scoring.accept(s1, s0, n_new, ref)
    return out


@pytest.mark.parametrize("model_error", [0.0, ERROR_AMPLITUDE])
def test_a_candidate_that_adds_nothing_is_rarely_accepted(model_error: float) -> None:
    # an exact base, or a base with a real error elsewhere than where the candidate acts
    acc = _verdicts(model_error, error_hz=10.0, candidate_hz=300.0, seed=11)
    assert acc.mean() <= MAX_FALSE_ALARM


def test_a_candidate_that_removes_a_real_error_is_accepted() -> None:
    acc = _verdicts(ERROR_AMPLITUDE, error_hz=10.0, candidate_hz=10.0, seed=12)
    assert acc.mean() >= MIN_POWER


#: a candidate of many parameters (a flexible base, soft mounts): 4 complex amplitudes
MANY = (3.0, 30.0, 300.0, 600.0)


@pytest.mark.parametrize("model_error", [0.0, ERROR_AMPLITUDE])
def test_a_candidate_of_many_parameters_that_adds_nothing_is_rarely_accepted(
    model_error: float,
) -> None:
    # the threshold grows with p as the chi-square quantile: 8 free parameters fitting noise
    # (or an error elsewhere) must not pass it more often than one does
    acc = _verdicts(model_error, error_hz=10.0, candidate_hz=MANY, seed=13)
    assert acc.mean() <= MAX_FALSE_ALARM


#: a smaller real error (the base ~1.3x the noise level): the 2-parameter candidate is
#: accepted in ~95 % of the trials; with a threshold of z² per parameter (72 for 8) the
#: 8-parameter one was accepted in 62 %
SMALL_ERROR = 1.1


def test_a_candidate_of_many_parameters_that_removes_a_real_error_is_accepted() -> None:
    # one of its 4 shapes is the error's: it must not need a far larger statistic for it
    acc = _verdicts(SMALL_ERROR, error_hz=10.0, candidate_hz=(10.0, *MANY[1:]), seed=14)
    assert acc.mean() >= MIN_POWER


def test_the_threshold_is_the_chi_square_quantile_at_the_one_parameter_rate() -> None:
    from scipy.stats import chi2

    assert scoring.lr_threshold(1) == pytest.approx(scoring.Z**2)
    alpha = chi2.sf(2 * scoring.Z**2, 1)
    for p in (2, 7, 8):
        t = scoring.lr_threshold(p)
        assert chi2.sf(2 * t, p) == pytest.approx(alpha, rel=1e-6)
        assert scoring.Z**2 < t < scoring.Z**2 * p


def test_refits_the_data_cannot_tell_from_the_best_are_listed() -> None:
    """With the noise reference: a refit whose Λ against the best is at most the
    one-parameter threshold ties with it; one beyond does not; a failed refit never ties."""
    thr = scoring.lr_threshold(1)
    s1 = 1.2
    # Λ = n (sⱼ² − s₁²) / L² just under and just over the threshold
    under = math.sqrt(s1**2 + 0.99 * thr / REF.n_eff)
    over = math.sqrt(s1**2 + 1.01 * thr / REF.n_eff)
    test = scoring.tests(s1, 2.0, 1, REF)
    got = scoring.indistinguishable([s1, under, over, math.inf], test)
    assert [j for j, _ in got] == [1]
    assert got[0][1] == pytest.approx(0.99 * thr)
    # without a reference: the margins (a tie unless the best is 5 % and 0.05 dB lower)
    plain = scoring.tests(1.0, 2.0, 1, None)
    got = scoring.indistinguishable([1.0, 1.03, 1.2], plain)
    assert [j for j, _ in got] == [1] and math.isnan(got[0][1])
    assert scoring.indistinguishable([], test) == []
