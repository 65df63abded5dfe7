"""Receptance, mobility and accelerance, and the conversions between them.

With the ``exp(+jωt)`` convention, mobility = jω · receptance and accelerance = −ω² ·
receptance.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import DataError

QUANTITIES: tuple[str, ...] = ("receptance", "mobility", "accelerance")


def quantity_factor(freq_hz: np.ndarray, quantity: str) -> np.ndarray:
    """Factor that turns a receptance into ``quantity``, shape ``(n_freq,)``, complex.

    Args:
        freq_hz: frequencies, shape ``(n_freq,)``, Hz.
        quantity: one of :data:`QUANTITIES`.
    """
    w = 2.0 * np.pi * np.asarray(freq_hz, dtype=float)
    if quantity == "receptance":
        return np.ones_like(w, dtype=complex)
    if quantity == "mobility":
        return 1j * w
    if quantity == "accelerance":
        return -(w**2) + 0j
    raise DataError(f"unknown quantity {quantity!r}; valid: {', '.join(QUANTITIES)}")


def convert_quantity(H: np.ndarray, freq_hz: np.ndarray, source: str, target: str) -> np.ndarray:
    """Convert an FRF array ``(..., n_freq)`` from quantity ``source`` to ``target``.

    Args:
        H: complex FRF, frequency on the last axis, e.g. ``(n_out, n_in, n_freq)``.
        freq_hz: frequencies, shape ``(n_freq,)``, Hz.
        source: quantity of ``H``.
        target: wanted quantity.
    """
    if source == target:
        return np.array(H, dtype=complex, copy=True)
    return np.asarray(H) * (quantity_factor(freq_hz, target) / quantity_factor(freq_hz, source))
