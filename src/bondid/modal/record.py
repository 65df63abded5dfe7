"""The record of one vibration mode, measured or of a model: :class:`IdentifiedMode`.

Measured modes come from :func:`bondid.modal.identify.identify_modes`, a model's from
:func:`bondid.modal.identify.model_modes`; :mod:`bondid.modal.pairing` pairs the two.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

#: a channel carries information at a frequency where its coherence (or information weight,
#: :func:`bondid.data.weights.with_weights_as_coherence`) is at least this: S/N ≥ 1
INFORMED_COHERENCE = 0.5


@dataclass
class IdentifiedMode:
    """One mode (one member of a conjugate pair).

    Attributes:
        f_hz: undamped natural frequency |λ|/2π [Hz].
        zeta: damping ratio −Re λ/|λ|.
        residues: modal residue matrix ``(n_out, n_in)`` complex [FRF units / s].
        shape: ``(n_out,)`` complex, dominant left singular vector of ``residues``, largest
            entry 1; None when unknown.
        prominence: peak contribution relative to the FRF (see
            :mod:`bondid.modal.identify`); NaN when unknown.
        n_orders: number of model orders at which the pole was stable (identified modes).
        determined: ``(n_out, n_in)`` bool, the channels whose data carry information at the
            mode (coherence, or the information weight, ≥ :data:`INFORMED_COHERENCE` at its
            frequency): the residue entries the data determine; None = all (model modes).
            Pairing compares residues on these entries only
            (:func:`bondid.modal.pairing.mac_matrix`).
    """

    f_hz: float
    zeta: float
    residues: np.ndarray
    shape: np.ndarray | None = None
    prominence: float = float("nan")
    n_orders: int = 0
    determined: np.ndarray | None = None

    @property
    def eigenvalue(self) -> complex:
        """λ [1/s] with Im λ > 0."""
        w = 2 * np.pi * self.f_hz
        return complex(-self.zeta * w, w * np.sqrt(max(1.0 - self.zeta**2, 0.0)))

    def to_dict(self) -> dict[str, Any]:
        def c(v: complex) -> dict[str, float]:
            return {"re": float(v.real), "im": float(v.imag)}

        return {
            "f_hz": float(self.f_hz),
            "zeta": float(self.zeta),
            "prominence": None if not np.isfinite(self.prominence) else float(self.prominence),
            "shape": None if self.shape is None else [c(v) for v in self.shape],
        }


def mode_shape(residues: np.ndarray) -> np.ndarray | None:
    """``(n_out,)`` complex: the dominant left singular vector of ``residues`` ``(n_out,
    n_in)``, scaled so its largest entry is 1; None when the residues are not finite or all
    zero."""
    if not np.all(np.isfinite(residues)) or not np.any(residues):
        return None
    u = np.linalg.svd(residues)[0][:, 0]
    k = int(np.argmax(np.abs(u)))
    out = u / u[k]
    out[k] = 1.0
    return out


__all__ = ["INFORMED_COHERENCE", "IdentifiedMode", "mode_shape"]
