"""Where the remainder lies: the excess of the residual over the noise in total, by channel,
output row, input column and frequency band (:func:`excess_figures`).

For a group of points: ``db_rms = (20/ln 10)·√(Σ w|e|² / Σ w)`` (the weighted gap of the
diagnosis), ``noise_db`` the same of the noise's ``m`` (the level an exact model would show),
its excess ``Σ w (|e − μ|² − m_c)`` on the centred residual (:mod:`.residual`: ``μ`` the
noise's own mean log error, ``m_c = m − μ²``), and ``z = (Σ w|e − μ|² − t Σ w m_c) /
(t √(Σ w² q))`` with ``t = (1 + LEVEL_TOL)²`` (how far it stands above the noise, allowing
the noise prediction's tolerance); ``above_noise`` of the whole is the rule of the verdict on
the same centred sums. The ``share`` of a group is its positive excess over the sum of the positive
excesses of its partition (channels, rows, columns or bands); ``even_share`` is its share of
the weight, what it would carry were the excess spread evenly.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...cost.residuals import DB
from ...jsonsafe import json_safe
from ..scoring import LEVEL_TOL, Z
from .residual import Residual

#: fixed analysis bands per decade of frequency
BANDS_PER_DECADE = 6
#: "where": the fewest bands (and channels) that carry this share of the excess
WHERE_SHARE = 0.6


@dataclass(frozen=True)
class Part:
    """The figures of one group of points (module docstring)."""

    name: str
    db_rms: float
    noise_db: float
    share: float
    even_share: float
    z: float
    excess: float
    f_lo_hz: float | None = None
    f_hi_hz: float | None = None

    @property
    def above_noise(self) -> bool:
        return self.z > Z

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "db_rms": self.db_rms,
            "noise_db": self.noise_db,
            "share": self.share,
            "even_share": self.even_share,
            "z": self.z,
            "above_noise": self.above_noise,
        }
        if self.f_lo_hz is not None:
            out = {"f_lo_hz": self.f_lo_hz, "f_hi_hz": self.f_hi_hz, **out}
        else:
            out = {"name": self.name, **out}
        return json_safe(out)


@dataclass
class ExcessFigures:
    """The excess of the residual over the noise.

    Attributes:
        db_rms: weighted RMS log error over every used point [dB].
        noise_db: the noise level an exact model would show there [dB].
        n_eff: independent points behind ``noise_db`` (as :func:`.scoring.heldout_noise`).
        above_noise: is ``db_rms`` above the level beyond its tolerance and sampling error
            (the rule of :func:`bondid.diagnose.scoring.above_level`)?
        by_channel, by_output, by_input: :class:`Part` per channel / row / column.
        by_band: :class:`Part` per fixed log band (:data:`BANDS_PER_DECADE`).
        where_bands: merged bands carrying :data:`WHERE_SHARE` of the excess.
        where_channels: the channels carrying :data:`WHERE_SHARE` of it, largest first.
    """

    db_rms: float
    noise_db: float
    n_eff: float
    above_noise: bool
    by_channel: list[Part]
    by_output: list[Part]
    by_input: list[Part]
    by_band: list[Part]
    where_bands: list[Part] = field(default_factory=list)
    where_channels: list[str] = field(default_factory=list)

    @property
    def ratio(self) -> float:
        return self.db_rms / self.noise_db if self.noise_db > 0 else math.inf

    def as_dict(self) -> dict[str, Any]:
        return json_safe(
            {
                "db_rms": self.db_rms,
                "noise_db": self.noise_db,
                "ratio": self.ratio,
                "n_eff": self.n_eff,
                "above_noise": self.above_noise,
                "by_channel": {p.name: _drop_name(p) for p in self.by_channel},
                "by_output": {p.name: _drop_name(p) for p in self.by_output},
                "by_input": {p.name: _drop_name(p) for p in self.by_input},
                "by_band": [p.as_dict() for p in self.by_band],
                "where": {
                    "bands": [p.as_dict() for p in self.where_bands],
                    "channels": list(self.where_channels),
                },
            }
        )


def _drop_name(p: Part) -> dict[str, Any]:
    d = p.as_dict()
    d.pop("name", None)
    return d


@dataclass
class _Sums:
    s: float = 0.0  # Σ w |e|²
    m: float = 0.0  # Σ w m
    sc: float = 0.0  # Σ w |e − μ|²
    mc: float = 0.0  # Σ w (m − μ²)
    q: float = 0.0  # Σ w² q
    w: float = 0.0  # Σ w

    def add(self, arrays: dict[str, np.ndarray], sel: np.ndarray) -> None:
        w = arrays["w"][sel]
        self.s += float(np.sum(w * arrays["e2"][sel]))
        self.m += float(np.sum(w * arrays["m"][sel]))
        self.sc += float(np.sum(w * arrays["c2"][sel]))
        self.mc += float(np.sum(w * arrays["mc"][sel]))
        self.q += float(np.sum(w * w * arrays["q"][sel]))
        self.w += float(np.sum(w))

    def pool(self, other: _Sums) -> None:
        for f in ("s", "m", "sc", "mc", "q", "w"):
            setattr(self, f, getattr(self, f) + getattr(other, f))

    @property
    def excess(self) -> float:
        return self.sc - self.mc

    def z(self) -> float:
        t = (1.0 + LEVEL_TOL) ** 2
        if self.q <= 0:
            return math.inf if self.sc > t * self.mc else -math.inf
        return (self.sc - t * self.mc) / (t * math.sqrt(self.q))


def _arrays(st: Any) -> dict[str, np.ndarray]:
    """A data set's per-point arrays for :class:`_Sums`."""
    return {"e2": np.abs(st.e()) ** 2, "c2": np.abs(st.centred()) ** 2, "w": st.w, "m": st.m,
            "mc": st.mc, "q": st.q}  # fmt: skip


def _rms(x: float, w: float) -> float:
    return float(DB * math.sqrt(max(x, 0.0) / w)) if w > 0 else math.nan


def _parts(groups: dict[str, _Sums], total_w: float, bands: dict[str, tuple] | None = None
           ) -> list[Part]:  # fmt: skip
    pos = sum(max(g.excess, 0.0) for g in groups.values())
    out = []
    for name, g in groups.items():
        if g.w <= 0:
            continue
        lo, hi = bands[name] if bands else (None, None)
        out.append(
            Part(
                name, _rms(g.s, g.w), _rms(g.m, g.w),
                max(g.excess, 0.0) / pos if pos > 0 else 0.0, g.w / total_w, g.z(), g.excess,
                lo, hi,
            )
        )  # fmt: skip
    return out


def band_edges(res: Residual, per_decade: int = BANDS_PER_DECADE) -> np.ndarray:
    """Log-spaced band edges [Hz] over the used frequencies of every data set."""
    fs = [s.freq_hz[np.any(s.used, axis=(0, 1))] for s in res.sets]
    f = np.concatenate([x for x in fs if x.size] or [np.array([1.0, 10.0])])
    lo, hi = float(f.min()), float(f.max())
    n = max(2, math.ceil(per_decade * math.log10(max(hi / lo, 1.0 + 1e-9))))
    edges = np.geomspace(lo, hi, n + 1)
    edges[-1] = np.nextafter(hi, np.inf)
    return edges


def positive_excess(res: Residual, per_decade: int = BANDS_PER_DECADE) -> float:
    """The excess over the noise where it lies: ``Σ max(0, Σ w (|e|² − m))`` over the cells
    of one channel of one data set in one fixed band (natural units). A noise reference
    that is high in some places (a cautious estimate) would otherwise cancel part of a real
    excess elsewhere in a plain sum, and every share taken against it would be inflated."""
    edges = band_edges(res, per_decade)
    total = 0.0
    for st in res.sets:
        x = st.w * (np.abs(st.centred()) ** 2 - st.mc)  # 0 where unused
        idx = np.clip(np.searchsorted(edges, st.freq_hz, side="right") - 1, 0, edges.size - 2)
        for n in np.unique(idx):
            cell = np.sum(x[:, :, idx == n], axis=2)
            total += float(np.sum(np.clip(cell, 0.0, None)))
    return total


def excess_figures(res: Residual, per_decade: int = BANDS_PER_DECADE) -> ExcessFigures:
    """The excess figures of ``res`` (module docstring)."""
    total = _Sums()
    chan: dict[str, _Sums] = {}
    rows: dict[str, _Sums] = {o: _Sums() for o in res.outputs}
    cols: dict[str, _Sums] = {i: _Sums() for i in res.inputs}
    edges = band_edges(res, per_decade)
    bands = {f"{lo:.6g}-{hi:.6g}": (float(lo), float(hi)) for lo, hi in itertools.pairwise(edges)}
    bsum = {name: _Sums() for name in bands}
    bnames = list(bands)
    for st in res.sets:
        arr = _arrays(st)
        u = st.used
        total.add(arr, u)
        idx = np.clip(np.searchsorted(edges, st.freq_hz, side="right") - 1, 0, len(bnames) - 1)
        for a, o in enumerate(st.outputs):
            for b, i in enumerate(st.inputs):
                uu = np.zeros(u.shape, bool)
                uu[a, b] = u[a, b]
                if not np.any(uu):
                    continue
                chan.setdefault(f"{o}.{i}", _Sums()).add(arr, uu)
                rows[o].add(arr, uu)
                cols[i].add(arr, uu)
                for n in np.unique(idx[u[a, b]]):
                    bsum[bnames[n]].add(arr, uu & (idx == n)[None, None, :])
    W = total.w
    by_band = _parts(bsum, W, bands)
    by_channel = _parts(chan, W)
    n_eff = total.mc**2 / total.q if total.q > 0 else math.inf
    s0, L2 = total.sc / W, total.mc / W
    above = s0 > (1.0 + LEVEL_TOL) ** 2 * L2 * (1.0 + Z / math.sqrt(n_eff))
    return ExcessFigures(
        db_rms=_rms(total.s, W), noise_db=_rms(total.m, W), n_eff=n_eff, above_noise=bool(above),
        by_channel=by_channel, by_output=_parts(rows, W), by_input=_parts(cols, W),
        by_band=by_band, where_bands=_where_bands(by_band, bsum, W),
        where_channels=_top(by_channel, lambda p: p.name),
    )  # fmt: skip


def _top(parts: list[Part], name: Callable[[Part], str]) -> list[str]:
    """Names of the fewest parts (largest share first) carrying :data:`WHERE_SHARE`."""
    out, acc = [], 0.0
    for p in sorted(parts, key=lambda p: -p.share):
        if acc >= WHERE_SHARE or p.share <= 0:
            break
        out.append(name(p))
        acc += p.share
    return out


def _where_bands(by_band: list[Part], sums: dict[str, _Sums], total_w: float) -> list[Part]:
    """The fewest bands carrying :data:`WHERE_SHARE` of the excess, adjacent ones merged
    (their sums pooled), in frequency order."""
    chosen = set(_top(by_band, lambda p: p.name))
    groups: list[list[Part]] = []
    prev = False
    for p in by_band:
        if p.name in chosen:
            if prev:
                groups[-1].append(p)
            else:
                groups.append([p])
        prev = p.name in chosen
    out = []
    for g in groups:
        pool = _Sums()
        for p in g:
            pool.pool(sums[p.name])
        out.append(
            Part(
                g[0].name, _rms(pool.s, pool.w), _rms(pool.m, pool.w), sum(p.share for p in g),
                pool.w / total_w, pool.z(), pool.excess, g[0].f_lo_hz, g[-1].f_hi_hz,
            )
        )  # fmt: skip
    return out
