"""``--lines``: how many frequency lines of a file a fit uses, and the record of what it kept.

:class:`LinesSetting` is the option (``auto``, ``all`` or at most ``N`` lines per file);
:class:`FileReduction` and :class:`LineReduction` say what :mod:`.reduce` kept, for the
results files and the command's summary. The setting is read without the reduction itself,
so an option parser or a study file can check it cheaply.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..exceptions import ConfigError
from .features import (
    DIP_SNR_DB,
    MAX_HALF_REL,
    MIN_HALF_REL,
    PEAK_SNR_DB,
    PROMINENCE_DB,
    WIDTHS,
    Feature,
)

#: ``--lines auto`` reduces files with more lines than this ...
AUTO_ABOVE = 4000
#: ... to at most this many lines per file
AUTO_LINES = 3000
#: the smallest ``--lines N``
MIN_LINES = 100
#: at most this share of the budget on the lines near resonances and anti-resonances
FEATURE_SHARE = 0.6

#: how the rule is described in the results files
RULE = (
    f"kept every line within {WIDTHS:g} half-power half-widths (taken within"
    f" {MIN_HALF_REL:.1%}..{MAX_HALF_REL:.0%} of the frequency) of each resonance and"
    f" anti-resonance (peaks/dips of the smoothed |H| of every used channel, prominence >="
    f" {PROMINENCE_DB:g} dB, estimated SNR >= {PEAK_SNR_DB:g} dB at a peak, >= {DIP_SNR_DB:g} dB"
    f" at a dip; at most {FEATURE_SHARE:.0%} of the budget: beyond, the lines within one"
    " half-width first, the widest bands thinned first)"
    " and the lines nearest a log-spaced grid elsewhere; the weights come from the noise"
    " estimated on all lines"
)


@dataclass(frozen=True)
class LinesSetting:
    """``--lines``: ``"auto"``, ``"all"`` or at most ``n`` lines per file (``mode "max"``)."""

    mode: str = "auto"
    n: int | None = None

    def __str__(self) -> str:
        return str(self.n) if self.mode == "max" else self.mode

    def budget(self, n_lines: int) -> int | None:
        """The most lines a file of ``n_lines`` keeps (None: all of them)."""
        if self.mode == "all":
            return None
        if self.mode == "auto":
            return AUTO_LINES if n_lines > AUTO_ABOVE else None
        assert self.n is not None
        return self.n if n_lines > self.n else None


def parse_lines(value: str | int | None, where: str = "--lines") -> LinesSetting:
    """``auto``, ``all`` or an integer ``N ≥`` :data:`MIN_LINES` (None: ``auto``); else
    :class:`ConfigError` naming ``where``."""
    if value is None:
        return LinesSetting()
    text = str(value).strip().lower()
    if text in ("auto", "all"):
        return LinesSetting(text)
    try:
        n = int(text)
    except ValueError:
        n = -1
    if isinstance(value, bool) or n < MIN_LINES or str(n) != text.lstrip("+"):
        raise ConfigError(
            f"{where} {value!r}: valid: auto (reduce files above {AUTO_ABOVE} lines to"
            f" {AUTO_LINES}), all, or a line count per file >= {MIN_LINES}"
        )
    return LinesSetting("max", n)


@dataclass(frozen=True)
class FileReduction:
    """What the reduction kept of one file.

    Attributes:
        file: the file (None for data built in memory).
        n_lines: its lines.
        kept: ``(n_kept,)`` sorted indices of the kept lines (all of them when not reduced).
        features: the resonances and anti-resonances found (empty when not reduced).
        feature_lines: how many kept lines lie near a feature.
        reduced: whether lines were dropped.
    """

    file: str | None
    n_lines: int
    kept: np.ndarray
    features: tuple[Feature, ...] = ()
    feature_lines: int = 0
    reduced: bool = False

    @property
    def n_kept(self) -> int:
        return int(self.kept.size)

    def to_json_dict(self) -> dict[str, Any]:
        return {
            "file": self.file,
            "lines": self.n_lines,
            "kept": self.n_kept,
            "reduced": self.reduced,
            "resonances": sum(f.kind == "resonance" for f in self.features),
            "anti_resonances": sum(f.kind == "anti-resonance" for f in self.features),
            "feature_lines": self.feature_lines,
        }


@dataclass(frozen=True)
class LineReduction:
    """The reduction of every file of a command (:func:`reduce_datasets`).

    Attributes:
        setting: the ``--lines`` setting.
        files: one :class:`FileReduction` per file, in order.
    """

    setting: LinesSetting
    files: tuple[FileReduction, ...]

    @property
    def reduced(self) -> bool:
        return any(f.reduced for f in self.files)

    def kept_per_file(self) -> list[int]:
        return [f.n_kept for f in self.files]

    def to_json_dict(self) -> dict[str, Any]:
        """``{"setting", "reduced", "rule", "auto_above", "auto_lines", "lines", "kept",
        "files": [...]}`` for the results files (``lines``/``kept``: totals over files)."""
        return {
            "setting": str(self.setting),
            "reduced": self.reduced,
            "rule": RULE if self.reduced else "all lines",
            "auto_above": AUTO_ABOVE,
            "auto_lines": AUTO_LINES,
            "lines": sum(f.n_lines for f in self.files),
            "kept": sum(f.n_kept for f in self.files),
            "files": [f.to_json_dict() for f in self.files],
        }

    def summary_line(self, verb: str = "fitted", figures: bool = True) -> str:
        """One line for a command's summary (``verb``: what the command did on the lines;
        ``figures``: say that the figures are on all lines)."""
        kept = ", ".join(f"{f.n_kept}/{f.n_lines}" for f in self.files)
        if not self.reduced:
            return f"lines: all used ({kept}; --lines {self.setting})"
        n_res = sum(f.kind == "resonance" for r in self.files for f in r.features)
        n_anti = sum(f.kind == "anti-resonance" for r in self.files for f in r.features)
        tail = "; figures on all lines" if figures else ""
        return (
            f"lines: {verb} on {kept} per file (--lines {self.setting}: every line near"
            f" {n_res} resonance and {n_anti} anti-resonance finds, log-spaced elsewhere){tail}"
        )
