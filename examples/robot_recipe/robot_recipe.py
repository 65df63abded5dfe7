"""A robot from example-robot-data with joint springs and dampers: its modes and FRF at a pose.

    python examples/robot_recipe/robot_recipe.py ur5 --out /tmp/ur5
    python examples/robot_recipe/robot_recipe.py panda --stiffness 5e4 --damping 8 \
        --q panda_joint2=-0.6,panda_joint4=-2.2

A stock robot description has no joint springs: linearised, every joint is a rigid-body DOF
(a UR5 has 6 modes at 0 Hz, and gravity makes the model "unstable" at most poses). A servoed
joint behaves like a spring and damper, so the recipe gives every movable joint one (the
servo's stiffness K [N·m/rad] and damping D [N·m·s/rad]; fit them to measurements with
``bondid fit`` later), then lists the modes at the pose and writes the receptance FRF there:

    OUT/<robot>.urdf     the robot with springs, dampers and an actuator on every joint
    OUT/frf.csv          receptance at the pose (bondid CSV: ``bondid fit --data`` reads it)
    OUT/bode.png         its Bode plot
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bondid.data import FrfData, write_csv
from bondid.linear import build_affine_model
from bondid.model import UrdfDocument
from bondid.modes import ModalResult, modal_analysis
from bondid.validation.operating_point import check_operating_point


def robot_urdf(name: str) -> Path:
    """The URDF file of example-robot-data's robot ``name`` (e.g. ``ur5``, ``panda``)."""
    import example_robot_data.robots_loader as loaders

    if name not in loaders.ROBOTS:
        raise SystemExit(f"unknown robot {name!r}; e.g. {', '.join(sorted(loaders.ROBOTS)[:12])}")
    return Path(loaders.ROBOTS[name]().df_path)


def with_springs(doc: UrdfDocument, stiffness: float, damping: float) -> UrdfDocument:
    """``doc`` with a spring ``stiffness`` and a damper ``damping`` on every movable joint
    and an actuator (transmission) on each joint that has none; mimic joints become
    independent DOFs."""
    for j in doc.mimic_joints():
        doc.drop_mimic(j)
    driven = {t.joint for t in doc.transmissions}
    for j in doc.movable_joint_names:
        doc.set_stiffness(j, stiffness)
        doc.set_damping(j, damping)
        if j not in driven:
            doc.add_transmission(j)
    return doc


@dataclass
class Recipe:
    """What the recipe computed: the robot, its pose, its modes there and the FRF."""

    doc: UrdfDocument
    pose: dict[str, float]
    stock_modes: ModalResult
    stock_warnings: list[str]
    modes: ModalResult
    warnings: list[str]
    frf: FrfData


def run(
    name: str, *, stiffness: float = 2e4, damping: float = 5.0,
    pose: dict[str, float] | None = None, freq_hz: np.ndarray | None = None,
) -> Recipe:  # fmt: skip
    """Load robot ``name``, give its joints springs and dampers, and analyse it at ``pose``
    (joint → rad or m; default: the robot's reference posture where it has one, else 0)."""
    path = robot_urdf(name)
    doc = UrdfDocument.load(path)
    q = dict(pose) if pose is not None else {}
    stock = modal_analysis(build_affine_model(doc, q).linear_model(), q)
    stock_warnings = check_operating_point(doc, q, f"{name} as shipped")
    doc = with_springs(doc, stiffness, damping)
    lm = build_affine_model(doc, q).linear_model()
    f = np.geomspace(1.0, 1000.0, 400) if freq_hz is None else np.asarray(freq_hz, float)
    H = lm.frf(f)
    outs = tuple(t.joint for t in doc.transmissions)
    frf = FrfData(f, outs, outs, H, "receptance", operating_point=q, source=f"{name} model")
    modes = modal_analysis(lm, q)
    return Recipe(doc, q, stock, stock_warnings, modes, check_operating_point(doc, q, name), frf)


def _pose(text: str) -> dict[str, float]:
    from bondid.linear.operating_point import parse_operating_point

    return parse_operating_point(text, "--q")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("robot", help="an example-robot-data name, e.g. ur5, panda")
    p.add_argument("--stiffness", type=float, default=2e4, help="joint spring, N·m/rad")
    p.add_argument("--damping", type=float, default=5.0, help="joint damper, N·m·s/rad")
    p.add_argument("--q", type=_pose, default=None, help="pose, e.g. shoulder_lift_joint=-1.2")
    p.add_argument("--out", type=Path, default=None, help="folder for the URDF, CSV and plot")
    p.add_argument("--points", type=int, default=400, help="frequencies, 1 Hz to 1 kHz")
    p.add_argument("--no-plot", action="store_true", help="skip bode.png")
    args = p.parse_args(argv)
    f = np.geomspace(1.0, 1000.0, args.points)
    r = run(args.robot, stiffness=args.stiffness, damping=args.damping, pose=args.q, freq_hz=f)
    rigid = sum(1 for m in r.stock_modes.modes if m.kind == "rigid")
    print(f"{args.robot} as shipped: {rigid} modes at 0 Hz (no joint springs)")
    for w in r.stock_warnings:
        print(f"  ({w.split(' is ', 1)[-1]})")
    print(f"with K = {args.stiffness:g} N·m/rad, D = {args.damping:g} N·m·s/rad on every joint,"
          f" at {r.pose or 'q = 0'}:")  # fmt: skip
    print(r.modes.table())
    for w in r.warnings:
        print(f"warning: {w}")
    if args.out is not None:
        from bondid.plots import Curve, plot_bode

        args.out.mkdir(parents=True, exist_ok=True)
        r.doc.write(args.out / f"{args.robot}.urdf")
        write_csv(r.frf, args.out / "frf.csv")
        if args.no_plot:
            print(f"wrote {args.out}/{args.robot}.urdf, frf.csv")
            return 0
        plot_bode(r.frf.freq_hz, [Curve("model", r.frf.H)], outputs=r.frf.outputs,
                  inputs=r.frf.inputs, path=args.out / "bode.png",
                  title=f"{args.robot}: receptance at {r.pose or 'q = 0'}",
                  units=dict.fromkeys(r.frf.outputs, "rad"))  # fmt: skip
        print(f"wrote {args.out}/{args.robot}.urdf, frf.csv, bode.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
