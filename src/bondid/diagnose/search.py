"""The search for missing effects, one step at a time (:func:`search`).

A step starts from a *base* model — the parameter refit, then the model with the effects
accepted so far — and

1. screens every candidate not yet accepted (:func:`.screen.screen`: a cheap training-cost
   figure each, in worker processes);
2. refits the best :attr:`Context.n_refit` of them fully (more, up to :attr:`Context.n_max`,
   when the best figure leaves the step well above the noise level and others tie with the
   last kept: :func:`.screen.select`), and the best :attr:`Context.n_profile` by the joint
   profile (:mod:`.joint_profile`, from its start: :func:`.screen.profile_picks`) and the
   best :attr:`Context.n_placed` by the placed alternation of a candidate with springs
   (from its end: :func:`.screen.placed_picks`)
   (:func:`.runner.run_job`: every nominal, accepted and new parameter together, from the
   base and from the nominal model), then gives the best of them that ended above the noise
   level the wider search in a second round (:func:`.widen.second_round`); the modal step of
   a stuck candidate with several springs (:mod:`.modal_start`, minutes per refit) runs only
   for the :data:`MODAL_TOP` best candidates of the screening (:func:`modal_ranked`);
3. scores them on held-out data (:mod:`.scoring`) and accepts the best whose effect
   strength the data determine (:func:`.scoring.determined`) only under the verdict rule of
   :func:`.scoring.accept` (the base above the held-out noise level, the improvement
   significant given that noise; the same rule at every step).

The search stops at the first step that accepts nothing, or after
:attr:`Context.max_effects` accepted effects. A step after the first whose base is already at
the held-out noise level is not run: no candidate can pass the rule's first condition there
(:func:`.scoring.may_accept`), so it is recorded as a step that accepted nothing, without
screenings (:func:`at_level_step`). The first step, whose candidates are the report's, is
screened whatever its base, but when the parameter refit is at that level none is refitted
(:func:`at_level_test`): the screening's one-step figures stand for them, and the final fit
starts at once. The first accepted effect is the verdict; the list of
accepted effects, each with the gap after it, is ``effects`` in ``diagnosis.json``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from concurrent.futures import as_completed
from dataclasses import dataclass, field, replace
from typing import Any

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..model.document import UrdfDocument
from . import scoring
from .effects import Candidate
from .job import Job, JobResult
from .parsimony import prefer_simpler
from .refit import Nominal
from .rescue import above_heldout_level
from .runner import run_job
from .screen import Screening, placed_picks, profile_picks, screen, select
from .widen import second_round

#: the candidates of a step, best by the screening's one-step figure and by its joint profile,
#: whose stuck refit may get the modal step. Measured over the kept outputs of stops 20–23
#: (60 refits of soft mounts or a flexible base): every one that was the withheld effect and
#: was refitted ranked first by the one-step figure or was a joint-profile pick (bonder/fb/
#: harsh), while the modal step also ran on candidates ranked 9th to 17th (gantry/sm/acc's
#: flexible base, 150 s; bonder_b/sd/nocoh's soft mounts in step 2, 393 s of a 592 s
#: diagnosis), never kept there.
MODAL_TOP = 2


@dataclass
class Context:
    """What every step of a search shares (data, options, the nominal model)."""

    nominal: UrdfDocument
    names: list[str]
    train: list[FrfData]
    heldout: list[FrfData]
    full: list[FrfData]
    options: CostOptions
    candidates: list[Candidate]
    hints_hz: tuple[float, ...] = ()
    refit_iter: int = 30
    n_starts: int = 3
    #: candidates refitted fully at the first step and at the later ones
    n_refit: tuple[int, int] = (4, 2)
    max_effects: int = 3
    #: the nominal parameters of every refit (names, bounds, prior); default: from
    #: ``nominal`` and ``names`` (:func:`.refit.nominal_space_for`)
    space: Nominal | None = None
    #: most candidates refitted at the first and at the later steps when the screening's
    #: figures tie (:func:`.screen.select`)
    n_max: tuple[int, int] = (6, 4)
    #: the held-out data's noise reference of the verdict rule (default: from ``heldout``)
    noise: scoring.NoiseReference | None = None
    #: candidates refitted (from its start) by the screening's joint profile at the first
    #: and at the later steps, on top of those :func:`.screen.select` keeps
    n_profile: tuple[int, int] = (2, 1)
    #: candidates refitted (from its end) by the screening's placed alternation
    #: (:func:`.screen.placed_picks`) at the first and at the later steps
    n_placed: tuple[int, int] = (1, 1)
    #: the modes identified in each full data set (:mod:`.modal_id`; empty: identified
    #: where a job needs them)
    measured: tuple = ()

    def __post_init__(self) -> None:
        if self.space is None:
            from .refit import nominal_space_for

            self.space = nominal_space_for(self.nominal, self.names, self.train)
        if self.noise is None:
            self.noise = scoring.heldout_noise(self.heldout, self.options)


@dataclass
class Step:
    """One step of the search (module docstring).

    Attributes:
        index: 0 for the first step.
        base: the model the step starts from (its refit result) and ``base_score`` its
            held-out score.
        screenings: every candidate's screening, in the order screened.
        refitted: indices into ``screenings`` of the candidates refitted fully.
        by_profile: those of them the joint profile picked (:func:`.screen.profile_picks`),
            refitted from its start.
        by_placed: those the placed alternation picked (:func:`.screen.placed_picks`),
            refitted from its end.
        results, scores: the full refits: those whose effect strength the data determine
            (:func:`.scoring.determined`) best score first, then the others best first; the
            verdict's test is taken on the first.
        winner: the accepted effect's refit, or None.
        test: the verdict rule's figures for the best refit (:func:`.scoring.tests`).
    """

    index: int
    base: JobResult
    base_score: float
    screenings: list[Screening]
    refitted: list[int]
    by_profile: list[int] = field(default_factory=list)
    by_placed: list[int] = field(default_factory=list)
    results: list[JobResult] = field(default_factory=list)
    scores: list[float] = field(default_factory=list)
    winner: JobResult | None = None
    test: dict[str, Any] = field(default_factory=dict)


Progress = Callable[[str], None]
#: ``submitted(step index, "screening" | "refits")``: a step's jobs are queued
Submitted = Callable[[int, str], None]


def _job(
    ctx: Context, base: JobResult, cand: Candidate | None, start: tuple[float, ...] = (),
    alt: bool = True, modal: bool = True,
) -> Job:  # fmt: skip
    """A job on top of ``base`` (its model text, values and accepted effects); ``alt``: with
    the nominal model as second origin. Without the wider search: the step runs it in its
    second round (:mod:`.widen`). The screening profiles every candidate when ``base`` is
    above the held-out noise level (:func:`.rescue.above_heldout_level`)."""
    assert ctx.space is not None
    level = ctx.noise.level_db if ctx.noise is not None else float("nan")
    return Job(
        base.urdf, ctx.space, ctx.train, ctx.heldout, ctx.full, cand, ctx.options,
        all_iter=ctx.refit_iter, n_starts=ctx.n_starts,
        alt_urdf=ctx.nominal.to_string() if alt else None, hints_hz=ctx.hints_hz,
        accepted=base.chain, start_new=start, wider=False,
        heldout_noise_db=level, profile_always=above_heldout_level(base.heldout_rms, level),
        modal=modal, measured=ctx.measured,
    )  # fmt: skip


def refit_indices(*orders: Sequence[int]) -> list[int]:
    """The candidates a step refits: those of every order (the figure's selection, the
    joint profile's picks, the placed alternation's), in turn, each once (a candidate picked
    twice is refitted once: two refits of one label would be two results for one
    candidate)."""
    return list(dict.fromkeys(i for o in orders for i in o))


def modal_ranked(screenings: Sequence[Screening], picks: Sequence[int]) -> set[int]:
    """Indices of the candidates whose stuck refit may get the modal step (``Job.modal``):
    the :data:`MODAL_TOP` best by the screening's one-step figure and the first
    :data:`MODAL_TOP` joint-profile picks (``picks``, best first)."""
    order = sorted((i for i, s in enumerate(screenings) if math.isfinite(s.cost)),
                   key=lambda i: screenings[i].cost)  # fmt: skip
    return {*order[:MODAL_TOP], *picks[:MODAL_TOP]}


def _open(ctx: Context, base: JobResult) -> list[Candidate]:
    """Candidates not yet accepted at their location (an effect is added once per place)."""
    taken = {c.label for c in base.chain}
    return [c for c in ctx.candidates if c.label not in taken]


def _refit_candidate(s: Screening, cand: Candidate) -> Candidate:
    """What a full refit tries: the variant the screening kept (the variants of a candidate
    differ in a detail the refit does not vary, e.g. a pivot), else the candidate."""
    return s.variant if s.variant is not None else cand


def verdict_order(results: Sequence[JobResult], scores: Sequence[float]) -> list[int]:
    """Indices of ``results`` (held-out ``scores`` [dB], same order) as a step lists them: the
    refits whose effect strength the data determine (:func:`.scoring.determined`) best score
    first, then the others best first. The verdict's test is taken on the first."""
    ranked = scoring.rank(scores)
    order = [i for i in ranked if scoring.determined(results[i])]
    return order + [i for i in ranked if i not in order]


def _step(
    ctx: Context, pool: Any, index: int, base: JobResult, base_score: float, progress: Progress,
    submitted: Submitted,
) -> Step:  # fmt: skip
    cands = _open(ctx, base)
    # later steps screen from their base alone: it is the first effect's refit, which the
    # full refits also ran from the nominal model
    futures = {pool.submit(screen, _job(ctx, base, c, alt=index == 0)): i
               for i, c in enumerate(cands)}  # fmt: skip
    submitted(index, "screening")
    screenings: list[Screening | None] = [None] * len(cands)
    for f in as_completed(futures):
        s = f.result()
        screenings[futures[f]] = s
        progress(f"step {index + 1} screened {s.label}")
    done = [s for s in screenings if s is not None]
    assert len(done) == len(cands)  # done[i] is the screening of cands[i]
    if not scoring.may_accept(base_score, ctx.noise):
        # only the first step gets here (search): its base, the parameter refit, is at the
        # held-out noise level, so no refit could be accepted; the screenings are the report
        step = Step(index, base, base_score, done, [])
        step.test = at_level_test(base_score, ctx.noise, screened=True)
        submitted(index, "refits")
        return step
    later = 0 if index == 0 else 1
    picks = profile_picks(done, ctx.n_profile[later])
    placed = placed_picks(done, ctx.n_placed[later])
    chosen = refit_indices(select(done, ctx.n_refit[later], ctx.n_max[later]), picks, placed)
    step = Step(index, base, base_score, done, chosen, picks, placed)
    modal_ok = modal_ranked(done, picks) | set(placed)
    jobs = {i: _job(ctx, base, _refit_candidate(done[i], cands[i]),
                    done[i].refit_start(i in picks, i in placed), modal=i in modal_ok)
            for i in chosen}  # fmt: skip
    futs = {pool.submit(run_job, jobs[i]): i for i in chosen}
    submitted(index, "refits")
    results, used = [], []
    for f in as_completed(futs):
        r = f.result()
        if cands[futs[f]].variants and done[futs[f]].variant is not None:
            r.extra.setdefault("variant", done[futs[f]].variant.description)  # type: ignore[union-attr]
        results.append(r)
        used.append(jobs[futs[f]])
        progress(f"step {index + 1} refitted {r.label}")
    results = second_round(pool, used, results,
                           lambda label: progress(f"step {index + 1} widened {label}"))  # fmt: skip
    scores = [scoring.score(r.heldout_rms, r.n_train, r.n_new) for r in results]
    order, displaced = prefer_simpler(
        results,
        scores,
        verdict_order(results, scores),
        ctx.noise,
        ctx.train[0].outputs,
        ctx.train[0].inputs,
    )
    step.results = [results[i] for i in order]
    step.scores = [scores[i] for i in order]
    if not step.results:
        return step
    best = step.results[0]
    z = scoring.strength_z(best)
    if z < scoring.Z:  # verdict_order put the determined refits first: none is
        why = "no refit determines its effect's strength (value/std < z)"
        step.test = {"accepted": False, "rule": "none", "why": why}
    else:
        # p of the test: this step's own candidate parameters (best.n_new also counts the
        # effects accepted before, already in the base)
        step.test = scoring.tests(step.scores[0], base_score, best.n_own, ctx.noise)
        scoring.refuse_unless_lower(step.test, best.db_rms, base.db_rms)
        if displaced is not None:  # the simpler equivalent modifier (parsimony.py)
            d = results[displaced]
            step.test["preferred_over"] = {
                "effect": d.effect,
                "location": d.location,
                "score": scores[displaced],
                "n_parameters": d.n_own,
            }
        if step.test["accepted"]:
            step.winner = best
    step.test["strength_z"] = z
    return step


def search(
    ctx: Context, pool: Any, baseline: JobResult, progress: Progress | None = None,
    submitted: Submitted | None = None,
) -> list[Step]:  # fmt: skip
    """Steps of the search from the parameter refit ``baseline`` (module docstring); the
    last step is the one that accepted nothing (unless ``max_effects`` were accepted).
    ``submitted(step index, "screening" | "refits")`` is called once a step's screenings,
    then its full refits, are queued in ``pool`` (e.g. to queue more work behind them)."""
    say = progress or (lambda _label: None)
    queued = submitted or (lambda _index, _what: None)
    base = replace(baseline, chain=())
    base_score = scoring.base_score(base)
    steps: list[Step] = []
    for index in range(ctx.max_effects):
        if index and not scoring.may_accept(base_score, ctx.noise):
            steps.append(at_level_step(index, base, base_score, ctx.noise))
            break
        step = _step(ctx, pool, index, base, base_score, say, queued)
        steps.append(step)
        if step.winner is None or not _open(ctx, step.winner):
            break
        base, base_score = step.winner, step.scores[0]
    return steps


def at_level_step(
    index: int, base: JobResult, base_score: float, noise: scoring.NoiseReference | None
) -> Step:
    """The record of a step not run because its base (held-out score ``base_score`` [dB]) is
    at the noise level of ``noise`` (module docstring): nothing screened or refitted, the
    test refused with the reason."""
    return Step(index, base, base_score, [], [], test=at_level_test(base_score, noise, False))


def at_level_test(
    base_score: float, noise: scoring.NoiseReference | None, screened: bool
) -> dict[str, Any]:
    """The refused test of a step whose base (held-out score ``base_score`` [dB]) is at the
    noise level of ``noise``: nothing refitted, and ``screened`` says whether the candidates
    were screened (the first step's are, for the report; a later step is not run at all)."""
    ratio = base_score / noise.level_db if scoring.usable(noise) else math.nan
    done = ("so no candidate was refitted (the screening's figures are reported)"
            if screened else "so the step was not run")  # fmt: skip
    why = (f"the base is at the held-out noise level ({ratio:.3f}x): no candidate can pass "
           f"the rule's first condition, {done}")  # fmt: skip
    return {"accepted": False, "rule": "none", "why": why, "screened": screened,
            "base_over_noise": ratio, "base_above_noise": False}  # fmt: skip


def accepted(steps: Sequence[Step]) -> list[JobResult]:
    """The accepted effects' refits, in order."""
    return [s.winner for s in steps if s.winner is not None]
