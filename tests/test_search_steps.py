"""Tests of the search's step loop (bondid.diagnose.search): a step whose base is already at
the held-out noise level is recorded, not run; a step probes its candidates in the order of
their screening figures, refits them in full in the order the probes reached, and stops as
soon as it is decided."""

from __future__ import annotations

import math
import sys
from types import SimpleNamespace

import numpy as np

from bondid.diagnose import scoring, search
from bondid.diagnose.effects import Candidate, NewParameter
from bondid.diagnose.job import JobResult
from bondid.diagnose.screen import Screening
from bondid.diagnose.starts import StartSpec

REF = scoring.NoiseReference(level_db=1.0, n_eff=400.0)
CANDS = [Candidate("sensor_delay", loc, ()) for loc in ("x", "y", "z")]


def _result(label: str, heldout: float, chain: tuple = (), cand=None) -> JobResult:
    return JobResult(
        label, None, None, [], np.zeros(0), np.zeros(0), 0, heldout, heldout, 100, heldout,
        heldout, [], "<robot/>", 0.0, chain=chain, candidate=cand,
    )  # fmt: skip


def _run(monkeypatch, scores: list[float], noise=REF) -> tuple[list, list[int]]:
    """The search with fake steps: step k accepts CANDS[k] with held-out score scores[k]."""
    ran: list[int] = []

    def fake_step(ctx, pool, index, base, base_score, say):
        ran.append(index)
        win = _result(CANDS[index].label, scores[index], (*base.chain, CANDS[index]))
        return search.Step(index, base, base_score, [], [], results=[win],
                           scores=[scores[index]], winner=win, test={"accepted": True})  # fmt: skip

    monkeypatch.setattr(search, "run_step", fake_step)
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


class _Done:
    """A finished future (the fake pool runs each task at once)."""

    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


class _Pool:
    """Runs each task at submission; ``workers`` lanes; records what was submitted and the
    cancellations."""

    def __init__(self, workers: int = 1):
        self.workers, self.tasks, self.cancelled = workers, [], []

    def submit(self, fn, task):
        self.tasks.append((fn.__name__, task.candidate.label if task.candidate else None))
        return _Done(fn(task))

    def first_done(self, futures):
        return next(iter(futures))

    def token(self):
        return 7

    def cancel_level(self, token):
        self.cancelled.append(token)


#: a candidate with a strength parameter (a delay), so the rule can test it
def _cand(loc: str) -> Candidate:
    return Candidate("sensor_delay", loc, (NewParameter("tau_s", 1e-5, 1e-7, 1e-3, "s",
                                                        strength=True),))  # fmt: skip


def _step(monkeypatch, base_heldout: float, figures: dict[str, float],
          heldout: dict[str, float], workers: int = 1, n_min: int = 2, n_max: int = 4,
          probed: dict[str, float] | None = None, first_starts: list | None = None):  # fmt: skip
    """The real step with fake screenings (figure per candidate) and refits (held-out score
    per candidate, strength determined; ``probed``: a probe's score, default the same);
    ``first_starts`` collects each refit's (candidate, probe, first start's label)."""
    cands = [_cand(loc) for loc in figures]
    first_starts = [] if first_starts is None else first_starts

    def fake_screen(task):
        c = task.candidate
        start = StartSpec("s", np.zeros(1), np.zeros(0), figures[c.location])
        return Screening(c.label, c.effect, c.location, figures[c.location], (start,), 0.0)

    def fake_refit(task):
        c = task.candidate
        # a probe reaches `probed` (default: its full refit's score); a full refit `heldout`
        score = (probed or heldout)[c.location] if task.probe else heldout[c.location]
        r = _result(c.label, score, (c,), cand=c)
        r.values, r.std, r.n_own, r.n_new = np.array([1e-5]), np.array([1e-7]), 1, 1
        r.db_rms, r.objective = score, score
        r.end = StartSpec(f"end of {c.location}", np.ones(1), np.zeros(0), score)
        first_starts.append((c.location, task.probe, task.starts[0].label))
        return r

    monkeypatch.setattr(search, "screen", fake_screen)
    monkeypatch.setattr(search, "run_refit", fake_refit)
    ctx = SimpleNamespace(
        max_effects=3, noise=REF, candidates=cands, n_min=n_min, n_max=n_max,
        train=[SimpleNamespace(outputs=("x",), inputs=("x",))],
        task=lambda base, c, **kw: SimpleNamespace(candidate=c, **{"probe": False, **kw}),
    )  # fmt: skip
    base = _result("refit", base_heldout)
    base.db_rms = base_heldout
    pool = _Pool(workers)
    step = search.run_step(ctx, pool, 0, base, base_heldout, lambda _l: None)  # type: ignore[arg-type]
    return step, pool


def test_a_first_step_at_the_noise_level_screens_and_refits_nothing(monkeypatch):
    step, pool = _step(monkeypatch, 1.02, {"x": 0.3, "y": 0.4}, {"x": 0.5, "y": 0.5})
    assert [t[0] for t in pool.tasks] == ["fake_screen"] * 2  # screened, none refitted
    assert len(step.screenings) == 2 and step.refitted == [] and not step.results
    assert step.winner is None and not step.test["accepted"]
    assert step.test["screened"] is True and step.test["base_over_noise"] == 1.02
    assert "no candidate was refitted" in step.test["why"]
    reason = scoring.reason(step.test, math.nan, 1.02)
    assert reason.startswith("held-out score of the base 1.020 dB:") and "nan" not in reason


def test_probes_follow_the_screening_order_and_stop_once_explained(monkeypatch):
    """The best-figured candidate is probed first; at the held-out noise level it decides
    the step at once, the others are not refitted."""
    figs = {"x": 0.9, "y": 0.2, "z": 0.5}
    step, pool = _step(monkeypatch, 3.0, figs, {"x": 2.9, "y": 1.0, "z": 2.9})
    refits = [label for name, label in pool.tasks if name == "fake_refit"]
    assert refits == ["sensor_delay@y"]
    assert step.winner is not None and step.winner.label == "sensor_delay@y"
    assert step.stopped == (
        "decided: an accepted refit is at the held-out noise level (first round)"
    )
    assert pool.cancelled == [7]


def test_full_refits_follow_the_probes_and_continue_from_their_end(monkeypatch):
    """A candidate the screening ranked last but whose probe reached lowest is refitted in
    full first, from the probe's end point."""
    figs = {"x": 0.2, "y": 0.3, "z": 0.4}
    probed = {"x": 2.8, "y": 2.7, "z": 1.6}
    seen: list = []
    step, _pool = _step(monkeypatch, 3.0, figs, {"x": 2.8, "y": 2.7, "z": 1.0}, n_min=3,
                       probed=probed, first_starts=seen)  # fmt: skip
    assert seen[:3] == [(k, True, "s") for k in "xyz"]  # probes: screening order, best start
    assert seen[3] == ("z", False, "end of z")  # the first full refit: the best probe's
    assert step.winner is not None and step.winner.label == "sensor_delay@z"
    assert step.stopped == "decided: an accepted refit is at the held-out noise level"


def test_an_accepted_refit_above_the_level_waits_for_n_min_full_refits(monkeypatch):
    figs = {"x": 0.2, "y": 0.3, "z": 0.4, "w": 0.5}
    held = {"x": 2.0, "y": 1.5, "z": 2.9, "w": 2.9}
    step, pool = _step(monkeypatch, 3.0, figs, held, n_min=3)
    refits = [label for name, label in pool.tasks if name == "fake_refit"]
    # four probes in the screening's order, then full refits in the probes' order
    probes = ["sensor_delay@x", "sensor_delay@y", "sensor_delay@z", "sensor_delay@w"]
    assert refits == [*probes, "sensor_delay@y", "sensor_delay@x", "sensor_delay@z"]
    # the best held-out score wins, not the best figure
    assert step.winner is not None and step.winner.label == "sensor_delay@y"
    assert step.stopped == "decided: an accepted refit after 3 full refits"


def test_an_undecided_step_probes_and_refits_at_most_n_max(monkeypatch):
    figs = {k: 0.1 * (i + 1) for i, k in enumerate("abcdef")}
    step, pool = _step(monkeypatch, 3.0, figs, dict.fromkeys(figs, 2.99), n_max=4)
    assert len([t for t in pool.tasks if t[0] == "fake_refit"]) == 2 * 4
    assert step.winner is None and step.stopped == "every probed candidate refitted"


def test_a_pool_with_more_workers_refits_that_many_at_once(monkeypatch):
    """A cluster refits every candidate at once (n_max grows to the pool's workers)."""
    figs = {k: 0.1 * (i + 1) for i, k in enumerate("abcdef")}
    step, pool = _step(monkeypatch, 3.0, figs, dict.fromkeys(figs, 2.99), workers=8,
                       n_max=4)  # fmt: skip
    assert len([t for t in pool.tasks if t[0] == "fake_refit"]) == 2 * 6
    assert step.stopped == "every probed candidate refitted"


class _ReversePool(_Pool):
    """Two lanes whose later submission ends first: a lower-ranked refit ends before the
    better-ranked one running beside it."""

    def first_done(self, futures):
        return list(futures)[-1]


def test_a_refit_that_ends_first_does_not_preempt_a_better_ranked_one(monkeypatch):
    """Both probes are at the noise level; the better-ranked x decides the step whichever
    ends first, as one worker would."""
    figs = {"x": 0.2, "y": 0.3, "z": 0.4}
    held = {"x": 1.0, "y": 0.95, "z": 2.9}
    one, _ = _step(monkeypatch, 3.0, figs, held, workers=1)
    monkeypatch.setattr(sys.modules[__name__], "_Pool", _ReversePool)
    two, pool = _step(monkeypatch, 3.0, figs, held, workers=2)
    refits = [label for name, label in pool.tasks if name == "fake_refit"]
    # y and then z (in the lane y left) end before x; x still decides, and alone
    assert refits == ["sensor_delay@x", "sensor_delay@y", "sensor_delay@z"]
    for step in (one, two):
        assert step.winner is not None and step.winner.label == "sensor_delay@x"
        assert [r.label for r in step.results] == ["sensor_delay@x"] and step.refitted == [0]
        assert step.stopped.startswith("decided: an accepted refit is at the held-out noise")


def test_full_refits_decide_on_the_ranking_whichever_ends_first(monkeypatch):
    figs = {"x": 0.2, "y": 0.3, "z": 0.4, "w": 0.5}
    held = {"x": 2.0, "y": 1.5, "z": 2.9, "w": 2.9}
    one, _ = _step(monkeypatch, 3.0, figs, held, n_min=3)
    monkeypatch.setattr(sys.modules[__name__], "_Pool", _ReversePool)
    two, _ = _step(monkeypatch, 3.0, figs, held, workers=2, n_min=3)
    for step in (one, two):
        assert step.winner is not None and step.winner.label == "sensor_delay@y"
        assert step.stopped == "decided: an accepted refit after 3 full refits"
    assert [r.label for r in two.results] == [r.label for r in one.results]
    assert two.scores == one.scores
