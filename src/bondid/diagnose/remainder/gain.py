"""A constant gain offset of an output row or an input column (a calibration): the measured
magnitude sits a constant number of dB off the model's over the whole range,
``H_meas = H_model · e^g`` (``g`` real; ``(20/ln 10)·g`` dB)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...cost.residuals import DB
from . import words
from .base import Candidate, Finding, Location, Significance
from .context import Context
from .groups import MIN_POINTS, groups
from .residual import Points, Residual
from .stats import assess


@dataclass
class GainOffset(Finding):
    """``gain_db`` [dB] (measured above the model when positive) and its ``std_db``."""

    gain_db: float = math.nan
    std_db: float = math.nan

    def figures(self) -> dict[str, Any]:
        return {"gain_db": self.gain_db, "std_db": self.std_db}


def _text(side: str, name: str, g: float, s: float) -> tuple[str, str]:
    where = words.side_phrase(side, [name]) if side != "global" else "every channel"
    what = "above" if g > 0 else "below"
    head = f"{where} reads {abs(g):.2f} dB (± {s:.2f}) {what} the model over the whole range"
    if side == "output":
        return f"{head}: a calibration (gain) offset of the {name} sensor", (
            f"check the {name} sensor's calibration (scale factor)"
        )
    if side == "input":
        return f"{head}: the {name} drive's gain is off (amplifier gain, force constant)", (
            f"check the {name} drive's gain chain (amplifier, motor force constant)"
        )
    return f"{head}: a common scale (the excitation's or the analyser's calibration)", (
        "check the common calibration of the measurement"
    )


def candidates(res: Residual, ctx: Context) -> list[Candidate]:
    """One candidate per output row and input column (and all channels together)."""
    out = []
    for side, name, select in groups(res):
        pts = res.points(select)
        if pts.size < MIN_POINTS:
            continue
        cand = _fit(pts, side, name)
        if cand is not None:
            out.append(cand)
    return out


def _fit(pts: Points, side: str, name: str) -> Candidate | None:
    e = pts.e()
    g = float(np.sum(pts.w * e.real) / np.sum(pts.w))

    def model(th: np.ndarray) -> np.ndarray:
        return pts.Hs * np.exp(th[0])

    r = np.sqrt(pts.w)
    jac = np.concatenate([-r, np.zeros_like(r)])[:, None]
    fit = assess(pts, model, np.array([g]), jac=jac)
    if fit is None:
        return None
    loc = Location(side, (name,) if name else ())

    def describe(sig: Significance) -> Finding:
        gd, sd = DB * float(fit.theta[0]), DB * float(fit.std[0])
        text, advice = _text(side, name, gd, sd)
        return GainOffset("gain_offset", text, sig.share, loc, None, advice, sig,
                          gain_db=gd, std_db=sd)  # fmt: skip

    key = f"gain offset on {words.side_phrase(side, [name] if name else [])}"
    return Candidate(key, pts, fit, 1.0, describe)
