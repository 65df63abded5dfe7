"""Tests of the search's step loop (bondid.diagnose.search.search): a step whose base is
already at the held-out noise level is recorded, not run."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from bondid.diagnose import scoring, search
from bondid.diagnose.effects import Candidate
from bondid.diagnose.job import JobResult

REF = scoring.NoiseReference(level_db=1.0, n_eff=400.0)
CANDS = [Candidate("sensor_delay", loc, ()) for loc in ("x", "y", "z")]


def _result(label: str, heldout: float, chain: tuple = ()) -> JobResult:
    return JobResult(
        label, None, None, [], np.zeros(0), np.zeros(0), 0, heldout, heldout, 100, heldout,
        heldout, [], "<robot/>", 0.0, chain=chain,
    )  # fmt: skip


def _run(monkeypatch, scores: list[float], noise=REF) -> tuple[list, list[int]]:
    """The search with fake steps: step k accepts CANDS[k] with held-out score scores[k]."""
    ran: list[int] = []

    def fake_step(ctx, pool, index, base, base_score, say, queued):
        ran.append(index)
        win = _result(CANDS[index].label, scores[index], (*base.chain, CANDS[index]))
        return search.Step(index, base, base_score, [], [], results=[win],
                           scores=[scores[index]], winner=win, test={"accepted": True})  # fmt: skip

    monkeypatch.setattr(search, "_step", fake_step)
    ctx = SimpleNamespace(max_effects=3, noise=noise, candidates=CANDS)
    steps = search.search(ctx, None, _result("refit", 3.0))  # type: ignore[arg-type]
    return steps, ran


def test_a_step_whose_base_is_at_the_noise_level_is_not_run(monkeypatch):
    # the first effect's refit scores at the level: the second step is recorded, not run
    steps, ran = _run(monkeypatch, [1.02, 0.99, 0.98])
    assert ran == [0] and len(steps) == 2
    last = steps[1]
    assert last.winner is None and not last.screenings and not last.results
    assert not last.test["accepted"] and not last.test["base_above_noise"]
    assert last.test["base_over_noise"] == 1.02 and last.test["screened"] is False
    assert "noise level (1.020x)" in last.test["why"]
    assert last.base is steps[0].winner and last.base_score == 1.02
    # the rule itself would refuse any candidate against that base
    assert not scoring.tests(0.5, 1.02, 1, REF)["accepted"]


def test_steps_above_the_noise_level_run_as_before(monkeypatch):
    steps, ran = _run(monkeypatch, [2.0, 1.5, 0.99])
    assert ran == [0, 1, 2] and len(steps) == 3
    # without a noise reference every step may accept: all run
    steps, ran = _run(monkeypatch, [1.02, 0.99, 0.98], noise=None)
    assert ran == [0, 1, 2]


def test_the_first_step_runs_whatever_its_base(monkeypatch):
    """The first step's screenings and refits are the report's candidates, so it runs even
    when its base (the parameter refit) is at the level."""
    ran: list[int] = []

    def fake_step(ctx, pool, index, base, base_score, say, queued):
        ran.append(index)
        return search.Step(index, base, base_score, [], [])

    monkeypatch.setattr(search, "_step", fake_step)
    ctx = SimpleNamespace(max_effects=3, noise=REF, candidates=CANDS)
    steps = search.search(ctx, None, _result("refit", 0.9))  # type: ignore[arg-type]
    assert ran == [0] and len(steps) == 1 and math.isclose(steps[0].base_score, 0.9)
