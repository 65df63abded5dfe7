"""The honest answer of a diagnosis: explained, partly explained or unexplained
(:func:`outcome`).

"No effect" means two different things, and a user must be able to tell them apart:

* **explained** — the final model (the parameter refit with the kept effects, or the
  parameter refit alone) is at the held-out noise level: nothing the data show is left.
  With no effect kept this says the model only had wrong parameters;
* **partly explained** — effects were kept, but the model with them is still above the
  held-out noise level: they explain part of the gap, the rest is something else (the
  remainder's description says what it looks like and where);
* **unexplained** — no candidate passes the rule while the parameter refit is above the
  held-out noise level: something is missing that none of the candidates explains.

Each kept effect is also graded by the share of the base's excess over the noise it
removes (:data:`CONFIRMED_SHARE`): an effect that leaves most of the excess in place is
*tentative*, never stated like one that removes it.

"At the held-out noise level" is the rule's own first condition (:func:`.scoring.above_level`)
on the model's held-out score: the test that decides whether a step can accept anything
decides whether anything is left. The search's models are fitted on the training bands only;
the final model is the same model refitted on all the data (:mod:`.final_fit`), with no
points held out. When that refit, with the kept effects, reaches the noise level of all the
data (:data:`bondid.optim.noise.AT_LEVEL`, the one ratio "at the noise level" of the
package) where the search's model did not — a basin the training bands alone did not lead
to, e.g. a pivot — nothing the data show is left either: the answer is *explained*, and says
so, provided the kept effects remove at least :data:`CONFIRMED_SHARE` of the held-out
excess (the all-data estimate is the looser test, and a tentative effect that leaves most of
the held-out excess in place is not made an explanation by it: *partly explained*, the text
giving both figures). Without a kept effect there is no new model to find such a basin:
the parameter refit above the held-out level is what the rule would have accepted an effect
against, so the answer is *unexplained* even when the refit on all data comes within that
looser ratio of the all-data noise estimate (the text says so: what is missing is then
small).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ..optim.noise import AT_LEVEL
from . import scoring

#: a kept effect that removes at least this share of its base's excess over the noise is
#: confirmed, less (down to the rule's own minimum) tentative
CONFIRMED_SHARE = 0.5

EXPLAINED = "explained"
PARTLY = "partly_explained"
UNEXPLAINED = "unexplained"
#: without a noise level (costs the noise model does not cover) nothing can be said
UNKNOWN = "unknown"


@dataclass
class Outcome:
    """The answer (module docstring).

    Attributes:
        kind: :data:`EXPLAINED`, :data:`PARTLY`, :data:`UNEXPLAINED` or :data:`UNKNOWN`.
        text: one sentence for the summary and the report.
        over_noise: the final model's held-out score over the held-out noise level (NaN
            without a level).
        refit_over_noise: the same for the parameter refit.
        excess_removed: the share of the parameter refit's excess mean square over the noise
            that the kept effects remove (NaN without effects or a level).
        grades: per kept effect ``"confirmed"`` or ``"tentative"``, in order.
        final_over_noise: the final model's weighted db_rms on all data over their noise
            level (NaN unknown or not refitted).
    """

    kind: str
    text: str
    over_noise: float = math.nan
    refit_over_noise: float = math.nan
    excess_removed: float = math.nan
    grades: list[str] = field(default_factory=list)
    final_over_noise: float = math.nan

    def as_dict(self) -> dict[str, Any]:
        return {
            "outcome": self.kind,
            "outcome_text": self.text,
            "over_noise": self.over_noise,
            "refit_over_noise": self.refit_over_noise,
            "excess_removed": self.excess_removed,
            "grades": list(self.grades),
            "final_over_noise": self.final_over_noise,
        }


def grade(test: dict[str, Any]) -> str:
    """``"confirmed"`` or ``"tentative"`` for an accepted effect's rule figures ``test``
    (``"confirmed"`` when the rule ran without a noise level: no share to grade by)."""
    # an effect accepted with the next one (:func:`.search.joint_step`) is graded by
    # the share the two remove together
    share = (test.get("joint") or test).get("excess_share")
    if share is None or not math.isfinite(float(share)):
        return "confirmed"
    return "confirmed" if float(share) >= CONFIRMED_SHARE else "tentative"


def outcome(
    refit_score: float,
    final_score: float,
    kept_tests: list[dict[str, Any]],
    noise: scoring.NoiseReference | None,
    final_ratio: float | None = None,
) -> Outcome:
    """The outcome of a diagnosis.

    Args:
        refit_score: the parameter refit's held-out score [dB].
        final_score: the held-out score [dB] of the model with every kept effect (the
            parameter refit's when none is kept).
        kept_tests: the rule's figures of each kept effect (:func:`.scoring.tests`), in order.
        noise: the held-out noise reference (None: unknown level).
        final_ratio: the final model's weighted db_rms on all data over their noise level
            (:mod:`.final_fit`; None: not refitted or unknown).
    """
    grades = [grade(t) for t in kept_tests]
    if not scoring.usable(noise) or not math.isfinite(final_score):
        text = ("no noise level for this cost: the diagnosis cannot tell whether anything is"
                " left")  # fmt: skip
        return Outcome(UNKNOWN, text, grades=grades)
    L = noise.level_db
    over, over0 = final_score / L, refit_score / L
    removed = math.nan
    if kept_tests and refit_score > L:
        removed = (refit_score**2 - final_score**2) / (refit_score**2 - L**2)
    left = scoring.above_level(final_score, noise)
    fin = math.nan if final_ratio is None else float(final_ratio)
    # the all-data figure stands for the held-out one only where the kept effects do most
    # of the work there: the all-data noise estimate is the looser test (a parameter refit
    # well above the held-out level can come within it), so an effect that leaves most of
    # the held-out excess in place is not made an explanation by it
    confirmed = math.isfinite(removed) and removed >= CONFIRMED_SHARE
    if left and kept_tests and math.isfinite(fin) and fin <= AT_LEVEL and confirmed:
        text = (f"explained: refitted on all data, the model with the kept effect(s) is at the"
                f" noise level ({fin:.2f}x; on the held-out bands the search's fit was at"
                f" {over:.2f}x)")  # fmt: skip
        return Outcome(EXPLAINED, text, over, over0, removed, grades, fin)
    if not left:
        if kept_tests:
            text = (f"explained: with the kept effect(s) the model is at the held-out noise"
                    f" level ({over:.2f}x)")  # fmt: skip
        else:
            text = (f"explained by the parameters alone: the parameter refit is at the"
                    f" held-out noise level ({over0:.2f}x); nothing is missing that these data"
                    f" show")  # fmt: skip
        return Outcome(EXPLAINED, text, over, over0, removed, grades, fin)
    if kept_tests:
        text = (f"partly explained: the kept effect(s) remove {removed:.0%} of the excess over"
                f" the noise, the model stays at {over:.2f}x the held-out noise level; the rest"
                f" is something no candidate explains (see the remainder)")  # fmt: skip
        if math.isfinite(fin) and fin <= AT_LEVEL:
            text += (f"; refitted on all data the model comes within {fin:.2f}x of that"
                     f" data's noise level, a looser test than the held-out one")  # fmt: skip
        return Outcome(PARTLY, text, over, over0, removed, grades, fin)
    small = ""
    if math.isfinite(fin) and fin <= AT_LEVEL:
        small = (f"; refitted on all data the parameters come within {fin:.2f}x of that"
                 f" data's noise level, so what is missing is small")  # fmt: skip
    text = (f"unexplained: the parameter refit is at {over0:.2f}x the held-out noise level and"
            f" no candidate passes the rule; something is missing that none of the candidates"
            f" explains (see the remainder){small}")  # fmt: skip
    return Outcome(UNEXPLAINED, text, over, over0, removed, grades, fin)
