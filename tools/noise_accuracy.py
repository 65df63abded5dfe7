"""Accuracy of the noise estimated from the FRF alone, against the known noise of synthetic data.

    python tools/noise_accuracy.py [--seeds 0 1 2] [--model urdf/bonder.urdf]

For each regime (flat displacement floor and flat acceleration floor 40 dB below each channel's
median, relative noise only, the simulator's default response-following floor at -70 dB) on
2000 log-spaced lines 1-4000 Hz, on a sparse linear grid of 60 lines and on an analyser's
linear grid (1600 lines, 0.5-2000 Hz), it prints: the points
whose true SNR is below 20 dB and the share of them where the estimate is within a factor 2 of
the true noise std (with the range of estimate / truth), and the points whose true SNR is at
least 30 dB that the estimate calls noise (estimated SNR below 10 dB), and the points whose true
SNR is below 0 dB (mostly noise) that it calls signal (estimated SNR at least 10 dB: the
harmful error, a noise point's log error is tens of dB against any model). The truth comes from the
simulator's coherence S/(S+N) of the very noise it added.
"""

from __future__ import annotations

import argparse

import numpy as np

from bondid.data.noise_estimate import estimate_noise
from bondid.model.document import UrdfDocument
from bondid.simulate import log_grid, simulate

REGIMES = {
    "displacement floor -40 dB (median)": (-40.0, "median", None),
    "acceleration floor -40 dB (median)": (-40.0, "median", "accelerance"),
    "relative only (2 %)": (None, "median", None),
    "response floor -70 dB (default)": (-70.0, "response", None),
}
GRIDS = {
    "2000 log lines": log_grid(1.0, 4000.0, 2000),
    "60 linear lines": np.linspace(4000.0 / 60, 4000.0, 60),
    # an analyser's grid: linear from near 0 Hz, so its low end is sparse in log f
    "1600 linear lines": 0.5 + 1.25 * np.arange(1600),
}


def one(doc: UrdfDocument, f: np.ndarray, regime: tuple, seed: int) -> dict[str, float]:
    floor_db, ref, fq = regime
    data = simulate(
        doc, None, f, noise=0.02, floor_db=floor_db, seed=seed, floor_ref=ref, floor_quantity=fq
    )
    S = np.abs(simulate(doc, None, f, noise=0.0).H) ** 2
    N = S * (1.0 - data.coherence) / data.coherence
    with np.errstate(divide="ignore"):
        snr = 10.0 * np.log10(S / N)
    est = estimate_noise(f, data.H)
    ratio = est.sigma / np.sqrt(N)
    low, high = snr < 20.0, snr >= 30.0
    inside = low & (ratio <= 2.0) & (ratio >= 0.5)
    return {
        "low": int(low.sum()),
        "inside": int(inside.sum()),
        "rmin": float(ratio[low].min()) if low.any() else np.nan,
        "rmax": float(ratio[low].max()) if low.any() else np.nan,
        "high": int(high.sum()),
        "called_noise": int((high & (est.snr_db < 10.0)).sum()),
        "noise": int((snr < 0.0).sum()),
        "called_signal": int(((snr < 0.0) & (est.snr_db >= 10.0)).sum()),
        "rho": float(np.nanmedian(est.rho)),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", default="urdf/bonder.urdf")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    args = p.parse_args()
    doc = UrdfDocument.load(args.model)
    print(
        "| grid | regime | SNR<20 dB points | within ×2 | estimate/truth range |"
        " SNR≥30 dB points | called noise | SNR<0 dB points | called signal | median ρ |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for gname, f in GRIDS.items():
        for rname, regime in REGIMES.items():
            rows = [one(doc, f, regime, s) for s in args.seeds]
            low = sum(r["low"] for r in rows)
            inside = sum(r["inside"] for r in rows)
            rmin = min((r["rmin"] for r in rows if r["low"]), default=np.nan)
            rmax = max((r["rmax"] for r in rows if r["low"]), default=np.nan)
            high = sum(r["high"] for r in rows)
            called = sum(r["called_noise"] for r in rows)
            noise = sum(r["noise"] for r in rows)
            signal = sum(r["called_signal"] for r in rows)
            share = f"{100 * inside / low:.1f} %" if low else "–"
            rng = f"{rmin:.2f}–{rmax:.2f}" if low else "–"
            rho = np.median([r["rho"] for r in rows])
            print(
                f"| {gname} | {rname} | {low} | {share} | {rng} | {high} | {called} | {noise} "
                f"| {signal} | {rho:.4f} |"
            )


if __name__ == "__main__":
    main()
