"""Exact FRF derivatives: dH/dp = −C Z⁻¹ (∂Z/∂p) Z⁻¹ B, batched over frequencies.

With ``X = Z⁻¹B`` ``(n_f, nv, n_in)`` and ``Y = C Z⁻¹`` ``(n_f, n_out, nv)``, the outer product
``P[o,i,f,n,m] = Y[f,o,n]·X[f,m,i]``, formed as separate contiguous real and imaginary parts,
contracted with the real parameter directions of ``∂Z/∂p = G_p − ω²M_p + jω D_p`` (stiffness
and mass directions side by side, damping on the diagonal) gives every derivative in a few
real matrix products. Frequencies are processed in small blocks that stay in cache.
"""

from __future__ import annotations

import numpy as np

from ..linear.affine import AffineModel
from .engine import dynamic_stiffness, omega, solve_columns
from .quantity import quantity_factor

#: Frequencies per block: the outer products of a block (2 × 8 bytes × n_out·n_in·nv² per
#: frequency) then stay in the processor's cache (measured on the bonder, 11 DOF, 3×3 channels:
#: 64–256 frequencies per block twice as fast as one block of 2000).
_BLOCK_FREQ = 128


def body_directions(affine: AffineModel, dpi: np.ndarray) -> np.ndarray:
    """Stiffness and mass directions of body-parameter changes, side by side.

    Args:
        affine: the model (its gravity-stiffness and mass bases).
        dpi: ``(nb, 10, n_p)`` derivative of the body parameters w.r.t. each parameter.

    Returns:
        ``(nv², 2 n_p)`` real: column ``p`` is ``∂G/∂p`` flattened (row-major), column
        ``n_p + p`` is ``∂M/∂p``; a contraction with the outer products ``Y Xᵀ`` is then one
        real matrix product per part.
    """
    n, n_p = affine.nv, dpi.shape[2]
    Kp = np.einsum("bkp,bkij->pij", dpi, affine.G_basis).reshape(n_p, n * n)
    Mp = np.einsum("bkp,bkij->pij", dpi, affine.M_basis).reshape(n_p, n * n)
    return np.concatenate([Kp, Mp]).T.copy()


def frf_and_jacobian(
    affine: AffineModel,
    freq_hz: np.ndarray,
    dpi: np.ndarray,
    dk: np.ndarray,
    dd: np.ndarray,
    quantity: str = "receptance",
) -> tuple[np.ndarray, np.ndarray]:
    """FRF and its derivatives at the affine model's current values.

    Args:
        affine: the model (its ``pi``, ``stiffness``, ``damping`` are the evaluation point).
        freq_hz: ``(n_f,)`` Hz.
        dpi: ``(nb, 10, n_p)`` derivative of the body parameters w.r.t. each parameter.
        dk, dd: ``(nv, n_p)`` derivatives of the joint springs and dampers.
        quantity: receptance, mobility or accelerance.

    Returns:
        ``H`` ``(n_out, n_in, n_f)`` and ``J`` ``(n_out, n_in, n_f, n_p)``, complex, both
        C-contiguous.
    """
    w = omega(freq_hz)
    M = affine.mass_matrix()
    K = affine.stiffness_matrix()
    D = affine.damping_matrix()
    n, n_p = affine.nv, dpi.shape[2]
    G = body_directions(affine, dpi)  # (n², 2 n_p): [∂K | ∂M]
    G[np.arange(n) * (n + 1), :n_p] += dk  # joint springs: on the diagonal of ∂K
    C, B = affine.C, affine.B
    n_out, n_in = C.shape[0], B.shape[1]
    H = np.empty((n_out, n_in, w.size), dtype=complex)
    J = np.empty((n_out, n_in, w.size, n_p), dtype=complex)
    for s in range(0, w.size, _BLOCK_FREQ):
        ws = w[s : s + _BLOCK_FREQ]
        Z = dynamic_stiffness(M, K, D, ws)
        X = solve_columns(Z, B)  # (f, m, i)
        Y = solve_columns(np.swapaxes(Z, 1, 2), C.T)  # (f, n, o) = (C Z^-1)^T
        H[:, :, s : s + ws.size] = np.einsum("on,fni->oif", C, X)
        # P[o,i,f,n,m] = Y[f,n,o]·X[f,m,i], real and imaginary parts, contiguous
        Yt = np.transpose(Y, (2, 0, 1))[:, None, :, :, None]  # (o, 1, f, n, 1)
        Xt = np.transpose(X, (2, 0, 1))[None, :, :, None, :]  # (1, i, f, 1, m)
        yr, yi, xr, xi = Yt.real, Yt.imag, Xt.real, Xt.imag
        Pr = (yr * xr - yi * xi).reshape(-1, n * n)
        Pi = (yr * xi + yi * xr).reshape(-1, n * n)
        Ar, Ai = Pr @ G, Pi @ G  # (o·i·f, 2 n_p): [∂K part | ∂M part]
        diag = np.arange(n) * (n + 1)  # damping is diagonal: P[..., n, n] only
        Dr, Di = Pr[:, diag] @ dd, Pi[:, diag] @ dd
        wf = np.tile(ws, n_out * n_in)[:, None]
        w2 = wf * wf
        # J = −P·(∂K − ω²∂M + jω∂D), split into real and imaginary parts
        blk = J[:, :, s : s + ws.size]
        shape = (n_out, n_in, ws.size, n_p)
        blk.real[...] = (w2 * Ar[:, n_p:] - Ar[:, :n_p] + wf * Di).reshape(shape)
        blk.imag[...] = (w2 * Ai[:, n_p:] - Ai[:, :n_p] - wf * Dr).reshape(shape)
    if quantity != "receptance":
        fac = quantity_factor(freq_hz, quantity)
        H = H * fac
        J = J * fac[:, None]
    return H, J
