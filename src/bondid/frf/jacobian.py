"""Exact FRF derivatives: dH/dp = −C Z⁻¹ (∂Z/∂p) Z⁻¹ B, batched over frequencies.

Per block of frequencies: one batched LU solve gives ``X = Z⁻¹B`` and ``Y = C Z⁻¹`` (one solve
with ``[B, Cᵀ]`` when ``Z`` is symmetric, none extra when also ``C = Bᵀ``: then ``Y = Xᵀ``);
the outer products ``Y[o,:] ⊗ X[:,i]`` of each channel are contracted with the parameters'
real directions (:class:`bondid.frf.directions.Directions`) in a few real matrix products.
When ``Y = Xᵀ`` the FRF and its derivatives are symmetric in (output, input), so only the
channels ``o ≤ i`` are computed and the others copied. Frequencies are processed in small
blocks that stay in the processor's cache.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import numpy as np

from ..data.quantity import quantity_factor
from ..linear.affine import AffineModel
from ..linear.coupling import CouplingTerms
from ..linear.response import dynamic_stiffness, omega, solve_columns
from .directions import Directions, is_symmetric

#: Frequencies per block: the products of a block then stay in the processor's cache
#: (measured on the bonder, 11 DOF, 3×3 channels: 64–256 frequencies per block twice as fast
#: as one block of 2000).
_BLOCK_FREQ = 128


def _channels(n_out: int, n_in: int, mirrored: bool) -> tuple[np.ndarray, np.ndarray]:
    """Channel pairs (output, input) to compute: ``o ≤ i`` when mirrored, else all."""
    if mirrored:
        return np.triu_indices(n_out)
    co, ci = np.indices((n_out, n_in))
    return co.reshape(-1), ci.reshape(-1)


def frequency_spans(n_freq: int, n_spans: int) -> list[slice]:
    """``n_freq`` frequencies cut into at most ``n_spans`` contiguous spans of whole blocks.

    A span's blocks are those the whole range would have, so the FRF and its derivatives
    computed span by span (on parallel threads) equal the whole range's bit for bit.
    """
    blocks = -(-n_freq // _BLOCK_FREQ)
    n = max(1, min(n_spans, blocks))
    edges = [round(k * blocks / n) * _BLOCK_FREQ for k in range(n + 1)]
    return [slice(a, min(b, n_freq)) for a, b in itertools.pairwise(edges)]


def jacobian_blocks(
    affine: AffineModel,
    freq_hz: np.ndarray,
    dpi: np.ndarray,
    dk: np.ndarray,
    dd: np.ndarray,
    drayleigh: np.ndarray | None = None,
    extra: CouplingTerms | None = None,
    span: slice | None = None,
) -> Iterator[tuple[slice, np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]]:
    """Receptance and its derivatives, one block of frequencies at a time.

    Args: as for :func:`frf_and_jacobian` (no quantity: receptance only), and ``span``: the
    frequencies to cover (one of :func:`frequency_spans`; None: all).

    Yields:
        ``(sl, H, dH, (X, Yt))``: the slice of ``freq_hz`` the block covers, ``H`` ``(n_out,
        n_in, nf)`` complex, ``dH`` ``(2, n_out, n_in, nf, n_p)`` real (real and imaginary
        parts of the derivatives), and the block's solves ``X = Z⁻¹B`` ``(nf, nv, n_in)`` and
        ``Yt = Z⁻ᵀCᵀ`` ``(nf, nv, n_out)`` (complex), all only valid until the next block is
        asked for.
    """
    w = omega(freq_hz)
    M = affine.mass_matrix()
    K = affine.stiffness_matrix()
    D = affine.damping_matrix()
    G = affine.loss_matrix(K)
    dirs = Directions.build(affine, dpi, dk, dd, drayleigh, extra)
    C, B = affine.C, affine.B
    n_out, n_in, n_p = C.shape[0], B.shape[1], dirs.n_p
    symmetric = is_symmetric(np.stack([M, K, D]))  # G = ηK is symmetric with K
    mirrored = symmetric and C.shape == B.T.shape and np.array_equal(C, B.T)
    co, ci = _channels(n_out, n_in, mirrored)
    pair = np.zeros((n_out, n_in), dtype=int)  # computed channel of each (output, input)
    pair[co, ci] = np.arange(co.size)
    if mirrored:
        pair[ci, co] = pair[co, ci]
    rhs = B if mirrored or not symmetric else np.concatenate([B, C.T], axis=1)
    lo, hi = (0, w.size) if span is None else (span.start, span.stop)
    for s in range(lo, hi, _BLOCK_FREQ):
        ws = w[s : min(s + _BLOCK_FREQ, hi)]
        nf = ws.size
        Z = dynamic_stiffness(M, K, D, ws, G)
        Xa = solve_columns(Z, rhs)
        X = Xa[:, :, :n_in]  # (f, m, i)
        if mirrored:
            Yt = X  # (f, n, o): C Z⁻¹ = (Z⁻¹ Cᵀ)ᵀ = Xᵀ
        elif symmetric:
            Yt = Xa[:, :, n_in:]
        else:
            Yt = solve_columns(np.swapaxes(Z, 1, 2), C.T)
        H = np.einsum("on,fni->oif", C, X)
        # rows (computed channel, frequency): Y[o,:] and X[:,i]
        Yr = np.transpose(Yt[:, :, co], (2, 0, 1)).reshape(-1, Yt.shape[1])
        Xr = np.transpose(X[:, :, ci], (2, 0, 1)).reshape(-1, X.shape[1])
        dH = dirs.derivatives(Yr, Xr, np.tile(ws, co.size)).reshape(2, co.size, nf, n_p)
        dH = dH[:, pair] if mirrored else dH.reshape(2, n_out, n_in, nf, n_p)
        if extra is not None:
            dH = dH + _input_output_terms(extra, X, Yt)
        yield slice(s, s + nf), H, dH, (X, Yt)


def _input_output_terms(extra: CouplingTerms, X: np.ndarray, Yt: np.ndarray) -> np.ndarray:
    """``∂C/∂x X + Y ∂B/∂x`` ``(2, n_out, n_in, nf, n_p)`` (real and imaginary parts): the
    part of the FRF derivative through ``B`` and ``C`` (free mimic multipliers,
    :mod:`bondid.linear.coupling`), from the block's solves ``X`` ``(nf, nv, n_in)`` and
    ``Yt`` ``(nf, nv, n_out)``."""
    # tensordot (BLAS) rather than einsum: this runs at every Jacobian of a refit with a free
    # pivot, where the unoptimised two-operand contraction was a sixth of the refit's time
    d = np.tensordot(extra.dC, X, axes=([2], [1])).transpose(1, 3, 2, 0)  # (o, i, f, p)
    d += np.tensordot(Yt, extra.dB, axes=([1], [1])).transpose(1, 3, 0, 2)
    return np.stack([d.real, d.imag])


def frf_and_jacobian(
    affine: AffineModel,
    freq_hz: np.ndarray,
    dpi: np.ndarray,
    dk: np.ndarray,
    dd: np.ndarray,
    quantity: str = "receptance",
    *,
    drayleigh: np.ndarray | None = None,
    extra: CouplingTerms | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """FRF and its derivatives at the affine model's current values.

    Args:
        affine: the model (its ``pi``, ``stiffness``, ``damping`` are the evaluation point).
        freq_hz: ``(n_f,)`` Hz.
        dpi: ``(nb, 10, n_p)`` derivative of the body parameters w.r.t. each parameter.
        dk, dd: ``(nv, n_p)`` derivatives of the joint springs and dampers.
        quantity: receptance, mobility or accelerance.
        drayleigh: ``(2, n_p)`` derivatives of the proportional damping's ``α``, ``β`` (None:
            held at the model's).
        extra: the derivatives through free mimic multipliers
            (:func:`bondid.linear.coupling.coupling_terms`; None: none free).

    Returns:
        ``H`` ``(n_out, n_in, n_f)`` and ``J`` ``(n_out, n_in, n_f, n_p)``, complex, both
        C-contiguous.
    """
    freq_hz = np.asarray(freq_hz, dtype=float)
    n_out, n_in, n_p = affine.C.shape[0], affine.B.shape[1], dpi.shape[2]
    H = np.empty((n_out, n_in, freq_hz.size), dtype=complex)
    J = np.empty((n_out, n_in, freq_hz.size, n_p), dtype=complex)
    for sl, Hb, dH, _ in jacobian_blocks(affine, freq_hz, dpi, dk, dd, drayleigh, extra):
        H[:, :, sl] = Hb
        J.real[:, :, sl] = dH[0]
        J.imag[:, :, sl] = dH[1]
    if quantity != "receptance":
        fac = quantity_factor(freq_hz, quantity)
        H = H * fac
        J = J * fac[:, None]
    return H, J
