"""The rescue of a refit that ends above the noise level (:func:`rescue`), for every refit job
of :mod:`.runner`: the fallbacks of the fit (:func:`bondid.optim.fallback.run_to_noise`), from
the refit's best point: the core's band continuation, then, if that did not reach the noise
level either, the staged schedule.

The staged schedule is what reaches the noise when a structural candidate's refit is stuck
with its new mode in the right place but the nominal stiffnesses, dampings and inertias bent
around it: it frees each kind of parameter in the bands where it acts (the model's own
resonances, the new DOF's included), which the continuation's growing low-pass bands do not.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..optim.search import Step
from .refit import Refit, State

if TYPE_CHECKING:
    from ..optim.problem import FitProblem

#: a full refit whose training db_rms ends above this multiple of the predicted noise level
#: (:func:`bondid.optim.fallback.noise_ratio`; a cost 1.5× the one an exact model would
#: score) gets the fallbacks (:func:`rescue`)
RESCUE_RATIO = math.sqrt(1.5)
#: bands of that continuation (the last is the full fit) and IPOPT iterations per band
RESCUE_BANDS = 4
RESCUE_BAND_ITER = 30
#: the staged schedule (a long search: every stage, then the full fit) runs only when the
#: continuation left the refit above this multiple of the noise level: a gap that size is a
#: wrong basin, not the noise level's prediction being a little low
STAGED_RATIO = 2.0


#: names of the rescue's fallbacks, in the order tried
BAND_CONTINUATION = "band continuation"
STAGED_SCHEDULE = "staged schedule"


def _schedules(
    presolve_iter: int, max_iter: int, continuation: bool = True
) -> list[tuple[str, float, Callable[[FitProblem], list[Step]]]]:
    """The fallbacks in the order tried with the noise ratio above which each runs, each
    built only when it runs, on the problem at the best point so far (the staged schedule's
    bands follow that model's resonances). ``continuation``: with the band continuation
    (False: the staged schedule alone)."""
    from ..optim.schedules import continuation as band_continuation
    from ..optim.schedules import staged

    every = {
        BAND_CONTINUATION: (RESCUE_RATIO, lambda p: band_continuation(
            p, RESCUE_BANDS, band_iter=RESCUE_BAND_ITER, presolve_iter=presolve_iter)),
        STAGED_SCHEDULE: (STAGED_RATIO, lambda p: staged(
            p, max_iter=max_iter, presolve_iter=presolve_iter)),
    }  # fmt: skip
    names = [BAND_CONTINUATION, STAGED_SCHEDULE] if continuation else [STAGED_SCHEDULE]
    return [(name, *every[name]) for name in names]


def noise_ratio_at(refit: Refit, state: State) -> float | None:
    """The training db_rms at ``state`` over the predicted noise level (None without one)."""
    from ..optim.fallback import ratio_to_level

    # the weights' (cautious) level: the training data hold only their weights, and the
    # rescue's ratios are calibrated on it (cost.noise_level.point_noise_to_signal); the
    # level is the refit's, computed once (Refit.noise_cost)
    return ratio_to_level(refit.data_cost(state), refit.noise_cost)


def above_noise(refit: Refit, state: State) -> bool:
    """Is the training db_rms at ``state`` above :data:`RESCUE_RATIO` times the predicted
    noise level (False without a prediction)?"""
    return above_ratio(noise_ratio_at(refit, state))


def above_ratio(ratio: float | None) -> bool:
    """:func:`above_noise` of a noise ratio already computed (:func:`noise_ratio_at`)."""
    return ratio is not None and ratio > RESCUE_RATIO


def above_heldout_level(heldout_rms: float, level_db: float) -> bool:
    """Is a refit's held-out weighted RMS [dB] above :data:`RESCUE_RATIO` times the held-out
    noise level ``level_db`` [dB] (False without a positive, finite level)?"""
    return math.isfinite(level_db) and level_db > 0 and heldout_rms > RESCUE_RATIO * level_db


def _due(ratio: float | None, above: float, always: bool) -> bool:
    """Does a fallback run at noise ratio ``ratio`` with threshold ``above``?"""
    return always or (ratio is not None and ratio > above)


def rescue(
    refit: Refit, state: State, res: Any, presolve_iter: int, max_iter: int,
    continuation: bool = True, always: bool = False,
) -> tuple[State, Any, str]:  # fmt: skip
    """The fallbacks (module docstring) from ``state`` while its training db_rms is above
    :data:`RESCUE_RATIO` (the staged schedule: :data:`STAGED_RATIO`) times the predicted
    noise level (the test of :mod:`bondid.optim.fallback`, which ``bondid.fit`` runs from its
    start); each fallback starts from the best point so far; the lowest objective is kept.
    ``always``: every fallback runs whatever the noise ratio (the final fit,
    :mod:`.final_fit`: the predicted level may be well above the truth's own figure).

    Args:
        refit, state, res: the refit, its best point and that point's search.
        presolve_iter: the presolve of the fallbacks' last steps (IPOPT iterations).
        max_iter: IPOPT's iteration limit of each fallback step (the staged schedule's band
            stages get a quarter of it).
        continuation: run the band continuation (False: the staged schedule alone, for a
            candidate whose refit already had the continuation from the nominal model,
            :func:`.alternatives.continuation_from_nominal`).

    Returns:
        The state, its search and a note ("" when the refit was at the noise level).
    """
    ratio = noise_ratio_at(refit, state)
    if not _due(ratio, RESCUE_RATIO, always):
        return state, res, ""
    said = [f"training db_rms {ratio or math.nan:.2f}x the predicted noise level"]
    best = refit.cost(state)
    for label, above, build in _schedules(presolve_iter, max_iter, continuation):
        if not _due(noise_ratio_at(refit, state), above, always):
            break
        s2, c2, res2 = refit.solve(state, build(refit.at(state)), max_iter=max_iter)
        kept = c2 < best
        r2 = noise_ratio_at(refit, s2)
        said.append(f"{label} to {r2 or math.nan:.2f}x, {'kept' if kept else 'not kept'}")
        if kept:
            state, res, best = s2, res2, c2
    return state, res, "; ".join(said)
