"""The report's section for ``fleet.json``: counts, the parameters over the machines,
outliers, failed machines and the effects found.

The file comes from another command, possibly of another version: any shape is read, and
an unexpected one degrades to a note, never raises.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .blocks import Block, Row, Table, cells, heading, note, summary_table, table_block
from .headline import records, value_of
from .html import fmt, percent


def fleet_section(fleet: Any) -> list[Block]:
    """Counts, per-parameter statistics, outliers, failed machines and effects of fleet.json."""
    if not isinstance(fleet, Mapping):
        return [note("fleet.json is not a JSON object; skipped")]
    out = []
    counts = fleet.get("counts")
    if isinstance(counts, Mapping):
        out.append(summary_table([(str(k).replace("_", " "), fmt(v)) for k, v in counts.items()]))
    params = records(fleet.get("parameters"))
    if params:
        rows = [
            Row(
                cells(
                    str(p.get("name", "?")),
                    fmt(p.get("n")),
                    fmt(p.get("median")),
                    percent(value_of(p, "robust_rel_spread"), ".3g"),
                    fmt(p.get("min")),
                    fmt(p.get("max")),
                )
            )
            for p in params
        ]
        head = ["parameter", "machines", "median", "robust spread", "min", "max"]
        out += [heading("Parameters over the fleet"), table_block(Table(head, rows))]
    out.append(heading("Outliers"))
    if fleet.get("outlier_rule"):
        out.append(note(f"rule: {fleet['outlier_rule']}"))
    rows = [
        Row(
            cells(
                str(o.get("machine")),
                str(o.get("parameter")),
                fmt(o.get("value")),
                str(o.get("reason", "")),
                left=(0, 1, 3),
            )
        )
        for o in records(fleet.get("outliers"))
    ]
    head = ["machine", "parameter", "value", "reason"]
    out.append(table_block(Table(head, rows, left=(0, 1, 3))) if rows else note("no outlier"))
    failed = [m for m in records(fleet.get("machines")) if m.get("status") != "ok"]
    if failed:
        rows = [
            Row(cells(str(m.get("id")), str(m.get("reason") or ""), left=(0, 1))) for m in failed
        ]
        out += [
            heading("Failed machines"),
            table_block(Table(["machine", "reason"], rows, left=(0, 1))),
        ]
    effects = fleet.get("effects")
    if isinstance(effects, Mapping) and isinstance(effects.get("counts"), Mapping):
        rows = [Row(cells(str(k), fmt(v))) for k, v in effects["counts"].items()]
        out += [
            heading("Effects found (diagnosis)"),
            table_block(Table(["effect", "machines"], rows)),
        ]
    return out
