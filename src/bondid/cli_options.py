"""The command-line options that several commands share, declared and checked once.

Each ``add_*_arg`` puts one option on a command's parser (built by
:func:`bondid.cli.make_parser`) with the same name, meaning and help text in every command;
``parse_band``/``parse_freq`` read the frequency options and ``check_workers``/``check_number``
apply one rule to a value wherever it was given. The commands take these through
:mod:`bondid.cli`, with the rest of their command-line plumbing.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

#: the most frequencies a command accepts on one grid (``--freq``): 1.6 MB per channel
MAX_FREQ = 100_000


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
    from .validation.datasets import parse_uff_map_item

    return dict(parse_uff_map_item(t) for t in getattr(args, "uff_map", [])) or None


def add_drop_nan_arg(p: argparse.ArgumentParser) -> None:
    """``--drop-nan``: drop the frequency rows of a data file that hold a NaN or empty cell."""
    p.add_argument(
        "--drop-nan", action="store_true",
        help="drop the frequency rows of a data file that hold a NaN or empty cell",
    )  # fmt: skip


def add_lines_arg(
    p: argparse.ArgumentParser, what: str, default: str | None = "auto", tail: str = ""
) -> None:
    """``--lines auto|all|N``: the frequency lines per file ``what`` works on (the line
    reduction of :mod:`bondid.data.reduce`); ``tail`` ends the help text."""
    from .data.lines import AUTO_ABOVE, AUTO_LINES

    p.add_argument(
        "--lines", default=default, metavar="auto|all|N",
        help=f"frequency lines per file {what}: auto (default: files above {AUTO_ABOVE} lines"
        f" keep {AUTO_LINES}: every line near each resonance and anti-resonance, log-spaced"
        f" elsewhere), all, or at most N{tail}",
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
