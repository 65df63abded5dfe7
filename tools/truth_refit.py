"""The diagnosis's refit of the TRUE effect's candidate, against the truth and the noise level.

For each benchmark case (``tools/benchmark``: the only place that knows the truth) this runs
the diagnosis's own steps on the case's data — :func:`bondid.diagnose.pipeline.prepare_data`
(weights, split), the parameter refit (``_baseline_task``), the screening of the candidate
whose class and location match the truth's, and its full refit
(:func:`bondid.diagnose.runner.run_job` with the search's Job settings) — and prints:

- ``base``: the parameter refit's training / held-out weighted db_rms [dB];
- ``cand``: the truth candidate's refit, the same figures, its training db_rms over the
  predicted noise level (``x noise``), its wall time and its notes (rescue, pivot);
- ``truth``: the truth model's own weighted db_rms on the same training / held-out points.

The training figure of a refit is ``sqrt`` of the core's data cost (the weighted mean square
complex-log error [dB²] the noise level is predicted in); the truth's and the held-out ones
are :func:`bondid.diagnose.gap.gap_report`'s weighted db_rms.

Data: ``<keep>/<case>/op*.csv`` when present (``blind_benchmark.py --keep``), else simulated
as the benchmark does (``--freq`` lines). Usage::

    python tools/truth_refit.py --cases gantry/jct/harsh bonder_b/fb/acc --keep /tmp/keep
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT / "tools")]

from benchmark.cases import Case, all_cases  # noqa: E402
from benchmark.designs import design  # noqa: E402
from benchmark.visibility import case_files, truth_model_db  # noqa: E402


def _data(case: Case, keep: Path | None, freq: int, tmp: Path) -> list[Path]:
    """The case's data files: kept ones, else simulated into ``tmp``."""
    if keep is not None and (keep / case.name / "op0.csv").exists():
        return sorted((keep / case.name).glob("op*.csv"))
    return case_files(case, tmp, freq)[0]


def _noise_db(sets: list, doc: Any, names: list[str], options: Any) -> float:
    """The predicted noise level [dB] of ``sets`` (the core's, as the rescue tests it)."""
    from bondid.cost.noise_level import noise_level_cost
    from bondid.optim.problem import FitProblem

    c = noise_level_cost(FitProblem(doc, list(sets), names[:1], options=options).frf)
    return float(np.sqrt(c)) if c else float("nan")


def _record_train(train: list) -> dict[str, float]:
    """Make the refit's held-out evaluation also record the training data's weighted db_rms
    (the same :func:`bondid.diagnose.evaluate.figures`, on ``train``); returns the record."""
    from bondid.diagnose import evaluate

    original = getattr(evaluate.figures, "original", evaluate.figures)
    seen: dict[str, float] = {}

    def figures(refit, fit, theta, datasets, options):
        out = original(refit, fit, theta, datasets, options)
        seen["train"] = original(refit, fit, theta, train, options).db_rms
        return out

    figures.original = original  # type: ignore[attr-defined]
    evaluate.figures = figures
    return seen


def run(
    case: Case, paths: list[Path], points: int, from_truth: bool = False, iters: tuple = ()
) -> dict[str, Any]:
    """The figures of one case (module docstring). Experiments: ``from_truth`` starts the
    candidate's first origin at the truth's nominal parameters (its random errors, without
    its effect) instead of the parameter refit; ``iters`` = (all_iter, alt_iter)."""
    from bondid.diagnose.runner import run_job

    from bondid.data.io import read_frf
    from bondid.diagnose.pipeline import (
        Settings,
        _baseline_task,
        missing_mode_hints,
        prepare_data,
    )
    from bondid.diagnose.screen import screen
    from bondid.diagnose.search import Context, _job, _refit_candidate
    from bondid.diagnose.where import where
    from bondid.model import UrdfDocument

    (truth,) = case.effects
    doc = UrdfDocument.load(design(case.design).path)
    s = Settings(n_points=points)
    p = prepare_data(doc, [read_frf(x) for x in paths], s)
    seen = _record_train(p.train)
    t0 = time.perf_counter()
    base, _ = _baseline_task(doc.to_string(), p.space, p.train, p.held, p.full, p.options,
                             True, s.ipopt_iter, s.refit_iter)  # fmt: skip
    t_base = time.perf_counter() - t0
    base_train = seen.get("train", float("nan"))
    _, by_ds, _, _, measured = where(doc, p.full, base, p.channels, s.modes)
    ctx = Context(doc, p.names, p.train, p.held, p.full, p.options, p.candidates,
                  missing_mode_hints(by_ds), s.refit_iter, s.n_starts, space=p.space,
                  noise=p.noise, measured=measured)  # fmt: skip
    match = [c for c in p.candidates
             if c.effect == truth.effect and c.location == truth.location]  # fmt: skip
    if not match:
        return {"case": case.name, "error": f"no candidate {truth.effect}@{truth.location}"}
    t1 = time.perf_counter()
    scr = screen(_job(ctx, base, match[0]))
    # with the wider search in the job (the search runs it in a second round, for the best
    # refits of a step: the true candidate's, when it could decide the step)
    job = replace(_job(ctx, base, _refit_candidate(scr, match[0]), scr.start), wider=True)
    if from_truth:
        from benchmark.truth import perturb

        job = replace(job, urdf=perturb(doc, np.random.default_rng(1000 + case.seed)).to_string())
    if os.environ.get("TRUTH_REFIT_NO_START"):
        job = replace(job, start_new=())
    if iters:
        job = replace(job, all_iter=iters[0], alt_iter=iters[1])
    r = run_job(job)
    t_cand = time.perf_counter() - t1
    noise_tr = _noise_db(p.train, doc, p.names, p.options)
    return {
        "case": case.name, "label": r.label, "error": r.error,
        "base_train": base_train, "base_held": base.heldout_db_rms,
        "cand_train": seen.get("train", float("nan")), "cand_cost_db": float(r.train_rms),
        "cand_held": r.heldout_db_rms,
        "cand_x_noise": float(r.train_rms) / noise_tr,
        "truth_train": truth_model_db(case, p.train, p.channels),
        "truth_held": truth_model_db(case, p.held, p.channels),
        "noise_train": noise_tr, "noise_held": _noise_db(p.held, doc, p.names, p.options),
        "screen_cost": scr.cost, "start": [float(x) for x in scr.start],
        "initial": [p.initial for p in match[0].parameters],
        "fitted_new": [float(x) for x in r.values[len(r.values) - r.n_own:]],
        "hints_hz": list(ctx.hints_hz), "t_base_s": t_base, "t_cand_s": t_cand,
        "extra": {k: v for k, v in r.extra.items() if isinstance(v, str)},
    }  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", required=True)
    ap.add_argument("--keep", type=Path, default=None)
    ap.add_argument("--freq", type=int, default=1000)
    ap.add_argument("--points", type=int, default=500)
    ap.add_argument(
        "--from-truth",
        action="store_true",
        help="experiment: first origin at the truth's nominal parameters",
    )
    ap.add_argument(
        "--iters",
        type=int,
        nargs=2,
        default=(),
        metavar=("ALL", "ALT"),
        help="experiment: the Job's all_iter and alt_iter",
    )
    ap.add_argument("--json", type=Path, default=None, help="append each row (JSON lines)")
    a = ap.parse_args(argv)
    cases = {c.name: c for c in all_cases()}
    for name in a.cases:
        with tempfile.TemporaryDirectory(prefix="truth_refit_") as tmp:
            row = run(
                cases[name],
                _data(cases[name], a.keep, a.freq, Path(tmp)),
                a.points,
                a.from_truth,
                tuple(a.iters),
            )
        print(_line(row), flush=True)
        if a.json:
            with a.json.open("a") as fh:
                fh.write(json.dumps(row) + "\n")
    return 0


def _line(r: dict[str, Any]) -> str:
    if "cand_held" not in r:
        return f"{r['case']}: {r.get('error')}"
    held_x = r["cand_held"] / r["noise_held"]
    return (
        f"{r['case']:24s} base train {r['base_train']:.3f} held {r['base_held']:.3f} | "
        f"cand {r['label']} train {r['cand_train']:.3f} (cost {r['cand_cost_db']:.3f}) held "
        f"{r['cand_held']:.3f} ({r['cand_x_noise']:.2f}x noise {r['noise_train']:.3f}, held "
        f"{held_x:.2f}x {r['noise_held']:.3f}) | truth train {r['truth_train']:.3f} held "
        f"{r['truth_held']:.3f} | {r['t_cand_s']:.0f}s (base {r['t_base_s']:.0f}s) "
        f"{r['error']} {r['extra']}"
    )


if __name__ == "__main__":
    raise SystemExit(main())
