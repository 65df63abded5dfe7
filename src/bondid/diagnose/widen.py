"""The wider search as a second round of a search step (:func:`second_round`, for
:mod:`.search`).

The first round refits every chosen candidate without the wider search (``Job.wider`` False:
the fit of both origins, the alternatives of :mod:`.alternatives`, the rescue). A refit that is
stuck (:func:`needs_wider`: above the noise level on the training data, the test of
:func:`.rescue.above_noise`, or on the held-out data, as :func:`.alternatives.stuck`) and ranks
among the best :data:`TOP_K` of the step by held-out score (:func:`.scoring.score`, ranked as
the step ranks) could still decide the step: it gets the wider search from its first-round
result (:func:`run_widen`): the refit with its own scans (the screening's start dropped), then,
if still above the noise level on the training data (only there has it something to find), the
band continuation from the nominal model with the new parameters at their best values so far;
the lower training objective of the first round and of each of these is kept, unless it is
bought with a worse held-out figure (:mod:`.keep`). When the first
round's refit stays, the result is the first round's (its note added); otherwise the kept refit
gets the rescue (the staged schedule alone after the continuation from the nominal model, as in
a job that runs the wider search itself) and is evaluated again.

The refits ranked below :data:`TOP_K` are left as the first round ended them, their note
``wider`` says so: in the kept outputs of stop 15's benchmark (40 refits) the wider search
ran on most refits and changed one verdict, the top refit's, while it raised the median
diagnosis time of those 12 cases from 179 s to 263 s.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from concurrent.futures import as_completed
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..exceptions import BondidError
from . import scoring
from .alternatives import _SKIPPED, NOMINAL_LABEL, kept_note, nominal_continuation
from .augmented import Augmented
from .job import Job, JobResult
from .keep import held_of, known, replaces
from .refit import State
from .rescue import above_heldout_level, above_ratio, noise_ratio_at
from .runner import _fit, finish

#: refits of a step (best held-out score first) that may get the wider search
TOP_K = 2


@dataclass
class Widen:
    """A second-round job: ``job`` (the first round's, with the candidate as refitted and
    ``wider`` True) and ``first``, its first-round result."""

    job: Job
    first: JobResult


def needs_wider(r: JobResult, heldout_noise_db: float = float("nan")) -> bool:
    """Is the first-round refit of a candidate (no failure) stuck (:func:`.alternatives.
    stuck`): above the noise level on its training data, or above :data:`.rescue.
    RESCUE_RATIO` times the held-out noise level ``heldout_noise_db`` [dB] on the held-out
    data?"""
    if r.error or r.candidate is None:
        return False
    return above_ratio(r.noise_ratio) or above_heldout_level(r.heldout_rms, heldout_noise_db)


def second_round(
    pool: Any, jobs: Sequence[Job], results: Sequence[JobResult],
    say: Callable[[str], None] | None = None, top_k: int = TOP_K,
) -> list[JobResult]:  # fmt: skip
    """The step's refits after the second round (module docstring), in the order of
    ``results`` (``jobs[i]``: the first-round job of ``results[i]``); ``pool.submit`` runs
    :func:`run_widen`; ``say`` is told each refit's label as its second round ends."""
    scores = [scoring.score(r.heldout_rms, r.n_train, r.n_new) for r in results]
    out = list(results)
    futs = {}
    for k, i in enumerate(scoring.rank(scores)):
        r = results[i]
        if not needs_wider(r, jobs[i].heldout_noise_db):
            continue
        if k < top_k:
            job = replace(jobs[i], candidate=r.candidate, wider=True)
            futs[pool.submit(run_widen, Widen(job, r))] = i
        else:
            why = f"not run: ranked {k + 1} of {len(results)} after the first round"
            out[i] = replace(r, extra={**r.extra, "wider": why})
    for f in as_completed(futs):
        out[futs[f]] = f.result()
        if say is not None:
            say(out[futs[f]].label)
    return out


def run_widen(w: Widen) -> JobResult:
    """The second round of one refit (module docstring); a numerical failure leaves the
    first round's result (the note says so)."""
    t0 = time.perf_counter()
    try:
        return _widen(w, t0)
    except (BondidError, np.linalg.LinAlgError, ValueError) as exc:
        return _first(w.first, f"failed ({type(exc).__name__})", t0)


def _first(first: JobResult, note: str, t0: float) -> JobResult:
    """The first round's result with the wider search's ``note`` and its time added."""
    extra = {**first.extra, "wider": note}
    return replace(first, extra=extra, wall_s=first.wall_s + time.perf_counter() - t0)


def _widen(w: Widen, t0: float) -> JobResult:
    job, first = w.job, w.first
    best: tuple[Augmented, State, Any] | None = None
    cost, ratio = first.objective, first.noise_ratio
    notes: list[str] = []

    held = known(first.heldout_rms)

    def compare(label: str, aug: Augmented, state: State, res: Any) -> None:
        """Keep ``state`` when :func:`.keep.replaces` says so (the note of ``_lower``)."""
        nonlocal best, cost, ratio, held
        c2, r2 = aug.refit.cost(state), noise_ratio_at(aug.refit, state)
        held2 = held_of(job, aug, res)
        kept = replaces(job, cost, held, c2, held2)
        notes.append(kept_note(label, r2, kept, c2 < cost))
        if kept:
            best, cost, ratio, held = (aug, state, res), c2, r2, held2

    if job.start_new:
        try:
            compare("own scans", *_fit(replace(job, start_new=())))
        except _SKIPPED as exc:
            notes.append(f"own scans failed ({type(exc).__name__})")
    if above_ratio(ratio) and job.alt_urdf is not None:
        if best is None:
            new = first.values[len(first.values) - first.n_own :]
        else:
            new = best[0].refit.new_values(best[1])
        try:
            compare(NOMINAL_LABEL, *nominal_continuation(job, new))
        except _SKIPPED as exc:
            notes.append(f"{NOMINAL_LABEL} failed ({type(exc).__name__})")
    note = "; ".join(notes)
    if best is None:
        return _first(first, note, t0)
    # the first round's rescue note is of the refit that lost; the kept one gets its own
    extra = {k: v for k, v in first.extra.items() if k != "rescue"}
    extra["wider"] = note
    r = finish(job, *best, extra, t0, continuation=job.alt_urdf is None)
    return replace(r, wall_s=first.wall_s + r.wall_s)
