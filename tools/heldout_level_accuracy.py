"""The verdict's held-out noise level against the truth model's own held-out score, per case.

    python tools/heldout_level_accuracy.py [--cases A B ...] [--keep DIR] [--freq 1000]

For every case of the blind benchmark (``tools/benchmark``; data simulated as the benchmark
does, or read from ``--keep DIR/<case>/op*.csv``) this prepares the data as
``bondid.diagnose`` does (weights, decimation, held-out split: ``prepare_data`` with 500
points) and prints the held-out noise level ``L`` of the verdict rule and its ``n``, the truth
model's own weighted held-out db_rms and its ratio to ``L``; then, per regime, the median,
range and count of ratios above 1.2. A ratio well above 1 means the rule calls an exact model
"above the noise" (and a refit near the truth can never be at the level); no refit is run.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT / "tools")]

import numpy as np  # noqa: E402
from benchmark.cases import all_cases  # noqa: E402
from benchmark.designs import design  # noqa: E402
from benchmark.regimes import REGIMES  # noqa: E402
from benchmark.visibility import truth_model_db  # noqa: E402
from truth_refit import _data  # noqa: E402

#: a truth this far above the level counts as an outlier in the summary
OUTLIER = 1.2


def row(case, keep: Path | None, freq: int) -> dict[str, float | str]:
    """The figures of one case (module docstring)."""
    from bondid.data.io import read_frf
    from bondid.diagnose.pipeline import Settings, prepare_data
    from bondid.model import UrdfDocument

    doc = UrdfDocument.load(design(case.design).path)
    with tempfile.TemporaryDirectory(prefix="heldout_level_") as tmp:
        paths = _data(case, keep, freq, Path(tmp))
        p = prepare_data(doc, [read_frf(x) for x in paths], Settings(n_points=500))
    truth = truth_model_db(case, p.held, p.channels)
    level = p.noise.level_db if p.noise is not None else float("nan")
    n_eff = p.noise.n_eff if p.noise is not None else float("nan")
    return {"case": case.name, "regime": case.regime, "level_db": level, "n_eff": n_eff,
            "truth_model_db": truth, "ratio": truth / level}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", help="case names (default: all)")
    ap.add_argument("--keep", type=Path, default=None)
    ap.add_argument("--freq", type=int, default=1000)
    a = ap.parse_args(argv)
    cases = all_cases()
    if a.cases:
        known = {c.name: c for c in cases}
        bad = [n for n in a.cases if n not in known]
        if bad:
            ap.error(f"unknown case(s) {', '.join(bad)}; see blind_benchmark.py --list")
        cases = [known[n] for n in a.cases]
    rows = []
    for c in cases:
        r = row(c, a.keep, a.freq)
        rows.append(r)
        print(f"{r['case']:26s} L {r['level_db']:.3f} dB (n {r['n_eff']:5.0f})  truth "
              f"{r['truth_model_db']:.3f} dB  ratio {r['ratio']:.2f}", flush=True)  # fmt: skip
    for reg in REGIMES:
        x = np.array([float(r["ratio"]) for r in rows if r["regime"] == reg])
        if x.size:
            print(f"{reg:6s} ratio median {np.median(x):.2f}, range {x.min():.2f}–{x.max():.2f},"
                  f" above {OUTLIER}: {int(np.sum(x > OUTLIER))}/{x.size}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
