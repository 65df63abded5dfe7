"""``python -m bondid.sensitivity``: which parameters the data determine, band by band.

Prints a short summary (top parameters per band, the aggregate by parameter kind, the
recommended subset with expected std, the number of identifiable combinations, the sweep)
and with ``--out DIR`` writes ``sensitivity.json`` and PNG maps there. Exit codes: 0 success,
2 bad input, 1 failed computation.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover - typing only
    from ..data.measurement import FrfData
    from ..model.document import UrdfDocument
    from ._common import Setup
    from .identifiability import Identifiability
    from .local import Linearisation, LocalSensitivity
    from .sweep import SweepResult


def _scales(text: str):
    from .sweep import default_scales

    try:
        lo, hi, step = (float(v) for v in text.split(":"))
        return default_scales(lo, hi, step)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(
            f"--scales {text!r} is not LO:HI:STEP (0 ≤ LO < HI)"
        ) from exc


def main(argv: Sequence[str] | None = None) -> int:
    from .. import cli

    args = _parser().parse_args(argv)
    return cli.run(lambda: _run(args), args)


def _parser() -> argparse.ArgumentParser:
    from .. import cli

    p = cli.make_parser(
        "sensitivity",
        "Local sensitivities per band and channel, identifiability (recommended subset) and "
        "the one-at-a-time sweep (each parameter alone over 50..150 %).",
    )
    cli.add_model_args(p)
    from ..setup.operating_points import add_operating_point_arg

    add_operating_point_arg(p)
    from ..setup.damping import add_damping_arg

    add_damping_arg(p)
    p.add_argument("--free", nargs="+", default=["all"], help="parameters: names, globs, groups")
    p.add_argument("--fixed", nargs="+", default=[], help="parameters to leave out (wins)")
    p.add_argument("--band", action="append", type=cli.parse_band, default=None,
                   help="F_LO:F_HI in Hz (repeatable): analysis bands, and only these frequencies"
                   " are used; default: automatic bands around the modes")  # fmt: skip
    cli.add_channels_arg(p)
    p.add_argument("--cost", default="complex_log", help="residual kind (default complex_log)")
    p.add_argument(
        "--max-rel-std", type=float, default=0.1,
        help="largest expected relative std of a recommended parameter (0.1 = 10 %%)",
    )  # fmt: skip
    p.add_argument(
        "--noise", type=float, default=None,
        help="noise std per residual part (dB for complex_log); default: from the data",
    )  # fmt: skip
    p.add_argument("--no-sweep", action="store_true", help="skip the one-at-a-time sweep")
    p.add_argument("--scales", type=_scales, default=None, help="sweep LO:HI:STEP (0.5:1.5:0.1)")
    p.add_argument("--workers", type=int, default=2, help="processes for the sweep (default 2)")
    cli.add_lines_arg(p, "analysed", tail=" (as bondid.fit does)")
    cli.add_drop_nan_arg(p)
    return p


def _run(args: argparse.Namespace) -> int:
    """Load the model and data, analyse, print the summary and write the results (``--out``)."""
    from .. import cli
    from ..cost import CostOptions
    from ..cost.selection import channels_by_file, informative_only
    from ..data.reduce import parse_lines, reduce_datasets
    from ..results import open_results
    from ..validation import check_inputs, check_selection, load_model
    from ..validation.datasets import load_datasets
    from . import output
    from ._common import make_setup
    from .local import linearise_cost

    t_start = time.perf_counter()
    cli.check_workers(args.workers)
    cli.check_number(args.max_rel_std, "--max-rel-std", low=0.0, low_open=True)
    cli.check_number(args.noise, "--noise", low=0.0)
    lines_setting = parse_lines(args.lines)
    res = None
    if args.out is not None:
        names = [*output.PNG_NAMES.values(), "sensitivity.json"]
        res = open_results(args.out, "sensitivity", [args.model, *args.data], patterns=names)
    doc, warnings = load_model(args.model, lambda d: cli.apply_model_options(d, args))
    datasets = load_datasets(
        doc, args.data, drop_nan=args.drop_nan, channel_map=cli.uff_channel_map(args)
    )
    from ..setup.operating_points import given_operating_points, operating_points_of

    warnings += given_operating_points(doc, datasets, operating_points_of(args))
    warnings += check_inputs(doc, datasets, args.data)
    channels = cli.split_names([args.channels or ""]) or None
    check_selection(datasets, bands=args.band, channels=channels)
    options = CostOptions(kind=args.cost, bands=args.band, channels=channels)
    options, left_out, note = informative_only(datasets, options)
    if note:
        warnings.append(note)
    # the analysis runs on the lines a fit with the same --lines uses
    datasets, reduction = reduce_datasets(datasets, lines_setting, options.channels, options.bands)
    free, fixed = _damping(doc, datasets, args, cli.split_names(args.free))
    setup = make_setup(doc, datasets, options, free, [*cli.split_names(args.fixed), *fixed])
    lin = linearise_cost(setup)
    local, ident, sweep, timing = _analyse(setup, lin, args)
    print(
        f"{doc.name}: {setup.n_params} parameters, {len(datasets)} data set(s), "
        f"{setup.problem.n_residuals} residuals ({options.name})"
    )
    if reduction.reduced:
        print(reduction.summary_line("analysed", figures=False))
    for line in output.summary_lines(local, ident, sweep, cost_kind=options.kind):
        print(line)
    for line in cli.warn_lines(warnings):
        print(line)
    if res is not None:
        timing["total_s"] = time.perf_counter() - t_start
        content = output.result_dict(
            local, ident, sweep, model=str(args.model), data=[str(d) for d in args.data],
            cost_name=options.name, n_residuals=setup.problem.n_residuals, timing=timing,
        )  # fmt: skip
        content["warnings"] = warnings
        content["channels_left_out"], content["channels_by_file"] = channels_by_file(
            datasets, options, left_out
        )
        content["lines"] = reduction.to_json_dict()
        output.write_json(res.path("sensitivity.json"), content)
        pngs = output.write_plots(res.tmp, local, sweep, title=doc.name)
        res.commit(warnings=warnings, main="sensitivity.json")
        print(
            f"wrote {Path(args.out) / 'sensitivity.json'} and {len(pngs)} PNG file(s) in {args.out}"
        )
    return 0


def _damping(
    doc: UrdfDocument, datasets: list[FrfData], args: argparse.Namespace, free: list[str]
) -> tuple[list[str], list[str]]:
    """Apply ``--damping`` to ``doc`` (:mod:`bondid.setup.damping`, as the fit does); the free
    names and the extra fixed ones it implies."""
    from ..setup.damping import damping_free, data_band, declare_damping

    kind = args.damping or "model"
    band = data_band(datasets, args.band)
    declare_damping(doc, kind, band_hz=band, operating_point=datasets[0].operating_point)
    return damping_free(doc, kind, free, [])


def _analyse(
    setup: Setup, lin: Linearisation, args: argparse.Namespace
) -> tuple[LocalSensitivity, Identifiability, SweepResult | None, dict[str, float | None]]:
    """``(local, identifiability, sweep or None, timing)``: the three analyses and their
    wall times in s (``jacobian_s``, ``local_s``, ``identifiability_s``, ``sweep_s``)."""
    from .. import cli
    from .identifiability import analyse_identifiability
    from .local import analyse_local
    from .sweep import run_sweep

    t0 = time.perf_counter()
    local = analyse_local(lin, args.band)
    t1 = time.perf_counter()
    ident = analyse_identifiability(lin, max_rel_std=args.max_rel_std, noise=args.noise)
    t2 = time.perf_counter()
    sweep = None
    if not args.no_sweep:
        prog = cli.Progress("sweep", setup.n_params, quiet=args.quiet)
        sweep = run_sweep(setup, args.scales, workers=args.workers,
                          progress=lambda n, name: prog.update(n, name))  # fmt: skip
        prog.close(f"{setup.n_params} parameters")
    timing: dict[str, float | None] = {
        "jacobian_s": lin.wall_s,
        "local_s": t1 - t0,
        "identifiability_s": t2 - t1,
        "sweep_s": None if sweep is None else sweep.wall_s,
    }
    return local, ident, sweep, timing


if __name__ == "__main__":
    from ..interrupt import exit_process

    exit_process(main())
