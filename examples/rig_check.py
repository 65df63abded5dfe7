"""Figures of a fit on a real rig: resonances of the data against the fitted model's, the fit's
db_rms against the data's noise level, the run's status and time.

Usage (after ``python -m bondid.fit ... --out RESULTS``)::

    python examples/rig_check.py RESULTS [--truth truth_modes.json] [--max-modes N]

Reads ``RESULTS/fit.json`` and ``RESULTS/fitted.urdf`` (the fitted model, with its points,
gains and floating base) and the data files fit.json names (a UFF58 file through the channel
map of the fit's settings). The data's resonances are found from the measured points alone:
the peaks of the channels' summed magnitude (in the file's quantity) that stand out by
``--prominence`` dB, each refined by a local rational model (Levy: ``(b0 + b1 s + b2 s²) /
(a0 + a1 s + s²)`` fitted by linear least squares to the lines around the peak of the
channel where it is highest). The model's are its modes (:mod:`bondid.modes`) at the data's
operating point, each data resonance paired with the nearest one. With ``--truth`` (a JSON
list of frequencies under any key ending in ``_hz``, as the examples' generators write) the
fitted modes are also compared with the generator's own; with ``--truth-model URDF`` (a
generator's own model, where it has one) the db_rms that model scores on the same points with
the same weights is reported: what an exact model reaches on these data. Writes
``RESULTS/check.json`` and ``RESULTS/resonances.png``; prints a one-line row for the docs'
table.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HALF_WINDOW = 4  # lines each side of a peak for its local rational model


def _levy_peak(f: np.ndarray, H: np.ndarray) -> float:
    """The peak frequency of the local model ``(b0 + b1 s + b2 s²)/(a0 + a1 s + s²)``: its
    undamped natural frequency ``√a0 / 2π`` (Hz)."""
    s = 2j * np.pi * f
    A = np.column_stack([H, H * s, -np.ones_like(s), -s, -(s**2)])
    Ar = np.vstack([A.real, A.imag])
    br = np.concatenate([(-H * s**2).real, (-H * s**2).imag])
    scale = np.linalg.norm(Ar, axis=0)
    a0 = (np.linalg.lstsq(Ar / scale, br, rcond=None)[0] / scale)[0]
    return float(np.sqrt(a0) / (2 * np.pi)) if a0 > 0 else float(f[np.argmax(np.abs(H))])


def data_resonances(f: np.ndarray, H: np.ndarray, prominence_db: float) -> list[float]:
    """Resonances (Hz) of ``H`` ``(n_out, n_in, n_f)`` from the data alone (module docstring)."""
    from scipy.signal import find_peaks

    mag = np.nansum(np.abs(H), axis=(0, 1))
    idx, _ = find_peaks(20 * np.log10(mag + 1e-300), prominence=prominence_db)
    out = []
    for k in idx:
        if k < HALF_WINDOW or k + HALF_WINDOW >= f.size:
            continue
        o, i = np.unravel_index(np.nanargmax(np.abs(H[:, :, k])), H.shape[:2])
        sl = slice(k - HALF_WINDOW, k + HALF_WINDOW + 1)
        out.append(_levy_peak(f[sl], H[o, i, sl]))
    return out


def model_modes(doc, ds) -> list[float]:
    """The fitted model's vibration frequencies (Hz) at the data's operating point."""
    from bondid.linear.affine import build_affine_model
    from bondid.modes.analysis import modal_analysis

    lm = build_affine_model(doc, ds.operating_point, outputs=ds.outputs).linear_model()
    return [m.f_hz for m in modal_analysis(lm).vibration_modes()]


def _pair(refs: list[float], modes: list[float]) -> list[dict]:
    rows = []
    for f in refs:
        m = min(modes, key=lambda v: abs(v - f)) if modes else float("nan")
        rows.append({"reference_hz": f, "model_hz": m, "rel_error": m / f - 1.0})
    return rows


def _truth(path: Path | None, band: tuple[float, float]) -> list[float]:
    if path is None:
        return []
    doc = json.loads(path.read_text())
    out: list[float] = []
    for k, v in doc.items():
        if k.endswith("_hz"):
            out += [float(x) for x in (v if isinstance(v, list) else [v])]
    return sorted(x for x in out if band[0] <= x <= band[1])


def exact_db_rms(truth: Path, ds, fit: dict) -> float | None:
    """The weighted db_rms of the model in ``truth`` on the fit's points (its bands, its
    channels, its weights)."""
    from bondid.cost.selection import CostOptions, informative_only
    from bondid.fit.outputs import db_rms_report
    from bondid.model import UrdfDocument

    st = fit["settings"]
    options = CostOptions(
        bands=st["bands"], channels=st["channels"], use_coherence=st["coherence"],
        weighting=st["weighting"],
    )  # fmt: skip
    options = informative_only([ds], options)[0]
    doc = UrdfDocument.load(truth)
    return db_rms_report(doc, doc, [ds], options)["final"]


def _plot(path: Path, ds, Hm: np.ndarray, peaks: list[dict], fit: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    f = ds.freq_hz
    fig, ax = plt.subplots(2, 1, figsize=(9, 6.5), height_ratios=[3, 1.3])
    ax[0].semilogy(f, np.nansum(np.abs(ds.H), axis=(0, 1)), color="0.55", lw=1, label="measured")
    ax[0].semilogy(f, np.nansum(np.abs(Hm), axis=(0, 1)), color="C3", lw=1, label="fitted model")
    for p in peaks:
        ax[0].axvline(p["reference_hz"], color="0.3", ls=":", lw=0.8)
    ax[0].set_ylabel(f"Σ |H| over channels ({ds.quantity})")
    db = fit["db_rms"]
    ax[0].set_title(
        f"{fit['status']} in {fit['wall_s']:.0f} s of search — db_rms {db['final']:.2f} dB,"
        f" noise level {db['noise_level']:.2f} dB ({db['final'] / db['noise_level']:.2f}×)",
        fontsize=10,
    )
    ax[0].legend(loc="best")
    x = [p["reference_hz"] for p in peaks]
    ax[1].bar(range(len(x)), [100 * p["rel_error"] for p in peaks], color="C0")
    ax[1].set_xticks(range(len(x)), [f"{v:.1f}" for v in x])
    ax[1].axhline(1, color="C3", ls="--", lw=0.8)
    ax[1].axhline(-1, color="C3", ls="--", lw=0.8)
    ax[1].set_xlabel("resonance of the data [Hz]")
    ax[1].set_ylabel("model − data [%]")
    fig.tight_layout()
    tmp = path.with_name(path.name + ".tmp.png")
    fig.savefig(tmp, dpi=100)
    plt.close(fig)
    tmp.replace(path)


def main(argv: list[str] | None = None) -> int:
    from bondid.atomic import write_text_atomic
    from bondid.data.io import read_frf
    from bondid.frf.aligned import model_frf
    from bondid.model import UrdfDocument

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("results", type=Path, help="the fit's --out folder")
    p.add_argument("--truth", type=Path, help="the generator's truth_modes.json")
    p.add_argument("--truth-model", type=Path, help="the generator's own model (URDF)")
    p.add_argument("--prominence", type=float, default=6.0, help="peak prominence [dB]")
    a = p.parse_args(argv)
    fit = json.loads((a.results / "fit.json").read_text())
    doc = UrdfDocument.load(a.results / "fitted.urdf")
    cmap = {k: tuple(v) for k, v in fit["settings"].get("uff_map", {}).items()} or None
    path = Path(fit["data_files"][0])
    ds = read_frf(path, channel_map=cmap if path.suffix.lower() in (".uff", ".unv") else None)
    Hm = model_frf(doc, ds)
    band = (float(ds.freq_hz[0]), float(ds.freq_hz[-1]))
    modes = [m for m in model_modes(doc, ds) if band[0] <= m <= band[1]]
    peaks = _pair(data_resonances(ds.freq_hz, ds.H, a.prominence), modes)
    truth = _pair(_truth(a.truth, band), modes)
    db = fit["db_rms"]
    out = {
        "status": fit["status"], "success": fit["success"], "stop_reason": fit.get("stop_reason"),
        "wall_s": fit["wall_s"], "iterations": fit["iterations"],
        "db_rms": db["final"], "noise_level": db["noise_level"],
        "ratio_to_noise": db["final"] / db["noise_level"] if db["noise_level"] else None,
        "data_resonances": peaks, "truth_modes": truth, "model_modes_hz": modes,
        "exact_model_db_rms": None if a.truth_model is None else exact_db_rms(
            a.truth_model, ds, fit),
    }  # fmt: skip
    write_text_atomic(a.results / "check.json", json.dumps(out, indent=2) + "\n")
    _plot(a.results / "resonances.png", ds, Hm, peaks, fit)
    worst = max((abs(r["rel_error"]) for r in peaks), default=float("nan"))
    worst_t = max((abs(r["rel_error"]) for r in truth), default=float("nan"))
    print(
        f"{fit['status']} | search {fit['wall_s']:.1f} s | {len(peaks)} resonances, worst"
        f" {100 * worst:.2f} % (truth: {100 * worst_t:.2f} %) | db_rms {db['final']:.3f} dB,"
        f" noise {db['noise_level']:.3f} dB ({out['ratio_to_noise']:.2f}×)"
        + ("" if out["exact_model_db_rms"] is None else
           f" | the generator's model: {out['exact_model_db_rms']:.3f} dB")
    )  # fmt: skip
    for r in peaks:
        print(
            f"  data {r['reference_hz']:9.3f} Hz  model {r['model_hz']:9.3f} Hz"
            f"  ({100 * r['rel_error']:+.3f} %)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
