"""Fitting a finding's few parameters to the log residual, and its significance against the
noise: :func:`fit_points`, :class:`LogFit`.

A finding is a correction ``H(θ)`` of the model at some points (:class:`.residual.Points`).
Its parameters are fitted by weighted least squares on the log residual,

    S(θ) = Σ w |ln(H_meas / H(θ))|²,

with the information weights ``w`` (the weighting of every figure of the remainder). The
finding's *reduction* is ``ΔS = S(θ₀) − S(θ̂)`` (``θ₀``: no correction).

**Significance.** Were the model exact, each real part of a point's log residual would be
noise of variance ``m/2`` (:mod:`.residual`). Linearised at ``θ̂`` (``J`` the Jacobian of
the real residuals ``√w·[Re, Im] e``, ``Σ = diag(w m / 2)``), the reduction pure noise gives
is a weighted sum of ``χ²₁`` with weights the eigenvalues ``λ`` of ``(JᵀJ)⁻¹ JᵀΣJ`` (``p``
of them), approximated by ``c·χ²_ν`` with ``c = Σλ²/Σλ``, ``ν = (Σλ)²/Σλ²``
(Satterthwaite); the *p-value* is ``P(c·χ²_ν ≥ ΔS)``. Two guards keep this honest when the
noise is not the only thing left: the noise's ``m`` is scaled by ``(1 + LEVEL_TOL)²`` (the
tolerance of the predicted noise level, :data:`bondid.diagnose.scoring.LEVEL_TOL`) and by
the misfit that remains at the finding's points, ``κ = max(1, S(θ̂) / Σ w m)`` (a finding
fitted to structure it does not describe leaves a large misfit, and is judged against it).
A third guard keeps it from resting on a few points: the log error of a point has a heavy
tail (where the noise nearly cancels the signal, ``|1 + u| → 0``, ``|ln(1 + u)|`` grows
without bound), far heavier than the Gaussian approximation's, and a narrow resonance or
a large leakage can be fitted to one such outlier; the test is taken on ``ΔS`` less the
reduction its :data:`TOP_OUT` largest points carry (a real finding rests on many).
The parameters' covariance is the sandwich ``(JᵀJ)⁻¹ JᵀΣJ (JᵀJ)⁻¹`` with the same scaling.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..scoring import LEVEL_TOL
from .residual import Points

#: the test leaves out the share of the reduction that this many points carry (module
#: docstring)
TOP_OUT = 3
#: Jacobians with more entries than this are solved iteratively in the fits
LARGE_JACOBIAN = 200_000
#: the most Jacobian entries a fit holds at once (16 MB); beyond, it fits on fewer points
JACOBIAN_BUDGET = 2_000_000
#: ``H(θ)`` at the points of a fit
Model = Callable[[np.ndarray], np.ndarray]
#: ``∂H/∂θ`` at the points ``sel`` (index array) of a fit, ``(len(sel), p)`` complex
Derivative = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass
class LogFit:
    """A fitted correction at a set of points.

    Attributes:
        theta: fitted parameters ``(p,)``.
        cov: their covariance ``(p, p)`` (module docstring).
        H: the corrected model at the points ``(N,)``.
        s0, s1: ``Σ w |e|²`` before and after (natural-log units²).
        null_mean: what pure noise would remove on average (``Σλ``).
        null_scale, null_dof: ``c`` and ``ν`` of the noise's reduction ``c·χ²_ν``.
        p_value: ``P(c·χ²_ν ≥ ΔS)``.
        kappa: the misfit scaling ``κ`` of the module docstring.
        top: the part of ``ΔS`` its :data:`TOP_OUT` largest points carry (left out of the
            test).
    """

    theta: np.ndarray
    cov: np.ndarray
    H: np.ndarray
    s0: float
    s1: float
    null_mean: float
    null_scale: float
    null_dof: float
    p_value: float
    kappa: float
    top: float = 0.0

    @property
    def reduction(self) -> float:
        """``ΔS = s0 − s1``."""
        return self.s0 - self.s1

    @property
    def gain(self) -> float:
        """``ΔS`` less what noise would remove on average (the ranking figure)."""
        return self.reduction - self.null_mean

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    @property
    def statistic(self) -> float:
        """``ΔS / c``: compare with ``χ²_ν``."""
        return self.reduction / self.null_scale if self.null_scale > 0 else math.inf


def weighted_residuals(pts: Points, H: np.ndarray) -> np.ndarray:
    """``√w·[Re, Im] ln(H_meas / H)`` ``(2N,)``."""
    e = pts.e(H)
    r = np.sqrt(pts.w)
    return np.concatenate([r * e.real, r * e.imag])


def fit_points(
    pts: Points,
    model: Model,
    theta0: np.ndarray,
    *,
    lower: np.ndarray | None = None,
    upper: np.ndarray | None = None,
    max_nfev: int = 200,
    derivative: Derivative | None = None,
) -> LogFit | None:
    """Fit ``θ`` of ``model`` by weighted least squares on the log residual at ``pts`` from
    ``theta0`` (bounds ``lower``/``upper``), with the figures of the module docstring.
    ``derivative(θ, sel)``: ``∂H/∂θ`` at the points ``sel`` (an index array) ``(n, p)``
    complex (finite differences when None).

    Where the Jacobian would hold more than :data:`JACOBIAN_BUDGET` entries the parameters
    are fitted on evenly spread points within it; the figures are taken on every point.

    Returns None when the fit fails (a non-finite model or no point)."""
    from scipy.optimize import least_squares

    theta0 = np.asarray(theta0, dtype=float)
    if pts.size == 0:
        return None
    lo = np.full(theta0.size, -np.inf) if lower is None else np.asarray(lower, float)
    hi = np.full(theta0.size, np.inf) if upper is None else np.asarray(upper, float)
    pad = 1e-9 * (1.0 + np.abs(np.where(np.isfinite(lo), lo, 0.0)))
    x0 = np.clip(
        theta0, np.where(np.isfinite(lo), lo + pad, lo), np.where(np.isfinite(hi), hi - pad, hi)
    )
    most = max(JACOBIAN_BUDGET // (2 * theta0.size), 1)
    sel = np.arange(0, pts.size, max(1, -(-pts.size // most)))
    part = pts.subset(sel)

    def fun(th: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):
            r = weighted_residuals(part, model(th)[sel])
        return np.where(np.isfinite(r), r, 1e3)

    jac: Any = "2-point"
    if derivative is not None:
        root = np.sqrt(part.w)[:, None]

        def jac(th: np.ndarray) -> np.ndarray:
            with np.errstate(all="ignore"):
                # ∂ ln(H_meas/H) = −∂H/H
                d = -root * derivative(th, sel) / model(th)[sel][:, None]
            return np.nan_to_num(np.concatenate([d.real, d.imag]))

    try:
        # an iterative trust-region step where the Jacobian is large (an SVD per step costs
        # more than the whole fit of a few parameters)
        solver = "lsmr" if 2 * sel.size * x0.size > LARGE_JACOBIAN else "exact"
        sol = least_squares(
            fun, x0, jac=jac, bounds=(lo, hi), x_scale="jac", max_nfev=max_nfev, method="trf",
            tr_solver=solver,
        )  # fmt: skip
    except (ValueError, np.linalg.LinAlgError):
        return None
    if sel.size == pts.size:
        return assess(pts, model, sol.x, jac=sol.jac)
    return assess(pts, model, sol.x, derivative=derivative)


def assess(
    pts: Points, model: Model, theta: np.ndarray, *, jac: np.ndarray | None = None,
    derivative: Derivative | None = None,
) -> LogFit | None:  # fmt: skip
    """The figures of a correction at ``theta``: ``jac`` the Jacobian of
    :func:`weighted_residuals` there ``(2N, p)``, else from ``derivative`` (taken in blocks
    of points), else by finite differences."""
    theta = np.asarray(theta, dtype=float)
    with np.errstate(all="ignore"):
        H = model(theta)
    if not np.all(np.isfinite(H)):
        return None
    s0, s1 = pts.sq(), pts.sq(H)
    noise = float(np.sum(pts.w * pts.m))
    kappa = max(1.0, s1 / noise) if noise > 0 else 1.0
    half = 0.5 * pts.w * pts.m * (1.0 + LEVEL_TOL) ** 2 * kappa
    p = theta.size
    A, B = np.zeros((p, p)), np.zeros((p, p))
    step = max(JACOBIAN_BUDGET // (2 * p), 1)
    for start in range(0, pts.size, step):
        idx = np.arange(start, min(start + step, pts.size))
        if jac is not None:
            J = np.concatenate([jac[idx], jac[pts.size + idx]])
        elif derivative is not None:
            with np.errstate(all="ignore"):
                d = -np.sqrt(pts.w[idx])[:, None] * derivative(theta, idx) / H[idx][:, None]
            J = np.nan_to_num(np.concatenate([d.real, d.imag]))
        else:
            J = _jacobian(pts.subset(idx), _restricted(model, idx), theta)
        sig = np.concatenate([half[idx], half[idx]])
        A += J.T @ J
        B += J.T @ (sig[:, None] * J)
    try:
        Ainv = np.linalg.pinv(A)
    except np.linalg.LinAlgError:
        return None
    lam = np.clip(np.linalg.eigvals(Ainv @ B).real, 0.0, None)
    cov = Ainv @ B @ Ainv
    gains = pts.w * (np.abs(pts.e()) ** 2 - np.abs(pts.e(H)) ** 2)
    top = float(np.sum(np.sort(gains)[::-1][:TOP_OUT].clip(0.0)))
    return _figures(theta, cov, H, s0, s1, lam, kappa, top)


def _restricted(model: Model, idx: np.ndarray) -> Model:
    """``model`` at the points ``idx`` only."""

    def part(th: np.ndarray) -> np.ndarray:
        return model(th)[idx]

    return part


def _figures(
    theta: np.ndarray, cov: np.ndarray, H: np.ndarray, s0: float, s1: float,
    lam: np.ndarray, kappa: float, top: float,
) -> LogFit:  # fmt: skip
    from scipy.special import chdtrc  # χ² survival function (lighter than scipy.stats)

    l1, l2 = float(np.sum(lam)), float(np.sum(lam**2))
    if l1 <= 0 or l2 <= 0:
        c, nu, p = 0.0, 0.0, (0.0 if s0 - s1 > 0 else 1.0)
    else:
        c, nu = l2 / l1, l1 * l1 / l2
        p = float(chdtrc(nu, max(s0 - s1 - top, 0.0) / c))
    return LogFit(theta, cov, H, s0, s1, l1, c, nu, p, kappa, top)


def _jacobian(pts: Points, model: Model, theta: np.ndarray) -> np.ndarray:
    r0 = weighted_residuals(pts, model(theta))
    out = np.empty((r0.size, theta.size))
    for i in range(theta.size):
        h = 1e-6 * max(1.0, abs(theta[i]))
        t = theta.copy()
        t[i] += h
        with np.errstate(all="ignore"):
            out[:, i] = (weighted_residuals(pts, model(t)) - r0) / h
    return np.nan_to_num(out)


def channel_reductions(
    pts: Points, H: np.ndarray
) -> dict[tuple[int, int, int], tuple[float, float]]:
    """Per channel ``(data set, row, column)`` of ``pts``: ``(ΔS of the channel, its noise
    scale)`` for the corrected model ``H`` at ``pts``, the scale ``Σ w² m / (2 Σ w)`` (what
    one parameter fitted to that channel's noise removes on average, :func:`seen`)."""
    e0, e1 = pts.e(), pts.e(H)
    d = pts.w * (np.abs(e0) ** 2 - np.abs(e1) ** 2)
    out: dict[tuple[int, int, int], tuple[float, float]] = {}
    for key in np.unique(pts.channel_keys()):
        sel = pts.channel_keys() == key
        k, a, b = int(pts.k[sel][0]), int(pts.a[sel][0]), int(pts.b[sel][0])
        ws = float(np.sum(pts.w[sel]))
        scale = float(np.sum(pts.w[sel] ** 2 * pts.m[sel])) / (2 * ws) if ws > 0 else 0.0
        out[(k, a, b)] = (float(np.sum(d[sel])), scale * (1.0 + LEVEL_TOL) ** 2)
    return out


#: a channel "sees" a finding when its own reduction is at least this multiple of its noise
#: scale (≈ the 0.1 % point of a χ²₂ times 2: two parameters per channel, with margin)
SEEN_FACTOR = 2.0 * 13.8
#: ... and at least this share of the finding's reduction
SEEN_SHARE = 0.03


def seen(
    reductions: dict[tuple[int, int, int], tuple[float, float]], total: float
) -> list[tuple[int, int, int]]:
    """The channels whose reduction is clearly above their noise and a fair share of the
    total ``total`` (:data:`SEEN_FACTOR`, :data:`SEEN_SHARE`)."""
    return [
        key
        for key, (d, scale) in reductions.items()
        if d > SEEN_FACTOR * scale and d >= SEEN_SHARE * total
    ]


def scan(cost: Callable[[float], float], grid: np.ndarray, fine: int = 25) -> float:
    """The best value of ``cost`` on ``grid`` (sorted), then on a ``fine`` grid between the
    best point's neighbours: a start for a fit whose cost is narrow (a sharp resonance,
    a wrapped phase), where a gradient from a coarse start stops short."""
    c = np.array([cost(float(x)) for x in grid])
    i = int(np.nanargmin(np.where(np.isfinite(c), c, np.nan))) if np.any(np.isfinite(c)) else 0
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    if hi <= lo:
        return float(grid[i])
    finer = np.linspace(lo, hi, fine)
    cf = np.array([cost(float(x)) for x in finer])
    if not np.any(np.isfinite(cf)) or np.nanmin(cf) >= c[i]:
        return float(grid[i])
    return float(finer[int(np.nanargmin(np.where(np.isfinite(cf), cf, np.nan)))])
