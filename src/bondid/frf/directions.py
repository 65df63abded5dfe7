"""Parameter directions ``∂Z/∂p = ∂K/∂p − ω²∂M/∂p + jω∂D/∂p + j∂G/∂p`` in a form fit for
contraction (``G = ηK``: the hysteretic stiffness of a structural loss factor ``η``).

The FRF derivative of parameter ``p`` for output ``o`` and input ``i`` is

    dH[o,i]/dp = −Σ_nm Y[o,n] (∂Z/∂p)[n,m] X[m,i],     X = Z⁻¹B, Y = CZ⁻¹,

a contraction of the outer products ``S[n,m] = Y[o,n]·X[m,i]`` with the real direction
matrices. :class:`Directions` keeps only what is not zero:

* when every direction is symmetric (mass matrices always are; the gravity stiffness is the
  Hessian of the potential energy) only the pairs ``n ≤ m`` are contracted, with
  ``S[n,m] + S[m,n]`` off the diagonal;
* of those, only the pairs some parameter's stiffness (resp. mass) direction touches enter the
  stiffness (resp. mass) part, and the damping part uses the diagonal of the joint dampers only
  — unless the model has proportional damping ``D ∋ α M + β K``: then
  ``∂D/∂p = ∂D_joints/∂p + α ∂M/∂p + β ∂K/∂p + (∂α/∂p) M + (∂β/∂p) K``, on the pairs it touches;
* a loss factor adds the part ``∂G/∂p = η ∂K/∂p + (∂η/∂p) K``, which enters as ``j∂G/∂p``
  (no factor ω: its dissipation per cycle does not depend on frequency).

So a fit of joint springs and dampers alone contracts ``2n`` products, not ``n²``; on the
bonder with all 52 parameters free it is 31 stiffness, 56 mass and 11 damping products
instead of 3 × 121.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..linear.affine import AffineModel
from ..linear.coupling import CouplingTerms

#: relative asymmetry below which a direction matrix counts as symmetric
SYMMETRY_RTOL = 1e-10


def is_symmetric(A: np.ndarray, rtol: float = SYMMETRY_RTOL) -> bool:
    """Whether the square matrices in the last two axes of ``A`` are symmetric to ``rtol``."""
    scale = float(np.abs(A).max(initial=0.0))
    return bool(np.abs(A - np.swapaxes(A, -1, -2)).max(initial=0.0) <= rtol * max(scale, 1e-300))


@dataclass(frozen=True)
class Directions:
    """The non-zero parameter directions, stacked for one real matrix product.

    Attributes:
        n_p: number of parameters.
        pn, pm: ``(n_pairs,)`` the index pairs ``(n, m)`` whose products are formed.
        mirror: positions in the pair list whose mirrored product ``S[m,n]`` is added (the
            off-diagonal pairs when the directions are symmetric, else empty).
        k_sel, m_sel, d_sel, g_sel: positions in the pair list entering the stiffness, mass,
            damping and hysteretic parts.
        W: ``(n_k + n_m + n_d + n_g, n_p)`` real: ``[−∂K; ∂M; ∂D; ∂G]`` on those pairs (SI per
            parameter unit), so that with ``T = [S_k, ω² S_m, −jω S_d, −j S_g]`` the
            derivatives are ``T @ W``.
    """

    n_p: int
    pn: np.ndarray
    pm: np.ndarray
    mirror: np.ndarray
    k_sel: np.ndarray
    m_sel: np.ndarray
    d_sel: np.ndarray
    W: np.ndarray
    g_sel: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    @classmethod
    def build(
        cls,
        affine: AffineModel,
        dpi: np.ndarray,
        dk: np.ndarray,
        dd: np.ndarray,
        drayleigh: np.ndarray | None = None,
        extra: CouplingTerms | None = None,
    ) -> Directions:
        """Directions of ``n_p`` parameters from their derivatives.

        Args:
            affine: the model (its gravity-stiffness and mass bases, its ``alpha``, ``beta``,
                ``eta``).
            dpi: ``(nb, 10, n_p)`` derivative of the body parameters w.r.t. each parameter.
            dk, dd: ``(nv, n_p)`` derivatives of the joint springs (N/m or N·m/rad) and
                dampers (N·s/m or N·m·s/rad).
            drayleigh: ``(2, n_p)`` derivatives of ``α`` (1/s) and ``β`` (s), or ``(3, n_p)``
                with the loss factor ``η``'s third, or None (all held).
            extra: the derivatives through free mimic multipliers
                (:mod:`bondid.linear.coupling`), or None.
        """
        n, n_p = affine.nv, dpi.shape[2]
        # tensordot (BLAS): built at every Jacobian, five times faster than the einsum
        Kp: Any = np.tensordot(dpi, affine.G_basis, axes=([0, 1], [0, 1]))  # (p, i, j)
        Mp: Any = np.tensordot(dpi, affine.M_basis, axes=([0, 1], [0, 1]))
        idx = np.arange(n)
        Kp[:, idx, idx] += dk.T
        if extra is not None:
            Kp += extra.K
            Mp += extra.M
        Dp = _damping_directions(affine, Kp, Mp, dd, drayleigh)
        Gp = _loss_directions(affine, Kp, drayleigh)
        if extra is not None and np.any(extra.D):
            if Dp is None:
                Dp = np.zeros((n_p, n, n))
                Dp[:, idx, idx] += dd.T
            Dp = Dp + extra.D
        symmetric = all(A is None or is_symmetric(A) for A in (Kp, Mp, Dp, Gp))
        if symmetric:
            pn, pm = np.triu_indices(n)
            Kp, Mp, Dp, Gp = (
                None if A is None else 0.5 * (A + np.swapaxes(A, 1, 2)) for A in (Kp, Mp, Dp, Gp)
            )
            assert Kp is not None and Mp is not None
        else:
            pn, pm = (a.reshape(-1) for a in np.indices((n, n)))
        K2, M2 = Kp[:, pn, pm].T, Mp[:, pn, pm].T  # (pairs, n_p)
        if Dp is None:
            D2 = np.zeros_like(K2)
            D2[pn == pm] = dd
        else:
            D2 = Dp[:, pn, pm].T
        G2 = np.zeros_like(K2) if Gp is None else Gp[:, pn, pm].T
        used = [np.any(A != 0, axis=1) for A in (K2, M2, D2, G2)]
        keep = np.flatnonzero(np.logical_or.reduce(used))
        k_sel, m_sel, d_sel, g_sel = (np.flatnonzero(u[keep]) for u in used)
        pn, pm = pn[keep], pm[keep]
        W = np.concatenate([-K2[keep][k_sel], M2[keep][m_sel], D2[keep][d_sel], G2[keep][g_sel]])
        mirror = np.flatnonzero(pn != pm) if symmetric else np.zeros(0, dtype=int)
        return cls(n_p, pn, pm, mirror, k_sel, m_sel, d_sel, np.ascontiguousarray(W), g_sel)

    def derivatives(self, Y: np.ndarray, X: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``dH = −Σ_nm Y[n] (∂K − ω²∂M + jω∂D + j∂G)[n,m] X[m]`` per row, as real parts.

        Args:
            Y, X: ``(rows, n)`` complex: per row, the output row ``Y[o, :]`` of ``C Z⁻¹`` and
                the input column ``X[:, i]`` of ``Z⁻¹ B``.
            w: ``(rows,)`` angular frequency of each row (rad/s).

        Returns:
            ``(2, rows, n_p)`` real: ``Re dH`` and ``Im dH``.
        """
        S = Y[:, self.pn] * X[:, self.pm]
        if self.mirror.size:
            k = self.mirror
            S[:, k] += Y[:, self.pm[k]] * X[:, self.pn[k]]
        rows = S.shape[0]
        nk, nm, nd = self.k_sel.size, self.m_sel.size, self.d_sel.size
        w = w[:, None]
        T = np.empty((2, rows, self.W.shape[0]))
        for part, Sp in enumerate((S.real, S.imag)):
            T[part, :, :nk] = Sp[:, self.k_sel]
            np.multiply(w * w, Sp[:, self.m_sel], out=T[part, :, nk : nk + nm])
        Sd = S[:, self.d_sel]
        ed = nk + nm + nd
        np.multiply(w, Sd.imag, out=T[0, :, nk + nm : ed])  # Re(−jω S) = ω Im S
        np.multiply(-w, Sd.real, out=T[1, :, nk + nm : ed])  # Im(−jω S) = −ω Re S
        if self.g_sel.size:
            Sg = S[:, self.g_sel]
            T[0, :, ed:] = Sg.imag  # Re(−j S) = Im S
            T[1, :, ed:] = -Sg.real  # Im(−j S) = −Re S
        return (T.reshape(2 * rows, -1) @ self.W).reshape(2, rows, self.n_p)


def _damping_directions(
    affine: AffineModel,
    Kp: np.ndarray,
    Mp: np.ndarray,
    dd: np.ndarray,
    drayleigh: np.ndarray | None,
) -> np.ndarray | None:
    """``∂D/∂p`` ``(n_p, nv, nv)`` of a model with proportional damping (module docstring), or
    None when ``D`` is the joint dampers' alone (its directions: the diagonal ``dd``)."""
    alpha, beta = affine.alpha, affine.beta
    free = drayleigh is not None and bool(np.any(drayleigh[:2]))
    if not alpha and not beta and not free:
        return None
    n = affine.nv
    Dp = alpha * Mp + beta * Kp
    Dp[:, np.arange(n), np.arange(n)] += dd.T
    if free:
        assert drayleigh is not None
        M, K = affine.mass_matrix(), affine.stiffness_matrix()
        Dp += drayleigh[0][:, None, None] * M[None] + drayleigh[1][:, None, None] * K[None]
    return Dp


def _loss_directions(
    affine: AffineModel, Kp: np.ndarray, drayleigh: np.ndarray | None
) -> np.ndarray | None:
    """``∂G/∂p = η ∂K/∂p + (∂η/∂p) K`` ``(n_p, nv, nv)`` of a model with a loss factor (the
    third row of ``drayleigh``), or None without one."""
    deta = None if drayleigh is None or drayleigh.shape[0] < 3 else drayleigh[2]
    if not affine.eta and (deta is None or not np.any(deta)):
        return None
    Gp = affine.eta * Kp
    if deta is not None and np.any(deta):
        Gp = Gp + deta[:, None, None] * affine.stiffness_matrix()[None]
    return Gp
