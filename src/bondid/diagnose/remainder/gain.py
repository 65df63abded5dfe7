"""A constant gain offset of an output row or an input column (a calibration): the measured
magnitude sits a constant number of dB off the model's over the whole range,
``H_meas = H_model · e^g`` (``g`` real; ``(20/ln 10)·g`` dB); or, with its sign reversed,
``H_meas = −H_model · e^g`` (a sensor or drive wired with the wrong polarity: the phase is
half a turn off everywhere)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...cost.residuals import DB
from . import words
from .base import Candidate, Finding, Location, Significance
from .context import Context
from .groups import group_points
from .residual import Points, Residual
from .stats import assess


@dataclass
class GainOffset(Finding):
    """``gain_db`` [dB] (measured above the model when positive), its ``std_db``, and
    ``reversed`` when the sign is flipped too."""

    gain_db: float = math.nan
    std_db: float = math.nan
    reversed: bool = False

    def figures(self) -> dict[str, Any]:
        return {"gain_db": self.gain_db, "std_db": self.std_db, "reversed": self.reversed}


def _text(side: str, name: str, g: float, s: float, flip: bool) -> tuple[str, str]:
    where = words.side_phrase(side, [name]) if side != "global" else "every channel"
    what = "above" if g > 0 else "below"
    head = f"{where} reads {abs(g):.2f} dB (± {s:.2f}) {what} the model over the whole range"
    if flip:
        head = f"{where} has its sign reversed (the phase half a turn off)"
        if abs(g) > 3 * s:
            head += f" and reads {g:+.2f} dB (± {s:.2f})"
        thing = {"output": f"the {name} sensor", "input": f"the {name} drive"}.get(
            side, "the common measurement chain"
        )
        return f"{head}: {thing} is wired with the wrong polarity", f"check {thing}'s polarity"
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
    """One candidate per output row and input column (and all channels together): the
    better of the gain alone and the gain with the sign reversed."""
    out = []
    for side, name, pts in group_points(res):
        fits = [c for c in (_fit(pts, side, name, flip) for flip in (False, True)) if c]
        if fits:
            out.append(max(fits, key=lambda c: c.fit.gain))
    return out


def _fit(pts: Points, side: str, name: str, flip: bool) -> Candidate | None:
    sign = -1.0 if flip else 1.0
    e = pts.e(sign * pts.Hs)
    g = float(np.sum(pts.w * e.real) / np.sum(pts.w))  # the fit is linear in g: closed form

    def model(th: np.ndarray) -> np.ndarray:
        return sign * pts.Hs * np.exp(th[0])

    r = np.sqrt(pts.w)
    jac = np.concatenate([-r, np.zeros_like(r)])[:, None]
    fit = assess(pts, model, np.array([g]), jac=jac)
    if fit is None:
        return None
    loc = Location(side, (name,) if name else ())

    def describe(sig: Significance) -> Finding:
        gd, sd = DB * float(fit.theta[0]), DB * float(fit.std[0])
        text, advice = _text(side, name, gd, sd, flip)
        return GainOffset("gain_offset", text, sig.share, loc, None, advice, sig,
                          gain_db=gd, std_db=sd, reversed=flip)  # fmt: skip

    where = words.side_phrase(side, [name] if name else [])
    key = f"{'reversed sign' if flip else 'gain offset'} on {where}"
    return Candidate(key, pts, fit, 2.0, describe, f"gain {side} {name}")
