"""The human summary of a diagnosis (what ``python -m bondid.diagnose`` prints), from the
content of ``diagnosis.json`` (:func:`.report.to_json_dict`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from .scoring import Z

if TYPE_CHECKING:
    from .pipeline import Diagnosis


def summary(diag: Diagnosis, content: dict[str, Any]) -> str:
    """A short human summary: gap, where, verdict, how far it shrinks."""
    st = content["stages"]
    g = content["gap"]
    v = content["verdict"]
    lines = [f"answer: {v['outcome_text']}"] if v.get("outcome_text") else []
    lines += [
        f"gap (db_rms over {len(diag.channels)} channels): nominal {st['nominal']['db_rms']:.2f}"
        f" dB -> after parameter refit {g['db_rms']:.2f} dB",
    ]
    ch = sorted(g["by_channel"].items(), key=lambda kv: -(kv[1] or 0))[:3]
    lines.append("  worst channels: " + ", ".join(f"{c} {v:.2f} dB" for c, v in ch))
    bands = sorted(g["by_band"], key=lambda b: -(b["db_rms"] or 0))[:3]
    lines.append(
        "  worst bands: "
        + ", ".join(f"{b['f_lo_hz']:.0f}-{b['f_hi_hz']:.0f} Hz {b['db_rms']:.2f} dB" for b in bands)
    )
    miss = [m for m in g["modes"] if m["status"] == "missing"]
    spur = [m for m in g["modes"] if m["status"] == "spurious"]
    if g.get("modes_error"):
        lines.append(f"  modes: {g['modes_error']}")
    elif g["modes"]:
        lines.append(
            f"  modes: {len(g['modes']) - len(miss) - len(spur)} paired, missing in the model at "
            + (", ".join(f"{m['f_measured_hz']:.0f}" for m in miss) or "-")
            + " Hz, spurious at "
            + (", ".join(f"{m['f_model_hz']:.0f}" for m in spur) or "-")
            + " Hz"
        )
    first = [c for c in content["candidates"] if c.get("step") == 1]
    n_ref = sum(1 for c in first if c.get("refitted"))
    if first and not n_ref:
        lines += _screened_only(first, content)
    else:
        lines.append(
            f"candidates: {len(first)} screened, {n_ref} refitted (held-out score, dB; lower"
            " is better):"
        )
        lines.append(f"  {'parameter refit only':42s} {diag.baseline_score:8.3f}")
    for c in [c for c in first if c.get("refitted")][:5]:
        lab = _label(c)
        sc = c["score"]
        z = c.get("strength_z")
        # a refit whose strength the data leave open is not the verdict's to take (scoring)
        why = f"  (strength undetermined: z = {z:.2g} < {Z:g})" if z is not None and z < Z else ""
        lines.append(f"  {lab:42s} {sc if sc is not None else float('nan'):8.3f}{why}")
    if v["effect"] == "none":
        lines.append(f"verdict: none — {v['reason']}")
    else:
        pars = ", ".join(f"{n} = {p['value']:.4g}" for n, p in v["parameters"].items())
        tentative = " (tentative: it leaves most of the excess in place)" if v.get(
            "grade") == "tentative" else ""  # fmt: skip
        lines.append(
            f"verdict: {v['effect']} at {v['location']} ({pars}); gap {g['db_rms']:.2f} ->"
            f" {st['effect']['db_rms']:.2f} dB, gap_closed {v['gap_closed']:.2f}{tentative}"
        )
        ties = [f"{_label(t)} ({t['score']:.3f} dB)" for t in v["indistinguishable_from"]]
        if ties:
            lines.append("  the data do not tell it from: " + ", ".join(ties))
    if content.get("effects"):
        lines.append("effects: " + steps_line(g["db_rms"], content["effects"]))
    lines += preferred_lines(content.get("effects") or [])
    lines += caveat_lines(content.get("effects") or [])
    lines += dropped_lines(content.get("dropped") or [])
    ff = content.get("final_fit")
    if ff:
        lines.append(f"final model refitted on all data (final.urdf): {ff['note']}")
        lines += [f"  {e['effect']}@{e['location']}: {e['detail']}"
                  for e in ff.get("effects") or [] if e.get("detail")]  # fmt: skip
    rem = content.get("remainder") or {}
    if rem.get("summary"):
        lines.append("what the final model still misses:")
        lines += [f"  {x}" for x in rem["summary"]]
    lines.append(f"time {diag.wall_s:.1f} s")
    return "\n".join(lines)


def _screened_only(first: Sequence[dict[str, Any]], content: dict[str, Any]) -> list[str]:
    """The candidate lines of a first step that refitted none (its base at the held-out noise
    level, :func:`.decide.at_level_test`): the best five by the screening's training figure
    [dB], beside the parameter refit's own training figure."""
    train = (content.get("refit") or {}).get("train_weighted_rms")
    out = [
        f"candidates: {len(first)} screened, none refitted: the parameter refit is at the"
        " held-out noise level (training figure after one screening step, dB):"
    ]
    if train is not None:
        out.append(f"  {'parameter refit only':42s} {train:8.3f}")
    for c in first[:5]:
        db = c.get("screening_db")
        out.append(f"  {_label(c):42s} {db if db is not None else float('nan'):8.3f}")
    return out


def _label(c: dict[str, Any]) -> str:
    """``effect@location`` (``effect`` alone without a location)."""
    return f"{c['effect']}@{c['location']}" if c.get("location") else str(c["effect"])


def preferred_lines(effects: Sequence[dict[str, Any]]) -> list[str]:
    """One line per effect named for a better-scoring equivalent FRF modifier with more
    parameters (``test.preferred_over``, :mod:`.parsimony`)."""
    out = []
    for e in effects:
        p = (e.get("test") or {}).get("preferred_over")
        if p:
            out.append(
                f"  step {e['step']}: {_label(e)} named for {_label(p)} ({p['score']:.3f} dB):"
                f" the data do not tell them apart and it has fewer parameters"
            )
    return out


def caveat_lines(effects: Sequence[dict[str, Any]]) -> list[str]:
    """One line per caveat of a kept effect (``caveats`` of diagnosis.json, :mod:`.caveats`)."""
    return [f"  caveat, {_label(e)}: {c['text']}" for e in effects for c in e.get("caveats") or []]


def dropped_lines(dropped: Sequence[dict[str, Any]]) -> list[str]:
    """One line per effect the backward elimination dropped (``dropped`` of diagnosis.json)."""
    return [
        f"  dropped: {_label(x)} (accepted at step {x['step']}; redundant once the others are"
        f" in: held-out {x['score_without']:.3f} dB without it, {x['score_with']:.3f} with it)"
        for x in dropped
    ]


def steps_line(refit_db: float, effects: Sequence[dict[str, Any]]) -> str:
    """``parameters 7.80 → +joint compliance 3.10 → +actuator lag 1.90 dB`` (the weighted
    gap after the parameter refit and after each accepted effect)."""
    parts = [f"parameters {refit_db:.2f}"]
    for e in effects:
        name = str(e["effect"]).replace("_", " ")
        at = f" at {e['location']}" if e.get("location") else ""
        parts.append(f"+{name}{at} {e['db_rms_after']:.2f}")
    return " → ".join(parts) + " dB"
