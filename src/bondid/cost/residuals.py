"""Residual kinds: how a model FRF is compared with a measured one, with derivatives.

Every kind maps complex model values ``Hs`` and measured values ``Hm`` (same shape) to real
residuals, and maps the model's derivatives ``dHs/dp`` to residual derivatives, so the cost
stays a (weighted) sum of squares and its Jacobian is exact.

========================  ======================================================  ===========
name                      residual                                                 seed report
========================  ======================================================  ===========
``complex_log``           (20/ln10)·[Re, Im] log(Hs/Hm), phase wrapped (−π, π]      default
``log_magnitude``         20·log10|Hs| − 20·log10|Hm| (dB)                          (6.2)
``normalised_complex``    [Re, Im] (Hs − Hm)/|Hm|                                   (6.3)
``linear_magnitude``      (|Hs| − |Hm|) / rms(|Hm| of the channel)                  (6.1)
========================  ======================================================  ===========

``complex_log`` gives the spec's ``db_rms`` directly: the root-mean-square over complex points
of ``(20/ln10)|ln(Hm/Hs)|`` equals the RMS of its two real parts per point.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ConfigError

DB = 20.0 / np.log(10.0)
RESIDUAL_KINDS: tuple[str, ...] = (
    "complex_log",
    "log_magnitude",
    "normalised_complex",
    "linear_magnitude",
)
NORMS: tuple[str, ...] = ("l2", "l1")


def check_kind(kind: str, norm: str = "l2") -> None:
    if kind not in RESIDUAL_KINDS:
        raise ConfigError(f"unknown cost {kind!r}; valid: {', '.join(RESIDUAL_KINDS)}")
    if norm not in NORMS:
        raise ConfigError(f"unknown norm {norm!r}; valid: {', '.join(NORMS)}")


def parts(kind: str) -> int:
    """Real residuals per complex point: 2 for complex kinds, 1 for magnitude kinds."""
    return 2 if kind in ("complex_log", "normalised_complex") else 1


def wrap(phase: np.ndarray) -> np.ndarray:
    """Wrap radians into (−π, π]."""
    return np.pi - np.mod(np.pi - phase, 2.0 * np.pi)


def residual(
    kind: str, Hs: np.ndarray, Hm: np.ndarray, scale: np.ndarray | None = None
) -> np.ndarray:
    """Residuals ``(parts, *Hs.shape)`` of ``kind``; ``scale`` (broadcastable) only for
    ``linear_magnitude`` (the per-channel RMS of |Hm|)."""
    if kind == "complex_log":
        L = np.log(Hs / Hm)
        return DB * np.stack([L.real, wrap(L.imag)])
    if kind == "log_magnitude":
        return DB * np.log(np.abs(Hs) / np.abs(Hm))[None]
    if kind == "normalised_complex":
        e = (Hs - Hm) / np.abs(Hm)
        return np.stack([e.real, e.imag])
    if kind == "linear_magnitude":
        s = 1.0 if scale is None else scale
        return ((np.abs(Hs) - np.abs(Hm)) / s)[None]
    raise ConfigError(f"unknown cost {kind!r}; valid: {', '.join(RESIDUAL_KINDS)}")


def residual_jacobian(
    kind: str,
    Hs: np.ndarray,
    Hm: np.ndarray,
    dHs: np.ndarray,
    scale: np.ndarray | None = None,
) -> np.ndarray:
    """Derivatives ``(parts, *Hs.shape, n_p)`` of :func:`residual`.

    ``dHs`` is ``(*Hs.shape, n_p)``: the model FRF's derivatives.
    """
    if kind == "complex_log":
        g = dHs / Hs[..., None]
        return DB * np.stack([g.real, g.imag])
    if kind == "log_magnitude":
        return DB * (dHs / Hs[..., None]).real[None]
    if kind == "normalised_complex":
        g = dHs / np.abs(Hm)[..., None]
        return np.stack([g.real, g.imag])
    if kind == "linear_magnitude":
        s = 1.0 if scale is None else np.asarray(scale)[..., None]
        g = (np.conj(Hs)[..., None] * dHs).real / np.abs(Hs)[..., None]
        return (g / s)[None]
    raise ConfigError(f"unknown cost {kind!r}; valid: {', '.join(RESIDUAL_KINDS)}")


def robust(r: np.ndarray, norm: str, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """Map residuals for the chosen norm, keeping a sum-of-squares form.

    ``l2``: identity. ``l1``: pseudo-Huber ρ(r) = 2δ²(√(1+(r/δ)²) − 1) (≈ r² near 0, ≈ 2δ|r|
    for |r| ≫ δ) written as r̃ = sign(r)·√ρ(r), so ‖r̃‖² = Σρ. Returns (r̃, dr̃/dr).
    """
    if norm == "l2":
        return r, np.ones_like(r)
    s = np.sqrt(1.0 + (r / delta) ** 2)
    rho = 2.0 * delta**2 * (s - 1.0)
    rt = np.sign(r) * np.sqrt(rho)
    # d r̃/dr = ρ'(r) / (2 √ρ) with ρ' = 2 r / s; limit 1 at r = 0
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.where(rho > 0, np.abs(r) / (s * np.sqrt(np.maximum(rho, 1e-300))), 1.0)
    return rt, d
