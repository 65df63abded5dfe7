"""Two missing effects at once (bondid.diagnose.search.search, scoring.short_of_share): a step
whose best refit fails only the share of the excess is held and accepted with the next effect
when the two pass the rule together; the search's own loop with scripted steps."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bondid.diagnose import scoring, search
from bondid.diagnose.effects.base import Candidate, NewParameter
from bondid.diagnose.runner import JobResult

#: the held-out noise reference of every scripted step: level L = 0.5 dB on n = 80 points
REF = scoring.NoiseReference(0.5, 80.0)
K = NewParameter("stiffness", 1.0, 1e-3, 1e3, "N/m", scan=1.0, strength=True)


def _refit(label: str, z: float = 100.0) -> JobResult:
    """A refit of one candidate (one strength parameter at ``value/std = z``)."""
    effect, location = label.split("@")
    cand = Candidate(effect, location, (K,))
    return JobResult(
        label, effect, location, ["k"], np.array([1.0]), np.array([1.0 / z]), 1, 1.0, 1.0, 400,
        1.0, 1.0, [], "", 0.0, candidate=cand, n_own=1,
    )  # fmt: skip


def _scripted(monkeypatch, plan: dict[int, list[tuple[str, float]]]) -> list[tuple[int, str]]:
    """Replace ``search._step``: step ``index`` refits ``plan[index]`` ((label, score) pairs,
    any order) from the given base; the verdict test is the real one. Returns the calls."""
    calls = []

    def fake(ctx, pool, index, base, base_score, progress):
        calls.append((index, base.label))
        results = [_refit(lab) for lab, _ in plan[index]]
        scores = [sc for _, sc in plan[index]]
        order = search.verdict_order(results, scores)
        step = search.Step(index, base, base_score, [], [])
        step.results = [results[i] for i in order]
        step.scores = [scores[i] for i in order]
        step.test = scoring.tests(step.scores[0], base_score, 1, REF)
        if step.test["accepted"]:
            step.winner = step.results[0]
        return step

    monkeypatch.setattr(search, "_step", fake)
    return calls


class _Ctx:
    max_effects = 3
    noise = REF
    candidates = tuple(Candidate(e, loc, (K,)) for e, loc in
                       [("a", "x"), ("b", "y"), ("c", "z")])  # fmt: skip


def _share(s0: float, s1: float) -> float:
    return (s0**2 - s1**2) / (s0**2 - REF.level_db**2)


def _baseline(score: float) -> JobResult:
    r = _refit("refit@none")
    r.label, r.candidate, r.n_own = "refit", None, 0
    # the search scores the baseline from its held-out RMS with no added parameter
    r.heldout_rms = score
    return r


def test_two_effects_each_short_of_the_share_are_accepted_together(monkeypatch) -> None:
    s0, sa, sab = 3.0, 2.7, 0.6
    assert _share(s0, sa) < scoring.MIN_EXCESS_SHARE < _share(s0, sab)
    calls = _scripted(monkeypatch, {0: [("a@x", sa), ("b@y", 2.8)], 1: [("b@y", sab)],
                                    2: [("c@z", 0.59)]})  # fmt: skip
    steps = search.search(_Ctx(), None, _baseline(s0))
    assert [(i, b) for i, b in calls] == [(0, "refit"), (1, "a@x"), (2, "b@y")]
    assert [s.winner.label for s in steps if s.winner] == ["a@x", "b@y"]
    pair = steps[0].test["pair"]
    assert pair["accepted"] and pair["second"] == "b@y"
    assert pair["excess_share"] == pytest.approx(_share(s0, sab))
    # the pair's threshold counts both effects' parameters
    assert pair["lr_threshold"] == pytest.approx(scoring.lr_threshold(2))
    assert "both accepted" in scoring.reason(steps[0].test, sa, s0)
    # the third step started from the pair and found nothing significant
    assert steps[-1].winner is None and len(steps) == 3


def test_a_second_effect_that_does_not_complete_the_share_ends_the_search(monkeypatch) -> None:
    s0, sa = 3.0, 2.7
    sab = math.sqrt(sa**2 - 0.01)  # barely better than the held one: not significant
    calls = _scripted(monkeypatch, {0: [("a@x", sa)], 1: [("b@y", sab)]})
    steps = search.search(_Ctx(), None, _baseline(s0))
    assert len(calls) == 2 and len(steps) == 1
    assert steps[0].winner is None and not steps[0].test["accepted"]
    assert steps[0].test["pair"]["accepted"] is False
    assert "not accepted" in scoring.reason(steps[0].test, sa, s0)


def test_an_effect_that_passes_alone_is_not_held(monkeypatch) -> None:
    s0 = 3.0
    calls = _scripted(monkeypatch, {0: [("a@x", 2.7), ("b@y", 0.61)], 1: [("c@z", 0.6)]})
    steps = search.search(_Ctx(), None, _baseline(s0))
    assert steps[0].winner is not None and steps[0].winner.label == "b@y"
    assert "pair" not in steps[0].test and calls[1] == (1, "b@y")


def test_only_a_refusal_for_the_share_alone_is_held() -> None:
    s0 = 3.0
    short = scoring.tests(2.7, s0, 1, REF)
    assert scoring.short_of_share(short)
    assert not scoring.short_of_share(scoring.tests(2.999, s0, 1, REF))  # LR not significant
    assert not scoring.short_of_share(scoring.tests(0.5, 0.52, 1, REF))  # base at the level
    assert not scoring.short_of_share(scoring.tests(0.6, s0, 1, REF))  # accepted outright
    assert not scoring.short_of_share({"accepted": False, "rule": "none", "why": "x"})
