"""Cross-channel leakage: one output reads a fraction of another output's response (a sensor
misaligned on its axis, electrical cross-talk), ``H_meas[o, :] = H_model[o, :] + ε
H_model[o', :]``; or one input also drives through another (a force not on its axis),
``H_meas[:, i] = H_model[:, i] + ε H_model[:, i']``. ``ε`` is real (a geometric
misalignment), in units of output ``o`` per output ``o'`` (or of input ``i'`` per ``i``).

The leaked row (column) is taken from the model and, as a second form, from the data (the
measured source row holds the truth the model may miss, with its noise); the form that
removes more is the candidate (``source_from``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .base import Candidate, Finding, Location, Significance
from .context import Context
from .groups import MIN_POINTS
from .residual import Points, Residual
from .stats import fit_points, scan

#: the grid of |ε| searched before the fit
GRID_LO, GRID_HI, GRID_N = 1e-4, 1.0, 41


@dataclass
class Leakage(Finding):
    """``epsilon`` (and ``std``) of ``target`` reading ``source`` (both outputs, or both
    inputs, as ``location.side`` says)."""

    target: str = ""
    source: str = ""
    epsilon: float = math.nan
    std: float = math.nan
    source_from: str = "model"

    def figures(self) -> dict[str, Any]:
        return {"target": self.target, "source": self.source, "epsilon": self.epsilon,
                "std": self.std, "source_from": self.source_from}  # fmt: skip


def candidates(res: Residual, ctx: Context) -> list[Candidate]:
    out = []
    for side, names in (("output", res.outputs), ("input", res.inputs)):
        for target in names:
            for source in names:
                if source == target:
                    continue
                fits = [_fit(res, side, target, source, m) for m in (False, True)]
                best = [c for c in fits if c is not None]
                if best:
                    out.append(max(best, key=lambda c: c.fit.gain))
    return out


def _gather(
    res: Residual, side: str, target: str, source: str, measured: bool
) -> tuple[Points, np.ndarray]:
    """The points of ``target``'s row (column) in the data sets that have ``source`` too, and
    the ``source`` row (column) at them: the model's, or the measured one (``measured``;
    where it is used)."""
    names = "outputs" if side == "output" else "inputs"

    def select(k: int, st: Any) -> np.ndarray:
        mask = np.zeros(st.Hm.shape, bool)
        have = getattr(st, names)
        if target in have and source in have:
            if side == "output":
                mask[have.index(target)] = True
            else:
                mask[:, have.index(target)] = True
        return mask

    pts = res.points(select)
    aux = np.empty(pts.size, complex)
    for k, st in enumerate(res.sets):
        sel = pts.k == k
        if not np.any(sel):
            continue
        src = getattr(st, names).index(source)
        H = np.where(st.used, st.Hm, np.nan) if measured else st.Hs
        if side == "output":
            aux[sel] = H[src, pts.b[sel], pts.j[sel]]
        else:
            aux[sel] = H[pts.a[sel], src, pts.j[sel]]
    ok = np.isfinite(aux) & (aux != 0)
    return pts.subset(ok), aux[ok]


def _fit(res: Residual, side: str, target: str, source: str, measured: bool
         ) -> Candidate | None:  # fmt: skip
    pts, aux = _gather(res, side, target, source, measured)
    if pts.size < MIN_POINTS:
        return None
    g = aux / pts.Hs
    e = pts.e()
    # a grid over |ε| of both signs (the log residual is far from linear in ε where the
    # leaked response outgrows the channel's own), with the first-order estimate
    # e ≈ ε g (real ε) among the starts
    den = float(np.sum(pts.w * np.abs(g) ** 2))
    if den <= 0:
        return None
    eps1 = float(np.sum(pts.w * (np.conj(g) * e).real) / den)
    mags = np.geomspace(GRID_LO, GRID_HI, GRID_N)
    grid = np.sort(np.concatenate([-mags[::-1], mags, [eps1]]))
    eps0 = scan(lambda x: pts.sq(pts.Hs + x * aux), grid)

    def model(th: np.ndarray) -> np.ndarray:
        return pts.Hs + th[0] * aux

    fit = fit_points(pts, model, np.array([eps0]))
    if fit is None:
        return None
    loc = Location(side, (target, source))
    what = "output" if side == "output" else "input"

    def describe(sig: Significance) -> Finding:
        eps, std = float(fit.theta[0]), float(fit.std[0])
        if side == "output":
            text = (
                f"output {target} reads ε = {eps:.3g} (± {std:.2g}) of output {source}'s "
                f"response: a misaligned {target} sensor or cross-talk from {source}"
            )
            advice = f"check the {target} sensor's alignment and its cabling next to {source}"
        else:
            text = (
                f"the {target} drive also acts through {source}: input column {target} reads "
                f"ε = {eps:.3g} (± {std:.2g}) of column {source} (the {target} force is not "
                "on its axis, or cross-talk)"
            )
            advice = f"check the {target} drive's line of action and its cabling"
        return Leakage("leakage", text, sig.share, loc, None, advice, sig, target=target,
                       source=source, epsilon=eps, std=std,
                       source_from="data" if measured else "model")  # fmt: skip

    return Candidate(f"{what} {target} reading {what} {source}", pts, fit, 1.0, describe)
