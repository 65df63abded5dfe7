"""Benchmark: ``python -m bondid.fleet`` on 50 synthetic machines of the reference bonder.

The fleet: ``urdf/bonder.urdf`` with the six parasitic stiffnesses below drawn uniformly in
±10 % of the nominal per machine, two planted faults (machine m07: y-guide rx 40 % softer;
m31: z-bearing ry 40 % stiffer), 2 % relative noise with a −70 dB sensor floor, two operating
points (all joints at 0, and x=0.05 y=−0.03 z=0.1), ``--freq`` log-spaced frequencies
(default 2000, 1–4000 Hz), 9 channels. Every machine is fitted with those six stiffnesses free
(``bondid.fit`` defaults otherwise: complex-log cost, ±50 % bounds).

The same command runs once per worker count (default 1 and 2 local worker processes), each in
a fresh output folder and as its own process (``python -m bondid.fleet``, so the wall time
includes starting the local Dask cluster); the table gives the wall time, machines per minute,
the median time of one machine inside a worker, and which outliers were found against the
planted ones.

Usage::

    python tools/bench_fleet.py [--machines 50] [--workers 1 2] [--freq 1:4000:2000]
        [--out /tmp/bench_fleet] [--png docs/fleet_strip.png] [--json bench_fleet.json]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT / "src") not in sys.path:
    sys.path.insert(0, str(ROOT / "src"))

from bondid.cli import parse_freq  # noqa: E402

NOMINAL = ROOT / "urdf" / "bonder.urdf"
FREE = [
    "x_guide_ry.stiffness",
    "x_guide_rz.stiffness",
    "y_guide_tx.stiffness",
    "y_guide_rx.stiffness",
    "y_guide_rz.stiffness",
    "z_bearing_ry.stiffness",
]
FAULTS = {"m07": {"y_guide_rx.stiffness": 0.6}, "m31": {"z_bearing_ry.stiffness": 1.4}}
OPERATING_POINTS = ({}, {"x": 0.05, "y": -0.03, "z": 0.1})


def make(out: Path, n: int, freq: tuple[float, float, int], seed: int) -> None:
    from bondid.fleet.synthetic import make_fleet
    from bondid.model.document import UrdfDocument

    make_fleet(
        UrdfDocument.load(NOMINAL), out, n_machines=n, parameters=FREE, spread=0.10,
        faults=FAULTS, operating_points=OPERATING_POINTS, freq=freq, noise=0.02, seed=seed,
    )  # fmt: skip


def run_fleet(machines: Path, out: Path, workers: int) -> dict[str, Any]:
    """One fleet run in its own process; returns wall time, throughput and what it found."""
    shutil.rmtree(out, ignore_errors=True)
    cmd = [sys.executable, "-m", "bondid.fleet", "--model", str(NOMINAL)]
    cmd += ["--machines", str(machines), "--out", str(out), "--workers", str(workers)]
    cmd += ["--free", *FREE]
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    load1 = os.getloadavg()[0]
    if proc.returncode == 2:
        sys.exit(f"bench_fleet: the fleet command refused its input:\n{proc.stderr}")
    doc = json.loads((out / "fleet.json").read_text())
    walls = [m["wall_s"] for m in doc["machines"] if m.get("wall_s") is not None]
    solves = []
    for m in doc["machines"]:
        st = json.loads((out / m["results"] / "status.json").read_text())
        if st.get("fit") and st["fit"].get("wall_s") is not None:
            solves.append(st["fit"]["wall_s"])
    n = doc["counts"]["machines"]
    return {
        "workers": workers,
        "load_1min": [load0, load1],  # the machine's load average before / after (shared)
        "exit_code": proc.returncode,
        "machines": n,
        "failed": doc["counts"]["failed"],
        "wall_s": wall,
        "machines_per_min": 60.0 * n / wall,
        "machine_s_median": statistics.median(walls) if walls else None,
        "machine_s_sum": sum(walls),
        "solve_s_median": statistics.median(solves) if solves else None,
        "outliers": sorted((o["machine"], o["parameter"]) for o in doc["outliers"]),
        "reasons": [f"{o['machine']}: {o['reason']}" for o in doc["outliers"]],
    }


def report(runs: list[dict[str, Any]]) -> str:
    planted = sorted((m, p) for m, d in FAULTS.items() for p in d)
    lines = [
        "| workers | machines | failed | wall [s] | machines / min | one machine in a worker,"
        " median [s] | of which the fit's solve [s] | outliers found | planted found |"
        " false alarms | load before / after |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        found = {tuple(o) for o in r["outliers"]}
        hit = sum(1 for p in planted if p in found)
        lines.append(
            f"| {r['workers']} | {r['machines']} | {r['failed']} | {r['wall_s']:.1f} |"
            f" {r['machines_per_min']:.1f} | {r['machine_s_median']:.2f} |"
            f" {r['solve_s_median']:.2f} | {len(found)} |"
            f" {hit}/{len(planted)} | {len(found) - hit} |"
            f" {r['load_1min'][0]:.1f} / {r['load_1min'][1]:.1f} |"
        )
    for r in runs[-1:]:
        lines += [f"outlier ({r['workers']} workers): {t}" for t in r["reasons"]]
    base = min(runs, key=lambda r: r["workers"])
    per = base["wall_s"] / base["machines"] * base["workers"]
    lines.append(
        f"cost of one machine (worker-seconds, from the {base['workers']}-worker run): {per:.2f} s;"
        f" 10,000 machines: {per * 1e4 / 3600:.1f} worker-hours"
        f" = {per * 1e4 / 3600 / 100:.2f} h on 100 workers"
    )
    return "\n".join(lines)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--machines", type=int, default=50)
    p.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    p.add_argument("--freq", type=parse_freq, default=(1.0, 4000.0, 2000))
    p.add_argument("--seed", type=int, default=2026)
    p.add_argument("--out", type=Path, default=Path("/tmp/bench_fleet"))
    p.add_argument("--png", type=Path, help="copy the last run's strip plot here")
    p.add_argument("--json", type=Path, help="write the figures as JSON")
    args = p.parse_args()
    machines = args.out / "machines"
    shutil.rmtree(machines, ignore_errors=True)
    t0 = time.perf_counter()
    make(machines, args.machines, args.freq, args.seed)
    print(f"made {args.machines} machines in {time.perf_counter() - t0:.1f} s", flush=True)
    runs = []
    for w in args.workers:
        runs.append(run_fleet(machines, args.out / f"run_w{w}", w))
        print(f"{w} worker(s): {runs[-1]['wall_s']:.1f} s", flush=True)
    print(report(runs))
    if args.png is not None:
        shutil.copyfile(args.out / f"run_w{args.workers[-1]}" / "fleet_strip.png", args.png)
    if args.json is not None:
        args.json.write_text(json.dumps(runs, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
