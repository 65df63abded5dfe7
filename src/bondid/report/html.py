"""The report's rendering layer: the jinja2 templates (package data, autoescaped), number
formatting and PNG embedding. The page has no scripts, fonts or external references."""

from __future__ import annotations

import base64
import functools
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_END = b"IEND\xaeB`\x82"  # the IEND chunk a complete PNG ends with


def fmt(value: Any, digits: int = 4) -> str:
    """A short rendering of a JSON scalar (None → "—", floats to ``digits`` significant
    digits, ±inf as ∞); lists and objects as ``k = v`` text, never as a Python repr."""
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
        return ", ".join(f"{k} = {fmt(v, digits)}" for k, v in value.items()) or "—"
    if isinstance(value, list | tuple):
        if len(value) > 8:
            return f"{len(value)} values"
        return ", ".join(fmt(v, digits) for v in value) or "—"
    return str(value)


def percent(fraction: Any, spec: str = ".1f") -> str:
    """A fraction as a percentage (``0.786`` → ``78.6 %``; "—" when not a finite number)."""
    if isinstance(fraction, bool) or not isinstance(fraction, int | float):
        return "—"
    if not math.isfinite(fraction):
        return fmt(float(fraction))
    return f"{100 * fraction:{spec}} %"


def png_problem(raw: bytes) -> str | None:
    """Why ``raw`` is not a complete PNG (None when it is one)."""
    if not raw.startswith(PNG_SIGNATURE):
        return "not a PNG file"
    if not raw.rstrip(b"\0").endswith(PNG_END):
        return "truncated PNG (no IEND chunk: its run was killed while writing?)"
    return None


@dataclass
class Figure:
    """A PNG for the page: its data URI, or the reason it is not embedded."""

    caption: str
    uri: str | None = None
    problem: str | None = None


def png_figure(path: Path, caption: str) -> Figure:
    """The PNG at ``path`` as a base64 data URI; a corrupt or truncated file is named in a
    warning instead (and on stderr), never embedded."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        problem: str | None = f"unreadable ({exc.strerror})"
    else:
        problem = png_problem(raw)
    if problem is not None:
        print(f"warning: {path}: {problem}; not embedded", file=sys.stderr)
        return Figure(caption, problem=problem)
    return Figure(caption, uri="data:image/png;base64," + base64.b64encode(raw).decode("ascii"))


@functools.cache
def environment() -> Any:
    """The jinja2 environment over the package's ``templates`` folder (autoescaped)."""
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("bondid.report", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["num"] = fmt
    env.filters["pct"] = percent
    return env


def render(template: str, **context: Any) -> str:
    """Template ``template`` rendered with ``context``."""
    return str(environment().get_template(template).render(**context))
