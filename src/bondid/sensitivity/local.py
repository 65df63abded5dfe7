"""Local (derivative-based) sensitivities from one exact Jacobian, per band and per channel.

With ``J = ∂r/∂ε`` the cost Jacobian in relative parameter units (columns of the exact
Jacobian times each parameter's scale, see :mod:`bondid.sensitivity._common`), the
sensitivity of parameter ``p`` over a set ``S`` of residual entries (a band, a channel, a
response direction) is

    ``s_p(S) = sqrt( Σ_{i∈S} J_ip² / W_S )``,

the RMS change of the residual over ``S`` for a unit relative change of ``p`` (first order;
``W_S`` is the set's weight, so the RMS is over the set's own points). For the default
``complex_log`` residual it reads in dB per 100 % change (× 0.01 for dB per 1 %). With data
that match the model (``r = 0``) the set's mean-square cost after a small step ``ε`` is
``ε²·s_p(S)²``. ``normalised`` maps divide each band (channel) column by its largest entry, so
a map compares parameters within a band.

Aggregates by parameter kind (stiffness / damping / inertial) per band class (below / at /
between / above the resonances, see :mod:`bondid.modes.bands`) use the union of the
class's bands: ``share`` is the kind's part of ``Σ_p s_p²``, ``rms`` the RMS of ``s_p`` over
the kind's parameters (a typical parameter of that kind), ``max`` its strongest parameter.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..cost import CostOptions
from ..data.measurement import FrfData
from ..exceptions import ComputationError
from ..model.document import UrdfDocument
from ..modes.bands import (
    BAND_CLASSES,
    Band,
    Feature,
    automatic_bands,
    band_masks,
    classify_bands,
    model_features,
)
from ._common import KIND_GROUPS, Setup, kind_group, label_masks, make_setup


@dataclass
class Linearisation:
    """The cost at the nominal parameters and its Jacobian in relative units.

    Attributes:
        setup: the :class:`Setup`.
        residual: scaled residual ``(n_r,)`` (``cost = ‖r‖²``).
        jacobian: ``∂r/∂ε`` ``(n_r, n_p)`` (exact Jacobian × scale per column).
        wall_s: time to compute it, s.
    """

    setup: Setup
    residual: np.ndarray
    jacobian: np.ndarray
    wall_s: float

    @property
    def cost(self) -> float:
        return float(self.residual @ self.residual)


def linearise_cost(setup: Setup) -> Linearisation:
    """One exact Jacobian at the nominal parameters (``setup.pmap.p0``)."""
    t0 = time.perf_counter()
    pm, p0 = setup.pmap, setup.pmap.p0
    r, J = setup.problem.residual_and_jacobian(pm, p0)
    Js = J * setup.scale[None, :]
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(Js))):
        raise ComputationError("sensitivity: the residual or its Jacobian is not finite")
    return Linearisation(setup, r, Js, time.perf_counter() - t0)


@dataclass
class KindAggregate:
    """Per band class and kind group: ``share``, ``rms`` and ``max`` (see module doc)."""

    share: dict[str, dict[str, float]] = field(default_factory=dict)
    rms: dict[str, dict[str, float]] = field(default_factory=dict)
    max: dict[str, dict[str, float]] = field(default_factory=dict)
    top: dict[str, dict[str, str]] = field(default_factory=dict)


@dataclass
class LocalSensitivity:
    """Local sensitivities (units: residual RMS per unit relative change; dB for complex_log).

    Attributes:
        names: parameters ``(n_p,)``; kinds: their kind groups (stiffness/damping/inertial).
        scale: relative unit per parameter ``(n_p,)``; zero_nominal: absolute-scaled names.
        features: resonances and anti-resonances used for the bands.
        bands: the bands ``(n_b,)``; band_sens ``(n_p, n_b)``; band_norm ``(n_p, n_b)``.
        channels: ``(n_ch,)``; channel_sens, channel_norm ``(n_p, n_ch)``.
        directions: output joints ``(n_dir,)``; direction_sens ``(n_p, n_dir)``.
        overall: over every entry ``(n_p,)`` (``overall² = ‖J_p‖²``).
        gradient: ``∂cost/∂ε`` ``(n_p,)`` (``2 Jᵀ r``).
        classes: band classes present; class_sens ``(n_p, n_classes)``.
        by_kind: :class:`KindAggregate` over the classes.
        cost: the nominal cost; jacobian_s: time of the Jacobian, s.
    """

    names: tuple[str, ...]
    kinds: tuple[str, ...]
    scale: np.ndarray
    zero_nominal: tuple[str, ...]
    features: list[Feature]
    bands: list[Band]
    band_sens: np.ndarray
    band_norm: np.ndarray
    channels: tuple[str, ...]
    channel_sens: np.ndarray
    channel_norm: np.ndarray
    directions: tuple[str, ...]
    direction_sens: np.ndarray
    overall: np.ndarray
    gradient: np.ndarray
    classes: tuple[str, ...]
    class_sens: np.ndarray
    by_kind: KindAggregate
    cost: float
    jacobian_s: float

    def top(self, band: int, k: int = 5) -> list[tuple[str, float]]:
        """The ``k`` most influential parameters in band ``band``: (name, sensitivity)."""
        col = self.band_sens[:, band]
        order = np.argsort(-np.nan_to_num(col, nan=-1.0), kind="stable")[:k]
        return [(self.names[i], float(col[i])) for i in order]


def _normalise(S: np.ndarray) -> np.ndarray:
    peak = np.nanmax(np.where(np.isfinite(S), S, np.nan), axis=0, initial=0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(peak > 0, S / np.where(peak > 0, peak, 1.0), 0.0)


def _sens(setup: Setup, J2: np.ndarray, masks: np.ndarray) -> np.ndarray:
    cols = [np.sqrt(setup.mean_square(J2, m)) for m in masks]
    return np.array(cols).T.reshape(J2.shape[1], len(cols))


def features_of(setup: Setup) -> list[Feature]:
    """Resonances and diagonal-channel anti-resonances of every data set's linearisation,
    within the used frequency range (duplicates from several operating points kept)."""
    f_range = (float(setup.freq_hz.min()), float(setup.freq_hz.max()))
    feats: list[Feature] = []
    for k, affine in enumerate(setup.problem.affines):
        chans = sorted({str(c) for c in setup.channel[setup.dataset == k]})
        feats += model_features(affine, chans, f_range)
    return sorted(feats, key=lambda f: f.f_hz)


def analyse_local(
    lin: Linearisation,
    bands: Sequence[tuple[float, float]] | None = None,
    *,
    min_halfwidth: float = 0.02,
) -> LocalSensitivity:
    """Per-band, per-channel and per-kind sensitivities from a :class:`Linearisation`.

    Args:
        lin: the nominal residual and relative Jacobian.
        bands: user bands ``[(f_lo, f_hi), ...]`` in Hz; None = automatic bands.
        min_halfwidth: smallest relative half-width of a resonance window.
    """
    setup = lin.setup
    J2 = lin.jacobian**2
    feats = features_of(setup)
    if bands:
        blist = classify_bands(bands, feats)
        masks = band_masks(blist, setup.freq_hz, exclusive=False)
    else:
        blist = automatic_bands(feats, setup.freq_hz, min_halfwidth=min_halfwidth)
        masks = band_masks(blist, setup.freq_hz, exclusive=True)
    band_sens = _sens(setup, J2, masks)
    channels, ch_masks = label_masks(setup.channel)
    channel_sens = _sens(setup, J2, ch_masks)
    directions, d_masks = label_masks(setup.direction)
    direction_sens = _sens(setup, J2, d_masks)
    classes = tuple(c for c in BAND_CLASSES if any(b.cls == c for b in blist))
    cls_masks = np.array(
        [np.any(masks[[b.cls == c for b in blist]], axis=0) for c in classes]
    ).reshape(len(classes), -1)
    class_sens = _sens(setup, J2, cls_masks)
    groups = tuple(kind_group(k) for k in setup.kinds)
    return LocalSensitivity(
        names=setup.names,
        kinds=groups,
        scale=setup.scale,
        zero_nominal=setup.zero_nominal,
        features=feats,
        bands=blist,
        band_sens=band_sens,
        band_norm=_normalise(band_sens),
        channels=channels,
        channel_sens=channel_sens,
        channel_norm=_normalise(channel_sens),
        directions=directions,
        direction_sens=direction_sens,
        overall=np.sqrt(J2.sum(axis=0)),
        gradient=2.0 * lin.jacobian.T @ lin.residual,
        classes=classes,
        class_sens=class_sens,
        by_kind=_kind_aggregate(class_sens, classes, groups, setup.names),
        cost=lin.cost,
        jacobian_s=lin.wall_s,
    )


def _kind_aggregate(
    class_sens: np.ndarray, classes: tuple[str, ...], groups: tuple[str, ...], names: Sequence[str]
) -> KindAggregate:
    """Share, RMS, max and strongest parameter of each kind group in each band class, from
    ``class_sens`` ``(n_params, n_classes)`` (see the module doc)."""
    agg = KindAggregate()
    for j, c in enumerate(classes):
        s = class_sens[:, j]
        total = float(np.sum(s**2))
        agg.share[c], agg.rms[c], agg.max[c], agg.top[c] = {}, {}, {}, {}
        for g in KIND_GROUPS:
            sel = np.array([x == g for x in groups], dtype=bool)
            if not sel.any():
                continue
            sg = s[sel]
            agg.share[c][g] = float(np.sum(sg**2) / total) if total > 0 else 0.0
            agg.rms[c][g] = float(np.sqrt(np.mean(sg**2)))
            agg.max[c][g] = float(sg.max())
            agg.top[c][g] = names[int(np.flatnonzero(sel)[int(np.argmax(sg))])]
    return agg


def local_sensitivity(
    doc: UrdfDocument,
    datasets: Sequence[FrfData],
    options: CostOptions | None = None,
    *,
    free: Sequence[str] = ("all",),
    bands: Sequence[tuple[float, float]] | None = None,
) -> LocalSensitivity:
    """Local sensitivities of ``free`` parameters at the URDF values (one exact Jacobian).

    Args:
        doc: the model; datasets: measured FRFs; options: cost options (its ``bands`` limit
            the frequencies used, its ``channels`` the channels).
        free: parameters (names, globs, groups).
        bands: analysis bands in Hz (columns of the band map); None = automatic bands.

    Returns:
        :class:`LocalSensitivity`.
    """
    return analyse_local(linearise_cost(make_setup(doc, datasets, options, free)), bands)
