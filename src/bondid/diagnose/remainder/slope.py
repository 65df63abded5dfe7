"""A gain that grows or falls as a power of frequency on an output row or input column:
``H_meas = H_model · e^c · (jω/ω₀)^α`` — the magnitude off by ``20·α`` dB per decade and
the phase by ``α·90°`` at every frequency. An ``α`` near ±1 or ±2 is one quantity read as
another (a velocity or acceleration taken for a displacement: a missing or extra
integration); a fractional one is a frequency-dependent sensitivity.

``c`` and ``α`` enter the log residual linearly (``e ≈ c + α (ln(ω/ω₀) + jπ/2)``), so the
start is a closed-form least-squares solution; the fit then takes the wrapped phase as it is.
``ω₀`` is the weighted geometric mean of the group's frequencies (``c`` is the offset there).
"""

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
from .stats import fit_points

#: what a whole power of jω between data and model means (both compared as receptances)
QUANTITY_MIXUPS = {
    1: "a velocity taken for a displacement",
    2: "an acceleration taken for a displacement",
    -1: "a displacement taken for a velocity",
    -2: "a displacement taken for an acceleration",
}


@dataclass
class GainSlope(Finding):
    """``alpha`` (``20·alpha`` dB per decade, ``alpha·90°``) and its ``std``; ``gain_db`` the
    offset at ``f0_hz``."""

    alpha: float = math.nan
    std: float = math.nan
    gain_db: float = math.nan
    f0_hz: float = math.nan

    def figures(self) -> dict[str, Any]:
        return {"alpha": self.alpha, "std": self.std, "gain_db": self.gain_db,
                "f0_hz": self.f0_hz}  # fmt: skip


def candidates(res: Residual, ctx: Context) -> list[Candidate]:
    fits = (_fit(pts, side, name) for side, name, pts in group_points(res))
    return [c for c in fits if c is not None]


def _fit(pts: Points, side: str, name: str) -> Candidate | None:
    om = pts.s.imag
    w0 = math.exp(float(np.sum(pts.w * np.log(om)) / np.sum(pts.w)))
    L = np.log(om / w0)
    e = pts.e()
    root = np.sqrt(np.concatenate([pts.w, pts.w]))
    X = np.stack([np.r_[np.ones_like(L), np.zeros_like(L)], np.r_[L, np.full(L.size, np.pi / 2)]],
                 axis=1) * root[:, None]  # fmt: skip
    theta0 = np.linalg.lstsq(X, np.r_[e.real, e.imag] * root, rcond=None)[0]

    def model(th: np.ndarray) -> np.ndarray:
        return pts.Hs * np.exp(th[0] + th[1] * (L + 0.5j * np.pi))

    fit = fit_points(pts, model, theta0)
    if fit is None:
        return None
    where = words.side_phrase(side, [name]) if side != "global" else "every channel"
    loc = Location(side, (name,) if name else ())

    def describe(sig: Significance) -> Finding:
        a, sa = float(fit.theta[1]), float(fit.std[1])
        g = DB * float(fit.theta[0])
        text = (
            f"{where} departs from the model as f^{a:.2f} (± {sa:.2f}): {20 * a:+.1f} dB per "
            f"decade and {90 * a:+.0f}° of phase"
        )
        near = round(a)
        if near in QUANTITY_MIXUPS and abs(a - near) < 0.15:
            text += f": the data look like {QUANTITY_MIXUPS[near]}"
            advice = "check the quantity and the integration of " + (
                f"the {name} sensor"
                if side == "output"
                else f"the {name} channel"
                if name
                else "the measurement"
            )
        else:
            advice = "a sensitivity that changes with frequency (sensor, conditioning filter)"
        return GainSlope("gain_slope", text, sig.share, loc, None, advice, sig, alpha=a, std=sa,
                         gain_db=g, f0_hz=w0 / (2 * np.pi))  # fmt: skip

    return Candidate(f"power-law gain on {where}", pts, fit, 1.0, describe, f"gain {side} {name}")
