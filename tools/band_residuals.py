"""Where a kept diagnosis's models still miss: the weighted gap per data set and held-out band.

For a blind-benchmark case kept by ``tools/blind_benchmark.py --keep DIR`` (its ``op*.csv``
and ``diag/``), this splits the data exactly as the diagnosis did
(:func:`bondid.diagnose.pipeline.prepare_data` with the default settings) and prints, for the
parameter refit (``diag/refit.urdf``), the final model (``diag/augmented.urdf``, when an
effect was accepted) and the truth model (``tools/benchmark``, the only place that knows it),
the weighted RMS complex-log error [dB] of each (data set, band) on the training and on the
held-out points: ``band:dB`` per data set, data sets separated by ``|``.

A refit can sit at 1.1× the training noise level overall while one band, where a mode lies, is
off by ten times the truth's figure there: the overall figure averages it away. This table
shows that band. Usage::

    python tools/band_residuals.py --keep /work/keep28 --cases bonder_b/jct/nocoh
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "src"), str(ROOT / "tools")]

import numpy as np  # noqa: E402
from benchmark.cases import Case, all_cases  # noqa: E402
from benchmark.designs import design  # noqa: E402
from benchmark.truth import signal_factor, truth_model  # noqa: E402


def band_figures(sets: list, H: list[np.ndarray], channels: list[str], edges: np.ndarray) -> str:
    """``band:dB`` of every band with points, per data set, ``" | "``-joined: the gap report's
    weighted db_rms (:func:`bondid.diagnose.gap.gap_report`, the data's coherence = the
    diagnosis's weights) over ``channels``, band ``k`` = ``[edges[k], edges[k+1])``."""
    from itertools import pairwise

    from bondid.diagnose.gap import gap_report

    bands = list(pairwise(float(e) for e in edges))
    out = []
    for d, Hm in zip(sets, H, strict=True):
        rep = gap_report(d, Hm, bands, channels=channels, weighting="coherence")
        cells = [f"{k}:{b['db_rms']:.2f}" if np.isfinite(b["db_rms"]) else f"{k}:-"
                 for k, b in enumerate(rep.by_band) if b["n_points"] > 0]  # fmt: skip
        out.append(" ".join(cells))
    return " | ".join(out)


def run(case: Case, keep: Path) -> None:
    """Print the table of one kept case (module docstring)."""
    from bondid.data.io import read_frf
    from bondid.diagnose.pipeline import Settings, prepare_data
    from bondid.diagnose.split import band_edges
    from bondid.frf.aligned import model_frf
    from bondid.model import UrdfDocument

    folder = keep / case.name
    paths = sorted(folder.glob("op*.csv"))
    if not paths:
        raise SystemExit(f"{folder}: no op*.csv (run blind_benchmark.py with --keep {keep})")
    nominal = UrdfDocument.load(design(case.design).path)
    s = Settings()
    p = prepare_data(nominal, [read_frf(x) for x in paths], s)
    edges = band_edges(p.full, s.n_holdout_bands)
    models = {"truth": truth_model(nominal, case.effects, case.seed)}
    for name, file in (("refit", "refit.urdf"), ("final", "augmented.urdf")):
        if (folder / "diag" / file).exists():
            models[name] = UrdfDocument.load(folder / "diag" / file)
    print(f"## {case.name} (bands: {s.n_holdout_bands} of equal log width)")
    for part, sets in (("train", p.train), ("held", p.held)):
        for name, doc in models.items():
            H = [model_frf(doc, d) for d in sets]
            if name == "truth":  # the signal effects (delays, lags) act on the FRF
                H = [h * signal_factor(case.effects, d.freq_hz, d.outputs, d.inputs)
                     for h, d in zip(H, sets, strict=True)]  # fmt: skip
            print(f"{part:5s} {name:5s} {band_figures(sets, H, p.channels, edges)}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--keep", type=Path, required=True, help="blind_benchmark.py --keep DIR")
    ap.add_argument("--cases", nargs="+", required=True)
    a = ap.parse_args(argv)
    cases = {c.name: c for c in all_cases()}
    unknown = [n for n in a.cases if n not in cases]
    if unknown:
        raise SystemExit(f"unknown case(s) {unknown}; see blind_benchmark.py --list")
    for name in a.cases:
        run(cases[name], a.keep)
    return 0


if __name__ == "__main__":
    sys.exit(main())
