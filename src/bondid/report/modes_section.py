"""The report's section for ``modes.json``: the mode table, linked to the animation pages
written beside it.

The file comes from another command, possibly of another version: any shape is read, and
an unexpected one degrades to a note, never raises.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .blocks import Block, Cell, Row, Table, note, table_block, text
from .headline import records
from .html import fmt


def modes_section(modes: Any, modes_dir: Path, out_dir: Path) -> list[Block]:
    """The mode table with relative links to the animation pages found next to modes.json."""
    if not isinstance(modes, Mapping):
        return [note("modes.json is not a JSON object; skipped")]
    out = []
    op = modes.get("operating_point")
    if isinstance(op, Mapping):
        where = ", ".join(f"{k} = {fmt(v)}" for k, v in op.items()) or "neutral (q = 0)"
        out.append(text(f"Operating point: {where}."))
    scene = modes_dir / "modes.html"
    if scene.is_file():
        out.append(
            Block(
                "link", "Mode scene (Meshcat, opens offline): modes.html", href=_rel(scene, out_dir)
            )
        )
    entries = records(modes.get("modes"))
    if not entries:
        return [*out, note("modes.json has no mode list")]
    fitted = modes.get("fitted")
    fmodes = records(fitted.get("modes")) if isinstance(fitted, Mapping) else []
    header = ["#", "frequency [Hz]", "damping ratio ζ", "kind", "main DOF"]
    if fmodes:
        header.append("fitted model [Hz]")
    header.append("animation")
    rows = []
    for i, m in enumerate(entries):
        row = [
            Cell(fmt(m.get("index", i + 1))),
            Cell(fmt(m.get("f_hz"), 6)),
            Cell(fmt(m.get("zeta"))),
            Cell(str(m.get("kind", "")), left=True),
            Cell(str(m.get("dominant_dof", "")), left=True),
        ]
        if fmodes:
            row.append(Cell(fmt(fmodes[i].get("f_hz"), 6) if i < len(fmodes) else "—"))
        link = m.get("html")
        if isinstance(link, str) and (modes_dir / link).is_file():
            row.append(Cell(link, left=True, href=_rel(modes_dir / link, out_dir)))
        else:
            row.append(Cell(f"{link} (missing)" if isinstance(link, str) else "", left=True))
        rows.append(Row(row))
    out.append(table_block(Table(header, rows, left=(3, 4, len(header) - 1))))
    return out


def _rel(target: Path, out_dir: Path) -> str:
    return Path(os.path.relpath(target.resolve(), out_dir.resolve())).as_posix()
