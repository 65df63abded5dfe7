"""The verdict's strength test (bondid.diagnose.scoring.strength_z, decide.verdict_order): the
Wald statistic of an absent effect against draws of noise of known level, its rules on the
parameters it reads, and the order in which a step tests its refits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bondid.diagnose import scoring
from bondid.diagnose.decide import verdict_order
from bondid.diagnose.effects.base import Candidate, NewParameter
from bondid.diagnose.job import JobResult
from bondid.optim.result import parameter_statistics

#: draws of the noise
N_DRAWS = 2000
#: share of draws of an absent effect (true strength 0) judged determined: Z = 3 gives
#: P(|N(0, 1)| ≥ 3) = 0.27 % in theory; the bound leaves room for 2000 draws' scatter
FALSE_SHARE_MAX = 0.01
#: a present effect at 8 of its own std: P(z < 3) ≈ 3e-7 in theory
TRUE_SHARE_MIN = 0.99

STIFF = NewParameter("stiffness", 1.0, 1e-3, 1e3, "N/m", scan=1.0, strength=True)
DAMP = NewParameter("damping", 1.0, 1e-3, 1e3, "N*s/m", scan=0.5)


def _result(values, std, params=(DAMP, STIFF), label="joint_compliance@a->b:tz") -> JobResult:
    """A refit whose last ``len(params)`` values are its candidate's parameters."""
    cand = Candidate("joint_compliance", "a->b:tz", tuple(params))
    values, std = np.asarray(values, float), np.asarray(std, float)
    return JobResult(
        label, cand.effect, cand.location, [f"p{i}" for i in range(values.size)], values, std,
        len(params), 1.0, 1.0, 100, 1.0, 1.0, [], "", 0.0, candidate=cand, n_own=len(params),
    )  # fmt: skip


def _wald_share(true_strength: float, seed: int) -> float:
    """Share of noise draws whose least-squares refit (two nominal columns, a damping and a
    strength column, all correlated) is judged determined."""
    rng = np.random.default_rng(seed)
    n = 200
    X = rng.normal(size=(n, 4))
    X[:, 3] += 0.6 * X[:, 0]  # the strength trades partly against a nominal parameter
    sigma = 0.1
    # the std of the strength's estimate, for scaling the present effect
    cov = sigma**2 * np.linalg.inv(X.T @ X)
    beta = np.array([1.0, -0.5, 0.3, true_strength * math.sqrt(cov[3, 3])])
    hits = 0
    for _ in range(N_DRAWS):
        y = X @ beta + sigma * rng.normal(size=n)
        b, *_ = np.linalg.lstsq(X, y, rcond=None)
        std, _ = parameter_statistics(X, y - X @ b)
        hits += scoring.determined(_result(b, std))
    return hits / N_DRAWS


def test_an_absent_effect_is_rarely_judged_determined() -> None:
    assert _wald_share(0.0, seed=1) <= FALSE_SHARE_MAX


def test_a_present_effect_is_judged_determined() -> None:
    assert _wald_share(8.0, seed=2) >= TRUE_SHARE_MIN


def test_strength_z_reads_only_the_strength_parameters() -> None:
    # nominal, damping (well determined), stiffness (value/std = 0.5)
    r = _result([1.0, 2.0, 10.0], [0.1, 0.01, 20.0])
    assert scoring.strength_z(r) == pytest.approx(0.5)
    assert not scoring.determined(r)
    # a flexible base: one determined stiffness of several is enough (the largest z)
    k2 = NewParameter("shear_y_stiffness", 1.0, 1e-3, 1e3, "N/m", scan=1.0, strength=True)
    r = _result([1.0, 5.0, 10.0], [0.1, 1e6, 1.0], params=(STIFF, k2))
    assert scoring.strength_z(r) == pytest.approx(10.0)
    assert scoring.determined(r)


def test_strength_z_of_unidentified_and_untestable_refits() -> None:
    # NaN std: the data do not identify the strength at all
    assert scoring.strength_z(_result([1.0, 2.0, 10.0], [0.1, 0.1, np.nan])) == 0.0
    # no std at all (a failed refit): not determined
    assert scoring.strength_z(_result([1.0, 2.0, 10.0], [])) == 0.0
    # a zero std (exactly determined) and a candidate without strength parameters
    assert scoring.strength_z(_result([1.0, 2.0, 10.0], [0.1, 0.1, 0.0])) == math.inf
    assert scoring.strength_z(_result([1.0, 2.0], [0.1, 0.1], params=(DAMP,))) == math.inf
    # the parameter refit (no candidate): nothing to test
    base = _result([1.0], [0.1], params=())
    base.candidate = None
    assert scoring.strength_z(base) == math.inf


def test_a_step_tests_the_best_determined_refit_first() -> None:
    undetermined = _result([1.0, 2.0, 10.0], [0.1, 0.1, 50.0])
    determined = _result([1.0, 2.0, 10.0], [0.1, 0.1, 0.5])
    results = [determined, undetermined, determined, determined]
    scores = [1.3, 1.0, 1.1, math.inf]
    # 1.1 (determined) is tested before the better-scoring 1.0 (undetermined)
    assert verdict_order(results, scores) == [2, 0, 3, 1]
    assert verdict_order([undetermined], [1.0]) == [0]


def test_conditional_std_is_the_std_of_a_fit_with_the_given_parameters_held() -> None:
    """Peer check on a linear least-squares problem: the std of parameter 0 with parameter 2
    held (:func:`conditional_std` from the full fit's std and correlation) is the std
    :func:`parameter_statistics` gives when column 2 is left out of the fit, once both use
    the same residual variance; never above the marginal std; two uncorrelated parameters
    keep their std."""
    from bondid.optim.result import conditional_std

    rng = np.random.default_rng(7)
    N = 400
    a = rng.normal(size=N)
    # columns 0 and 2 nearly collinear (a mass and a spring at one mode), 1 independent
    J = np.column_stack([a, rng.normal(size=N), 0.9 * a + 0.2 * rng.normal(size=N)])
    r = 0.1 * rng.normal(size=N)
    std, corr = parameter_statistics(J, r)
    held, _ = parameter_statistics(J[:, :2], r)
    # parameter_statistics divides r·r by N − n: bring the two-column fit to the same variance
    same = held[0] * math.sqrt((N - 2) / (N - 3))
    assert conditional_std(std, corr, 0, [2]) == pytest.approx(same, rel=1e-9)
    assert conditional_std(std, corr, 0, [2]) < 0.5 * std[0]
    assert conditional_std(std, corr, 0, []) == std[0]
    assert conditional_std(std, corr, 1, [0]) == pytest.approx(std[1], rel=0.05)


def test_strength_z_reads_the_std_with_the_candidates_own_parameters_held() -> None:
    """A refit that gives ``own_std`` is tested on it; without it, on the marginal std."""
    r = _result([1.0, 2.0, 10.0], [0.1, 1.0, 5.0])
    assert scoring.strength_z(r) == pytest.approx(2.0)
    r.own_std = np.array([1.0, 1.0])
    assert scoring.strength_z(r) == pytest.approx(10.0)
