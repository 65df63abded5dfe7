"""A filter on one output row or input column (or on every channel): a first-order lag
``H_meas = H_model / (1 + jωT)`` (an amplifier's or current loop's bandwidth, a sensor's
filter), or a second-order one ``H_meas = H_model / (1 + 2ζ jω/ω₀ + (jω/ω₀)²)``.

A second-order filter with ``ζ`` below :data:`RESONANT_ZETA` is a resonance that only that
row or column shows (a read head on a compliant bracket multiplies its sensor's row by such
a factor; an amplifier's resonance, its drive's column): it is described as a missing mode
(:mod:`.mode_finding`), seen in that row or column. Both are found on a grid (corner
frequency, and damping), then refined by least squares; every grid point is a look of its
own (:attr:`.base.Candidate.trials`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import words
from .base import Candidate, Finding, Location, Significance, mode_group
from .context import Context
from .groups import group_points
from .modal import nearest, pole
from .mode_finding import Seen, missing_mode
from .residual import Points, Residual, log_ratio
from .stats import channel_reductions, fit_points, seen

#: below this damping a second-order filter is a resonance (a mode), above it a roll-off
RESONANT_ZETA = 0.3
#: damping ratios of the second-order grid
ZETA_GRID = (0.01, 0.03, 0.1, 0.3, 0.7)
#: corner frequencies per decade of the grids
PER_DECADE = 16


@dataclass
class Lag(Finding):
    """``order`` 1: ``time_s`` T [s] (corner ``f_c = 1/(2πT)``); order 2: ``f_c`` and
    ``zeta``. ``std_rel``: relative std of the corner frequency."""

    order: int = 1
    f_c_hz: float = math.nan
    time_s: float = math.nan
    zeta: float | None = None
    std_rel: float = math.nan

    def figures(self) -> dict[str, Any]:
        return {"order": self.order, "f_c_hz": self.f_c_hz, "time_s": self.time_s,
                "zeta": self.zeta, "std_rel": self.std_rel}  # fmt: skip


def candidates(res: Residual, ctx: Context) -> list[Candidate]:
    f_lo, f_hi = ctx.freq_range(res)
    all_chan = _names(res)
    out = []
    for side, name, pts in group_points(res):
        for cand in (_first(pts, side, name, f_lo, f_hi),
                     _second(pts, side, name, f_lo, f_hi, ctx, res, all_chan)):  # fmt: skip
            if cand is not None:
                out.append(cand)
    return out


def _names(res: Residual) -> dict[tuple[int, int, int], str]:
    return {
        (k, a, b): f"{o}.{i}"
        for k, st in enumerate(res.sets)
        for a, o in enumerate(st.outputs)
        for b, i in enumerate(st.inputs)
    }


def _grid(f_lo: float, f_hi: float, below: float, above: float) -> np.ndarray:
    lo, hi = f_lo / below, f_hi * above
    n = max(4, math.ceil(PER_DECADE * math.log10(hi / lo)))
    return np.geomspace(lo, hi, n)


def _cost(pts: Points, e: np.ndarray, den: np.ndarray) -> float:
    """``Σ w |e + ln den|²``: the cost left by the filter ``1/den`` on the residual ``e``."""
    return float(np.sum(pts.w * np.abs(e + log_ratio(den, np.ones_like(den))) ** 2))


def _where(side: str, name: str) -> str:
    return words.side_phrase(side, [name]) if side != "global" else "every channel"


def _first(pts: Points, side: str, name: str, f_lo: float, f_hi: float) -> Candidate | None:
    grid = _grid(f_lo, f_hi, 3.0, 10.0)
    few = pts.thinned()
    e = few.e()
    costs = [_cost(few, e, 1.0 + few.s / (2 * np.pi * fc)) for fc in grid]
    x0 = math.log(2 * np.pi * grid[int(np.argmin(costs))])

    def model(th: np.ndarray) -> np.ndarray:
        return pts.Hs / (1.0 + pts.s * math.exp(-th[0]))

    lo, hi = math.log(2 * np.pi * grid[0]), math.log(2 * np.pi * grid[-1])
    fit = fit_points(pts, model, np.array([x0]), lower=np.array([lo]), upper=np.array([hi]))
    if fit is None:
        return None
    loc = Location(side, (name,) if name else ())
    where = _where(side, name)

    def describe(sig: Significance) -> Finding:
        fc = math.exp(fit.theta[0]) / (2 * np.pi)
        T = 1.0 / (2 * np.pi * fc)
        text = (
            f"{where} falls behind the model like a first-order lag: T = {words.seconds(T)} "
            f"(corner {words.hz(fc)}, ± {100 * fit.std[0]:.0f} %)"
        )
        advice = _lag_advice(side, name)
        return Lag("lag", text, sig.share, loc, None, advice, sig, order=1, f_c_hz=fc,
                   time_s=T, std_rel=float(fit.std[0]))  # fmt: skip

    return Candidate(f"first-order lag on {where}", pts, fit, len(grid) / 2, describe)


def _lag_advice(side: str, name: str) -> str:
    if side == "input":
        return f"the {name} drive's bandwidth (amplifier, current loop)"
    if side == "output":
        return f"the {name} sensor's bandwidth (its filter, interpolator)"
    return "a filter common to every channel (the analyser's anti-aliasing)"


def _second(
    pts: Points, side: str, name: str, f_lo: float, f_hi: float, ctx: Context,
    res: Residual, all_chan: dict[tuple[int, int, int], str],
) -> Candidate | None:  # fmt: skip
    grid = _grid(f_lo, f_hi, 1.0, 3.0)
    few = pts.thinned()
    e = few.e()
    best: list[tuple[float, float, float]] = []
    for fc in grid:
        x = few.s / (2 * np.pi * fc)
        for z in ZETA_GRID:
            best.append((_cost(few, e, 1.0 + 2 * z * x + x * x), fc, z))
    best.sort()

    def model(th: np.ndarray) -> np.ndarray:
        x = pts.s * math.exp(-th[0])
        return pts.Hs / (1.0 + 2 * math.exp(th[1]) * x + x * x)

    lo = np.array([math.log(2 * np.pi * grid[0]), math.log(0.002)])
    hi = np.array([math.log(2 * np.pi * grid[-1]), math.log(2.0)])
    fit = None
    for _, fc, z in best[:2]:
        f = fit_points(pts, model, np.array([math.log(2 * np.pi * fc), math.log(z)]),
                       lower=lo, upper=hi)  # fmt: skip
        if f is not None and (fit is None or f.s1 < fit.s1):
            fit = f
    if fit is None:
        return None
    where = _where(side, name)
    loc = Location(side, (name,) if name else ())
    found = fit
    fc = math.exp(found.theta[0]) / (2 * np.pi)
    zeta = math.exp(found.theta[1])
    trials = max(len(grid) * len(ZETA_GRID) / 4, ctx.resonance_looks(res, zeta))
    if zeta < RESONANT_ZETA and f_lo <= fc <= f_hi and side in ("output", "input"):
        return _as_mode(pts, found, side, name, fc, zeta, ctx, res, all_chan, trials)

    def describe(sig: Significance) -> Finding:
        text = (
            f"{where} rolls off against the model like a second-order filter: corner "
            f"{words.hz(fc)}, ζ {zeta:.2f} (± {100 * found.std[0]:.0f} % in frequency)"
        )
        return Lag("lag", text, sig.share, loc, None, _lag_advice(side, name), sig, order=2,
                   f_c_hz=fc, time_s=1 / (2 * np.pi * fc), zeta=zeta,
                   std_rel=float(found.std[0]))  # fmt: skip

    return Candidate(f"second-order filter on {where}", pts, found, trials, describe)


def _as_mode(
    pts: Points, fit: Any, side: str, name: str, fc: float, zeta: float, ctx: Context,
    res: Residual, all_chan: dict[tuple[int, int, int], str], trials: float,
) -> Candidate:  # fmt: skip
    red = channel_reductions(pts, fit.H)
    shown = seen(red, fit.reduction)
    fitted = tuple(sorted(set(all_chan.values()), key=list(all_chan.values()).index))
    used = {all_chan[k] for k in all_chan if np.any(res.sets[k[0]].used[k[1], k[2]])}
    view = Seen(
        tuple(dict.fromkeys(all_chan[k] for k in shown)), tuple(c for c in fitted if c in used)
    )
    lam = pole(fc, zeta)
    near = None
    if ctx.settings.modes:
        k = 0
        st = res.sets[k]
        j = int(np.argmin(np.abs(st.freq_hz - fc)))
        R = np.zeros(st.Hs[:, :, j].shape, complex)
        w0 = 2 * np.pi * fc
        gres = w0 * w0 / (lam - np.conj(lam))  # residue of 1/(1 + 2ζs/ω₀ + s²/ω₀²) at λ
        if side == "output" and name in st.outputs:
            a = st.outputs.index(name)
            R[a] = st.Hs[a, :, j] * gres
        elif side == "input" and name in st.inputs:
            b = st.inputs.index(name)
            R[:, b] = st.Hs[:, b, j] * gres
        models = ctx.model()
        near = nearest(fc, zeta, R, models[k]) if models and models[k] else None
    h = max(0.1, 5 * zeta)
    band = (fc / (1 + h), fc * (1 + h))
    form = f"{side} filter"

    def describe(sig: Significance) -> Finding:
        return missing_mode(sig, fc, zeta, view, near, form, band)

    key = f"resonance on {words.side_phrase(side, [name])}"
    return Candidate(key, pts, fit, trials, describe, mode_group(fc))
