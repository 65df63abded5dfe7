"""What the detectors share: the choices (:class:`Settings`) and the modes of the data and the
model (:class:`Context`), computed once when a detector first asks."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...data.measurement import FrfData
from ..scoring import MIN_EXCESS_SHARE, Z
from .residual import Residual


def _alpha() -> float:
    """The verdict rule's false-alarm rate of a one-parameter test
    (:func:`bondid.diagnose.scoring.lr_threshold`): ``P(χ²₁ > 2 Z²)``."""
    from scipy.special import chdtrc

    return float(chdtrc(1, 2.0 * Z**2))


@dataclass
class Settings:
    """Choices of :func:`~bondid.diagnose.remainder.describe_remainder`.

    Attributes:
        min_share: smallest share of the excess over the noise a finding must explain to be
            claimed.
        alpha: false-alarm rate of the whole search on pure noise (shared among every look it
            takes, Bonferroni); the verdict rule's one-parameter rate by default.
        max_findings: most causes described one after the other.
        confined_share: smallest share of the excess a row / column / channel must carry to
            be called the place the remainder is confined to (and at least
            ``confined_ratio`` times its even share).
        confined_ratio: see ``confined_share``.
        modes: look for missing, spurious and misplaced modes (needs a modal identification
            of the data and the model, a few seconds).
        bands_per_decade: fixed analysis bands of the excess figures.
        rotary: the drives (collocated output and input names) that are rotary, for the
            units of a drive's stiffness, damping and mass (N·m/rad, N·m·s/rad, kg·m²).
    """

    min_share: float = 0.10
    alpha: float = field(default_factory=_alpha)
    max_findings: int = 5
    confined_share: float = 0.6
    confined_ratio: float = 1.5
    modes: bool = True
    bands_per_decade: int = 6
    rotary: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        return {
            "min_share": self.min_share,
            "alpha": self.alpha,
            "max_findings": self.max_findings,
            "confined_share": self.confined_share,
            "confined_ratio": self.confined_ratio,
            "modes": self.modes,
            "bands_per_decade": self.bands_per_decade,
            "rotary": list(self.rotary),
            "verdict_min_excess_share": MIN_EXCESS_SHARE,
        }


@dataclass
class Context:
    """The data, the settings and the modes (per data set) the detectors share.

    ``measured_modes`` / ``model_modes``: lists per data set of
    :class:`~bondid.modal.identify.IdentifiedMode` (None: identified on first use, the
    model's from its own FRF).
    """

    data: Sequence[FrfData]
    model_H: Sequence[np.ndarray]
    settings: Settings
    measured_modes: list[list[Any]] | None = None
    model_modes: list[list[Any]] | None = None
    notes: list[str] = field(default_factory=list)

    def measured(self) -> list[list[Any]]:
        """The modes identified in each data set (none where identification fails)."""
        if self.measured_modes is None:
            from .modal import identify_each

            self.measured_modes = identify_each(list(self.data), None, self.notes)
        return self.measured_modes

    def model(self) -> list[list[Any]]:
        """The model's modes per data set (identified from its FRF when not given)."""
        if self.model_modes is None:
            from .modal import identify_each

            self.model_modes = identify_each(list(self.data), list(self.model_H), self.notes)
        return self.model_modes

    def log_spacing(self, res: Residual) -> float:
        """The median step of ``ln f`` of the data sets' grids."""
        steps = [np.diff(np.log(s.freq_hz)) for s in res.sets if s.freq_hz.size > 1]
        return float(np.median(np.concatenate(steps))) if steps else 0.01

    def resonance_looks(self, res: Residual, zeta: float) -> float:
        """How many resonances of damping ``zeta`` the frequency range holds side by side
        (each a look of a search over frequency): its width in ``ln f`` over the larger of
        the half-power bandwidth ``2ζ`` and the grid's step."""
        f_lo, f_hi = self.freq_range(res)
        return max(1.0, math.log(f_hi / f_lo) / max(2.0 * zeta, self.log_spacing(res)))

    def freq_range(self, res: Residual) -> tuple[float, float]:
        """The lowest and highest used frequency [Hz]."""
        fs = [s.freq_hz[np.any(s.used, axis=(0, 1))] for s in res.sets]
        f = np.concatenate([x for x in fs if x.size])
        return float(f.min()), float(f.max())
