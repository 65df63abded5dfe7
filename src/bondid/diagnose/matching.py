"""Springs placed so that the model's modes match the measured ones (:func:`matched_start`), the
start of a candidate with several springs.

A candidate that adds several independent springs (a flexible base: two shear directions and
compression; soft mounts: six) has one family of modes per spring, and its scale scan moves
them all together in fixed ratios: the measured modes the model lacks are seldom in those
ratios. So each spring is set on its own, by a coordinate search of the **matching cost**:
for every measured mode of every data set, ``min_j ((ln f_j/f)/σ)² + w (1 − MAC_j)`` over the
model's modes ``j`` at that operating point (capped at :data:`MISS_COST`: a measured mode no
model mode comes near costs the same however far it is), summed. Each spring is tried at
:data:`MATCH_POINTS` values over its scan range, then again within :data:`LOCAL_SPAN` of the
best, the others held; a spring is never moved out of the range its own scan covers (a mode
pushed out of the band matches nothing and costs nothing).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .effects import Candidate
from .refit import Refit, State

if TYPE_CHECKING:
    from ..data.measurement import FrfData
    from ..modal.identify import IdentifiedMode

#: relative frequency error that costs as much as a MAC of 0.75 in the matching cost
SIGMA_F = 0.1
MAC_WEIGHT = 4.0
#: cost of a measured mode no model mode comes near (8 = 0.28 in ln f)
MISS_COST = 8.0
#: values of each spring in a coordinate sweep (log-spaced over its scan range)
MATCH_POINTS = 13
#: the second sweep stays within this factor of the first's result (stiffness; √10 ≈ 3.2× in
#: frequency)
LOCAL_SPAN = 10.0


def springs(cand: Candidate) -> list[int]:
    """Indices of ``cand``'s stiffnesses (structural parameters scanned in proportion)."""
    return [i for i, q in enumerate(cand.parameters) if q.scan == 1.0 and q.members]


def model_modes(refit: Refit, state: State, data: Sequence[FrfData]) -> list[list[Any]]:
    """The modes of the model at ``state`` for each data set (its operating point and
    channels; :func:`~bondid.modal.identify.model_modes`)."""
    from ..modal.identify import model_modes as modes_of

    affines = refit.at(state).frf.affines
    return [modes_of(am.linear_model(), data=d) for d, am in zip(data, affines, strict=True)]


def matching_cost(
    refit: Refit, state: State, measured: Sequence[Sequence[IdentifiedMode]],
    data: Sequence[FrfData],
) -> float:  # fmt: skip
    """The matching cost (module docstring) of the model at ``state``; inf where it fails."""
    from ..exceptions import BondidError
    from ..modal.pairing import mac_matrix

    try:
        by_set = model_modes(refit, state, data)
    except (BondidError, np.linalg.LinAlgError, ValueError):
        return float("inf")
    total = 0.0
    for meas, mm in zip(measured, by_set, strict=True):
        if not meas:
            continue
        if not mm:
            total += MISS_COST * len(meas)
            continue
        mac = mac_matrix(meas, mm)
        f = np.array([b.f_hz for b in mm])
        for i, a in enumerate(meas):
            c = (np.log(f / a.f_hz) / SIGMA_F) ** 2 + MAC_WEIGHT * (1.0 - mac[i])
            total += min(float(np.min(c)), MISS_COST)
    return total


def _sweep(
    refit: Refit, v: np.ndarray, v0: np.ndarray, idx: Sequence[int], values: np.ndarray,
    cost: float, measured: Sequence[Sequence[IdentifiedMode]], data: Sequence[FrfData],
) -> tuple[float, np.ndarray]:  # fmt: skip
    """One coordinate sweep: each spring in turn at ``values`` times its start value ``v0``,
    kept where the matching cost is lowest."""
    for i in idx:
        for m in values:
            w = v.copy()
            w[i] = v0[i] * m
            c = matching_cost(refit, refit.with_new(refit.state0, w), measured, data)
            if c < cost:
                cost, v = c, w
    return cost, v


def matched_start(
    refit: Refit, cand: Candidate, scale: float,
    measured: Sequence[Sequence[IdentifiedMode]], data: Sequence[FrfData],
) -> np.ndarray | None:  # fmt: skip
    """New parameters ``(n_new,)`` (SI) of ``cand`` with every spring matched to the measured
    modes (module docstring), from all springs at ``scale`` times their start values; None
    when the candidate has fewer than two springs, no scan range or no measured mode."""
    idx = springs(cand)
    if len(idx) < 2 or not cand.scan_grid or not any(measured):
        return None
    lo, hi = min(cand.scan_grid), max(cand.scan_grid)
    v0 = refit.new_values(refit.state0)
    v = v0.copy()
    v[idx] = v0[idx] * scale
    cost = matching_cost(refit, refit.with_new(refit.state0, v), measured, data)
    cost, v = _sweep(refit, v, v0, idx, np.geomspace(lo, hi, MATCH_POINTS), cost, measured, data)
    around = np.geomspace(1 / LOCAL_SPAN, LOCAL_SPAN, MATCH_POINTS)
    for i in idx:  # the second sweep: each spring near where the first left it
        local = np.clip(v[i] / v0[i] * around, lo, hi)
        cost, v = _sweep(refit, v, v0, [i], np.unique(local), cost, measured, data)
    return v if np.isfinite(cost) else None
