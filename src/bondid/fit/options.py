"""The command line of ``python -m bondid.fit``: its parser and the settings it resolves
(a study file, if any, with the options laid over it)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..cli import (
    add_channels_arg,
    add_drop_nan_arg,
    add_floating_base_arg,
    add_lines_arg,
    add_package_path_arg,
    add_points_arg,
    add_uff_map_arg,
    add_weighting_arg,
    check_workers,
    make_parser,
    parse_band,
    split_names,
)
from ..cost.residuals import NORMS, RESIDUAL_KINDS
from ..data.lines import parse_lines
from ..exceptions import ConfigError
from ..setup.operating_points import add_operating_point_arg, operating_points_of
from .defaults import add_prior_arg, check_prior
from .setting_checks import check_names, parse_bound_option
from .settings import StudySettings, add_bound
from .study import STAGES, load_study


def build_parser() -> argparse.ArgumentParser:
    """The command's options. One flat declaration, in the order ``--help`` lists them (longer
    than 60 lines because it is a list, read top-down; splitting it would scatter the list)."""
    p = make_parser("fit", "Fit a machine model's parameters to measured FRFs.")
    p.add_argument("--model", type=Path, help="the machine's URDF file (or model = in --study)")
    p.add_argument(
        "--data",
        nargs="+",
        type=Path,
        help="measured FRF files, CSV or UFF58 (or data = in --study)",
    )
    p.add_argument("--study", type=Path, help="study TOML file; command-line options override it")
    add_package_path_arg(p)
    add_uff_map_arg(p)
    add_operating_point_arg(p)
    add_floating_base_arg(p)
    add_points_arg(p)
    p.add_argument(
        "--free", nargs="+", action="extend",
        help="parameters to fit: names, globs (x_stage.*, *.stiffness), groups (inertial,"
        " parasitic, joints, all), auto, or default: every inertial parameter and every"
        " non-zero stiffness and damping (the default; with --prior, what the data cannot"
        " determine stays near the model's value)",
    )  # fmt: skip
    p.add_argument(
        "--fixed", nargs="+", action="extend", help="parameters to hold (wins over --free)"
    )
    add_prior_arg(p)
    p.add_argument(
        "--bound", action="append", metavar="KEY=REL|KEY=LO:HI",
        help="bound for a kind (mass, com, inertia, stiffness, damping), name or glob: relative"
        " fraction (0.2 = ±20 %%) or absolute LO:HI; repeatable",
    )  # fmt: skip
    p.add_argument(
        "--band", action="append", type=parse_band, metavar="F_LO:F_HI",
        help="frequency band to fit, Hz; repeatable",
    )  # fmt: skip
    add_channels_arg(p, "channels to fit (default: those above the noise floor, file by file)")
    p.add_argument(
        "--weight",
        action="append",
        metavar="OUT.IN=W",
        help="extra weight of a channel; repeatable",
    )
    p.add_argument("--cost", choices=RESIDUAL_KINDS, help="residual kind (default complex_log)")
    p.add_argument("--norm", choices=NORMS, help="norm (default l2)")
    p.add_argument(
        "--coherence", action=argparse.BooleanOptionalAction, default=None,
        help="use the file's coherence column in the weights where present (default on);"
        " --no-coherence ignores it (the weights then come from the estimated noise)",
    )  # fmt: skip
    add_weighting_arg(p)
    add_lines_arg(
        p,
        "the fit uses",
        default=None,
        tail="; the figures (db_rms, noise level) are always on all lines",
    )
    p.add_argument("--multistart", type=int, metavar="N", help="number of starts (default 1)")
    p.add_argument("--seed", type=int, help="Latin-hypercube seed (default 0)")
    p.add_argument("--workers", type=int, help="parallel processes for --multistart (default 2)")
    p.add_argument(
        "--staged", action=argparse.BooleanOptionalAction, default=None,
        help="fit bands first (stiffness, damping, inertia), then everything",
    )  # fmt: skip
    p.add_argument(
        "--stage-band", action="append", metavar="STAGE=F_LO:F_HI",
        help=f"band of a stage ({', '.join(STAGES)}) for --staged; repeatable",
    )  # fmt: skip
    p.add_argument(
        "--continuation", type=int, metavar="N",
        help="band continuation: fit a band growing from the lowest frequencies in N steps (the"
        " last is the full fit), for starts far from the truth (default 0 = off; try 8)",
    )  # fmt: skip
    p.add_argument(
        "--max-iter", type=int, metavar="N", help="IPOPT iterations per fit (default 200)"
    )
    p.add_argument(
        "--presolve", type=int, metavar="N",
        help="IPOPT iterations on the normalised complex error before a log-cost fit (default"
        " 60; 0 = none): crosses the walls a log cost has where a cross term changes sign",
    )  # fmt: skip
    p.add_argument(
        "--fallback", type=int, metavar="N",
        help="when a direct or staged fit ends above the noise level (more than 10 %% above the"
        " predicted level), try the band continuation with N bands and the staged schedule"
        " from the same start, keeping the best (default 8; 0 = off)",
    )  # fmt: skip
    p.add_argument(
        "--fallback-starts", type=int, metavar="N",
        help="then, while the fit is above the noise level and a restart still improves, up to"
        " N-1 random starts within the prior's box (default 4; 0 = off)",
    )  # fmt: skip
    _add_structure_args(p)
    add_drop_nan_arg(p)
    p.add_argument("--out", type=Path, default=None, help="folder for the results")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    return p


def _add_structure_args(p: argparse.ArgumentParser) -> None:
    """Options that give the free parameters a structure (ties, the damping model)."""
    from ..setup.damping import add_damping_arg

    add_damping_arg(p)
    p.add_argument(
        "--tie", action="append", metavar="PATTERN",
        help="parameters sharing one value: names or globs of one kind (joint stiffness or"
        " damping; link mass, or one CoM or inertia component), e.g. --tie '*.damping' (one"
        " damping for every joint), --tie 'j2.stiffness,j3.stiffness' or --tie"
        " 'seg*.inertia.iyy' (identical parts); repeatable, one tie each; kept in fitted.urdf",
    )  # fmt: skip


def _positive(value: int | None, name: str, minimum: int) -> int | None:
    if value is not None and value < minimum:
        raise ConfigError(f"{name} {value}: give an integer >= {minimum}")
    return value


def resolve_settings(args: argparse.Namespace) -> StudySettings:
    """The study file (if any) with the command-line options laid over it."""
    s = load_study(args.study) if args.study is not None else StudySettings()
    if args.model is not None:
        s.model = args.model
    if args.data:
        s.data = list(args.data)
    s.operating_points.update(operating_points_of(args))
    if args.free:
        s.free = split_names(args.free)
    if args.fixed:
        s.fixed = split_names(args.fixed)
    if args.prior is not None:
        s.prior = check_prior(args.prior, "--prior")
    for text in args.bound or ():
        add_bound(s, *parse_bound_option(text))
    if args.band:
        s.bands = list(args.band)
    if args.channels is not None:
        s.channels = check_names(args.channels, "--channels", "value")
        if not s.channels:
            raise ConfigError("--channels: empty; give OUT.IN names such as x.x,y.y")
    for text in args.weight or ():
        ch, sep, w = text.partition("=")
        try:
            value = float(w)
        except ValueError:
            value = math.nan
        if not sep or ch.count(".") != 1 or not 0 <= value < math.inf:
            raise ConfigError(f"--weight {text!r}: not OUT.IN=W with a finite weight W >= 0")
        s.channel_weights[ch] = value
    if args.cost is not None:
        s.cost = args.cost
    if args.norm is not None:
        s.norm = args.norm
    if args.coherence is not None:
        s.coherence = args.coherence
    if args.weighting is not None:
        s.weighting = args.weighting
    if args.lines is not None:
        s.lines = str(parse_lines(args.lines))
    _search_settings(args, s)
    for text in args.tie or ():
        s.ties[text] = split_names([text])
    if args.damping is not None:
        if args.damping != s.damping:
            s.damping_start = None  # the study's start belongs to the study's kind
        s.damping = args.damping
    if s.model is None:
        raise ConfigError("no model: give --model URDF (or model = ... in the study file)")
    if not s.data:
        raise ConfigError("no data: give --data FILE... (or data = [...] in the study file)")
    return s


def _search_settings(args: argparse.Namespace, s: StudySettings) -> None:
    """The search options (multistart, seed, workers, staged, stage bands, continuation,
    iterations, presolve) laid over ``s``."""
    s.multistart = _positive(args.multistart, "--multistart", 1) or s.multistart
    if args.seed is not None:
        s.seed = int(_positive(args.seed, "--seed", 0) or 0)
    if args.workers is not None:
        s.workers = check_workers(args.workers)
    if args.staged is not None:
        s.staged = args.staged
    cli_stage: dict[str, list[tuple[float, float]]] = {}
    for text in args.stage_band or ():
        stage, sep, band = text.partition("=")
        if not sep or stage not in STAGES:
            raise ConfigError(
                f"--stage-band {text!r}: not STAGE=F_LO:F_HI with STAGE in {', '.join(STAGES)}"
            )
        try:
            cli_stage.setdefault(stage, []).append(parse_band(band))
        except argparse.ArgumentTypeError as exc:
            raise ConfigError(f"--stage-band: {exc}") from None
    s.stage_bands.update(cli_stage)
    if args.continuation is not None:
        s.continuation = int(_positive(args.continuation, "--continuation", 0) or 0)
    if s.continuation == 1 or (s.continuation and s.staged):
        where = "--continuation" if s.source is None else f"{s.source} / --continuation"
        raise ConfigError(
            f"{where}: {s.continuation} with staged={s.staged}; valid: 0 (off) or at least 2"
            " bands, and not together with --staged (choose one search strategy)"
        )
    if args.max_iter is not None:
        s.max_iter = int(_positive(args.max_iter, "--max-iter", 0) or 0)
    if args.presolve is not None:
        s.presolve = int(_positive(args.presolve, "--presolve", 0) or 0)
    if args.fallback is not None:
        s.fallback = int(_positive(args.fallback, "--fallback", 0) or 0)
    if args.fallback_starts is not None:
        s.fallback_starts = int(_positive(args.fallback_starts, "--fallback-starts", 0) or 0)
