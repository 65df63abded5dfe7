"""Mimic multipliers as parameters: the reduced model and its exact derivatives.

A ``<mimic>`` joint ``s`` follows its master ``m`` as ``δq_s = a·δq_m``; the model in the
independent coordinates is ``M_red = Tᵀ M T`` (likewise the stiffness and the damping),
``B_red = Tᵀ B`` and ``C_red = C T`` with the constant map ``T`` of :mod:`.mimic`, whose only
entry that depends on ``a`` is ``T[s, m] = a``. So, with ``E = ∂T/∂a`` (a single 1 at
``(s, m)``),

    ∂X_red/∂a = Eᵀ X T + Tᵀ X E = e_m (X[s,:] T) + (Tᵀ X[:,s]) e_mᵀ     (X = M, K, D),
    ∂B_red/∂a = e_m B[s,:],        ∂C_red/∂a = C[:,s] e_mᵀ,

exact, every matrix in the full coordinates at the current parameters (the joint springs
and dampers of the independent coordinates act on them directly and do not depend on
``a``). A multiplier that is a free parameter thus enters the FRF derivative as three more
direction matrices and one more input column and output row (:mod:`bondid.frf.jacobian`).

The operating point is held: a mimic joint is placed at ``a₀·q_master + b`` with the model's
multiplier ``a₀`` (for a compliance, whose master sits at 0, the placement does not depend
on ``a`` at all).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from .affine import AffineModel, reduce_mimic
from .mimic import reduction


@dataclass(frozen=True)
class CouplingTerms:
    """The derivatives of a reduced model through its free multipliers, chained to ``x``.

    Attributes:
        K, M, D: ``(n_p, nv, nv)`` ``∂K/∂x``, ``∂M/∂x``, ``∂D/∂x`` (reduced coordinates;
            ``D``: the joint dampers' part — proportional damping ``α M + β K`` follows
            ``M`` and ``K``, :mod:`bondid.frf.directions`).
        dB: ``(n_p, nv, n_in)`` ``∂B/∂x`` (with the input gains).
        dC: ``(n_p, n_out, nv)`` ``∂C/∂x`` (with the output gains).
    """

    K: np.ndarray
    M: np.ndarray
    D: np.ndarray
    dB: np.ndarray
    dC: np.ndarray


def recouple(affine: AffineModel, multipliers: Mapping[str, float]) -> AffineModel:
    """``affine`` (a reduced model) with the mimic joints' multipliers set to
    ``multipliers`` (joint → ``a``; others kept); its parameter values, gains and
    proportional damping are kept. Unchanged when ``multipliers`` is empty."""
    if not multipliers:
        return affine
    c = affine.coupled
    if c is None:
        raise ValueError("the model has no <mimic> joint: no multiplier to set")
    couplings = dict(c.couplings)
    for name, a in multipliers.items():
        couplings[name] = replace(couplings[name], multiplier=float(a))
    red = reduce_mimic(c.full, couplings)
    red = replace(red, pi=affine.pi, stiffness=affine.stiffness, damping=affine.damping,
                  alpha=affine.alpha, beta=affine.beta, eta=affine.eta)  # fmt: skip
    return red.with_gains(affine.gain_in, affine.gain_out)


def coupling_terms(affine: AffineModel, dmultipliers: Mapping[str, np.ndarray]) -> CouplingTerms:
    """The derivatives of ``affine`` (reduced, at its current values) through the free
    multipliers, ``dmultipliers`` = joint → ``da/dx`` ``(n_p,)`` (module docstring)."""
    c = affine.coupled
    assert c is not None and affine.gain_in is not None and affine.gain_out is not None
    full = c.full
    T, red = reduction(full.dofs, c.couplings)
    slaves = np.array([d in c.couplings for d in full.dofs])
    # the full-coordinate matrices at the current inertial parameters; of the joint springs
    # and dampers only the mimic joints' own act in these coordinates (module docstring)
    Mf = full.mass_matrix(affine.pi)
    Kf = full.stiffness_matrix(affine.pi, np.where(slaves, full.stiffness, 0.0))
    Df = full.D_rest + np.diag(np.where(slaves, full.damping, 0.0))
    assert full.B_kin is not None and full.C_kin is not None
    Bf = full.B_kin * affine.gain_in[None, :]
    Cf = affine.gain_out[:, None] * full.C_kin
    n_p = next(iter(dmultipliers.values())).size
    nv, n_in, n_out = len(red), Bf.shape[1], Cf.shape[0]
    out = {k: np.zeros((n_p, nv, nv)) for k in "KMD"}
    dB, dC = np.zeros((n_p, nv, n_in)), np.zeros((n_p, n_out, nv))
    for name, da in dmultipliers.items():
        s, m = full.dofs.index(name), red.index(c.couplings[name].master)
        for key, X in (("K", Kf), ("M", Mf), ("D", Df)):
            G = np.zeros((nv, nv))
            G[m] += X[s] @ T
            G[:, m] += T.T @ X[:, s]
            out[key] += da[:, None, None] * G[None]
        dB[:, m, :] += da[:, None] * Bf[s][None, :]
        dC[:, :, m] += da[:, None] * Cf[:, s][None, :]
    return CouplingTerms(out["K"], out["M"], out["D"], dB, dC)
