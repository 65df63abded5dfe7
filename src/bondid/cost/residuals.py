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


def _derivative_factor(
    kind: str, Hs: np.ndarray, Hm: np.ndarray, scale: np.ndarray | None
) -> np.ndarray:
    """Complex ``c`` per point such that the residual's derivatives are the real (and, for the
    complex kinds, imaginary) part of ``c · dHs``."""
    if kind in ("complex_log", "log_magnitude"):
        return DB / Hs
    if kind == "normalised_complex":
        return 1.0 / np.abs(Hm)
    if kind == "linear_magnitude":
        s = 1.0 if scale is None else np.asarray(scale)
        return np.conj(Hs) / (np.abs(Hs) * s)
    raise ConfigError(f"unknown cost {kind!r}; valid: {', '.join(RESIDUAL_KINDS)}")


def residual_jacobian(
    kind: str,
    Hs: np.ndarray,
    Hm: np.ndarray,
    dHs: np.ndarray,
    scale: np.ndarray | None = None,
    weight: np.ndarray | None = None,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Derivatives ``(parts, *Hs.shape, n_p)`` of :func:`residual`, optionally weighted.

    Args:
        kind: residual kind.
        Hs, Hm: model and measured FRF values (same shape), complex.
        dHs: ``(*Hs.shape, n_p)`` complex: the model FRF's derivatives.
        scale: per-point channel scale, only for ``linear_magnitude``.
        weight: ``(parts, *Hs.shape)`` real factor per residual (e.g. √weight × the robust
            norm's slope); None = 1.
        out: where to write the result (real, ``(parts, *Hs.shape, n_p)``); None = new.
    """
    return residual_jacobian_parts(kind, Hs, Hm, dHs.real, dHs.imag, scale, weight, out)


def residual_jacobian_parts(
    kind: str,
    Hs: np.ndarray,
    Hm: np.ndarray,
    dRe: np.ndarray,
    dIm: np.ndarray,
    scale: np.ndarray | None = None,
    weight: np.ndarray | None = None,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """:func:`residual_jacobian` from the real and imaginary parts ``(*Hs.shape, n_p)`` of
    the model FRF's derivatives (each residual is ``Re`` or ``Im`` of ``c · dHs``)."""
    k = parts(kind)
    c = _derivative_factor(kind, Hs, Hm, scale)
    if out is None:
        out = np.empty((k, *dRe.shape))
    for part in range(k):  # Re(c·d) = cr·dRe − ci·dIm, Im(c·d) = cr·dIm + ci·dRe
        cp = c if weight is None else c * weight[part]
        first, second = (dRe, dIm) if part == 0 else (dIm, dRe)
        np.multiply(first, np.real(cp)[..., None], out=out[part])
        if np.iscomplexobj(cp):
            cross = second * np.imag(cp)[..., None]
            if part == 0:
                out[part] -= cross
            else:
                out[part] += cross
    return out


def robust(r: np.ndarray, norm: str, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """Map residuals for the chosen norm, keeping a sum-of-squares form.

    ``l2``: identity. ``l1``: pseudo-Huber ρ(r) = 2δ²(√(1+(r/δ)²) − 1) (≈ r² near 0, ≈ 2δ|r|
    for |r| ≫ δ) written as r̃ = sign(r)·√ρ(r), so ‖r̃‖² = Σρ. Returns (r̃, dr̃/dr).
    """
    if norm == "l2":
        return r, np.ones_like(r)
    s = np.sqrt(1.0 + (r / delta) ** 2)
    # ρ = 2δ²(s − 1) = 2r²/(1 + s), so r̃ = r·g with g = √(2/(1 + s)) (no cancellation near
    # r = 0) and dr̃/dr = ρ'/(2√ρ) = 1/(s·g) (ρ' = 2r/s); both → 1 at r = 0
    g = np.sqrt(2.0 / (1.0 + s))
    rt = r * g
    d = 1.0 / (s * g)
    return rt, d


def db_rms(Hs: np.ndarray, Hm: np.ndarray) -> float:
    """The spec's gap figure: RMS over points of (20/ln10)·|ln(Hm/Hs)| (phase wrapped)."""
    r = residual("complex_log", np.asarray(Hs), np.asarray(Hm))
    finite = np.all(np.isfinite(r), axis=0)
    return float(np.sqrt(np.mean(np.sum(r[:, finite] ** 2, axis=0))))
