"""``python -m bondid.report [RESULTS_DIR] [--out DIR]``: one self-contained HTML page.

Gathers fit.json, sensitivity.json, diagnosis.json, modes.json and the PNG plots found in
RESULTS_DIR (and its sub-folders) into ``report.html`` (in --out, default RESULTS_DIR).
``python -m bondid.report --out DIR`` reports on DIR itself. Exit 2 when neither is given,
the folder does not exist or it holds nothing to report.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from ..cli import make_parser, run


def main(argv: Sequence[str] | None = None) -> int:
    p = make_parser("report", "One offline HTML page from a results folder.")
    p.add_argument(
        "results", type=Path, nargs="?", default=None,
        help="results folder (fit.json, modes.json, PNGs, ...; default: --out)",
    )  # fmt: skip
    p.add_argument(
        "--out", type=Path, default=None, help="folder for report.html (default: RESULTS)"
    )
    p.add_argument("--quiet", action="store_true", help="print nothing on success")
    args = p.parse_args(argv)
    if args.results is None and args.out is None:
        p.error("give the results folder (RESULTS_DIR or --out DIR)")

    def body() -> int:
        from ..paths import check_output_path
        from ..results import open_results
        from .build import REPORT_NAME, build_report_html
        from .inputs import check_folder, check_results, manifest_warnings, with_warnings

        results = Path(args.results or args.out)
        check_output_path(results, "RESULTS_DIR")
        out = Path(args.out) if args.out is not None else results
        same = out.absolute() == results.absolute()
        check_folder(results, restoring=same)
        res = open_results(out, "report", [], patterns=(REPORT_NAME,))
        for command, what in res.recovered.items():
            print(f"note: {results}: an interrupted commit of bondid.{command} was {what}"
                  f" ({'its results kept' if what == 'done' else 'the previous results restored'})",
                  file=sys.stderr)  # fmt: skip
        check_folder(results, restoring=False)
        check_results(results)
        warnings = manifest_warnings(results)
        text, _ = build_report_html(results, out)
        text = with_warnings(text, warnings)
        res.path(REPORT_NAME).write_text(text, encoding="utf-8")
        res.commit(warnings=warnings, main=REPORT_NAME)
        path = out / REPORT_NAME
        for w in warnings:
            print(f"warning: {w}", file=sys.stderr)
        if not args.quiet:
            print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB)")
        return 0

    return run(body, args)


if __name__ == "__main__":
    from ..interrupt import exit_process

    exit_process(main())
