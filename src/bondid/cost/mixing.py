"""Points with a second component in the FRF problem: their mix parameters and derivatives.

A point with a second component (a piezo patch driving bending and torsion,
:mod:`bondid.model.points`) has the kinematic row ``r₁ + μ r₂`` (:mod:`bondid.linear.points`)
as an input column of ``B`` and as an output row of ``C``. Its mix ``μ`` (the parameter
``mix.<point>``) is a free parameter when the parameter model has ``mix_values(x) ->
{point: μ}`` and ``mix_jacobian(x) -> {point: dμ/dx (size,)}``. Since ``B`` and ``C`` are
linear in ``μ``,

    ∂H[o, i]/∂μ = C Z⁻¹ (g_i r₂) [o]   (the point as input i)
                + (g_o r₂)ᵀ Z⁻¹ B [i]   (the point as output o),

exact, with ``g`` the channel's transducer gain: one more FRF column (row) per mixed point.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..exceptions import ModelError
from ..linear.affine import AffineModel
from ..linear.points import component_rows
from ..model.document import UrdfDocument

#: per mixed point of a linearisation: its two component rows ``(nv,)`` each
MixRows = dict[str, tuple[np.ndarray, np.ndarray]]


def mix_rows(doc: UrdfDocument, affine: AffineModel) -> MixRows:
    """The component rows of the mixed points among ``affine``'s channels, at its pose.

    Raises:
        ModelError: the model has ``<mimic>`` joints (a mixed point is not reduced to the
            independent coordinates).
    """
    chans = set(affine.inputs) | set(affine.outputs)
    points = [p for p in doc.points if p.mixed and p.name in chans]
    if not points:
        return {}
    where = doc.source or "<URDF>"
    if doc.mimic_joints():
        raise ModelError(
            f"{where}: point {points[0].name!r} has a second component, which a model with"
            " <mimic> joints does not support; declare two points instead"
        )
    first, second = component_rows(doc.build_pinocchio_model(), affine.q0, points, where)
    return {p.name: (first[k], second[k]) for k, p in enumerate(points)}


def mixed_affine(affine: AffineModel, rows: MixRows, mixes: dict[str, float]) -> AffineModel:
    """``affine`` with the mixed points' columns of ``B`` and rows of ``C`` at ``mixes``."""
    if not mixes:
        return affine
    assert affine.B_kin is not None and affine.C_kin is not None
    Bk, Ck = affine.B_kin.copy(), affine.C_kin.copy()
    for name, mu in mixes.items():
        if name not in rows:
            continue
        r1, r2 = rows[name]
        if name in affine.inputs:
            Bk[:, affine.inputs.index(name)] = r1 + mu * r2
        if name in affine.outputs:
            Ck[affine.outputs.index(name)] = r1 + mu * r2
    return replace(affine, B_kin=Bk, C_kin=Ck).with_gains(affine.gain_in, affine.gain_out)


def mix_columns(
    affine: AffineModel, rows: MixRows, dmix: dict[str, np.ndarray], freq_hz: np.ndarray,
    sel: tuple[np.ndarray, np.ndarray, np.ndarray],
    solved: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:  # fmt: skip
    """``∂Hs/∂x`` ``(n_sel, size)`` complex through the mixes (module docstring); ``sel`` =
    the selected points' (output rows, input columns, frequency indices) of ``freq_hz``;
    ``solved`` = ``(X = Z⁻¹B (n_f, nv, n_in), Yt = Z⁻ᵀCᵀ (n_f, nv, n_out))`` at ``freq_hz``
    when the caller has them (the extra column and row then cost no solve)."""
    o_sel, i_sel, f_sel = sel
    n_p = next(iter(dmix.values())).size
    out = np.zeros((o_sel.size, n_p), dtype=complex)
    gi, go = affine.gain_in, affine.gain_out
    assert gi is not None and go is not None
    for name, dmu in dmix.items():
        if name not in rows:
            continue
        r2 = rows[name][1]
        if name in affine.inputs:  # C Z⁻¹ (g_i r₂): one more input column
            k = affine.inputs.index(name)
            if solved is not None:
                H2 = gi[k] * np.einsum("fno,n->of", solved[1], r2)  # (n_out, nf)
            else:
                col = replace(affine, B_kin=r2[:, None]).with_gains(gi[k : k + 1], go)
                H2 = col.linear_model().frf(freq_hz)[:, 0]
            hit = i_sel == k
            out[hit] += H2[o_sel[hit], f_sel[hit]][:, None] * dmu[None, :]
        if name in affine.outputs:  # (g_o r₂)ᵀ Z⁻¹ B: one more output row
            k = affine.outputs.index(name)
            if solved is not None:
                H2 = go[k] * np.einsum("n,fni->if", r2, solved[0])  # (n_in, nf)
            else:
                row = replace(affine, C_kin=r2[None, :]).with_gains(gi, go[k : k + 1])
                H2 = row.linear_model().frf(freq_hz)[0]
            hit = o_sel == k
            out[hit] += H2[i_sel[hit], f_sel[hit]][:, None] * dmu[None, :]
    return out
