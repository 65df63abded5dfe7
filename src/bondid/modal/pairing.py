"""How measured and model modes pair up: :func:`pair_modes` (paired / missing / spurious, by
frequency and MAC of the residues, :func:`mac_matrix`).

Modes are :class:`~bondid.modal.record.IdentifiedMode` records (measured ones from
:func:`~bondid.modal.identify.identify_modes`, the model's from
:func:`~bondid.modal.identify.model_modes`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from . import lscf
from .record import IdentifiedMode

VISIBLE_PROMINENCE = 0.1
"""A model mode counts as visible (so unpaired = spurious) at this prominence or above."""


def mac_matrix(a: Sequence[IdentifiedMode], b: Sequence[IdentifiedMode]) -> np.ndarray:
    """MAC ``(len(a), len(b))`` of the vectorised, balanced residue matrices.

    Each output row and input column of every residue matrix is divided by one common scale
    (from all modes of both lists, so m/N and rad/(N·m) channels weigh alike);
    MAC = |aᴴb|² / (|a|²|b|²) over the entries both modes determine (``determined``, None =
    all: a measured mode's residue in a channel whose data are noise at its frequency is
    noise, and would lower the MAC of a right pair). Non-finite entries count as 0.
    """
    allR = [np.nan_to_num(m.residues) for m in [*a, *b]]
    if not allR:
        return np.zeros((len(a), len(b)))
    c = np.sqrt(np.mean(np.abs(np.stack(allR)) ** 2, axis=0))
    r, t = lscf.balance(c)
    va = [(r[:, None] * np.nan_to_num(m.residues) * t[None, :]).ravel() for m in a]
    vb = [(r[:, None] * np.nan_to_num(m.residues) * t[None, :]).ravel() for m in b]
    ma = [_mask(m, allR[0].size) for m in a]
    mb = [_mask(m, allR[0].size) for m in b]
    out = np.zeros((len(a), len(b)))
    for i, x0 in enumerate(va):
        for j, y0 in enumerate(vb):
            both = ma[i] & mb[j]
            x, y = x0 * both, y0 * both
            den = np.vdot(x, x).real * np.vdot(y, y).real
            out[i, j] = abs(np.vdot(x, y)) ** 2 / den if den > 0 else 0.0
    return out


def _mask(m: IdentifiedMode, n: int) -> np.ndarray:
    """The entries (raveled, ``(n,)``) of ``m``'s residues the data determine."""
    return np.ones(n, bool) if m.determined is None else np.asarray(m.determined, bool).ravel()


def pair_modes(
    measured: Sequence[IdentifiedMode],
    model: Sequence[IdentifiedMode],
    *,
    f_tol: float = 0.2,
    mac_min: float = 0.5,
    f_band: tuple[float, float] | None = None,
    min_prominence: float = VISIBLE_PROMINENCE,
    include_unobserved: bool = False,
) -> list[dict[str, Any]]:
    """Pair measured and model modes by frequency and residue MAC.

    A pair needs ``|f_model − f_measured| ≤ f_tol · f_measured`` and MAC ≥ ``mac_min``; among
    the admissible pairs one-to-one assignment minimises Σ (1 − MAC) + |df_rel| / f_tol.
    An unpaired measured mode is ``"missing"`` (in the data, not the model). An unpaired
    model mode is ``"spurious"`` only if the data would have revealed it: its frequency lies in
    ``f_band`` (the measured range, when given) and its prominence (see
    :func:`model_modes`) is at least ``min_prominence``; other unpaired model modes are
    left out, or listed as ``"unobserved"`` with ``include_unobserved``.

    Returns:
        ``[{f_measured_hz, f_model_hz, status, mac, df_rel, zeta_measured, zeta_model}]``
        by frequency; ``df_rel = (f_model − f_measured) / f_measured``; absent values None.
    """
    from scipy.optimize import linear_sum_assignment

    mac = mac_matrix(measured, model)
    big = 1e6
    cost = np.full(mac.shape, big)
    for i, a in enumerate(measured):
        for j, b in enumerate(model):
            df = (b.f_hz - a.f_hz) / a.f_hz
            if abs(df) <= f_tol and mac[i, j] >= mac_min:
                cost[i, j] = (1.0 - mac[i, j]) + abs(df) / f_tol
    pairs: dict[int, int] = {}
    if cost.size:
        for i, j in zip(*linear_sum_assignment(cost), strict=True):
            if cost[i, j] < big:
                pairs[int(i)] = int(j)
    used = set(pairs.values())
    rows: list[dict[str, Any]] = []
    for i, a in enumerate(measured):
        if i in pairs:
            b = model[pairs[i]]
            rows.append(_row(a, b, "paired", float(mac[i, pairs[i]])))
        else:
            rows.append(_row(a, None, "missing", None))
    for j, b in enumerate(model):
        if j in used:
            continue
        inside = f_band is None or f_band[0] <= b.f_hz <= f_band[1]
        visible = inside and np.isfinite(b.prominence) and b.prominence >= min_prominence
        if visible or (inside and not np.isfinite(b.prominence)):
            rows.append(_row(None, b, "spurious", None))
        elif include_unobserved:
            rows.append(_row(None, b, "unobserved", None))
    rows.sort(key=lambda r: r["f_measured_hz"] or r["f_model_hz"])
    return rows


def _row(
    a: IdentifiedMode | None, b: IdentifiedMode | None, status: str, mac: float | None
) -> dict[str, Any]:
    return {
        "f_measured_hz": None if a is None else float(a.f_hz),
        "f_model_hz": None if b is None else float(b.f_hz),
        "status": status,
        "mac": mac,
        "df_rel": None if a is None or b is None else float((b.f_hz - a.f_hz) / a.f_hz),
        "zeta_measured": None if a is None else float(a.zeta),
        "zeta_model": None if b is None else float(b.zeta),
    }


__all__ = ["VISIBLE_PROMINENCE", "mac_matrix", "pair_modes"]
