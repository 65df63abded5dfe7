"""The wider search as the second round of a search step (:mod:`bondid.diagnose.widen`): it
runs only for the best TOP_K refits that ended above the noise level, and keeps the lower
training objective of the first round and of its own refits."""

from __future__ import annotations

from concurrent.futures import Future
from dataclasses import replace

import numpy as np
import pytest
from test_diagnose_wider import _exact_cost, _job, compliance, doc  # noqa: F401

from bondid.diagnose.rescue import RESCUE_RATIO
from bondid.diagnose.runner import Job


class RecordingPool:
    """A pool that records what it is given and returns each second-round job's first-round
    result with a mark (the selection is under test here, not the refits)."""

    def __init__(self) -> None:
        self.submitted: list = []

    def submit(self, fn, w):  # type: ignore[no-untyped-def]
        self.submitted.append(w)
        fut: Future = Future()
        fut.set_result(replace(w.first, extra={**w.first.extra, "wider": "ran"}))
        return fut


def _result(label: str, heldout_rms: float, ratio: float | None, cand, error: str = ""):  # type: ignore[no-untyped-def]
    from bondid.diagnose.runner import JobResult

    return JobResult(
        label, "effect", label, [], np.zeros(1), np.zeros(1), 1, 1.0, heldout_rms, 100,
        heldout_rms, heldout_rms, [], "", 1.0, error=error, candidate=cand,
        objective=1.0, noise_ratio=ratio,
    )  # fmt: skip


def test_second_round_runs_for_the_best_refits_above_the_noise_level(doc, compliance):  # noqa: F811
    """Six refits, ranked by held-out score: the best (at the noise level) is left alone; of
    those above it only the ones ranked within TOP_K = 2 are submitted (rank 2), the others
    say their rank; a failed refit is left alone; the results keep their order."""
    from bondid.diagnose.widen import second_round

    c, exact, data = compliance
    above, at = 2.0 * RESCUE_RATIO, 0.9 * RESCUE_RATIO
    rows = [("d", 4.0, above), ("a", 1.0, at), ("c", 3.0, above), ("b", 2.0, above),
            ("e", 5.0, None), ("f", 6.0, above)]  # fmt: skip
    results = [_result(lab, h, r, c) for lab, h, r in rows]
    results.append(_result("g", np.inf, above, c, error="ValueError: x"))  # last, as failed
    jobs = [replace(_job(doc, c, data, exact), wider=False, start_new=(float(k),))
            for k in range(len(results))]  # fmt: skip
    pool = RecordingPool()
    out = second_round(pool, jobs, results, top_k=2)
    assert [w.first.label for w in pool.submitted] == ["b"]
    assert pool.submitted[0].job.wider and pool.submitted[0].job.start_new == (3.0,)
    notes = {r.label: r.extra.get("wider") for r in out}
    assert notes == {"d": "not run: ranked 4 of 7 after the first round", "a": None,
                     "c": "not run: ranked 3 of 7 after the first round", "b": "ran",
                     "e": None, "f": "not run: ranked 6 of 7 after the first round",
                     "g": None}  # fmt: skip
    assert [r.label for r in out] == [lab for lab, _, _ in rows] + ["g"]


@pytest.fixture(scope="module")
def first_round(doc, compliance):  # type: ignore[no-untyped-def]  # noqa: F811
    """The first round's refit of the compliance started with its mode out of the band (the
    screening's start 40x the exact stiffness, the damping 1000x too low), as it ends without
    its rescue: above the noise level (with the rescue it reaches the level by itself since
    stop 51's weights, 0.88x; 1.95x before, and nothing would be left for a second round).
    Its second origin gets 3 iterations (``alt_iter``), the second round's the default. No
    modal step (``modal=False``: a candidate the search's screening did not rank among its
    best): its restarts from the measured modes reach the exact model's objective on this
    small problem in the first round on some machines, and then no second round can improve
    on it (measured on an AMD EPYC: 4.642 against the exact model's 4.649)."""
    from bondid.diagnose.runner import run_job

    c, exact, data = compliance
    start = exact * np.array([40.0, 1e-3])
    job = replace(_job(doc, c, data, start), wider=False, alt_iter=3, modal=False)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(
            "bondid.diagnose.runner.rescue", lambda refit, state, res, *a, **k: (state, res, "")
        )
        first = run_job(job)
    return replace(job, alt_iter=Job.alt_iter), first


def test_first_round_ends_above_the_noise_level_without_a_wider_note(first_round):
    from bondid.diagnose.widen import needs_wider

    _, first = first_round

    assert not first.error and needs_wider(first), first.noise_ratio
    assert "wider" not in first.extra and first.candidate is not None


def test_second_round_keeps_its_refit_when_lower(doc, compliance, first_round):  # noqa: F811
    """Known answer: the own scans reach the exact model's objective (within 1.3x); the
    second round keeps them (lower objective than the first round's), with a note."""
    from bondid.diagnose.widen import Widen, run_widen

    c, exact, data = compliance
    job, first = first_round
    out = run_widen(Widen(replace(job, candidate=first.candidate, wider=True), first))
    c_exact = _exact_cost(doc, c, data, exact)
    assert out.objective < first.objective
    assert out.objective < 1.3 * c_exact, (out.objective, c_exact)
    assert out.extra["wider"].startswith("own scans to") and ", kept" in out.extra["wider"]
    assert out.heldout_rms < first.heldout_rms  # re-evaluated


def test_second_round_keeps_the_first_round_when_it_is_lower(first_round):
    """The same second round against a first round given an objective below anything a refit
    reaches (0): nothing is kept, the first round's result is returned with the note."""
    from bondid.diagnose.widen import Widen, run_widen

    job, first = first_round
    low = replace(first, objective=0.0)
    out = run_widen(Widen(replace(job, candidate=first.candidate, wider=True), low))
    assert out.objective == 0.0 and np.array_equal(out.values, first.values)
    assert out.heldout_rms == first.heldout_rms and out.urdf == first.urdf
    assert "kept" in out.extra["wider"] and ", kept" not in out.extra["wider"]
    assert out.extra["wider"].count("not kept") == 2  # both its refits ran, neither kept


def test_a_refit_at_the_training_noise_level_is_widened_when_its_heldout_figure_is_not(
    compliance,  # noqa: F811
):
    """needs_wider: a refit at the training noise level is stuck when its held-out figure
    is above RESCUE_RATIO times the held-out noise level, not below it, nor without a level;
    a failed refit never."""
    from bondid.diagnose.widen import needs_wider

    c = compliance[0]
    at = 0.9 * RESCUE_RATIO
    level = 1.0
    assert needs_wider(_result("x", 1.1 * RESCUE_RATIO * level, at, c), level)
    assert not needs_wider(_result("y", 0.9 * RESCUE_RATIO * level, at, c), level)
    assert not needs_wider(_result("z", 1.1 * RESCUE_RATIO * level, at, c))  # no level
    assert not needs_wider(_result("w", 5.0, at, c, error="ValueError: x"), level)
