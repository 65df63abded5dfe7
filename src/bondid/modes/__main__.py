"""``python -m bondid.modes``: the mode table of a model, ``modes.json`` and a Meshcat scene.

Examples::

    python -m bondid.modes --model urdf/bonder.urdf
    python -m bondid.modes --model urdf/bonder.urdf --q x=0.02 y=-0.01 --out results/ --mode 6
    python -m bondid.modes --model urdf/bonder.urdf --fitted results/fitted.urdf --serve

Writes under ``--out``: ``modes.json`` (spec §4) and ``modes.html`` (static, offline page
animating the chosen mode; ``--all-modes`` adds ``mode_NN.html`` for every vibration mode).
``--serve`` keeps a live Meshcat server running (URL printed) until Ctrl-C.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..cli import Progress, add_model_args, make_parser, run
from ..exceptions import ConfigError
from .analysis import ModalResult, Mode, match_mode, modal_analysis


def _parser():
    p = make_parser("modes", "Modal analysis of the linearised model; mode shapes in Meshcat.")
    add_model_args(p, data=False, out=True)
    p.add_argument(
        "--q",
        nargs="+",
        default=None,
        metavar="JOINT=VALUE",
        help="operating point, e.g. --q x=0.01 y=0 (m or rad; others neutral)",
    )
    p.add_argument(
        "--mode",
        type=int,
        default=None,
        help="mode number (table index) to animate; default the lowest vibration mode",
    )
    p.add_argument(
        "--amplitude",
        type=float,
        default=0.05,
        help="largest displacement as a fraction of the machine's size (default 0.05)",
    )
    p.add_argument(
        "--fitted",
        type=Path,
        default=None,
        help="a fitted URDF of the same machine, shown beside the nominal one",
    )
    p.add_argument(
        "--serve",
        action="store_true",
        help="start a live Meshcat server, print its URL, run until Ctrl-C",
    )
    p.add_argument("--no-html", action="store_true", help="do not write modes.html")
    p.add_argument(
        "--all-modes", action="store_true", help="also write mode_NN.html for every vibration mode"
    )
    return p


#: the names ``bondid.modes`` may write under ``--out``
OUT_PATTERNS = ("modes.json", "modes.html", "mode_*.html")


def _analyse(
    path: Path, op: dict[str, float], args: Any, warnings: list[str]
) -> tuple[object, ModalResult]:
    from ..cli import apply_model_options
    from ..linear import build_affine_model
    from ..validation import check_inputs, load_model

    doc, found = load_model(path, lambda d: apply_model_options(d, args))
    warnings += found + check_inputs(doc, operating_points={"--q": op})
    aff = build_affine_model(doc, op)
    return doc, modal_analysis(aff.linear_model(), op)


def _default_mode(result: ModalResult) -> int:
    vib = result.vibration_modes()
    return vib[0].index if vib else 1


def _paired(mode: Mode, other: ModalResult) -> Mode:
    pool = [m for m in other.modes if m.kind == mode.kind] or other.modes
    return match_mode(mode, pool)


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)

    def body() -> int:
        from ..linear import parse_operating_point

        if not 0 < args.amplitude < float("inf"):
            raise ConfigError(
                f"--amplitude {args.amplitude}: must be a finite number > 0 (fraction of size)"
            )
        op = parse_operating_point(" ".join(args.q or []), "--q")
        res = None
        if args.out is not None:
            from ..results import open_results

            inputs = [args.model] + ([args.fitted] if args.fitted is not None else [])
            res = open_results(args.out, "modes", inputs, patterns=OUT_PATTERNS)
        warnings: list[str] = []
        doc, result = _analyse(args.model, op, args, warnings)
        fitted = _analyse(args.fitted, op, args, warnings) if args.fitted is not None else None
        index = args.mode if args.mode is not None else _default_mode(result)
        if not 1 <= index <= len(result.modes):
            raise ConfigError(f"--mode {index}: {args.model} has modes 1..{len(result.modes)}")

        print(f"modes of {args.model} at {op or 'q = neutral'}:")
        print(result.table())
        if fitted is not None:
            print(f"\nmodes of the fitted model {args.fitted}:")
            print(fitted[1].table())
        for w in warnings:
            print(f"warning: {w}")

        if res is not None:
            _write_outputs(args, res.tmp, doc, result, fitted, index, warnings)
            res.commit(warnings=warnings, main="modes.json")
            print(f"wrote {args.out / 'modes.json'}" + ("" if args.no_html else " and pages"))
        if args.serve:
            _serve(args, doc, result, fitted, index)
        return 0

    return run(body, args)


def _scene(args, doc, result: ModalResult, fitted, index: int):
    from .viewer import build_mode_scene, mode_caption

    mode = result.mode(index)
    extra, fmode = None, None
    if fitted is not None:
        fdoc, fres = fitted
        fmode = _paired(mode, fres)
        extra = (fdoc, fres.q0, fmode, fres.dofs)
    scene = build_mode_scene(
        doc, result.q0, mode, result.dofs, amplitude=args.amplitude, fitted=extra, quiet=True
    )
    return scene, mode_caption(mode, fmode)


def _write_outputs(
    args, out: Path, doc, result: ModalResult, fitted, index: int, warnings: list[str]
) -> None:
    """Write modes.json and the pages into ``out`` (the run's staging folder)."""
    from ..atomic import write_text_atomic

    if not args.no_html:
        from .viewer import write_mode_html

        todo = [(index, "modes.html")]
        if args.all_modes:
            todo += [(m.index, f"mode_{m.index:02d}.html") for m in result.vibration_modes()]
        prog = Progress("modes: writing HTML", len(todo), quiet=args.quiet)
        for k, name in todo:
            scene, caption = _scene(args, doc, result, fitted, k)
            with scene:
                write_mode_html(out / name, scene, f"{Path(args.model).name} mode {k}", caption)
            result.html[k] = name
            prog.update(1, name)
        prog.close(f"{len(todo)} page(s) in {args.out}")
    data = result.to_dict()
    data["model"] = str(args.model)
    data["animated_mode"] = index
    data["amplitude"] = args.amplitude
    if fitted is not None:
        fdata = fitted[1].to_dict()
        data["fitted"] = {"model": str(args.fitted), "modes": fdata["modes"]}
    data["warnings"] = list(warnings)
    write_text_atomic(out / "modes.json", json.dumps(data, indent=2) + "\n")


def _serve(args, doc, result: ModalResult, fitted, index: int) -> None:
    import signal

    def _stop(signum, frame):  # SIGTERM ends the loop like Ctrl-C, so the server is killed
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, _stop)
    scene, _ = _scene(args, doc, result, fitted, index)
    with scene:
        print(f"Meshcat: open {scene.url} (mode {index}); Ctrl-C to stop", flush=True)
        try:
            while True:
                time.sleep(0.5)
        except KeyboardInterrupt:
            print("stopped", file=sys.stderr)


if __name__ == "__main__":
    from ..interrupt import exit_process

    exit_process(main())
