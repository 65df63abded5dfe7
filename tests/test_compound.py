"""The first step's look-ahead (:mod:`bondid.diagnose.compound`): two effects accepted
together when each alone removes too small a share of the excess over the noise.

Known answers from the verdict rule's own formula (:func:`bondid.diagnose.scoring.tests`)
with the figures of the benchmark case that motivated it (held-out noise level 0.732 dB on
82 independent points, parameter refit 2.286 dB, best first refit 2.029 dB: 24 % of the
excess)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from bondid.diagnose import scoring
from bondid.diagnose.compound import look_ahead, pair_test, short_of_share
from bondid.diagnose.search import Step

NOISE = scoring.NoiseReference(level_db=0.732, n_eff=82.0)
S0, S1 = 2.286, 2.029


def _result(effect: str, location: str, n_own: int) -> SimpleNamespace:
    return SimpleNamespace(effect=effect, location=location, n_own=n_own,
                           label=f"{effect}@{location}")  # fmt: skip


def _step(index: int, base_score: float, score: float, result: SimpleNamespace) -> Step:
    step = Step(index, SimpleNamespace(), base_score, [], [])  # type: ignore[arg-type]
    step.results, step.scores = [result], [score]  # type: ignore[list-item]
    step.test = scoring.tests(score, base_score, result.n_own, NOISE)
    if step.test["accepted"]:
        step.winner = result  # type: ignore[assignment]
    return step


def _ctx(max_effects: int = 3) -> SimpleNamespace:
    return SimpleNamespace(max_effects=max_effects, noise=NOISE)


LAG = _result("actuator_lag", "xa", 1)
JOINT = _result("joint_compliance", "carriage_y->slide_x:rz", 2)


def test_the_motivating_first_step_is_short_of_the_share_only():
    test = scoring.tests(S1, S0, 1, NOISE)
    assert not test["accepted"] and test["base_above_noise"]
    assert test["lr"] > test["lr_threshold"]
    assert test["excess_share"] == pytest.approx((S0**2 - S1**2) / (S0**2 - 0.732**2))
    assert test["excess_share"] < scoring.MIN_EXCESS_SHARE
    assert short_of_share(test)


@pytest.mark.parametrize(
    "s1, why",
    [(S0 * 0.999, "not significant"), (1.2, "accepted already")],
)
def test_other_refusals_and_acceptances_are_not_short_of_the_share(s1, why):
    assert not short_of_share(scoring.tests(s1, S0, 1, NOISE)), why


def test_a_base_at_the_noise_level_does_not_look_ahead():
    first = _step(0, 0.75, 0.60, LAG)
    assert not first.test["base_above_noise"]

    def run_step(*_a):  # pragma: no cover - must not run
        raise AssertionError("look-ahead ran from a base at the noise level")

    assert look_ahead(_ctx(), first, run_step) is None  # type: ignore[arg-type]
    assert first.winner is None and "compound" not in first.test


def test_a_pair_that_passes_is_accepted_together():
    first = _step(0, S0, S1, LAG)
    calls = []

    def run_step(index, base, base_score):
        calls.append((index, base, base_score))
        return _step(index, base_score, 1.05, JOINT)

    nxt = look_ahead(_ctx(), first, run_step)  # type: ignore[arg-type]
    assert calls == [(1, LAG, S1)]
    assert nxt is not None and nxt.winner is JOINT and first.winner is LAG
    pair = scoring.tests(1.05, S0, LAG.n_own + JOINT.n_own, NOISE)
    assert first.test["accepted"] and first.test["compound"]["pair"] == pair
    assert first.test["compound"]["with"]["effect"] == "joint_compliance"
    assert nxt.test["compound"]["with"]["effect"] == "actuator_lag"
    assert pair["excess_share"] >= scoring.MIN_EXCESS_SHARE
    assert "accepted together with joint_compliance" in scoring.reason(first.test, S1, S0)


def test_a_second_refit_that_is_not_significant_leaves_the_step_refused():
    """The second's own gain must be significant against the first: a pair whose second
    step adds nothing the data show is no pair, whatever the pair's share."""
    first = _step(0, S0, S1, LAG)
    s2 = 2.025  # Λ against S1 well below the two-parameter threshold
    nxt_step = _step(1, S1, s2, JOINT)
    assert nxt_step.test["lr"] < nxt_step.test["lr_threshold"]
    out = look_ahead(_ctx(), first, lambda *_a: nxt_step)  # type: ignore[arg-type]
    assert out is None and first.winner is None and not first.test["accepted"]
    info = first.test["compound"]
    assert info["accepted"] is False and info["with"]["effect"] == "joint_compliance"
    assert "not accepted" in scoring.reason(first.test, S1, S0)


def test_a_pair_short_of_the_share_is_refused():
    """Two significant gains that together still remove less than the share are refused."""
    s1 = S1 + 0.09  # ~16 % alone
    first = _step(0, S0, s1, LAG)
    assert short_of_share(first.test)
    s2 = s1 - 0.06  # significant against s1, the pair below 25 %
    nxt_step = _step(1, s1, s2, JOINT)
    assert nxt_step.test["lr"] > nxt_step.test["lr_threshold"]
    pair = pair_test(first, nxt_step, NOISE)
    assert pair["excess_share"] < scoring.MIN_EXCESS_SHARE
    assert look_ahead(_ctx(), first, lambda *_a: nxt_step) is None  # type: ignore[arg-type]
    assert first.winner is None


def test_only_the_first_step_with_room_looks_ahead():
    later = _step(1, S0, S1, LAG)
    assert look_ahead(_ctx(), later, lambda *_a: 1 / 0) is None  # type: ignore[arg-type]
    first = _step(0, S0, S1, LAG)
    assert look_ahead(_ctx(max_effects=1), first, lambda *_a: 1 / 0) is None  # type: ignore[arg-type]
