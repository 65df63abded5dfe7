"""Every element and attribute of a user's URDF survives read → write (example-robot-data)."""

from __future__ import annotations

import glob
import math
import os
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from models import robot_path

from bondid.exceptions import ModelError, OperatingPointError
from bondid.linear.affine import build_affine_model
from bondid.model import UrdfDocument


def _erd_urdfs() -> list[str]:
    root = os.path.dirname(os.path.dirname(os.path.dirname(robot_path("ur5"))))
    return sorted(glob.glob(os.path.join(root, "**", "*.urdf"), recursive=True))


def _same_value(a: str, b: str) -> bool:
    """Attribute values equal as text, or as numbers (yourdfpy rewrites 1 as 1.0)."""
    if a.strip() == b.strip():
        return True
    try:
        x, y = [float(v) for v in a.split()], [float(v) for v in b.split()]
    except ValueError:
        return False
    return len(x) == len(y) and all(
        math.isclose(p, q, rel_tol=1e-12, abs_tol=1e-15) for p, q in zip(x, y, strict=True)
    )


def _rotation(rpy: str) -> np.ndarray:
    import pinocchio as pin

    return pin.rpy.rpyToMatrix(*[float(v) for v in rpy.split()])


def _same_attr(tag: str, name: str, a: str, b: str | None) -> bool:
    if b is None:
        return False
    if tag == "origin" and name == "rpy":  # an equal rotation may be written other angles
        return bool(np.allclose(_rotation(a), _rotation(b), rtol=0, atol=1e-12))
    return _same_value(a, b)


def _missing(orig: ET.Element, out: ET.Element, path: str) -> list[str]:
    """Elements/attributes of ``orig`` that ``out`` lacks or changed (by tag/name, position)."""
    bad = [
        f"{path}@{k}"
        for k, v in orig.attrib.items()
        if not _same_attr(str(orig.tag), k, v, out.get(k))
    ]

    def keyed(el: ET.Element) -> dict[tuple[str, str], ET.Element]:
        res, count = {}, {}
        for c in el:
            if not isinstance(c.tag, str):
                continue
            name = c.get("name") if c.tag in ("link", "joint", "material") else None
            if name is None:
                name = str(count.get(c.tag, 0))
                count[c.tag] = count.get(c.tag, 0) + 1
            res[(c.tag, name)] = c
        return res

    have = keyed(out)
    for key, child in keyed(orig).items():
        if key not in have:
            bad.append(f"{path}/{key[0]}[{key[1]}]")
        else:
            bad += _missing(child, have[key], f"{path}/{key[0]}[{key[1]}]")
    return bad


def test_every_example_robot_data_model_round_trips():
    paths = _erd_urdfs()
    assert len(paths) > 20
    checked = 0
    for path in paths:
        try:
            doc = UrdfDocument.load(path)
        except ModelError:
            continue  # not readable by yourdfpy offline (3 of 77 here): nothing to keep
        orig = ET.parse(path).getroot()
        back = ET.fromstring(UrdfDocument.from_string(doc.to_string()).to_string())
        assert _missing(orig, back, "robot") == [], path
        checked += 1
    assert checked >= len(paths) - 5


def test_mimic_joint_kept_on_write():
    xml = (
        '<robot name="r"><link name="a"/><link name="b"/><link name="c"/>'
        '<joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/><calibration rising="0.1"/>'
        '<safety_controller soft_lower_limit="-0.9" soft_upper_limit="0.9" k_velocity="1"/>'
        "</joint>"
        '<joint name="j2" type="revolute"><parent link="b"/><child link="c"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/><mimic joint="j1" multiplier="2"/>'
        "</joint></robot>"
    )
    text = UrdfDocument.from_string(xml, source="m.urdf").copy().to_string()
    for tag in ("<mimic", "<calibration", "<safety_controller"):
        assert tag in text


#: the reduced model against Pinocchio's own mimic model (round-off, and central differences
#: of its gravity torques with step 1e-6)
MIMIC_TOL, GRAVITY_FD_TOL = 1e-12, 1e-6


def test_mimic_joint_is_a_coupled_dof_like_pinocchios_mimic_model():
    import pinocchio as pin

    doc = UrdfDocument.load(robot_path("panda"))  # panda_finger_joint2 mimics joint1
    doc.add_transmission("panda_joint2")
    doc.add_transmission("panda_finger_joint1")
    op = {"panda_joint2": -0.4, "panda_joint4": -1.9, "panda_finger_joint1": 0.02}
    am = build_affine_model(doc, op, outputs=("panda_finger_joint1", "panda_finger_joint2"))
    assert "panda_finger_joint2" not in am.dofs
    ref = pin.buildModelFromUrdf(robot_path("panda"), mimic=True)
    data = ref.createData()
    q = pin.neutral(ref)
    for name, v in op.items():
        q[ref.joints[ref.getJointId(name)].idx_q] = v
    assert ref.nv == am.nv
    M_ref = pin.crba(ref, data, q)
    M_ref = np.triu(M_ref) + np.triu(M_ref, 1).T
    assert np.max(np.abs(am.mass_matrix() - M_ref)) < MIMIC_TOL * np.max(np.abs(M_ref))

    def g(qq: np.ndarray) -> np.ndarray:
        return pin.rnea(ref, data, qq, np.zeros(ref.nv), np.zeros(ref.nv)).copy()

    G = np.empty((ref.nv, ref.nv))
    for k in range(ref.nv):
        e = np.zeros(ref.nv)
        e[k] = 1e-6
        G[:, k] = (g(pin.integrate(ref, q, e)) - g(pin.integrate(ref, q, -e))) / 2e-6
    assert np.max(np.abs(am.stiffness_matrix() - G)) < GRAVITY_FD_TOL * np.max(np.abs(G))
    # the mimic joint's encoder reads the master's motion times the multiplier (1 here)
    assert np.array_equal(am.C[0], am.C[1])
    with pytest.raises(OperatingPointError, match="mimic"):
        build_affine_model(doc, {"panda_finger_joint2": 0.01})
