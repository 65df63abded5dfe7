"""The one progress convention of every command: a tqdm bar on stderr with a meaningful total.

``Progress(label, total)`` counts work items (iterations out of the iteration limit, starts,
parameters swept, machines, pages); ``update(n, info)`` advances, ``set(count, info)`` jumps
(an IPOPT iteration number), ``close(info)`` ends with one final line that stays in logs.
On a terminal the bar redraws in place; into a file or a pipe it writes a plain line at most
every :data:`LOG_INTERVAL_S` seconds (no carriage returns in logs). ``quiet`` prints nothing.
"""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO

#: seconds between two progress lines when stderr is not a terminal
LOG_INTERVAL_S = 10.0


class _Lines:
    """A stream that turns tqdm's in-place redraws into whole lines (for logs)."""

    def __init__(self, stream: TextIO):
        self.stream = stream

    def write(self, text: str) -> None:
        text = text.replace("\r", "").strip()
        if text:
            self.stream.write(text + "\n")

    def flush(self) -> None:
        self.stream.flush()


class Progress:
    """A progress bar (tqdm) named ``label`` over ``total`` items (None: a counter)."""

    def __init__(self, label: str, total: int | None = None, *, quiet: bool = False):
        from tqdm import tqdm

        self.label, self.quiet = label, quiet
        self.t0 = time.perf_counter()
        tty = sys.stderr.isatty()
        self._bar: Any = tqdm(
            total=total,
            desc=label,
            file=sys.stderr if tty else _Lines(sys.stderr),
            disable=quiet,
            mininterval=0.2 if tty else LOG_INTERVAL_S,
            dynamic_ncols=tty,
            ascii=not tty,
            leave=False,
            bar_format=None if total else "{desc}: {n} {postfix} [{elapsed}]",
        )

    @property
    def total(self) -> int | None:
        return self._bar.total

    @total.setter
    def total(self, value: int | None) -> None:
        self._bar.total = value
        self._bar.bar_format = None if value else self._bar.bar_format

    @property
    def count(self) -> int:
        return int(self._bar.n)

    @count.setter
    def count(self, value: int) -> None:
        self._bar.n = value

    def update(self, n: int = 1, info: str = "") -> None:
        """Advance by ``n`` items; ``info`` is shown after the bar."""
        if info:
            self._bar.set_postfix_str(info, refresh=False)
        self._bar.update(n)

    def set(self, count: int, info: str = "") -> None:
        """Jump to ``count`` items done (e.g. the solver's iteration number)."""
        if info:
            self._bar.set_postfix_str(info, refresh=False)
        self._bar.update(count - self._bar.n)

    def write(self, line: str) -> None:
        """A message line above the bar (not when ``quiet``)."""
        if not self.quiet:
            self._bar.write(line, file=sys.stderr)

    def close(self, info: str = "") -> None:
        """End the bar and print one final line (kept in logs)."""
        self._bar.close()
        if self.quiet:
            return
        done = f"{self.count}/{self.total}" if self.total else f"{self.count}"
        extra = f", {info}" if info else ""
        elapsed = time.perf_counter() - self.t0
        print(f"{self.label}: done ({done}{extra}) [{elapsed:.1f} s]", file=sys.stderr, flush=True)
