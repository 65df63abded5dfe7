"""Mesh paths as URDFs write them: package://, relative, file:// — in hulls and the viewer."""

from __future__ import annotations

from pathlib import Path

import pytest
from models import robot_path

from bondid.exceptions import ModelError
from bondid.model import UrdfDocument
from bondid.model.packages import text_with_resolved_meshes
from bondid.optim.bounds import link_hulls

#: the hull of a 0.2 m cube mesh: its diagonal, to STL float32 precision
SIZE_TOL = 1e-7


def _urdf(folder: Path, filename: str) -> Path:
    import trimesh

    mesh_dir = folder / "ws" / "mypkg" / "meshes"
    mesh_dir.mkdir(parents=True)
    trimesh.creation.box(extents=(0.2, 0.2, 0.2)).export(mesh_dir / "cube.stl")
    (folder / "ws" / "mypkg" / "urdf").mkdir()
    xml = (
        '<robot name="r"><link name="base"/><link name="arm"><inertial><mass value="1"/>'
        '<inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial>'
        f'<collision><geometry><mesh filename="{filename}"/></geometry></collision></link>'
        '<joint name="x" type="prismatic"><parent link="base"/><child link="arm"/>'
        '<axis xyz="1 0 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>'
    )
    path = folder / "elsewhere" / "r.urdf"
    path.parent.mkdir()
    path.write_text(xml)
    return path


def test_package_uri_needs_a_package_path_then_resolves(tmp_path):
    doc = UrdfDocument.load(_urdf(tmp_path, "package://mypkg/meshes/cube.stl"))
    with pytest.raises(ModelError, match="--package-path"):
        link_hulls(doc, ["arm"])
    doc.package_path = [str(tmp_path / "ws")]
    hull = link_hulls(doc, ["arm"])["arm"]
    assert hull is not None
    assert abs(hull.size - 0.2 * 3**0.5) < SIZE_TOL
    doc.package_path = [str(tmp_path / "ws" / "mypkg")]  # the package folder itself
    assert link_hulls(doc, ["arm"])["arm"] is not None


def test_relative_mesh_path_is_relative_to_the_urdf(tmp_path):
    doc = UrdfDocument.load(_urdf(tmp_path, "../ws/mypkg/meshes/cube.stl"))
    assert link_hulls(doc, ["arm"])["arm"] is not None
    text = text_with_resolved_meshes(doc)
    assert str((tmp_path / "ws" / "mypkg" / "meshes" / "cube.stl").resolve()) in text


def test_ros_package_path_is_searched(tmp_path, monkeypatch):
    doc = UrdfDocument.load(_urdf(tmp_path, "package://mypkg/meshes/cube.stl"))
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "ws"))
    assert link_hulls(doc, ["arm"])["arm"] is not None


def test_example_robot_data_meshes_resolve_without_options():
    doc = UrdfDocument.load(robot_path("ur5"))
    hulls = link_hulls(doc, ["forearm_link"])
    assert hulls["forearm_link"] is not None
    assert "package://" not in text_with_resolved_meshes(doc)


def test_the_diagnosis_model_text_finds_its_meshes_in_any_folder(tmp_path, monkeypatch):
    """The diagnosis hands model texts to worker processes (no file, no folder): with the mesh
    filenames made absolute (``with_absolute_meshes``) a text read in another folder finds the
    hull boxes its candidates need, and a written model gets the user's names back."""
    import numpy as np

    from bondid.diagnose.effects import get_effect
    from bondid.diagnose.effects.topology import link_box
    from bondid.model.packages import restore_mesh_names, with_absolute_meshes

    doc = UrdfDocument.load(_urdf(tmp_path, "../ws/mypkg/meshes/cube.stl"))
    doc.add_transmission("x")  # an FRF input, as every diagnosed model has
    monkeypatch.chdir(tmp_path)  # not the URDF's folder
    with pytest.raises(ModelError, match=r"cube\.stl"):  # the text alone: relative to nothing
        link_box(UrdfDocument.from_string(doc.to_string()), "arm")
    work, names = with_absolute_meshes(doc)
    assert list(names.values()) == ["../ws/mypkg/meshes/cube.stl"]
    assert work.source == doc.source and "cube.stl" in next(iter(names))
    text = UrdfDocument.from_string(work.to_string())
    box = link_box(text, "arm")
    assert box is not None and np.allclose(box[1] - box[0], 0.2, atol=SIZE_TOL)
    rot = [c for c in get_effect("joint_compliance").candidates(text)
           if c.spec["kind"] == "revolute"]  # fmt: skip
    # the pivot's starting places reach the faces of the hull read from the mesh
    from bondid.model.pivot import pivot_of

    effect = get_effect("joint_compliance")
    pivots = np.array([pivot_of(effect.augment(text, v), c.spec["joint"])
                       for c in rot for v in c.variants])  # fmt: skip
    assert rot and np.isclose(pivots, box[0]).any() and np.isclose(pivots, box[1]).any()
    assert restore_mesh_names(work.to_string(), names) == doc.to_string()
    bonder = UrdfDocument.load(Path(__file__).parents[1] / "urdf" / "bonder.urdf")
    assert with_absolute_meshes(bonder) == (bonder, {})  # no mesh: nothing changes
