"""Blind benchmark of ``python -m bondid.diagnose`` over machine designs and data regimes.

Each case builds a *truth* machine from one design (``tools/benchmark/designs.py``: the
reference bonder, a second bonder, a gantry with a rotary head) with random 10–30 % parameter
errors and zero, one or two withheld effects built unlike the diagnosis's own candidates
(``tools/benchmark/truth.py``), measures it at two operating points in one data regime
(``coh``, ``nocoh``, ``harsh``, ``acc``: ``tools/benchmark/regimes.py``) and writes CSV files
to a temporary folder. ``python -m bondid.diagnose`` then runs as a subprocess with ONLY the
nominal URDF and those files, and ``python -m bondid.fit --free all`` on the same files, both
timed in the same run.

Scores per case: effect class and location of the verdict (two-effect cases: both effects in
``diagnosis.json``'s ``effects`` list, class and location, and no third), the verdict's
``gap_closed`` against the truth model's own, the screening recall (when candidates carry
``refitted``/``screened``), wall times. Prints one Markdown row per case and a summary per
design × regime.

Usage: ``python tools/blind_benchmark.py [--designs D,..] [--regimes R,..] [--cases NAME,..]
[--quick] [--jobs N] [--out rows.json]``; ``--list`` prints the cases.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT / "tools")]

from benchmark.cases import QUICK, Case, all_cases, leave_one_out, open_cases  # noqa: E402
from benchmark.designs import DESIGNS  # noqa: E402
from benchmark.regimes import REGIMES  # noqa: E402
from benchmark.runner import STOPPING, Settings, run_case, stop_on_sigterm  # noqa: E402
from benchmark.tables import case_table, open_table, summary_table  # noqa: E402


def _names(text: str | None, valid: tuple[str, ...] | list[str], what: str) -> list[str]:
    if not text:
        return list(valid)
    names = [t.strip() for t in text.split(",") if t.strip()]
    bad = [n for n in names if n not in valid]
    if bad:
        raise SystemExit(
            f"blind_benchmark: unknown {what} {', '.join(bad)}; valid: {', '.join(valid)}"
        )
    return names


def select(args: argparse.Namespace) -> list[Case]:
    """The cases named by ``--cases`` (in the order named, so that a run stopped early has
    the broadest subset first; else ``--quick``'s or all), kept to ``--designs`` and
    ``--regimes``."""
    cases = open_cases() if args.open else all_cases()
    if args.cases:
        wanted = _names(args.cases, [c.name for c in cases], "case")
        by_name = {c.name: c for c in cases}
        cases = [by_name[n] for n in dict.fromkeys(wanted)]
    elif args.quick:
        cases = [c for c in cases if c.name in QUICK]
    designs = _names(args.designs, list(DESIGNS), "design")
    regimes = _names(args.regimes, REGIMES, "regime")
    return [c for c in cases if c.design in designs and c.regime in regimes]


def parse(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    p.add_argument("--designs", help=f"comma-separated, of {', '.join(DESIGNS)} (default all)")
    p.add_argument("--regimes", help=f"comma-separated, of {', '.join(REGIMES)} (default all)")
    p.add_argument("--cases", help="comma-separated case names (see --list)")
    p.add_argument("--quick", action="store_true", help="3 small cases, 300 frequencies")
    p.add_argument(
        "--open",
        action="store_true",
        help="the open-world cases (later causes and causes outside the library)",
    )
    p.add_argument("--leave-one-out", action="store_true",
                   help="each case diagnosed without its own effect classes among the "
                   "candidates (the leave-one-class-out run)")  # fmt: skip
    p.add_argument("--list", action="store_true", help="print the selected cases and stop")
    p.add_argument("--jobs", type=int, default=1, help="cases in parallel (default 1)")
    p.add_argument("--freq", type=int, help="frequencies per data file (default 2000; quick 300)")
    p.add_argument("--points", type=int, help="diagnose --points (default 500; quick 120)")
    p.add_argument("--workers", type=int, default=2, help="diagnose --workers (default 2)")
    p.add_argument("--effects", help="diagnose --effects subset (for quick checks only)")
    p.add_argument("--no-fit", action="store_true", help="do not time bondid.fit")
    p.add_argument("--no-visibility", action="store_true",
                   help="single-effect cases as listed: no oracle check that strengthens "
                   "an effect the data do not show (benchmark/visibility.py)")  # fmt: skip
    p.add_argument("--out", type=Path, help="write the rows as JSON (after every case)")
    p.add_argument("--resume", action="store_true",
                   help="keep the rows --out already holds and run only the cases it lacks "
                   "(a long run that was stopped goes on where it was)")  # fmt: skip
    p.add_argument("--tables", type=Path, help="print the tables of a rows JSON (--out) and stop")
    p.add_argument("--keep", type=Path,
                   help="copy each case's data files and outputs into KEEP/<case>/")  # fmt: skip
    args = p.parse_args(argv)
    if args.jobs < 1:
        p.error(f"--jobs {args.jobs}: give 1 or more")
    if args.resume and not args.out:
        p.error("--resume continues the rows of --out FILE: give --out")
    return args


def earlier_rows(path: Path) -> dict[str, dict[str, Any]]:
    """The finished rows of an earlier run's ``--out`` file, by case name (rows that ended
    in an error are run again); none when the file does not exist yet."""
    if not path.exists():
        return {}
    try:
        rows = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise SystemExit(f"blind_benchmark: --resume: cannot read {path}: {exc}") from exc
    if not isinstance(rows, list):
        raise SystemExit(f"blind_benchmark: --resume: {path} holds no list of rows")
    return {r["case"]: r for r in rows if isinstance(r, dict) and "case" in r and "error" not in r}


def write_rows(path: Path, rows: list[dict[str, Any]]) -> None:
    """``rows`` as JSON at ``path``, replaced atomically (a stop mid-write keeps the last)."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(rows, indent=2, default=float) + "\n")
    os.replace(tmp, path)


def settings(args: argparse.Namespace) -> Settings:
    """The runner's settings of the command line ``args``."""
    return Settings(
        freq=args.freq or (300 if args.quick else 2000),
        points=args.points or (120 if args.quick else 500),
        workers=args.workers, effects=args.effects, fit=not args.no_fit, keep=args.keep,
        visibility=not args.no_visibility,
    )  # fmt: skip


def tables(rows: list[dict[str, Any]]) -> str:
    """The per-case table and the summary; the open-world table too when a cause was left
    out of the candidates (an open-world or leave-one-class-out run)."""
    out = case_table(rows) + "\n\n" + summary_table(rows)
    if any(r.get("left_out") for r in rows):
        out += "\n\n" + open_table(rows)
    return out


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    if args.tables:  # e.g. the rows a long run wrote before it was stopped
        rows = json.loads(args.tables.read_text())
        print(tables(rows))
        return 0
    cases = select(args)
    if args.list:
        for c in cases:
            print(f"{c.name}: {c.label} @ {c.where}")
        return 0
    s = settings(args)
    earlier = earlier_rows(args.out) if args.resume else {}
    done: list[dict[str, Any]] = [earlier[c.name] for c in cases if c.name in earlier]
    if earlier:
        print(f"resuming: {len(done)} of {len(cases)} cases already in {args.out}", flush=True)

    def one(c: Case) -> dict[str, Any]:
        if c.name in earlier:
            return earlier[c.name]
        cs = s
        if args.leave_one_out:  # the candidates without the case's own classes
            base = tuple(args.effects.split(",")) if args.effects else None
            cs = dataclasses.replace(s, effects=",".join(leave_one_out(c, base)))
        try:
            r = run_case(c, cs)
        except Exception as exc:  # one broken case must not lose the others
            truth = [[e.effect, e.location] for e in c.effects]
            r = {"case": c.name, "design": c.design, "regime": c.regime, "truth": truth,
                 "error": repr(exc)}  # fmt: skip
        if STOPPING.is_set():  # a case cut short by SIGTERM is not a result
            return r
        got = r.get("error") or ", ".join(f"{e}@{loc}" for e, loc in r["claimed"]) or "none"
        took = f"diagnose {r.get('diagnosis_s', 0):.0f} s, fit {r.get('fit_s', 0):.0f} s"
        print(f"{c.name}: {got} (truth {c.label} @ {c.where}) {took}", flush=True)
        done.append(r)
        if args.out:  # rows so far, so a long run that stops keeps what it did
            write_rows(args.out, done)
        return r

    stop_on_sigterm()
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(one, cases))
    print()
    print(tables(rows))
    if args.out:
        write_rows(args.out, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
