"""The predicted noise level against the truth model's own weighted db_rms, without any fit.

    python tools/noise_level_accuracy.py [--seeds 2] [--freq 2000]

For the parameter-error-only truths of ``tools/refit_benchmark.py`` (the same designs, regimes,
seeds and files), it scores the truth model on the files the way ``fit.json`` scores a model
(``bondid.fit.outputs.db_rms_report`` with the fit's default cost options: ``final``) and
prints it next to the predicted noise level (``db_rms.noise_level``), their ratio, and the
ratio's median, range and mean absolute log. The fit's fallback and the diagnosis's rescue act
on that prediction (at 1.1× and √1.5×), so a ratio far from 1 makes them run for nothing or
not at all.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT / "tools")]

import numpy as np  # noqa: E402
from benchmark.designs import DESIGNS, design  # noqa: E402
from benchmark.regimes import REGIMES, measure  # noqa: E402
from benchmark.truth import signal_factor, truth_model  # noqa: E402
from refit_benchmark import cases  # noqa: E402


def one(design_name: str, regime: str, seed: int, n_freq: int) -> tuple[float, float]:
    """(truth's weighted db_rms, predicted noise level) [dB] of one case."""
    from bondid.fit.cli import cost_options
    from bondid.fit.outputs import db_rms_report
    from bondid.fit.study import StudySettings
    from bondid.model import UrdfDocument
    from bondid.validation.datasets import load_datasets

    dz = design(design_name)
    nominal = UrdfDocument.load(dz.path)
    truth = truth_model(nominal, (), seed)
    f = np.logspace(0.0, np.log10(4000.0), n_freq)
    with tempfile.TemporaryDirectory(prefix="bondid_level_") as tmp:

        def factor(ff, outs, ins):
            return signal_factor((), ff, outs, ins)

        paths, _ = measure(truth, dz.operating_points, f, regime, factor, Path(tmp), seed)
        raw = load_datasets(nominal, paths)
        data = [d if d.quantity == "receptance" else d.to_quantity("receptance") for d in raw]
        rep = db_rms_report(truth, truth, data, cost_options(StudySettings()))
    return float(rep["final"]), float(rep["noise_level"])


def main() -> int:
    p = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    p.add_argument("--seeds", type=int, default=2, help="cases per design × regime (default 2)")
    p.add_argument("--freq", type=int, default=2000, help="frequencies per file (default 2000)")
    a = p.parse_args()
    print("| case | truth db_rms | predicted noise level | ratio |\n|---|---|---|---|")
    ratios = []
    for c in cases(list(DESIGNS), list(REGIMES), a.seeds):
        truth, level = one(c.design, c.regime, c.seed, a.freq)
        ratios.append(level / truth)
        print(f"| {c.name} | {truth:.3f} | {level:.3f} | {level / truth:.3f} |", flush=True)
    r = np.array(ratios)
    print(f"\nratio: median {np.median(r):.3f}, range {r.min():.3f}–{r.max():.3f}, "
          f"mean |ln| {np.mean(np.abs(np.log(r))):.3f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
