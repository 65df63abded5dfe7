"""Rayleigh coefficients from a model's modes: a start, the scales and the default upper bounds.

A mode of natural angular frequency ``ω`` under ``D = α M + β K`` has the damping ratio

    ζ(ω) = α / (2ω) + β ω / 2,

so ``α`` damps the low modes and ``β`` the high ones. :func:`rayleigh_start` fits ``(α, β)``
to the damping ratios the model's joint dampers give its vibration modes (non-negative least
squares over the modes within a band): the proportional damping closest to the model's. A
model whose modes are undamped has no such ratios; its start is then :func:`reference` — the
coefficients of which each alone gives ``ζ = ZETA_REF`` at one end of the band. The same
reference scales the fit's variables (:mod:`bondid.optim.model_vars`), and
:func:`upper_bounds` bounds them: ``α`` at most what alone damps the lowest vibration mode
critically, ``β`` at most what alone damps a mode at the data's highest frequency critically.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .affine import AffineModel

#: the damping ratio of the reference coefficients (light structural damping)
ZETA_REF = 0.005
#: damping ratios at or below this count as none (round-off of an undamped model's modes)
ZETA_MIN = 1e-9
#: the band's ends when the model has no vibration mode in it (Hz)
FALLBACK_BAND_HZ = (1.0, 4000.0)


@dataclass(frozen=True)
class RayleighStart:
    """A start of ``(alpha (1/s), beta (s))`` and how it was found (``how``, for reports)."""

    alpha: float
    beta: float
    how: str


def _modes(affine: AffineModel, damped: bool) -> list[tuple[float, float]]:
    """``(f_hz, ζ)`` of the model's vibration modes (undamped ones when not ``damped``)."""
    from .linear_model import underdamped

    M, K = affine.mass_matrix(), affine.stiffness_matrix()
    D = affine.damping_matrix() if damped else np.zeros_like(M)
    try:
        return underdamped(M, K, D)
    except np.linalg.LinAlgError:  # a DOF without mass: no modes to speak of
        return []


def _within(modes: Sequence[tuple[float, float]], band_hz: tuple[float, float] | None):
    """The modes inside ``band_hz`` (all of them when the band holds none or is None)."""
    if band_hz is None:
        return list(modes)
    inside = [m for m in modes if band_hz[0] <= m[0] <= band_hz[1]]
    return inside or list(modes)


def _span(affine: AffineModel, band_hz: tuple[float, float] | None) -> tuple[float, float]:
    """Lowest and highest undamped vibration frequency (rad/s) of the model in the band."""
    f = [m[0] for m in _within(_modes(affine, damped=False), band_hz)]
    lo, hi = (min(f), max(f)) if f else (band_hz or FALLBACK_BAND_HZ)
    return 2.0 * np.pi * lo, 2.0 * np.pi * max(hi, lo)


def reference(
    affine: AffineModel, band_hz: tuple[float, float] | None = None
) -> tuple[float, float, float]:
    """``(α_ref, β_ref, η_ref)``: ``α_ref`` alone gives ``ZETA_REF`` at the lowest vibration
    mode in ``band_hz`` (Hz), ``β_ref`` alone at the highest one, the loss factor ``η_ref``
    alone at every mode (1/s, s, 1; always > 0)."""
    w_lo, w_hi = _span(affine, band_hz)
    return 2.0 * ZETA_REF * w_lo, 2.0 * ZETA_REF / w_hi, 2.0 * ZETA_REF


def fit_coefficients(f_hz: np.ndarray, zeta: np.ndarray) -> tuple[float, float]:
    """Non-negative least squares of ``ζ_i = α/(2ω_i) + β ω_i/2`` (``f_hz``, ``zeta``
    ``(n,)``, ``ω = 2π f``); returns ``(α (1/s), β (s))``."""
    from scipy.optimize import nnls

    w = 2.0 * np.pi * np.asarray(f_hz, dtype=float)
    A = np.column_stack([0.5 / w, 0.5 * w])
    s = np.abs(A).max(axis=0)  # columns of one size: nnls is not scale invariant
    x, _ = nnls(A / s, np.asarray(zeta, dtype=float))
    return float(x[0] / s[0]), float(x[1] / s[1])


def rayleigh_start(
    affine: AffineModel, band_hz: tuple[float, float] | None = None
) -> RayleighStart:
    """The start of ``(α, β)`` for ``affine`` (module docstring); ``band_hz``: the data's band
    (Hz), None = every vibration mode. A coefficient the least squares puts at 0 starts at 1 %
    of its reference, inside its bounds."""
    ref = reference(affine, band_hz)
    modes = [m for m in _within(_modes(affine, damped=True), band_hz) if m[1] > ZETA_MIN]
    if not modes:
        return RayleighStart(*ref[:2], how=f"no damped mode: ζ = {ZETA_REF:g} at the band's ends")
    f, z = (np.array(v) for v in zip(*modes, strict=True))
    a, b = fit_coefficients(f, z)
    how = (
        f"least squares on the damping ratios of {len(modes)} mode(s),"
        f" {f.min():.4g}–{f.max():.4g} Hz"
    )
    return RayleighStart(max(a, 0.01 * ref[0]), max(b, 0.01 * ref[1]), how)


def loss_start(
    affine: AffineModel, band_hz: tuple[float, float] | None = None
) -> tuple[float, str]:
    """The start of the loss factor ``η`` and how it was found: twice the median damping ratio
    of the model's vibration modes in ``band_hz`` (Hz) as written (its joint dampers and any
    ``α·M + β·K``; a loss factor gives every mode ``ζ = η/2``), else :func:`reference`'s."""
    modes = [m for m in _within(_modes(affine, damped=True), band_hz) if m[1] > ZETA_MIN]
    if not modes:
        return 2.0 * ZETA_REF, f"no damped mode: ζ = {ZETA_REF:g} at every mode"
    z = float(np.median([m[1] for m in modes]))
    return 2.0 * z, f"twice the median damping ratio of {len(modes)} mode(s), ζ = {z:.3g}"


def upper_bounds(affine: AffineModel, f_max_hz: float) -> tuple[float, float, float]:
    """``(α_max, β_max, η_max)``: α alone critical (ζ = 1) at the lowest vibration mode, β
    alone critical at ``f_max_hz`` (the data's highest frequency, Hz), η alone critical at
    every mode."""
    w_lo, _ = _span(affine, None)
    return 2.0 * w_lo, 2.0 / (2.0 * np.pi * float(f_max_hz)), 2.0
