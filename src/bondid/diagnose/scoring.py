"""Scoring and the verdict.

* ``score`` of a refit (lower is better): its held-out error — the coherence-weighted RMS
  complex-log error [dB] on the held-out frequencies (see :mod:`bondid.diagnose.split`) —
  times the final-prediction-error factor ``√((N + p)/(N − p))`` for the ``p`` parameters
  the candidate adds over the parameter-only refit (``N`` training residuals). The held-out
  error is the main penalty on complexity; the factor only breaks ties in its favour of the
  simpler model.
* verdict: the best-scoring candidate wins only if it beats the parameter-only refit
  *clearly* on held-out data: its score must be lower by at least :data:`REL_MARGIN` of the
  refit's score **and** by at least :data:`ABS_MARGIN_DB`; otherwise the verdict is
  ``"none"`` (refitting parameters alone explains the data as well as any candidate).
* ``gap_closed = 1 − db_rms_after / db_rms_before`` with ``before`` = the gap after the
  parameter refit (``gap.db_rms`` of ``diagnosis.json``), i.e. the share of the remaining gap
  the effect removes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

REL_MARGIN = 0.05
ABS_MARGIN_DB = 0.05


def score(heldout_rms: float, n_train: int, n_new: int) -> float:
    """Held-out weighted RMS [dB] × FPE factor for ``n_new`` added parameters."""
    if not math.isfinite(heldout_rms) or n_train <= n_new:
        return math.inf
    return heldout_rms * math.sqrt((n_train + n_new) / (n_train - n_new))


def gap_closed(before: float, after: float) -> float:
    """``1 − after/before`` (NaN when ``before`` is not positive and finite)."""
    if not (math.isfinite(before) and before > 0 and math.isfinite(after)):
        return math.nan
    return 1.0 - after / before


def clearly_better(candidate_score: float, baseline_score: float) -> bool:
    """The verdict rule of the module docstring."""
    if not (math.isfinite(candidate_score) and math.isfinite(baseline_score)):
        return False
    gain = baseline_score - candidate_score
    return gain >= REL_MARGIN * baseline_score and gain >= ABS_MARGIN_DB


def rank(scores: Sequence[float]) -> list[int]:
    """Indices sorted best (lowest score) first; non-finite scores last."""
    return sorted(range(len(scores)), key=lambda i: (not math.isfinite(scores[i]), scores[i]))
