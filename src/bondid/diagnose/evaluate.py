"""A refitted model read on other data: the held-out and full figures of a refit job.

The fitted (augmented) model and its FRF modifier's values are evaluated through the core's
own problem on each set of data (:class:`bondid.optim.FitProblem`: the same residual, weights
and normalisation as the refit's training cost), and the model FRF on each data set's whole
grid (:func:`bondid.frf.aligned.model_frf` times the modifier's factor) feeds the gap figures
(:func:`.gap.gap_report`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..fit.result import FitResult
from .refit import Refit


@dataclass
class Figures:
    """Weighted mean-square complex-log cost ``cost`` (as the training cost), the model FRF
    per data set ``H`` ``(n_out, n_in_data, n_freq)``, and ``db_rms`` (weighted) /
    ``db_rms_unweighted`` (points of weight ≥ 0.5) [dB] over the used channels."""

    cost: float
    H: list[np.ndarray]
    db_rms: float
    db_rms_unweighted: float


def figures(
    refit: Refit, fit: FitResult, theta: np.ndarray, datasets: Sequence[FrfData],
    options: CostOptions,
) -> Figures:  # fmt: skip
    """The figures of the fitted model ``fit`` (with the modifier at ``theta``) on
    ``datasets`` (see the module docstring)."""
    from ..frf.aligned import model_frf
    from ..optim.problem import FitProblem
    from .gap import gap_report
    from .split import mask_incoherent

    p = refit.problem
    mod = refit.modifier
    if mod is not None:
        th = tuple(float(t) for t in theta)
        mod = replace(mod, start=th, lower=th, upper=th)
    doc = fit.document
    on = FitProblem(
        doc, list(datasets), p.names, options=options, lower=p.lower, upper=p.upper,
        ties=p.ties, modifier=mod, use_hull=False,
    )  # fmt: skip
    cost = on.data_cost(on.z0)
    H = []
    for ds, aff in zip(datasets, on.frf.affines, strict=True):
        h = model_frf(doc, ds, affine=aff)
        if mod is not None:
            h = h * mod.at(theta, ds.freq_hz, ds.outputs, ds.inputs)[0]
        H.append(h)
    chans = options.channels
    weighted = gap_report(list(datasets), H, channels=chans, weighting="coherence").db_rms
    plain = gap_report([mask_incoherent(d) for d in datasets], H, channels=chans).db_rms
    return Figures(float(cost), H, float(weighted), float(plain))


def heldout_ratio(
    refit: Refit, fit: FitResult, datasets: Sequence[FrfData], options: CostOptions,
    level_db: float,
) -> float:  # fmt: skip
    """The held-out weighted RMS of ``fit`` on ``datasets`` (``sqrt`` of :func:`figures`'s
    ``cost``, the verdict's figure before its FPE factor) over the held-out noise level
    ``level_db`` [dB] (:class:`.scoring.NoiseReference`); NaN without a level or data."""
    import math

    if not datasets or not (math.isfinite(level_db) and level_db > 0):
        return math.nan
    held = figures(refit, fit, refit.state_theta(fit), datasets, options)
    return math.sqrt(held.cost) / level_db
