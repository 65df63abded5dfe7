"""Modes in the measured FRF, modes of the model, and how they pair up.

* :func:`identify_modes` — poles and residues of a measured 3×3 (any n_out × n_in) FRF:
  poly-reference LSCF band by band with a stabilisation diagram, nonlinear refinement, LSFD
  residues (see :mod:`bondid.modal.lscf` for the estimators).
* :func:`model_modes` — the same description of a :class:`~bondid.linear.LinearModel`'s
  vibration modes, from :func:`bondid.modes.analysis.modal_analysis`.
* :func:`pair_modes` — paired / missing / spurious, by frequency and MAC of the residues
  (in :mod:`bondid.modal.pairing`, re-exported here).
* :func:`antiresonances`, :func:`antiresonance_shifts` — drive-point anti-resonances.

Modes are :class:`~bondid.modal.record.IdentifiedMode` records (re-exported here).

A mode is described by its pole ``λ`` (``f_hz = |λ|/2π``, ``zeta = −Re λ/|λ|``) and its
residue matrix ``R`` (n_out, n_in) in ``H(s) ≈ Σ R/(s−λ) + R̄/(s−λ̄)`` (receptance units ×
1/s). Its ``prominence`` is ``max over channels |R/(s−λ) + R̄/(s−λ̄)| / |H|`` at
``s = j·Im λ``: about 1 for a mode that makes its own peak, ≪ 1 for one hidden under others.

Identification (:func:`identify_modes`): the FRF (receptance) is balanced (one scale per
output and per input, so that channels in m/N and rad/(N·m) weigh alike; this does not move
poles). The range is cut
into geometric core bands about ``band_ratio`` wide; each is fitted on itself widened by
``overlap`` with pLSCF for orders 1..``max_order`` (default 24), each output row weighted
by ``1/‖H_o(ω)‖`` (a relative error, so log-spaced data and a 140 dB dynamic range are
treated evenly) times its mean coherence. Poles are tracked from order to order; a track
that stays within ``tol_f`` / ``tol_zeta`` (relative) for at least max(4, max_order/3)
orders, is physical (0 < ζ < ``zeta_max``) and lies in the fitted band less an
``edge_margin`` is a mode (duplicates within 2·``tol_f`` keep the longest track). Where the
FRF has several complete output rows, each row is also identified alone, and a mode a row
finds that the whole matrix does not (farther than 2·``tol_f`` from all of its modes, and an
``edge_margin`` inside the data's ends) is added: when the channels' noise floors differ, the
joint fit can lose every mode that only some channels carry (e.g. direct channels in the
noise above a few hundred hertz while the cross channels carry the modes at 40–70 dB SNR:
the whole matrix then finds one mode where a single output row finds them all). With
``refine`` each band's poles are then polished by nonlinear least squares on the FRF
itself (variable projection over ``ln ω``, ``ln ζ``; error weighted by
``√(γ²/(1−γ²))/|H|``, γ² the coherence, i.e. by the inverse noise level). Residues come
from LSFD on each band (all poles near the band, lower residual terms ``1/s, 1/s², 1/s³``
for the rigid-body mass lines, upper ``1, s``), and modes whose prominence is below
``min_prominence`` (computational poles) are dropped. Output rows holding a missing
channel are left out of the pole estimation; where no output row is complete (e.g. only the
drive points were measured), each present channel is identified alone and their modes
merged, as the rows are (without it such files would give no modes at all, and the
diagnosis no measured modes to place its structural candidates at).
"""

from __future__ import annotations

import json
from collections.abc import Sequence

import numpy as np

from ..data.measurement import FrfData
from ..exceptions import DataError
from ..linear.linear_model import LinearModel
from . import lscf
from .antiresonance import antiresonance_shifts, antiresonances
from .pairing import VISIBLE_PROMINENCE, mac_matrix, pair_modes
from .record import INFORMED_COHERENCE, IdentifiedMode, mode_shape


def identify_modes(
    data: FrfData,
    *,
    f_range: tuple[float, float] | None = None,
    max_order: int | None = None,
    stability: bool = True,
    band_ratio: float = 4.0,
    overlap: float = 1.5,
    edge_margin: float = 1.15,
    zeta_max: float = 0.3,
    tol_f: float = 0.01,
    tol_zeta: float = 0.1,
    min_prominence: float = 0.05,
    use_coherence: bool = True,
    refine: bool = True,
) -> list[IdentifiedMode]:
    """Poles and residues of a measured FRF.

    Method: see the module docstring (identification).

    Args:
        data: measured FRF (any quantity; converted to receptance).
        f_range: ``(f_lo, f_hi)`` [Hz] to use (default all).
        max_order: highest pLSCF order per band (default 24).
        stability: False keeps every physical pole of the highest order (no diagram).
        band_ratio, overlap: band plan (see above).
        zeta_max, tol_f, tol_zeta: pole selection (see above).
        min_prominence: smallest prominence of a reported mode.
        use_coherence: weigh by the data's coherence where it has one.
        refine: polish the poles by nonlinear least squares (see above).

    Returns:
        The modes, lowest frequency first.

    Raises:
        DataError: too few frequencies, or no channel present at every frequency.
    """
    f, H, coh, rows = _prepared(data, f_range, use_coherence)
    n_max = 24 if max_order is None else int(max_order)
    plan = lscf.band_plan(f, band_ratio, overlap)

    def poles(sub: tuple[slice | np.ndarray, slice]) -> list[tuple[complex, int]]:
        out: list[tuple[complex, int]] = []
        for lo, hi in plan:
            out += _band_poles(
                f, H[sub], coh[sub], (lo, hi), n_max, overlap=overlap,
                edge_margin=edge_margin, stability=stability, zeta_max=zeta_max, tol_f=tol_f,
                tol_zeta=tol_zeta,
            )  # fmt: skip
        return out

    every = slice(None)
    if rows.size:
        merged = _merge_close(poles((rows, every)), tol_f)
        parts = [(rows[k : k + 1], every) for k in range(rows.size)] if rows.size > 1 else []
    else:  # no output has every input (e.g. the drive points alone): channel by channel
        merged = []
        present = np.argwhere(np.all(np.isfinite(H), axis=2))
        parts = [(np.array([o]), slice(i, i + 1)) for o, i in present]
    if parts:
        more = _merge_close([c for sub in parts for c in poles(sub)], tol_f)
        inner = (f[0] * edge_margin, f[-1] / edge_margin)
        more = [c for c in more if inner[0] <= abs(c[0]) / (2 * np.pi) <= inner[1]]
        merged = _with_new(merged, more, tol_f) if merged else more
    if not merged:
        return []
    lam = np.array([c[0] for c in merged])
    cw = np.sqrt(np.clip(coh, 1e-6, 0.999) / (1.0 - np.clip(coh, 1e-6, 0.999)))
    lam, R = _polished(f, H, lam, cw, plan, overlap=overlap, zeta_max=zeta_max, refine=refine)
    return _prominent(f, H, coh, lam, R, [c[1] for c in merged], min_prominence)


def _prepared(
    data: FrfData, f_range: tuple[float, float] | None, use_coherence: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(f, H, coh, rows)`` of the receptance in ``f_range``: frequencies ``(n_f,)`` [Hz],
    FRF and coherence ``(n_out, n_in, n_f)`` (coherence clipped to [1e-3, 1], 1 where unknown
    or unused, 1e-3 in a missing channel) and the indices of the output rows with every
    channel present (possibly none)."""
    d = data.to_quantity("receptance") if data.quantity != "receptance" else data
    f = d.freq_hz
    m = np.ones(f.size, bool) if f_range is None else (f >= f_range[0]) & (f <= f_range[1])
    f, H = f[m], d.H[:, :, m]
    where = d.source or "<in-memory FRF>"
    if f.size < 8:
        raise DataError(f"{where}: identify_modes needs at least 8 frequencies in range")
    coh = np.ones(H.shape)
    if use_coherence and d.coherence is not None:
        coh = np.where(np.isfinite(d.coherence[:, :, m]), d.coherence[:, :, m], 1.0)
        coh = np.clip(coh, 1e-3, 1.0)
    if not np.any(np.all(np.isfinite(H), axis=2)):
        raise DataError(f"{where}: identify_modes needs at least one channel without a gap")
    # a missing channel determines nothing (its residues are NaN, its weight the least)
    coh = np.where(np.isfinite(H), coh, 1e-3)
    rows = np.flatnonzero(np.all(np.isfinite(H), axis=(1, 2)))
    return f, H, coh, rows


def _band_poles(
    f: np.ndarray,
    H: np.ndarray,
    coh: np.ndarray,
    band: tuple[float, float],
    n_max: int,
    *,
    overlap: float,
    edge_margin: float,
    stability: bool,
    zeta_max: float,
    tol_f: float,
    tol_zeta: float,
) -> list[tuple[complex, int]]:
    """``[(λ, n_orders)]`` of one core ``band`` (Hz): pLSCF on the balanced, row-weighted FRF
    ``H`` (complete output rows only) over the band widened by ``overlap``, then the
    stabilisation diagram (or the highest order's physical poles without ``stability``)."""
    lo, hi = band
    sel = (f >= lo / overlap) & (f <= hi * overlap)
    if np.count_nonzero(sel) < 8:
        return []
    # keep poles inside the fitted band less a margin (none at the ends of the data)
    keep_lo = lo if lo <= f[0] else lo / overlap * edge_margin
    keep_hi = hi if hi >= f[-1] else hi * overlap / edge_margin
    Hb = H[:, :, sel]
    r, t = lscf.balance(np.median(np.abs(Hb), axis=2))
    Hs = r[:, None, None] * Hb * t[None, :, None]
    w = np.mean(coh[:, :, sel], axis=1) / np.linalg.norm(Hs, axis=1)
    poles = lscf.plscf(f[sel], Hs, w, n_max)
    if stability:
        return lscf.stable_clusters(
            poles, keep_lo, keep_hi, zeta_max=zeta_max, tol_f=tol_f, tol_zeta=tol_zeta,
            min_count=max(4, n_max // 3),
        )  # fmt: skip
    last = poles[-1].lam
    ok = lscf.physical(last, keep_lo, keep_hi, zeta_max)
    return [(complex(x), 1) for x in last[ok]]


def _with_new(
    base: list[tuple[complex, int]], more: list[tuple[complex, int]], tol_f: float
) -> list[tuple[complex, int]]:
    """``base`` and the poles of ``more`` farther than ``2·tol_f`` (relative) from every pole
    of ``base``, by frequency (a pole of ``base`` is never replaced)."""

    new = [c for c in more if not any(_close(c[0], b[0], tol_f) for b in base)]
    return sorted(base + new, key=lambda c: abs(c[0]))


def _close(pole: complex, other: complex, tol_f: float) -> bool:
    """Are the two poles' frequencies within ``2·tol_f`` of ``pole``'s (relative)?"""
    return abs(abs(pole) - abs(other)) < 2 * tol_f * abs(pole)


def _merge_close(cands: list[tuple[complex, int]], tol_f: float) -> list[tuple[complex, int]]:
    """``cands`` by frequency, poles within ``2·tol_f`` (relative) of the previous kept one
    merged into it (the one stable over more orders wins)."""
    merged: list[tuple[complex, int]] = []
    for pole, cnt in sorted(cands, key=lambda c: abs(c[0])):
        if merged and _close(pole, merged[-1][0], tol_f):
            if cnt > merged[-1][1]:
                merged[-1] = (pole, cnt)
            continue
        merged.append((pole, cnt))
    return merged


def _polished(
    f: np.ndarray,
    H: np.ndarray,
    lam: np.ndarray,
    cw: np.ndarray,
    plan: list[tuple[float, float]],
    *,
    overlap: float,
    zeta_max: float,
    refine: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """``(λ, R)``: the poles ``lam`` polished band by band (with ``refine``) and their residues
    ``(n_modes, n_out, n_in)`` by LSFD on each band (on the whole range for poles whose band
    is too short); ``cw`` ``(n_out, n_in, n_f)`` weighs by the inverse noise level."""
    lam = lam.copy()
    wn = np.abs(lam) / (2 * np.pi)
    R, _ = lscf.lsfd(f, H, lam, cw)  # fallback for poles whose band is too short
    for lo, hi in plan:
        sel = (f >= lo / overlap) & (f <= hi * overlap)
        inc = (wn >= lo / overlap**2) & (wn <= hi * overlap**2)
        core = (wn >= lo) & (wn < hi)
        if not np.any(core) or np.count_nonzero(sel) < 4 * (2 * np.count_nonzero(inc) + 6):
            continue
        if refine:
            lam[inc] = lscf.refine_poles(
                f[sel], H[:, :, sel], lam[inc], core[inc], cw[:, :, sel], zeta_max=zeta_max
            )
        Rb, _ = lscf.lsfd(f[sel], H[:, :, sel], lam[inc], cw[:, :, sel], upper=2)
        R[core] = Rb[core[inc]]
        wn = np.abs(lam) / (2 * np.pi)
    return lam, R


def _prominent(
    f: np.ndarray,
    H: np.ndarray,
    coh: np.ndarray,
    lam: np.ndarray,
    R: np.ndarray,
    counts: list[int],
    min_prominence: float,
) -> list[IdentifiedMode]:
    """The modes of poles ``lam`` with residues ``R`` whose prominence in ``H`` is at least
    ``min_prominence`` (``counts``: orders each pole was stable over)."""
    modes = []
    for k, (lr, cnt) in enumerate(zip(lam, counts, strict=True)):
        lr = complex(lr)
        prom = _prominence(f, H, lr, R[k], coh)
        if prom >= min_prominence:
            at = _nearest(f, lr)
            modes.append(
                IdentifiedMode(
                    f_hz=abs(lr) / (2 * np.pi), zeta=-lr.real / abs(lr), residues=R[k],
                    shape=mode_shape(R[k]), prominence=prom, n_orders=cnt,
                    determined=coh[:, :, at] >= INFORMED_COHERENCE,
                )
            )  # fmt: skip
    return modes


def _nearest(f: np.ndarray, lam: complex) -> int:
    """Index of the frequency of ``f`` [Hz] nearest the damped frequency ``Im λ / 2π``."""
    return int(np.argmin(np.abs(f - lam.imag / (2 * np.pi))))


def _prominence(
    f: np.ndarray, H: np.ndarray, lam: complex, R: np.ndarray, coh: np.ndarray | None = None
) -> float:
    """max over channels (coherence ≥ 0.5 where given) of |mode terms| / |H| at ω = Im λ."""
    fd = lam.imag / (2 * np.pi)
    if not f[0] <= fd <= f[-1]:
        return 0.0
    k = _nearest(f, lam)
    terms = np.abs(lscf.mode_terms(np.array([fd]), lam, R)[..., 0])
    ratio = terms / np.abs(H[:, :, k])
    if coh is not None:
        ratio = np.where(coh[:, :, k] >= INFORMED_COHERENCE, ratio, np.nan)
    ratio = ratio[np.isfinite(ratio)]
    return float(ratio.max()) if ratio.size else 0.0


def model_modes(
    linear_model: LinearModel,
    *,
    freq_hz: np.ndarray | None = None,
    channel_mask: np.ndarray | None = None,
    data: FrfData | None = None,
    min_coherence: float = 0.5,
) -> list[IdentifiedMode]:
    """The vibration modes of a linear model in the form of :class:`IdentifiedMode`.

    Residues ``R = C x ψᴴ B / (ψᴴ x)`` from :func:`bondid.modes.analysis.modal_analysis`
    (rigid-body and real modes are left out). ``prominence`` is computed against the model's
    own receptance, over the channels where ``channel_mask`` (n_out, n_in) is True and, when
    ``data`` is given, where that channel is present in the data with coherence ≥
    ``min_coherence`` at the mode's frequency (channels matched by name). It is 0 for a mode
    outside the range of ``freq_hz`` (or of ``data``).
    """
    from ..modes.analysis import modal_analysis

    res = modal_analysis(linear_model)
    outs, ins = list(linear_model.outputs), list(linear_model.inputs)
    if data is not None and freq_hz is None:
        freq_hz = data.freq_hz
    out = []
    for md in res.vibration_modes():
        lam = md.eigenvalue
        fd = lam.imag / (2 * np.pi)
        fgrid = np.array([fd])
        H = linear_model.frf(fgrid)
        mask = np.ones((len(outs), len(ins)))
        if channel_mask is not None:
            mask *= np.asarray(channel_mask, bool)
        if data is not None:
            k = int(np.argmin(np.abs(data.freq_hz - fd)))
            seen = np.zeros_like(mask)
            for a, o in enumerate(outs):
                for b, i in enumerate(ins):
                    if o in data.outputs and i in data.inputs:
                        oa, ib = data.outputs.index(o), data.inputs.index(i)
                        ok = bool(np.isfinite(data.H[oa, ib, k]))
                        if ok and data.coherence is not None:
                            c = data.coherence[oa, ib, k]
                            ok = not np.isfinite(c) or c >= min_coherence
                        seen[a, b] = float(ok)
            mask *= seen
        prom = _prominence(fgrid, H, lam, md.residue, mask[:, :, None])
        if freq_hz is not None and not float(np.min(freq_hz)) <= md.f_hz <= float(np.max(freq_hz)):
            prom = 0.0
        out.append(
            IdentifiedMode(
                f_hz=md.f_hz,
                zeta=float(md.zeta if md.zeta is not None else 0.0),
                residues=md.residue,
                shape=mode_shape(md.residue),
                prominence=prom,
            )
        )
    return out


def modes_to_json(modes: Sequence[IdentifiedMode]) -> str:
    """A list of modes as JSON text (frequency, damping, prominence, shape)."""
    return json.dumps([m.to_dict() for m in modes], indent=2) + "\n"


__all__ = [
    "INFORMED_COHERENCE",
    "VISIBLE_PROMINENCE",
    "IdentifiedMode",
    "antiresonance_shifts",
    "antiresonances",
    "identify_modes",
    "mac_matrix",
    "model_modes",
    "modes_to_json",
    "pair_modes",
]
