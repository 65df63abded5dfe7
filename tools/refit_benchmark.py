"""Does ``python -m bondid.fit`` (its defaults) reach the noise level on machines it was not
tuned to?

For parameter-error-only truths (no withheld effect) of the blind benchmark's designs
(``tools/benchmark/``: the truth's 10–30 % errors, the regimes' noise, the same files), each
case runs ``python -m bondid.fit`` as a subprocess on the nominal URDF and the data files
(default options: no ``--free``), then scores the truth model itself on the same files with
the fit's own weighted ``db_rms`` (``bondid.fit.outputs.db_rms_report`` with the fit's default
cost options: what ``fit.json``'s ``db_rms.final`` would say of the truth). A case is "at the
noise level" when the fit's ``db_rms`` is within 10 % of the truth's (or below).

Prints one Markdown row per case (fit's and truth's db_rms, their ratio, the predicted noise
level, IPOPT iterations and status, parameters on a bound, wall time) and the share within
10 %. Usage: ``python tools/refit_benchmark.py [--designs D,..] [--regimes R,..] [--seeds N]
[--freq 2000] [--jobs 1] [--out rows.json] [-- extra bondid.fit options]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT / "tools")]

import numpy as np  # noqa: E402
from benchmark.cases import Case  # noqa: E402
from benchmark.designs import DESIGNS, design  # noqa: E402
from benchmark.regimes import REGIMES, measure  # noqa: E402
from benchmark.runner import STOPPING, _error, _run, stop_on_sigterm  # noqa: E402
from benchmark.truth import signal_factor, truth_model  # noqa: E402

#: a fit within this factor of the truth's own db_rms is "at the noise level"
WITHIN = 1.10
#: seeds of these cases start here (the blind benchmark's own cases use 1–60)
SEED0 = 500


def cases(designs: list[str], regimes: list[str], n_seeds: int) -> list[Case]:
    """``n_seeds`` parameter-error-only cases per design × regime."""
    out = []
    for d in designs:
        for r in regimes:
            for k in range(n_seeds):
                seed = SEED0 + 100 * list(DESIGNS).index(d) + 10 * REGIMES.index(r) + k
                out.append(Case(f"{d}/refit{k}/{r}", d, r, (), seed))
    return out


def truth_score(model: Path, truth: Any, paths: list[Path]) -> float | None:
    """The truth model's weighted db_rms on the files, as ``bondid.fit`` (defaults) scores a
    model: the same loading, receptance conversion, cost options and channels."""
    from bondid.cost.selection import informative_only
    from bondid.fit.cli import cost_options
    from bondid.fit.outputs import db_rms_report
    from bondid.fit.study import StudySettings
    from bondid.model import UrdfDocument
    from bondid.validation.datasets import load_datasets

    nominal = UrdfDocument.load(model)
    raw = load_datasets(nominal, paths)
    data = [d if d.quantity == "receptance" else d.to_quantity("receptance") for d in raw]
    # the channels the fit uses (those under the noise floor left out, as bondid.fit does)
    options, _, _ = informative_only(data, cost_options(StudySettings()))
    rep = db_rms_report(truth, truth, data, options)
    return rep["final"]


def on_bounds(fit: dict[str, Any], rel: float = 1e-6) -> list[str]:
    """Names of the fitted parameters within ``rel`` (of the bound range) of a bound."""
    out = []
    for p in fit.get("parameters", []):
        lo, hi, v = p.get("lower"), p.get("upper"), p.get("fitted")
        if v is None or lo is None or hi is None:
            continue
        tol = rel * max(abs(hi - lo), 1e-300)
        if v - lo <= tol or hi - v <= tol:
            out.append(p["name"])
    return out


def run_case(case: Case, freq: int, extra: list[str]) -> dict[str, Any]:
    dz = design(case.design)
    from bondid.model import UrdfDocument

    truth = truth_model(UrdfDocument.load(dz.path), (), case.seed)
    f = np.logspace(0.0, np.log10(4000.0), freq)
    row: dict[str, Any] = {"case": case.name, "design": case.design, "regime": case.regime}
    with tempfile.TemporaryDirectory(prefix="bondid_refit_") as tmp:
        folder = Path(tmp)

        def factor(ff, outs, ins):
            return signal_factor((), ff, outs, ins)

        paths, _ = measure(truth, dz.operating_points, f, case.regime, factor, folder, case.seed)
        cmd = [sys.executable, "-m", "bondid.fit", "--model", str(dz.path), "--data",
               *map(str, paths), "--out", str(folder / "fit"), "--quiet", *extra]  # fmt: skip
        proc, row["wall_s"] = _run(cmd)
        fj = folder / "fit" / "fit.json"
        if not fj.exists():
            return {**row, "error": _error(proc)}
        fit = json.loads(fj.read_text())
        t0 = time.perf_counter()
        row["truth_db"] = truth_score(dz.path, truth, paths)
        row["truth_s"] = time.perf_counter() - t0
    db = fit.get("db_rms") or {}
    row.update(fit_db=db.get("final"), noise_level=db.get("noise_level"),
               iterations=fit.get("iterations"), status=fit.get("status"),
               bounds=on_bounds(fit), stages=len(fit.get("stages") or []),
               notes=[n for n in fit.get("notes", []) if "fallback" in n])  # fmt: skip
    if row["fit_db"] is not None and row["truth_db"]:
        row["ratio"] = row["fit_db"] / row["truth_db"]
    return row


def table(rows: list[dict[str, Any]]) -> str:
    head = ("| case | fit db_rms | truth db_rms | ratio | noise level (pred.) | iterations |"
            " status | on bounds | wall s |\n|---|---|---|---|---|---|---|---|---|")  # fmt: skip
    lines = [head]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['case']} | error: {r['error']} | | | | | | | |")
            continue
        nl = r.get("noise_level")
        lines.append(
            f"| {r['case']} | {r['fit_db']:.3f} | {r['truth_db']:.3f} | {r.get('ratio', 0):.3f}"
            f" | {nl:.3f} | {r['iterations']} | {r['status']} | {len(r['bounds'])}"
            f" | {r['wall_s']:.0f} |"
            if nl is not None
            else f"| {r['case']} | {r['fit_db']} | {r['truth_db']} | | | | {r['status']} | | |"
        )
    ok = [r for r in rows if r.get("ratio") is not None and r["ratio"] <= WITHIN]
    lines.append(f"\nwithin {100 * (WITHIN - 1):.0f} % of the truth's db_rms: {len(ok)} of"
                 f" {len(rows)} ({100 * len(ok) / max(len(rows), 1):.0f} %)")  # fmt: skip
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    extra = argv[argv.index("--") + 1 :] if "--" in argv else []
    argv = argv[: argv.index("--")] if "--" in argv else argv
    p = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    p.add_argument("--designs", default=",".join(DESIGNS))
    p.add_argument("--regimes", default=",".join(REGIMES))
    p.add_argument("--seeds", type=int, default=2, help="cases per design × regime (default 2)")
    p.add_argument("--freq", type=int, default=2000, help="frequencies per file (default 2000)")
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--out", type=Path)
    p.add_argument("--tables", type=Path, help="print the table of a rows JSON and stop")
    a = p.parse_args(argv)
    if a.tables:
        print(table(json.loads(a.tables.read_text())))
        return 0
    todo = cases(a.designs.split(","), a.regimes.split(","), a.seeds)
    done: list[dict[str, Any]] = []

    def one(c: Case) -> dict[str, Any]:
        try:
            r = run_case(c, a.freq, extra)
        except Exception as exc:  # one broken case must not lose the others
            r = {"case": c.name, "design": c.design, "regime": c.regime, "error": repr(exc)}
        if STOPPING.is_set():  # a case cut short by SIGTERM is not a result
            return r
        print(json.dumps(r, default=float), flush=True)
        done.append(r)
        if a.out:
            a.out.write_text(json.dumps(done, indent=1, default=float) + "\n")
        return r

    stop_on_sigterm()
    with ThreadPoolExecutor(max_workers=a.jobs) as pool:
        rows = list(pool.map(one, todo))
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
