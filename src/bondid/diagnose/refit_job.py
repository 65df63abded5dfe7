"""One refit of a diagnosis (:func:`run_refit`, runs in a worker): a model, optionally with a
candidate effect, refitted on the training data through the optimisation core's one loop
(:func:`bondid.optim.multistart.keep_best`), then read on the held-out and the whole data.

The starts and their order:

* a candidate: the screening's starts (:mod:`.starts`: the scale scan, the mode placed at
  measured modes, the nominal origin; over the candidate and its variants, best figure
  first), each run with the held schedule (:func:`.starts.held_schedule`); then the best of
  them under the staged schedule, which frees each kind of parameter in the bands where it
  acts (when the nominal stiffnesses, dampings and inertias are bent around a new mode, a
  joint solve stays there);
* no candidate (the parameter refit): the model's values under the direct schedule, then
  the band continuation and the staged schedule (as ``bondid.fit``);
* a warm refit (the elimination's and the final fit's): the model's values, direct; then the
  nominal origin the task names (e.g. the parameter refit's values with the effects held),
  and the staged schedule.

The loop stops at the training noise level, when a restart cannot improve, or when the
task's budget is spent (:mod:`bondid.optim.multistart`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

from ..exceptions import ComputationError
from ..optim.multistart import Attempt, Budget, Outcome, Start, keep_best
from ..optim.noise import NoisePolicy
from ..optim.search import PRESOLVE_ITER, Step
from .augmented import Augmented, build, chain_of
from .effects import Candidate, get_effect
from .job import AttemptNote, JobResult, Task
from .pool import cancelled
from .refit import Refit, State
from .starts import (
    FAILURES,
    HELD_ITER,
    Places,
    StartSpec,
    candidate_starts,
    held_schedule,
    rank,
)

#: the parameter refit's band continuation: bands and IPOPT iterations per band
FALLBACK_BANDS = 4
FALLBACK_BAND_ITER = 30


def options_of(cand: Candidate | None) -> list[Candidate | None]:
    """The candidate and its variants (variants cleared), or ``[None]``."""
    from dataclasses import replace

    if cand is None:
        return [None]
    return [replace(cand, variants=()), *(replace(v, variants=()) for v in cand.variants)]


class Models:
    """The augmented models of a task, one per option of its candidate, built when first
    asked for (building one linearises the model at every operating point)."""

    def __init__(self, task: Task):
        self.task = task
        self.options = options_of(task.candidate)
        self._built: dict[int, Augmented] = {}

    def __getitem__(self, k: int) -> Augmented:
        if k and _same_model(self.options[k], self.options[0]):
            return self[0]  # a variant that only starts elsewhere: the candidate's model
        if k not in self._built:
            from ..optim.ipopt import WARM_START

            t = self.task
            # a warm refit starts near its optimum: IPOPT's small initial barrier keeps it
            # there instead of first pushing every variable to the middle of its bounds
            ipopt = dict(WARM_START) if t.warm else None
            self._built[k] = build(t.urdf, t.nominal, t.train, t.options, t.accepted,
                                   self.options[k], ipopt)  # fmt: skip
        return self._built[k]


def _same_model(a: Candidate | None, b: Candidate | None) -> bool:
    """Do options ``a`` and ``b`` build the same model (same effect, place, construction and
    parameters: they differ in where the parameters start only)?"""
    if a is None or b is None:
        return False
    return (a.effect, a.location, a.spec) == (b.effect, b.location, b.spec) and [
        (p.name, p.lower, p.upper, p.members) for p in a.parameters
    ] == [(p.name, p.lower, p.upper, p.members) for p in b.parameters]


def screening_starts(models: Models, places: Places) -> list[StartSpec]:
    """The starts of a task's candidate and its variants, in the order a refit tries them.

    The candidate's own starts (:func:`.starts.candidate_starts`) come first in line; each
    variant (the same effect at the same place, differing in a detail no fit varies, e.g. an
    elastic centre, or in where a parameter starts, e.g. a pivot's shift) gets one start,
    from the candidate's best new values when it has the same parameters (its own start
    values of the signed ones where they differ; else its own best scan start), and takes
    its place among the others by its figure, taken, as a placed start's, once the nominal
    parameters have relaxed around it. The nominal origin of the best start stays
    second (see :mod:`.starts`).
    """
    own_option = models.options[0]
    if own_option is None:
        return []
    own = candidate_starts(models[0].refit, own_option, places, 0, models.task.full)
    extra: list[StartSpec] = []
    for k, option in enumerate(models.options[1:], start=1):
        assert option is not None
        try:
            extra += _variant_start(models, k, option, own, places)
        except FAILURES:
            continue
    if not own:
        return sorted(extra, key=rank)
    lead = min([own[0], *extra], key=rank)
    second = [s for s in own[1:2] if not math.isfinite(s.figure)] if lead is own[0] else []
    taken = [lead, *second]
    rest = [s for s in [*own, *extra] if not any(s is t for t in taken)]
    rest.sort(key=rank)
    return [*taken, *rest]


def _variant_start(
    models: Models, k: int, option: Candidate, own: list[StartSpec], places: Places
) -> list[StartSpec]:
    """The one start of variant ``k`` (see :func:`screening_starts`)."""
    from .starts import NEW_ITER, spec_of

    refit = models[k].refit
    cand = models.options[0]
    assert cand is not None
    same = [p.name for p in option.parameters] == [p.name for p in cand.parameters]
    if not (same and own):
        mine = Places(places.missing, places.worst, None, places.measured)
        return candidate_starts(refit, option, mine, k, models.task.full)[:1]
    best = own[0]
    new = models[0].refit.new_values(State(best.x, best.theta))
    # a variant that starts a signed parameter elsewhere (a pivot's shift) keeps its own
    # start there; its springs take the candidate's best values, as every variant's do
    for i, (p, q) in enumerate(zip(option.parameters, cand.parameters, strict=True)):
        if p.signed and p.initial != q.initial:
            new[i] = p.initial
    state, _ = refit.solve_new(refit.with_new(refit.state0, new), NEW_ITER)
    # ranked like a placed start, once the nominal parameters have relaxed around it: from
    # the parameter refit's bent values one linearised step ranks a pivot start by how the
    # bent model happens to sit, not by the basin the start lies in
    return [
        spec_of(refit, f"{best.label}, {option.description}", state, k, relax=True, edge=best.edge)
    ]


def _starts(task: Task, models: Models) -> Iterator[Start]:
    """The loop's starts (module docstring), built when reached."""
    from ..optim.schedules import continuation, direct, staged

    if task.candidate is None:
        refit = models[0].refit
        yield Start("model values", steps=[Step("all")] if task.warm else direct(PRESOLVE_ITER),
                    payload=0)  # fmt: skip
        if task.places.nominal is not None:
            x = refit.state0.x.copy()
            x[: refit.n_nominal] = task.places.nominal
            yield Start("nominal origin", x, refit.state0.theta.copy(), direct(0), payload=0)
        if task.fallbacks:
            if not task.warm:  # a light continuation: a refit above the level usually lacks
                # an effect, which no schedule supplies; a bad basin needs only a few bands
                yield Start("band continuation", steps=lambda p: continuation(
                    p, FALLBACK_BANDS, band_iter=FALLBACK_BAND_ITER), payload=0)  # fmt: skip
            yield Start("staged schedule", steps=lambda p: staged(p, max_iter=task.max_iter),
                        payload=0)  # fmt: skip
        return
    specs = list(task.starts) or screening_starts(models, task.places)
    if task.probe:
        specs = specs[:1]
    for s in specs:
        refit = models[s.variant].refit
        yield Start(s.label, s.x, s.theta, held_schedule(refit), s.figure, payload=s.variant)
    if specs and not task.probe:
        s = specs[0]
        yield Start(f"{s.label}, staged schedule", s.x, s.theta,
                    lambda p: staged(p, max_iter=task.max_iter), payload=s.variant)  # fmt: skip


class Cancelled(ComputationError):
    """The work a refit belongs to no longer needs it (:func:`.pool.cancelled`)."""


def _watch(token: int) -> Any:
    """A per-iteration callback that ends the solve once ``token`` is cancelled (raised out
    of IPOPT, which then returns its best point as failed)."""

    def progress(_iteration: int, _cost: float) -> None:
        if cancelled(token):
            raise Cancelled("cancelled: the step no longer needs this refit")

    return progress if token else None


def _attempt(models: Models, start: Start, max_iter: int) -> Attempt:
    """Run one start on its option's refit (a numerical failure becomes a failed attempt)."""
    from ..optim.search import run_search

    t0 = time.perf_counter()
    refit = models[int(start.payload)].refit
    try:
        s0 = refit.state0
        x = s0.x if start.x is None else np.asarray(start.x, float)
        theta = s0.theta if start.theta is None else np.asarray(start.theta, float)
        state = State(x, theta)
        sub = refit.at(state)
        steps = start.steps if start.steps is not None else [Step("all")]
        schedule = list(steps(sub) if callable(steps) else steps)
        res = run_search(sub, schedule, max_iter=max_iter, ipopt_options=refit.ipopt_options(),
                         progress=_watch(models.task.token))  # fmt: skip
        end = State(res.result.fitted.copy(), refit.state_theta(res.result))
        obj, data = refit.cost(end), refit.data_cost(end)
        return Attempt(start, res, obj, data if math.isfinite(data) else math.inf,
                       res.result.iterations, time.perf_counter() - t0, x_end=end.x,
                       theta_end=end.theta)  # fmt: skip
    except FAILURES as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        return Attempt(start, None, math.inf, math.inf, 0, time.perf_counter() - t0, msg)


def refit_loop(task: Task, models: Models) -> Outcome:
    """The loop of ``task`` (module docstring)."""
    noise = NoisePolicy(models[0].refit.noise_cost)
    per_start = task.max_iter + (0 if task.candidate is None else HELD_ITER)
    return keep_best(
        _starts(task, models), lambda s, n: _attempt(models, s, n), noise=noise,
        budget=Budget(task.budget_starts * per_start), max_iter=task.max_iter,
        stop=lambda: cancelled(task.token),
    )  # fmt: skip


def run_refit(task: Task) -> JobResult:
    """Refit ``task``'s model (module docstring); never raises for a numerical failure of the
    model or the solver (``error`` set)."""
    t0 = time.perf_counter()
    if cancelled(task.token):
        return JobResult.failed(task, "cancelled", 0.0)
    try:
        models = Models(task)
        outcome = refit_loop(task, models)
        if outcome.stopped == "cancelled":
            return JobResult.failed(task, "cancelled", time.perf_counter() - t0)
        return finish(task, models, outcome, t0)
    except FAILURES as exc:
        msg = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
        if cancelled(task.token):
            msg = "cancelled"
        return JobResult.failed(task, msg, time.perf_counter() - t0)


def finish(task: Task, models: Models, outcome: Outcome, t0: float) -> JobResult:
    """The kept attempt's figures on held-out and all data, as a :class:`JobResult`."""
    from .evaluate import figures

    best = outcome.best
    k = int(best.start.payload)
    aug = models[k]
    refit: Refit = aug.refit
    option = models.options[k]
    assert best.search is not None and best.x_end is not None and best.theta_end is not None
    state = State(best.x_end, best.theta_end)
    fit, std_theta = refit.result(best.search)
    theta = refit.state_theta(fit)
    train = refit.at(state)
    r = train.residual(train.z0)[: train.n_residuals]
    held = figures(refit, fit, theta, task.heldout, task.options) if task.heldout else None
    full = figures(refit, fit, theta, task.full, task.options)
    new_vals = refit.new_values(state, own=False)
    noise = outcome.noise
    notes = tuple(AttemptNote(a.start.label + (" (resumed)" if a.resumed else ""),
                              noise.ratio_of(a.data_cost) or math.nan, a.iterations, a.error)
                  for a in outcome.attempts)  # fmt: skip
    variant = "" if k == 0 or option is None else option.description
    if option is not None:
        variant = get_effect(option.effect).detail(fit.document, option) or variant
    return JobResult(
        label="refit" if option is None else option.label,
        effect=None if option is None else option.effect,
        location=None if option is None else option.location,
        names=aug.names,
        values=np.r_[fit.fitted[: aug.n_nominal], new_vals],
        std=np.r_[fit.std[: aug.n_nominal], refit.new_std(fit, std_theta)],
        own_std=refit.own_strength_std(fit, std_theta) if option is not None else np.zeros(0),
        n_new=len(refit.new),
        train_rms=float(np.sqrt(r @ r)),
        heldout_rms=math.nan if held is None else float(np.sqrt(held.cost)),
        n_train=int(r.size),
        heldout_db_rms=math.nan if held is None else held.db_rms,
        db_rms=full.db_rms,
        full_H=full.H,
        urdf=fit.document.to_string(),
        wall_s=time.perf_counter() - t0,
        status=fit.status,
        db_rms_unweighted=full.db_rms_unweighted,
        chain=chain_of(task.accepted, option, new_vals),
        n_own=0 if option is None else len(option.parameters),
        candidate=option,
        objective=best.objective,
        noise_ratio=noise.ratio_of(best.data_cost),
        attempts=notes,
        stopped=outcome.stopped,
        variant=variant,
        end=StartSpec(_continued(best.start.label), best.x_end.copy(), best.theta_end.copy(),
                      best.objective, k),
    )  # fmt: skip


def _continued(label: str) -> str:
    """The label of a start that continues the search begun at ``label``."""
    return label if label.endswith(", continued") else f"{label}, continued"
