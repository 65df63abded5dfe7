"""A pure delay: the measured phase falls behind the model's in proportion to frequency,
``H_meas = H_model · e^(−jωτ)``, on one output row (the sensor's path: sampling, filtering,
a bus), one input column (the drive's path) or every channel.

The delay is found on a grid (the residual's phase is wrapped, so a delay of more than half
a period at the highest frequency cannot be read from a straight line), then refined by
least squares. The grid spans ``|τ| ≤ 2 / f_max`` with steps of ``1/(8 f_max)``; each step
is a look of its own (:attr:`.base.Candidate.trials`). A negative ``τ`` means the measured
phase leads the model's (the model holds a delay the data do not show).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...cost.residuals import wrap
from . import words
from .base import Candidate, Finding, Location, Significance
from .context import Context
from .groups import group_points
from .residual import Points, Residual
from .stats import fit_points

#: the grid's reach in periods of the highest frequency, and its steps per period
REACH_PERIODS = 2.0
STEPS_PER_PERIOD = 8


@dataclass
class Delay(Finding):
    """``tau_s`` [s] (measured behind the model when positive) and its ``std_s``."""

    tau_s: float = math.nan
    std_s: float = math.nan

    def figures(self) -> dict[str, Any]:
        return {"tau_s": self.tau_s, "std_s": self.std_s}


def candidates(res: Residual, ctx: Context) -> list[Candidate]:
    fits = (_fit(pts, side, name) for side, name, pts in group_points(res))
    return [c for c in fits if c is not None]


def _fit(pts: Points, side: str, name: str) -> Candidate | None:
    e = pts.e()
    om = pts.s.imag
    f_max = float(om.max()) / (2 * np.pi)
    step = 1.0 / (STEPS_PER_PERIOD * f_max)
    n = round(REACH_PERIODS * STEPS_PER_PERIOD)
    taus = step * np.arange(-n, n + 1)
    cost = [float(np.sum(pts.w * wrap(e.imag + om * t) ** 2)) for t in taus]
    t0 = float(taus[int(np.argmin(cost))])

    def model(th: np.ndarray) -> np.ndarray:
        return pts.Hs * np.exp(-pts.s * th[0])

    fit = fit_points(pts, model, np.array([t0]), lower=np.array([t0 - step]),
                     upper=np.array([t0 + step]))  # fmt: skip
    if fit is None:
        return None
    where = words.side_phrase(side, [name]) if side != "global" else "every channel"
    loc = Location(side, (name,) if name else ())

    def describe(sig: Significance) -> Finding:
        tau, std = float(fit.theta[0]), float(fit.std[0])
        lag = "behind" if tau > 0 else "ahead of"
        text = (
            f"the phase of {where} runs {lag} the model's in proportion to frequency: a "
            f"delay of {words.seconds(tau)} (± {words.seconds(std)})"
        )
        if side == "output":
            advice = f"the {name} sensor's signal path (sampling, filters, bus latency)"
        elif side == "input":
            advice = f"the {name} drive's signal path (amplifier, command latency)"
        else:
            advice = "a delay common to every channel (the analyser's or controller's timing)"
        return Delay("delay", text, sig.share, loc, None, advice, sig, tau_s=tau, std_s=std)

    return Candidate(f"delay on {where}", pts, fit, float(taus.size) / 2, describe)
