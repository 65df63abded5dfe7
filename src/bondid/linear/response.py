"""The FRF engine: ``H(f) = C (K − ω²M + jωD)⁻¹ B`` for many frequencies at once.

One batched LU solve per block of frequencies (NumPy/LAPACK ``gesv`` over the frequency axis)
with only the ``n_in`` input columns solved for, then a small product with C. Any model size, not
bonder-specific.
"""

from __future__ import annotations

import numpy as np

from ..data.quantity import quantity_factor
from ..exceptions import ComputationError, DataError

#: frequencies solved at once: the dynamic stiffness of a block, ``(block, nv, nv)`` complex,
#: stays small however many lines a file has (100 000 lines of an 11-DOF model would hold
#: 190 MB at once)
BLOCK_FREQ = 2048


def omega(freq_hz: np.ndarray) -> np.ndarray:
    """Angular frequencies (rad/s) from Hz, validating positivity and finiteness."""
    f = np.asarray(freq_hz, dtype=float)
    if f.ndim != 1 or f.size == 0:
        raise DataError(f"frequencies must be a non-empty 1-D array, got shape {f.shape}")
    if not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise DataError("frequencies must be finite and > 0 Hz")
    return 2.0 * np.pi * f


def dynamic_stiffness(
    M: np.ndarray, K: np.ndarray, D: np.ndarray, w: np.ndarray, G: np.ndarray | None = None
) -> np.ndarray:
    """Z(ω) = K + jG − ω²M + jωD, shape ``(n_freq, nv, nv)``, complex; ``w`` in rad/s, ``G``
    the hysteretic stiffness ``(nv, nv)`` (None: none)."""
    Z = np.empty((w.size, *M.shape), dtype=complex)
    Z.real[...] = K[None] - (w**2)[:, None, None] * M[None]
    Z.imag[...] = w[:, None, None] * D[None]
    if G is not None:
        Z.imag[...] += G[None]
    return Z


def solve_columns(Z: np.ndarray, B: np.ndarray) -> np.ndarray:
    """X = Z⁻¹B for every frequency.

    Z is ``(n_freq, nv, nv)``, B ``(nv, n_in)``; returns ``(n_freq, nv, n_in)``.
    """
    try:
        X = np.linalg.solve(Z, np.broadcast_to(B.astype(complex), (Z.shape[0], *B.shape)))
    except np.linalg.LinAlgError as exc:
        raise ComputationError(
            "the dynamic stiffness K − ω²M + jωD is singular at some frequency "
            "(an undamped resonance exactly on a grid point, or a DOF without mass or spring)"
        ) from exc
    return X


def frf(
    M: np.ndarray,
    K: np.ndarray,
    D: np.ndarray,
    B: np.ndarray,
    C: np.ndarray,
    freq_hz: np.ndarray,
    quantity: str = "receptance",
    G: np.ndarray | None = None,
) -> np.ndarray:
    """Frequency response of ``M q̈ + D q̇ + K q = B u, y = C q`` (with a hysteretic
    stiffness ``G``: ``K + jG − ω²M + jωD``).

    Args:
        M, K, D: ``(nv, nv)`` mass, stiffness and damping matrices (SI).
        B: ``(nv, n_in)`` input matrix (generalised forces).
        C: ``(n_out, nv)`` output matrix (positions).
        freq_hz: ``(n_freq,)`` frequencies in Hz, > 0.
        quantity: ``receptance`` (position/force), ``mobility`` or ``accelerance``.
        G: ``(nv, nv)`` hysteretic stiffness (a structural loss factor times K), or None.

    Returns:
        Complex array ``(n_out, n_in, n_freq)``.
    """
    w = omega(freq_hz)
    H = np.empty((C.shape[0], B.shape[1], w.size), dtype=complex)
    for s in range(0, w.size, BLOCK_FREQ):
        X = solve_columns(dynamic_stiffness(M, K, D, w[s : s + BLOCK_FREQ], G), B)
        H[:, :, s : s + BLOCK_FREQ] = np.einsum("oi,fin->onf", C, X)
    if quantity != "receptance":
        H = H * quantity_factor(freq_hz, quantity)
    if not np.all(np.isfinite(H)):
        raise ComputationError("the FRF has non-finite values (singular or overflowing model)")
    return H
