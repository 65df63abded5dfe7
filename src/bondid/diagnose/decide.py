"""Stage 3 of a search step (:mod:`.search`): the rule of :mod:`.scoring` on the step's
refits (:func:`apply_rule`), and the refused test of a step whose base is already at the noise
level (:func:`at_level_test`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from . import scoring
from .job import JobResult
from .parsimony import prefer_simpler


def verdict_order(results: Sequence[JobResult], scores: Sequence[float]) -> list[int]:
    """Indices of ``results`` (held-out ``scores`` [dB], same order): the refits whose effect
    strength the data determine (:func:`.scoring.determined`) best score first, then the
    others best first."""
    ranked = scoring.rank(scores)
    order = [i for i in ranked if scoring.determined(results[i])]
    return order + [i for i in ranked if i not in order]


def apply_rule(
    noise: scoring.NoiseReference | None,
    channels: tuple[Sequence[str], Sequence[str]],
    base: JobResult,
    base_score: float,
    results: list[JobResult],
) -> tuple[list[JobResult], list[float], dict[str, Any], JobResult | None]:
    """The rule on a step's refits against their ``base`` (held-out score ``base_score``
    [dB]), with the held-out ``noise`` reference and the data's ``channels`` (outputs,
    inputs): (results and scores in the step's order, the test, the winner or None)."""
    scores = [scoring.score(r.heldout_rms, r.n_train, r.n_new) if not r.error else math.inf
              for r in results]  # fmt: skip
    outs, ins = channels
    order, displaced = prefer_simpler(results, scores, verdict_order(results, scores),
                                      noise, outs, ins)  # fmt: skip
    ordered, ordered_scores = [results[i] for i in order], [scores[i] for i in order]
    if not ordered:
        return ordered, ordered_scores, {"accepted": False, "rule": "none",
                                         "why": "no candidate could be refitted"}, None  # fmt: skip
    best = ordered[0]
    z = scoring.strength_z(best)
    if z < scoring.Z:
        test: dict[str, Any] = {
            "accepted": False,
            "rule": "none",
            "why": "no refit determines its effect's strength (value/std < z)",
        }
    else:
        # p of the test: this step's own candidate parameters
        test = scoring.tests(ordered_scores[0], base_score, best.n_own, noise)
        scoring.refuse_unless_lower(test, best.db_rms, base.db_rms)
        if displaced is not None:
            d = results[displaced]
            test["preferred_over"] = {
                "effect": d.effect,
                "location": d.location,
                "score": scores[displaced],
                "n_parameters": d.n_own,
            }
    test["strength_z"] = z
    winner = best if test.get("accepted") else None
    return ordered, ordered_scores, test, winner


def at_level_test(
    base_score: float, noise: scoring.NoiseReference | None, screened: bool
) -> dict[str, Any]:
    """The refused test of a step whose base (held-out score ``base_score`` [dB]) is at the
    noise level: nothing refitted; ``screened``: the candidates were screened (the first
    step's are, for the report; a later step is not run at all)."""
    ratio = base_score / noise.level_db if scoring.usable(noise) else math.nan
    done = ("so no candidate was refitted (the screening's figures are reported)"
            if screened else "so the step was not run")  # fmt: skip
    why = (f"the base is at the held-out noise level ({ratio:.3f}x): no candidate can pass "
           f"the rule's first condition, {done}")  # fmt: skip
    return {"accepted": False, "rule": "none", "why": why, "screened": screened,
            "base_over_noise": ratio, "base_above_noise": False}  # fmt: skip
