"""FRF modifiers: ``H ← G(ω; θ) ⊙ H`` with their own positive parameters θ.

A modifier is what a model effect outside the URDF does to every channel's FRF, e.g. a pure
sensor delay ``G = e^{−jωτ}`` on some output rows, or a first-order actuator lag on some input
columns. Its function returns ``G`` and ``∂G/∂θ`` on the model's channels, so that the fit's
residual keeps its exact Jacobian: ``∂(G H)/∂x = G ∂H/∂x + H ∂G/∂θ · ∂θ/∂x``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..exceptions import ConfigError

#: ``(θ (n_θ,), freq_hz (n_f,), outputs, inputs) -> (G (n_out, n_in, n_f), ∂G/∂θ (…, n_θ))``
ModifierFn = Callable[
    [np.ndarray, np.ndarray, tuple[str, ...], tuple[str, ...]], tuple[np.ndarray, np.ndarray]
]


@dataclass(frozen=True)
class FrfModifier:
    """An FRF modifier and its parameters (see the module docstring).

    Attributes:
        fn: :data:`ModifierFn`, called with the model's output and input names.
        names: a name per parameter (``"sensor_delay.tau"``).
        start, lower, upper: ``(n_θ,)`` start and bounds, all finite and > 0 except ``upper``
            (may be +inf): a fit moves θ in ``ln θ``.
    """

    fn: ModifierFn
    names: tuple[str, ...]
    start: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]

    def __post_init__(self) -> None:
        n = len(self.names)
        if not (len(self.start) == len(self.lower) == len(self.upper) == n):
            raise ConfigError(f"FRF modifier {self.names}: give a start and bounds per name")
        for name, s, lo, hi in zip(self.names, self.start, self.lower, self.upper, strict=True):
            if not (0 < lo <= s <= hi and np.isfinite(lo) and np.isfinite(s)):
                raise ConfigError(
                    f"FRF modifier {name}: start {s!r} and bounds [{lo!r}, {hi!r}]; valid: "
                    "0 < lower <= start <= upper (lower and start finite)"
                )

    @property
    def size(self) -> int:
        return len(self.names)

    def at(
        self, theta: np.ndarray, freq_hz: np.ndarray, outputs: Sequence[str], inputs: Sequence[str]
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(G (n_out, n_in, n_f), ∂G/∂θ (n_out, n_in, n_f, n_θ))`` at ``theta``."""
        G, dG = self.fn(np.asarray(theta, float), np.asarray(freq_hz, float),
                        tuple(outputs), tuple(inputs))  # fmt: skip
        return np.asarray(G, complex), np.asarray(dG, complex)
