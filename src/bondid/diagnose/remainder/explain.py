"""The search for what the remainder is made of (:func:`explain`): every detector proposes
its best-fitting candidates; the one that removes the most beyond what noise would
(:attr:`.stats.LogFit.gain`) among those that pass the tests is claimed, its correction is
applied to the model, and the search repeats on what is left.

A candidate passes when

1. its p-value against the noise (:mod:`.stats`) is at most ``α / T``, ``T`` the number of
   looks every detector took in that round together (Bonferroni: the false-alarm rate of the
   whole round on pure noise stays at most ``α``); and
2. it explains at least ``min_share`` of the excess over the noise of the original residual.

Candidates the data cannot tell from the claimed one (a reduction within the one-parameter
threshold ``χ²₁⁻¹(1 − α)`` times the larger noise scale ``c``, as the verdict's
indistinguishable rule) are named with it as alternatives.
"""

from __future__ import annotations

from collections.abc import Callable

from . import delay, drive, gain, lag, leakage, modes, notch, slope
from .base import Candidate, Finding
from .context import Context
from .residual import Residual

Detector = Callable[[Residual, Context], list[Candidate]]

#: every detector, in no particular order (the search ranks their candidates)
DETECTORS: tuple[Detector, ...] = (
    gain.candidates,
    slope.candidates,
    delay.candidates,
    lag.candidates,
    notch.candidates,
    leakage.candidates,
    drive.candidates,
    modes.missing_candidates,
    modes.model_candidates,
)
#: most alternatives named with a finding
MAX_ALTERNATIVES = 3


def explain(res: Residual, ctx: Context, excess: float) -> tuple[list[Finding], Residual]:
    """The findings (in the order claimed) and the residual against the model with all their
    corrections; ``excess`` is the original residual's excess over the noise
    (:func:`.excess.positive_excess`), which every share is taken against."""
    from scipy.special import chdtri  # inverse χ² survival function

    s = ctx.settings
    weight = res.weight
    found: list[Finding] = []
    current = res
    for _ in range(s.max_findings):
        cands = [c for det in DETECTORS for c in det(current, ctx)]
        if not cands:
            break
        p_thr = s.alpha / sum(c.trials for c in cands)
        need = s.min_share * excess if excess > 0 else 0.0
        ok = [
            c for c in cands
            if c.fit.p_value <= p_thr and c.fit.reduction > need and c.fit.gain > 0
        ]  # fmt: skip
        if not ok:
            break
        best = max(ok, key=lambda c: c.fit.gain)
        finding = best.describe(best.significance(excess, weight, p_thr))
        q = float(chdtri(1, s.alpha))
        alts = [
            c for c in sorted(ok, key=lambda c: -c.fit.gain)
            if c is not best and c.key != best.key and not (c.group and c.group == best.group)
            and best.fit.gain - c.fit.gain <= q * max(best.fit.null_scale, c.fit.null_scale)
        ]  # fmt: skip
        finding.alternatives = [c.key for c in alts[:MAX_ALTERNATIVES]]
        found.append(finding)
        current = current.with_model(best.corrected(current))
    return found, current
