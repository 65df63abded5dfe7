"""The residual rows and their exact Jacobian rows of one data set, written in place.

:class:`~bondid.cost.problem.FrfProblem` lays the residual vector and its Jacobian out data
set by data set; :class:`Rows` fills one data set's slice. Three layouts share the cost's
mapping (residual kind, norm, weights):

* :meth:`Rows.grid` — every channel at every frequency: the FRF derivatives are taken one
  block of frequencies at a time and written as they come, no complex Jacobian assembled;
* :meth:`Rows.points` — any selection (channel subsets, free gains, point mixes, an FRF
  modifier), still one block of frequencies at a time, so memory does not grow with the
  lines times the parameters;
* :meth:`Rows.mixed` — a modifier that mixes channels (``L H R``): every channel of the grid
  enters every mixed one, so the whole grid is formed at once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..frf.jacobian import frf_and_jacobian, jacobian_blocks
from ..linear.affine import AffineModel
from ..linear.coupling import CouplingTerms
from .mixing import MixRows, mix_columns
from .modifier import FrfModifier
from .residuals import parts, residual, residual_jacobian, residual_jacobian_parts, robust
from .selection import CostOptions, DataSelection

Gains = dict[str, float]
#: ``(dπ (nb, 10, n_p), dk (nv, n_p), dd (nv, n_p), d(α, β, η) (3, n_p) or None, the terms
#: of free mimic multipliers or None)``
Derivatives = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, CouplingTerms | None]
#: a data set's mix rows and the mixes' d/dx
Mix = tuple[MixRows, dict[str, np.ndarray]]


def gain_arrays(affine: AffineModel, gains: Gains) -> tuple[np.ndarray, np.ndarray]:
    """``(gain_in (n_in,), gain_out (n_out,))`` of ``affine`` with the free ``gains`` set."""
    assert affine.gain_in is not None and affine.gain_out is not None
    gi, go = affine.gain_in.copy(), affine.gain_out.copy()
    for name, g in gains.items():
        _, side, chan = name.split(".", 2)
        names, arr = (affine.inputs, gi) if side == "in" else (affine.outputs, go)
        if chan in names:
            arr[names.index(chan)] = g
    return gi, go


def gain_columns(
    affine: AffineModel, gains: Gains, dgains: dict[str, np.ndarray], rows: np.ndarray,
    cols: np.ndarray, Hs: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """d Hs / d x ``(n_sel, n_p)`` through the free gains: ``Hs · d ln g / d x`` (``Hs``
    already holds the gains, ``H = g_out · H_kin · g_in``)."""
    n_p = next(iter(dgains.values())).size
    dlog = np.zeros((Hs.size, n_p))
    for name, g in gains.items():
        _, side, chan = name.split(".", 2)
        names, idx = (affine.inputs, cols) if side == "in" else (affine.outputs, rows)
        if chan in names:
            dlog[idx == names.index(chan)] += dgains[name] / g
    return Hs[:, None] * dlog


@dataclass
class Rows:
    """The cost's mapping of one problem: ``options`` (kind, norm), ``norm`` (1/√ of the
    total weight), the FRF ``modifier`` and ``modifier_at(b, θ)`` → its ``(G, ∂G/∂θ)`` on
    data set ``b``'s grid."""

    options: CostOptions
    norm: float
    modifier: FrfModifier | None = None
    modifier_at: Callable[[DataSelection, np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None

    def grid(
        self,
        b: DataSelection,
        affine: AffineModel,
        derivatives: Derivatives,
        r: np.ndarray,
        J: np.ndarray,
        span: slice | None = None,
    ) -> None:
        """Residuals and Jacobian rows of a data set that uses every channel at every one of
        its frequencies, written into ``r`` ``(k·n_sel,)`` and ``J`` ``(k, n_sel, n_p)`` (views
        of the result) one block of frequencies at a time while the FRF derivatives are in
        cache (no complex Jacobian is assembled). ``derivatives`` = ``(dπ, dk, dd, d(α, β))``;
        ``span``: the frequencies written (:func:`bondid.frf.jacobian.frequency_spans`; None:
        all), the rest of ``r`` and ``J`` untouched."""
        kind, k = self.options.kind, parts(self.options.kind)
        grid = (len(affine.outputs), len(affine.inputs), b.freq_hz.size)
        Hm, scale = b.Hm.reshape(grid), b.scale.reshape(grid)
        sw = (np.sqrt(b.weight) * self.norm).reshape(grid)
        rg, Jg = r.reshape(k, *grid), J.reshape(k, *grid, J.shape[-1])
        for sl, H, dH, _ in jacobian_blocks(affine, b.freq_hz, *derivatives, span=span):
            res = residual(kind, H, Hm[:, :, sl], scale[:, :, sl])
            rt, drt = robust(res, self.options.norm, self.options.l1_delta)
            rg[:, :, :, sl] = rt * sw[:, :, sl]
            residual_jacobian_parts(
                kind, H, Hm[:, :, sl], dH[0], dH[1], scale[:, :, sl], drt * sw[:, :, sl],
                out=Jg[:, :, :, sl],
            )  # fmt: skip

    def points(
        self,
        b: DataSelection,
        affine: AffineModel,
        derivatives: Derivatives,
        gains: tuple[Gains, dict[str, np.ndarray]],
        mix: Mix | None,
        modifier: tuple[tuple[np.ndarray, np.ndarray] | None, np.ndarray | None],
        r: np.ndarray,
        J: np.ndarray,
        span: slice | None = None,
    ) -> None:
        """Residuals and Jacobian rows of any selection (channel subsets, free gains, an FRF
        modifier), written into ``r`` ``(k·n_sel,)`` and ``J`` ``(k, n_sel, n_p)`` one block
        of frequencies at a time: the model's derivatives are never held for every frequency
        at once (``(n_out, n_in, n_f, n_p)`` complex would grow with the lines times the
        parameters). ``mix`` = the points' mix rows and the mixes' d/dx, or None;
        ``gains`` = ``(free gains, their d/dx)``, ``modifier`` = ``((G, ∂G/∂θ) or None,
        ∂θ/∂x or None)``; ``span``: the frequencies whose points are written (None: all)."""
        kind, k = self.options.kind, parts(self.options.kind)
        rk = r.reshape(k, -1)
        order = np.argsort(b.fidx, kind="stable")
        fsorted = b.fidx[order]
        G, dtheta = modifier
        for sl, H, dH, solved in jacobian_blocks(affine, b.freq_hz, *derivatives, span=span):
            lo, hi = np.searchsorted(fsorted, [sl.start, sl.stop])
            pts = order[lo:hi]
            if pts.size == 0:
                continue
            rows, cols, fidx = b.rows[pts], b.cols[pts], b.fidx[pts]
            at = (rows, cols, fidx - sl.start)
            Hs = H[at]
            dHs = dH[0][at] + 1j * dH[1][at]
            if gains[0]:
                dHs = dHs + gain_columns(affine, gains[0], gains[1], rows, cols, Hs)
            if mix is not None:
                at_block = (rows, cols, fidx - sl.start)
                dHs = dHs + mix_columns(affine, mix[0], mix[1], b.freq_hz[sl], at_block, solved)
            if G is not None:
                Hs, dHs = self.modified(G, (rows, cols, fidx), dtheta, Hs, dHs)
            res = residual(kind, Hs, b.Hm[pts], b.scale[pts])
            sw = np.sqrt(b.weight[pts]) * self.norm
            rt, drt = robust(res, self.options.norm, self.options.l1_delta)
            rk[:, pts] = rt * sw
            J[:, pts] = residual_jacobian(kind, Hs, b.Hm[pts], dHs, b.scale[pts], drt * sw)

    def mixed(
        self,
        b: DataSelection,
        affine: AffineModel,
        derivatives: Derivatives,
        gains: tuple[Gains, dict[str, np.ndarray]],
        mix: Mix | None,
        modifier: tuple[np.ndarray, np.ndarray | None],
        r: np.ndarray,
        J: np.ndarray,
    ) -> None:
        """Residuals and Jacobian rows, written into ``r`` ``(k·n_sel,)`` and ``J`` ``(k,
        n_sel, n_p)``, under a modifier that mixes channels (``L H R``): every channel of the
        data set's grid enters every mixed one, so the whole grid and its derivatives are
        formed at once. ``modifier`` = ``(θ, ∂θ/∂x or None)``."""
        assert self.modifier is not None and self.modifier_at is not None
        theta, dtheta = modifier
        H, dH = frf_and_jacobian(
            affine, b.freq_hz, *derivatives[:3], drayleigh=derivatives[3], extra=derivatives[4]
        )
        if gains[0]:
            no, ni, nf = H.shape
            rows = np.repeat(np.arange(no), ni * nf)
            cols = np.tile(np.repeat(np.arange(ni), nf), no)
            dg = gain_columns(affine, gains[0], gains[1], rows, cols, H.reshape(-1))
            dH = dH + dg.reshape(dH.shape)
        if mix is not None:
            no, ni, nf = H.shape
            grid = tuple(a.reshape(-1) for a in np.indices((no, ni, nf)))
            dm = mix_columns(affine, mix[0], mix[1], b.freq_hz, grid)
            dH = dH + dm.reshape(dH.shape)
        H, dH = self.modifier.mixed_with_jacobian(
            theta, dtheta, b.affine.outputs, b.affine.inputs, H, dH
        )
        at = (b.rows, b.cols, b.fidx)
        Hs, dHs = H[at], dH[at]
        Hs, dHs = self.modified(self.modifier_at(b, theta), at, dtheta, Hs, dHs)
        res = residual(self.options.kind, Hs, b.Hm, b.scale)
        rb, weight = self.weighted(b, res)
        r[:] = rb
        J[:] = residual_jacobian(self.options.kind, Hs, b.Hm, dHs, b.scale, weight)

    def modified(
        self,
        G: tuple[np.ndarray, np.ndarray],
        at: tuple[np.ndarray, np.ndarray, np.ndarray],
        dtheta: np.ndarray | None,
        Hs: np.ndarray,
        dHs: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``G ⊙ Hs`` ``(n,)`` and its derivative ``G ∂Hs/∂x + Hs ∂G/∂θ ∂θ/∂x`` ``(n, size)``
        (module :mod:`bondid.cost.modifier`) at the points ``at`` = ``(rows, cols, fidx)``
        of the modifier's ``G`` ``(n_out, n_in, n_fu)`` and ``∂G/∂θ`` ``(…, n_θ)``."""
        Gs, dGs = G[0][at], G[1][at]
        out = Gs[:, None] * dHs
        if dtheta is not None:
            out = out + Hs[:, None] * (dGs @ dtheta)
        return Gs * Hs, out

    def weighted(self, b: DataSelection, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weighted residuals ``(parts·n_sel,)`` (norm mapping, √weight, normalisation) and
        the factor ``(parts, n_sel)`` their derivatives take."""
        sw = np.sqrt(b.weight) * self.norm
        rt, drt = robust(r, self.options.norm, self.options.l1_delta)
        return (rt * sw).reshape(-1), drt * sw
