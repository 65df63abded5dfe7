"""Exact FRF derivatives: dH/dp = −C Z⁻¹ (∂Z/∂p) Z⁻¹ B, batched over frequencies.

With ``X = Z⁻¹B`` ``(n_f, nv, n_in)`` and ``Y = C Z⁻¹`` ``(n_f, n_out, nv)``, the outer product
``P[f,o,i,n,m] = Y[f,o,n]·X[f,m,i]`` contracted with the real parameter directions of
``∂Z/∂p = G_p − ω²M_p + jω D_p`` gives every derivative in three real matrix products.
Frequencies are processed in blocks to bound memory.
"""

from __future__ import annotations

import numpy as np

from ..linear.affine import AffineModel
from .engine import dynamic_stiffness, omega, solve_columns
from .quantity import quantity_factor

_BLOCK_BYTES = 64 * 2**20


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
        ``H`` ``(n_out, n_in, n_f)`` and ``J`` ``(n_out, n_in, n_f, n_p)``, complex.
    """
    w = omega(freq_hz)
    M = affine.mass_matrix()
    K = affine.stiffness_matrix()
    D = affine.damping_matrix()
    Mp = np.einsum("bkp,bkij->pij", dpi, affine.M_basis)
    Kp = np.einsum("bkp,bkij->pij", dpi, affine.G_basis)
    Kp[:, np.arange(affine.nv), np.arange(affine.nv)] += dk.T
    n, n_p = affine.nv, dpi.shape[2]
    Mp2 = Mp.reshape(n_p, n * n).T  # (n*n, n_p)
    Kp2 = Kp.reshape(n_p, n * n).T
    n_out, n_in = affine.C.shape[0], affine.B.shape[1]
    H = np.empty((w.size, n_out, n_in), dtype=complex)
    J = np.empty((w.size, n_out, n_in, n_p), dtype=complex)
    step = max(1, _BLOCK_BYTES // (16 * n_out * n_in * n * n))
    for s in range(0, w.size, step):
        ws = w[s : s + step]
        Z = dynamic_stiffness(M, K, D, ws)
        X = solve_columns(Z, affine.B)  # (f, n, n_in)
        Yt = solve_columns(np.swapaxes(Z, 1, 2), affine.C.T)  # (f, n, n_out) = (C Z^-1)^T
        H[s : s + step] = np.einsum("on,fni->foi", affine.C, X)
        P = np.einsum("fno,fmi->foinm", Yt, X).reshape(ws.size * n_out * n_in, n * n)
        PD = np.einsum("fno,fni->foin", Yt, X).reshape(ws.size * n_out * n_in, n)
        PK = P.real @ Kp2 + 1j * (P.imag @ Kp2)
        PM = P.real @ Mp2 + 1j * (P.imag @ Mp2)
        PDd = PD.real @ dd + 1j * (PD.imag @ dd)
        wf = np.repeat(ws, n_out * n_in)[:, None]
        J[s : s + step] = -(PK - wf**2 * PM + 1j * wf * PDd).reshape(ws.size, n_out, n_in, n_p)
    H = np.moveaxis(H, 0, 2)
    J = np.moveaxis(J, 0, 2)
    if quantity != "receptance":
        fac = quantity_factor(freq_hz, quantity)
        H = H * fac
        J = J * fac[:, None]
    return H, J
