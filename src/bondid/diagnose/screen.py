"""Screening: every candidate's starts and its cheap figure, before any full refit
(:func:`screen`, runs in a worker).

A full refit of a candidate costs hundreds of IPOPT iterations and most candidates of a
diagnosis explain nothing, so each is screened first from the model the search step starts
at: its starts (:func:`.refit_job.screening_starts`: the scale scan, the mode placed at the
measured modes, the nominal origin, over the candidate and its variants) with their figure,
the training objective one Levenberg–Marquardt step over every parameter predicts
(:func:`.starts.predicted_cost`). The candidate's figure is its best start's; the search
probes the best-figured candidates from their best start, then refits them in the order
the probes reached (:mod:`.search`), each from its screened starts in their order, so the
screening's work is not done again.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from .effects import Candidate
from .job import Task
from .refit_job import Models, screening_starts
from .starts import FAILURES, StartSpec, best_figure


@dataclass
class Screening:
    """The screening of one candidate.

    Attributes:
        label, effect, location: the candidate.
        cost: its figure, the best start's predicted training objective (inf when every
            start failed).
        starts: its starts in the order a refit tries them (:class:`.starts.StartSpec`).
        wall_s: time spent [s].
        error: why it failed ("" if it did not).
        variant: the option (the candidate or a variant, variants cleared) of the best start.
        noise_cost: the training objective an exact model would score on the data (NaN
            unknown); the same for every candidate of a step.
        base_cost: the objective of the step's base on the same data (NaN unknown).
    """

    label: str
    effect: str
    location: str | None
    cost: float
    starts: tuple[StartSpec, ...]
    wall_s: float
    error: str = ""
    variant: Candidate | None = None
    noise_cost: float = math.nan
    base_cost: float = math.nan

    @property
    def db(self) -> float | None:
        """The figure as a weighted RMS [dB] (None when not finite)."""
        return math.sqrt(self.cost) if math.isfinite(self.cost) and self.cost >= 0 else None


def screen(task: Task) -> Screening:
    """Screen ``task``'s candidate (module docstring); never raises for a numerical failure
    (``cost = inf``, ``error`` set)."""
    t0 = time.perf_counter()
    cand = task.candidate
    assert cand is not None
    models = Models(task)
    starts: list[StartSpec] = []
    error = ""
    noise = base = math.nan
    try:
        refit = models[0].refit
        nc = refit.noise_cost
        noise = float(nc) if nc is not None and math.isfinite(nc) else math.nan
        base = refit.cost(refit.state0)
        starts = screening_starts(models, task.places)
    except FAILURES as exc:
        error = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
    figure = best_figure(starts)
    if not starts and not error:
        error = "every start failed"
    best = min((s for s in starts if math.isfinite(s.figure)), key=lambda s: s.figure,
               default=None)  # fmt: skip
    variant = None if best is None else models.options[best.variant]
    return Screening(
        cand.label, cand.effect, cand.location, figure, tuple(starts),
        time.perf_counter() - t0, error, variant, noise, base,
    )  # fmt: skip
