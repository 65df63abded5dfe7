"""Figures of the motor-bench fit: resonance and anti-resonance of the data and of the fitted
model, db_rms per channel, and a Bode overlay with the model on a dense grid.

Usage (after the fit of README.md)::

    python examples/motor_bench/check.py examples/motor_bench/motor_bench.csv results/motor_bench

The data's resonance (peak of |H|) and anti-resonance (dip) are found from the measured
points alone: a local rational model ``(b0 + b1 s + b2 s²)/(a0 + a1 s + s²)`` fitted by linear
least squares (Levy) to the 9 lines around the largest |H| (for the dip: to 1/H around the
smallest), then its extremum on a 0.001 Hz grid. The model's come from its FRF on the same
fine grid. Writes ``check.json`` and ``bode_dense.png`` into the results folder.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from bondid.atomic import write_text_atomic
from bondid.data.io import read_frf
from bondid.linear.affine import build_affine_model
from bondid.model import UrdfDocument

HALF_WINDOW = 4  # lines each side of the extremum for the local rational model
FINE_HZ = 0.001


def _levy(f: np.ndarray, H: np.ndarray) -> np.ndarray:
    """Coefficients (a0, a1, b0, b1, b2) of H ≈ (b0 + b1 s + b2 s²)/(a0 + a1 s + s²)."""
    s = 2j * np.pi * f
    A = np.column_stack([H, H * s, -np.ones_like(s), -s, -(s**2)])
    rhs = -H * s**2
    Ar = np.vstack([A.real, A.imag])
    br = np.concatenate([rhs.real, rhs.imag])
    scale = np.linalg.norm(Ar, axis=0)
    x = np.linalg.lstsq(Ar / scale, br, rcond=None)[0] / scale
    return x


def _extremum_index(f: np.ndarray, H: np.ndarray, kind: str) -> int:
    """The interior local maximum (minimum) of |H| that stands out most above (below) the
    rigid-body line (ranked by |H|·f²): the resonance (anti-resonance)."""
    a = np.abs(H)
    sign = 1.0 if kind == "max" else -1.0
    inner = [
        k for k in range(1, a.size - 1) if sign * (a[k] - a[k - 1]) > 0 < sign * (a[k] - a[k + 1])
    ]
    if not inner:
        raise ValueError(f"no interior local {kind}imum of |H|")
    return max(inner, key=lambda k: sign * a[k] * f[k] ** 2)


def _local_extremum(f: np.ndarray, H: np.ndarray, kind: str) -> float:
    """Frequency [Hz] of the peak (kind 'max') or dip ('min') of |H| from the data alone."""
    k = _extremum_index(f, H, kind)
    sl = slice(max(k - HALF_WINDOW, 0), k + HALF_WINDOW + 1)
    G = H[sl] if kind == "max" else 1.0 / H[sl]
    a0, a1, b0, b1, b2 = _levy(f[sl], G)
    ff = np.arange(f[sl][0], f[sl][-1], FINE_HZ)
    s = 2j * np.pi * ff
    g = np.abs((b0 + b1 * s + b2 * s**2) / (a0 + a1 * s + s**2))
    return float(ff[np.argmax(g)])


def _model_extremum(doc: UrdfDocument, f: np.ndarray, H: np.ndarray, kind: str) -> float:
    """The same extremum of the model's |H_motor,motor| on a fine grid near the data's."""
    k = _extremum_index(f, H, kind)
    lo, hi = f[max(k - HALF_WINDOW, 0)], f[min(k + HALF_WINDOW, f.size - 1)]
    ff = np.arange(lo, hi, FINE_HZ)
    Hm = build_affine_model(doc, outputs=("motor",)).linear_model().frf(ff)[0, 0]
    g = np.abs(Hm)
    return float(ff[np.argmax(g) if kind == "max" else np.argmin(g)])


def _phase(H: np.ndarray) -> np.ndarray:
    """Phase in degrees, wrapped to [-360, 0) (a lag never shows as a lead)."""
    return np.mod(np.angle(H, deg=True), 360.0) - 360.0


def _plot(doc: UrdfDocument, data, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ff = np.geomspace(data.freq_hz[0], data.freq_hz[-1], 3000)
    Hm = build_affine_model(doc, outputs=data.outputs).linear_model().frf(ff)
    fig, ax = plt.subplots(2, 2, figsize=(11, 6), sharex=True)
    for o, name in enumerate(data.outputs):
        H = data.H[o, 0]
        ax[0, o].loglog(data.freq_hz, np.abs(H), "o", ms=3, color="0.4", label="measured")
        ax[0, o].loglog(ff, np.abs(Hm[o, 0]), "-", color="C3", label="fitted model")
        ax[1, o].semilogx(data.freq_hz, _phase(H), "o", ms=3, color="0.4")
        ax[1, o].semilogx(ff, _phase(Hm[o, 0]), "-", color="C3")
        ax[0, o].set_title(f"{name}.{data.inputs[0]} [rad/A]")
        ax[1, o].set_xlabel("frequency [Hz]")
        ax[1, o].set_ylim(-365, 5)
    ax[0, 0].set_ylabel("|H|")
    ax[1, 0].set_ylabel("phase [°]")
    ax[0, 0].legend()
    fig.tight_layout()
    tmp = path.with_name(path.name + ".tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)


def main(argv: list[str]) -> int:
    data_path, results = Path(argv[0]), Path(argv[1])
    data = read_frf(data_path)
    doc = UrdfDocument.load(results / "fitted.urdf")
    fit = json.loads((results / "fit.json").read_text())
    f, H = data.freq_hz, data.H[data.outputs.index("motor"), 0]
    out = {}
    for label, kind in (("resonance", "max"), ("anti_resonance", "min")):
        fd, fm = _local_extremum(f, H, kind), _model_extremum(doc, f, H, kind)
        out[label] = {"data_hz": fd, "model_hz": fm, "rel_error": fm / fd - 1.0}
        print(f"{label:15s} data {fd:8.3f} Hz  model {fm:8.3f} Hz  ({100 * (fm / fd - 1):+.2f} %)")
    out["db_rms"] = fit["db_rms"]["by_channel"]
    for ch, v in out["db_rms"].items():
        print(f"db_rms {ch:12s} {v['initial']:.3f} dB → {v['final']:.3f} dB")
    out["parameters"] = {p["name"]: p["fitted"] for p in fit["parameters"]}
    write_text_atomic(results / "check.json", json.dumps(out, indent=2) + "\n")
    _plot(doc, data, results / "bode_dense.png")
    print(f"wrote {results / 'check.json'}, {results / 'bode_dense.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
