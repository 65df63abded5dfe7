"""Two effects accepted together (:func:`look_ahead`): a first step refused only because its
best refit removes too small a share of the excess over the noise.

The verdict rule (:func:`.scoring.tests`) asks an accepted effect to remove at least
:data:`.scoring.MIN_EXCESS_SHARE` of its base's excess mean square over the held-out noise
level: a refit that only lands in another basin moves the score by a few per cent. But when
a machine misses two effects, each of them alone may remove less than that share of the
parameter refit's excess, although both are plainly there. Measured on the blind benchmark's
bonder_b/jcr+al/harsh (a rotational compliance and an actuator lag withheld, harsh floor):
the true actuator lag was the best refit of the first step with its strength determined at
``z`` = 40 and a likelihood-ratio statistic of 170 (threshold 10.7), and it removed 24 % of
the excess; the verdict was ``none``, the final model 3.1× the truth's weighted gap.

So when the first step's best refit passes every part of the rule but the share (the base
above the noise level, the improvement significant, the strength determined) and there is
room for another effect, the search runs the next step from it, provisionally. The two are
accepted together only when that step's best refit passes the same rule against it except
the share (significant, its strength determined), and the pair, taken as one candidate with
both effects' parameters, passes the whole rule against the first step's base, the share
included. Otherwise the first step stays refused and the look-ahead is only reported. The
backward elimination (:mod:`.prune`) then tests each of the two against the model with the
other, as for any two accepted effects.

Only the first step looks ahead: its base (the parameter refit) carries every missing
effect's share of the excess, while a later step's base has already taken the larger one,
so a real effect there removes a large share of what is left.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from . import scoring

if TYPE_CHECKING:
    from .search import Context, Step


def short_of_share(test: dict[str, Any]) -> bool:
    """Did the verdict rule's figures ``test`` (:func:`.scoring.tests`, with a noise
    reference) refuse only for the excess share: base above the noise level, the likelihood
    ratio above its threshold, the share below :data:`.scoring.MIN_EXCESS_SHARE`?"""
    return (
        test.get("rule") == "noise"
        and not test.get("accepted")
        and bool(test.get("base_above_noise"))
        and float(test.get("lr", 0.0)) > float(test.get("lr_threshold", float("inf")))
        and float(test.get("excess_share", 1.0)) < scoring.MIN_EXCESS_SHARE
    )


def pair_test(first: Step, second: Step, noise: scoring.NoiseReference | None) -> dict[str, Any]:
    """The verdict rule's figures of the pair: the second step's best refit (both effects)
    against the first step's base, with both effects' parameters."""
    best1, best2 = first.results[0], second.results[0]
    return scoring.tests(second.scores[0], first.base_score, best1.n_own + best2.n_own, noise)


def look_ahead(
    ctx: Context, step: Step, run_step: Callable[[int, Any, float], Step]
) -> Step | None:
    """The look-ahead of the module docstring for the refused first step ``step``:
    ``run_step(index, base, base_score)`` runs a search step. Returns the next step with
    both steps marked accepted (``step.winner`` set, each ``test`` with a ``compound``
    entry), or None when the pair is not accepted (``step.test["compound"]`` then says what
    was tried)."""
    if step.index != 0 or ctx.max_effects < 2 or not step.results or not short_of_share(step.test):
        return None
    first = step.results[0]
    nxt = run_step(step.index + 1, first, step.scores[0])
    info: dict[str, Any] = {"with": None, "accepted": False}
    if nxt.results:
        second = nxt.results[0]
        pair = pair_test(step, nxt, ctx.noise)
        own = nxt.test
        own_ok = own.get("rule") == "noise" and float(own.get("lr", 0.0)) > float(
            own.get("lr_threshold", float("inf"))
        )
        info = {
            "with": {"effect": second.effect, "location": second.location,
                     "score": nxt.scores[0]},
            "pair": pair,
            "accepted": bool(own_ok and pair["accepted"]),
        }  # fmt: skip
    if not info["accepted"]:
        step.test = {**step.test, "compound": info}
        return None
    step.winner = first
    step.test = {**step.test, "accepted": True, "compound": info}
    nxt.winner = nxt.results[0]
    pair = info["pair"]
    back = {"effect": first.effect, "location": first.location, "score": step.scores[0]}
    nxt.test = {**nxt.test, "accepted": True,
                "compound": {"with": back, "pair": pair, "accepted": True}}  # fmt: skip
    return nxt
