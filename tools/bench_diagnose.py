"""Benchmark: how long ``bondid.diagnose`` takes against ``bondid.fit`` on the same files.

For each benchmark case (``tools/benchmark``: a design, a data regime, withheld effects, made
visible as the blind benchmark makes them) the case's files are written once (``--data``,
reused when present), then the diagnosis (A) and the fit (B) of the same files run in turn,
A B A B …, and the ratio A/B is taken pair by pair: a machine that slows down during the run
weighs on both.
Each command is a fresh process with single-threaded BLAS; the diagnosis has ``--workers``
local worker processes. Printed per case: the truth, the verdict and outcome, the fit's and
the diagnosis's median wall times and the median ratio; then the median and worst ratio.

``--scaling 2,4`` times the diagnosis with the second number of workers (A) against the
first (B) instead: the speed-up from more local workers.

Usage::

    python tools/bench_diagnose.py [--cases NAME,...] [--freq 2000] [--workers 2] [--runs 2]
        [--data DIR] [--json rows.json] [--scaling 2,4]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT / "tools")]

#: every effect class on every design (four designs), two regimes each, and "none" cases
CASES = (
    "bonder/jct/coh", "bonder/sd/coh", "bonder/sm/acc", "bonder/none_a/coh",
    "bonder_b/jcr/harsh", "bonder_b/fb/nocoh", "bonder_b/al/coh", "bonder_b/sm/coh",
    "gantry/fb/coh", "gantry/al/nocoh", "gantry/jct/harsh", "gantry/none_b/acc",
    "polar/sm/mob", "polar/jct2/acc", "polar/sd/nocoh", "bonder/jcr+al/coh",
)  # fmt: skip


def case_files(name: str, folder: Path, freq: int) -> dict[str, Any]:
    """The files of benchmark case ``name`` in ``folder`` (written when missing) and its
    description (``model``, ``files``, ``truth``)."""
    meta = folder / "case.json"
    if meta.exists():
        return json.loads(meta.read_text())
    from benchmark.cases import all_cases
    from benchmark.designs import design
    from benchmark.regimes import measure
    from benchmark.truth import signal_factor, truth_model
    from benchmark.visibility import frequencies, visible_case

    from bondid.model import UrdfDocument

    case = {c.name: c for c in all_cases()}[name]
    case, _ = visible_case(case, freq)
    dz = design(case.design)
    truth = truth_model(UrdfDocument.load(dz.path), case.effects, case.seed)
    folder.mkdir(parents=True, exist_ok=True)

    def factor(f, outs, ins):  # type: ignore[no-untyped-def]
        return signal_factor(case.effects, f, outs, ins)

    paths, _ = measure(truth, dz.operating_points, frequencies(freq), case.regime, factor,
                       folder, case.seed)  # fmt: skip
    out = {"case": name, "model": str(dz.path), "files": [p.name for p in paths],
           "truth": [f"{e.effect}@{e.location}" for e in case.effects] or ["none"]}  # fmt: skip
    meta.write_text(json.dumps(out, indent=1) + "\n")
    return out


def commands(meta: dict[str, Any], folder: Path, workers: int) -> tuple[list[str], list[str]]:
    """(diagnosis, fit) command lines of a case; the diagnosis writes ``folder/diag``."""
    data = [str(folder / f) for f in meta["files"]]
    py = sys.executable
    diag = [py, "-m", "bondid.diagnose", "--model", meta["model"], "--data", *data, "--out",
            str(folder / "diag"), "--quiet", "--no-plots", "--workers", str(workers)]  # fmt: skip
    fit = [py, "-m", "bondid.fit", "--model", meta["model"], "--data", *data, "--quiet"]
    return diag, fit


def alternate(a: list[str], b: list[str], runs: int, timeout: int) -> dict[str, float]:
    """Median wall times [s] of ``a`` and ``b``, run in turn ``runs`` times, and the median
    ratio of the pairs' wall times (a command past ``timeout`` s counts as ``timeout``)."""
    ta, tb, ratios = [], [], []
    for _ in range(runs):
        pair = []
        for cmd in (a, b):
            t0 = time.perf_counter()
            with contextlib.suppress(subprocess.TimeoutExpired):
                subprocess.run(cmd, capture_output=True, check=False, timeout=timeout)
            pair.append(time.perf_counter() - t0)
        ta.append(pair[0])
        tb.append(pair[1])
        ratios.append(pair[0] / pair[1])
    return {"a_s": statistics.median(ta), "b_s": statistics.median(tb),
            "ratio": statistics.median(ratios)}  # fmt: skip


def verdict(folder: Path) -> tuple[str, str]:
    """(kept effects, outcome) of the case's last diagnosis."""
    try:
        d = json.loads((folder / "diag" / "diagnosis.json").read_text())
    except (OSError, ValueError):
        return "failed", ""
    effects = [f"{e['effect']}@{e['location']}" for e in d.get("effects") or []]
    return " + ".join(effects) or "none", str(d["verdict"].get("outcome", ""))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated case names")
    ap.add_argument("--freq", type=int, default=2000, help="lines per data file")
    ap.add_argument("--workers", type=int, default=2, help="the diagnosis's --workers")
    ap.add_argument("--runs", type=int, default=2, help="pairs per case")
    ap.add_argument("--timeout", type=int, default=3600, help="seconds per case at most")
    ap.add_argument("--data", type=Path, default=None, help="folder of the case files")
    ap.add_argument("--json", type=Path, default=None, help="write the rows here")
    ap.add_argument(
        "--scaling",
        default=None,
        metavar="W1,W2",
        help="time the diagnosis with W2 workers against W1 instead of the fit",
    )
    args = ap.parse_args(argv)
    data = args.data or Path(tempfile.mkdtemp(prefix="bondid-bench-"))
    rows = []
    print(
        f"| case | truth | verdict | outcome | {'B' if args.scaling else 'fit'} s | "
        f"{'A' if args.scaling else 'diagnose'} s | ratio |\n|---|---|---|---|---|---|---|"
    )
    for name in [c.strip() for c in args.cases.split(",") if c.strip()]:
        folder = data / name.replace("/", "__")
        meta = case_files(name, folder, args.freq)
        diag, fit = commands(meta, folder, args.workers)
        if args.scaling:
            w1, w2 = (int(x) for x in args.scaling.split(","))
            diag = commands(meta, folder, w2)[0]
            fit = commands(meta, folder, w1)[0]
        t = alternate(diag, fit, args.runs, args.timeout)
        got, outcome = verdict(folder)
        row = {"case": name, "truth": " + ".join(meta["truth"]), "verdict": got,
               "outcome": outcome, "workers": args.workers, **t}  # fmt: skip
        rows.append(row)
        print(f"| {name} | {row['truth']} | {got} | {outcome} | {t['b_s']:.1f} | "
              f"{t['a_s']:.1f} | {t['ratio']:.2f} |", flush=True)  # fmt: skip
        if args.json:
            args.json.write_text(json.dumps(rows, indent=1) + "\n")
    ratios = [r["ratio"] for r in rows if r["ratio"] == r["ratio"]]
    if ratios:
        print(
            f"\nmedian ratio {statistics.median(ratios):.2f}, worst {max(ratios):.2f}, "
            f"{len(ratios)} cases"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
