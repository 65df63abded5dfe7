"""The final fit (:func:`start_final`): the diagnosis's final model refitted on all its data.

The search decides on held-out data: every refit is fitted to the training points and
scored on the others, and its verdict, scores and ``db_rms_after`` figures stay those. The
model a user takes away is the final one — the parameter refit with every kept effect, or
the parameter refit alone — and it should rest on all the data: a mode that the training
bands do not pin may stay off the measured one. The final fit refits it on every point of
every data set through the loop of :mod:`.refit_job` (warm from the model's values; then
the nominal parameters restarted at the parameter refit's values with the effects held,
which undoes nominal parameters an effect's refit bent on the way; then the staged
schedule), stopped at the noise level of all the data. It is kept when its weighted gap on
all data is lower than the final model's. It changes no verdict and no figure of the search;
its held-out figure is in-sample and is not reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

from .job import JobResult, Task
from .refit_job import run_refit
from .starts import Places


@dataclass
class FinalFit:
    """The final model refitted on all data.

    Attributes:
        source: the final model as the search left it (the refit with every kept effect, or
            the parameter refit).
        model: the final fit when kept (the source's label, effect and chain, refitted
            values, model text and figures), else ``source``.
        kept: whether the final fit lowered the weighted gap on all data.
        note: what the fit did, one line (figures in dB).
        starts: the starts it tried and why it stopped ("" for one start).
    """

    source: JobResult
    model: JobResult
    kept: bool
    note: str
    starts: str = ""


def final_task(source: JobResult, base: Task, restart: JobResult | None) -> Task:
    """The task refitting ``source`` (its model and effects, no new candidate) on all the data
    of ``base``; ``restart``: the parameter refit, whose nominal values are the loop's second
    start (None, or ``source`` itself: no such start)."""
    n = len(base.nominal.names)
    nominal = None
    if restart is not None and restart is not source and len(restart.values) >= n:
        nominal = restart.values[:n].copy()
    return replace(
        base, urdf=source.urdf, train=list(base.full), heldout=[], candidate=None,
        accepted=source.chain, places=Places(nominal=nominal), starts=(), warm=True,
        fallbacks=True,
    )  # fmt: skip


def judged(source: JobResult, result: JobResult) -> FinalFit:
    """The :class:`FinalFit` of ``source`` given the final task's ``result`` (kept when its
    weighted gap on all data is lower)."""
    if result.error or list(result.names) != list(source.names):
        why = result.error or "the final fit has other parameters"
        return FinalFit(source, source, False, f"not kept: {why}")
    keep = bool(math.isfinite(result.db_rms) and result.db_rms < source.db_rms)
    note = f"all data: weighted gap {source.db_rms:.3f} -> {result.db_rms:.3f} dB, " + (
        "kept" if keep else "not kept"
    )
    if not keep:
        return FinalFit(source, source, False, note, result.notes())
    model = replace(
        result, label=source.label, effect=source.effect, location=source.location,
        candidate=source.candidate, n_own=source.n_own, variant=source.variant,
    )  # fmt: skip
    return FinalFit(source, model, True, note, result.notes())


@dataclass
class PendingFinal:
    """A final fit started on a pool (:func:`start_final`): call it to wait for the
    :class:`FinalFit`."""

    source: JobResult
    future: Any

    def __call__(self) -> FinalFit:
        return judged(self.source, self.future.result())


def start_final(
    source: JobResult, base: Task, restart: JobResult | None, pool: Any
) -> PendingFinal:
    """Start the final fit of ``source`` on ``pool`` and return what waits for it: the caller
    can do other work (e.g. draw the plots) while a worker fits."""
    return PendingFinal(source, pool.submit(run_refit, final_task(source, base, restart)))
