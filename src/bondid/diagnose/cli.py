"""The command line of ``python -m bondid.diagnose``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path


def build_parser() -> argparse.ArgumentParser:
    from .. import cli
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
    p.add_argument(
        "--channels", default=None,
        help="OUT.IN channels to use, comma-separated (default: those above the noise floor)",
    )  # fmt: skip
    p.add_argument("--points", type=int, default=500, help="frequencies per data set for refits")
    p.add_argument("--workers", type=int, default=2, help="worker processes (1 = in-process)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument(
        "--weighting", default="auto", choices=["auto", "coherence", "estimated", "none"],
        help="point weights: auto (coherence combined with the noise estimated from the data,"
        " the estimate alone without coherence; default), coherence, estimated or none",
    )  # fmt: skip
    return p


def main(argv: Sequence[str] | None = None) -> int:
    from .. import cli

    args = build_parser().parse_args(argv)

    def body() -> int:
        from ..data.for_model import load_datasets
        from ..exceptions import ConfigError
        from ..model.document import UrdfDocument
        from .pipeline import Settings, diagnose
        from .report import gaps, summary, to_json_dict, write_outputs

        doc = UrdfDocument.load(args.model)
        cli.apply_model_options(doc, args)
        if args.out is not None:
            from ..atomic import refuse_overwrite

            refuse_overwrite(Path(args.out) / "diagnosis.json", [args.model, *args.data])
        data = load_datasets(doc, args.data, channel_map=cli.uff_channel_map(args))
        if args.points < 20:
            raise ConfigError(f"--points {args.points}: need at least 20")
        settings = Settings(
            effects=cli.split_names([args.effects]) if args.effects else None,
            free=cli.split_names(args.free) if args.free else None,
            bands=args.band,
            channels=cli.split_names([args.channels]) if args.channels else None,
            n_points=args.points,
            workers=max(1, args.workers),
            weighting=args.weighting,
        )
        prog = cli.Progress("diagnose", quiet=args.quiet)

        def on_progress(done: int, total: int, label: str) -> None:
            prog.total = total
            prog.count = done - 1
            prog.update(1, label)

        diag = diagnose(doc, data, settings, progress=on_progress)
        prog.close()
        if args.out is not None:
            written = write_outputs(diag, Path(args.out), plots=not args.no_plots)
            content = __import__("json").loads(written[0].read_text())
        else:
            content = to_json_dict(diag, gaps(diag))
        print(summary(diag, content))
        if args.out is not None:
            print(f"wrote {', '.join(str(p) for p in written)}")
        return 0

    return cli.run(body)


if __name__ == "__main__":
    sys.exit(main())
