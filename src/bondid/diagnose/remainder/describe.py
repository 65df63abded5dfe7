"""The entry point: :func:`describe_remainder` → :class:`Remainder`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...data.measurement import FrfData
from ...jsonsafe import json_safe
from . import words
from .base import Finding
from .context import Context, Settings
from .damping_law import KIND as DAMPING_LAW
from .damping_law import Pair, damping_law, pairs_of
from .excess import ExcessFigures, excess_figures, positive_excess
from .explain import explain
from .location import confined
from .residual import build_residual

#: more bands than this carrying most of the excess are said as "across the range"
MAX_BANDS_SAID = 3
#: below this share of the excess described, the summary says the rest has no simple form
DESCRIBED_ENOUGH = 0.5


@dataclass
class Remainder:
    """What the remainder of a model against measured data looks like.

    Attributes:
        findings: the causes the search claimed (:mod:`.explain`), largest share of the
            excess explained first, then where the excess is confined (:mod:`.location`).
        excess: the excess figures of the residual (:mod:`.excess`).
        after: the same with every claimed cause's correction applied to the model.
        explained_share: the share of the excess over the noise the causes remove together.
        notes: what could not be done (e.g. a modal identification that failed).
        settings: the choices used.
    """

    findings: list[Finding]
    excess: ExcessFigures
    after: ExcessFigures
    explained_share: float
    notes: list[str] = field(default_factory=list)
    settings: Settings = field(default_factory=Settings)

    @property
    def causes(self) -> list[Finding]:
        """The findings that describe a cause (every kind but ``"confined"``)."""
        return [f for f in self.findings if f.kind != "confined"]

    def primary(self) -> dict[str, Any]:
        """Where the remainder points, in one place: the largest cause's kind, side
        (``output``/``input``/``channel``/``drive``/``global``), names and band [Hz] (its own,
        else the bands carrying most of the excess); without a cause, where the excess is
        confined (kind ``"confined"``), else ``kind`` None with the channels and bands that
        carry most of it."""
        bands = [[b.f_lo_hz, b.f_hi_hz] for b in self.excess.where_bands]
        own = [f for f in self.findings if f.kind != DAMPING_LAW]  # a summary, not a place
        for f in [*(f for f in own if f.kind != "confined"), *own]:
            band = [list(f.band_hz)] if f.band_hz is not None else bands
            return {"kind": f.kind, "side": f.location.side, "names": list(f.location.names),
                    "bands_hz": band}  # fmt: skip
        return {"kind": None, "side": "channel", "names": list(self.excess.where_channels),
                "bands_hz": bands}  # fmt: skip

    def as_dict(self) -> dict[str, Any]:
        """JSON-safe form (schema in :mod:`bondid.diagnose.remainder`)."""
        return json_safe(
            {
                "primary": self.primary(),
                "excess": self.excess.as_dict(),
                "after": {
                    "db_rms": self.after.db_rms,
                    "noise_db": self.after.noise_db,
                    "above_noise": self.after.above_noise,
                },
                "explained_share": self.explained_share,
                "findings": [f.as_dict() for f in self.findings],
                "summary": self.sentences(),
                "notes": list(self.notes),
                "settings": self.settings.as_dict(),
            }
        )

    def sentences(self, n: int = 4) -> list[str]:
        """A few lines for a printed summary: the excess and where it lies, then the ``n``
        largest findings, then how much is left undescribed and what the remainder would be
        with the causes corrected."""
        ex = self.excess
        head = (
            f"remainder {ex.db_rms:.2f} dB against a noise level of {ex.noise_db:.2f} dB "
            f"({ex.ratio:.1f}×)"
        )
        if not ex.above_noise and not self.causes:
            return [f"{head}: at the noise level, nothing left to describe"]
        where = []
        if len(ex.where_bands) > MAX_BANDS_SAID:
            where.append("bands across the range")
        elif ex.where_bands:
            where.append(", ".join(words.band(b.f_lo_hz or 0.0, b.f_hi_hz or 0.0)
                                   for b in ex.where_bands))  # fmt: skip
        if ex.where_channels and len(ex.where_channels) < len(ex.by_channel):
            where.append("channels " + ", ".join(ex.where_channels))
        lines = [head + (f"; most of the excess in {' and '.join(where)}" if where else "")]
        for f in self.findings[:n]:
            share = f" ({words.pct(f.share)} of the excess)" if f.kind != "confined" else ""
            alt = f" [or: {'; '.join(f.alternatives)}]" if f.alternatives else ""
            lines.append(f"{f.text}{share}{alt}")
        if ex.above_noise:
            if not self.causes:
                lines.append(
                    "none of the simple forms (a mode, a row or column filter, delay, gain, "
                    "leakage, a drive's stiffness or mass) describes the excess: an effect of "
                    "another form, or more noise where it lies than the noise reference says"
                )
            elif self.explained_share < DESCRIBED_ENOUGH:
                lines.append(
                    f"these describe {words.pct(self.explained_share)} of the excess; the "
                    "rest has no simple form"
                )
        if self.causes:
            af = self.after
            state = "at the noise level" if not af.above_noise else "still above the noise"
            lines.append(
                f"with them corrected the remainder would be {af.db_rms:.2f} dB against "
                f"{af.noise_db:.2f} dB ({state})"
            )
        return lines


def describe_remainder(
    data: FrfData | Sequence[FrfData],
    model_H: np.ndarray | Sequence[np.ndarray],
    channels: Sequence[str] | None = None,
    *,
    noise_to_signal: Sequence[np.ndarray] | None = None,
    weights: Sequence[np.ndarray] | None = None,
    measured_modes: Sequence[Sequence[Any]] | None = None,
    model_modes: Sequence[Sequence[Any]] | None = None,
    settings: Settings | None = None,
) -> Remainder:
    """Describe the remainder of the best model against the measured data.

    Args:
        data: the measured data set(s) (any quantity; ``coherence``, where given, holds the
            information weights ``w = S/(S + N)``, as in the diagnosis).
        model_H: the best model's FRF for each data set, ``(n_out, n_in, n_freq)`` complex,
            in the data set's quantity, aligned with its outputs, inputs and frequencies.
        channels: the ``OUT.IN`` channels to use (default every channel present).
        noise_to_signal: per data set, each point's ``N/S`` ``(n_out, n_in, n_freq)`` (e.g.
            :func:`bondid.cost.noise_level.point_noise_to_signal` on the prediction basis);
            default from the weights (``1/w − 1``) or the data's noise estimate
            (:func:`.residual.build_residual`).
        weights: per data set, the information weights (default the coherence).
        measured_modes: per data set, the modes identified in it
            (:func:`bondid.modal.identify.identify_modes`); identified here when None.
        model_modes: per data set, the model's modes as
            :class:`~bondid.modal.identify.IdentifiedMode` on the data set's channels
            (e.g. :func:`~bondid.modal.identify.model_modes`); identified from ``model_H``
            when None.
        settings: :class:`Settings`.

    Returns:
        :class:`Remainder`.

    Raises:
        DataError: shapes differ, or no point is usable.
    """
    sets = [data] if isinstance(data, FrfData) else list(data)
    arrays = [model_H] if isinstance(model_H, np.ndarray) and model_H.ndim == 3 else model_H
    models = [np.asarray(m, complex) for m in arrays]
    s = settings or Settings()
    res = build_residual(sets, models, channels, noise_to_signal=noise_to_signal,
                         weights=weights)  # fmt: skip
    ctx = Context(
        sets, models, s,
        None if measured_modes is None else [list(m) for m in measured_modes],
        None if model_modes is None else [list(m) for m in model_modes],
    )  # fmt: skip
    ex = excess_figures(res, s.bands_per_decade)
    total = positive_excess(res, s.bands_per_decade)
    causes, final = explain(res, ctx, total)
    after = excess_figures(final, s.bands_per_decade)
    left = positive_excess(final, s.bands_per_decade)
    explained = (1.0 - left / total) if total > 0 else 0.0
    explained = float(min(max(explained, 0.0), 1.0)) if math.isfinite(explained) else 0.0
    causes.sort(key=lambda f: -f.share)
    law = damping_law(causes, _mode_pairs(ctx)) if s.modes and causes else None
    if law is not None:  # the modes' damping read as one law, ahead of the modes it sums up
        causes.insert(0, law)
    findings: list[Finding] = [*causes, *sorted(confined(ex, s), key=lambda f: -f.share)]
    return Remainder(findings, ex, after, explained, ctx.notes, s)


def _mode_pairs(ctx: Context) -> list[Pair]:
    """The data's modes paired with the model's over every data set (:func:`.damping_law.
    pairs_of`); none where the modal identification failed (its note is in ``ctx``)."""
    from ...modal.pairing import pair_modes

    rows = [
        pair_modes(measured, model)
        for measured, model in zip(ctx.measured(), ctx.model(), strict=True)
    ]
    return pairs_of(rows)
