"""Benchmark the FRF engine against a bare NumPy batched complex solve of the same size.

Both run in one process, interleaved, and the report gives ratios (engine / baseline), which
are meaningful on a shared, noisy machine where absolute times are not:

* the reference bonder (urdf/bonder.urdf) at 2000 log-spaced frequencies, 3×3 channels;
* growth with model size: serial spring-mass chains of 10, 20 and 40 DOF (3 inputs, 3 outputs);
* growth with the number of frequencies: 500, 2000, 8000 on the bonder.

The baseline is the practical floor for this computation in NumPy::

    Z = K − ω²M + jωD  (n_f, n, n);  X = np.linalg.solve(Z, B);  H = C @ X

    python tools/bench_frf.py [--repeat 15] [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT / "src") not in sys.path:
    sys.path.insert(0, str(ROOT / "src"))

from bondid.frf import frf  # noqa: E402
from bondid.linear import LinearModel, linearise  # noqa: E402
from bondid.model import UrdfDocument  # noqa: E402


def chain_model(n: int) -> UrdfDocument:
    """A serial chain of ``n`` sprung prismatic/revolute joints, actuated at 3 of them."""
    parts = ['<robot name="chain"><link name="l0"/>']
    for i in range(1, n + 1):
        kind = "prismatic" if i % 2 else "revolute"
        axis = ("1 0 0", "0 1 0", "0 0 1")[i % 3]
        parts.append(
            f'<link name="l{i}"><inertial><origin xyz="0.01 0.02 0.05"/>'
            f'<mass value="{1 + 0.1 * i}"/>'
            f'<inertia ixx="0.01" ixy="0.001" ixz="0" iyy="0.012" iyz="0.0005" izz="0.008"/>'
            f"</inertial></link>"
            f'<joint name="j{i}" type="{kind}"><parent link="l{i - 1}"/><child link="l{i}"/>'
            f'<origin xyz="0 0 0.1"/><axis xyz="{axis}"/>'
            f'<limit lower="-1" upper="1" effort="1" velocity="1"/><dynamics damping="{0.5 + i}"/>'
            f"</joint>"
            f'<gazebo reference="j{i}"><springStiffness>{1e4 * (1 + i)}</springStiffness>'
            f"</gazebo>"
        )
    for i in (1, n // 2, n):
        parts.append(
            f'<transmission name="t{i}"><joint name="j{i}"><hardwareInterface>'
            f"hardware_interface/EffortJointInterface</hardwareInterface></joint></transmission>"
        )
    parts.append("</robot>")
    return UrdfDocument.from_string("".join(parts), source=f"<chain {n}>")


def baseline(lm: LinearModel, freq_hz: np.ndarray) -> np.ndarray:
    w = 2 * np.pi * freq_hz
    Z = lm.K[None] - (w**2)[:, None, None] * lm.M[None] + 1j * w[:, None, None] * lm.D[None]
    X = np.linalg.solve(Z, np.broadcast_to(lm.B.astype(complex), (w.size, *lm.B.shape)))
    return lm.C @ X


def engine(lm: LinearModel, freq_hz: np.ndarray) -> np.ndarray:
    return frf(lm.M, lm.K, lm.D, lm.B, lm.C, freq_hz)


def best_of(fns: list[Callable[[], object]], repeat: int) -> list[float]:
    """Interleaved runs; the minimum time of each (least disturbed by other load)."""
    times = [[] for _ in fns]
    for _ in range(repeat):
        for k, fn in enumerate(fns):
            t0 = time.perf_counter()
            fn()
            times[k].append(time.perf_counter() - t0)
    return [min(t) for t in times]


def compare(label: str, lm: LinearModel, f: np.ndarray, repeat: int) -> tuple[str, float, float]:
    H_e, H_b = engine(lm, f), np.moveaxis(baseline(lm, f), 0, 2)
    err = np.max(np.abs(H_e - H_b) / np.abs(H_b).max())
    assert err < 1e-12, f"{label}: engine and baseline disagree ({err:.1e})"
    t_e, t_b = best_of([lambda: engine(lm, f), lambda: baseline(lm, f)], repeat)
    return label, t_e, t_b


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--quick", action="store_true", help="few repeats (a smoke run)")
    args = ap.parse_args(argv)
    repeat = 3 if args.quick else args.repeat
    bonder = linearise(UrdfDocument.load(ROOT / "urdf" / "bonder.urdf"))
    rows = [
        compare(
            f"bonder ({bonder.nv} DOF), 2000 freq",
            bonder,
            np.logspace(0, np.log10(4000), 2000),
            repeat,
        )
    ]
    for n in (10, 20, 40):
        rows.append(
            compare(
                f"chain {n} DOF, 2000 freq",
                linearise(chain_model(n)),
                np.logspace(0, 3.6, 2000),
                repeat,
            )
        )
    for nf in (500, 2000, 8000):
        rows.append(
            compare(f"bonder, {nf} freq", bonder, np.logspace(0, np.log10(4000), nf), repeat)
        )
    print(f"{'case':34s} {'engine [ms]':>12s} {'numpy [ms]':>12s} {'ratio':>7s}")
    for label, t_e, t_b in rows:
        print(f"{label:34s} {1e3 * t_e:12.2f} {1e3 * t_b:12.2f} {t_e / t_b:7.2f}")
    worst = max(t_e / t_b for _, t_e, t_b in rows)
    print(f"worst ratio engine/numpy: {worst:.2f} (goal ≤ 1.5)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
