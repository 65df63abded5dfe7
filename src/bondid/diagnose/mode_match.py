"""How the modes of a model at a refit's state compare with the modes measured in the data
(for the starts of :mod:`.modal_start`): the modes identified in each data set, the model's
own modes, and the matching cost of each measured mode."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from ..data.measurement import FrfData
    from .job import Job
    from .modal_id import IdentifiedMode
    from .refit import Refit, State

#: relative frequency error that costs as much as a MAC of 0.75 in the matching cost
SIGMA_F = 0.1
MAC_WEIGHT = 4.0
#: cost of a measured mode no model mode comes near (a capped term: 8 = 0.28 in ln f)
MISS_COST = 8.0


def model_modes_by_set(refit: Refit, state: State, data: Sequence[FrfData]) -> list[list[Any]]:
    """The modes (:func:`.modal_id.model_modes`) of the model at ``state`` for each data set
    (its operating point and channels). Raises what the model raises where it fails."""
    from .modal_id import model_modes

    affines = refit.at(state).frf.affines
    return [model_modes(am.linear_model(), data=d) for d, am in zip(data, affines, strict=True)]


def matching_cost(
    refit: Refit, state: State, measured: Sequence[Sequence[IdentifiedMode]],
    data: Sequence[FrfData],
) -> float:  # fmt: skip
    """How far the modes of the model at ``state`` are from the measured ones: the sum of
    :func:`mode_mismatch`; inf where the model fails."""
    from ..exceptions import BondidError

    try:
        return float(sum(c for c, _ in mode_mismatch(refit, state, measured, data)))
    except (BondidError, np.linalg.LinAlgError, ValueError):
        return float("inf")


def mode_mismatch(
    refit: Refit, state: State, measured: Sequence[Sequence[IdentifiedMode]],
    data: Sequence[FrfData],
) -> list[tuple[float, float]]:  # fmt: skip
    """(term, frequency [Hz]) of every measured mode of every data set: the term is
    ``min_j ((ln f_j/f)/σ)² + w (1 − MAC_j)`` over the modes ``j`` of the model at ``state``,
    capped at :data:`MISS_COST`. Raises what the model raises where it fails."""
    from .pairing import mac_matrix

    out: list[tuple[float, float]] = []
    for meas, mm in zip(measured, model_modes_by_set(refit, state, data), strict=True):
        if not meas:
            continue
        if not mm:
            out += [(MISS_COST, a.f_hz) for a in meas]
            continue
        mac = mac_matrix(meas, mm)
        f = np.array([b.f_hz for b in mm])
        for i, a in enumerate(meas):
            c = (np.log(f / a.f_hz) / SIGMA_F) ** 2 + MAC_WEIGHT * (1.0 - mac[i])
            out.append((min(float(np.min(c)), MISS_COST), a.f_hz))
    return out


def model_modes_hz(refit: Refit, data: Sequence[FrfData]) -> list[float]:
    """Frequencies [Hz] of the modes of the model at ``refit``'s start inside each data set's
    band, ascending (none where the model fails)."""
    from ..exceptions import BondidError

    try:
        by_set = model_modes_by_set(refit, refit.state0, data)
    except (BondidError, np.linalg.LinAlgError, ValueError):
        return []
    return sorted(
        m.f_hz
        for d, mm in zip(data, by_set, strict=True)
        for m in mm
        if d.freq_hz[0] <= m.f_hz <= d.freq_hz[-1]
    )


def measured_modes(data: Sequence[FrfData]) -> list[list[IdentifiedMode]]:
    """The modes identified in each data set (:func:`.modal_id.identify_modes`); a set whose
    identification fails has none (as in the gap report)."""
    from .modal_id import identify_modes

    out: list[list[IdentifiedMode]] = []
    for d in data:
        try:
            out.append(list(identify_modes(d)))
        except Exception:  # a set whose identification fails adds nothing
            out.append([])
    return out


def job_modes(job: Job) -> list[list[IdentifiedMode]]:
    """The modes identified in each of ``job``'s full data sets: those it carries
    (``Job.measured``), else :func:`measured_modes`."""
    if job.measured and len(job.measured) == len(job.full):
        return [list(m) for m in job.measured]
    return measured_modes(job.full)
