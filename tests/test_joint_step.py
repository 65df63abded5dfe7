"""Tests of the joint step of the search (bondid.diagnose.search.joint_step): when the rule
refuses a step's best refit only for the share of the excess it removes, the next step is
taken on top of it, and the pair is accepted when the second passes the rule on top of the
first and the two together pass it against the first step's base."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from bondid.diagnose import outcome, scoring, search
from bondid.diagnose.effects import Candidate
from bondid.diagnose.job import JobResult

#: held-out noise level 1 dB on 400 independent points
REF = scoring.NoiseReference(level_db=1.0, n_eff=400.0)
CANDS = [Candidate("actuator_lag", "x", ()), Candidate("joint_compliance", "a->b:ty", ())]
#: the parameter refit's held-out score [dB]: 3x the noise level
BASE = 3.0


def _result(label: str, heldout: float, chain: tuple = ()) -> JobResult:
    r = JobResult(
        label, None, None, [], np.zeros(0), np.zeros(0), 0, heldout, heldout, 100, heldout,
        heldout, [], "<robot/>", 0.0, chain=chain,
    )  # fmt: skip
    r.n_own = 1
    return r


def _rule(score: float, before: float, z: float = 20.0) -> dict:
    """The rule's figures for one refit, as the search's decision takes them."""
    test = scoring.tests(score, before, 1, REF)
    test["strength_z"] = z
    return test


def _search(monkeypatch, first: float, second: float | None, z: float = 20.0):
    """The search with fake steps: step 1's best refit adds CANDS[0] at held-out score
    ``first`` (accepted or not by the rule against BASE); a step on top of it refits CANDS[1]
    at ``second`` (None: nothing accepted)."""
    ran: list[tuple[int, str]] = []

    def fake_step(ctx, pool, index, base, base_score, say):
        ran.append((index, base.label))
        if not base.chain:
            r = _result(CANDS[0].label, first, (CANDS[0],))
            test = _rule(first, base_score, z)
            win = r if test["accepted"] else None
            return search.Step(index, base, base_score, [], results=[r], scores=[first],
                               winner=win, test=test)  # fmt: skip
        if len(base.chain) == 1 and second is not None:
            r = _result(CANDS[1].label, second, (*base.chain, CANDS[1]))
            test = _rule(second, base_score)
            win = r if test["accepted"] else None
            return search.Step(index, base, base_score, [], results=[r], scores=[second],
                               winner=win, test=test)  # fmt: skip
        return search.Step(index, base, base_score, [], test={"accepted": False})

    monkeypatch.setattr(search, "run_step", fake_step)
    ctx = SimpleNamespace(max_effects=3, noise=REF, candidates=CANDS)
    refit = _result("refit", BASE)
    return search.search(ctx, None, refit), ran  # type: ignore[arg-type]


def test_short_of_share_is_the_rule_refused_for_the_share_alone():
    # 3.0 -> 2.9 dB: significant (LR = 400 * 0.59 = 236 > 9) but 7 % of the excess of 8
    short = _rule(2.9, BASE)
    assert not short["accepted"] and short["significant"] is False
    assert short["excess_share"] == pytest.approx(0.59 / 8.0)
    assert scoring.short_of_share(short)
    # an accepted refit, an insignificant one, an undetermined strength, a base at the level
    assert not scoring.short_of_share(_rule(1.5, BASE))
    assert not scoring.short_of_share(_rule(2.999, BASE))
    assert not scoring.short_of_share(_rule(2.9, BASE, z=scoring.Z / 2))
    assert not scoring.short_of_share(_rule(1.0, 1.05))
    lower = {**short, "gap_not_lower": True}
    assert not scoring.short_of_share(lower)


def test_a_pair_each_short_alone_is_accepted_together(monkeypatch):
    steps, ran = _search(monkeypatch, first=2.9, second=1.0)
    assert ran[:2] == [(0, "refit"), (1, CANDS[0].label)]
    assert [s.winner.label for s in steps[:2]] == [c.label for c in CANDS]
    joint = steps[0].test["joint"]
    assert steps[0].test["accepted"] and joint["with"] == CANDS[1].label
    # the pair's figures: both parameters counted, against the parameter refit
    assert joint["lr_threshold"] == pytest.approx(scoring.lr_threshold(2))
    assert joint["excess_share"] == pytest.approx((BASE**2 - 1.0) / (BASE**2 - 1.0))
    # the first effect's own share stays on record; its grade is the pair's
    assert steps[0].test["excess_share"] < scoring.MIN_EXCESS_SHARE
    assert outcome.grade(steps[0].test) == "confirmed"
    why = scoring.reason(steps[0].test, 2.9, BASE)
    assert "together they remove 100%" in why and CANDS[1].label in why
    # every candidate is taken: the search ends with the pair
    assert len(steps) == 2 and steps[1].base is steps[0].winner


def test_no_pair_when_the_second_step_accepts_nothing(monkeypatch):
    steps, ran = _search(monkeypatch, first=2.9, second=None)
    assert ran == [(0, "refit"), (1, CANDS[0].label)]
    assert len(steps) == 1 and steps[0].winner is None
    assert "joint" not in steps[0].test and not steps[0].test["accepted"]


def test_no_joint_step_when_the_refusal_is_not_for_the_share(monkeypatch):
    # an insignificant gain, or a strength the data do not determine: one step, no more
    for first, z in ((2.999, 20.0), (2.9, 1.0)):
        steps, ran = _search(monkeypatch, first=first, second=1.0, z=z)
        assert ran == [(0, "refit")] and len(steps) == 1 and steps[0].winner is None


def test_a_single_effect_that_passes_needs_no_joint_step(monkeypatch):
    steps, ran = _search(monkeypatch, first=1.5, second=1.0)
    assert steps[0].winner is not None and "joint" not in steps[0].test
    assert ran[1] == (1, CANDS[0].label)  # the ordinary next step
