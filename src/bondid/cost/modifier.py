"""FRF modifiers: ``H ← G(ω; θ) ⊙ (L(θ) · H · R(θ))`` with their own parameters θ.

A modifier is what a model effect outside the URDF does to the model's FRF:

* an elementwise factor ``G`` ``(n_out, n_in, n_f)``, e.g. a pure sensor delay
  ``G = e^{−jωτ}`` on some output rows, or an actuator lag on some input columns;
* optionally a *mixing* of the outputs (``L``, ``(n_out, n_out)``) and of the inputs (``R``,
  ``(n_in, n_in)``), frequency-independent, e.g. a sensor misalignment ``L = I + E`` with a
  small off-diagonal ``E`` (cross-talk between measurement directions).

The mixing acts on the mechanical FRF first, the factor last (a sensor's electronics see what
its misaligned head measures; an amplifier's lag acts before the force is split between
directions). Its functions return the values and their exact derivatives in θ, so that the
fit's residual keeps its exact Jacobian:
``∂H'/∂x = G ⊙ (L ∂H/∂x R) + [∂G/∂θ ⊙ (L H R) + G ⊙ (∂L/∂θ H R + L H ∂R/∂θ)] ∂θ/∂x``.

A fit moves each parameter on its own scale: a positive parameter (a delay, a lag time) on a
log scale, ``θ = θ₀ e^u``; a *linear* one (a signed, near-zero mixing entry or log-gain) as
``θ = θ₀ + s·u`` with ``s`` its typical size (:meth:`FrfModifier.theta_of`).
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
class Mixing:
    """Output and input mixing matrices of a modifier and their derivatives in θ.

    Attributes:
        left: ``L`` ``(n_out, n_out)`` (None: the identity).
        dleft: ``∂L/∂θ`` ``(n_out, n_out, n_θ)`` (None with ``left``).
        right: ``R`` ``(n_in, n_in)`` (None: the identity).
        dright: ``∂R/∂θ`` ``(n_in, n_in, n_θ)`` (None with ``right``).
    """

    left: np.ndarray | None = None
    dleft: np.ndarray | None = None
    right: np.ndarray | None = None
    dright: np.ndarray | None = None

    def apply(self, H: np.ndarray) -> np.ndarray:
        """``L H R`` of ``H`` ``(n_out, n_in, n_f[, n_p])`` (every trailing slice alike)."""
        out = H
        if self.left is not None:
            out = np.einsum("ab,b...->a...", self.left, out)
        if self.right is not None:
            out = np.einsum("ab...,bd->ad...", out, self.right)
        return out

    def dtheta(self, H: np.ndarray, n_theta: int) -> np.ndarray:
        """``∂(L H R)/∂θ`` ``(n_out, n_in, n_f, n_θ)`` of ``H`` ``(n_out, n_in, n_f)``."""
        out = np.zeros((*H.shape, n_theta), complex)
        if self.left is not None and self.dleft is not None:
            HR = H if self.right is None else Mixing(right=self.right).apply(H)
            out += np.einsum("abk,bcf->acfk", self.dleft, HR)
        if self.right is not None and self.dright is not None:
            LH = H if self.left is None else Mixing(left=self.left).apply(H)
            out += np.einsum("bcf,cdk->bdfk", LH, self.dright)
        return out


#: ``(θ (n_θ,), outputs, inputs) -> Mixing | None``
MixingFn = Callable[[np.ndarray, tuple[str, ...], tuple[str, ...]], Mixing | None]


@dataclass(frozen=True)
class FrfModifier:
    """An FRF modifier and its parameters (see the module docstring).

    Attributes:
        fn: :data:`ModifierFn`, called with the model's output and input names.
        names: a name per parameter (``"sensor_delay.tau"``).
        start, lower, upper: ``(n_θ,)`` start and bounds: ``lower ≤ start ≤ upper``, ``lower``
            and ``start`` finite; a log-scale parameter also ``0 < lower``.
        linear: per parameter, True when it is fitted on a linear scale (may be signed or
            zero); empty: every parameter on a log scale.
        scale: per parameter, the typical size ``s`` of a linear one (``θ = θ₀ + s·u``);
            empty: 1 each. Ignored for log-scale parameters.
        mixing: :data:`MixingFn` of the output/input mixing, or None (an elementwise factor
            alone).
    """

    fn: ModifierFn
    names: tuple[str, ...]
    start: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    linear: tuple[bool, ...] = ()
    scale: tuple[float, ...] = ()
    mixing: MixingFn | None = None

    def __post_init__(self) -> None:
        n = len(self.names)
        if not (len(self.start) == len(self.lower) == len(self.upper) == n):
            raise ConfigError(f"FRF modifier {self.names}: give a start and bounds per name")
        if len(self.linear) not in (0, n) or len(self.scale) not in (0, n):
            raise ConfigError(
                f"FRF modifier {self.names}: give a linear flag and a scale per name (or none)"
            )
        for k, (name, s, lo, hi) in enumerate(
            zip(self.names, self.start, self.lower, self.upper, strict=True)
        ):
            ok = lo <= s <= hi and np.isfinite(lo) and np.isfinite(s)
            if self.is_linear(k):
                sc = self.scales[k]
                if not (ok and np.isfinite(sc) and sc > 0):
                    raise ConfigError(
                        f"FRF modifier {name}: start {s!r}, bounds [{lo!r}, {hi!r}], scale "
                        f"{sc!r}; valid: lower <= start <= upper (finite), scale > 0"
                    )
            elif not (ok and lo > 0):
                raise ConfigError(
                    f"FRF modifier {name}: start {s!r} and bounds [{lo!r}, {hi!r}]; valid: "
                    "0 < lower <= start <= upper (lower and start finite)"
                )

    @property
    def size(self) -> int:
        return len(self.names)

    def is_linear(self, k: int) -> bool:
        return bool(self.linear[k]) if self.linear else False

    @property
    def linear_mask(self) -> np.ndarray:
        """``(n_θ,)`` bool: the parameters fitted on a linear scale."""
        return np.array([self.is_linear(k) for k in range(self.size)], bool)

    @property
    def scales(self) -> np.ndarray:
        """``(n_θ,)``: the typical size of each linear parameter (1 where not given)."""
        return np.asarray(self.scale, float) if self.scale else np.ones(self.size)

    # -- the decision variables u of a fit (θ = θ₀ e^u, or θ₀ + s u) ------------------------
    def theta_of(self, u: np.ndarray, theta0: np.ndarray) -> np.ndarray:
        """θ ``(n_θ,)`` at the fit's variables ``u`` ``(n_θ,)`` around ``theta0``."""
        u, theta0 = np.asarray(u, float), np.asarray(theta0, float)
        lin = self.linear_mask
        with np.errstate(over="ignore"):
            return np.where(lin, theta0 + self.scales * u, theta0 * np.exp(np.where(lin, 0, u)))

    def u_of(self, theta: np.ndarray, theta0: np.ndarray) -> np.ndarray:
        """The fit's variables ``u`` ``(n_θ,)`` of ``theta`` around ``theta0`` (±inf kept:
        an infinite bound stays infinite)."""
        theta, theta0 = np.asarray(theta, float), np.asarray(theta0, float)
        lin = self.linear_mask
        with np.errstate(divide="ignore", invalid="ignore"):
            log = np.log(np.where(lin, 1.0, theta) / np.where(lin, 1.0, theta0))
        return np.where(lin, (theta - theta0) / self.scales, log)

    def slope(self, theta: np.ndarray) -> np.ndarray:
        """``dθ/du`` ``(n_θ,)`` at ``theta``: θ (log scale) or the scale ``s`` (linear)."""
        return np.where(self.linear_mask, self.scales, np.asarray(theta, float))

    # -- values ------------------------------------------------------------------------------
    def at(
        self, theta: np.ndarray, freq_hz: np.ndarray, outputs: Sequence[str], inputs: Sequence[str]
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(G (n_out, n_in, n_f), ∂G/∂θ (n_out, n_in, n_f, n_θ))`` at ``theta`` (the
        elementwise factor; see :meth:`apply` for the whole transform)."""
        G, dG = self.fn(np.asarray(theta, float), np.asarray(freq_hz, float),
                        tuple(outputs), tuple(inputs))  # fmt: skip
        return np.asarray(G, complex), np.asarray(dG, complex)

    def mix(
        self, theta: np.ndarray, outputs: Sequence[str], inputs: Sequence[str]
    ) -> Mixing | None:
        """The mixing at ``theta`` (None: none)."""
        if self.mixing is None:
            return None
        return self.mixing(np.asarray(theta, float), tuple(outputs), tuple(inputs))

    def apply(
        self, theta: np.ndarray, freq_hz: np.ndarray, outputs: Sequence[str],
        inputs: Sequence[str], H: np.ndarray,
    ) -> np.ndarray:  # fmt: skip
        """The modified FRF ``G ⊙ (L H R)`` of ``H`` ``(n_out, n_in, n_f)`` whose rows are
        ``outputs`` and columns ``inputs``."""
        mixing = self.mix(theta, outputs, inputs)
        if mixing is not None:
            H = mixing.apply(H)
        return H * self.at(theta, freq_hz, outputs, inputs)[0]

    def mixed_with_jacobian(
        self, theta: np.ndarray, dtheta: np.ndarray | None, outputs: Sequence[str],
        inputs: Sequence[str], H: np.ndarray, dH: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """``L H R`` ``(n_out, n_in, n_f)`` and its derivative ``(n_out, n_in, n_f, n_p)``:
        ``L ∂H/∂x R + ∂(L H R)/∂θ · ∂θ/∂x`` (``dtheta`` ``(n_θ, n_p)``, None: θ held), from
        ``H`` and ``dH`` ``(n_out, n_in, n_f, n_p)`` on a whole grid of channels. Without a
        mixing ``H`` and ``dH`` are returned as they are."""
        mixing = self.mix(theta, outputs, inputs)
        if mixing is None:
            return H, dH
        Hm, dHm = mixing.apply(H), mixing.apply(dH)
        if dtheta is not None:
            dHm = dHm + mixing.dtheta(H, self.size) @ np.asarray(dtheta, float)
        return Hm, dHm
