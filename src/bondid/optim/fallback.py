"""A search that falls back on the band continuation when it ends above the noise level.

A local fit (the direct or staged schedule) from 10–30 % parameter errors can stop in another
basin of the log cost, or crawl to its iteration limit, far above what an exact model would
score on the same data. The fit can tell without knowing the truth: the cost an exact model
would score on these data is predicted from the data's own noise
(:func:`bondid.cost.noise_level.noise_level_cost`, ``fit.json``'s ``db_rms.noise_level``).
:func:`run_to_noise` runs the schedule; when its final data cost is above
:data:`NOISE_MARGIN`² times that prediction (its ``db_rms`` more than 10 % above the noise
level), it runs the band continuation (:func:`bondid.optim.schedules.continuation`) from the
same start and keeps the lower final cost (a failed search loses to one that did not fail).

Measured (``tools/refit_benchmark.py``; the second bonder design with 10–30 % errors, coherence
regime): the direct fit stopped at its iteration limit at 3.22 dB (600 iterations: 6.80 dB),
the continuation reached 1.301 dB, the truth model's own score 1.304 dB.

Costs without a noise-level prediction (kinds other than ``complex_log``/``log_magnitude``,
the ``l1`` norm) never fall back.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from typing import Any

from .problem import FitProblem
from .search import SearchResult, Step, run_search

#: a fit whose weighted db_rms is above this factor times the predicted noise level falls
#: back on the band continuation (the factor of "at the noise level" in ``bondid.fit``)
NOISE_MARGIN = 1.10


def noise_ratio(problem: FitProblem, data_cost: float) -> float | None:
    """``sqrt(data_cost / C_noise)``: the fit's db_rms over the predicted noise level (None
    when the cost has no noise-level prediction)."""
    from ..cost.noise_level import noise_level_cost

    c_noise = noise_level_cost(problem.frf)
    if c_noise is None or not c_noise > 0 or not math.isfinite(data_cost):
        return None
    return math.sqrt(max(data_cost, 0.0) / c_noise)


def _better(a: SearchResult, b: SearchResult) -> bool:
    """Is ``b`` better than ``a`` (not failed beats failed, then the lower data cost)?"""
    fa, fb = a.result.status == "failed", b.result.status == "failed"
    if fa != fb:
        return fa
    return b.result.cost_final < a.result.cost_final


def run_to_noise(
    problem: FitProblem,
    steps: Sequence[Step],
    *,
    fallback_bands: int = 8,
    band_iter: int | None = None,
    presolve_iter: int | None = None,
    **kw: Any,
) -> SearchResult:
    """:func:`~bondid.optim.search.run_search` of ``steps``, then the band continuation
    (``fallback_bands`` bands, from the same start) when the result's data cost is above the
    noise level (module docstring); the better of the two.

    Args:
        problem, steps: as :func:`run_search`.
        fallback_bands: bands of the fallback continuation (0 = no fallback).
        band_iter: IPOPT iterations per band step (default
            :data:`bondid.optim.schedules.BAND_ITER`).
        presolve_iter: the presolve of the continuation's last step (default: the largest
            ``presolve`` of ``steps``).
        kw: passed to :func:`run_search` (``max_iter``, ``tol``, ``progress``, ``on_step``,
            ``ipopt_options``, ``constraint_hessian``).

    Returns:
        The kept :class:`SearchResult`; its ``result.notes`` say whether the fallback ran and
        which was kept, and ``result.iterations``/``wall_s`` count both searches.
    """
    from .schedules import BAND_ITER, continuation

    t0 = time.perf_counter()
    first = run_search(problem, steps, **kw)
    ratio = noise_ratio(problem, first.result.cost_final)
    if fallback_bands < 2 or ratio is None or ratio <= NOISE_MARGIN:
        return first
    pre = max((s.presolve for s in steps), default=0) if presolve_iter is None else presolve_iter
    cont = continuation(
        problem, fallback_bands, band_iter=band_iter or BAND_ITER, presolve_iter=pre
    )
    second = run_search(problem, cont, **kw)
    ratio2 = noise_ratio(problem, second.result.cost_final)
    keep = second if _better(first, second) else first
    note = (
        f"fallback: the search ended at {ratio:.2f}× the predicted noise level (db_rms); the"
        f" band continuation ({fallback_bands} bands) from the same start ended at"
        f" {ratio2 if ratio2 is not None else math.nan:.2f}×; kept the"
        f" {'continuation' if keep is second else 'first search'}"
    )
    result = dataclasses.replace(
        keep.result,
        iterations=first.result.iterations + second.result.iterations,
        wall_s=time.perf_counter() - t0,
        notes=[*keep.result.notes, note],
    )
    return SearchResult(result, keep.steps, keep.solution)
