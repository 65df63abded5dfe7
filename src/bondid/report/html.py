"""Small HTML building blocks for the offline report (no external CSS, JS or fonts)."""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

STYLE = """
body{font:15px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;color:#222;
background:#fafafa}
main{max-width:1150px;margin:0 auto;padding:16px 24px 48px}
h1{font-size:1.6em;margin:.4em 0}h2{border-bottom:2px solid #ccd;padding-bottom:.2em;
margin-top:1.8em}h3{margin-top:1.2em}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em;background:#fff}
th,td{border:1px solid #ccd;padding:3px 8px;text-align:right;vertical-align:top}
th{background:#eef;text-align:center}td.l,th.l{text-align:left}
tr.flag td{background:#fff4e0}
.note{color:#666;font-style:italic}.warn{color:#a40}
.verdict{font-size:1.15em;background:#eef6ee;border:1px solid #9c9;padding:8px 12px;
display:inline-block;border-radius:4px}
figure{margin:.8em 0;background:#fff;border:1px solid #dde;padding:6px;display:inline-block;
max-width:100%}figure img{max-width:100%;height:auto}figcaption{font-size:.85em;color:#555}
nav a{margin-right:1em}code{background:#eee;padding:0 3px}
"""


def esc(value: object) -> str:
    """HTML-escaped text of ``value``."""
    return html.escape(str(value), quote=True)


def fmt(value: Any, digits: int = 4) -> str:
    """A short, escaped rendering of a JSON scalar (None → "—", floats to ``digits``)."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "NaN"
        if math.isinf(value):
            return "∞" if value > 0 else "−∞"
        return f"{value:.{digits}g}"
    if isinstance(value, Mapping):
        return esc(", ".join(f"{k}={_plain(v)}" for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        if len(value) > 8:
            return esc(f"[{len(value)} values]")
        return esc(", ".join(_plain(v) for v in value))
    return esc(value)


def _plain(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, (list, tuple)):
        return (
            f"[{len(value)} values]"
            if len(value) > 8
            else "[" + ", ".join(map(_plain, value)) + "]"
        )
    return str(value)


def table(
    header: Sequence[str],
    rows: Iterable[Sequence[str]],
    *,
    left: Iterable[int] = (0,),
    flagged: Iterable[int] = (),
) -> str:
    """An HTML table; cells are already-escaped HTML. ``left``: left-aligned column indices;
    ``flagged``: row indices to highlight."""
    lset, fset = set(left), set(flagged)
    head = "".join(
        f'<th class="l">{h}</th>' if i in lset else f"<th>{h}</th>" for i, h in enumerate(header)
    )
    body = []
    for r, row in enumerate(rows):
        cells = "".join(
            f'<td class="l">{c}</td>' if i in lset else f"<td>{c}</td>" for i, c in enumerate(row)
        )
        body.append(f'<tr class="flag">{cells}</tr>' if r in fset else f"<tr>{cells}</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def key_values(items: Mapping[str, Any]) -> str:
    """A two-column table of scalars."""
    return table(["item", "value"], [[esc(k), fmt(v)] for k, v in items.items()])


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_END = b"IEND\xaeB`\x82"  # the IEND chunk a complete PNG ends with


def png_problem(raw: bytes) -> str | None:
    """Why ``raw`` is not a complete PNG (None when it is one)."""
    if not raw.startswith(PNG_SIGNATURE):
        return "not a PNG file"
    if not raw.rstrip(b"\0").endswith(PNG_END):
        return "truncated PNG (no IEND chunk: its run was killed while writing?)"
    return None


def png_figure(path: Path, caption: str) -> str:
    """The PNG at ``path`` embedded as a base64 data URI in a ``<figure>``; a corrupt or
    truncated file is named in a warning instead (and on stderr), never embedded."""
    import sys

    try:
        raw = path.read_bytes()
    except OSError as exc:
        problem: str | None = f"unreadable ({exc.strerror})"
    else:
        problem = png_problem(raw)
    if problem is not None:
        print(f"warning: {path}: {problem}; not embedded", file=sys.stderr)
        return f'<p class="warn">{esc(caption)}: {esc(problem)}; not embedded</p>'
    data = base64.b64encode(raw).decode("ascii")
    return (
        f'<figure><img alt="{esc(caption)}" src="data:image/png;base64,{data}">'
        f"<figcaption>{esc(caption)}</figcaption></figure>"
    )


def note(text: str) -> str:
    return f'<p class="note">{esc(text)}</p>'


def page(title: str, body: str) -> str:
    """The whole document: inline style, no scripts, no external references."""
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width,initial-scale=1">'
        f"<title>{esc(title)}</title><style>{STYLE}</style></head>"
        f"<body><main>{body}</main></body></html>\n"
    )


def generic_json(data: Any, depth: int = 0) -> str:
    """A readable rendering of arbitrary JSON (tables for lists of records, long arrays
    summarised) — for result files whose keys the spec does not fix."""
    if isinstance(data, Mapping):
        scalars = {k: v for k, v in data.items() if not isinstance(v, (Mapping, list))}
        parts = [key_values(scalars)] if scalars else []
        for k, v in data.items():
            if isinstance(v, (Mapping, list)) and depth < 3:
                parts.append(f"<h4>{esc(k)}</h4>" + generic_json(v, depth + 1))
            elif isinstance(v, (Mapping, list)):
                parts.append(f"<p><b>{esc(k)}</b>: {fmt(v)}</p>")
        return "".join(parts)
    if isinstance(data, list):
        if data and all(isinstance(r, Mapping) for r in data):
            cols: list[str] = []
            for r in data:
                cols += [str(c) for c in r if str(c) not in cols]
            shown = data[:200]
            out = table(
                [esc(c) for c in cols],
                [[fmt(r.get(c)) for c in cols] for r in shown],
                left=range(len(cols)) if len(cols) < 2 else (0,),
            )
            if len(data) > len(shown):
                out += note(f"{len(data) - len(shown)} more rows not shown")
            return out
        if data and all(isinstance(r, list) for r in data):
            return f"<p>{esc(f'{len(data)} × {len(data[0])} array')}</p>"
        return f"<p>{fmt(data)}</p>"
    return f"<p>{fmt(data)}</p>"
