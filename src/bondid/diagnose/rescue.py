"""The rescue of a refit that ends above the noise level: the core's band continuation
from its best point (:func:`rescue`), for every refit job of :mod:`.runner`."""

from __future__ import annotations

import math
from typing import Any

from .refit import Refit, State

#: a full refit whose training db_rms ends above this multiple of the predicted noise level
#: (:func:`bondid.optim.fallback.noise_ratio`; a cost 1.5× the one an exact model would
#: score) gets the core's band continuation from its best point (:func:`rescue`)
RESCUE_RATIO = math.sqrt(1.5)
#: bands of that continuation (the last is the full fit) and IPOPT iterations per band
RESCUE_BANDS = 4
RESCUE_BAND_ITER = 30


def rescue(
    refit: Refit, state: State, res: Any, presolve_iter: int, max_iter: int
) -> tuple[State, Any, str]:
    """The core's band continuation (:func:`bondid.optim.schedules.continuation`) from
    ``state`` when its training db_rms is above :data:`RESCUE_RATIO` times the predicted
    noise level (the test of :mod:`bondid.optim.fallback`, which ``bondid.fit`` runs from
    its start); the lower objective is kept.

    Args:
        refit, state, res: the refit, its best point and that point's search.
        presolve_iter: the presolve of the continuation's last step (IPOPT iterations).
        max_iter: IPOPT's iteration limit of each continuation step.

    Returns:
        The state, its search and a note ("" when the refit was at the noise level).
    """
    from ..optim.fallback import noise_ratio
    from ..optim.schedules import continuation

    p = refit.at(state)
    data = p.data_cost(p.z0)
    ratio = noise_ratio(p, data)
    if ratio is None or not ratio > RESCUE_RATIO:
        return state, res, ""
    c0 = p.cost(p.z0)
    steps = continuation(p, RESCUE_BANDS, band_iter=RESCUE_BAND_ITER, presolve_iter=presolve_iter)
    s2, c2, res2 = refit.solve(state, steps, max_iter=max_iter)
    kept = c2 < c0
    note = (
        f"training db_rms {ratio:.2f}x the predicted noise level (cost {data:.4g}): band "
        f"continuation to cost {refit.data_cost(s2):.4g}, {'kept' if kept else 'not kept'}"
    )
    return (s2, res2, note) if kept else (state, res, note)
