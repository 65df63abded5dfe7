"""Shared command-line plumbing for ``python -m bondid.<command>``.

Exit codes (spec §4): 0 success, 2 bad input (one line naming the file and what is wrong),
1 the computation itself failed. Every command builds its parser with :func:`make_parser`,
adds the options it shares with other commands (:mod:`bondid.cli_options`, importable from
here too), runs its body through :func:`run`, and reports progress with
:class:`bondid.progress.Progress` (a tqdm bar).
"""

from __future__ import annotations

import argparse
import errno
import math
import os
import signal
import sys
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from .cli_options import (
    add_channels_arg,
    add_drop_nan_arg,
    add_floating_base_arg,
    add_lines_arg,
    add_model_args,
    add_package_path_arg,
    add_points_arg,
    add_uff_map_arg,
    add_weighting_arg,
    apply_model_options,
    check_number,
    check_workers,
    parse_band,
    parse_freq,
    split_names,
    uff_channel_map,
)
from .exceptions import BondidError, ComputationError
from .progress import Progress

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_FAILED",
    "EXIT_OK",
    "Progress",
    "add_channels_arg",
    "add_drop_nan_arg",
    "add_floating_base_arg",
    "add_lines_arg",
    "add_model_args",
    "add_package_path_arg",
    "add_points_arg",
    "add_uff_map_arg",
    "add_weighting_arg",
    "apply_model_options",
    "check_number",
    "check_workers",
    "parse_band",
    "parse_freq",
    "split_names",
    "uff_channel_map",
]

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


#: the largest magnitude an integer option takes (what the solvers' C ``int`` holds): a
#: larger value wrapped round to 0 iterations once
MAX_INT_OPTION = 2**31 - 1


def _bounded_int(text: str) -> int:
    """``type=int`` of every bondid option: an integer of at most :data:`MAX_INT_OPTION`."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if abs(value) > MAX_INT_OPTION:
        raise argparse.ArgumentTypeError(
            f"{text} is out of range; valid: an integer from -{MAX_INT_OPTION} to {MAX_INT_OPTION}"
        )
    return value


def _number(text: str) -> float:
    """``type=float`` of every bondid option (NaN is refused after parsing, naming the
    option: :meth:`_Parser.parse_known_args`; each option checks its own range, some take
    ±inf)."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


class _Parser(argparse.ArgumentParser):
    """argparse with bondid's conventions: errors in one line (exit 2), ``--version``,
    integer options bounded (:func:`_bounded_int`) and float options never NaN."""

    def error(self, message: str) -> NoReturn:  # argparse exits with 2 as well
        text = " ".join(message.split())
        print(f"{self.prog}: bad input: {text}; see {self.prog} --help", file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT)

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        ns, rest = super().parse_known_args(args, namespace)
        for action in self._actions:
            if action.type is not _number or not action.option_strings:
                continue
            value = getattr(ns, action.dest, None)
            for v in value if isinstance(value, list) else [value]:
                if isinstance(v, float) and math.isnan(v):
                    self.error(f"{action.option_strings[0]} {v}: not a number; valid: a number")
        return ns, rest

    def add_argument(self, *args: Any, **kwargs: Any) -> argparse.Action:
        kwargs["type"] = _TYPES.get(kwargs.get("type"), kwargs.get("type"))
        if kwargs["type"] is None:
            del kwargs["type"]
        return super().add_argument(*args, **kwargs)

    def add_argument_group(self, *args: Any, **kwargs: Any) -> Any:
        group = super().add_argument_group(*args, **kwargs)
        plain = group.add_argument

        def add(*a: Any, **kw: Any) -> argparse.Action:
            kw["type"] = _TYPES.get(kw.get("type"), kw.get("type"))
            if kw["type"] is None:
                del kw["type"]
            return plain(*a, **kw)

        group.add_argument = add  # type: ignore[method-assign]
        return group


_TYPES: dict[Any, Any] = {int: _bounded_int, float: _number}


def version_text() -> str:
    """``bondid X.Y.Z`` (the installed package's version)."""
    from . import __version__

    return f"bondid {__version__}"


def make_parser(prog: str, description: str) -> argparse.ArgumentParser:
    p = _Parser(prog=f"python -m bondid.{prog}", description=description)
    p.add_argument("--version", action="version", version=version_text())
    return p


EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report it


def run(body: Callable[[], int | None], args: argparse.Namespace | None = None) -> int:
    """Run a command body, mapping bondid errors onto the spec's exit codes.

    With the parsed ``args``, their input files and output paths are checked first
    (:func:`bondid.paths.check_path_options`: regular, readable files; no link loops).
    Ctrl-C (SIGINT) prints ``interrupted`` and returns 130, SIGTERM ``terminated`` and 143;
    worker processes are stopped and no partial result is left (:mod:`bondid.interrupt`,
    :mod:`bondid.results`).
    """
    from . import interrupt, open_runs
    from .warnlines import one_line_warnings

    if args is not None:
        from .paths import check_path_options

        first = body

        def body() -> int | None:
            check_path_options(args)
            return first()

    previous = interrupt.install()
    try:
        with one_line_warnings():
            return _run(body)
    finally:
        open_runs.close_all()
        interrupt.restore(previous)


def parse_and_run(
    parser: argparse.ArgumentParser,
    argv: Sequence[str] | None,
    body: Callable[[argparse.Namespace], int | None],
) -> int:
    """Parse ``argv`` and :func:`run` ``body(args)``; ``--help`` or a bad option returns
    argparse's exit code (0, or 2 with its message printed) instead of raising
    ``SystemExit``, so that the command can run in-process (a fleet worker)."""
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    return run(lambda: body(args), args)


def one_line(text: object) -> str:
    """``text`` folded into one line (a library's multi-line message inside ours)."""
    return " ".join(str(text).split())


def _run(body: Callable[[], int | None]) -> int:
    try:
        code = body()
        from . import interrupt

        interrupt.check()
    except ComputationError as exc:
        status = getattr(exc, "status", None)
        extra = f" (solver status: {status})" if status else ""
        print(f"error: {one_line(exc)}{extra}", file=sys.stderr)
        return EXIT_FAILED
    except BondidError as exc:
        print(f"bad input: {one_line(exc)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:
        print(f"error: {os_error_line(exc)}", file=sys.stderr)
        return EXIT_FAILED
    except RecursionError:
        print(
            "error: the input is nested too deeply for the computation (Python's recursion"
            " limit was reached); please report the input",
            file=sys.stderr,
        )
        return EXIT_FAILED
    except MemoryError:
        print("error: out of memory; use fewer frequencies or channels", file=sys.stderr)
        return EXIT_FAILED
    except Exception as exc:
        if os.environ.get("BONDID_TRACEBACK"):
            raise
        print(
            f"error: internal error ({type(exc).__name__}: {one_line(exc)}); this is a bug,"
            " please report it (BONDID_TRACEBACK=1 shows where it happened)",
            file=sys.stderr,
        )
        return EXIT_FAILED
    except KeyboardInterrupt:
        from . import interrupt

        signum = interrupt.signal_number()
        print("terminated" if signum == signal.SIGTERM else "interrupted", file=sys.stderr)
        return 128 + signum
    return EXIT_OK if code is None else int(code)


def os_error_line(exc: OSError) -> str:
    """One line for a file-system failure of the run: a full disk (or quota) names the
    results folder being written and says the previous results are intact (the staged run
    is abandoned, :mod:`bondid.results`)."""
    from .open_runs import open_targets

    targets = open_targets()
    where = str(targets[0]) if targets else str(exc.filename or "the results")
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return f"no space left writing {where}; the previous results are intact"
    if exc.errno == errno.EROFS:
        return f"cannot write {where} (read-only file system); the previous results are intact"
    if exc.errno in (errno.EACCES, errno.EPERM):
        return f"permission denied: {exc.filename or where}; the previous results are intact"
    name = f" {exc.filename}" if exc.filename else ""
    return f"file system error{name}: {one_line(exc.strerror or exc)} (writing {where})"


def warn_lines(warnings: Sequence[str]) -> list[str]:
    """``warning: …`` lines for a command's printed summary."""
    return [f"warning: {w}" for w in warnings]
