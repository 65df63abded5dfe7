"""The fit's decision vector with the parameters of an FRF modifier appended.

``z = [z_layout, u]`` with ``θ = θ₀ ∘ e^u`` (θ₀ the modifier's start, so ``u = 0`` at the
start and a bound ``[lo, hi]`` is ``[ln(lo/θ₀), ln(hi/θ₀)]``), or ``θ = θ₀ + s·u`` for the
modifier's linear-scale (signed) parameters
(:meth:`bondid.cost.modifier.FrfModifier.theta_of`). The model values and gains come from the
:class:`~.layout.Layout` part; :meth:`modifier_values` and :meth:`modifier_jacobian` give θ to
:class:`bondid.cost.FrfProblem` (see :mod:`bondid.cost.modifier`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .layout import Layout

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..cost.modifier import FrfModifier


class ModifiedLayout:
    """A parameter model over ``z`` ``(layout.size + n_θ,)`` (see the module docstring)."""

    def __init__(self, layout: Layout, theta0: np.ndarray, modifier: FrfModifier | None = None):
        """``modifier``: the FRF modifier whose scales θ follows (None: every θ on a log
        scale)."""
        self.layout = layout
        self.theta0 = np.asarray(theta0, dtype=float)
        self.offset = layout.size
        self.modifier = modifier

    @property
    def size(self) -> int:
        return self.offset + self.theta0.size

    def _pad(self, a: np.ndarray) -> np.ndarray:
        width = [(0, 0)] * (a.ndim - 1) + [(0, self.theta0.size)]
        return np.pad(a, width)

    def values(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.layout.values(z)

    def jacobian(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        dpi, dk, dd = self.layout.jacobian(z)
        return self._pad(dpi), self._pad(dk), self._pad(dd)

    def gain_values(self, z: np.ndarray) -> dict[str, float]:
        return self.layout.gain_values(z)

    def gain_jacobian(self, z: np.ndarray) -> dict[str, np.ndarray]:
        return {k: self._pad(v) for k, v in self.layout.gain_jacobian(z).items()}

    def mix_values(self, z: np.ndarray) -> dict[str, float]:
        return self.layout.mix_values(z)

    def mix_jacobian(self, z: np.ndarray) -> dict[str, np.ndarray]:
        return {k: self._pad(v) for k, v in self.layout.mix_jacobian(z).items()}

    def coupling_values(self, z: np.ndarray) -> dict[str, float]:
        return self.layout.coupling_values(z)

    def coupling_jacobian(self, z: np.ndarray) -> dict[str, np.ndarray]:
        return {k: self._pad(v) for k, v in self.layout.coupling_jacobian(z).items()}

    def rayleigh_values(self, z: np.ndarray) -> tuple[float, float, float] | None:
        return self.layout.rayleigh_values(z)

    def rayleigh_jacobian(self, z: np.ndarray) -> np.ndarray:
        return self._pad(self.layout.rayleigh_jacobian(z))

    def modifier_values(self, z: np.ndarray) -> np.ndarray:
        """θ ``(n_θ,)`` at ``z``."""
        u = np.asarray(z, dtype=float)[self.offset :]
        if self.modifier is None:
            return self.theta0 * np.exp(u)
        return self.modifier.theta_of(u, self.theta0)

    def modifier_jacobian(self, z: np.ndarray) -> np.ndarray:
        """∂θ/∂z ``(n_θ, size)``."""
        out = np.zeros((self.theta0.size, self.size))
        theta = self.modifier_values(z)
        slope = theta if self.modifier is None else self.modifier.slope(theta)
        out[:, self.offset :] = np.diag(slope)
        return out
