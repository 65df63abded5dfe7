"""A refitted model read on other data: the held-out and full figures of a refit job.

The fitted (augmented) model and its FRF modifier's values are evaluated through the core's
own problem on each set of data (:class:`bondid.optim.FitProblem`: the same residual, weights
and normalisation as the refit's training cost), and the model FRF on each data set's whole
grid (:func:`bondid.frf.aligned.model_frf` through the modifier) feeds the gap figures
(:func:`.gap.gap_report`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..optim.result import FitResult
from .refit import Refit

if TYPE_CHECKING:
    from ..optim.problem import FitProblem


@dataclass
class Figures:
    """Weighted mean-square complex-log cost ``cost`` (as the training cost), the model FRF
    per data set ``H`` ``(n_out, n_in_data, n_freq)``, and ``db_rms`` (weighted) /
    ``db_rms_unweighted`` (points of weight ≥ 0.5) [dB] over the used channels."""

    cost: float
    H: list[np.ndarray]
    db_rms: float
    db_rms_unweighted: float


def _problem_on(
    refit: Refit, fit: FitResult, theta: np.ndarray, datasets: Sequence[FrfData],
    options: CostOptions,
) -> FitProblem:  # fmt: skip
    """The core's problem of ``refit`` on ``datasets`` at ``fit`` (the modifier held at
    ``theta``): the refit's residual, weights and normalisation on other data."""
    from ..optim.problem import FitProblem

    p = refit.problem
    mod = refit.modifier
    if mod is not None:
        th = tuple(float(t) for t in theta)
        mod = replace(mod, start=th, lower=th, upper=th)
    return FitProblem(
        fit.document, list(datasets), p.names, options=options, lower=p.lower,
        upper=p.upper, ties=p.ties, modifier=mod, use_hull=False,
    )  # fmt: skip


def figures(
    refit: Refit, fit: FitResult, theta: np.ndarray, datasets: Sequence[FrfData],
    options: CostOptions,
) -> Figures:  # fmt: skip
    """The figures of the fitted model ``fit`` (with the modifier at ``theta``) on
    ``datasets`` (see the module docstring)."""
    from ..frf.aligned import model_frf
    from .gap import gap_report
    from .split import mask_incoherent

    on = _problem_on(refit, fit, theta, datasets, options)
    cost = on.data_cost(on.z0)
    doc, mod = fit.document, refit.modifier
    H = []
    for ds, aff in zip(datasets, on.frf.affines, strict=True):
        h = model_frf(doc, ds, affine=aff)
        if mod is not None:
            h = mod.apply(theta, ds.freq_hz, ds.outputs, ds.inputs, h)
        H.append(h)
    chans = options.channels
    fb = options.channels_by_file
    weighted = gap_report(
        list(datasets), H, channels=chans, by_file=fb, weighting="coherence"
    ).db_rms
    plain = gap_report([mask_incoherent(d) for d in datasets], H, channels=chans, by_file=fb).db_rms
    return Figures(float(cost), H, float(weighted), float(plain))


def heldout_rms(
    refit: Refit, fit: FitResult, datasets: Sequence[FrfData], options: CostOptions
) -> float:
    """The weighted RMS [dB] of ``fit`` on ``datasets`` (``sqrt`` of :func:`figures`'s
    ``cost``, the verdict's held-out figure before its FPE factor), without the model FRFs
    and gap figures :func:`figures` also computes; NaN without data."""
    if not datasets:
        return float("nan")
    on = _problem_on(refit, fit, refit.state_theta(fit), datasets, options)
    return float(np.sqrt(on.data_cost(on.z0)))
