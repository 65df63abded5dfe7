"""Shared command-line plumbing for ``python -m bondid.<command>``.

Exit codes (spec §4): 0 success, 2 bad input (one line naming the file and what is wrong),
1 the computation itself failed. Every command builds its parser with :func:`make_parser`,
runs its body through :func:`run`, and reports progress with :class:`Progress`.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn

from .exceptions import BondidError, ComputationError

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # argparse exits with 2 as well
        self.print_usage(sys.stderr)
        print(f"{self.prog}: bad input: {message}", file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT)


def make_parser(prog: str, description: str) -> argparse.ArgumentParser:
    return _Parser(prog=f"python -m bondid.{prog}", description=description)


def add_model_args(p: argparse.ArgumentParser, *, data: bool = True, out: bool = True) -> None:
    """The common options: --model, --data, --out, --quiet."""
    p.add_argument("--model", required=True, type=Path, help="the machine's URDF file")
    if data:
        p.add_argument(
            "--data", required=True, nargs="+", type=Path, help="measured FRF files (CSV/UFF58)"
        )
    if out:
        p.add_argument("--out", type=Path, default=None, help="folder for the results")
    p.add_argument("--quiet", action="store_true", help="no progress display")


def parse_band(text: str) -> tuple[float, float]:
    """``"F_LO:F_HI"`` (Hz) → (f_lo, f_hi); raises ``argparse.ArgumentTypeError``."""
    try:
        lo, hi = (float(x) for x in text.split(":"))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"band {text!r} is not F_LO:F_HI in Hz") from exc
    if not 0 <= lo < hi:
        raise argparse.ArgumentTypeError(f"band {text!r}: need 0 ≤ F_LO < F_HI")
    return lo, hi


def parse_freq(text: str) -> tuple[float, float, int]:
    """``"F_LO:F_HI:N"`` → (f_lo Hz, f_hi Hz, n) for a log-spaced grid."""
    try:
        lo_s, hi_s, n_s = text.split(":")
        lo, hi, n_f = float(lo_s), float(hi_s), float(n_s)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"--freq {text!r} is not F_LO:F_HI:N") from exc
    if not (0 < lo < hi < math.inf) or not (2 <= n_f <= MAX_FREQ) or n_f != int(n_f):
        raise argparse.ArgumentTypeError(
            f"--freq {text!r}: need 0 < F_LO < F_HI (finite, Hz) and an integer N from 2 to"
            f" {MAX_FREQ}"
        )
    return lo, hi, int(n_f)


EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report it

#: the most frequencies a command accepts on one grid (``--freq``): 1.6 MB per channel
MAX_FREQ = 100_000


def run(body: Callable[[], int | None]) -> int:
    """Run a command body, mapping bondid errors onto the spec's exit codes.

    Ctrl-C (SIGINT) prints ``interrupted`` and returns 130; worker processes are stopped and
    no partial result is left (:mod:`bondid.interrupt`, :mod:`bondid.results`).
    """
    from . import interrupt, results

    previous = interrupt.install()
    try:
        return _run(body)
    finally:
        results.close_all()
        interrupt.restore(previous)


def _run(body: Callable[[], int | None]) -> int:
    try:
        code = body()
        from . import interrupt

        interrupt.check()
    except ComputationError as exc:
        status = getattr(exc, "status", None)
        extra = f" (solver status: {status})" if status else ""
        print(f"error: {exc}{extra}", file=sys.stderr)
        return EXIT_FAILED
    except BondidError as exc:
        print(f"bad input: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_OK if code is None else int(code)


class Progress:
    """A one-line progress display on stderr (silent when ``quiet`` or not a terminal... but
    always prints the final line so logs show the work was done)."""

    def __init__(self, label: str, total: int | None = None, *, quiet: bool = False):
        self.label, self.total, self.quiet = label, total, quiet
        self.count = 0
        self.t0 = time.perf_counter()
        self._tty = sys.stderr.isatty()
        self._last = 0.0

    def update(self, n: int = 1, info: str = "") -> None:
        self.count += n
        if self.quiet:
            return
        now = time.perf_counter()
        if (
            not self._tty
            and now - self._last < 2.0
            and (self.total is None or self.count < self.total)
        ):
            return
        self._last = now
        frac = f"{self.count}/{self.total}" if self.total else str(self.count)
        line = f"{self.label}: {frac} {info} [{now - self.t0:.1f} s]"
        print(
            ("\r" + line) if self._tty else line,
            end="" if self._tty else "\n",
            file=sys.stderr,
            flush=True,
        )

    def close(self, info: str = "") -> None:
        if self.quiet:
            return
        line = f"{self.label}: done {info} [{time.perf_counter() - self.t0:.1f} s]"
        print(("\r" + line) if self._tty else line, file=sys.stderr, flush=True)


def split_names(values: Sequence[str] | None) -> list[str]:
    """Flatten comma/space separated option values."""
    out: list[str] = []
    for v in values or ():
        out += [t for t in v.replace(",", " ").split() if t]
    return out


def check_workers(value: int, option: str = "--workers") -> int:
    """The same rule in every command: an integer ≥ 1 (1 = in this process)."""
    from .exceptions import ConfigError

    if value is None or int(value) < 1:
        raise ConfigError(f"{option} {value}: give an integer >= 1 (1 = no worker processes)")
    return int(value)


def warn_lines(warnings: Sequence[str]) -> list[str]:
    """``warning: …`` lines for a command's printed summary."""
    return [f"warning: {w}" for w in warnings]
