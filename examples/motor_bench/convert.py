"""Convert an FRF stored in a NumPy ``.npz`` (keys ``f`` [Hz], ``H`` complex ``(n_out, n_in,
n_freq)``, optional ``coh``) into a bondid CSV file, naming its channels for a model.

Usage (the motor bench of this folder; its converted ``motor_bench.csv`` is bundled, this
rebuilds it from FdiTools' original ``motor_bench_B.npz``, wherever it is)::

    python examples/motor_bench/convert.py PATH/TO/motor_bench_B.npz \\
        examples/motor_bench/motor_bench.csv --outputs motor load --inputs motor

``--outputs``/``--inputs`` give the bondid channel names in the file's order (a joint name
for an encoder or an actuator, a measurement-point name otherwise). The values are written
as they are (here rad/A: the input is a current, so the model's input gain is the torque
constant). The input file is only read; the output is written atomically and never over
the input.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from bondid.data.io import write_frf
from bondid.data.measurement import FrfData
from bondid.exceptions import BondidError


def convert(src: Path, dst: Path, outputs: list[str], inputs: list[str], quantity: str) -> FrfData:
    """Read ``src`` (npz) and write ``dst`` (CSV or UFF58 by suffix); returns the data."""
    with np.load(src, allow_pickle=False) as z:
        f = np.asarray(z["f"], dtype=float)
        H = np.asarray(z["H"], dtype=complex)
        coh = np.asarray(z["coh"], dtype=float) if "coh" in z.files else None
    if H.shape[:2] != (len(outputs), len(inputs)):
        raise BondidError(
            f"{src}: H has {H.shape[0]} outputs × {H.shape[1]} inputs; --outputs/--inputs"
            f" give {len(outputs)} × {len(inputs)}"
        )
    data = FrfData(f, tuple(outputs), tuple(inputs), H, quantity, {}, coh, str(src))
    if dst.resolve() == src.resolve():
        raise BondidError(f"{dst}: is the input file; give another output path")
    write_frf(data, dst)
    return data


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("src", type=Path, help="the .npz file")
    p.add_argument("dst", type=Path, help="the bondid file to write (.csv or .uff)")
    p.add_argument("--outputs", nargs="+", required=True, help="output channel names")
    p.add_argument("--inputs", nargs="+", required=True, help="input channel names")
    p.add_argument("--quantity", default="receptance", help="receptance (default), mobility…")
    a = p.parse_args(argv)
    try:
        d = convert(a.src, a.dst, a.outputs, a.inputs, a.quantity)
    except (BondidError, OSError, KeyError) as exc:
        print(f"bad input: {exc}", file=sys.stderr)
        return 2
    print(
        f"{a.dst}: {', '.join(d.channels)}, {d.freq_hz.size} lines "
        f"{d.freq_hz[0]:g}–{d.freq_hz[-1]:g} Hz"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
