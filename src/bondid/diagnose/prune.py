"""Backward elimination of the accepted effects (:func:`prune`).

The search (:mod:`.search`) adds effects forward: each is tested against the model with the
effects accepted before it. An effect accepted early may only have stood in for one found
later (a rotational compliance at an interface where the translational one is the real
cause), and then keeps parameters the data no longer ask for.

Once two or more effects are accepted, each is tested again against the model with all the
others: that model is refitted (every nominal parameter and the other effects' free, warm
from the full model's values, :mod:`.refit_job`; a model the search already fitted keeps the
better of its two refits) and the rule of :func:`.scoring.tests` — the
same rule at every step — asks whether the effect still earns its parameters on held-out
data. Of the effects that fail it, the one whose removal leaves the best held-out score is
dropped, and the test repeats on the effects left until each passes or one is left. A refit
without an effect that fails keeps the effect: the elimination only ever drops what the data
show to be redundant. When a model of the kept effects cannot be refitted at the end, the
drops are not applied (the search's accepted effects stand, ``Pruning.note`` says why).

The models of the kept effects in order (the first alone, the first two, ...) give the
figures of ``effects`` in ``diagnosis.json``; those the search or the elimination did not
already fit are refitted the same way. The first kept effect is the verdict.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..model.parameters import set_parameters
from . import scoring
from .effects import Candidate
from .job import JobResult, Task
from .pool import Pool
from .refit_job import run_refit
from .search import Context, Step

Key = frozenset[str]


@dataclass
class Kept:
    """One effect the diagnosis keeps, in the order accepted.

    Attributes:
        step: index of the search step that accepted it (0 = the first).
        model: the refit of the model with the kept effects up to it.
        score, score_before: held-out scores [dB] of that model and of the one before it
            (the parameter refit for the first).
        test: the verdict rule's figures of ``score`` against ``score_before``
            (:func:`.scoring.tests`; the search step's own when nothing before it was
            dropped).
        forward: the model is the search step's own winner (nothing before it was dropped).
    """

    step: int
    model: JobResult
    score: float
    score_before: float
    test: dict[str, Any]
    forward: bool = True


@dataclass
class Dropped:
    """An accepted effect the elimination dropped.

    Attributes:
        step: index of the search step that had accepted it.
        candidate: the effect (its parameters at their fitted values in the model it left).
        round: the elimination round that dropped it (1 = the first).
        score_with, score_without: held-out scores [dB] of the model with all effects of that
            round and of the refit without this one.
        test: the verdict rule's figures of ``score_with`` against ``score_without``.
    """

    step: int
    candidate: Candidate
    round: int
    score_with: float
    score_without: float
    test: dict[str, Any]


@dataclass
class Pruning:
    """What :func:`prune` found: the effects kept (each with its model) and those dropped,
    the refits it ran and their wall time [s]."""

    kept: list[Kept] = field(default_factory=list)
    dropped: list[Dropped] = field(default_factory=list)
    n_refits: int = 0
    wall_s: float = 0.0
    #: why the elimination's drops were not applied ("" when they were, or none were found)
    note: str = ""

    @property
    def final(self) -> JobResult | None:
        """The model with every kept effect (None when none is kept)."""
        return self.kept[-1].model if self.kept else None


def _key(chain: Sequence[Candidate]) -> Key:
    return frozenset(c.label for c in chain)


def reduced_task(ctx: Context, source: JobResult, chain: Sequence[Candidate]) -> Task:
    """The warm refit of the model with the effects ``chain`` only (parameters at their
    values in ``source``), the nominal parameters at ``source``'s values, on the search's
    data (module docstring)."""
    doc = ctx.nominal.copy()
    n = len(ctx.space.names)
    set_parameters(doc, dict(zip(source.names[:n], map(float, source.values[:n]), strict=True)))
    return Task(
        doc.to_string(), ctx.space, ctx.train, ctx.heldout, ctx.full, ctx.options,
        tuple(chain), None, warm=True,
    )  # fmt: skip


def _score(r: JobResult) -> float:
    if r.error:
        return math.inf
    return scoring.score(r.heldout_rms, r.n_train, r.n_new)


class _Models:
    """The refits known so far, by the set of their effects' labels: the parameter refit,
    the search's winners, then every refit the elimination runs (in ``pool``)."""

    def __init__(self, ctx: Context, pool: Pool, steps: Sequence[Step], baseline: JobResult):
        self.ctx, self.pool, self.n_refits = ctx, pool, 0
        self.known: dict[Key, tuple[JobResult, float]] = {
            frozenset(): (baseline, steps[0].base_score if steps else _score(baseline))
        }
        for s in steps:
            if s.winner is not None:
                self.known[_key(s.winner.chain)] = (s.winner, s.scores[0])

    def ensure(
        self, source: JobResult, chains: Sequence[Sequence[Candidate]], again: bool = False
    ) -> None:
        """Refit (in parallel) every chain of ``chains`` not known yet, warm from ``source``;
        ``again``: the known ones too, keeping the better held-out score of the two (a
        model refitted without one effect, from the values the others took beside it, may
        reach a basin its own forward step did not: a pivot found only with a later
        effect's help)."""
        todo = {_key(c): c for c in chains if again or _key(c) not in self.known}
        futures = {k: self.pool.submit(run_refit, reduced_task(self.ctx, source, c))
                   for k, c in todo.items()}  # fmt: skip
        for k, f in futures.items():
            r = f.result()
            self.n_refits += 1
            if k not in self.known or _score(r) < self.known[k][1]:
                self.known[k] = (r, _score(r))

    def __getitem__(self, chain: Sequence[Candidate]) -> tuple[JobResult, float]:
        return self.known[_key(chain)]


def _step_of(steps: Sequence[Step], label: str) -> int:
    for s in steps:
        if s.winner is not None and s.winner.label == label:
            return s.index
    return -1


def _without(chain: Sequence[Candidate], i: int) -> list[Candidate]:
    return [*chain[:i], *chain[i + 1 :]]


def prune(
    ctx: Context, pool: Pool, steps: Sequence[Step], baseline: JobResult,
    progress: Callable[[str], None] | None = None,
) -> Pruning:  # fmt: skip
    """Backward elimination of the search's accepted effects (module docstring). ``pool``:
    a worker pool with ``submit``; ``baseline``: the parameter refit."""
    t0 = time.perf_counter()
    say = progress or (lambda _label: None)
    winners = [s.winner for s in steps if s.winner is not None]
    models = _Models(ctx, pool, steps, baseline)
    out = Pruning()
    if not winners:
        return out
    full = winners[-1]
    chain = list(full.chain)
    rnd = 0
    while len(chain) >= 2:
        rnd += 1
        full, s_full = models[chain]
        models.ensure(full, [_without(chain, i) for i in range(len(chain))], again=True)
        redundant = []
        for i, c in enumerate(chain):
            s_without = models[_without(chain, i)][1]
            test = scoring.tests(s_full, s_without, len(c.parameters), ctx.noise)
            # a failed refit without it (no finite score) shows nothing: the effect stays
            if math.isfinite(s_without) and not test["accepted"]:
                redundant.append((s_without, i, test))
        say(f"elimination round {rnd}: {len(redundant)} of {len(chain)} effects redundant")
        if not redundant:
            break
        s_without, i, test = min(redundant, key=lambda t: t[0])
        c = models[chain][0].chain[i]
        out.dropped.append(Dropped(_step_of(steps, c.label), c, rnd, s_full, s_without, test))
        chain = list(models[_without(chain, i)][0].chain)
    full = models[chain][0]
    chain = list(full.chain)
    models.ensure(full, [chain[: j + 1] for j in range(len(chain))])
    failed = [models[chain[: j + 1]][0].error for j in range(len(chain))]
    if out.dropped and any(failed):
        # a model of the kept effects that could not be refitted: no figures to report for
        # it, so the search's own result stands (every accepted effect kept)
        why = next(e for e in failed if e)
        out = Pruning(note=f"not applied: a refit of the kept effects failed ({why})")
        chain = list(winners[-1].chain)
    forward = True
    for j, c in enumerate(chain):
        step = _step_of(steps, c.label)
        model, score = models[chain[: j + 1]]
        before = models[chain[:j]][1]
        forward = forward and 0 <= step < len(steps) and steps[step].winner is model
        test = dict(steps[step].test) if forward else \
            scoring.tests(score, before, len(c.parameters), ctx.noise)  # fmt: skip
        out.kept.append(Kept(step, model, score, before, test, forward))
    out.n_refits = models.n_refits
    out.wall_s = time.perf_counter() - t0
    return out
