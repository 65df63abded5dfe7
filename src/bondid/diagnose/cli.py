"""The command line of ``python -m bondid.diagnose``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path


def build_parser() -> argparse.ArgumentParser:
    from .. import cli
    from ..setup.damping import add_damping_arg
    from ..setup.operating_points import add_operating_point_arg
    from .effects import available

    effects = available()
    listing = "; ".join(f"{n}: {cls.description}" for n, cls in effects.items())
    p = cli.make_parser(
        "diagnose",
        "Diagnose the gap between a model and measured FRFs: where it lies, which unmodelled "
        "effect causes it, how far it shrinks.",
    )
    cli.add_model_args(p, points_alias=False)  # --points is the refit frequency count here
    p.add_argument(
        "--effects",
        default=None,
        help=f"comma-separated subset of the candidate effects (default all). {listing}",
    )
    p.add_argument(
        "--free", nargs="*", default=None,
        help="parameters of the parameter refit: names, globs, groups (inertial, parasitic,"
        " joints, all); default: all (every inertial parameter, every non-zero spring and damper)",
    )  # fmt: skip
    p.add_argument(
        "--band", action="append", type=cli.parse_band, default=None,
        help="F_LO:F_HI in Hz (repeatable): frequencies to use",
    )  # fmt: skip
    cli.add_channels_arg(p, "channels OUT.IN to use (default: those above the noise floor)")
    add_operating_point_arg(p)
    add_damping_arg(p)
    p.add_argument("--points", type=int, default=500, help="frequencies per data set for refits")
    p.add_argument("--workers", type=int, default=2, help="worker processes (1 = in-process)")
    p.add_argument(
        "--scheduler", default=None, metavar="ADDRESS",
        help="run the screenings and refits on the workers of a Dask cluster "
        "(tcp://HOST:PORT; needs pip install 'bondid[fleet]'); default: local processes",
    )  # fmt: skip
    cli.add_lines_arg(p, "the diagnosis works on", tail=" (as bondid.fit does)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    cli.add_weighting_arg(p, "auto")
    cli.add_drop_nan_arg(p)
    return p


#: the names ``bondid.diagnose`` may write under ``--out``
OUT_PATTERNS = (
    "diagnosis.json", "refit.urdf", "augmented.urdf", "augmented_all.urdf", "final.urdf",
    "residual_map.png", "bode_*.png",
)  # fmt: skip


def absolute_mesh_paths(doc, base: Path) -> None:
    """Rewrite relative mesh file names of ``doc`` against ``base`` (the URDF's folder), so
    the model text sent to worker processes and written as refit.urdf resolves anywhere."""
    for lk in doc.robot.links:
        for el in [*(lk.collisions or []), *(lk.visuals or [])]:
            mesh = getattr(getattr(el, "geometry", None), "mesh", None)
            name = getattr(mesh, "filename", None)
            if mesh is not None and name and "://" not in name and not Path(name).is_absolute():
                mesh.filename = str((base / name).resolve())


def main(argv: Sequence[str] | None = None) -> int:
    from .. import cli

    args = build_parser().parse_args(argv)

    def body() -> int:
        from ..data.lines import parse_lines
        from ..data.reduce import reduce_datasets
        from ..exceptions import ConfigError
        from ..results import open_results
        from ..validation import check_inputs, check_selection, load_model
        from ..validation.datasets import load_datasets
        from .pipeline import Settings, diagnose
        from .report import gaps, to_json_dict, write_outputs, write_plots
        from .summary import summary

        cli.check_workers(args.workers)
        if args.points < 20:
            raise ConfigError(f"--points {args.points}: need at least 20")
        lines_setting = parse_lines(args.lines)
        res = None
        if args.out is not None:
            res = open_results(
                args.out, "diagnose", [args.model, *args.data], patterns=OUT_PATTERNS
            )
        doc, warnings = load_model(args.model, lambda d: cli.apply_model_options(d, args))
        absolute_mesh_paths(doc, Path(args.model).absolute().parent)
        data = load_datasets(
            doc, args.data, drop_nan=args.drop_nan, channel_map=cli.uff_channel_map(args)
        )
        from ..setup.operating_points import given_operating_points, operating_points_of

        warnings += given_operating_points(doc, data, operating_points_of(args))
        warnings += check_inputs(doc, data, args.data)
        channels = cli.split_names([args.channels]) if args.channels else None
        check_selection(data, bands=args.band, channels=channels)
        from ..setup.damping import data_band, declare_damping

        declare_damping(
            doc, args.damping or "model", band_hz=data_band(data, args.band),
            operating_point=data[0].operating_point,
        )  # fmt: skip
        # dense analyser files: every later step (noise estimate, refits, gap figures on all
        # data, the final fit) works on the lines a fit with the same --lines uses
        data, reduction = reduce_datasets(data, lines_setting, channels, args.band)
        if not args.quiet:  # at once, not only after a run of minutes (the summary repeats them)
            for line in cli.warn_lines(warnings):
                print(line, file=sys.stderr, flush=True)
        settings = Settings(
            effects=cli.split_names([args.effects]) if args.effects else None,
            free=cli.split_names(args.free) if args.free else None,
            bands=args.band,
            channels=channels,
            n_points=args.points,
            workers=args.workers,
            scheduler=args.scheduler,
            weighting=args.weighting,
            damping=args.damping or "model",
        )
        prog = cli.Progress("diagnose", quiet=args.quiet)

        def on_progress(label: str) -> None:
            prog.update(1, label)

        # the plots are drawn while a worker runs the final fit (they do not depend on it)
        draw = None
        if res is not None and not args.no_plots:
            plot_dir = res.tmp
            draw = lambda d: write_plots(d, plot_dir)  # noqa: E731
        diag = diagnose(doc, data, settings, progress=on_progress, during_final=draw)
        diag.lines = reduction.to_json_dict()
        prog.close()
        if res is not None:
            staged = write_outputs(diag, res.tmp, plots=False, warnings=warnings)
            content = __import__("json").loads(staged[0].read_text())
            written = res.commit(warnings=warnings, main="diagnosis.json")
        else:
            content = to_json_dict(diag, gaps(diag))
        print(summary(diag, content))
        if reduction.reduced:
            print(reduction.summary_line("diagnosed", figures=False))
        for line in cli.warn_lines(warnings):
            print(line)
        if res is not None:
            print(f"wrote {', '.join(str(p) for p in written)}")
        return 0

    return cli.run(body, args)


if __name__ == "__main__":
    sys.exit(main())
