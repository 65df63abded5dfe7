"""Python warnings as the commands print them: one line each, paths shortened.

``warning: [Category: ]message (package/module.py:LINE)`` on stderr, instead of Python's two
lines with the full install path and the source line. A path inside the message is shortened
the same way (the current folder's prefix dropped, an installed package's path cut to the
package), so it reads as the user typed it.
"""

from __future__ import annotations

import os
import sys
import sysconfig
import warnings
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any, TextIO


def _prefixes() -> list[str]:
    """Folder prefixes to drop: the current folder, site-packages, the standard library."""
    out = [os.getcwd() + os.sep]
    for key in ("purelib", "platlib", "stdlib"):
        p = sysconfig.get_paths().get(key)
        if p:
            out.append(p.rstrip(os.sep) + os.sep)
    src = str(Path(__file__).resolve().parents[1]) + os.sep  # a source checkout's src/
    out.append(src)
    return sorted(set(out), key=len, reverse=True)


def shorten(text: str) -> str:
    """``text`` with the long folder prefixes of :func:`_prefixes` dropped."""
    for p in _prefixes():
        text = text.replace(p, "")
    return text


def format_line(message: Warning | str, category: type[Warning], filename: str, lineno: int) -> str:
    """The one line printed for a warning (module docstring)."""
    kind = "" if category is UserWarning else f"{category.__name__}: "
    body = " ".join(str(message).split())
    return f"warning: {kind}{shorten(body)} ({shorten(filename)}:{lineno})"


def show_warning(
    message: Warning | str, category: type[Warning], filename: str, lineno: int,
    file: TextIO | None = None, line: str | None = None,
) -> None:  # fmt: skip
    """A :data:`warnings.showwarning` that prints :func:`format_line` on stderr."""
    stream: Any = file if file is not None else sys.stderr
    with suppress(OSError):  # stderr closed: nothing to tell
        stream.write(format_line(message, category, filename, lineno) + "\n")


@contextmanager
def one_line_warnings() -> Iterator[None]:
    """Within the block, warnings print as :func:`format_line` (the previous hook after)."""
    previous = warnings.showwarning
    warnings.showwarning = show_warning
    try:
        yield
    finally:
        warnings.showwarning = previous
