"""Measurement regimes: how a truth machine's exact FRFs become the files the diagnosis reads.

- ``coh``: 2 % relative noise + a floor −70 dB below each sensor's response level (the
  package's simulator noise, ``floor_ref="response"``); coherence column written; receptance.
- ``nocoh``: the same noise; no coherence column; receptance.
- ``harsh``: 2 % relative + a flat floor 40 dB below each channel's median magnitude; no
  coherence; receptance.
- ``acc``: 2 % relative + a flat acceleration floor 40 dB below each channel's median
  accelerance (in receptance: a floor ∝ 1/ω², so the low frequencies are the noisy ones); no
  coherence; quantity ``accelerance``. (A floor per sensor, 50 dB below its strongest
  channel, was tried: weak cross-terms were then pure noise and even the truth model's gap
  was 109 dB, so no score could be read from it.)
- ``mob`` (stop 35, with the fourth design): a laser vibrometer's velocity, quantity
  ``mobility``: 2 % relative + a flat velocity floor 40 dB below each channel's median
  mobility (in receptance: a floor ∝ 1/ω); no coherence.

The harsh and accelerance generators are written here (not in ``bondid.data.noise``): the
benchmark's noise must not move when the package's noise options change.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bondid.data.io import write_frf
from bondid.data.measurement import FrfData
from bondid.model import UrdfDocument

REGIMES = ("coh", "nocoh", "harsh", "acc", "mob")
REL = 0.02
COH_FLOOR_DB = -70.0
HARSH_FLOOR_DB = -40.0
ACC_FLOOR_DB = -40.0
MOB_FLOOR_DB = -40.0
#: the regimes with a flat floor below each channel's median (in the files' quantity) [dB]
FLAT_FLOOR_DB = {"harsh": HARSH_FLOOR_DB, "acc": ACC_FLOOR_DB, "mob": MOB_FLOOR_DB}
#: the quantity of each regime's files (receptance unless named)
QUANTITY = {"acc": "accelerance", "mob": "mobility"}


def _cn(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Circular complex Gaussian samples, E|e|² = 1."""
    z = rng.standard_normal((2, *shape))
    return (z[0] + 1j * z[1]) / math.sqrt(2.0)


def flat_floor_noise(
    H: np.ndarray, rng: np.random.Generator, *, rel: float, sigma: np.ndarray
) -> np.ndarray:
    """``H (1 + rel·e1) + sigma·e2``; ``sigma`` broadcasts against ``H`` (a flat floor)."""
    return H * (1.0 + rel * _cn(rng, H.shape)) + sigma * _cn(rng, H.shape)


def channel_median_sigma(H: np.ndarray, floor_db: float) -> np.ndarray:
    """``(n_out, n_in, 1)``: ``floor_db`` dB below each channel's median magnitude."""
    return np.median(np.abs(H), axis=2, keepdims=True) * 10.0 ** (floor_db / 20.0)


def quantity_of(regime: str) -> str:
    return QUANTITY.get(regime, "receptance")


def noisy(
    regime: str, H: np.ndarray, f: np.ndarray, seed: int
) -> tuple[np.ndarray, np.ndarray | None]:
    """``(H_measured, coherence or None)`` of exact ``H`` (already in the regime's quantity)."""
    rng = np.random.default_rng(seed)
    if regime in ("coh", "nocoh"):
        from bondid.data.noise import add_measurement_noise

        Hn, coh = add_measurement_noise(
            H, f, rel=REL, floor_db=COH_FLOOR_DB, rng=rng, floor_ref="response"
        )
        return Hn, (coh if regime == "coh" else None)
    if regime in FLAT_FLOOR_DB:
        sigma = channel_median_sigma(H, FLAT_FLOOR_DB[regime])
        return flat_floor_noise(H, rng, rel=REL, sigma=sigma), None
    raise ValueError(f"unknown regime {regime!r}; valid: {', '.join(REGIMES)}")


def measure(
    truth: UrdfDocument,
    operating_points: Sequence[dict[str, float]],
    f: np.ndarray,
    regime: str,
    factor,
    folder: Path,
    seed: int,
    effects: Sequence | None = None,
) -> tuple[list[Path], list[np.ndarray]]:
    """Simulate, apply the signal effects (``factor(f, outputs, inputs)``), add the regime's
    noise and write one CSV per operating point. Returns the paths and the exact FRFs (in the
    files' quantity). With the case's ``effects`` the exact FRFs are the truth as observed
    (:func:`.truth.observe_data`: read heads' deflections in their outputs, mixings and
    signal factors; ``factor`` unused)."""
    from bondid.simulate import simulate

    from .truth import observe_data

    paths, exact = [], []
    for k, op in enumerate(operating_points):
        if effects is None:
            d = simulate(truth, op, f, noise=0.0, quantity=quantity_of(regime))
            H = d.H * factor(f, d.outputs, d.inputs)
        else:
            d = observe_data(truth, effects, op, f, quantity_of(regime))
            H = d.H
        Hn, coh = noisy(regime, H, f, seed * 10 + k)
        p = folder / f"op{k}.csv"
        data = FrfData(f, d.outputs, d.inputs, Hn, d.quantity, dict(d.operating_point), coh, str(p))
        write_frf(data, p)
        paths.append(p)
        exact.append(H)
    return paths, exact
