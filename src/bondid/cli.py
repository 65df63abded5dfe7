"""Shared command-line plumbing for ``python -m bondid.<command>``.

Exit codes (spec §4): 0 success, 2 bad input (one line naming the file and what is wrong),
1 the computation itself failed. Every command builds its parser with :func:`make_parser`,
runs its body through :func:`run`, and reports progress with
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
from pathlib import Path
from typing import Any, NoReturn

from .exceptions import BondidError, ComputationError
from .progress import Progress

__all__ = ["EXIT_BAD_INPUT", "EXIT_FAILED", "EXIT_OK", "Progress"]

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
    from .ranges import FREQUENCY

    try:
        lo, hi = (float(x) for x in text.split(":"))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"band {text!r} is not F_LO:F_HI in Hz") from exc
    if not (0 <= lo < hi and hi in FREQUENCY):
        raise argparse.ArgumentTypeError(
            f"band {text!r}: need 0 ≤ F_LO < F_HI ≤ {FREQUENCY.hi:g} Hz"
        )
    return lo, hi


def parse_freq(text: str) -> tuple[float, float, int]:
    """``"F_LO:F_HI:N"`` → (f_lo Hz, f_hi Hz, n) for a log-spaced grid."""
    try:
        lo_s, hi_s, n_s = text.split(":")
        lo, hi, n_f = float(lo_s), float(hi_s), float(n_s)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"--freq {text!r} is not F_LO:F_HI:N") from exc
    from .ranges import FREQUENCY

    if not (0 < lo < hi <= FREQUENCY.hi) or not (2 <= n_f <= MAX_FREQ) or n_f != int(n_f):
        raise argparse.ArgumentTypeError(
            f"--freq {text!r}: need 0 < F_LO < F_HI ≤ {FREQUENCY.hi:g} Hz and an integer N"
            f" from 2 to {MAX_FREQ}"
        )
    return lo, hi, int(n_f)


EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report it

#: the most frequencies a command accepts on one grid (``--freq``): 1.6 MB per channel
MAX_FREQ = 100_000


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


class _JoinNames(argparse.Action):
    """Store the names of one or more values (``a b`` or ``a,b``, repeatable) as one
    comma-separated string."""

    def __call__(self, parser: Any, namespace: Any, values: Any, option_string: Any = None):
        before = getattr(namespace, self.dest, None) or ""
        setattr(namespace, self.dest, ",".join(split_names([before, *values])))


def add_channels_arg(p: Any, text: str = "channels OUT.IN to use") -> None:
    """``--channels`` taking ``x.x y.y`` as well as ``x.x,y.y`` (stored comma-separated)."""
    p.add_argument(
        "--channels", nargs="+", action=_JoinNames, default=None, metavar="OUT.IN",
        help=f"{text}, e.g. x.x y.y or x.x,y.y (OUT.IN = response at OUT to the excitation at IN)",
    )  # fmt: skip


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


def check_number(
    value: float | None, option: str, *, low: float = -math.inf, low_open: bool = False
) -> float | None:
    """The same rule for a float option in every command: finite and at least ``low``
    (above it with ``low_open``); None (not given) passes."""
    from .exceptions import ConfigError

    if value is None:
        return None
    if not (math.isfinite(value) and (value > low if low_open else value >= low)):
        sign = ">" if low_open else ">="
        raise ConfigError(f"{option} {value}: give a finite number {sign} {low:g}")
    return value


def warn_lines(warnings: Sequence[str]) -> list[str]:
    """``warning: …`` lines for a command's printed summary."""
    return [f"warning: {w}" for w in warnings]
