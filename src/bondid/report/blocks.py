"""What the report's templates draw: tables, notes, figures and sections as plain dataclasses.

The section builders (:mod:`.fit_section`, :mod:`.diagnosis_section`, :mod:`.fleet_section`,
:mod:`.modes_section`, :mod:`.sensitivity_section`) turn result files into these;
``templates/blocks.html.j2`` renders them. Every cell holds text (the template escapes it),
never markup and never a Python repr of a dict or list.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .html import Figure


@dataclass
class Cell:
    """One table cell: its text, left-aligned or not, an optional link (relative URL)."""

    text: str
    left: bool = False
    href: str = ""


@dataclass
class Row:
    """A table row; ``kind`` ``"flag"`` (highlighted) or ``"muted"`` (greyed: left out)."""

    cells: list[Cell]
    kind: str = ""


@dataclass
class Table:
    """A table with human headings (units in brackets) and footnotes below it."""

    header: list[str]
    rows: list[Row]
    footer: list[str] = field(default_factory=list)
    left: tuple[int, ...] = (0,)


@dataclass
class Block:
    """One item of a section's body.

    ``kind``: ``"heading"``, ``"text"``, ``"note"``, ``"warn"``, ``"table"``, ``"figures"``,
    ``"list"`` (``items``) or ``"link"`` (``text`` and ``href``)."""

    kind: str
    text: str = ""
    table: Table | None = None
    figures: list[Figure] = field(default_factory=list)
    items: list[str] = field(default_factory=list)
    href: str = ""


@dataclass
class Section:
    """A section of the page: its anchor, heading, the file it came from and its body."""

    key: str
    title: str
    blocks: list[Block] = field(default_factory=list)
    source: str | None = None


def heading(text: str) -> Block:
    return Block("heading", text)


def text(value: str) -> Block:
    return Block("text", value)


def note(value: str) -> Block:
    return Block("note", value)


def warn(value: str) -> Block:
    return Block("warn", value)


def table_block(t: Table) -> Block:
    return Block("table", table=t)


def cells(*values: str, left: tuple[int, ...] = (0,)) -> list[Cell]:
    """Cells of ``values``, the columns in ``left`` left-aligned."""
    return [Cell(v, left=i in left) for i, v in enumerate(values)]


def summary_table(items: list[tuple[str, str]]) -> Block:
    """A two-column table of ``(what, value)`` rows, both left-aligned, without a header."""
    return table_block(Table([], [Row(cells(k, v, left=(0, 1))) for k, v in items], left=(0, 1)))
