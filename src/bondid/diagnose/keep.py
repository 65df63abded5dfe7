"""Which of two refits of one job is kept (for :mod:`.runner`, :mod:`.alternatives`,
:mod:`.modal_start` and :mod:`.widen`): the new one only when its training objective is
lower **and** it does not trade that for a worse held-out figure.

A refit can lower the training objective by fitting the training frequencies with bent
parameters while missing the held-out ones. Measured (benchmark case gantry/sm+al/acc, stop
22): the soft mounts' restart alternation was kept for a weighted training figure of 0.739 dB
against 0.751 dB, while its held-out figure was 1.87 dB against 0.87 dB; the diagnosis ended
at 1.43 dB instead of 0.91 dB. So, when the job has held-out data, the new refit must also
either keep its held-out figure at or below the current one's, or stay at the held-out noise
level (not above :data:`.rescue.RESCUE_RATIO` times ``Job.heldout_noise_db``, when the job
has that level). Without held-out data the training objective alone decides.

The held-out figure is :func:`.evaluate.heldout_rms` (the verdict's held-out figure before its
FPE factor); it is computed only when the training objective alone would keep the new refit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .augmented import Augmented
    from .job import Job

#: a held-out figure [dB], computed when asked
Held = Callable[[], float]


def held_of(job: Job, aug: Augmented, res: Any) -> Held:
    """The held-out figure [dB] of the refit ``aug`` ended at (its search ``res``), lazily."""

    def held() -> float:
        from .evaluate import heldout_rms

        return heldout_rms(aug.refit, res.result, job.heldout, job.options)

    return held


def known(value: float) -> Held:
    """A held-out figure [dB] already computed, as a :data:`Held`."""
    return lambda: value


def replaces(job: Job, cost: float, held: Held, cost2: float, held2: Held) -> bool:
    """Does the new refit (training objective ``cost2``, held-out figure ``held2`` [dB])
    replace the current one (``cost``, ``held``)? The module docstring's rule."""
    from .rescue import above_heldout_level

    if not cost2 < cost:
        return False
    if not job.heldout:
        return True
    h2 = held2()
    if not math.isfinite(h2):
        return True
    level = job.heldout_noise_db
    if math.isfinite(level) and level > 0 and not above_heldout_level(h2, level):
        return True
    h = held()
    return not math.isfinite(h) or h2 <= h
