"""What a native library prints on the process's stderr, caught and folded into one line:
:func:`captured_native_stderr`.

urdfdom (inside Pinocchio's URDF reader) reports a bad element through console_bridge,
straight onto file descriptor 2, in several lines each followed by its C++ source line
(``Error: Joint [x] is of type REVOLUTE but it does not specify limits`` / ``at line 607 in
.../joint.cpp``), before Pinocchio raises a generic "does not contain a valid URDF model".
Here descriptor 2 is pointed at a temporary file for the call, and the messages become part
of bondid's own one-line error.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
import threading
from collections.abc import Iterator

_LOCK = threading.Lock()
_SOURCE_LINE = re.compile(r"^\s*at line \d+ in \S+")
_LEVEL = re.compile(r"^\s*(Error|Warning|Info|Debug):\s*")


class Captured:
    """The text caught by :func:`captured_native_stderr` (set when the block ends)."""

    def __init__(self) -> None:
        self.text = ""

    def messages(self) -> list[str]:
        """The library's messages, one string each, source-line notes dropped."""
        out = []
        for line in self.text.splitlines():
            if not line.strip() or _SOURCE_LINE.match(line):
                continue
            out.append(" ".join(_LEVEL.sub("", line).split()))
        return out

    def one_line(self) -> str:
        """The messages joined with ``"; "``."""
        return "; ".join(self.messages())


@contextlib.contextmanager
def captured_native_stderr() -> Iterator[Captured]:
    """Context: descriptor 2 writes into a temporary file; yields a :class:`Captured`
    whose ``text`` holds what was written once the block ends. Python's own ``sys.stderr``
    is flushed before and after. One block at a time in the process (a lock)."""
    got = Captured()
    with _LOCK, tempfile.TemporaryFile(mode="w+b") as tmp:
        with contextlib.suppress(Exception):
            sys.stderr.flush()
        saved = os.dup(2)
        try:
            os.dup2(tmp.fileno(), 2)
            yield got
        finally:
            with contextlib.suppress(Exception):
                sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            got.text = tmp.read().decode("utf-8", errors="replace")
