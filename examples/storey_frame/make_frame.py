"""A three-storey frame tested with 3 references, exported as a vendor's UFF58 file.

The "measurement" comes from a model unlike the one fitted: each storey's columns carry
their own mass at mid-height (a finer model: 12 degrees of freedom, the fitted one has 6),
floors of 20, 20 and 15 kg on columns 3–4 × 10⁵ N/m along x and 2.4–3 × 10⁵ N/m along y, light
joint damping. The hammer hits floor 3 along x and along y and floor 1 along x (the 3
references); accelerometers on every floor measure x and y (6 responses). The file is what a
vendor's software exports: ASCII UFF58, one record per channel with its coherence, accelerance
(m/s²/N), 481 lines 0–60 Hz, the vendor's own node numbers (floor k: node 100·k + 1,
direction +1 = x, +2 = y) and no channel names; noise 1 % of the response plus a floor 50 dB
under its ±½-octave envelope.

The fitted model (``frame.urdf``, written with ``--model``): each storey two shear springs
(prismatic x then y), the floor and its columns as one rigid mass, handbook values 15 % off.
Next to it ``frame_columns.urdf``: the data's own finer structure (the columns' mass at
mid-height), from the same handbook values — the model that can express the data.

Usage::

    python examples/storey_frame/make_frame.py examples/storey_frame/data \\
        --model examples/storey_frame/frame.urdf

writes ``DIR/frame.uff``, ``DIR/truth_modes.json`` and the finer model itself,
``DIR/truth.urdf``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

FLOOR_KG = (20.0, 20.0, 15.0)
COLUMN_KG = 2.0  # per storey, at mid-height
K_X = (4.0e5, 3.6e5, 3.2e5)  # N/m per storey
K_Y = (3.0e5, 2.7e5, 2.4e5)
DAMPING = 25.0  # N·s/m per storey and direction
#: the vendor's nodes: floor k -> 100 k + 1; UFF directions +1 = x, +2 = y
NODES = {f"a{k}{ax}": (100 * k + 1, d) for k in (1, 2, 3) for ax, d in (("x", 1), ("y", 2))}
REFERENCES = {"h3x": (301, 1), "h3y": (301, 2), "h1x": (101, 1)}
REL_NOISE, FLOOR_DB = 0.01, -50.0


def _link(name: str, mass: float) -> str:
    if mass == 0:
        return f'<link name="{name}"/>'
    i = mass * 0.02
    return (
        f'<link name="{name}"><inertial><mass value="{mass!r}"/><inertia ixx="{i!r}" ixy="0"'
        f' ixz="0" iyy="{i!r}" iyz="0" izz="{i!r}"/></inertial><collision><geometry>'
        '<box size="0.5 0.5 0.05"/></geometry></collision></link>'
    )


def _slide(name: str, parent: str, child: str, axis: str, k: float, d: float) -> str:
    return (
        f'<joint name="{name}" type="prismatic"><parent link="{parent}"/><child link="{child}"/>'
        f'<axis xyz="{axis}"/><limit lower="-0.1" upper="0.1" effort="1e4" velocity="1"/>'
        f'<dynamics damping="{d!r}"/></joint><gazebo reference="{name}"><springStiffness>'
        f"{k!r}</springStiffness><springReference>0</springReference></gazebo>"
    )


def _points() -> str:
    out = []
    for k in (1, 2, 3):
        for ax, vec in (("x", "1.0 0.0 0.0"), ("y", "0.0 1.0 0.0")):
            out.append(
                f'<measurement_point name="a{k}{ax}" link="floor{k}" kind="translation"'
                f' direction="{vec}" axes="world"/>'
            )
    for name, k, vec in (("h3x", 3, "1.0 0.0 0.0"), ("h3y", 3, "0.0 1.0 0.0"),
                         ("h1x", 1, "1.0 0.0 0.0")):  # fmt: skip
        out.append(
            f'<measurement_point name="{name}" link="floor{k}" kind="translation"'
            f' direction="{vec}" axes="world"/>'
        )
    return "".join(out)


def truth_urdf(mass: float = 1.0, stiff: float = 1.0, damp: float = 1.0) -> str:
    """The finer model: per storey a column mass at mid-height between two half-columns
    (each twice as stiff as the storey); its masses, springs and dampers scaled by ``mass``,
    ``stiff`` and ``damp`` (1: the truth)."""
    parts = ['<robot name="frame_columns"><link name="ground"/>']
    parent = "ground"
    d = 2 * DAMPING * damp
    for k in range(3):
        s = k + 1
        kx, ky = 2 * K_X[k] * stiff, 2 * K_Y[k] * stiff
        parts += [_link(f"c{s}x", 0), _link(f"col{s}", COLUMN_KG * mass), _link(f"f{s}x", 0),
                  _link(f"floor{s}", FLOOR_KG[k] * mass)]  # fmt: skip
        parts.append(_slide(f"lc{s}x", parent, f"c{s}x", "1 0 0", kx, d))
        parts.append(_slide(f"lc{s}y", f"c{s}x", f"col{s}", "0 1 0", ky, d))
        parts.append(_slide(f"uc{s}x", f"col{s}", f"f{s}x", "1 0 0", kx, d))
        parts.append(_slide(f"uc{s}y", f"f{s}x", f"floor{s}", "0 1 0", ky, d))
        parent = f"floor{s}"
    parts += [_points(), "</robot>"]
    return "".join(parts)


def model_urdf() -> str:
    """The model a user writes: one shear spring per storey and direction, the columns'
    mass in the floor, handbook values 15 % off (stiffer, lighter)."""
    parts = [
        '<robot name="frame"><link name="ground"/>',
    ]
    parent = "ground"
    for k in range(3):
        s = k + 1
        parts += [_link(f"s{s}", 0), _link(f"floor{s}", 0.85 * (FLOOR_KG[k] + COLUMN_KG))]
        parts.append(_slide(f"s{s}x", parent, f"s{s}", "1 0 0", 1.15 * K_X[k], DAMPING / 2))
        parts.append(_slide(f"s{s}y", f"s{s}", f"floor{s}", "0 1 0", 1.15 * K_Y[k], DAMPING / 2))
        parent = f"floor{s}"
    parts += [_points(), "</robot>"]
    head = (
        '<?xml version="1.0"?>\n<!-- A three-storey frame: per storey a shear spring along x'
        " then y\n     (prismatic joints), the floor and its columns one rigid mass; handbook"
        " values.\n     Points: accelerometers a1x ... a3y, hammer points h3x, h3y, h1x. -->\n"
    )
    return head + "".join(parts).replace("><", ">\n<") + "\n"


def write_vendor_uff(path: Path, f: np.ndarray, H: np.ndarray, coh: np.ndarray,
                     outs: list[str], ins: list[str]) -> None:  # fmt: skip
    """ASCII UFF58 as a vendor exports it: the vendor's nodes, no bondid ID lines."""
    import pyuff

    sets = []
    for a, o in enumerate(outs):
        for b, i in enumerate(ins):
            (rn, rd), (fn, fd) = NODES[o], REFERENCES[i]
            common = {
                "type": 58, "binary": 0, "id1": f"FRF {rn}:+{rd} / {fn}:+{fd}",
                "id2": "Modal test 2026-03-14", "id3": "NONE", "id4": "NONE", "id5": "NONE",
                "rsp_node": rn, "rsp_dir": rd, "ref_node": fn, "ref_dir": fd,
                "abscissa_spacing": 1, "abscissa_spec_data_type": 18,
                "abscissa_axis_units_lab": "Hz", "x": f,
            }  # fmt: skip
            sets.append({**common, "func_type": 4, "ordinate_spec_data_type": 12,
                         "orddenom_spec_data_type": 13, "data": H[a, b]})  # fmt: skip
            coherence = coh[a, b].astype(float)
            sets.append({**common, "func_type": 6, "ordinate_spec_data_type": 1,
                         "orddenom_spec_data_type": 0, "data": coherence})  # fmt: skip
    tmp = path.with_name(path.name + ".tmp")
    tmp.unlink(missing_ok=True)
    pyuff.UFF(str(tmp)).write_sets(sets, mode="add")
    tmp.replace(path)


def main(argv: list[str] | None = None) -> int:
    from bondid.data.noise import add_measurement_noise
    from bondid.linear.affine import build_affine_model
    from bondid.model import UrdfDocument
    from bondid.modes.analysis import modal_analysis

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out", type=Path, help="folder for the data file")
    p.add_argument("--lines", type=int, default=481, help="analyser lines, 0 Hz included")
    p.add_argument("--f-max", type=float, default=60.0, help="last line [Hz]")
    p.add_argument("--seed", type=int, default=0, help="noise seed")
    p.add_argument("--model", type=Path, help="also write the fitted model URDF here")
    a = p.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    truth = UrdfDocument.from_string(truth_urdf(), source="<frame truth>")
    outs, ins = list(NODES), list(REFERENCES)
    lm = build_affine_model(truth, outputs=tuple(outs)).linear_model()
    f = np.linspace(0.0, a.f_max, a.lines)
    cols = [lm.inputs.index(i) for i in ins]
    A = np.zeros((len(outs), len(ins), f.size), complex)
    A[:, :, 1:] = lm.frf(f[1:], "accelerance")[:, cols]
    Hn, coh = add_measurement_noise(A[:, :, 1:], f[1:], rel=REL_NOISE, floor_db=FLOOR_DB,
                                    rng=a.seed, floor_ref="response",
                                    quantity="accelerance")  # fmt: skip
    H = np.concatenate([A[:, :, :1], Hn], axis=2)  # the 0 Hz line: exact 0 (grounded)
    C = np.concatenate([np.zeros((len(outs), len(ins), 1)), coh], axis=2)
    write_vendor_uff(a.out / "frame.uff", f, H, C, outs, ins)
    truth.write(a.out / "truth.urdf")
    modes = [m.f_hz for m in modal_analysis(lm).vibration_modes() if m.f_hz <= a.f_max]
    (a.out / "truth_modes.json").write_text(
        json.dumps({"modes_hz": modes, "nodes": NODES, "references": REFERENCES}, indent=2) + "\n"
    )
    if a.model is not None:
        a.model.write_text(model_urdf())
        # the same finer model as the data's, from handbook values 15 % off
        columns = truth_urdf(mass=0.85, stiff=1.15, damp=0.5).replace("><", ">\n<")
        a.model.with_name("frame_columns.urdf").write_text(columns + "\n")
    print(f"{a.out / 'frame.uff'}: {len(outs)} × {len(ins)} records, {f.size} lines; modes"
          f" {', '.join(f'{v:.2f}' for v in modes)} Hz")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
