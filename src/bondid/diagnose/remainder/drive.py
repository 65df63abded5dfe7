"""A stiffness, damping or mass the model lacks at a drive: a spring and damper to ground in
parallel with the drive (a cable carrier, drag chain, bellows, a guide's preload), or a mass
moving with it (a cable, a bracket).

For a collocated drive ``d`` (an output and an input of one name: the drive's own position
and force), adding a dynamic stiffness ``Δz(ω) = k + jωc − ω²m`` between its coordinate and
ground changes every receptance by the rank-one update (Sherman–Morrison)

    H'(o, i) = H(o, i) − H(o, d) Δz H(d, i) / (1 + Δz H(d, d)),

exact whatever the rest of the model. Below the first mode the drive-point receptance of a
free axis rises as ``1/ω²``; with ``k`` it flattens at ``1/k``; a mass offsets the mass line
above the modes. ``k``, ``c`` and ``m`` are fitted by least squares on the log residual of
every channel; the terms the data do not determine (``|value|/std < Z``) are dropped and the
rest refitted. Units: N/m, N·s/m and kg for a linear axis, N·m/rad, N·m·s/rad and kg·m² for
the rotary ones named in :attr:`.Settings.rotary`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..scoring import Z
from . import words
from .base import Candidate, Finding, Location, Significance
from .context import Context
from .groups import MIN_POINTS
from .residual import Points, Residual
from .stats import LogFit, fit_points, scan

TERMS = ("k", "c", "m")
#: the units of k, c and m on a linear and on a rotary drive (:attr:`.Settings.rotary`)
LINEAR_UNITS = {"k": "N/m", "c": "N·s/m", "m": "kg"}
ROTARY_UNITS = {"k": "N·m/rad", "c": "N·m·s/rad", "m": "kg·m²"}
#: the grid of |k|/k_ref and |m|/m_ref searched for a start (k_ref, m_ref: the drive point's
#: apparent stiffness at the lowest frequency and mass at the highest)
GRID_LO, GRID_HI, GRID_N = 1e-3, 1e3, 49


@dataclass
class DriveOffset(Finding):
    """At drive ``drive``: ``stiffness`` [N/m], ``damping`` [N·s/m], ``mass`` [kg] (0 when
    not determined) and their stds."""

    drive: str = ""
    stiffness: float = 0.0
    damping: float = 0.0
    mass: float = 0.0
    std: dict[str, float] | None = None
    units: dict[str, str] | None = None

    def figures(self) -> dict[str, Any]:
        return {"drive": self.drive, "stiffness": self.stiffness, "damping": self.damping,
                "mass": self.mass, "std": dict(self.std or {}),
                "units": dict(self.units or LINEAR_UNITS)}  # fmt: skip


def candidates(res: Residual, ctx: Context) -> list[Candidate]:
    out = []
    for d in [n for n in res.outputs if n in res.inputs]:
        cand = _fit(res, d, ctx)
        if cand is not None:
            out.append(cand)
    return out


def _gather(res: Residual, d: str) -> tuple[Points, np.ndarray, np.ndarray, np.ndarray]:
    """Every used point of the data sets holding drive ``d``, with the model's ``H(o, d)``,
    ``H(d, i)`` and ``H(d, d)`` there."""

    def select(k: int, st: Any) -> np.ndarray:
        return np.full(st.Hm.shape, d in st.outputs and d in st.inputs)

    pts = res.points(select)
    col, row, dd = (np.empty(pts.size, complex) for _ in range(3))
    for k, st in enumerate(res.sets):
        sel = pts.k == k
        if not np.any(sel):
            continue
        a, b = st.outputs.index(d), st.inputs.index(d)
        j = pts.j[sel]
        col[sel] = st.Hs[pts.a[sel], b, j]
        row[sel] = st.Hs[a, pts.b[sel], j]
        dd[sel] = st.Hs[a, b, j]
    ok = np.isfinite(col) & np.isfinite(row) & np.isfinite(dd)
    return pts.subset(ok), col[ok], row[ok], dd[ok]


def _fit(res: Residual, d: str, ctx: Context) -> Candidate | None:
    pts, col, row, dd = _gather(res, d)
    if pts.size < MIN_POINTS:
        return None
    s = pts.s
    basis = np.stack([np.ones_like(s), s, s * s])  # Δz = k + s c + s² m
    # reference scales: the drive point's apparent stiffness at the ends of the range
    lo, hi = int(np.argmin(np.abs(s))), int(np.argmax(np.abs(s)))
    k_ref = 1.0 / abs(dd[lo])
    m_ref = 1.0 / (abs(dd[hi]) * abs(s[hi]) ** 2)
    ref = np.array([k_ref, math.sqrt(k_ref * m_ref), m_ref])
    g = col * row / pts.Hs  # first order: e ≈ −Δz g

    def model_of(use: list[int]) -> Any:
        def model(th: np.ndarray) -> np.ndarray:
            dz = (th * ref[use]) @ basis[use]
            return pts.Hs - col * dz * row / (1.0 + dz * dd)

        return model

    def derivative_of(use: list[int]) -> Any:
        def derivative(th: np.ndarray, sel: np.ndarray) -> np.ndarray:
            b = basis[use][:, sel]
            dz = (th * ref[use]) @ b
            dH = -col[sel] * row[sel] / (1.0 + dz * dd[sel]) ** 2  # ∂H/∂Δz
            return (dH[None, :] * b * ref[use, None]).T

        return derivative

    # starts: the first-order least-squares solution, and the best stiffness alone and mass
    # alone on a grid of both signs (far from first order where k flattens the low end)
    w2 = np.sqrt(np.concatenate([pts.w, pts.w]))
    thin = np.arange(0, pts.size, max(1, -(-pts.size // 800)))  # the grid's points
    few = pts.subset(thin)
    e = pts.e()
    mags = np.geomspace(GRID_LO, GRID_HI, GRID_N)
    grid = np.concatenate([-mags[::-1], mags])

    def fit_terms(use: list[int]) -> LogFit | None:
        X = -(basis[use] * ref[use, None]).T * g[:, None]  # (N, p) complex
        A = np.concatenate([X.real, X.imag]) * w2[:, None]
        y = np.concatenate([e.real, e.imag]) * w2
        starts = [np.linalg.lstsq(A, y, rcond=None)[0]]
        for u in (0, 2):
            if u in use:
                one = model_of([u])

                def cost(v: float, one: Any = one) -> float:
                    return few.sq(one(np.array([v]))[thin])

                x = scan(cost, grid)
                starts.append(np.where(np.array(use) == u, x, 0.0))
        best = None
        for x0 in starts:
            f = fit_points(pts, model_of(use), x0, derivative=derivative_of(use))
            if f is not None and (best is None or f.s1 < best.s1):
                best = f
        return best

    use = [0, 1, 2]
    fit = fit_terms(use)
    if fit is None:
        return None
    z = np.abs(fit.theta) / np.where(fit.std > 0, fit.std, np.inf)
    keep = [u for u, zz in zip(use, z, strict=True) if zz >= Z]
    if keep and keep != use:
        refit = fit_terms(keep)
        if refit is not None:
            fit, use = refit, keep
    values = {t: 0.0 for t in TERMS}
    stds = {t: 0.0 for t in TERMS}
    for n, u in enumerate(use):
        values[TERMS[u]] = float(fit.theta[n] * ref[u])
        stds[TERMS[u]] = float(fit.std[n] * ref[u])
    units = ROTARY_UNITS if d in ctx.settings.rotary else LINEAR_UNITS
    return Candidate(f"stiffness or mass at drive {d}", pts, fit, 1.0,
                     _describer(d, values, stds, k_ref, units))  # fmt: skip


def _describer(
    d: str, v: dict[str, float], sd: dict[str, float], k_ref: float, units: dict[str, str]
) -> Any:
    def describe(sig: Significance) -> Finding:
        k, c, m = v["k"], v["c"], v["m"]
        loc = Location("drive", (d,), ())
        stiff = k != 0 and (m == 0 or abs(k) / k_ref >= 0.1)
        parts = []
        uk, uc, um = units["k"], units["c"], units["m"]
        if k:
            sign = "a spring to ground" if k > 0 else "less stiffness to ground than the model"
            parts.append(f"{sign} of {words.si(abs(k), uk)} (± {words.si(sd['k'], uk)})")
        if c:
            parts.append(f"damping {words.si(c, uc)}")
        if m:
            what = "a mass the model lacks" if m > 0 else "less moving mass than the model"
            parts.append(f"{what}: {abs(m):.3g} {um} (± {sd['m']:.2g})")
        if stiff:
            kind = "stiffness_offset"
            text = (
                f"at drive {d} the data show {words.names(parts)}, in parallel with the drive: "
                "the receptance below the first mode flattens where the model's rises"
                if k > 0
                else f"at drive {d} the data show {words.names(parts)}"
            )
            advice = (f"look for what holds the {d} axis to ground (cable carrier, drag chain, "
                      "bellows, a guide's preload)")  # fmt: skip
        else:
            kind = "mass_offset"
            text = f"at drive {d} the mass line is offset: {words.names(parts)}"
            advice = f"look for mass moving with the {d} axis (cables, a bracket, a payload)"
        return DriveOffset(kind, text, sig.share, loc, None, advice, sig, drive=d, stiffness=k,
                           damping=c, mass=m, std=sd, units=dict(units))  # fmt: skip

    return describe
