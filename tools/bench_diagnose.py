"""Benchmark: ``bondid.diagnose`` on the bundled reference case, this tree against a baseline
revision, side by side in one run, and against ``bondid.fit`` on the same files.

Issue 14's reference case: ``python -m bondid.diagnose --model urdf/bonder.urdf --data
data/bonder_q0.csv data/bonder_q1.csv`` (its goals: at most 60 s on a 2-core machine and at
most 4× the wall time of ``bondid.fit`` on the same data). The baseline is checked out into a
temporary git worktree; the two diagnoses run alternately (``--rounds`` pairs, the baseline
first in odd rounds, this tree first in even ones, so a machine that slows down during the
run weighs on both), each a fresh process with single-threaded BLAS, then ``bondid.fit`` of
this tree on the same files. Printed: every wall time, the medians, the ratio this tree /
baseline of the diagnoses and diagnose / fit of this tree, and each diagnosis's verdict.
Wall times on a shared machine are noisy: read the ratios, never one time alone.

Usage::

    python tools/bench_diagnose.py --baseline 9bdbf3b [--rounds 3] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "urdf" / "bonder.urdf"
DATA = [ROOT / "data" / "bonder_q0.csv", ROOT / "data" / "bonder_q1.csv"]


def _timed(cmd: list[str], src: Path) -> tuple[float, str]:
    """Wall time [s] of ``cmd`` run with ``src`` first on the Python path, and its stdout."""
    env = dict(os.environ, PYTHONPATH=str(src), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:]
        raise SystemExit(f"{' '.join(cmd[:4])} … failed ({done.returncode}): {tail}")
    return wall, done.stdout


def _diagnose(src: Path, out: Path) -> tuple[float, str]:
    """Wall time of one diagnosis of the reference case with the package at ``src``, and its
    verdict (effect@location, or none)."""
    cmd = [sys.executable, "-m", "bondid.diagnose", "--model", str(MODEL), "--data",
           *map(str, DATA), "--out", str(out), "--quiet"]  # fmt: skip
    wall, _ = _timed(cmd, src)
    v = json.loads((out / "diagnosis.json").read_text())["verdict"]
    return wall, v["effect"] + (f"@{v['location']}" if v.get("location") else "")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", required=True, help="git revision to compare with")
    ap.add_argument("--rounds", type=int, default=3, help="pairs of diagnoses (default 3)")
    ap.add_argument("--json", type=Path, help="write the times and ratios here")
    a = ap.parse_args(argv)
    if a.rounds < 1:
        ap.error("--rounds must be >= 1")
    times: dict[str, list[float]] = {"baseline": [], "this tree": []}
    verdicts: dict[str, set[str]] = {"baseline": set(), "this tree": set()}
    with tempfile.TemporaryDirectory(prefix="bondid_bench_diag_") as tmp:
        tree = Path(tmp) / "baseline"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(tree),
                        a.baseline], check=True)  # fmt: skip
        try:
            srcs = {"baseline": tree / "src", "this tree": ROOT / "src"}
            for k in range(a.rounds):
                order = ["baseline", "this tree"] if k % 2 == 0 else ["this tree", "baseline"]
                for who in order:
                    wall, verdict = _diagnose(srcs[who], Path(tmp) / f"{who}_{k}")
                    times[who].append(wall)
                    verdicts[who].add(verdict)
                    print(f"round {k + 1}: {who:9s} diagnose {wall:6.1f} s  ({verdict})")
            fit_cmd = [sys.executable, "-m", "bondid.fit", "--model", str(MODEL), "--data",
                       *map(str, DATA), "--out", str(Path(tmp) / "fit"), "--quiet"]  # fmt: skip
            fit_s, _ = _timed(fit_cmd, ROOT / "src")
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                            str(tree)], check=False)  # fmt: skip
    med = {who: statistics.median(t) for who, t in times.items()}
    ratio = med["this tree"] / med["baseline"]
    print(f"fit (this tree) {fit_s:.1f} s")
    new = med["this tree"]
    print(f"median diagnose: baseline {med['baseline']:.1f} s, this tree {new:.1f} s; this tree"
          f" / baseline {ratio:.2f}x; diagnose / fit {new / fit_s:.2f}x")  # fmt: skip
    if a.json:
        a.json.write_text(json.dumps({
            "baseline": a.baseline, "times_s": times, "fit_s": fit_s, "median_s": med,
            "ratio": ratio, "diagnose_over_fit": new / fit_s,
            "verdicts": {k: sorted(v) for k, v in verdicts.items()},
        }, indent=2) + "\n")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
