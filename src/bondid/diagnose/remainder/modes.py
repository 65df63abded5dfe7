"""Modes in the remainder, fitted in a band around each one.

* **A mode the model lacks** (:func:`missing_candidates`): ``H_meas = H_model + R/(jω−λ) +
  R̄/(jω−λ̄)`` with one pole ``λ`` shared by every channel and data set and a residue ``R``
  per channel, fitted on the log residual in a band around a seed. Seeds: the measured modes
  the pairing calls missing (:func:`.modal.missing_seeds`) and the peaks of the excess over
  frequency (a mode the identification missed). Where a model mode pairs with the fitted one
  (within 20 % and MAC ≥ 0.5) the mode is *misplaced* rather than missing.
* **A model mode the data lack or place elsewhere** (:func:`model_candidates`): for each
  visible mode of the model (prominence ≥ 0.1), ``H_meas = H_model − c·T(λ)`` (spurious: the
  data keep ``|c|`` of it) and ``H_meas = H_model − T(λ) + c·T(λ')`` with ``λ'`` the pole
  moved by a relative frequency and damping shared by every data set (misplaced).

A mode's term reaches beyond its band (a stiffness below it, a mass line above): the model
modes' terms are applied at every frequency, and a missing mode fitted in its band is refitted
on every frequency of its channels and kept so when that does better. Which channels show a
mode is judged in its band.

Each search over frequency counts as many looks as bands of its width fit in the range
(:attr:`.base.Candidate.trials`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...modal.pairing import VISIBLE_PROMINENCE
from ..scoring import LEVEL_TOL, Z
from .base import Candidate, Finding, Significance, mode_group
from .context import Context
from .groups import MIN_POINTS, on_band
from .modal import merged, missing_seeds, nearest, pole
from .mode_finding import missing_mode, model_mode, seen_from
from .residual import Points, Residual
from .stats import LogFit, channel_reductions, fit_points, seen

#: the band around a mode: ± max(MIN_HALF_WIDTH, ZETA_WIDTHS·ζ) (relative), at most MAX_HALF
MIN_HALF_WIDTH = 0.1
ZETA_WIDTHS = 5.0
MAX_HALF_WIDTH = 0.4
#: highest damping of a fitted mode
ZETA_MAX = 0.3
#: a mode fitted in its band must lower the residual there at least this significantly
#: (p-value, before the search's own test), ...
BAND_P = 1e-3
#: ... and refitted on every frequency, keep at least this share of that reduction in band
WIDE_IN_BAND = 0.5
#: the band fits refitted on every frequency (the best by their gain in band), and the most
#: evaluations such a refit may take
N_WIDE = 2
WIDE_NFEV = 60
#: a model mode the data keep less than this share of (moved or not) is absent from them
SPURIOUS_SCALE = 0.25
#: seeds taken from the peaks of the excess over frequency, per round
N_PEAK_SEEDS = 2
#: their smoothing window (± relative frequency), and the largest damping read from a peak's
#: width
PEAK_WINDOW = 0.05
PEAK_ZETA_MAX = 0.05


def _half(zeta: float) -> float:
    return min(max(MIN_HALF_WIDTH, ZETA_WIDTHS * zeta), MAX_HALF_WIDTH)


def _names(res: Residual) -> dict[tuple[int, int, int], str]:
    return {
        (k, a, b): f"{o}.{i}"
        for k, st in enumerate(res.sets)
        for a, o in enumerate(st.outputs)
        for b, i in enumerate(st.inputs)
    }


def _trials(f_lo: float, f_hi: float, half: float) -> float:
    return max(1.0, math.log(f_hi / f_lo) / math.log1p(half))


# -- a mode the model lacks -------------------------------------------------------------


def missing_candidates(res: Residual, ctx: Context) -> list[Candidate]:
    f_lo, f_hi = ctx.freq_range(res)
    seeds = excess_peaks(res)
    if ctx.settings.modes:
        seeds = merged(seeds + missing_seeds(ctx.measured(), ctx.model(), list(ctx.data)))
    fits = []
    for f0, z0 in seeds:
        if f_lo < f0 < f_hi:
            b = _band_fit(res, f0, min(max(z0, 0.002), ZETA_MAX))
            if b is not None:
                fits.append(b)
    fits.sort(key=lambda b: -b.fit.gain)
    out = []
    for rank, b in enumerate(fits):
        cand = _finish(res, ctx, b, wide=rank < N_WIDE)
        if cand is not None:
            out.append(cand)
    return out


def excess_peaks(res: Residual, n: int = N_PEAK_SEEDS) -> list[tuple[float, float]]:
    """``(f, ζ₀)`` of the ``n`` largest local peaks of each data set's excess over frequency
    (summed over ± :data:`PEAK_WINDOW`) that stand above the noise there (``z > Z`` as in
    :mod:`.excess`), ``ζ₀`` from the width of the peak."""
    t = (1.0 + LEVEL_TOL) ** 2
    out: list[tuple[float, float]] = []
    for st in res.sets:
        e2 = np.abs(st.centred()) ** 2
        s, m, q = (np.sum(a, axis=(0, 1)) for a in (st.w * e2, st.w * st.mc, st.w**2 * st.q))
        f = st.freq_hz
        lf = np.log(f)
        win = [np.abs(lf - lf[j]) <= PEAK_WINDOW for j in range(f.size)]
        sm = np.array([s[k].sum() - m[k].sum() for k in win])
        z = np.array([(s[k].sum() - t * m[k].sum()) / (t * math.sqrt(max(q[k].sum(), 1e-300)))
                      for k in win])  # fmt: skip
        peaks = [j for j in range(1, f.size - 1)
                 if z[j] > Z and sm[j] >= sm[j - 1] and sm[j] >= sm[j + 1]]  # fmt: skip
        peaks.sort(key=lambda j: -sm[j])
        for j in peaks[:n]:
            above = sm >= 0.5 * sm[j]
            lo, hi = j, j
            while lo > 0 and above[lo - 1]:
                lo -= 1
            while hi < f.size - 1 and above[hi + 1]:
                hi += 1
            width = math.log(f[hi] / f[lo]) if hi > lo else 0.02
            out.append((float(f[j]), float(min(max(width / 2, 0.005), PEAK_ZETA_MAX))))
    return merged(out)


def _mode_model(pts: Points, idx: np.ndarray, n: int) -> tuple[Any, Any]:
    """``H_model + R/(s−λ) + R̄/(s−λ̄)`` at ``pts`` for ``θ = (ln f, ln ζ, Re R, Im R)``,
    ``R`` per channel (``idx``: each point's channel among ``n``), and its derivative."""

    def model(th: np.ndarray) -> np.ndarray:
        lam = pole(math.exp(th[0]), math.exp(th[1]))
        R = (th[2 : 2 + n] + 1j * th[2 + n :])[idx]
        return pts.Hs + R / (pts.s - lam) + np.conj(R) / (pts.s - np.conj(lam))

    def derivative(th: np.ndarray, sel: np.ndarray) -> np.ndarray:
        f, z = math.exp(th[0]), math.exp(th[1])
        lam = pole(f, z)
        ix = idx[sel]
        R = (th[2 : 2 + n] + 1j * th[2 + n :])[ix]
        s = pts.s[sel]
        p1, p2 = 1.0 / (s - lam), 1.0 / (s - np.conj(lam))
        w = 2 * math.pi * f
        root = math.sqrt(max(1.0 - z * z, 1e-12))
        dlam = (lam, z * w * complex(-1.0, -z / root))  # ∂λ/∂ln f, ∂λ/∂ln ζ
        out = np.zeros((s.size, 2 + 2 * n), complex)
        for k, dl in enumerate(dlam):
            out[:, k] = R * p1 * p1 * dl + np.conj(R) * p2 * p2 * np.conj(dl)
        rows = np.arange(s.size)
        out[rows, 2 + ix] = p1 + p2
        out[rows, 2 + n + ix] = 1j * (p1 - p2)
        return out

    return model, derivative


def _residue_layout(pts: Points) -> tuple[np.ndarray, np.ndarray]:
    """Per point, the index of its channel (data set, row, column) among the unique ones,
    and those unique keys."""
    keys = pts.channel_keys()
    uniq, idx = np.unique(keys, return_inverse=True)
    return idx, uniq


def _linear_residues(
    pts: Points, idx: np.ndarray, n: int, lam: complex
) -> tuple[np.ndarray, float]:
    """Per channel the residue that best fits ``H_meas − H_model`` relative to ``|H_meas|``
    for the pole ``lam`` (real-linear in ``Re R``, ``Im R``), and the cost it leaves."""
    p1 = 1.0 / (pts.s - lam)
    p2 = 1.0 / (pts.s - np.conj(lam))
    b_re, b_im = p1 + p2, 1j * (p1 - p2)
    y = (pts.Hm - pts.Hs) / np.abs(pts.Hm)
    sw = np.sqrt(pts.w) / np.abs(pts.Hm)
    R = np.zeros(n, complex)
    cost = 0.0
    for c in range(n):
        sel = idx == c
        X = np.stack([b_re[sel], b_im[sel]], axis=1) * sw[sel, None]
        A = np.concatenate([X.real, X.imag])
        rhs = np.concatenate([(y[sel] * np.sqrt(pts.w[sel])).real,
                              (y[sel] * np.sqrt(pts.w[sel])).imag])  # fmt: skip
        sol, *_ = np.linalg.lstsq(A, rhs, rcond=None)
        R[c] = complex(sol[0], sol[1])
        cost += float(np.sum((A @ sol - rhs) ** 2))
    return R, cost


@dataclass
class _BandFit:
    """A mode fitted in its band: the points, each point's channel (``idx``) among the
    channel keys ``uniq``, the fit, the band [Hz] and the bounds of ``θ``."""

    pts: Points
    idx: np.ndarray
    uniq: np.ndarray
    fit: LogFit
    band: tuple[float, float]
    lo: np.ndarray
    hi: np.ndarray


def _band_fit(res: Residual, f0: float, z0: float) -> _BandFit | None:
    """A mode near ``(f0, z0)`` fitted in its band; None when it does not show there."""
    h = _half(z0)
    band = (f0 / (1 + h), f0 * (1 + h))
    pts = res.points(on_band(*band))
    idx, uniq = _residue_layout(pts)
    n = uniq.size
    if pts.size < max(MIN_POINTS, 3 * (2 * n + 2)):
        return None
    # the start: the best of a small grid of poles, residues linear for each
    starts = [(f0 * (1 + df), z) for df in np.linspace(-h / 2, h / 2, 9)
              for z in (z0 / 2, z0, 2 * z0)]  # fmt: skip
    best = min(starts, key=lambda fz: _linear_residues(pts, idx, n, pole(*fz))[1])
    R0, _ = _linear_residues(pts, idx, n, pole(*best))
    theta0 = np.concatenate([[math.log(best[0]), math.log(min(best[1], ZETA_MAX))],
                             R0.real, R0.imag])  # fmt: skip
    lo = np.full(theta0.size, -np.inf)
    hi = np.full(theta0.size, np.inf)
    lo[:2] = math.log(band[0]), math.log(1e-4)
    hi[:2] = math.log(band[1]), math.log(ZETA_MAX)
    model, deriv = _mode_model(pts, idx, n)
    fit = fit_points(pts, model, theta0, lower=lo, upper=hi, derivative=deriv)
    if fit is None or fit.p_value > BAND_P:  # no mode shows in the band itself
        return None
    return _BandFit(pts, idx, uniq, fit, band, lo, hi)


def _finish(res: Residual, ctx: Context, b: _BandFit, wide: bool) -> Candidate | None:
    """The candidate of a band fit; with ``wide``, refitted on every frequency first.

    A mode's term reaches beyond its band (its stiffness below, its mass line above):
    refitted on every point of the channels fitted, it is kept so when it does better there
    and still shows in its band (not a far tail standing in for something else)."""
    pts, fit, band, n = b.pts, b.fit, b.band, b.uniq.size
    H_band, pts_band = fit.H, pts
    if wide:
        every = res.points()
        every = every.subset(np.isin(every.channel_keys(), b.uniq))
        model, deriv = _mode_model(every, np.searchsorted(b.uniq, every.channel_keys()), n)
        refit = fit_points(every, model, fit.theta, lower=b.lo, upper=b.hi, derivative=deriv,
                           max_nfev=WIDE_NFEV)  # fmt: skip
        inband = (every.f_hz >= band[0]) & (every.f_hz <= band[1])
        sub = every.subset(inband)
        if (
            refit is not None
            and refit.gain > fit.gain
            and sub.sq() - sub.sq(refit.H[inband]) >= WIDE_IN_BAND * fit.reduction
        ):
            pts, fit, H_band, pts_band = every, refit, refit.H[inband], sub
    f_hat, z_hat = math.exp(fit.theta[0]), math.exp(fit.theta[1])
    if not (band[0] * 1.01 < f_hat < band[1] / 1.01):  # pinned at the band's edge: no mode
        return None
    red = channel_reductions(pts_band, H_band)
    view = seen_from(red, seen(red, sum(d for d, _ in red.values())), _names(res))
    near = None
    if ctx.settings.modes:
        models = ctx.model()
        R = fit.theta[2 : 2 + n] + 1j * fit.theta[2 + n :]
        k_best = int(pts.k[np.argmax(pts.w)])
        st = res.sets[k_best]
        Rm = np.zeros(st.Hs.shape[:2], complex)
        for c, key in enumerate(b.uniq):
            k, rest = divmod(int(key), 10_000 * 10_000)
            if k == k_best:
                Rm[rest // 10_000, rest % 10_000] = R[c]
        if models and models[k_best]:
            near = nearest(f_hat, z_hat, Rm, models[k_best])

    def describe(sig: Significance) -> Finding:
        return missing_mode(sig, f_hat, z_hat, view, near, "additive", band)

    key = f"mode at {f_hat:.4g} Hz"
    return Candidate(key, pts, fit, ctx.resonance_looks(res, z_hat), describe, mode_group(f_hat))


# -- a model mode the data lack or place elsewhere ---------------------------------------


def model_candidates(res: Residual, ctx: Context) -> list[Candidate]:
    if not ctx.settings.modes:
        return []
    f_lo, f_hi = ctx.freq_range(res)
    models = ctx.model()
    ref = next((k for k, m in enumerate(models) if m), None)
    if ref is None:
        return []
    out = []
    for mode in models[ref]:
        if not (f_lo < mode.f_hz < f_hi) or not mode.prominence >= VISIBLE_PROMINENCE:
            continue
        per_set = _matching(models, mode)
        for moved in (False, True):
            cand = _model_mode(res, per_set, mode, moved, f_lo, f_hi)
            if cand is not None:
                out.append(cand)
    return out


def _matching(models: list[list[Any]], mode: Any) -> dict[int, Any]:
    """Per data set, its model mode nearest ``mode`` (within 5 %)."""
    out = {}
    for k, mm in enumerate(models):
        if not mm:
            continue
        m = min(mm, key=lambda x: abs(x.f_hz - mode.f_hz))
        if abs(m.f_hz - mode.f_hz) <= 0.05 * mode.f_hz:
            out[k] = m
    return out


def _model_mode(
    res: Residual, per_set: dict[int, Any], mode: Any, moved: bool, f_lo: float, f_hi: float
) -> Candidate | None:
    h = _half(mode.zeta)
    band = (mode.f_hz / (1 + h), mode.f_hz * (1 + h))

    def select(k: int, st: Any) -> np.ndarray:  # the mode's term reaches every frequency
        return np.full(st.Hm.shape, k in per_set)

    pts = res.points(select)
    if pts.size < MIN_POINTS:
        return None
    lam = np.empty(pts.size, complex)
    R = np.empty(pts.size, complex)
    for k, m in per_set.items():
        s = pts.k == k
        lam[s] = m.eigenvalue
        R[s] = np.asarray(m.residues)[pts.a[s], pts.b[s]]
    own = R / (pts.s - lam) + np.conj(R) / (pts.s - np.conj(lam))
    base = pts.Hs - own

    if not moved:

        def model(th: np.ndarray) -> np.ndarray:
            return base + (th[0] + 1j * th[1]) * own

        fit = fit_points(pts, model, np.array([0.0, 0.0]))
    else:
        w0, z0 = np.abs(lam), -lam.real / np.abs(lam)

        def model(th: np.ndarray) -> np.ndarray:
            w = w0 * math.exp(th[0])
            z = np.clip(z0 * math.exp(th[1]), 0.0, 0.999)
            lm = -z * w + 1j * w * np.sqrt(1 - z * z)
            c = th[2] + 1j * th[3]
            return base + c * (R / (pts.s - lm) + np.conj(R) / (pts.s - np.conj(lm)))

        fit = fit_points(pts, model, np.array([0.0, 0.0, 1.0, 0.0]),
                         lower=np.array([-h, -3.0, -np.inf, -np.inf]),
                         upper=np.array([h, 3.0, np.inf, np.inf]))  # fmt: skip
    if fit is None:
        return None
    inband = (pts.f_hz >= band[0]) & (pts.f_hz <= band[1])
    red = channel_reductions(pts.subset(inband), fit.H[inband])
    view = seen_from(red, seen(red, sum(d for d, _ in red.values())), _names(res))
    f_m, z_m = float(mode.f_hz), float(mode.zeta)
    if moved:
        f_new = f_m * math.exp(fit.theta[0])
        z_new = z_m * math.exp(fit.theta[1])
        scale = abs(complex(fit.theta[2], fit.theta[3]))
        key = f"model mode at {f_m:.4g} Hz moved"

        def describe(sig: Significance) -> Finding:
            moved = (f_new, z_new) if scale >= SPURIOUS_SCALE else None  # nothing left: absent
            return model_mode(sig, f_m, z_m, scale, moved, view, band)
    else:
        scale = abs(complex(fit.theta[0], fit.theta[1]))
        key = f"model mode at {f_m:.4g} Hz absent"

        def describe(sig: Significance) -> Finding:
            return model_mode(sig, f_m, z_m, scale, None, view, band)

    looks = _trials(f_lo, f_hi, h) if moved else 1.0
    return Candidate(key, pts, fit, looks, describe, mode_group(f_m))
