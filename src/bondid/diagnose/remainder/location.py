"""Residual confined to one output row (the sensor side: mounting, calibration, alignment),
one input column (the actuator side: amplifier, current loop, force constant) or one channel
(:func:`confined`).

From the excess figures (:mod:`.excess`): a row (column, channel) is where the remainder is
confined when it carries at least ``confined_share`` of the excess over the noise and at
least ``confined_ratio`` times what an even spread would give it (its share of the weight),
and its own excess stands above the noise (``z > Z``). A channel takes precedence over its
row and column; a row and a column may both be named (a drive-point channel's row and
column).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from . import words
from .base import Finding, Location
from .context import Settings
from .excess import ExcessFigures, Part


@dataclass
class Confined(Finding):
    """``name``'s ``part`` figures (share of the excess, even share, dB figures, z)."""

    part: Part | None = None

    def figures(self) -> dict[str, Any]:
        p = self.part
        if p is None:
            return {}
        return {"name": p.name, "share": p.share, "even_share": p.even_share,
                "ratio_to_even": p.share / p.even_share if p.even_share > 0 else None,
                "db_rms": p.db_rms, "noise_db": p.noise_db, "z": p.z}  # fmt: skip


def _passes(p: Part, n: int, s: Settings) -> bool:
    return (
        n > 1
        and p.above_noise
        and p.share >= s.confined_share
        and p.share >= s.confined_ratio * p.even_share
    )


def confined(ex: ExcessFigures, s: Settings) -> list[Confined]:
    """The confinement findings of ``ex`` (module docstring); none when the whole is at the
    noise level."""
    if not ex.above_noise:
        return []
    for p in ex.by_channel:
        if _passes(p, len(ex.by_channel), s):
            return [_finding("channel", p)]
    out = []
    for side, parts in (("output", ex.by_output), ("input", ex.by_input)):
        for p in parts:
            if _passes(p, len(parts), s):
                out.append(_finding(side, p))
    return out


def _finding(side: str, p: Part) -> Confined:
    where = words.side_phrase(side, [p.name])
    text = (
        f"the remainder is confined to {where}: {words.pct(p.share)} of the excess over the "
        f"noise, where an even spread would give {words.pct(p.even_share)} ({p.db_rms:.2f} dB "
        f"against a noise level of {p.noise_db:.2f} dB there)"
    )
    return Confined("confined", text, p.share, Location(side, (p.name,)), None,
                    words.advice(side, [p.name]), None, part=p)  # fmt: skip
