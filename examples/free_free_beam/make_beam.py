"""A roving-hammer test of a free-free beam, and the beam's lumped model.

The "measurement" comes from a model unlike the one fitted: an Euler–Bernoulli beam of
finite elements (80 Hermite elements, consistent mass), an aluminium flat bar
1.0 m × 50 mm × 10 mm hanging on soft cords, a 3 g accelerometer at one end (x = 0), light
modal damping (ζ = 0.4 % for every bending mode). The hammer roves over 9 points
x = 0, 0.125, …, 1 m and hits along z; the accelerometer measures z at x = 0. The file is
what an analyser exports: accelerance (m/s²/N), 51,201 lines from 0 to 1000 Hz (0.0195 Hz
apart) with the coherence, and measurement noise (1 % of the response plus a floor 40 dB under
the response's ±½-octave envelope, :func:`bondid.data.noise.add_measurement_noise`).

The fitted model (``beam_chain.urdf``, written with ``--model``) is what a test engineer
writes from a handbook: 8 rigid segments joined by 7 revolute springs about y (bending in the
x–z plane), a floating base (free-free), masses and rotational springs ``EI / l`` from the
nominal material values, the 9 hammer points and the accelerometer as measurement points.

Usage::

    python examples/free_free_beam/make_beam.py examples/free_free_beam/data
    python examples/free_free_beam/make_beam.py DIR --lines 2001 --f-max 500  # a small file

writes ``DIR/hammer_dense.csv`` (every line), ``DIR/hammer_thinned.csv`` (every 32nd line
and every line within ±0.5 Hz of each resonance of the data, as one reduces dense data by
hand) and ``DIR/truth_modes.json`` (the generator's own bending frequencies). ``--model
FILE`` also writes the chain model, of ``--segments N`` segments (a multiple of 8, so that
every hammer point falls on a joint; default 8).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

#: the bar: length [m], width, thickness, Young's modulus [Pa], density [kg/m³]
LENGTH, WIDTH, THICK = 1.0, 0.05, 0.01
E_TRUE, RHO_TRUE = 68.9e9, 2700.0
#: the handbook values a user starts from
E_NOMINAL, RHO_NOMINAL = 70.0e9, 2700.0
ACC_MASS = 0.003  # kg, the accelerometer at x = 0
ZETA = 0.004  # modal damping of every bending mode
ELEMENTS = 80
POINTS = 9  # hammer points x = k L / 8
SEGMENTS = 8
REL_NOISE, FLOOR_DB = 0.01, -40.0


def fe_beam(n_el: int = ELEMENTS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mass and stiffness matrices of the free-free bar (DOFs w, θ per node) and node x."""
    l = LENGTH / n_el
    EI = E_TRUE * WIDTH * THICK**3 / 12.0
    rhoA = RHO_TRUE * WIDTH * THICK
    k = EI / l**3 * np.array(
        [[12, 6 * l, -12, 6 * l], [6 * l, 4 * l**2, -6 * l, 2 * l**2],
         [-12, -6 * l, 12, -6 * l], [6 * l, 2 * l**2, -6 * l, 4 * l**2]]
    )  # fmt: skip
    m = rhoA * l / 420.0 * np.array(
        [[156, 22 * l, 54, -13 * l], [22 * l, 4 * l**2, 13 * l, -3 * l**2],
         [54, 13 * l, 156, -22 * l], [-13 * l, -3 * l**2, -22 * l, 4 * l**2]]
    )  # fmt: skip
    n = 2 * (n_el + 1)
    K, M = np.zeros((n, n)), np.zeros((n, n))
    for e in range(n_el):
        s = slice(2 * e, 2 * e + 4)
        K[s, s] += k
        M[s, s] += m
    M[0, 0] += ACC_MASS
    return M, K, np.linspace(0.0, LENGTH, n_el + 1)


def modes() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Natural frequencies ω [rad/s] (ascending, the two rigid ones 0) and mass-normalised
    shapes ``(n_dof, n_modes)`` of the bar; and the node x."""
    from scipy.linalg import eigh

    M, K, x = fe_beam()
    w2, phi = eigh(K, M)
    w = np.sqrt(np.clip(w2, 0.0, None))
    w[:2] = 0.0  # the two rigid-body modes (translation, rotation)
    return w, phi, x


def accelerance(freq_hz: np.ndarray) -> np.ndarray:
    """Exact accelerance ``(1, POINTS, n_freq)``: z at x = 0 per unit force along z at the
    hammer points, by modal superposition over every mode of the mesh."""
    w, phi, _ = modes()
    nodes = [round(k * ELEMENTS / (POINTS - 1)) for k in range(POINTS)]
    out_dof, in_dofs = 0, [2 * n for n in nodes]
    om = 2 * np.pi * np.asarray(freq_hz, float)
    A = np.zeros((1, POINTS, om.size), complex)
    for r in range(w.size):
        res = phi[out_dof, r] * phi[in_dofs, r]  # (POINTS,)
        if w[r] == 0.0:
            A[0] += res[:, None]  # −ω² · (−1/ω²)
        else:
            den = w[r] ** 2 - om**2 + 2j * ZETA * w[r] * om
            A[0] += res[:, None] * (-(om**2) / den)[None, :]
    return A


def truth_modes_hz(f_max: float) -> list[float]:
    w, _, _ = modes()
    f = w[w > 0] / (2 * np.pi)
    return [float(v) for v in f[f <= f_max]]


def write_csv(path: Path, f: np.ndarray, H: np.ndarray, coh: np.ndarray) -> None:
    """The analyser's export as a bondid CSV (a 0 Hz line included, as analysers write it)."""
    names = [f"acc.h{k}" for k in range(POINTS)]
    cols = ["freq_hz"] + [f"{c}.{p}" for c in names for p in ("re", "im")]
    cols += [f"{c}.coh" for c in names]
    lines = ["# bondid-frf: 1", "# quantity: accelerance", ",".join(cols)]
    for i in range(f.size):
        row = [repr(float(f[i]))]
        for k in range(POINTS):
            row += [repr(float(H[0, k, i].real)), repr(float(H[0, k, i].imag))]
        row += [repr(float(coh[0, k, i])) for k in range(POINTS)]
        lines.append(",".join(row))
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text("\n".join(lines) + "\n")
    tmp.replace(path)


def thinned(f: np.ndarray, peaks_hz: list[float], step: int = 32, half: float = 0.5) -> np.ndarray:
    """Indices kept by hand-thinning: every ``step``-th line and every line within ±``half``
    Hz of each resonance."""
    keep = np.zeros(f.size, bool)
    keep[::step] = True
    for p in peaks_hz:
        keep |= np.abs(f - p) <= half
    return np.flatnonzero(keep)


def data_peaks_hz(f: np.ndarray, H: np.ndarray, prominence_db: float = 10.0) -> list[float]:
    """The resonances as one finds them in the data: the peaks of the channels' summed
    magnitude that stand ``prominence_db`` above their surroundings."""
    from scipy.signal import find_peaks

    level = 20 * np.log10(np.nansum(np.abs(H), axis=(0, 1)) + 1e-300)
    idx, _ = find_peaks(level, prominence=prominence_db)
    return [float(f[i]) for i in idx if f[i] > 0]


def chain_urdf(n_seg: int = SEGMENTS) -> str:
    """The handbook chain model (see the module docstring) as URDF text.

    ``n_seg`` must be a multiple of ``POINTS - 1`` so that every hammer point falls on a
    joint between segments (or on an end).
    """
    if n_seg < POINTS - 1 or n_seg % (POINTS - 1):
        raise ValueError(f"--segments {n_seg}: must be a multiple of {POINTS - 1} (8, 16, 24, ...)")
    per = n_seg // (POINTS - 1)
    l = LENGTH / n_seg
    m = RHO_NOMINAL * WIDTH * THICK * l
    EI = E_NOMINAL * WIDTH * THICK**3 / 12.0
    ixx = m * (WIDTH**2 + THICK**2) / 12.0
    iyy = m * (l**2 + THICK**2) / 12.0
    izz = m * (l**2 + WIDTH**2) / 12.0
    parts = [
        '<?xml version="1.0"?>',
        f"<!-- A free-free aluminium bar 1.0 m x 50 mm x 10 mm as {n_seg} rigid segments joined by",
        "     rotational springs EI/l about y (bending in the x-z plane), from handbook values",
        "     (E = 70 GPa, rho = 2700 kg/m3). The floating base comes from the study",
        "     (floating_base = true). p0..p8: the hammer points (and the accelerometer at p0). -->",
        '<robot name="beam_chain">',
    ]
    for k in range(n_seg):
        parts += [
            f'  <link name="seg{k}">',
            "    <inertial>",
            f'      <origin xyz="{l / 2!r} 0 0" rpy="0 0 0"/>',
            f'      <mass value="{m!r}"/>',
            f'      <inertia ixx="{ixx!r}" ixy="0" ixz="0" iyy="{iyy!r}" iyz="0" izz="{izz!r}"/>',
            "    </inertial>",
            "    <collision>",
            f'      <origin xyz="{l / 2!r} 0 0" rpy="0 0 0"/>',
            f'      <geometry><box size="{l!r} {WIDTH!r} {THICK!r}"/></geometry>',
            "    </collision>",
            "  </link>",
        ]
    for k in range(1, n_seg):
        parts += [
            f'  <joint name="j{k}" type="revolute">',
            f'    <parent link="seg{k - 1}"/>',
            f'    <child link="seg{k}"/>',
            f'    <origin xyz="{l!r} 0 0" rpy="0 0 0"/>',
            '    <axis xyz="0 1 0"/>',
            '    <limit lower="-0.1" upper="0.1" effort="100" velocity="1"/>',
            '    <dynamics damping="0.01"/>',
            "  </joint>",
            f'  <gazebo reference="j{k}">',
            f"    <springStiffness>{EI / l!r}</springStiffness>",
            "    <springReference>0</springReference>",
            "  </gazebo>",
        ]
    for k in range(POINTS):
        seg, x = (k * per, 0.0) if k * per < n_seg else (n_seg - 1, l)
        parts += [
            f'  <link name="p{k}"/>',
            f'  <joint name="fix_p{k}" type="fixed">',
            f'    <parent link="seg{seg}"/>',
            f'    <child link="p{k}"/>',
            f'    <origin xyz="{x!r} 0 0" rpy="0 0 0"/>',
            "  </joint>",
        ]
    for k in range(POINTS):
        parts.append(
            f'  <measurement_point name="h{k}" link="p{k}" kind="translation"'
            ' direction="0.0 0.0 1.0" axes="world"/>'
        )
    parts.append(
        '  <measurement_point name="acc" link="p0" kind="translation" direction="0.0 0.0 1.0"'
        ' axes="world"/>'
    )
    parts.append("</robot>")
    return "\n".join(parts) + "\n"


def main(argv: list[str] | None = None) -> int:
    from bondid.data.noise import add_measurement_noise

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out", type=Path, help="folder for the data files")
    p.add_argument("--lines", type=int, default=51201, help="analyser lines, 0 Hz included")
    p.add_argument("--f-max", type=float, default=1000.0, help="last line [Hz]")
    p.add_argument("--seed", type=int, default=0, help="noise seed")
    p.add_argument("--model", type=Path, help="also write the chain model URDF here")
    p.add_argument(
        "--segments", type=int, default=SEGMENTS,
        help=f"rigid segments of the chain model (a multiple of {POINTS - 1}; default {SEGMENTS})",
    )  # fmt: skip
    a = p.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    f = np.linspace(0.0, a.f_max, a.lines)
    A = accelerance(f)
    H, coh = add_measurement_noise(
        A, np.where(f > 0, f, f[1]), rel=REL_NOISE, floor_db=FLOOR_DB, rng=a.seed,
        floor_ref="response", quantity="accelerance",
    )  # fmt: skip
    write_csv(a.out / "hammer_dense.csv", f, H, coh)
    peaks = truth_modes_hz(a.f_max)
    keep = thinned(f, data_peaks_hz(f, H))
    write_csv(a.out / "hammer_thinned.csv", f[keep], H[:, :, keep], coh[:, :, keep])
    truth = {"bending_modes_hz": peaks, "zeta": ZETA, "lines": int(f.size),
             "thinned_lines": int(keep.size)}  # fmt: skip
    (a.out / "truth_modes.json").write_text(json.dumps(truth, indent=2) + "\n")
    if a.model is not None:
        a.model.write_text(chain_urdf(a.segments))
    print(
        f"{a.out}: hammer_dense.csv ({f.size} lines), hammer_thinned.csv ({keep.size} lines);"
        f" bending modes {', '.join(f'{v:.2f}' for v in peaks)} Hz"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
