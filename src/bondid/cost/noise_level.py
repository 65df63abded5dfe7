"""The noise level: the cost that a model without any error would still score on noisy data.

A measured point is ``H_m = H (1 + u)`` with ``u`` complex Gaussian of variance ``v = N/S``
(the noise-to-signal ratio of that point). The complex-log error of the exact model is then
``ln(1 + u)``, whose mean square has a closed form per radius ``r = |u|`` (angular average,
principal branch):

    F(r) = Li₂(r²)                                        r ≤ 1
    F(r) = ln² r + π²/3 + Li₂(r⁻²) − 2 Li₂(r⁻¹)           r > 1

(for the magnitude part alone, ``ln²|1 + u|``: ``½ Li₂(r²)`` and ``ln² r + ½ Li₂(r⁻²)``), and
``E|ln(1 + u)|² = ∫₀^∞ e⁻ˣ F(√(v x)) dx`` (``|u|²/v`` is exponential). For small ``v`` it is
``v``; for pure noise (``v → ∞``) it is ``((ln v − γ)² + π²/6)/4 + π²/3``.
:func:`expected_log_error` tabulates it once (adaptive quadrature, split at ``r = 1``) and
interpolates in ``ln v``.

:func:`noise_level_cost` sums it over the points of a :class:`~bondid.cost.problem.FrfProblem`
with the problem's own weights, the noise-to-signal ratio of each point taken from the data
(the estimate of :mod:`bondid.data.noise_estimate`, combined with the file's coherence where
there is one, as the ``auto`` weights do): the expected weighted mean square error of the true
model, i.e. ``db_rms²`` at the noise level for the ``complex_log`` cost. On the bundled data it
predicts 1.33 dB; the truth model scores 1.338 dB.
"""

from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING

import numpy as np

from ..data.measurement import FrfData
from ..data.weights import noise_to_signal
from ..exceptions import ConfigError
from .residuals import DB
from .selection import used_points

if TYPE_CHECKING:
    from .problem import FrfProblem

#: ``ln v`` grid of the table (``v`` from 1e-6 to 1e8; below, ``E = v`` to a relative 1e-6)
_LOG_V = np.linspace(math.log(1e-6), math.log(1e8), 169)
_X_MAX = 60.0  # the quadrature's split of the exponential weight (e⁻⁶⁰ is nothing)


def _li2(x: float) -> float:
    from scipy.special import spence

    return float(spence(1.0 - x))  # scipy's spence(z) = Li₂(1 − z)


def _angular(r: float, magnitude: bool) -> float:
    """``F(r)`` of the module docstring (complex, or the magnitude part alone)."""
    if r <= 1.0:
        return (0.5 if magnitude else 1.0) * _li2(r * r)
    lr = math.log(r)
    if magnitude:
        return lr * lr + 0.5 * _li2(1.0 / (r * r))
    return lr * lr + math.pi**2 / 3.0 + _li2(1.0 / (r * r)) - 2.0 * _li2(1.0 / r)


@functools.lru_cache(maxsize=2)
def _table(magnitude: bool) -> np.ndarray:
    from scipy.integrate import quad

    out = np.empty(_LOG_V.size)
    for k, lv in enumerate(_LOG_V):
        v = math.exp(lv)

        def f(x: float, v: float = v) -> float:
            return math.exp(-x) * _angular(math.sqrt(v * x), magnitude)

        split = 1.0 / v  # r = 1, where F has a log singularity in its derivative
        kinks = [split] if split < _X_MAX else None
        out[k] = quad(f, 0.0, _X_MAX, points=kinks, limit=200)[0] + quad(f, _X_MAX, math.inf)[0]
    return np.log(out)


def expected_log_error(v: np.ndarray, magnitude: bool = False) -> np.ndarray:
    """``E|ln(1 + u)|²`` (or ``E ln²|1 + u|`` with ``magnitude``) for ``u`` complex Gaussian
    of variance ``v`` (any shape, ≥ 0; inf allowed) — natural-log units, not dB."""
    v = np.asarray(v, dtype=float)
    small = 0.5 * v if magnitude else v
    with np.errstate(divide="ignore", invalid="ignore"):
        lv = np.log(np.maximum(v, 1e-300))
    inner = np.exp(np.interp(lv, _LOG_V, _table(magnitude)))
    # beyond the table: the small-v limit, and pure noise above 1e8 (ln|u| = ½ ln(v x) with
    # x exponential: E ln x = −γ, var ln x = π²/6; a uniform phase adds π²/3)
    g = 0.5772156649015329
    big = 0.25 * ((lv - g) ** 2 + math.pi**2 / 6) + (0.0 if magnitude else math.pi**2 / 3)
    return np.where(lv < _LOG_V[0], small, np.where(lv > _LOG_V[-1], big, inner))


def _panels(breaks: np.ndarray, n: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights of composite ``n``-point Gauss–Legendre on the panels ``breaks``."""
    x, w = np.polynomial.legendre.leggauss(n)
    a, b = breaks[:-1, None], breaks[1:, None]
    return (0.5 * (a + b) + 0.5 * (b - a) * x).ravel(), (0.5 * (b - a) * w).ravel()


@functools.lru_cache(maxsize=1)
def _var_table() -> np.ndarray:
    """``ln Var|ln(1 + u)|²`` on the ``ln v`` grid.

    The angular means ``F(r)`` and ``G(r)`` of ``|ln(1 + r e^{iθ})|²`` and of its square are
    taken once on a fixed radial rule and reused for every ``v``: ``E[·] = ∫ (2r/v) e^{−r²/v}
    ·(r) dr``. Both rules are composite Gauss–Legendre whose panels are graded geometrically
    (down to 2⁻³⁵) towards the singularity at ``u = −1``: in ``θ`` towards π, in ``ln r``
    towards 0 from both sides (uniform unit panels in ``ln r`` from e⁻¹⁵ to e¹²). Checked
    against the closed form of ``E|ln(1 + u)|²`` (to ~1e-7 relative) and a Monte-Carlo
    estimate (tests/test_noise_level.py). The former rule (Gauss–Laguerre in ``|u|²/v`` and
    the trapezoid in ``θ``, through the singularity) was 17 % high at ``v = 1``."""
    grade = 2.0 ** -np.arange(36.0)
    th, wth = _panels(np.unique(np.concatenate([[0.0, math.pi], math.pi * (1.0 - grade)])))
    s, ws = _panels(np.unique(np.concatenate([np.arange(-15.0, 13.0), -grade, grade])))
    r = np.exp(s)
    e2 = np.abs(np.log1p(r[:, None] * np.exp(1j * th)[None, :])) ** 2
    mean_f, mean_g = (e2 @ wth) / math.pi, ((e2 * e2) @ wth) / math.pi  # θ over [0, π]
    v = np.exp(_LOG_V)[:, None]
    kernel = (ws * r)[None, :] * (2.0 * r / v) * np.exp(-(r * r) / v)  # (n_v, n_r)
    m1, m2 = kernel @ mean_f, kernel @ mean_g
    return np.log(np.maximum(m2 - m1 * m1, 1e-300))


def log_error_variance(v: np.ndarray) -> np.ndarray:
    """``Var |ln(1 + u)|²`` for ``u`` complex Gaussian of variance ``v`` (natural-log units
    squared, any shape): ``v²`` for small ``v`` (``|u|²`` is exponential); between the table's
    ends interpolated in ``ln v``; above ``1e8``, the table's last value scaled by
    ``(ln v)²`` (``|ln(1 + u)|² ≈ ¼ ln²(v x) + θ²``)."""
    v = np.asarray(v, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        lv = np.log(np.maximum(v, 1e-300))
    tab = _var_table()
    inner = np.exp(np.interp(lv, _LOG_V, tab))
    big = math.exp(tab[-1]) * (lv / _LOG_V[-1]) ** 2
    return np.where(lv < _LOG_V[0], v * v, np.where(lv > _LOG_V[-1], big, inner))


#: the two bases of a point's ``N/S`` (:func:`point_noise_to_signal`)
BASES: tuple[str, ...] = ("prediction", "weights")


def _from_original(ds: FrfData, original: FrfData, weighting: str) -> np.ndarray | None:
    """The prediction's ``N/S`` of ``original`` under ``weighting`` at the points of ``ds``
    (same channels, frequencies a subset of the original's), or None when they do not map."""
    orig = original
    idx = np.clip(np.searchsorted(orig.freq_hz, ds.freq_hz), 0, orig.freq_hz.size - 1)
    if not np.allclose(orig.freq_hz[idx], ds.freq_hz, rtol=1e-9, atol=0.0):
        return None
    try:
        oi = [orig.outputs.index(o) for o in ds.outputs]
        ii = [orig.inputs.index(i) for i in ds.inputs]
    except ValueError:
        return None
    full = noise_to_signal(orig, weighting, prediction=True)
    return full[np.ix_(np.array(oi, int), np.array(ii, int), idx)]


def point_noise_to_signal(
    ds: FrfData, weighting: str, basis: str,
    original: tuple[FrfData, str] | None = None,
) -> np.ndarray:  # fmt: skip
    """``N/S`` of every point of ``ds`` (``(n_out, n_in, n_freq)``; NaN where ``H`` is NaN)
    for predicting an exact model's error, on one of two bases (:data:`BASES`):

    * ``"prediction"``: the noise estimate's signal taken as ``P̄ − 2N̂``
      (:data:`~bondid.data.noise_estimate.PREDICTION_MARGIN`): the unbiased prediction of the
      error. For anything that makes a statistical claim against the level: the verdict's
      held-out reference (:func:`bondid.diagnose.scoring.heldout_noise`) and ``bondid.fit``'s
      "at the noise level" (``fit.json``'s ``db_rms.noise_level``, its fallbacks).
      ``original``: ``(data set, its weighting rule)`` that ``ds`` was cut from before its
      weights went into its coherence (the diagnosis); the prediction is taken from it at
      the same points (from ``ds`` itself when they do not map).
    * ``"weights"``: the ``N/S`` the weights themselves hold (``w = 1/(1 + N/S)``; the
      estimate's part with the cautious ``P̄ − 3N̂``): the level comes out 10–20 % high.
      The stopping test of a diagnosis refit's loop (:mod:`bondid.diagnose.refit_job`):
      there the training data hold only the weights; it decides when more starts are
      worth it, not a statistical claim.

    Under ``weighting="coherence"`` the coherence is taken as it is on either basis (it holds
    no estimate to take the prediction's signal from).
    """
    if basis not in BASES:
        raise ConfigError(f"noise-to-signal basis {basis!r} is invalid; valid: {', '.join(BASES)}")
    if basis == "weights":
        return noise_to_signal(ds, weighting, prediction=False)
    if original is not None:
        ns = _from_original(ds, original[0], original[1])
        if ns is not None:
            return ns
    return noise_to_signal(ds, weighting, prediction=True)


def expected_sq_db(
    ds: FrfData, use_coherence: bool = True, magnitude: bool = False,
    weighting: str | None = None, basis: str = "prediction",
) -> np.ndarray:  # fmt: skip
    """Expected squared error (dB²) of an exact model at every point of ``ds``,
    ``(n_out, n_in, n_freq)``: ``(20/ln 10)² E|ln(1 + u)|²`` with ``v = N/S`` of the point from
    the data's noise estimate, combined with the file's coherence where there is one (the
    ``auto`` rule of :mod:`bondid.data.weights`; ``use_coherence=False``: the estimate alone;
    ``weighting="coherence"``: the coherence alone, e.g. when it already holds information
    weights, as in the diagnosis), on the ``basis`` of :func:`point_noise_to_signal`. NaN
    where ``H`` is NaN."""
    if weighting != "coherence":
        weighting = "auto" if use_coherence else "estimated"
    ns = point_noise_to_signal(ds, weighting, basis)
    out = DB**2 * expected_log_error(np.where(np.isnan(ns), 0.0, ns), magnitude)
    out[np.isnan(ns)] = np.nan
    return out


def weighted_level(sq_db: list[np.ndarray], weights: list[np.ndarray]) -> float | None:
    """``sqrt(Σ w e² / Σ w)`` (dB) of expected squared errors and their weights (flat arrays;
    a point of weight 0 counts nothing, even where its expected error is infinite; a point
    whose expected error is NaN, its noise unknown, is left out of both sums)."""
    num = den = 0.0
    for e, w in zip(sq_db, weights, strict=True):
        known = (w > 0) & ~np.isnan(e)
        with np.errstate(invalid="ignore"):
            num += float(np.sum(np.where(known, w * e, 0.0)))
        den += float(np.sum(np.where(known, w, 0.0)))
    return math.sqrt(num / den) if den > 0 else None


def noise_level_cost(problem: FrfProblem, basis: str = "prediction") -> float | None:
    """Expected cost ``‖r‖²`` of an exact model on the problem's noisy data (module docstring).

    Args:
        problem: the fitting problem (its weights, channel weights included, and points).
        basis: of each point's ``N/S`` (:func:`point_noise_to_signal`: which caller takes
            which, and why).

    Returns:
        The expected cost (dB² for the log kinds: ``db_rms²`` at the noise level), or None
        for a cost this module does not model (kinds other than ``complex_log`` and
        ``log_magnitude``, or the ``l1`` norm).
    """
    opt = problem.options
    if opt.kind not in ("complex_log", "log_magnitude") or opt.norm != "l2":
        return None
    sq, ws = [], []
    for b in problem.blocks:
        ds = b.data
        e = expected_sq_db(
            ds, opt.use_coherence, magnitude=opt.kind != "complex_log",
            weighting=opt.effective_weighting, basis=basis,
        )  # fmt: skip
        sq.append(e[used_points(ds, opt)])
        ws.append(b.weight)
    level = weighted_level(sq, ws)
    return None if level is None else level**2
