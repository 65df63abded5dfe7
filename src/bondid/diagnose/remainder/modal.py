"""The modal side of the remainder, on the diagnosis' own tools: modes identified in the data
and in the model's FRF (:func:`~bondid.modal.identify.identify_modes`), their pairing
(:func:`~bondid.modal.pairing.pair_modes`) and the MAC of a fitted mode to the model's
(:func:`~bondid.modal.pairing.mac_matrix`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...data.measurement import FrfData
from ...modal.pairing import mac_matrix, pair_modes

#: a model mode within this relative frequency and at least this MAC is "the same mode"
#: (the pairing's defaults, :func:`bondid.modal.pairing.pair_modes`)
PAIR_F_TOL = 0.2
PAIR_MAC = 0.5


def identify_each(
    data: list[FrfData], model_H: list[np.ndarray] | None, notes: list[str]
) -> list[list[Any]]:
    """The modes of each data set (``model_H`` None) or of the model FRF of each data set
    (noise-free: no weights); none where identification fails (a note says so)."""
    from ...modal.identify import identify_modes

    out: list[list[Any]] = []
    for k, d in enumerate(data):
        if model_H is not None:
            d = FrfData(d.freq_hz, d.outputs, d.inputs, np.asarray(model_H[k], complex),
                        d.quantity)  # fmt: skip
        try:
            out.append(list(identify_modes(d)))
        except Exception as exc:  # a set whose identification fails adds no mode
            what = "model" if model_H is not None else "measured"
            notes.append(f"modal identification of the {what} data set {k + 1} failed: {exc}")
            out.append([])
    return out


def missing_seeds(
    measured: Sequence[Sequence[Any]], model: Sequence[Sequence[Any]], data: Sequence[FrfData]
) -> list[tuple[float, float]]:
    """``(f_hz, zeta)`` of the measured modes the pairing calls missing in the model, over
    every data set, merged within 3 %."""
    found: list[tuple[float, float]] = []
    for meas, mod, d in zip(measured, model, data, strict=True):
        rows = pair_modes(list(meas), list(mod), f_band=(float(d.freq_hz[0]),
                                                         float(d.freq_hz[-1])))  # fmt: skip
        for r in rows:
            if r.get("status") == "missing" and r.get("f_measured_hz"):
                found.append((float(r["f_measured_hz"]), float(r["zeta_measured"] or 0.02)))
    return merged(found)


def merged(items: list[tuple[float, float]], tol: float = 0.03) -> list[tuple[float, float]]:
    """``(f, ζ)`` sorted by frequency, those within ``tol`` of the previous kept one dropped."""
    out: list[tuple[float, float]] = []
    for f, z in sorted(items):
        if not out or f > out[-1][0] * (1.0 + tol):
            out.append((f, z))
    return out


@dataclass(frozen=True)
class Nearest:
    """The model mode nearest a fitted one: ``f_hz`` (None: the model has none), its
    relative distance ``df_rel`` and ``mac``; ``best_mac`` the largest MAC of any model mode
    within :data:`PAIR_F_TOL`, ``paired`` whether one of them pairs (MAC ≥ :data:`PAIR_MAC`)."""

    f_hz: float | None
    df_rel: float | None
    mac: float | None
    best_mac: float
    paired: bool

    def as_dict(self) -> dict[str, Any]:
        return {"f_model_hz": self.f_hz, "df_rel": self.df_rel, "mac": self.mac,
                "best_mac_within_20pct": self.best_mac, "paired": self.paired}  # fmt: skip


def nearest(f_hz: float, zeta: float, residues: np.ndarray, model: Sequence[Any]) -> Nearest:
    """:class:`Nearest` of a mode at ``f_hz`` with ``residues`` ``(n_out, n_in)`` among the
    model's modes ``model`` (:class:`~bondid.modal.identify.IdentifiedMode`, same
    channels)."""
    from ...modal.identify import IdentifiedMode

    if not model:
        return Nearest(None, None, None, 0.0, False)
    me = IdentifiedMode(f_hz=f_hz, zeta=zeta, residues=np.asarray(residues, complex))
    try:
        mac = mac_matrix([me], list(model))[0]
    except ValueError:  # residue shapes differ: frequency alone
        mac = np.zeros(len(model))
    f = np.array([m.f_hz for m in model])
    df = (f - f_hz) / f_hz
    j = int(np.argmin(np.abs(df)))
    near = np.abs(df) <= PAIR_F_TOL
    best = float(np.max(mac[near])) if np.any(near) else 0.0
    return Nearest(float(f[j]), float(df[j]), float(mac[j]), best, bool(best >= PAIR_MAC))


def pole(f_hz: float, zeta: float) -> complex:
    """λ [1/s] of a mode of natural frequency ``f_hz`` and damping ``zeta`` (Im λ > 0)."""
    w = 2 * math.pi * f_hz
    z = min(max(zeta, 0.0), 0.999999)
    return complex(-z * w, w * math.sqrt(1.0 - z * z))
