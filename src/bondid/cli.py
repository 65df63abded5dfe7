"""Shared command-line plumbing for ``python -m bondid.<command>``.

Exit codes (spec §4): 0 success, 2 bad input (one line naming the file and what is wrong),
1 the computation itself failed. Every command builds its parser with :func:`make_parser`,
runs its body through :func:`run`, and reports progress with :class:`Progress`.
"""

from __future__ import annotations

import argparse
import math
import signal
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


def add_model_args(
    p: argparse.ArgumentParser, *, data: bool = True, out: bool = True, points_alias: bool = True
) -> None:
    """The common options: --model, --data, --out, --quiet, --package-path, --points-file
    (also spelt --points unless ``points_alias`` is False: diagnose's --points is another)."""
    p.add_argument("--model", required=True, type=Path, help="the machine's URDF file")
    if data:
        p.add_argument(
            "--data", required=True, nargs="+", type=Path, help="measured FRF files (CSV/UFF58)"
        )
        add_uff_map_arg(p)
    if out:
        p.add_argument("--out", type=Path, default=None, help="folder for the results")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    add_package_path_arg(p)
    add_points_arg(p, alias=points_alias)
    add_floating_base_arg(p)


def add_uff_map_arg(p: argparse.ArgumentParser) -> None:
    """``--uff-map NAME=NODE:DIR`` (repeatable): UFF58 record → channel name."""
    p.add_argument(
        "--uff-map", action="append", default=[], metavar="NAME=NODE:DIR",
        help="UFF58 files: the channel (joint or point) of a node and direction code, e.g."
        " acc=101:+3 (±1..±3 translation x/y/z, ±4..±6 rotation); repeatable; replaces the"
        " default map (node i = i-th transmitted joint); two names on one node and axis: the"
        " first names the response, the second the reference (a driving point)",
    )  # fmt: skip


def uff_channel_map(args: argparse.Namespace) -> dict[str, tuple[int, int]] | None:
    """The ``--uff-map`` items as a channel map (None when none is given)."""
    from .data.for_model import parse_uff_map_item

    return dict(parse_uff_map_item(t) for t in getattr(args, "uff_map", [])) or None


def add_drop_nan_arg(p: argparse.ArgumentParser) -> None:
    """``--drop-nan``: drop the frequency rows of a data file that hold a NaN or empty cell."""
    p.add_argument(
        "--drop-nan", action="store_true",
        help="drop the frequency rows of a data file that hold a NaN or empty cell",
    )  # fmt: skip


def add_weighting_arg(p: argparse.ArgumentParser, default: str | None = None) -> None:
    """``--weighting``: the point weights (:mod:`bondid.data.weights`)."""
    from .data.weights import WEIGHTINGS

    p.add_argument(
        "--weighting", default=default, choices=WEIGHTINGS,
        help="point weights: auto (coherence combined with the noise estimated from the data,"
        " the estimate alone without coherence; default), coherence, estimated or none",
    )  # fmt: skip


def add_floating_base_arg(p: argparse.ArgumentParser) -> None:
    """``--floating-base``: the model's root is free (a free-free structure)."""
    p.add_argument(
        "--floating-base", action=argparse.BooleanOptionalAction, default=None,
        help="the model's root is free (a free-free structure): add a floating joint above it"
        " (rigid-body modes at 0 Hz, no gravity); or write a URDF floating joint",
    )  # fmt: skip


def add_points_arg(p: argparse.ArgumentParser, *, alias: bool = True) -> None:
    """``--points-file FILE`` (alias ``--points``): measurement points and transducer gains."""
    names = ["--points-file", "--points"] if alias else ["--points-file"]
    p.add_argument(
        *names, dest="points_file", type=Path, default=None, metavar="TOML",
        help="measurement points and transducer gains ([points], [gains] tables; see README)",
    )  # fmt: skip


def apply_model_options(doc: object, args: argparse.Namespace) -> None:
    """Apply ``--package-path``, ``--floating-base`` and ``--points-file`` (when the parser
    has them) to a loaded model (a :class:`bondid.model.UrdfDocument`)."""
    from .model.points import apply_declarations, load_points_file

    if getattr(args, "package_path", None):
        doc.package_path = [str(p) for p in args.package_path]  # type: ignore[attr-defined]
    if getattr(args, "floating_base", None):
        from .model.authoring import add_floating_base

        add_floating_base(doc)  # type: ignore[arg-type]
    if getattr(args, "points_file", None) is not None:
        apply_declarations(doc, *load_points_file(args.points_file))


def add_package_path_arg(p: argparse.ArgumentParser) -> None:
    """``--package-path DIR`` (repeatable): where ``package://`` meshes are looked up first."""
    p.add_argument(
        "--package-path", action="append", default=[], metavar="DIR",
        help="folder holding (or being) a ROS package named by package:// mesh URIs; searched"
        " before ROS_PACKAGE_PATH, the URDF's folders and example-robot-data; repeatable",
    )  # fmt: skip


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

    Ctrl-C (SIGINT) prints ``interrupted`` and returns 130, SIGTERM ``terminated`` and 143;
    worker processes are stopped and no partial result is left (:mod:`bondid.interrupt`,
    :mod:`bondid.results`).
    """
    from . import interrupt, results

    previous = interrupt.install()
    try:
        return _run(body)
    finally:
        results.close_all()
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
    return run(lambda: body(args))


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
        from . import interrupt

        signum = interrupt.signal_number()
        print("terminated" if signum == signal.SIGTERM else "interrupted", file=sys.stderr)
        return 128 + signum
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
