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


class _Done:
    """A finished future (the fake pool runs each task at once)."""

    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


def _first_step(monkeypatch, base_heldout: float) -> tuple[search.Step, list, list]:
    """The real first step with fake screenings and refits: each candidate screens at 0.5
    (training figure); returns the step, the tasks submitted and the ``submitted`` calls."""
    from bondid.diagnose.screen import Screening

    tasks: list = []
    calls: list = []

    def fake_screen(job):
        c = job.candidate
        return Screening(c.label, c.effect, c.location, 0.3, 0.25, 0.0)

    def fake_run(job):
        return _result(job.candidate.label, 0.5, (job.candidate,))

    class Pool:
        def submit(self, fn, job):
            tasks.append(fn.__name__)
            return _Done(fn(job))

    monkeypatch.setattr(search, "screen", fake_screen)
    monkeypatch.setattr(search, "run_job", fake_run)
    monkeypatch.setattr(search, "as_completed", lambda futs: list(futs))
    monkeypatch.setattr(search, "second_round", lambda pool, used, results, say: results)
    ctx = SimpleNamespace(
        max_effects=3, noise=REF, candidates=CANDS, space=object(), nominal=SimpleNamespace(
            to_string=lambda: "<robot/>"), train=[SimpleNamespace(outputs=("x",), inputs=("x",))],
        heldout=[], full=[], options=None,
        refit_iter=30, n_starts=3, hints_hz=(), measured=(), n_refit=(4, 2), n_max=(6, 4),
        n_profile=(2, 1), n_placed=(1, 1),
    )  # fmt: skip
    base = _result("refit", base_heldout)
    step = search._step(ctx, Pool(), 0, base, base_heldout, lambda _l: None,
                        lambda i, what: calls.append((i, what)))  # fmt: skip
    return step, tasks, calls


def test_a_first_step_at_the_noise_level_screens_and_refits_nothing(monkeypatch):
    step, tasks, calls = _first_step(monkeypatch, 1.02)
    assert tasks == ["fake_screen"] * len(CANDS)  # screened, none refitted
    assert len(step.screenings) == len(CANDS) and step.refitted == [] and not step.results
    assert step.winner is None and not step.test["accepted"]
    assert step.test["screened"] is True and step.test["base_over_noise"] == 1.02
    assert "no candidate was refitted" in step.test["why"]
    # the pipeline queues the final fit when the step's refits are queued: it is told
    assert calls == [(0, "screening"), (0, "refits")]
    reason = scoring.reason(step.test, math.nan, 1.02)
    assert reason.startswith("held-out score of the base 1.020 dB:") and "nan" not in reason


def test_a_first_step_above_the_noise_level_refits_its_best(monkeypatch):
    step, tasks, _ = _first_step(monkeypatch, 3.0)
    assert tasks.count("fake_run") == len(CANDS) and len(step.results) == len(CANDS)
