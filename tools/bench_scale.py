"""Time and peak memory of every command on dense data, against a baseline revision.

For each line count (default 2 000, 20 000 and 100 000 log-spaced lines from 1 to 4 000 Hz per
channel), the bundled bonder's truth (``data/truth/bonder_truth.urdf``, 3×3 channels) is
simulated at the two operating points of the bundled data (``bonder_q0``, ``bonder_q1``); then
each command runs on those files with this tree (A) and with a baseline tree (B, e.g. a git
worktree of the revision before the change), alternating A B A B. Each run is a separate
process (``python -m bondid.<command>``) with the given time limit and address-space limit;
its wall time and its peak resident memory (``wait4``'s ``ru_maxrss``, the largest process
it waited for) are recorded. The fit's figures — ``db_rms`` on all lines, the noise level and
the parameters against the truth — are compared between ``--lines auto`` and ``--lines all``
(this tree) and the baseline's fit.

    python tools/bench_scale.py --base ../base-worktree [--sizes 2000 20000 100000]
        [--commands simulate fit fit_all sensitivity diagnose] [--repeats 1]
        [--timeout 1800] [--mem-gib 12] [--out /tmp/bench_scale]

Writes ``bench_scale.json`` and ``bench_scale.md`` (the table) under ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "urdf" / "bonder.urdf"
TRUTH = ROOT / "data" / "truth" / "bonder_truth.urdf"
OPERATING_POINTS = {"q0": [], "q1": ["x=0.05", "y=-0.03", "z=0.1"]}
COMMANDS = ("simulate", "fit", "fit_all", "sensitivity", "diagnose")
#: the main result file of each command (a run that wrote none failed)
RESULTS = ("fit.json", "sensitivity.json", "diagnosis.json")
#: commands run by this tree only (the baseline has no such option)
A_ONLY = ("fit_all",)


def _limits(mem_bytes: int) -> Any:
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (mem_bytes, mem_bytes))
        os.setsid()

    return apply


def run_one(
    src: Path, argv: list[str], log: Path, timeout: float, mem_bytes: int
) -> dict[str, Any]:
    """Run ``python -m bondid.<...> argv`` with ``src`` on the path; wall time, peak RSS,
    exit code and whether the time limit ended it."""
    env = dict(os.environ, PYTHONPATH=str(src), OPENBLAS_NUM_THREADS="1")
    t0 = time.perf_counter()
    with open(log, "w") as out:
        proc = subprocess.Popen(
            [sys.executable, "-m", *argv],
            stdout=out,
            stderr=subprocess.STDOUT,
            env=env,
            preexec_fn=_limits(mem_bytes),
            stdin=subprocess.DEVNULL,
        )
        timed_out = False
        deadline = t0 + timeout
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() > deadline:
                os.killpg(proc.pid, 9)
                timed_out = True
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.2)
    wall = time.perf_counter() - t0
    code = os.waitstatus_to_exitcode(status)
    return {
        "wall_s": wall,
        "peak_mib": usage.ru_maxrss / 1024.0,
        "exit": code,
        "timed_out": timed_out,
        "log": str(log),
    }


def command_argv(cmd: str, size: int, files: list[Path], out: Path) -> list[str]:
    """The command line of ``cmd`` on the data ``files`` (``out``: results folder/file)."""
    data = [str(f) for f in files]
    if cmd == "fit":
        return ["bondid.fit", "--model", str(MODEL), "--data", *data, "--out", str(out), "--quiet"]
    if cmd == "fit_all":
        return [*command_argv("fit", size, files, out), "--lines", "all"]
    if cmd == "sensitivity":
        return [
            "bondid.sensitivity",
            "--model",
            str(MODEL),
            "--data",
            *data,
            "--out",
            str(out),
            "--no-sweep",
            "--quiet",
        ]
    if cmd == "diagnose":
        return [
            "bondid.diagnose",
            "--model",
            str(MODEL),
            "--data",
            *data,
            "--out",
            str(out),
            "--effects",
            "sensor_delay",
            "--quiet",
        ]
    raise ValueError(cmd)


def simulate_argv(size: int, pose: str, out: Path, seed: int) -> list[str]:
    return [
        "bondid.simulate",
        "--model",
        str(TRUTH),
        "--out",
        str(out),
        "--freq",
        f"1:4000:{size}",
        "--seed",
        str(seed),
        "--quiet",
        "--q",
        *OPERATING_POINTS[pose],
    ]


def truth_values(names: list[str]) -> dict[str, float]:
    sys.path.insert(0, str(ROOT / "src"))
    from bondid.model import UrdfDocument, get_parameter

    doc = UrdfDocument.load(TRUTH)
    return {n: float(get_parameter(doc, n)) for n in names}


def fit_figures(fit_json: Path) -> dict[str, Any] | None:
    """db_rms (final, on every line the baseline or this tree reports), noise level, lines
    and the fitted parameters of a ``fit.json`` (None when missing)."""
    if not fit_json.is_file():
        return None
    d = json.loads(fit_json.read_text())
    params = {p["name"]: p for p in d["parameters"] if p.get("fitted") is not None}
    truth = truth_values(list(params))
    err = [abs(params[n]["fitted"] / t - 1.0) for n, t in truth.items() if t != 0]
    return {
        "status": d.get("status"),
        "db_rms": d["db_rms"]["final"],
        "noise_level": d["db_rms"].get("noise_level"),
        "kept_lines": (d.get("lines") or {}).get("kept"),
        "lines": (d.get("lines") or {}).get("lines"),
        "wall_s_fit": d.get("wall_s"),
        "median_rel_err_vs_truth": sorted(err)[len(err) // 2] if err else None,
        "max_rel_err_vs_truth": max(err) if err else None,
        "fitted": {n: p["fitted"] for n, p in params.items()},
        "std": {n: p.get("std") for n, p in params.items()},
    }


def compare_fits(a: dict[str, Any], b: dict[str, Any]) -> dict[str, Any]:
    """Parameter differences of two fits: relative, and in units of the larger std."""
    rel, zs = [], []
    for n, va in a["fitted"].items():
        vb = b["fitted"].get(n)
        if vb is None or vb == 0:
            continue
        rel.append(abs(va / vb - 1.0))
        sd = max(a["std"].get(n) or 0.0, b["std"].get(n) or 0.0)
        if sd > 0:
            zs.append(abs(va - vb) / sd)
    med = sorted(rel)[len(rel) // 2] if rel else math.nan
    return {
        "median_rel_diff": med,
        "max_rel_diff": max(rel, default=math.nan),
        "max_diff_in_std": max(zs, default=math.nan),
        "median_diff_in_std": sorted(zs)[len(zs) // 2] if zs else math.nan,
    }


def _fmt(x: float | None, spec: str = ".1f") -> str:
    return "—" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def table(rows: list[dict[str, Any]]) -> str:
    """The markdown table: per size and command, median wall time and peak memory of A and B,
    and their ratios (A/B)."""
    out = [
        "| lines/channel | command | A time [s] | A peak [MiB] | B time [s] | B peak [MiB] |"
        " time A/B | peak A/B |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        a, b = r.get("A"), r.get("B")

        def cell(x: dict[str, Any] | None, key: str) -> str:
            if x is None:
                return "—"
            v = _fmt(x[key], ".0f" if key == "peak_mib" else ".1f")
            if x["timed_out"]:
                return f">{v} (time limit)"
            return v if x.get("results", True) else f"{v} (failed, exit {x['exit']})"

        ok = a and b and not b["timed_out"] and b.get("results", True)
        tr = _fmt(a["wall_s"] / b["wall_s"], ".2f") if ok else "—"
        pr = _fmt(a["peak_mib"] / b["peak_mib"], ".2f") if ok else "—"
        out.append(
            f"| {r['size']} | {r['command']} | {cell(a, 'wall_s')} | {cell(a, 'peak_mib')}"
            f" | {cell(b, 'wall_s')} | {cell(b, 'peak_mib')} | {tr} | {pr} |"
        )
    return "\n".join(out)


def _median(runs: list[dict[str, Any]]) -> dict[str, Any] | None:
    if not runs:
        return None
    runs = sorted(runs, key=lambda x: x["wall_s"])
    return runs[len(runs) // 2]


def rule_check(out: Path) -> list[str]:
    """The reduction's rule against a plain log-spaced decimation at the same budget (600
    of 20 000 lines per file), both against the fit on all lines: a lightly damped two-mass
    chain (ζ ≈ 0.2–0.5 %), 2 % relative noise and a floor 70 dB down, two operating points.
    Runs in this process with this tree; returns the table's lines."""
    sys.path.insert(0, str(ROOT / "src"))
    import numpy as np

    import bondid.fit.cli as fit_cli
    from bondid.data import FrfData, add_measurement_noise, write_csv
    from bondid.data import reduce as red
    from bondid.linear import build_affine_model
    from bondid.model import UrdfDocument, set_parameter

    truth_v = {
        "body_a.mass": 1.0,
        "body_b.mass": 0.5,
        "a.stiffness": 1.0e5,
        "b.stiffness": 2.0e5,
        "a.damping": 1.5,
        "b.damping": 1.2,
    }
    start = {
        "body_a.mass": 1.2,
        "body_b.mass": 0.8,
        "a.stiffness": 0.8,
        "b.stiffness": 1.25,
        "a.damping": 1.3,
        "b.damping": 0.7,
    }
    sys.path.insert(0, str(ROOT / "tests"))  # the chain's builder lives with the tests
    from models import two_mass_chain

    truth: UrdfDocument = two_mass_chain(1.0, 0.5, 1.0e5, 1.5, 2.0e5, 1.2)
    model = truth.copy()
    for n, f in start.items():
        set_parameter(model, n, truth_v[n] * f)
    out.mkdir(parents=True, exist_ok=True)
    (out / "model.urdf").write_text(model.to_string())
    f = np.geomspace(1.0, 1000.0, 20000)
    files = []
    for k, op in enumerate(({}, {"a": 0.05})):
        H = build_affine_model(truth, op).linear_model().frf(f)
        Hn, coh = add_measurement_noise(H, f, rel=0.02, floor_db=-70.0, rng=10 + k)
        ds = FrfData(f, ("a", "b"), ("a", "b"), Hn, coherence=coh, operating_point=op)
        files.append(str(write_csv(ds, out / f"pose{k}.csv")))

    def log_only(datasets: Any, setting: Any, channels: Any = None) -> Any:
        st = red.parse_lines(setting)
        sets, info = [], []
        for ds in datasets:
            idx = red._log_spaced(ds.freq_hz, st.budget(ds.freq_hz.size) or ds.freq_hz.size)
            sets.append(red.subset_lines(ds, idx))
            info.append(red.FileReduction(ds.source, ds.freq_hz.size, idx, (), 0, True))
        return sets, red.LineReduction(st, tuple(info))

    res = {}
    original = fit_cli.reduce_datasets
    try:
        for label, lines, rule in (
            ("all lines", "all", original),
            ("features + log, 600", "600", original),
            ("log-spaced only, 600", "600", log_only),
        ):
            fit_cli.reduce_datasets = rule
            folder = out / label.split()[0].strip(",")
            fit_cli.main(
                [
                    "--model",
                    str(out / "model.urdf"),
                    "--data",
                    *files,
                    "--out",
                    str(folder),
                    "--quiet",
                    "--lines",
                    lines,
                    "--free",
                    "*.mass",
                    "*.stiffness",
                    "*.damping",
                    "--prior",
                    "0",
                ]
            )
            res[label] = json.loads((folder / "fit.json").read_text())
    finally:
        fit_cli.reduce_datasets = original
    rows = [
        "| lines per file | db_rms all lines [dB] | noise level [dB] | max rel. error vs"
        " truth | max diff vs all-lines fit [std] | fit wall [s] |",
        "|---|---|---|---|---|---|",
    ]
    ref = {p["name"]: p for p in res["all lines"]["parameters"]}
    for label, j in res.items():
        err = max(abs(p["fitted"] / truth_v[p["name"]] - 1) for p in j["parameters"])
        dz = max(
            abs(p["fitted"] - ref[p["name"]]["fitted"]) / max(p["std"], ref[p["name"]]["std"])
            for p in j["parameters"]
        )
        rows.append(
            f"| {label} | {j['db_rms']['final']:.4f} | {j['db_rms']['noise_level']:.4f}"
            f" | {err:.2%} | {dz:.2f} | {j['wall_s']:.1f} |"
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--base", type=Path, required=True, help="baseline tree (its src/ is used)")
    p.add_argument("--sizes", type=int, nargs="+", default=[2000, 20000, 100000])
    p.add_argument("--commands", nargs="+", default=list(COMMANDS), choices=COMMANDS)
    p.add_argument("--repeats", type=int, default=1, help="A B pairs per command and size")
    p.add_argument("--timeout", type=float, default=1800.0, help="seconds per run")
    p.add_argument("--mem-gib", type=float, default=12.0, help="address-space limit per run")
    p.add_argument("--out", type=Path, default=Path("/tmp/bench_scale"))
    p.add_argument(
        "--rule-check",
        action="store_true",
        help="only compare the reduction's rule with a plain log-spaced decimation (rule_check)",
    )
    args = p.parse_args(argv)
    if args.rule_check:
        rows = rule_check(args.out / "rule_check")
        (args.out / "rule_check.md").write_text("\n".join(rows) + "\n")
        print("\n".join(rows))
        return 0
    srcs = {"A": ROOT / "src", "B": args.base / "src"}
    mem = int(args.mem_gib * 2**30)
    args.out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    figures: dict[str, Any] = {}
    for size in args.sizes:
        files = [args.out / f"bonder_{pose}_{size}.csv" for pose in OPERATING_POINTS]
        for k, (pose, f) in enumerate(zip(OPERATING_POINTS, files, strict=True)):
            if not f.is_file():
                r = run_one(
                    srcs["A"],
                    simulate_argv(size, pose, f, 2026 + k),
                    args.out / f"make_{pose}_{size}.log",
                    args.timeout,
                    mem,
                )
                if r["exit"] != 0:
                    print(f"simulate failed: see {r['log']}", file=sys.stderr)
                    return 1
        for cmd in args.commands:
            runs: dict[str, list[dict[str, Any]]] = {"A": [], "B": []}
            for rep in range(args.repeats):
                for side in ("A", "B"):
                    if side == "B" and cmd in A_ONLY:
                        continue
                    tag = f"{cmd}_{size}_{side}{rep}"
                    out = args.out / tag
                    if cmd == "simulate":
                        av = simulate_argv(size, "q1", args.out / f"{tag}.csv", 7)
                    else:
                        av = command_argv(cmd, size, files, out)
                    r = run_one(srcs[side], av, args.out / f"{tag}.log", args.timeout, mem)
                    r["tag"] = tag
                    made = [args.out / f"{tag}.csv"] + [out / n for n in RESULTS]
                    r["results"] = any(m.is_file() for m in made)
                    runs[side].append(r)
                    print(
                        f"{tag}: {r['wall_s']:.1f} s, {r['peak_mib']:.0f} MiB, exit"
                        f" {r['exit']}{' (time limit)' if r['timed_out'] else ''}",
                        flush=True,
                    )
                    if cmd in ("fit", "fit_all"):
                        figures[tag] = fit_figures(out / "fit.json")
            rows.append(
                {
                    "size": size,
                    "command": cmd,
                    "A": _median(runs["A"]),
                    "B": _median(runs["B"]),
                    "runs": runs,
                }
            )
            (args.out / "bench_scale.md").write_text(table(rows) + "\n")
    comparisons = {}
    for size in args.sizes:
        a, al, b = (
            figures.get(f"{c}_{size}_{s}0")
            for c, s in (("fit", "A"), ("fit_all", "A"), ("fit", "B"))
        )
        if a and al:
            comparisons[f"{size}: auto vs all (A)"] = compare_fits(a, al)
        if a and b:
            comparisons[f"{size}: A auto vs B"] = compare_fits(a, b)
    lines = [
        table(rows),
        "",
        "| run | status | lines kept | db_rms [dB] | noise level [dB] |"
        " median / max rel. error vs truth |",
        "|---|---|---|---|---|---|",
    ]
    for tag, f in figures.items():
        if f is None:
            lines.append(f"| {tag} | no fit.json | | | | |")
            continue
        kept = f"{f['kept_lines']}/{f['lines']}" if f["kept_lines"] else "all"
        lines.append(
            f"| {tag} | {f['status']} | {kept} | {_fmt(f['db_rms'], '.3f')} |"
            f" {_fmt(f['noise_level'], '.3f')} | {_fmt(f['median_rel_err_vs_truth'], '.2%')}"
            f" / {_fmt(f['max_rel_err_vs_truth'], '.2%')} |"
        )
    lines += [
        "",
        "| fits compared | median rel. diff | max rel. diff | median / max diff in std |",
        "|---|---|---|---|",
    ]
    for k, c in comparisons.items():
        lines.append(
            f"| {k} | {_fmt(c['median_rel_diff'], '.3%')} | {_fmt(c['max_rel_diff'], '.3%')}"
            f" | {_fmt(c['median_diff_in_std'], '.2f')} / {_fmt(c['max_diff_in_std'], '.2f')} |"
        )
    (args.out / "bench_scale.md").write_text("\n".join(lines) + "\n")
    (args.out / "bench_scale.json").write_text(
        json.dumps(
            {"rows": rows, "figures": figures, "comparisons": comparisons}, indent=2, default=str
        )
    )
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
