"""The report's section for ``diagnosis.json``: the effects found, the gap left and the
candidates tried.

The file comes from another command, possibly of another version: any shape is read, and
an unexpected one degrades to a note, never raises.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..jsonsafe import number
from .blocks import Block, Row, Table, cells, heading, note, table_block, text
from .headline import records, value_of
from .html import fmt, percent


def diagnosis_section(diag: Any) -> list[Block]:
    """Verdict reason, effects (kept and dropped), the gap tables and the candidates."""
    if not isinstance(diag, Mapping):
        return [note("diagnosis.json is not a JSON object; skipped")]
    out: list[Block] = []
    verdict = diag.get("verdict")
    if isinstance(verdict, Mapping) and verdict.get("reason"):
        out.append(text(f"Why: {verdict['reason']}"))
    effects, dropped = records(diag.get("effects")), records(diag.get("dropped"))
    for e in effects:
        for c in records(e.get("caveats")):
            if isinstance(c.get("text"), str):
                where = f" at {e['location']}" if e.get("location") else ""
                out.append(note(f"Caveat on {e.get('effect', '?')}{where}: {c['text']}"))
    if len(effects) > 1 or dropped:
        rows = [
            Row(
                cells(
                    str(e.get("effect", "?")),
                    fmt(e.get("location")),
                    fmt(e.get("step")),
                    fmt(e.get("db_rms_after")),
                    percent(value_of(e, "gap_closed")),
                    left=(0, 1),
                )
            )
            for e in effects
        ]
        head = ["effect", "where", "search step", "gap after [dB]", "gap closed"]
        out += [heading("Effects found, in the order added"), table_block(Table(head, rows))]
    if dropped:
        rows = [
            Row(
                cells(
                    str(d.get("effect", "?")),
                    fmt(d.get("location")),
                    fmt(d.get("step")),
                    fmt(d.get("score_with")),
                    fmt(d.get("score_without")),
                    left=(0, 1),
                )
            )
            for d in dropped
        ]
        head = [
            "effect",
            "where",
            "accepted at step",
            "held-out score with it [dB]",
            "without it [dB]",
        ]
        out += [heading("Accepted, then dropped as redundant"), table_block(Table(head, rows))]
    gap = diag.get("gap")
    if isinstance(gap, Mapping):
        out += _gap_blocks(gap)
    cands = records(diag.get("candidates"))
    if cands:
        out += [heading("Candidates tried (best first)"), table_block(_candidate_table(cands))]
    return out


def _gap_blocks(gap: Mapping[str, Any]) -> list[Block]:
    """The gap after the parameter refit: overall, by channel, by band and by mode."""
    out = []
    db = value_of(gap, "db_rms")
    if db is not None:
        out.append(
            text(
                f"Model–measurement gap after the parameter refit: {db:.3g} dB"
                " (information-weighted, all used channels)."
            )
        )
    by_ch = gap.get("by_channel")
    if isinstance(by_ch, Mapping) and by_ch:
        rows = [Row(cells(str(k), fmt(number(v), 3))) for k, v in by_ch.items()]
        foot = ["OUT.IN = the response at OUT to the excitation at IN."]
        out += [heading("Gap by channel"), table_block(Table(["channel", "gap [dB]"], rows, foot))]
    bands = records(gap.get("by_band"))
    if bands:
        rows = [
            Row(cells(*(fmt(value_of(b, k), 4) for k in ("f_lo_hz", "f_hi_hz", "db_rms")), left=()))
            for b in bands
        ]
        head = ["from [Hz]", "to [Hz]", "gap [dB]"]
        out += [heading("Gap by frequency band"), table_block(Table(head, rows, left=()))]
    modes = records(gap.get("modes"))
    if modes:
        rows = [
            Row(
                cells(
                    fmt(value_of(m, "f_measured_hz"), 5),
                    fmt(value_of(m, "f_model_hz"), 5),
                    str(m.get("status", "")),
                    left=(2,),
                ),
                kind="" if m.get("status") == "paired" else "flag",
            )
            for m in modes
        ]
        head = ["measured [Hz]", "model [Hz]", "status"]
        foot = [
            "paired: a model mode matches; missing: measured, not in the model;"
            " spurious: in the model, not measured."
        ]
        out += [heading("Modes: measured and model"), table_block(Table(head, rows, foot, (2,)))]
    return out


def _candidate_table(cands: list[Mapping[str, Any]]) -> Table:
    """One row a candidate effect, in the order of diagnosis.json (best first)."""
    rows = []
    for c in cands:
        params = c.get("parameters")
        shown = fmt(params, 3) if isinstance(params, Mapping) else fmt(params)
        rows.append(
            Row(
                cells(
                    str(c.get("effect", "?")),
                    fmt(c.get("location")),
                    shown,
                    fmt(value_of(c, "db_rms_after"), 3),
                    percent(value_of(c, "gap_closed")),
                    fmt(value_of(c, "heldout_db_rms_after"), 3),
                    fmt(value_of(c, "score"), 3),
                    left=(0, 1, 2),
                )
            )
        )
    head = [
        "effect",
        "where",
        "its parameters (SI)",
        "gap after [dB]",
        "gap closed",
        "held-out gap after [dB]",
        "score [dB]",
    ]
    foot = [
        "— in the figures: screened, not refitted (a better candidate of the same step was"
        " refitted instead). score: the held-out gap with a penalty per added parameter."
    ]
    return Table(head, rows, foot, left=(0, 1, 2))
