"""Mesh paths as URDFs write them: package://, relative, file:// — in hulls and the viewer."""

from __future__ import annotations

from pathlib import Path

import pytest
from models import robot_path

from bondid.exceptions import ModelError
from bondid.fit.bounds import link_hulls
from bondid.model import UrdfDocument
from bondid.model.packages import text_with_resolved_meshes

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
