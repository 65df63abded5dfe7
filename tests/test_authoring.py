"""Authoring: parameters by name, parasitic-joint insertion, lossless write → read."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from models import robot_path, sprung_robot, two_mass_chain

from bondid.exceptions import ModelError, ParameterError
from bondid.model import (
    UrdfDocument,
    get_parameter,
    insert_parasitic_joint,
    parameter_names,
    select_parameters,
    set_parameter,
)


def _same_pinocchio_model(a, b, tol=1e-12):
    assert a.nq == b.nq and a.nv == b.nv and list(a.names) == list(b.names)
    for j in range(a.njoints):
        assert a.joints[j].shortname() == b.joints[j].shortname()
        assert np.allclose(
            a.jointPlacements[j].homogeneous, b.jointPlacements[j].homogeneous, atol=tol
        )
        assert np.allclose(
            a.inertias[j].toDynamicParameters(), b.inertias[j].toDynamicParameters(), atol=tol
        )


def test_round_trip_write_read_gives_the_same_model(tmp_path):
    doc = sprung_robot("panda")
    out = doc.write(tmp_path / "panda_sprung.urdf")
    back = UrdfDocument.load(out)
    _same_pinocchio_model(doc.build_pinocchio_model(), back.build_pinocchio_model())
    assert back.springs == doc.springs
    assert back.transmissions == doc.transmissions
    for n in parameter_names(doc):
        assert get_parameter(back, n) == get_parameter(doc, n)


def test_unknown_elements_survive_a_round_trip(tmp_path):
    src = robot_path("ur5")
    doc = UrdfDocument.load(src)
    text = doc.to_string()
    assert text.count("<transmission") == Path(src).read_text().count("<transmission")


def test_writing_over_the_source_is_refused(tmp_path):
    p = tmp_path / "m.urdf"
    two_mass_chain(1, 1, 1, 1, 1, 1).write(p)
    doc = UrdfDocument.load(p)
    with pytest.raises(Exception, match="refusing to overwrite"):
        doc.write(p)


def test_set_and_get_parameters_by_name():
    doc = two_mass_chain(1.0, 2.0, 10.0, 0.5, 20.0, 0.25)
    assert get_parameter(doc, "body_b.mass") == 2.0
    assert get_parameter(doc, "b.stiffness") == 20.0
    set_parameter(doc, "body_a.com.y", 0.01)
    set_parameter(doc, "body_a.inertia.ixy", 2e-6)
    set_parameter(doc, "a.damping", 0.75)
    assert get_parameter(doc, "body_a.com.y") == 0.01
    assert get_parameter(doc, "body_a.inertia.ixy") == 2e-6
    assert get_parameter(doc, "a.damping") == 0.75
    with pytest.raises(ParameterError, match="unknown parameter"):
        get_parameter(doc, "body_a.colour")
    with pytest.raises(ParameterError, match="negative"):
        set_parameter(doc, "a.stiffness", -1.0)


def test_selection_by_glob_group_and_fixed():
    doc = two_mass_chain(1.0, 2.0, 10.0, 0.5, 20.0, 0.25)
    assert select_parameters(doc, ["*.stiffness"]) == ["a.stiffness", "b.stiffness"]
    assert select_parameters(doc, ["body_a.*"], ["body_a.inertia.*"]) == [
        "body_a.mass",
        "body_a.com.x",
        "body_a.com.y",
        "body_a.com.z",
    ]
    assert len(select_parameters(doc, ["inertial"])) == 20
    assert select_parameters(doc, ["parasitic"]) == []  # both joints are driven
    with pytest.raises(ParameterError, match="matches no parameter"):
        select_parameters(doc, ["nope.*"])


def test_rotated_inertial_origin_is_read_in_the_link_frame():
    xml = Path(robot_path("ur5")).read_text()
    doc = UrdfDocument.from_string(xml)
    lk = doc.link("upper_arm_link")
    R = pin.rpy.rpyToMatrix(0.3, -0.2, 0.1)
    Ic = np.diag([0.01, 0.02, 0.025])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = [0.0, 0.01, 0.2]
    lk.inertial.origin, lk.inertial.inertia = T, Ic
    I_link = R @ Ic @ R.T
    assert np.isclose(get_parameter(doc, "upper_arm_link.inertia.ixy"), I_link[0, 1], rtol=1e-14)
    set_parameter(doc, "upper_arm_link.mass", 8.0)  # rewrites with rpy = 0, same physics
    Ij = doc.build_pinocchio_model().inertias[2]
    assert np.allclose(Ij.inertia, I_link, atol=1e-12)


@pytest.mark.parametrize("pivot", [(0.0, 0.0, 0.0), (0.05, -0.02, 0.1)])
def test_inserted_parasitic_joint_keeps_the_child_in_place(pivot):
    doc = UrdfDocument.load(robot_path("ur5"))
    before = doc.build_pinocchio_model()
    insert_parasitic_joint(
        doc,
        "elbow_rx",
        after="elbow_joint",
        kind="revolute",
        axis=(1, 0, 0),
        pivot=pivot,
        stiffness=5e4,
        damping=3.0,
    )
    after = doc.build_pinocchio_model()
    assert after.nv == before.nv + 1
    assert doc.stiffness("elbow_rx") == 5e4 and doc.damping("elbow_rx") == 3.0
    for m in (before, after):
        m.data = m.createData()
        pin.framesForwardKinematics(m, m.data, pin.neutral(m))
    for frame in ("forearm_link", "wrist_3_link", "tool0"):
        a = before.data.oMf[before.getFrameId(frame)].homogeneous
        b = after.data.oMf[after.getFrameId(frame)].homogeneous
        assert np.allclose(a, b, atol=1e-14)
    assert "elbow_rx.stiffness" in parameter_names(doc)
    assert "elbow_rx.stiffness" in select_parameters(doc, ["parasitic"])


def test_insert_rejects_bad_requests():
    doc = UrdfDocument.load(robot_path("ur5"))
    with pytest.raises(ModelError, match="no joint connects"):
        insert_parasitic_joint(doc, "q", parent="base_link", child="forearm_link")
    with pytest.raises(ModelError, match="names already used"):
        insert_parasitic_joint(doc, "elbow_joint", after="shoulder_lift_joint")
    with pytest.raises(ModelError, match="kind"):
        insert_parasitic_joint(doc, "q", after="elbow_joint", kind="spherical")


def test_bad_files_name_the_file(tmp_path):
    p = tmp_path / "bad.urdf"
    p.write_text("<robot name='r'><link name='a'/><joint name='j' type='fixed'>")
    with pytest.raises(ModelError, match=r"bad\.urdf"):
        UrdfDocument.load(p)
    with pytest.raises(ModelError, match=r"missing\.urdf"):
        UrdfDocument.load(tmp_path / "missing.urdf")


def test_frames_written_with_mass_zero_are_massless():
    """ROS URDFs write their frames as ``<inertial>`` of mass 0 and zero inertia (UR5's
    ``ee_link``): massless, as a link without ``<inertial>``; a mass 0 with a non-zero inertia
    is still refused."""
    from bondid.linear.affine import build_affine_model
    from bondid.validation.model import check_model

    doc = sprung_robot("ur5")
    assert float(doc.link("ee_link").inertial.mass) == 0.0
    check_model(doc)  # refused "ee_link has mass 0" before
    names = parameter_names(doc)
    assert not [n for n in names if n.startswith("ee_link.")]
    assert "wrist_3_link.mass" in names
    am = build_affine_model(doc)
    assert "ee_link" not in am.bodies
    # the same M as Pinocchio's, which holds the frame's zero inertia
    model = doc.build_pinocchio_model()
    ref = pin.crba(model, model.createData(), pin.neutral(model))
    np.testing.assert_allclose(am.mass_matrix(), np.triu(ref) + np.triu(ref, 1).T, atol=1e-12)
    doc.link("ee_link").inertial.inertia = np.diag([1e-4, 1e-4, 1e-4])
    with pytest.raises(ModelError, match=r"ee_link.*mass 0"):
        check_model(doc)
