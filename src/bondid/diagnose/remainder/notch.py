"""A notch on an output row or input column: ``H_meas = H_model · (1 + 2ζ_z x + x²) /
(1 + 2ζ_p x + x²)``, ``x = jω/ω₀``, ``ζ_z < ζ_p`` — a dip of depth ``ζ_z/ζ_p`` at ``ω₀``
that leaves both ends alone (a notch filter in a drive's or sensor's chain, or an
anti-resonance only that row or column shows).

Found on a grid (``ω₀`` over the data's range, ``ζ_p`` and the depth on a few values), then
refined by least squares in ``(ln ω₀, ln ζ_p, ln(ζ_z/ζ_p) ≤ 0)``; every grid point is a look
of its own.
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
from .groups import MIN_POINTS, groups
from .residual import Points, Residual, log_ratio
from .stats import fit_points

#: the grid: notch frequencies per decade, widths ζ_p and depths ζ_z/ζ_p
PER_DECADE = 16
ZETA_GRID = (0.05, 0.2, 0.6)
DEPTH_GRID = (0.03, 0.1, 0.3)


@dataclass
class Notch(Finding):
    """At ``f_hz``: ``depth_db`` (negative), width ``zeta`` (ζ_p), ``std_rel`` of ``f_hz``."""

    f_hz: float = math.nan
    depth_db: float = math.nan
    zeta: float = math.nan
    std_rel: float = math.nan

    def figures(self) -> dict[str, Any]:
        return {"f_hz": self.f_hz, "depth_db": self.depth_db, "zeta": self.zeta,
                "std_rel": self.std_rel}  # fmt: skip


def _factor(s: np.ndarray, w0: float, zp: float, zz: float) -> np.ndarray:
    x = s / w0
    return (1.0 + 2 * zz * x + x * x) / (1.0 + 2 * zp * x + x * x)


def candidates(res: Residual, ctx: Context) -> list[Candidate]:
    f_lo, f_hi = ctx.freq_range(res)
    n = max(4, math.ceil(PER_DECADE * math.log10(f_hi / f_lo)))
    grid = np.geomspace(f_lo, f_hi, n)
    out = []
    for side, name, select in groups(res, with_global=False):
        pts = res.points(select)
        if pts.size < MIN_POINTS:
            continue
        cand = _fit(pts, side, name, grid)
        if cand is not None:
            out.append(cand)
    return out


def _fit(pts: Points, side: str, name: str, grid: np.ndarray) -> Candidate | None:
    few = pts.thinned()
    e = few.e()
    best = min(
        (float(np.sum(few.w * np.abs(e - log_ratio(_factor(few.s, 2 * np.pi * f, zp, zp * d),
                                                    np.ones(few.size))) ** 2)), f, zp, d)
        for f in grid for zp in ZETA_GRID for d in DEPTH_GRID
    )  # fmt: skip
    _, f0, zp0, d0 = best

    def model(th: np.ndarray) -> np.ndarray:
        zp = math.exp(th[1])
        return pts.Hs * _factor(pts.s, math.exp(th[0]), zp, zp * math.exp(th[2]))

    lo = np.array([math.log(2 * np.pi * grid[0]), math.log(0.01), math.log(1e-4)])
    hi = np.array([math.log(2 * np.pi * grid[-1]), math.log(2.0), 0.0])
    theta0 = np.array([math.log(2 * np.pi * f0), math.log(zp0), math.log(d0)])
    fit = fit_points(pts, model, theta0, lower=lo, upper=hi)
    if fit is None:
        return None
    where = words.side_phrase(side, [name])
    loc = Location(side, (name,))
    f_hat = math.exp(fit.theta[0]) / (2 * np.pi)
    zeta, depth = math.exp(fit.theta[1]), DB * float(fit.theta[2])
    band = (f_hat / (1 + 3 * zeta), f_hat * (1 + 3 * zeta))

    def describe(sig: Significance) -> Finding:
        thing = f"the {name} drive's" if side == "input" else f"the {name} sensor's"
        text = (
            f"{where} shows a notch at {words.hz(f_hat)} ({depth:.0f} dB deep, ζ {zeta:.2f}) "
            f"that the model lacks: a notch filter in {thing} chain, or an anti-resonance "
            "only it shows"
        )
        return Notch("notch", text, sig.share, loc, band, f"check {thing} filters", sig,
                     f_hz=f_hat, depth_db=depth, zeta=zeta,
                     std_rel=float(fit.std[0]))  # fmt: skip

    looks = grid.size * len(ZETA_GRID) * len(DEPTH_GRID) / 4
    return Candidate(f"notch on {where}", pts, fit, looks, describe)
