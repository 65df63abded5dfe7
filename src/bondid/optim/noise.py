"""What "at the noise level" means, once for the whole package: :class:`NoisePolicy`.

Every fit of bondid can tell how far it is from the best any model could do without knowing
the truth: the cost an exact model would score on the same data follows from the data's own
noise estimate (:func:`bondid.cost.noise_level.noise_level_cost`). The ratio
``sqrt(cost / noise_cost)`` is the fit's weighted ``db_rms`` over the noise level's. A fit
whose ratio is at most :data:`AT_LEVEL` is *at the noise level*: nothing a model could add
would be told apart from the noise by its cost. One ratio serves every decision that asks
this question (when a fit stops looking for a better basin, the fit's headline, when a
diagnosis candidate's refit stops, whether a diagnosis has anything left to explain).

The 10 % margin is the accuracy of the prediction itself: on synthetic data with known noise
the exact model scores 0.89–1.14× the predicted level, so a fit within 10 % of it is not
distinguishable from the exact model by this test.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: a fit whose weighted db_rms is at most this multiple of the predicted noise level is at
#: the noise level (module docstring)
AT_LEVEL = 1.10


@dataclass(frozen=True)
class NoisePolicy:
    """The noise level of one set of data and the test "at the noise level".

    Attributes:
        cost: the cost an exact model would score on the data (the same units as the fit's
            data cost: mean square of the weighted residual, dB² for the log costs); None
            when the cost's noise level is not modelled (then nothing is ever "at the level").
        ratio: the :data:`AT_LEVEL` of this policy.
    """

    cost: float | None
    ratio: float = AT_LEVEL

    @property
    def known(self) -> bool:
        """Is there a positive, finite noise-level cost?"""
        return self.cost is not None and math.isfinite(self.cost) and self.cost > 0

    def ratio_of(self, cost: float) -> float | None:
        """``sqrt(cost / noise cost)``: the db_rms over the noise level's (None when the
        level is unknown or ``cost`` is not finite)."""
        if not self.known or not math.isfinite(cost):
            return None
        assert self.cost is not None
        return math.sqrt(max(cost, 0.0) / self.cost)

    def at_level(self, cost: float) -> bool:
        """Is a fit of data cost ``cost`` at the noise level (False when unknown)?"""
        r = self.ratio_of(cost)
        return r is not None and r <= self.ratio

    def describe(self, cost: float) -> str:
        """``"1.23× the noise level"`` (or ``"noise level unknown"``)."""
        r = self.ratio_of(cost)
        return "noise level unknown" if r is None else f"{r:.2f}× the noise level"


def level_ratio_db(db_rms: float, level_db: float | None) -> float | None:
    """``db_rms / level_db`` (None when either is missing or the level is not positive): the
    same ratio as :meth:`NoisePolicy.ratio_of` on figures already in dB."""
    if level_db is None or not level_db > 0 or not math.isfinite(db_rms):
        return None
    return db_rms / level_db


def at_level_db(db_rms: float, level_db: float | None) -> bool:
    """Is a weighted ``db_rms`` [dB] at the noise level ``level_db`` [dB]?"""
    r = level_ratio_db(db_rms, level_db)
    return r is not None and r <= AT_LEVEL
