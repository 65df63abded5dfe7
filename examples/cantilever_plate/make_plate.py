"""A cantilever plate driven by 2 piezo patches, measured by 2 accelerometers, and its model.

The "measurement" comes from a model unlike the one fitted: a Kirchhoff plate (aluminium,
300 × 100 × 2 mm, clamped along x = 0) by the Rayleigh–Ritz method (4 cantilever functions
along x times 3 free–free functions across y: bending, torsion and the first plate mode), with
two things no model of the plate has:

* the fixture: the clamp's own resonance at 22.57 Hz (ζ = 2 %) seen in every channel;
* the drive amplifier's first-order lag (corner 11.5 Hz: about 60° of phase lag at 20 Hz).

The patches (40 × 30 mm at x = 10–50 mm, one on each side of the centre line, y = 5–35 mm and
65–95 mm) strain the plate along x: each drives bending and, being off the centre line,
torsion. Accelerometers at the free corners (x = 300 mm, y = 10 and 90 mm) measure z.
Accelerance (m/s² per V), 1601 lines 5–405 Hz with coherence, modal damping 0.5 %, noise
1 % of the response plus a floor 50 dB under its ±½-octave envelope.

The fitted model (``plate_chain.urdf``, written with ``--model``): the plate as 3 rigid
segments, each joined to the previous by a bending spring (about y) then a torsion spring
(about x), springs from handbook values; the patches as torque points (about y, on the first
segment, reacting on the clamp) and their V → N·m constants as gains are declared in the
study (``study.toml``), the accelerometers as points in the URDF.

Usage::

    python examples/cantilever_plate/make_plate.py examples/cantilever_plate/data \\
        --model examples/cantilever_plate/plate_chain.urdf

writes ``DIR/plate.csv`` and ``DIR/truth_modes.json`` (the plate's own modes in the band and
the fixture's).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

L, B, H = 0.30, 0.10, 0.002  # m
E, NU, RHO = 70e9, 0.33, 2700.0
ZETA = 0.005
FIXTURE_HZ, FIXTURE_ZETA = 22.57, 0.02
LAG_HZ = 11.5  # the amplifier's corner
PATCH_X = (0.010, 0.050)
PATCH_Y = ((0.005, 0.035), (0.065, 0.095))
PATCH_MOMENT = 0.05  # N·m per V: the bending moment a patch induces across its width
ACC_AT = ((L, 0.010), (L, 0.090))
N_X, N_Y = 4, 3
REL_NOISE, FLOOR_DB = 0.01, -50.0
_CANTI = (1.875104069, 4.694091133, 7.854757438, 10.99554073)
_FREE = 4.730040745


def _cantilever(m: int, x: np.ndarray, d: int) -> np.ndarray:
    """d-th derivative of the m-th clamped–free beam function on [0, L]."""
    b = _CANTI[m] / L
    s = (np.cosh(b * L) + np.cos(b * L)) / (np.sinh(b * L) + np.sin(b * L))
    t = b * x
    funcs = [
        lambda: np.cosh(t) - np.cos(t) - s * (np.sinh(t) - np.sin(t)),
        lambda: b * (np.sinh(t) + np.sin(t) - s * (np.cosh(t) - np.cos(t))),
        lambda: b**2 * (np.cosh(t) + np.cos(t) - s * (np.sinh(t) + np.sin(t))),
    ]
    return funcs[d]()


def _across(n: int, y: np.ndarray, d: int) -> np.ndarray:
    """d-th derivative of the n-th free–free function across the width: 1, the rigid rotation,
    then the first elastic free–free beam function."""
    u = 2 * y / B - 1
    if n == 0:
        return np.ones_like(y) if d == 0 else np.zeros_like(y)
    if n == 1:
        return [np.sqrt(3) * u, np.full_like(y, 2 * np.sqrt(3) / B), np.zeros_like(y)][d]
    b = _FREE / B
    s = (np.cosh(_FREE) - np.cos(_FREE)) / (np.sinh(_FREE) - np.sin(_FREE))
    t = b * y
    funcs = [
        lambda: np.cosh(t) + np.cos(t) - s * (np.sinh(t) + np.sin(t)),
        lambda: b * (np.sinh(t) - np.sin(t) - s * (np.cosh(t) - np.cos(t))),
        lambda: b**2 * (np.cosh(t) - np.cos(t) - s * (np.sinh(t) - np.sin(t))),
    ]
    return funcs[d]()


def ritz() -> tuple[np.ndarray, np.ndarray]:
    """Natural frequencies ω [rad/s] and mass-normalised shapes ``(N_X·N_Y, n)`` (Ritz
    coordinates) of the clamped plate."""
    from scipy.linalg import eigh

    gx, wx = np.polynomial.legendre.leggauss(80)
    gy, wy = np.polynomial.legendre.leggauss(40)
    x, wxs = 0.5 * L * (gx + 1), 0.5 * L * wx
    y, wys = 0.5 * B * (gy + 1), 0.5 * B * wy
    D = E * H**3 / (12 * (1 - NU**2))
    n = N_X * N_Y
    Xd = [[_cantilever(m, x, d) for d in range(3)] for m in range(N_X)]
    Yd = [[_across(k, y, d) for d in range(3)] for k in range(N_Y)]
    idx = [(m, k) for m in range(N_X) for k in range(N_Y)]
    K, M = np.zeros((n, n)), np.zeros((n, n))

    def integral(fx: np.ndarray, fy: np.ndarray) -> float:
        return float((wxs @ fx) * (wys @ fy))

    for i, (m, k) in enumerate(idx):
        for j, (p, q) in enumerate(idx):
            M[i, j] = RHO * H * integral(Xd[m][0] * Xd[p][0], Yd[k][0] * Yd[q][0])
            K[i, j] = D * (
                integral(Xd[m][2] * Xd[p][2], Yd[k][0] * Yd[q][0])
                + integral(Xd[m][0] * Xd[p][0], Yd[k][2] * Yd[q][2])
                + NU * integral(Xd[m][2] * Xd[p][0], Yd[k][0] * Yd[q][2])
                + NU * integral(Xd[m][0] * Xd[p][2], Yd[k][2] * Yd[q][0])
                + 2 * (1 - NU) * integral(Xd[m][1] * Xd[p][1], Yd[k][1] * Yd[q][1])
            )
    w2, phi = eigh(0.5 * (K + K.T), 0.5 * (M + M.T))
    return np.sqrt(w2), phi


def _shape_at(x: float, y: float) -> np.ndarray:
    """Ritz functions at a point ``(N_X·N_Y,)``."""
    xs, ys = np.array([x]), np.array([y])
    return np.array([_cantilever(m, xs, 0)[0] * _across(k, ys, 0)[0]
                     for m in range(N_X) for k in range(N_Y)])  # fmt: skip


def _patch_load(y_span: tuple[float, float]) -> np.ndarray:
    """Generalised forces of a patch inducing a bending moment (per unit width) along x over
    its area: ``∫∫ m_x ∂²w/∂x² dA`` per Ritz function ``(N_X·N_Y,)``."""
    gy, wy = np.polynomial.legendre.leggauss(20)
    y0, y1 = y_span
    y = y0 + 0.5 * (y1 - y0) * (gy + 1)
    wys = 0.5 * (y1 - y0) * wy
    out = []
    for m in range(N_X):
        dx = (
            _cantilever(m, np.array([PATCH_X[1]]), 1)[0]
            - _cantilever(m, np.array([PATCH_X[0]]), 1)[0]
        )
        for k in range(N_Y):
            out.append(PATCH_MOMENT / (y1 - y0) * dx * float(wys @ _across(k, y, 0)))
    return np.array(out)


def accelerance(freq_hz: np.ndarray) -> tuple[np.ndarray, list[float]]:
    """Accelerance ``(2, 2, n_freq)`` (accelerometers × patches, m/s² per V) with the fixture
    and the amplifier's lag; and the plate's own natural frequencies (Hz)."""
    w, phi = ritz()
    outs = np.array([_shape_at(*p) for p in ACC_AT]) @ phi  # (2, n)
    ins = np.array([_patch_load(s) for s in PATCH_Y]) @ phi  # (2, n)
    om = 2 * np.pi * np.asarray(freq_hz, float)
    A = np.zeros((2, 2, om.size), complex)
    for r in range(w.size):
        den = w[r] ** 2 - om**2 + 2j * ZETA * w[r] * om
        A += np.einsum("o,i->oi", outs[:, r], ins[:, r])[:, :, None] * (-(om**2) / den)
    # the fixture: a mode every channel sees, residue a fifth of the first bending mode's
    wf = 2 * np.pi * FIXTURE_HZ
    res = 0.2 * np.einsum("o,i->oi", outs[:, 0], ins[:, 0]) * w[0] ** 2 / wf**2
    A += res[:, :, None] * (-(om**2) / (wf**2 - om**2 + 2j * FIXTURE_ZETA * wf * om))
    A = A / (1.0 + 1j * np.asarray(freq_hz) / LAG_HZ)[None, None, :]
    return A, [float(v) for v in w / (2 * np.pi)]


def chain_urdf(n_seg: int = 3) -> str:
    """The plate as ``n_seg`` rigid segments (bending then torsion spring at each joint)."""
    l = L / n_seg
    m = RHO * L * B * H / n_seg
    EI, GJ = E * B * H**3 / 12.0, E / (2 * (1 + NU)) * B * H**3 / 3.0
    ixx, iyy, izz = m * (B**2 + H**2) / 12, m * (l**2 + H**2) / 12, m * (l**2 + B**2) / 12
    parts = [
        '<?xml version="1.0"?>',
        "<!-- A cantilever aluminium plate 300 x 100 x 2 mm clamped along x = 0, as 3 rigid",
        "     segments; each joint a bending spring EI/l (about y) then a torsion spring GJ/l",
        "     (about x), handbook values. Accelerometers at the free corners; the patches are",
        "     declared in the study. -->",
        '<robot name="plate_chain">',
        '  <link name="clamp"/>',
    ]
    for k in range(n_seg):
        parent = "clamp" if k == 0 else f"seg{k - 1}"
        x0 = 0.0 if k == 0 else l
        parts += [
            f'  <link name="bend{k}"/>',
            f'  <joint name="b{k}" type="revolute"><parent link="{parent}"/>'
            f'<child link="bend{k}"/><origin xyz="{x0!r} 0 0"/><axis xyz="0 1 0"/>'
            '<limit lower="-0.1" upper="0.1" effort="10" velocity="1"/>'
            '<dynamics damping="0.001"/></joint>',
            f'  <gazebo reference="b{k}"><springStiffness>{EI / l!r}</springStiffness>'
            "<springReference>0</springReference></gazebo>",
            f'  <link name="seg{k}"><inertial><origin xyz="{l / 2!r} 0 0"/>'
            f'<mass value="{m!r}"/><inertia ixx="{ixx!r}" ixy="0" ixz="0" iyy="{iyy!r}"'
            f' iyz="0" izz="{izz!r}"/></inertial><collision><origin xyz="{l / 2!r} 0 0"/>'
            f'<geometry><box size="{l!r} {B!r} {H!r}"/></geometry></collision></link>',
            f'  <joint name="t{k}" type="revolute"><parent link="bend{k}"/>'
            f'<child link="seg{k}"/><axis xyz="1 0 0"/>'
            '<limit lower="-0.1" upper="0.1" effort="10" velocity="1"/>'
            '<dynamics damping="0.0001"/></joint>',
            f'  <gazebo reference="t{k}"><springStiffness>{GJ / l!r}</springStiffness>'
            "<springReference>0</springReference></gazebo>",
        ]
    last = f"seg{n_seg - 1}"
    for i, (x, y) in enumerate(ACC_AT, start=1):
        parts += [
            f'  <link name="acc{i}_at"/>',
            f'  <joint name="fix_acc{i}" type="fixed"><parent link="{last}"/>'
            f'<child link="acc{i}_at"/><origin xyz="{x - (n_seg - 1) * l!r} {y - B / 2!r} 0"/>'
            "</joint>",
            f'  <measurement_point name="acc{i}" link="acc{i}_at" kind="translation"'
            ' direction="0.0 0.0 1.0" axes="world"/>',
        ]
    parts.append("</robot>")
    return "\n".join(parts) + "\n"


def main(argv: list[str] | None = None) -> int:
    from bondid.data.io import write_frf
    from bondid.data.measurement import FrfData
    from bondid.data.noise import add_measurement_noise

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out", type=Path, help="folder for the data files")
    p.add_argument("--lines", type=int, default=1601, help="analyser lines")
    p.add_argument("--seed", type=int, default=0, help="noise seed")
    p.add_argument("--model", type=Path, help="also write the chain model URDF here")
    a = p.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    f = np.linspace(5.0, 405.0, a.lines)
    A, f_plate = accelerance(f)
    Hn, coh = add_measurement_noise(A, f, rel=REL_NOISE, floor_db=FLOOR_DB, rng=a.seed,
                                    floor_ref="response", quantity="accelerance")  # fmt: skip
    data = FrfData(f, ("acc1", "acc2"), ("patch1", "patch2"), Hn, "accelerance", {}, coh)
    write_frf(data, a.out / "plate.csv")
    in_band = [v for v in f_plate if f[0] <= v <= f[-1]]
    truth = {"plate_modes_hz": in_band, "fixture_hz": FIXTURE_HZ, "lag_corner": LAG_HZ,
             "zeta": ZETA}  # fmt: skip
    (a.out / "truth_modes.json").write_text(json.dumps(truth, indent=2) + "\n")
    if a.model is not None:
        a.model.write_text(chain_urdf())
    print(f"{a.out / 'plate.csv'}: {f.size} lines; plate modes in the band"
          f" {', '.join(f'{v:.2f}' for v in in_band)} Hz, fixture {FIXTURE_HZ} Hz")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
