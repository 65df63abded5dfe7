"""Frequency bands for the per-band sensitivities, found from the model's modes.

*Features* are the resonances (damped natural frequencies ``|λ|/2π`` of the linearised model,
``λ`` eigenvalues of its state matrix) and the anti-resonances of each measured diagonal
(driving-point) channel ``j.j``: the zeros of ``H_jj`` are the eigenvalues of the model with
coordinate ``j`` clamped (row and column ``j`` removed from M, K, D). Each feature gets a
window ``f·(1 ± h)`` with ``h = max(2ζ, min_halfwidth, 1.5 × the local grid step)`` (``±2ζ``
holds the half-power band ``±ζ`` with margin); windows that overlap, or whose gap holds no
used frequency, merge into one ``resonance`` band. What lies below the first window is
``below``, above the last one ``above``, and the gaps in between are ``between`` bands, so the
bands tile the used frequency range. Bands without data are dropped.

User bands are kept as given and classed by the features they hold: a band holding a feature
is ``resonance``, one below (above) every feature ``below`` (``above``), otherwise ``between``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..linear.affine import AffineModel

BAND_CLASSES: tuple[str, ...] = ("below", "resonance", "between", "above")


@dataclass(frozen=True)
class Feature:
    """A resonance (``kind="resonance"``) or an anti-resonance of channel ``channel``."""

    f_hz: float
    zeta: float
    kind: str
    channel: str | None = None


@dataclass
class Band:
    """A frequency band ``[f_lo_hz, f_hi_hz]`` (Hz) of class ``below/resonance/between/above``
    (``user``: given by the user rather than found from the model)."""

    f_lo_hz: float
    f_hi_hz: float
    cls: str
    features: list[Feature] = field(default_factory=list)
    user: bool = False

    @property
    def label(self) -> str:
        if self.user:
            return f"{_fmt(self.f_lo_hz)}–{_fmt(self.f_hi_hz)} Hz ({self.cls})"
        res = [f for f in self.features if f.kind == "resonance"]
        anti = [f for f in self.features if f.kind != "resonance"]
        if self.cls == "resonance" and (res or anti):
            shown = res if res else anti
            tag = "R" if res else "A"
            core = ",".join(f"{f.f_hz:.4g}" for f in shown[:3]) + ("…" if len(shown) > 3 else "")
            return f"{tag} {core} Hz"
        return f"{self.cls} {_fmt(self.f_lo_hz)}–{_fmt(self.f_hi_hz)} Hz"

    def contains(self, f_hz: np.ndarray) -> np.ndarray:
        return (f_hz >= self.f_lo_hz) & (f_hz <= self.f_hi_hz)


def _fmt(f: float) -> str:
    return f"{f:.3g}" if f < 1000 else f"{f / 1000:.3g}k"


def _underdamped(M: np.ndarray, K: np.ndarray, D: np.ndarray) -> list[tuple[float, float]]:
    """(f_hz, ζ) of the oscillatory eigenvalues (Im λ > 0) of M q̈ + D q̇ + K q = 0."""
    n = M.shape[0]
    if n == 0:
        return []
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ D]])
    lam = np.linalg.eigvals(A)
    out = []
    for v in lam:
        if v.imag > 1e-9 * max(1.0, abs(v)):
            a = abs(v)
            out.append((float(a / (2.0 * np.pi)), float(-v.real / a)))
    return sorted(out)


def model_features(
    affine: AffineModel, channels: Sequence[str] = (), f_range: tuple[float, float] | None = None
) -> list[Feature]:
    """Resonances of ``affine`` and anti-resonances of its diagonal ``channels`` (``j.j``).

    Args:
        affine: the model at one operating point (current values).
        channels: channel names ``OUT.IN``; those with ``OUT == IN`` give anti-resonances.
        f_range: keep features with ``f_lo ≤ f ≤ f_hi`` (Hz); None = all.

    Returns:
        Features sorted by frequency.
    """
    lm = affine.linear_model()
    feats = [Feature(f, z, "resonance") for f, z in _underdamped(lm.M, lm.K, lm.D)]
    for ch in channels:
        out, _, inp = ch.rpartition(".")
        if out != inp or out not in affine.dofs:
            continue
        j = affine.dofs.index(out)
        keep = [i for i in range(affine.nv) if i != j]
        ix = np.ix_(keep, keep)
        feats += [
            Feature(f, z, "anti-resonance", ch)
            for f, z in _underdamped(lm.M[ix], lm.K[ix], lm.D[ix])
        ]
    if f_range is not None:
        feats = [f for f in feats if f_range[0] <= f.f_hz <= f_range[1]]
    return sorted(feats, key=lambda f: f.f_hz)


def _grid_step(freq_hz: np.ndarray, f: float) -> float:
    """Relative spacing of the sorted grid ``freq_hz`` near ``f``."""
    fs = np.unique(freq_hz)
    if fs.size < 2:
        return 0.0
    k = int(np.clip(np.searchsorted(fs, f), 1, fs.size - 1))
    return float((fs[k] - fs[k - 1]) / fs[k - 1])


def automatic_bands(
    features: Sequence[Feature], freq_hz: np.ndarray, *, min_halfwidth: float = 0.02
) -> list[Band]:
    """Bands around and between ``features`` covering the used frequencies ``freq_hz`` (Hz).

    Returns:
        Bands in frequency order (see the module docstring); each holds ≥ 1 frequency.
    """
    fs = np.unique(np.asarray(freq_hz, dtype=float))
    lo_all, hi_all = float(fs[0]), float(fs[-1])
    wins: list[list] = []
    for ft in sorted(features, key=lambda x: x.f_hz):
        h = max(2.0 * ft.zeta, min_halfwidth, 1.5 * _grid_step(fs, ft.f_hz))
        lo, hi = ft.f_hz / (1.0 + h), ft.f_hz * (1.0 + h)
        if hi < lo_all or lo > hi_all:
            continue
        gap_empty = bool(wins) and not np.any((fs > wins[-1][1]) & (fs < lo))
        if wins and (lo <= wins[-1][1] or gap_empty):
            wins[-1][1] = max(wins[-1][1], hi)
            wins[-1][2].append(ft)
        else:
            wins.append([lo, hi, [ft]])
    bands: list[Band] = []
    if not wins:
        return [Band(lo_all, hi_all, "between")]
    edge = lo_all
    for k, (lo, hi, fts) in enumerate(wins):
        if lo > edge:
            bands.append(Band(edge, lo, "below" if k == 0 else "between"))
        bands.append(Band(max(lo, lo_all), min(hi, hi_all), "resonance", list(fts)))
        edge = hi
    if edge < hi_all:
        bands.append(Band(edge, hi_all, "above"))
    # half-open use of the shared edges: a frequency on an edge belongs to the resonance band
    out = []
    for b in bands:
        inside = b.contains(fs)
        if b.cls != "resonance":
            for r in bands:
                if r.cls == "resonance":
                    inside &= ~r.contains(fs)
        if inside.any():
            out.append(b)
    return out


def classify_bands(user: Sequence[tuple[float, float]], features: Sequence[Feature]) -> list[Band]:
    """User bands (Hz) as :class:`Band` objects, classed by the features they hold."""
    fts = sorted(features, key=lambda x: x.f_hz)
    out = []
    for lo, hi in user:
        inside = [f for f in fts if lo <= f.f_hz <= hi]
        if inside:
            cls = "resonance"
        elif not fts or hi < fts[0].f_hz:
            cls = "below"
        elif lo > fts[-1].f_hz:
            cls = "above"
        else:
            cls = "between"
        out.append(Band(float(lo), float(hi), cls, inside, user=True))
    return out


def band_masks(bands: Sequence[Band], freq_hz: np.ndarray, *, exclusive: bool = True) -> np.ndarray:
    """Boolean ``(n_bands, n_r)``: which entries (frequencies ``freq_hz`` ``(n_r,)``) fall in
    each band. With ``exclusive`` (automatic bands, which share edges) a frequency inside a
    resonance band counts for that band only; user bands (``exclusive=False``) may overlap."""
    f = np.asarray(freq_hz, dtype=float)
    masks = np.array([b.contains(f) for b in bands]).reshape(len(bands), f.size)
    res = np.array([b.cls == "resonance" for b in bands], dtype=bool)
    if exclusive and res.any():
        in_res = masks[res].any(axis=0)
        masks[~res] &= ~in_res
    return masks
