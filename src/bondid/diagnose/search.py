"""The forward search for missing effects: :func:`search`, one :class:`Step` per effect.

Each step starts from a base model (the parameter refit, then the model with the effects
accepted so far) and runs three stages:

1. **screen** every open candidate (:mod:`.screen`, in parallel): its starts and the figure
   of its best one;
2. **refit** in two rounds through the one loop of :mod:`.refit_job`, at most one refit per
   worker at a time. The first round (the *probes*) refits the :attr:`Context.n_max` best
   screened candidates (or as many as the pool has workers, whichever is more) from their
   best start only: the screening's figure is a one-step prediction, and a missing spring's
   basin is often reached only by iterating, so what a start really reaches ranks the
   candidates better. The second round refits them in full (every screened start, the
   probe's end point first) in the order of the probes' training objectives. The work stops
   as soon as the step is decided: at once, in either round, when a refit passes the rule
   at the held-out noise level (no later candidate could be told from it); after at least
   :attr:`Context.n_min` full refits (all of them when a pool has that many workers) once
   the best passes the rule; after the probed candidates in any case. The step is decided
   on the refits of the best-ranked candidates only, all of them ended: refits run side by
   side end in any order, and one that ends early must not pre-empt a better-ranked one, so
   the answer is the same with one worker or many;
3. **decide** with the rule of :mod:`.scoring`: the best-scoring refit whose effect strength
   the data determine is tested against the base; it is accepted only when the base is above
   the held-out noise level, the gain is significant, it removes a good share of the excess
   over the noise, and it lowers the gap on all data.

An accepted effect becomes the next step's base (its parameters stay free in every later
refit) until nothing is accepted or :attr:`Context.max_effects` are. A best refit refused
only for the share of the excess it removes is taken as the base of one more step, and the
two are accepted together when the pair passes the rule (:func:`joint_step`). A step whose
base is already at the held-out noise level is not run (no candidate could pass the rule's
first condition), except the first, whose candidates are screened for the report.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..model.document import UrdfDocument
from . import scoring
from .decide import apply_rule, at_level_test
from .effects import Candidate
from .job import JobResult, Task
from .pool import Pool, as_completed
from .refit import Nominal
from .refit_job import run_refit
from .screen import Screening, screen
from .starts import Places, StartSpec

#: refits of a step before the rule may end it (when it is not yet at the noise level)
N_MIN = 4
#: refits of a step at most (a pool with more workers refits that many)
N_MAX = 8


@dataclass
class Context:
    """What every step of a search shares.

    Attributes:
        nominal: the nominal model; names: the nominal parameters refitted.
        train, heldout, full: the data (weights in ``coherence``).
        options: the cost options; candidates: every candidate of the chosen effects.
        space: the nominal parameters' bounds and prior.
        noise: the held-out noise reference of the rule (None: the margins' rule).
        places: where candidates' starts are placed (missing and worst-matched modes, the
            nominal origin).
        max_effects: effects accepted at most; n_min, n_max: see the module docstring.
    """

    nominal: UrdfDocument
    names: list[str]
    train: list[FrfData]
    heldout: list[FrfData]
    full: list[FrfData]
    options: CostOptions
    candidates: list[Candidate]
    space: Nominal
    noise: scoring.NoiseReference | None = None
    places: Places = field(default_factory=Places)
    max_effects: int = 3
    n_min: int = N_MIN
    n_max: int = N_MAX

    def task(self, base: JobResult, cand: Candidate | None, **kw: Any) -> Task:
        """A task on top of ``base`` (its model text and accepted effects)."""
        return Task(
            base.urdf, self.space, self.train, self.heldout, self.full, self.options,
            base.chain, cand, self.places, **kw,
        )  # fmt: skip


@dataclass
class Step:
    """One step of the search (module docstring).

    Attributes:
        index: 0 for the first step.
        base: the model the step starts from (its refit) and ``base_score`` its held-out
            score [dB].
        screenings: every open candidate's screening, in the candidates' order.
        refitted: indices into ``screenings`` of the candidates refitted, in the order
            submitted.
        results, scores: the refits, those whose effect strength the data determine best
            score first, then the others best first; the rule is taken on the first.
        winner: the accepted effect's refit, or None.
        test: the rule's figures for the best refit (:func:`.scoring.tests`).
        stopped: why no more candidates were refitted.
    """

    index: int
    base: JobResult
    base_score: float
    screenings: list[Screening]
    refitted: list[int] = field(default_factory=list)
    results: list[JobResult] = field(default_factory=list)
    scores: list[float] = field(default_factory=list)
    winner: JobResult | None = None
    test: dict[str, Any] = field(default_factory=dict)
    stopped: str = ""


Progress = Callable[[str], None]


def decide(
    ctx: Context, base: JobResult, base_score: float, results: list[JobResult]
) -> tuple[list[JobResult], list[float], dict[str, Any], JobResult | None]:
    """:func:`.decide.apply_rule` with ``ctx``'s noise reference and channels."""
    channels = (ctx.train[0].outputs, ctx.train[0].inputs)
    return apply_rule(ctx.noise, channels, base, base_score, results)


def _open(ctx: Context, base: JobResult) -> list[Candidate]:
    """Candidates not yet accepted at their place (an effect is added once per place)."""
    taken = {c.label for c in base.chain}
    return [c for c in ctx.candidates if c.label not in taken]


def _screen_all(ctx: Context, pool: Pool, index: int, base: JobResult,
                cands: list[Candidate], say: Progress) -> list[Screening]:  # fmt: skip
    futures = {pool.submit(screen, ctx.task(base, c)): i for i, c in enumerate(cands)}
    out: list[Screening | None] = [None] * len(cands)
    for f in as_completed(pool, futures):
        s = f.result()
        out[futures[f]] = s
        say(f"step {index + 1}: screened {s.label}")
    return [s for s in out if s is not None]


def _explained(ctx: Context, r: JobResult) -> bool:
    """Is ``r``'s held-out score at the held-out noise level (no candidate could be told
    from it)?"""
    if not scoring.usable(ctx.noise) or r.error:
        return False
    s = scoring.score(r.heldout_rms, r.n_train, r.n_new)
    return not scoring.above_level(s, ctx.noise)


def _submit(ctx: Context, pool: Pool, step: Step, cands: list[Candidate], i: int,
            starts: tuple[StartSpec, ...], token: int, **kw: Any) -> Any:  # fmt: skip
    task = ctx.task(step.base, cands[i], starts=starts, token=token, **kw)
    return pool.submit(run_refit, task)


def _at_level(ctx: Context, step: Step, results: list[JobResult]) -> bool:
    """Does the rule accept the best of ``results``, at the held-out noise level?"""
    winner = decide(ctx, step.base, step.base_score, results)[3]
    return winner is not None and _explained(ctx, winner)


class _Ranked:
    """Refits submitted in rank order and completed in any order: the step is decided on the
    longest prefix of the ranking that is complete, so its answer is the one a refit of the
    candidates one by one, in rank order, gives, whatever the number of workers and
    whichever refit ends first (a refit that ends early must not pre-empt a better-ranked
    one still running)."""

    def __init__(self) -> None:
        self.order: list[int] = []  # candidate indices, as submitted
        self.done: dict[int, JobResult] = {}
        self.n = 0  # the first n of ``order`` are done and have been judged

    def grow(self) -> Iterator[list[int]]:
        """Each longer complete prefix of the ranking not judged yet, shortest first."""
        while self.n < len(self.order) and self.order[self.n] in self.done:
            self.n += 1
            yield self.order[: self.n]

    def prefix(self) -> dict[int, JobResult]:
        """The judged prefix's results, in rank order."""
        return {i: self.done[i] for i in self.order[: self.n]}


def _probe(ctx: Context, pool: Pool, step: Step, cands: list[Candidate], order: list[int],
           token: int, say: Progress) -> tuple[dict[int, JobResult], str]:  # fmt: skip
    """The probes (module docstring): each candidate of ``order`` refitted from its best
    screened start only; stops once the probes up to some rank decide the step at the noise
    level (:class:`_Ranked`)."""
    lanes = max(1, pool.workers)
    ranked = _Ranked()
    running: dict[Any, int] = {}
    queue, decided = list(order), ""
    while queue or running:
        while queue and not decided and len(running) < lanes:
            i = queue.pop(0)
            starts = step.screenings[i].starts
            f = _submit(ctx, pool, step, cands, i, starts, token, probe=True, budget_starts=1)
            running[f] = i
            ranked.order.append(i)
        if not running:
            break
        f = pool.first_done(running)
        i = running.pop(f)
        r = f.result()
        if decided:  # ranked after the deciding prefix (cancelled, or ended anyway)
            continue
        ranked.done[i] = r
        say(f"step {step.index + 1}: probed {r.label}")
        for prefix in ranked.grow():
            if _at_level(ctx, step, [ranked.done[j] for j in prefix]):
                decided = "an accepted refit is at the held-out noise level"
                pool.cancel_level(token)  # the probes still running are no longer needed
                break
    probes = ranked.prefix()  # undecided: every probe ended, the prefix is all of them
    step.refitted.extend(probes)
    return probes, decided


def _refit_ranked(ctx: Context, pool: Pool, step: Step, cands: list[Candidate],
                  say: Progress) -> list[JobResult]:  # fmt: skip
    """Stage 2 of the module docstring: the probes, then the full refits in the order the
    probes reached, until the step is decided (on complete prefixes of that order, as the
    probes are: :class:`_Ranked`)."""
    scr = step.screenings
    order = sorted((i for i, s in enumerate(scr) if math.isfinite(s.cost) and s.starts),
                   key=lambda i: scr[i].cost)  # fmt: skip
    lanes = max(1, pool.workers)
    n_max = max(ctx.n_max, lanes)
    n_min = min(max(ctx.n_min, lanes), n_max)
    token = pool.token()
    probes, decided = _probe(ctx, pool, step, cands, order[:n_max], token, say)
    if decided:
        step.stopped = f"decided: {decided} (first round)"
        return list(probes.values())
    # the training objective a candidate's first start reached ranks it better than the
    # screening's one-step prediction: a missing spring's basin is seldom reached in a step
    queue = sorted(probes, key=lambda i: (bool(probes[i].error), probes[i].objective))
    ranked = _Ranked()
    running: dict[Any, int] = {}

    def results(full: dict[int, JobResult]) -> list[JobResult]:
        """The full refits ``full``, and the probes not refitted in full."""
        return [full.get(i, probes[i]) for i in probes]

    while queue or running:
        while queue and not decided and len(running) < lanes and len(ranked.order) < n_max:
            i = queue.pop(0)
            end = probes[i].end
            starts = scr[i].starts if end is None else (end, *scr[i].starts[1:])
            running[_submit(ctx, pool, step, cands, i, starts, token)] = i
            ranked.order.append(i)
        if not running:
            break
        f = pool.first_done(running)
        i = running.pop(f)
        r = f.result()
        if decided:
            continue
        ranked.done[i] = r
        say(f"step {step.index + 1}: refitted {r.label}")
        for prefix in ranked.grow():
            now = results({j: ranked.done[j] for j in prefix})
            if _at_level(ctx, step, now):
                decided = "an accepted refit is at the held-out noise level"
            elif decide(ctx, step.base, step.base_score, now)[3] is not None and (
                len(prefix) >= n_min
            ):
                decided = f"an accepted refit after {len(prefix)} full refits"
            if decided:  # the refits still running are no longer needed
                pool.cancel_level(token)
                break
    step.stopped = f"decided: {decided}" if decided else "every probed candidate refitted"
    return results(ranked.prefix())


def run_step(ctx: Context, pool: Pool, index: int, base: JobResult, base_score: float,
             say: Progress) -> Step:  # fmt: skip
    """One step (module docstring)."""
    cands = _open(ctx, base)
    step = Step(index, base, base_score, _screen_all(ctx, pool, index, base, cands, say))
    if not scoring.may_accept(base_score, ctx.noise):
        # only the first step gets here (search): no refit could be accepted
        step.test = at_level_test(base_score, ctx.noise, screened=True)
        step.stopped = "the base is at the held-out noise level"
        return step
    results = _refit_ranked(ctx, pool, step, cands, say)
    step.results, step.scores, step.test, step.winner = decide(ctx, base, base_score, results)
    return step


def search(ctx: Context, pool: Pool, baseline: JobResult,
           progress: Progress | None = None) -> list[Step]:  # fmt: skip
    """The steps from the parameter refit ``baseline`` (module docstring); the last one
    accepted nothing (unless ``max_effects`` were accepted)."""
    say = progress or (lambda _label: None)
    base = replace(baseline, chain=())
    base_score = scoring.base_score(base)
    steps: list[Step] = []
    while len(steps) < ctx.max_effects:
        index = len(steps)
        if index and not scoring.may_accept(base_score, ctx.noise):
            steps.append(Step(index, base, base_score, [],
                              test=at_level_test(base_score, ctx.noise, False)))  # fmt: skip
            break
        step = run_step(ctx, pool, index, base, base_score, say)
        steps.append(step)
        if step.winner is None:
            second = joint_step(ctx, pool, step, say)
            if second is None:
                break
            steps.append(second)
            step = second
        if step.winner is None or not _open(ctx, step.winner):
            break
        base, base_score = step.winner, step.scores[0]
    return steps


def joint_step(ctx: Context, pool: Pool, step: Step, say: Progress) -> Step | None:
    """The step after ``step`` taken on top of ``step``'s best refit when the rule refused
    that refit only for the share of the excess it removes (:func:`.scoring.short_of_share`):
    with two effects missing, each alone leaves most of the excess in place. The pair is
    accepted, ``step``'s refit as its winner (changed in place) and the returned step's as
    its own, when the second passes the rule on top of the first and the two together pass
    it against ``step``'s base (their parameters counted together); else None and ``step``
    is left as it was."""
    if not (step.results and scoring.short_of_share(step.test)):
        return None
    if len(step.base.chain) + 2 > ctx.max_effects:
        return None
    first, first_score = step.results[0], step.scores[0]
    if not _open(ctx, first):
        return None
    say(f"step {step.index + 2}: on top of {first.label}, short of the share on its own")
    second = run_step(ctx, pool, step.index + 1, first, first_score, say)
    if second.winner is None:
        return None
    pair = scoring.tests(second.scores[0], step.base_score, first.n_own + second.winner.n_own,
                         ctx.noise)  # fmt: skip
    scoring.refuse_unless_lower(pair, second.winner.db_rms, step.base.db_rms)
    if not pair.get("accepted"):
        return None
    step.winner = first
    step.test = {**step.test, "accepted": True,
                 "joint": {**pair, "with": second.winner.label}}  # fmt: skip
    return second


def accepted(steps: Sequence[Step]) -> list[JobResult]:
    """The accepted effects' refits, in order."""
    return [s.winner for s in steps if s.winner is not None]
