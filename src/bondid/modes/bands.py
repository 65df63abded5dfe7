"""Modes and frequency bands of a linearised model: the one place the fit (staged bands), the
sensitivity (per-band sensitivities), the diagnosis and the mode table find resonances and
bands.

Resonances. The oscillatory eigenvalues λ (``Im λ > 0``,
:func:`~bondid.linear.linear_model.is_oscillatory`) of the state matrix of
``M q̈ + D q̇ + K q = B u`` give ``f = |λ|/2π`` and ``ζ = −Re λ/|λ|``
(:func:`~bondid.linear.linear_model.underdamped`). :func:`resonances`
(:func:`model_resonances` from a URDF) adds whether
a resonance is *parasitic*: most of its modal strain energy in springs of joints without a
transmission.

Stage bands (the staged fit, :func:`stage_bands`): ``stiffness`` below the first parasitic
resonance ``f_p`` (``[f_min, f_p/1.5]``), ``damping`` in ``[f/1.25, f·1.25]`` around every
resonance, ``inertia`` from ``f_p`` up (``[f_p, f_max]``); a band is a :data:`Span` ``(lo, hi)``
in Hz.

Classed bands (the sensitivity, :func:`automatic_bands`). *Features* are the resonances and
the anti-resonances of each measured diagonal (driving-point) channel ``j.j``: the zeros of
``H_jj`` are the eigenvalues of the model with coordinate ``j`` clamped (row and column ``j``
removed from M, K, D). Each feature gets a window ``f·(1 ± h)`` with ``h = max(2ζ,
min_halfwidth, 1.5 × the local grid step)`` (``±2ζ`` holds the half-power band ``±ζ`` with
margin); windows that overlap, or whose gap holds no used frequency, merge into one
``resonance`` band. What lies below the first window is ``below``, above the last one
``above``, and the gaps in between are ``between`` bands, so the bands tile the used frequency
range. Bands without data are dropped. User bands are kept as given and classed by the features
they hold (:func:`classify_bands`): a band holding a feature is ``resonance``, one below (above)
every feature ``below`` (``above``), otherwise ``between``.

For the diagnosis: ``automatic_bands(model_features(affine, channels, f_range), freq_hz)``
gives the bands of a model around its resonances and anti-resonances; :func:`band_masks` says
which residual entries fall in each.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..linear.affine import AffineModel
from ..linear.linear_model import underdamped, viscous_equivalent

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..model.document import UrdfDocument

BAND_CLASSES: tuple[str, ...] = ("below", "resonance", "between", "above")
#: a frequency span ``(lo, hi)`` in Hz
Span = tuple[float, float]
#: Half-width of a damping stage band around a resonance, as a frequency ratio.
DAMPING_BAND_RATIO = 1.25
#: The stiffness stage band ends this factor below the first parasitic resonance.
STIFFNESS_BAND_MARGIN = 1.5


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


def _damped_modes(
    M: np.ndarray, K: np.ndarray, D: np.ndarray, G: np.ndarray | None
) -> list[tuple[float, float]]:
    """``(f_hz, ζ)`` of ``M q̈ + D q̇ + K q = 0``; a hysteretic stiffness ``G`` as its viscous
    equivalent at each of these modes' own frequencies (so a clamped system's loss factor
    damps its own modes, not those of the whole model)."""
    return underdamped(M, K, D if G is None else viscous_equivalent(M, K, D, G))


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
    feats = [Feature(f, z, "resonance") for f, z in _damped_modes(lm.M, lm.K, lm.D, lm.G)]
    for ch in channels:
        out, _, inp = ch.rpartition(".")
        if out != inp or out not in affine.dofs:
            continue
        j = affine.dofs.index(out)
        keep = [i for i in range(affine.nv) if i != j]
        ix = np.ix_(keep, keep)
        G = None if lm.G is None else lm.G[ix]
        feats += [
            Feature(f, z, "anti-resonance", ch)
            for f, z in _damped_modes(lm.M[ix], lm.K[ix], lm.D[ix], G)
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
    features: Sequence[Feature],
    freq_hz: np.ndarray,
    *,
    min_halfwidth: float = 0.02,
    min_points: int = 1,
) -> list[Band]:
    """Bands around and between ``features`` covering the used frequencies ``freq_hz`` (Hz).

    ``min_points``: a band holding fewer frequencies is merged into its lower neighbour (the
    first into its upper one), so that every band can be scored (the diagnosis's gap bands).

    Returns:
        Bands in frequency order (see the module docstring); each holds ≥ 1 frequency
        (≥ ``min_points`` when there are that many).
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
    return _merge_small(out, fs, min_points)


def _merge_small(bands: list[Band], fs: np.ndarray, min_points: int) -> list[Band]:
    """``bands`` with those holding fewer than ``min_points`` of ``fs`` merged into their
    lower neighbour (the first into its upper one)."""
    out = list(bands)
    k = 0
    while len(out) > 1 and k < len(out):
        if int(out[k].contains(fs).sum()) >= min_points:
            k += 1
            continue
        a = k - 1 if k > 0 else 0
        lo, hi = out[a], out[a + 1]
        if "resonance" in (lo.cls, hi.cls):
            cls = "resonance"
        else:
            cls = lo.cls if lo.cls == "below" else hi.cls
        out[a : a + 2] = [Band(lo.f_lo_hz, hi.f_hi_hz, cls, [*lo.features, *hi.features])]
        k = a
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


# -- resonances and the staged fit's bands ---------------------------------------------------
@dataclass
class Resonance:
    """A resonance of the linearised model: ``f_hz = |λ|/2π``, ``zeta = −Re λ/|λ|``;
    ``parasitic`` when most of its spring energy is in joints without a transmission."""

    f_hz: float
    zeta: float
    parasitic: bool


def model_resonances(
    doc: UrdfDocument, operating_point: Mapping[str, float] | None = None
) -> list[Resonance]:
    """The vibration modes of ``doc`` at ``operating_point``, lowest first (linearises the
    model; :func:`resonances` reads an existing linearisation)."""
    from ..linear.affine import build_affine_model

    driven = {t.joint for t in doc.transmissions}
    return resonances(build_affine_model(doc, operating_point), driven)


def resonances(affine: AffineModel, driven: Collection[str]) -> list[Resonance]:
    """The vibration modes of the linearised model ``affine`` (at its current values), lowest
    first; ``driven``: the joints with a transmission.

    The modes of :func:`bondid.modes.analysis.modal_analysis` (rigid-body and real
    eigenvalues left out); the strain energy of a mode shape ``φ`` in a joint spring is
    ``k_j |φ_j|²``.
    """
    from .analysis import modal_analysis

    k = np.asarray(affine.stiffness, dtype=float)
    para = np.array([d not in driven for d in affine.dofs])
    out: list[Resonance] = []
    for mode in modal_analysis(affine.linear_model()).vibration_modes():
        e = k * np.abs(mode.shape) ** 2  # strain energy per joint spring
        total = float(e.sum())
        parasitic = bool(total > 0 and e[para].sum() > 0.5 * total)
        out.append(Resonance(mode.f_hz, float(mode.zeta or 0.0), parasitic))
    return out


def merge_spans(spans: Sequence[Span]) -> list[Span]:
    """``spans`` sorted, overlapping ones merged."""
    out: list[Span] = []
    for lo, hi in sorted(spans):
        if out and lo <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


def clip_spans(spans: Sequence[Span], limits: Sequence[Span] | None) -> list[Span]:
    """``spans`` intersected with ``limits`` (None or empty = no limit), merged."""
    if not limits:
        return merge_spans(list(spans))
    out = []
    for lo, hi in spans:
        for a, b in limits:
            c, d = max(lo, a), min(hi, b)
            if c < d:
                out.append((c, d))
    return merge_spans(out)


def stage_bands(modes: Sequence[Resonance], f_min: float, f_max: float) -> dict[str, list[Span]]:
    """The staged fit's bands (Hz) from the model's resonances within ``[f_min, f_max]``.

    ``stiffness``: ``[f_min, f_p / 1.5]``, ``damping``: ``[f/1.25, f·1.25]`` around every
    resonance, ``inertia``: ``[f_p, f_max]``, where ``f_p`` is the first parasitic resonance
    (the lowest resonance if none is parasitic). Stages without a usable band are absent.
    """
    inside = [m for m in modes if f_min <= m.f_hz <= f_max]
    out: dict[str, list[Span]] = {}
    para = [m for m in inside if m.parasitic] or inside
    if not para:
        return out
    fp = para[0].f_hz
    if fp / STIFFNESS_BAND_MARGIN > f_min:
        out["stiffness"] = [(f_min, fp / STIFFNESS_BAND_MARGIN)]
    out["damping"] = merge_spans(
        [(m.f_hz / DAMPING_BAND_RATIO, m.f_hz * DAMPING_BAND_RATIO) for m in inside]
    )
    out["inertia"] = [(fp, f_max)]
    return out
