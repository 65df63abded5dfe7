"""Every element and attribute of a user's URDF survives read → write (example-robot-data)."""

from __future__ import annotations

import glob
import math
import os
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from models import robot_path

from bondid.exceptions import ModelError
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


def test_mimic_joint_kept_on_write_and_refused_by_the_linearisation():
    xml = (
        '<robot name="r"><link name="a"/><link name="b"><inertial><mass value="1"/>'
        '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>'
        '<link name="c"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1"'
        ' iyz="0" izz="1"/></inertial></link>'
        '<joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/><calibration rising="0.1"/>'
        '<safety_controller soft_lower_limit="-0.9" soft_upper_limit="0.9" k_velocity="1"/>'
        "</joint>"
        '<joint name="j2" type="revolute"><parent link="b"/><child link="c"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/><mimic joint="j1" multiplier="2"/>'
        '</joint><transmission name="t"><joint name="j1"/></transmission></robot>'
    )
    doc = UrdfDocument.from_string(xml, source="m.urdf")
    text = doc.copy().to_string()
    for tag in ("<mimic", "<calibration", "<safety_controller"):
        assert tag in text
    with pytest.raises(ModelError, match=r"m\.urdf: joint 'j2' mimics joint 'j1'"):
        build_affine_model(doc)
