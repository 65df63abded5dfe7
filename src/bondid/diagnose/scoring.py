"""Scoring and the verdict.

* ``score`` of a refit (lower is better): its held-out error — the information-weighted RMS
  complex-log error [dB] on the held-out frequencies (see :mod:`bondid.diagnose.split`) —
  times the final-prediction-error factor ``√((N + p)/(N − p))`` for the ``p`` parameters
  the candidate adds over the parameter-only refit (``N`` training residuals).
* the **held-out noise reference** (:func:`heldout_noise`): ``L``, the score an exact model
  would get on the held-out points (:mod:`bondid.cost.noise_level`, from the weights the
  diagnosis uses), and ``n``, the number of independent held-out points it rests on:
  ``n = (Σ wᵢ mᵢ)² / Σ wᵢ² qᵢ`` with ``mᵢ`` and ``qᵢ`` the mean and variance of point ``i``'s
  squared log error under its noise (:func:`bondid.cost.noise_level.log_error_variance`), so
  that the weighted mean square of pure noise has relative std ``1/√n``.
* verdict (:func:`accept`): the best-scoring candidate (score ``s₁``) is accepted against the
  model it is added to (score ``s₀``) only when both hold:

  1. **the base is above the noise level**, beyond the prediction's tolerance and its
     sampling error: ``s₀² > (1 + LEVEL_TOL)² L² (1 + z/√n)`` (:data:`LEVEL_TOL` = 0.1, the
     "at the noise level" of the fit; ``z`` = :data:`Z`). A model already at the noise level
     has nothing left to explain.
  2. **the improvement is significant and real**: the likelihood-ratio-type statistic
     ``Λ = n (s₀² − s₁²) / L²`` of the held-out scores (FPE factors included, so it is a
     little conservative) exceeds ``½ χ²_p⁻¹(1 − α)`` (:func:`lr_threshold`; ``p`` the
     parameters this step's candidate adds, ``α = P(χ²₁ > 2z²)`` ≈ 2.2e-5 the false-alarm
     rate of a one-parameter test at ``Λ > z²``). This is a calibrated heuristic, not an
     exact law: for nested fits scored on their own training points with 1/variance
     weights, ``2Λ`` (``n`` counts complex points, two real residuals each) would follow
     ``χ²_p`` when the candidate adds nothing; held-out points with information weights (not
     1/variance) follow no such law, hence the small ``α``. The threshold grows with ``p``
     as the ``χ²_p`` quantile does (``p + O(√p)``, 9.0 for ``p = 1``, 10.7 for 2, 16.7 for
     7), not in proportion to ``p``: a threshold of ``z²·p`` would ask a 7-parameter
     flexible base for a statistic 3.8× what pure noise reaches at that rate. **And** the
     candidate removes at least :data:`MIN_EXCESS_SHARE` of the base's excess over the noise,
     ``s₀² − s₁² ≥ MIN_EXCESS_SHARE · (s₀² − L²)`` (a refit that lands in another basin moves
     the score by a few per cent either way; an effect the data really show closes a good
     part of what lies above the noise).

  Without a noise reference (costs the noise level does not model) the former rule stands:
  lower by :data:`REL_MARGIN` of the base's score and by :data:`ABS_MARGIN_DB`.
* **the effect's strength is determined** (:func:`strength_z`, :func:`determined`): the test
  above is taken on the best-scoring refit whose *strength* the data determine, i.e. at least
  one of its strength parameters (``NewParameter.strength``: a stiffness, a delay, a lag
  time) has ``value/std ≥ Z``, the std from the refit's Jacobian with every nominal parameter
  free (:func:`bondid.optim.result.parameter_statistics`) and, for a structural candidate,
  its other own parameters held (:meth:`.refit.Refit.own_strength_std`: a lumped base's
  masses and springs, a pivot's shift and its spring trade among themselves, which says
  nothing about whether the effect is there). For a delay this is the Wald test of
  ``τ = 0`` (the absent effect); for a stiffness ``k`` the compliance ``1/k`` has the same
  relative std to first order, so it is the Wald test of a zero compliance. A refit that
  lowers the held-out score while its strength stays undetermined trades the new parameter
  against the nominal ones (another basin, a retuned model) rather than showing the effect:
  an effect the data really show is determined many times over (``z`` in the tens), while
  a refit at a wrong place that lowers the score by trading parameters has ``z`` below 1.
* **indistinguishable** (:func:`indistinguishable`): a refitted candidate whose score ``sⱼ``
  the best one's does not beat by the significance part of the rule taken with one
  parameter, ``n (sⱼ² − s₁²) / L² ≤ ½ χ²₁⁻¹(1 − α)`` (without a noise reference: not lower
  by the margins). The data cannot tell it from the best (e.g. a sensor delay and an
  actuator lag on a single input give nearly the same phase); ``diagnosis.json`` lists it
  with the accepted effect, which is then only the best-scoring of the two.
* ``gap_closed = 1 − db_rms_after / db_rms_before`` with ``before`` = the gap after the
  parameter refit (``gap.db_rms`` of ``diagnosis.json``), i.e. the share of the remaining gap
  the effect removes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, TypeGuard

import numpy as np

from ..cost.problem import CostOptions
from ..data.measurement import FrfData
from ..optim.noise import AT_LEVEL

#: fallback rule (no noise reference): relative and absolute margins of the score
REL_MARGIN = 0.05
ABS_MARGIN_DB = 0.05
#: "at the noise level": within this share of the predicted level (the package's one test,
#: :data:`bondid.optim.noise.AT_LEVEL`)
LEVEL_TOL = AT_LEVEL - 1.0
#: normal quantile of the base-above-noise test (one-sided: 3 ≈ 0.13 % false alarms on pure
#: noise); the significance test's threshold is ``Z²`` per added parameter (module docstring)
Z = 3.0
#: share of the base's excess mean square over the noise a candidate must remove
MIN_EXCESS_SHARE = 0.25


@dataclass(frozen=True)
class NoiseReference:
    """The held-out points' noise: ``level_db`` the predicted score of an exact model [dB],
    ``n_eff`` the number of independent points behind it (module docstring)."""

    level_db: float
    n_eff: float

    def as_dict(self) -> dict[str, float]:
        return {"heldout_noise_level_db": self.level_db, "heldout_n_eff": self.n_eff}


def lr_threshold(n_new: int) -> float:
    """The threshold of ``Λ`` for a candidate adding ``n_new`` parameters: half the
    ``χ²_p`` quantile at the false-alarm rate ``P(χ²₁ > 2 Z²)`` (``Z²`` for one parameter)."""
    from scipy.stats import chi2

    alpha = float(chi2.sf(2.0 * Z**2, 1))
    return 0.5 * float(chi2.isf(alpha, max(int(n_new), 1)))


def score(heldout_rms: float, n_train: int, n_new: int) -> float:
    """Held-out weighted RMS [dB] × FPE factor for ``n_new`` added parameters."""
    if not math.isfinite(heldout_rms) or n_train <= n_new:
        return math.inf
    return heldout_rms * math.sqrt((n_train + n_new) / (n_train - n_new))


def strength_z(result: Any) -> float:
    """The Wald statistic of a refit's effect (module docstring): the largest ``value/std``
    over its candidate's strength parameters (the last ``n_own`` of ``result.values``; the
    std with the candidate's other own structural parameters held, ``result.own_std``, where
    the refit gives it, else the marginal ``result.std``);
    0 for a strength parameter the data do not identify at all (NaN std), ``inf`` when the
    refit has no candidate or its candidate no strength parameter (nothing to test)."""
    cand = getattr(result, "candidate", None)
    n_own = int(getattr(result, "n_own", 0))
    if cand is None or n_own <= 0 or len(result.values) < n_own:
        return math.inf
    params = cand.parameters[-n_own:]
    values = np.asarray(result.values, float)[-n_own:]
    own = np.asarray(getattr(result, "own_std", ()), float)
    std: np.ndarray | None = own
    if len(own) != n_own:
        std = np.asarray(result.std, float)[-n_own:] if len(result.std) >= n_own else None
    zs = []
    for k, p in enumerate(params):
        if not p.strength:
            continue
        s = float(std[k]) if std is not None else math.nan
        if s == 0.0:
            zs.append(math.inf)
        elif math.isfinite(s) and s > 0:
            zs.append(abs(float(values[k])) / s)
        else:
            zs.append(0.0)
    return max(zs) if zs else math.inf


def determined(result: Any) -> bool:
    """True when the data determine the refit's effect strength (:func:`strength_z` ≥ Z)."""
    return strength_z(result) >= Z


def gap_closed(before: float, after: float) -> float:
    """``1 − after/before`` (NaN when ``before`` is not positive and finite)."""
    if not (math.isfinite(before) and before > 0 and math.isfinite(after)):
        return math.nan
    return 1.0 - after / before


def heldout_noise(
    datasets: Sequence[FrfData], options: CostOptions,
    originals: Sequence[FrfData] | None = None, weighting: str = "auto",
) -> NoiseReference | None:  # fmt: skip
    """The noise reference of the held-out data (module docstring), weighted as the held-out
    score is (``options``: its channels, bands and weighting).

    Args:
        datasets: held-out data sets (in the diagnosis their ``coherence`` holds the weights).
        options: the cost options of the held-out score.
        originals: the measured data sets they were cut from (same order), whose noise
            estimate gives the points' noise-to-signal ratio for the prediction under the
            rule ``weighting`` (the basis ``"prediction"`` of
            :func:`bondid.cost.noise_level.point_noise_to_signal`: the verdict's tests are
            statistical claims against the level, which must not be biased; the weights
            alone would give the cautious ratio, whose level comes out 10–20 % high); None:
            from ``datasets`` themselves (in the diagnosis, whose data hold their weights in
            the coherence, that is the cautious level).
        weighting: the weighting rule of ``originals``.

    Returns:
        The reference, or None when the cost's noise level is not modelled (kinds other than
        ``complex_log``, the ``l1`` norm) or no point weighs.
    """
    from ..cost.noise_level import expected_log_error, log_error_variance, point_noise_to_signal
    from ..cost.residuals import DB
    from ..cost.selection import used_points
    from ..data.weights import information_weights

    if options.kind != "complex_log" or options.norm != "l2":
        return None
    wm, wq, ws = [], [], []
    rule = options.effective_weighting
    for k, ds in enumerate(datasets):
        m = used_points(ds, options)
        w = np.nan_to_num(information_weights(ds, rule)[m])
        orig = (originals[k], weighting) if originals is not None and k < len(originals) else None
        v = point_noise_to_signal(ds, rule, "prediction", orig)[m]
        keep = (w > 0) & ~np.isnan(v)  # a point of unknown noise tells nothing of the level
        w, v = w[keep], v[keep]
        wm.append(w * expected_log_error(v))
        wq.append(w * w * log_error_variance(v))
        ws.append(w)
    mean, var, w_all = (np.concatenate(x) for x in (wm, wq, ws))
    if w_all.sum() <= 0 or not (np.all(np.isfinite(mean)) and np.all(np.isfinite(var))):
        return None
    level2 = float(mean.sum() / w_all.sum())
    n_eff = float(mean.sum() ** 2 / max(float(var.sum()), 1e-300))
    return NoiseReference(float(DB * math.sqrt(level2)), n_eff)


def usable(noise: NoiseReference | None) -> TypeGuard[NoiseReference]:
    """Does the verdict rule run on ``noise`` (a positive level and point count), rather than
    on the fallback margins?"""
    return noise is not None and noise.level_db > 0 and noise.n_eff > 0


def base_score(base: Any) -> float:
    """:func:`score` of a step's base ``base`` (a refit result with ``heldout_rms`` [dB] and
    ``n_train``): no parameters added over itself."""
    return score(base.heldout_rms, base.n_train, 0)


def above_level(baseline_score: float, noise: NoiseReference) -> bool:
    """Condition 1 of the verdict rule (module docstring): is a base of held-out score
    ``baseline_score`` [dB] above the noise level of ``noise``?"""
    s0, L2, n = baseline_score**2, noise.level_db**2, noise.n_eff
    return bool(s0 > (1.0 + LEVEL_TOL) ** 2 * L2 * (1.0 + Z / math.sqrt(n)))


def may_accept(baseline_score: float, noise: NoiseReference | None) -> bool:
    """Can any candidate be accepted against a base of held-out score ``baseline_score``
    [dB]? Not when the rule runs on a noise reference and the base is at its level
    (:func:`above_level`); else (or without a finite score) it may."""
    if not (usable(noise) and math.isfinite(baseline_score)):
        return True
    return above_level(baseline_score, noise)


def tests(
    candidate_score: float, baseline_score: float, n_new: int, noise: NoiseReference | None
) -> dict[str, Any]:
    """The figures of the verdict rule (module docstring) for one candidate: ``accepted`` and,
    with a noise reference, ``base_over_noise`` (``s₀/L``), ``base_above_noise``, ``lr``
    (``Λ``), ``lr_threshold``, ``excess_share`` (the share of the base's excess mean square
    removed) and ``significant``."""
    if not (math.isfinite(candidate_score) and math.isfinite(baseline_score)):
        return {"accepted": False, "rule": "none", "why": "a score is not finite"}
    gain = baseline_score - candidate_score
    if not usable(noise):
        ok = gain >= REL_MARGIN * baseline_score and gain >= ABS_MARGIN_DB
        return {"accepted": bool(ok), "rule": "margin"}
    s0, s1, L2, n = baseline_score**2, candidate_score**2, noise.level_db**2, noise.n_eff
    above = above_level(baseline_score, noise)
    lr = n * (s0 - s1) / L2
    threshold = lr_threshold(n_new)
    excess = (s0 - s1) / (s0 - L2) if s0 > L2 else 0.0
    significant = lr > threshold and excess >= MIN_EXCESS_SHARE
    return {
        "accepted": bool(above and significant),
        "rule": "noise",
        **noise.as_dict(),
        "base_over_noise": math.sqrt(s0 / L2),
        "base_above_noise": bool(above),
        "lr": lr,
        "lr_threshold": threshold,
        "excess_share": excess,
        "significant": bool(significant),
    }


#: the rule as ``diagnosis.json`` states it (``scoring.rule``)
RULE = (
    "accept the best candidate (held-out score s1) against the model it is added to (s0) iff "
    "s0^2 > (1 + level_tol)^2 L^2 (1 + z/sqrt(n)) [the base is above the held-out noise level "
    "L, predicted from the data's noise, n independent held-out points] and "
    "n (s0^2 - s1^2)/L^2 > chi2_p.isf(alpha)/2 with alpha = chi2_1.sf(2 z^2) "
    "[likelihood-ratio-type heuristic, p parameters the candidate adds] and "
    "(s0^2 - s1^2) >= min_excess_share (s0^2 - L^2); without a noise level: s1 lower by "
    "rel_margin of s0 and by abs_margin_db; the best candidate is the best-scoring one whose "
    "strength the data determine: value/std >= z for at least one of its strength parameters "
    "(stiffness, delay, lag time); and the accepted refit lowers the weighted gap on all data; "
    "a best refit refused only for min_excess_share is accepted with the next step's winner "
    "when that one passes the rule on top of it and the pair passes it against the same base "
    "(p: both effects' parameters)"
)


def short_of_share(test: dict[str, Any]) -> bool:
    """Was the refit of ``test`` (from :func:`tests`, with ``strength_z`` set) refused only
    because it removes too small a share of the excess: the base above the noise level, the
    gain significant, the strength determined, the gap on all data lower? Such an effect is
    real but not alone: a second missing effect holds most of the excess."""
    if test.get("rule") != "noise" or test.get("accepted") or test.get("gap_not_lower"):
        return False
    return bool(test["base_above_noise"] and test["lr"] > test["lr_threshold"]
                and test["excess_share"] < MIN_EXCESS_SHARE
                and test.get("strength_z", 0.0) >= Z)  # fmt: skip


def refuse_unless_lower(test: dict[str, Any], gap_after: float, gap_before: float) -> None:
    """The rule's last condition, on ``test`` (from :func:`tests`, changed in place): an
    accepted refit must also lower the weighted gap on all data [dB] (``gap_after`` below
    ``gap_before``, the model it is added to); else it is refused, ``gap_not_lower`` set.
    A held-out score can improve while the whole gets worse when a few points of wrongly
    judged noise decide the held-out figure (seen on H1 data whose coherence from 20
    averages read 0.05 on pure noise: an effect accepted at 2.65 → 3.02 dB)."""
    if test.get("accepted") and not gap_after < gap_before:
        test.update(accepted=False, gap_not_lower=True)


def reason(test: dict[str, Any], candidate_score: float, baseline_score: float) -> str:
    """One sentence on why the rule accepted or refused (``test`` from :func:`tests`)."""
    if test.get("rule") == "none" and not math.isfinite(candidate_score):  # nothing refitted
        return f"held-out score of the base {baseline_score:.3f} dB: {test.get('why', 'no test')}"
    head = f"held-out score {candidate_score:.3f} dB vs {baseline_score:.3f} dB"
    if test.get("rule") == "none":
        return f"{head}: {test.get('why', 'no test')}"
    if test.get("rule") != "noise":
        worse = "; its weighted gap on all data is not lower" if test.get("gap_not_lower") else ""
        return (f"{head} (needs >= {REL_MARGIN:.0%} and >= {ABS_MARGIN_DB} dB lower;"
                f" no noise level for this cost){worse}")  # fmt: skip
    L = test["heldout_noise_level_db"]
    parts = [f"{head}; held-out noise level {L:.3f} dB (n = {test['heldout_n_eff']:.0f})"]
    if test.get("gap_not_lower"):
        parts.append("its weighted gap on all data is not lower than the base's")
    if not test["base_above_noise"]:
        parts.append(f"the base is at the noise level ({test['base_over_noise']:.3f}x)")
    if test["lr"] <= test["lr_threshold"]:
        parts.append(
            f"improvement not significant (LR {test['lr']:.1f} <= {test['lr_threshold']:.1f})"
        )
    elif test["excess_share"] < MIN_EXCESS_SHARE:
        parts.append(f"removes {test['excess_share']:.0%} of the excess over the noise (needs"
                     f" >= {MIN_EXCESS_SHARE:.0%})")  # fmt: skip
    pair = test.get("joint")
    if test.get("accepted") and pair:
        parts.append(f"accepted with {pair['with']}, the next step's effect: together they"
                     f" remove {pair['excess_share']:.0%} of it (LR {pair['lr']:.1f} >"
                     f" {pair['lr_threshold']:.1f})")  # fmt: skip
    return "; ".join(parts)


def accept(
    candidate_score: float, baseline_score: float, n_new: int = 1,
    noise: NoiseReference | None = None,
) -> bool:  # fmt: skip
    """The verdict rule of the module docstring."""
    return bool(tests(candidate_score, baseline_score, n_new, noise)["accepted"])


def clearly_better(candidate_score: float, baseline_score: float) -> bool:
    """The rule without a noise reference (the margins of the module docstring)."""
    return accept(candidate_score, baseline_score, 1, None)


def indistinguishable(scores: Sequence[float], test: dict[str, Any]) -> list[tuple[int, float]]:
    """The refits the data cannot tell from the best (module docstring): ``(j, Λⱼ)`` for
    each ``j ≥ 1`` of ``scores`` (held-out scores [dB], best first) whose score the best
    one's does not significantly beat, with ``Λⱼ = n (sⱼ² − s₁²) / L²`` (NaN without a noise
    reference); ``test`` is the step's :func:`tests` of the best (its ``L`` and ``n``)."""
    if not scores or not math.isfinite(scores[0]):
        return []
    s1 = scores[0]
    out = []
    for j, sj in enumerate(scores[1:], start=1):
        if not math.isfinite(sj):
            continue
        if test.get("rule") == "noise":
            lr = test["heldout_n_eff"] * (sj**2 - s1**2) / test["heldout_noise_level_db"] ** 2
            if lr <= lr_threshold(1):
                out.append((j, lr))
        elif not clearly_better(s1, sj):
            out.append((j, math.nan))
    return out


def rank(scores: Sequence[float]) -> list[int]:
    """Indices sorted best (lowest score) first; non-finite scores last."""
    return sorted(range(len(scores)), key=lambda i: (not math.isfinite(scores[i]), scores[i]))
