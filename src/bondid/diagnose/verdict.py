"""The verdict and the accepted effects of ``diagnosis.json`` (``verdict``, ``effects``,
``dropped``), from the search's steps and the backward elimination (:mod:`.prune`).

The effects listed are those the elimination kept, in the order the search accepted them,
each with the figures of the model with the kept effects up to it; the verdict is the first.
An effect the elimination dropped is listed under ``dropped`` with the figures that dropped
it, never among ``effects``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from . import scoring
from .caveats import caveats
from .job import JobResult
from .outcome import grade
from .prune import Kept
from .scoring import gap_closed

if TYPE_CHECKING:
    from .pipeline import Diagnosis


def kept_effects(diag: Diagnosis) -> list[Kept]:
    """The effects the diagnosis keeps (:attr:`.prune.Pruning.kept`; without an elimination,
    every step's winner with the step's own figures)."""
    if diag.pruning is not None:
        return diag.pruning.kept
    return [Kept(s.index, s.winner, s.scores[0], s.base_score, s.test)
            for s in diag.steps if s.winner is not None]  # fmt: skip


def effect_params(model: JobResult, j: int) -> tuple[dict[str, float], dict[str, float]]:
    """Values and std (SI) of the ``j``-th effect of ``model``'s chain: its parameters come
    after the nominal ones, in the chain's order."""
    chain = model.chain
    n = len(chain[j].parameters)
    k = len(model.names) - model.n_new + sum(len(c.parameters) for c in chain[:j])
    names = model.names[k : k + n]
    vals = {a: float(v) for a, v in zip(names, model.values[k : k + n], strict=True)}
    if not len(model.std):
        return vals, {}
    return vals, {a: float(v) for a, v in zip(names, model.std[k : k + n], strict=True)}


def tied(step: Any) -> list[dict[str, Any]]:
    """The step's refits the data cannot tell from its best (:func:`.scoring.
    indistinguishable`) and whose effect strength they determine: effect, location, held-out
    score [dB] and ``lr`` (Λ, null without a noise reference), best score first."""
    out = []
    for j, lr in scoring.indistinguishable(step.scores, step.test):
        r = step.results[j]
        if not scoring.determined(r):
            continue
        out.append({"effect": r.effect, "location": r.location, "score": step.scores[j],
                    "lr": lr if math.isfinite(lr) else None})  # fmt: skip
    return out


def _detail(k: Kept, j: int) -> Any:
    """The variant of the ``j``-th effect of a kept model (e.g. a pivot): the search step's
    note for its own winner, else the effect's description as refitted."""
    return (k.model.variant or None) if k.forward else k.model.chain[j].description


def _params(k: Kept, j: int) -> dict[str, Any]:
    vals, std = effect_params(k.model, j)
    return {n: {"value": v, "std": std.get(n)} for n, v in vals.items()}


def _caveats(diag: Diagnosis, k: Kept, j: int, params: dict[str, Any]) -> list[dict[str, Any]]:
    """The ``j``-th effect's caveats (:mod:`.caveats`) at its fitted ``params`` (as
    :func:`_params` gives them), on the channels of every data set."""
    channels = [(tuple(d.outputs), tuple(d.inputs)) for d in diag.datasets]
    by_file = diag.channels_by_file or {}
    used = [by_file.get(d.source or "", diag.channels) for d in diag.datasets]
    return caveats(k.model.chain[j], [p["value"] for p in params.values()], channels,
                   k.model.full_H or None, used)  # fmt: skip


def effect_entries(diag: Diagnosis, before: float) -> list[dict[str, Any]]:
    """``effects`` of diagnosis.json (spec extension): the kept effects in the order added,
    each with its parameters and the gap after it (the kept effects up to it in the model);
    ``refitted_without_dropped``: its figures are those of a refit without an effect the
    elimination dropped (the step's own otherwise)."""
    out = []
    for j, k in enumerate(kept_effects(diag)):
        c = k.model.chain[j]
        step = diag.steps[k.step]
        params = _params(k, j)
        out.append({
            "step": k.step + 1, "effect": c.effect, "location": c.location,
            "detail": _detail(k, j),
            "parameters": params,
            "db_rms_after": k.model.db_rms, "heldout_db_rms_after": k.model.heldout_db_rms,
            "gap_closed": gap_closed(before, k.model.db_rms), "score": k.score,
            "score_before": k.score_before, "test": k.test,
            "refitted_without_dropped": not k.forward,
            "grade": grade(k.test),
            "indistinguishable_from": tied(step),
            "caveats": _caveats(diag, k, j, params),
        })  # fmt: skip
    return out


def dropped_entries(diag: Diagnosis) -> list[dict[str, Any]]:
    """``dropped`` of diagnosis.json (spec extension): each accepted effect the backward
    elimination dropped (:mod:`.prune`), with the held-out scores [dB] of the model with it
    and of the refit without it and the rule's figures."""
    if diag.pruning is None:
        return []
    return [
        {"step": d.step + 1, "effect": d.candidate.effect, "location": d.candidate.location,
         "detail": d.candidate.description, "round": d.round, "score_with": d.score_with,
         "score_without": d.score_without, "test": d.test,
         "reason": scoring.reason(d.test, d.score_with, d.score_without)
         + " (the model with it against the refit without it)"}
        for d in diag.pruning.dropped
    ]  # fmt: skip


def verdict_entry(
    diag: Diagnosis, before: float, nominal: float, where: dict[str, Any] | None
) -> dict[str, Any]:
    """``verdict`` of diagnosis.json: the first kept effect, or ``none`` and why. ``before``,
    ``nominal``: the weighted gaps [dB] of the parameter refit and the nominal model;
    ``where``: the gap (by channel and band) of the model with the verdict's effect."""
    kept = kept_effects(diag)
    out = getattr(diag, "outcome", None)
    answer = out.as_dict() if out is not None else {}
    if kept:
        k = kept[0]
        c = k.model.chain[0]
        params = _params(k, 0)
        verdict: dict[str, Any] = {
            "effect": c.effect,
            "location": c.location,
            "detail": _detail(k, 0),
            "gap_closed": gap_closed(before, k.model.db_rms),
            "gap_closed_total": gap_closed(nominal, k.model.db_rms),
            "parameters": params,
            "reason": scoring.reason(k.test, k.score, k.score_before)
            + " (against the parameter refit)",
            "where": where,
            "indistinguishable_from": tied(diag.steps[k.step]),
            "caveats": _caveats(diag, k, 0, params),
            "grade": grade(k.test),
            **answer,
        }
        if not k.forward:
            verdict["reason"] += (
                f"; accepted at step {k.step + 1}, the effect of an earlier step dropped by the"
                " backward elimination (see 'dropped')"
            )
        return verdict
    best = diag.scores[0] if diag.scores else math.nan
    return {
        "effect": "none",
        "location": None,
        "gap_closed": 0.0,
        **answer,
        "reason": "no candidate passes the verdict rule against the parameter refit: "
        + (
            scoring.reason(diag.steps[0].test, best, diag.baseline_score)
            if diag.steps and diag.steps[0].test
            else f"best {best:.3f} dB"
        ),
    }
