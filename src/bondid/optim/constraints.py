"""The fit's constraints ``g(z)`` as CasADi expressions, with their bounds and labels.

Rows, each scaled to O(1), per fitted body (:class:`~.layout.Layout`): fixed inertia components
``(I_c,k(θ) − v)/s_I = 0`` of a body whose other inertia components are free, bounds on free
inertia components, the CoM-in-hull inequalities ``(A t − b)/L ≤ 0`` (linear in z), and the
ties of inertial parameters: ``α − α_lead = ½ ln f`` for a mass, ``(t_k − f t_lead,k)/L = 0``
for a CoM component, ``(I_c,k − f I_lead,k)/s_I = 0`` for an inertia component.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..model.parameters import COM_AXES, INERTIA_COMPONENTS
from .layout import Layout
from .variables import _ALPHA, _DIAG, _IJ, _OFF, _T, BodyBlock


@dataclass(frozen=True)
class Constraints:
    """The constraints ``lower ≤ g(z) ≤ upper`` of a fit problem, symbolic in CasADi.

    Attributes:
        zsym: the CasADi SX symbol of ``z`` ``(size,)`` the expressions are written in.
        expr: ``g(z)`` as a CasADi SX column ``(ng,)`` (each row scaled to O(1)).
        lower, upper: bounds ``(ng,)`` (equal for an equality, ±inf allowed).
        labels: a readable name per row (``"x_stage.inertia.ixx"``, ``"x_stage com in
            hull"``, ``"x_stage.inertia.iyy fixed"``).
    """

    zsym: Any
    expr: Any
    lower: np.ndarray
    upper: np.ndarray
    labels: tuple[str, ...]

    @property
    def size(self) -> int:
        return len(self.labels)


def layout_constraints(
    layout: Layout, zsym: Any, lower: np.ndarray, upper: np.ndarray
) -> tuple[Any, np.ndarray, np.ndarray, list[str]]:
    """Constraint expressions ``g(z)`` (CasADi column) with bounds and labels.

    Rows, each scaled to O(1): fixed inertia components ``(I_c,k(θ) − v)/s_I = 0``; bounded
    free inertia components ``lo/s_I ≤ I_c,k(θ)/s_I ≤ hi/s_I``; CoM in hull
    ``(A t − b)/L ≤ 0`` (one row per facet, only for bodies with a free CoM component).

    Returns:
        ``(g, lbg, ubg, labels)``: a readable label per row (``"x_stage.inertia.ixx"``,
        ``"x_stage.inertia.iyy fixed"``, ``"x_stage com in hull"``).
    """
    import casadi

    rows: list[tuple[Any, float, float, str]] = []
    exprs = _BodyExprs(zsym)
    for blk in layout.blocks:
        zb = zsym[blk.offset : blk.offset + 10]
        if blk.fixed_v is None:
            rows += _inertia_rows(layout, blk, exprs.inertia(blk), lower, upper)
        rows += _tie_rows(layout, blk, exprs)
        if blk.hull is not None and any(k.startswith("com.") for k in [*blk.free, *blk.tied]):
            t = blk.scale[_T] * zb[_T : _T + 3]  # shift of t is 0
            for A_row, b_row in zip(blk.hull.A, blk.hull.b, strict=True):
                expr = (casadi.dot(casadi.DM(A_row), t) - b_row) / blk.length
                rows.append((expr, -np.inf, 0.0, f"{blk.link} com in hull"))
    g = casadi.vertcat(*(r[0] for r in rows)) if rows else casadi.SX(0, 1)
    lbg = np.array([r[1] for r in rows])
    ubg = np.array([r[2] for r in rows])
    return g, lbg, ubg, [r[3] for r in rows]


def _inertia_rows(
    layout: Layout, blk: BodyBlock, I_c: Any, lower: np.ndarray, upper: np.ndarray
) -> list[tuple[Any, float, float, str]]:
    """``(I_c,k(θ)/s_I, lower, upper, label)`` of a body's fixed and bounded components
    (``I_c``: the body's inertia expression, :meth:`_BodyExprs.inertia`)."""
    s_i = blk.inertia_scale
    rows = []
    for comp in INERTIA_COMPONENTS:
        r, c = _IJ[comp]
        key = f"inertia.{comp}"
        if key in blk.tied:
            continue  # held by its tie (:func:`_tie_rows`)
        if key in blk.fixed:
            v = blk.fixed[key] / s_i
            rows.append((I_c[r, c] / s_i, v, v, f"{blk.link}.{key} fixed"))
            continue
        j = blk.free[key]
        lo, hi = float(lower[j]), float(upper[j])
        if np.isfinite(lo) or np.isfinite(hi):
            rows.append((I_c[r, c] / s_i, lo / s_i, hi / s_i, layout.infos[j].name))
    return rows


class _BodyExprs:
    """The bodies' expressions at ``zsym``, each built once: a body's inertia enters its own
    rows and the tie row of every member tied to it."""

    def __init__(self, zsym: Any) -> None:
        self.zsym = zsym
        self._inertia: dict[str, Any] = {}

    def inertia(self, blk: BodyBlock) -> Any:
        """The body's inertia about its CoM ``I_c(θ)`` (3×3 CasADi expression)."""
        if blk.link not in self._inertia:
            import casadi

            zb = self.zsym[blk.offset : blk.offset + 10]
            ze = casadi.DM(blk.shift) + casadi.DM(blk.scale) * zb
            V: Any = casadi.SX.zeros(3, 3) if isinstance(zb, casadi.SX) else casadi.MX.zeros(3, 3)
            for k in range(3):
                V[k, k] = casadi.exp(ze[_DIAG[k]])
            for idx, r, c in _OFF:
                V[r, c] = ze[idx]
            S = V @ V.T  # second moment about the CoM
            self._inertia[blk.link] = casadi.trace(S) * casadi.DM.eye(3) - S
        return self._inertia[blk.link]

    def component(self, blk: BodyBlock, comp: str) -> Any:
        """A body's ``comp`` (``mass`` as α, ``com.x`` as t_x, ``inertia.ixx``…), in the
        units the tie rows compare: α for a mass, metres, kg·m²."""
        zb = self.zsym[blk.offset : blk.offset + 10]
        if comp == "mass":
            return blk.shift[_ALPHA] + blk.scale[_ALPHA] * zb[_ALPHA]
        if comp.startswith("com."):
            k = COM_AXES.index(comp[4:])
            return blk.scale[_T + k] * zb[_T + k]  # shift of t is 0
        r, c = _IJ[comp[8:]]
        return self.inertia(blk)[r, c]


def _tie_rows(
    layout: Layout, blk: BodyBlock, exprs: _BodyExprs
) -> list[tuple[Any, float, float, str]]:
    """The equality rows of ``blk``'s tied inertial components, each scaled to O(1)."""
    rows = []
    for comp, (j, factor) in blk.tied.items():
        info = layout.infos[j]
        lead = next(b for b in layout.blocks if b.link == info.owner)
        mine = exprs.component(blk, comp)
        theirs = exprs.component(lead, info.component_key)
        if comp == "mass":
            expr, target = mine - theirs, 0.5 * float(np.log(factor))
        else:
            scale = blk.length if comp.startswith("com.") else blk.inertia_scale
            expr, target = (mine - factor * theirs) / scale, 0.0
        rows.append((expr, target, target, f"{blk.link}.{comp} tied to {info.name}"))
    return rows
