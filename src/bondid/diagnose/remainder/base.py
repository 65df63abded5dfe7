"""What every finding of the remainder holds: :class:`Finding` (and :class:`Significance`,
:class:`Location`), and the :class:`Candidate` a detector proposes before the search
(:mod:`.explain`) decides which are claimed."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...cost.residuals import DB
from ...jsonsafe import json_safe
from .residual import Points, Residual
from .stats import LogFit

#: every kind a finding may have
KINDS: tuple[str, ...] = (
    "missing_mode",
    "spurious_mode",
    "misplaced_mode",
    "damping_law",
    "confined",
    "stiffness_offset",
    "mass_offset",
    "delay",
    "lag",
    "leakage",
    "gain_offset",
    "gain_slope",
    "notch",
)


@dataclass(frozen=True)
class Location:
    """Where a finding lives.

    Attributes:
        side: ``"output"`` (a sensor row), ``"input"`` (an actuator column), ``"channel"``,
            ``"drive"`` (a collocated drive: its row and column) or ``"global"``.
        names: the output / input / channel / drive names (empty for ``"global"``).
        channels: the channels ``OUT.IN`` where the finding shows.
    """

    side: str
    names: tuple[str, ...] = ()
    channels: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        return {"side": self.side, "names": list(self.names), "channels": list(self.channels)}


@dataclass(frozen=True)
class Significance:
    """How a finding stands against the noise.

    Attributes:
        reduction_db2: the weighted mean square it removes, over every used point [dB²].
        share: its share of the excess over the noise (``reduction / excess``).
        statistic: ``ΔS/c`` (:mod:`.stats`), to compare with ``χ²_ν``.
        dof: ``ν``.
        p_value: the chance that noise alone removes as much.
        p_threshold: the largest p-value claimed (the false-alarm rate shared among every
            look the search takes, :mod:`.explain`).
        n_params: parameters fitted.
    """

    reduction_db2: float
    share: float
    statistic: float
    dof: float
    p_value: float
    p_threshold: float
    n_params: int

    @property
    def significant(self) -> bool:
        return self.p_value <= self.p_threshold

    def as_dict(self) -> dict[str, Any]:
        return json_safe(
            {
                "reduction_db2": self.reduction_db2,
                "share": self.share,
                "statistic": self.statistic,
                "dof": self.dof,
                "p_value": self.p_value,
                "p_threshold": self.p_threshold,
                "n_params": self.n_params,
                "significant": self.significant,
            }
        )


@dataclass
class Finding:
    """One thing the remainder shows.

    Attributes:
        kind: one of :data:`KINDS`.
        text: one sentence in the words of a mechatronics engineer, with its figures.
        share: the share of the excess over the noise it explains (for ``"confined"``: the
            share that lies there).
        location: where it lives.
        band_hz: ``(f_lo, f_hi)`` [Hz] where it acts, None for the whole range.
        advice: where to look, in a few words.
        significance: against the noise (None for a location finding, whose test is in its
            figures).
        alternatives: other descriptions the data cannot tell from this one (kind and
            location in words).
    """

    kind: str
    text: str
    share: float
    location: Location
    band_hz: tuple[float, float] | None = None
    advice: str = ""
    significance: Significance | None = None
    alternatives: list[str] = field(default_factory=list)

    def figures(self) -> dict[str, Any]:
        """The finding's own figures (each kind adds its own)."""
        return {}

    def as_dict(self) -> dict[str, Any]:
        """JSON-safe form (schema in :mod:`bondid.diagnose.remainder`)."""
        return json_safe(
            {
                "kind": self.kind,
                "text": self.text,
                "share": self.share,
                "location": self.location.as_dict(),
                "band_hz": None if self.band_hz is None else list(self.band_hz),
                "advice": self.advice,
                "significance": None if self.significance is None else self.significance.as_dict(),
                "figures": self.figures(),
                "alternatives": list(self.alternatives),
            }
        )


def mode_group(f_hz: float) -> str:
    """The :attr:`Candidate.group` of every description of a mode near ``f_hz`` (bins 5 %
    wide in frequency)."""
    return f"mode {round(math.log(f_hz) / 0.05)}" if f_hz > 0 else "mode"


#: builds the finding of a candidate once its share and significance are known
Describe = Callable[[Significance], Finding]


@dataclass
class Candidate:
    """A detector's proposal: a fitted correction at some points, and how to word it.

    Attributes:
        key: what it is and where, for telling alternatives apart (e.g. ``"delay on
            output z"``).
        pts: the points it changes.
        fit: the fit there.
        trials: how many independent looks the detector took to find it (a search over a
            frequency or a delay looks many times): it divides the false-alarm rate.
        describe: builds the :class:`Finding` from its :class:`Significance`.
        group: candidates of one group describe one thing in different forms (a mode added,
            or the model's own mode removed): none of them is named as an alternative of
            another ("" = a group of its own).
    """

    key: str
    pts: Points
    fit: LogFit
    trials: float
    describe: Describe
    group: str = ""

    @property
    def n_params(self) -> int:
        return int(self.fit.theta.size)

    def corrected(self, res: Residual) -> list[np.ndarray]:
        """Every data set's model with this correction applied."""
        return res.corrected(self.pts, self.fit.H)

    def significance(self, excess: float, weight: float, p_threshold: float) -> Significance:
        """Its :class:`Significance` against the total ``excess`` (natural units) of points
        of total weight ``weight``."""
        red = self.fit.reduction
        share = red / max(excess, red) if red > 0 else 0.0
        return Significance(
            reduction_db2=DB**2 * red / weight if weight > 0 else math.nan,
            share=float(share),
            statistic=self.fit.statistic,
            dof=self.fit.null_dof,
            p_value=self.fit.p_value,
            p_threshold=p_threshold,
            n_params=self.n_params,
        )
