"""Checks of the reference wire-bonder model urdf/bonder.urdf.

The file is read three ways: Pinocchio (dynamics), yourdfpy (links, joints, geometry) and
the raw XML (the `<gazebo>` springs and `<transmission>` elements, which yourdfpy 0.0.60
does not parse). The linearised model at q = 0 is checked against the issue's physics.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy
from scipy.spatial import ConvexHull

URDF = Path(__file__).resolve().parents[1] / "urdf" / "bonder.urdf"

PRIMARY = {  # name: (type, axis, parent link, first parasitic joint downstream)
    "x": ("prismatic", (1, 0, 0), "base", "x_guide_ty"),
    "y": ("prismatic", (0, 1, 0), "x_stage", "y_guide_tx"),
    "z": ("revolute", (1, 0, 0), "y_stage", "z_bearing_ry"),
}
PARASITIC = {  # name: (type, axis)
    "x_guide_ty": ("prismatic", (0, 1, 0)),
    "x_guide_ry": ("revolute", (0, 1, 0)),
    "x_guide_rz": ("revolute", (0, 0, 1)),
    "y_guide_tx": ("prismatic", (1, 0, 0)),
    "y_guide_rx": ("revolute", (1, 0, 0)),
    "y_guide_rz": ("revolute", (0, 0, 1)),
    "z_bearing_ry": ("revolute", (0, 1, 0)),
    "z_bearing_rz": ("revolute", (0, 0, 1)),
}
STAGES = ("x_stage", "y_stage", "z_stage")


@pytest.fixture(scope="module")
def robot() -> yourdfpy.URDF:
    return yourdfpy.URDF.load(str(URDF), build_scene_graph=False, load_meshes=False)


@pytest.fixture(scope="module")
def xml_root() -> ET.Element:
    return ET.parse(URDF).getroot()


@pytest.fixture(scope="module")
def springs(xml_root: ET.Element) -> dict[str, tuple[float, float]]:
    out = {}
    for g in xml_root.findall("gazebo"):
        k = g.find("springStiffness")
        r = g.find("springReference")
        assert k is not None and r is not None, f"gazebo {g.get('reference')} incomplete"
        out[str(g.get("reference"))] = (float(k.text or "nan"), float(r.text or "nan"))
    return out


@pytest.fixture(scope="module")
def linear(springs: dict[str, tuple[float, float]]) -> dict[str, np.ndarray]:
    """M, K (springs + gravity stiffness), D, B at q = 0, shapes (nv, nv) / (nv, 3)."""
    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    q0 = pin.neutral(model)
    mass = pin.crba(model, data, q0)
    mass = np.triu(mass) + np.triu(mass, 1).T
    stiff = np.array(pin.computeGeneralizedGravityDerivatives(model, data, q0))
    damp = np.zeros((model.nv, model.nv))
    for j in range(1, model.njoints):
        iv = model.joints[j].idx_v
        stiff[iv, iv] += springs.get(model.names[j], (0.0, 0.0))[0]
        damp[iv, iv] = model.damping[iv]
    idx = [model.joints[model.getJointId(n)].idx_v for n in ("x", "y", "z")]
    sel = np.zeros((model.nv, 3))
    sel[idx, range(3)] = 1.0
    return {"M": mass, "K": stiff, "D": damp, "B": sel, "idx": np.array(idx)}


def _frf(lin: dict[str, np.ndarray], f_hz: np.ndarray) -> np.ndarray:
    """Receptance (3, 3, n_freq) of the linear model at `f_hz` [Hz]."""
    w = 2 * np.pi * f_hz[:, None, None]
    z = lin["K"][None] - w**2 * lin["M"][None] + 1j * w * lin["D"][None]
    h = np.linalg.solve(z, np.broadcast_to(lin["B"], (len(f_hz), *lin["B"].shape)))
    return np.moveaxis(lin["B"].T[None] @ h, 0, -1)


def test_loads_with_both_parsers(robot: yourdfpy.URDF) -> None:
    model = pin.buildModelFromUrdf(str(URDF))
    assert model.nq == model.nv == 11
    assert list(model.names)[1:] == [
        "x",
        *list(PARASITIC)[:3],
        "y",
        *list(PARASITIC)[3:6],
        "z",
        *list(PARASITIC)[6:],
    ]
    assert robot.robot.links[0].name == "base"
    assert {"base", *STAGES} <= {link.name for link in robot.robot.links}
    assert np.allclose(model.gravity.linear, [0.0, 0.0, -9.81])


def test_primary_joints(robot: yourdfpy.URDF) -> None:
    joints = {j.name: j for j in robot.robot.joints}
    for name, (jtype, axis, parent, first) in PRIMARY.items():
        joint = joints[name]
        assert joint.type == jtype
        assert np.allclose(joint.axis, axis)
        assert joint.parent == parent
        assert joint.child == f"{first}_link"
        assert joint.limit is not None and joint.limit.lower < 0 < joint.limit.upper


def test_parasitic_chain_pattern(robot: yourdfpy.URDF) -> None:
    joints = {j.name: j for j in robot.robot.joints}
    links = {link.name: link for link in robot.robot.links}
    children = {j.parent: j for j in robot.robot.joints}
    for name, (jtype, axis) in PARASITIC.items():
        joint = joints[name]
        assert joint.type == jtype and np.allclose(joint.axis, axis), name
        assert np.isclose(np.linalg.norm(joint.axis), 1.0)
        assert joint.parent == f"{name}_link"
        assert joint.limit is not None and joint.limit.upper <= 0.01
        assert np.allclose(joint.origin[:3, :3], np.eye(3))
        pivot = joint.origin[:3, 3]
        if np.any(pivot != 0.0):
            assert joint.child == f"{name}_moving"
            offset = joints[f"{name}_offset"]
            assert offset.type == "fixed" and offset.parent == f"{name}_moving"
            assert np.allclose(offset.origin[:3, 3], -pivot)
            assert np.allclose(offset.origin[:3, :3], np.eye(3))
            next_link = offset.child
        else:
            next_link = joint.child
        assert next_link in STAGES or next_link.endswith("_link")
        for massless in (f"{name}_link", f"{name}_moving"):
            if massless in links:
                assert links[massless].inertial is None, massless
    # every stage is reached from its primary joint through parasitic joints only
    for stage, primary in zip(STAGES, PRIMARY, strict=True):
        link, hops = joints[primary].child, 0
        while link != stage:
            link = children[link].child
            hops += 1
            assert hops < 20
        assert links[stage].inertial is not None


def test_springs_dampers_and_values(
    robot: yourdfpy.URDF, springs: dict[str, tuple[float, float]]
) -> None:
    joints = {j.name: j for j in robot.robot.joints}
    assert set(springs) == set(PARASITIC) | {"z"}
    for name, (k, ref) in springs.items():
        assert k > 0 and ref == 0.0, name
        assert float(joints[name].dynamics.damping) > 0, name
    assert springs["x_guide_ty"][0] == pytest.approx(5e7, rel=0.3)
    assert float(joints["x_guide_ty"].dynamics.damping) == pytest.approx(400, rel=0.3)
    assert springs["z"][0] == pytest.approx(1.44, rel=0.05)
    assert float(joints["z"].dynamics.damping) == pytest.approx(0.0031, rel=0.05)
    for name in ("x", "y"):
        assert name not in springs
        assert 0 <= float(joints[name].dynamics.damping) < 10


def test_transmissions(xml_root: ET.Element) -> None:
    trans = xml_root.findall("transmission")
    assert [t.get("name") for t in trans] == ["x_trans", "y_trans", "z_trans"]
    for t, joint in zip(trans, "xyz", strict=True):
        assert t.findtext("type") == "transmission_interface/SimpleTransmission"
        assert [j.get("name") for j in t.findall("joint")] == [joint]
        iface = t.findtext("joint/hardwareInterface")
        assert iface == "hardware_interface/EffortJointInterface"
        actuator = t.find("actuator")
        assert actuator is not None and actuator.get("name") == f"{joint}_motor"
        assert float(t.findtext("actuator/mechanicalReduction") or "nan") == 1.0


def _hull_points(link: yourdfpy.Link) -> np.ndarray:
    """Points (n, 3) whose hull lies inside the link's collision geometry [m]."""
    pts = []
    for col in link.collisions:
        g = col.geometry
        if g.box is not None:
            h = 0.5 * np.asarray(g.box.size)
            local = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)]) * h
        else:
            assert g.cylinder is not None, f"{link.name}: only boxes and cylinders expected"
            t = np.linspace(0, 2 * np.pi, 16, endpoint=False)
            r, half = g.cylinder.radius, 0.5 * g.cylinder.length
            ring = np.stack([r * np.cos(t), r * np.sin(t)], axis=1)
            local = np.vstack([np.c_[ring, np.full(16, s * half)] for s in (-1, 1)])
        pts.append(local @ col.origin[:3, :3].T + col.origin[:3, 3])
    return np.vstack(pts)


@pytest.mark.parametrize("name", ["base", *STAGES])
def test_inertia_consistent_and_com_inside(robot: yourdfpy.URDF, name: str) -> None:
    link = next(link for link in robot.robot.links if link.name == name)
    inertial = link.inertial
    assert inertial is not None and link.collisions and link.visuals
    assert np.allclose(inertial.origin[:3, :3], np.eye(3)), "inertial rpy must be 0 0 0"
    com, mass, inertia = inertial.origin[:3, 3], float(inertial.mass), np.asarray(inertial.inertia)
    if name != "base":
        assert np.all(np.abs(inertia[np.triu_indices(3, 1)]) > 0), "full tensor expected"
        assert np.linalg.norm(com) > 1e-3, "CoM offset from the link origin expected"
    moments = np.linalg.eigvalsh(inertia)
    assert moments.min() > 0
    assert moments[0] + moments[1] > moments[2]
    sigma = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    pseudo = np.block([[sigma + mass * np.outer(com, com), mass * com[:, None]],
                       [mass * com[None, :], np.array([[mass]])]])  # fmt: skip
    assert np.linalg.eigvalsh(pseudo).min() > 0
    hull = ConvexHull(_hull_points(link))
    assert np.all(hull.equations[:, :3] @ com + hull.equations[:, 3] < -1e-4), "CoM outside"


def test_masses_match_seed_report(robot: yourdfpy.URDF) -> None:
    masses = {link.name: link.inertial.mass for link in robot.robot.links if link.inertial}
    assert set(masses) == {"base", *STAGES}
    assert masses["x_stage"] == pytest.approx(1.67, rel=0.05)
    assert masses["z_stage"] == pytest.approx(0.136, rel=0.05)
    assert 10 < masses["base"] < 100
    assert 0.3 < masses["y_stage"] < 1.67


def test_linearisation_stable_and_modes(linear: dict[str, np.ndarray]) -> None:
    m, k, d = linear["M"], linear["K"], linear["D"]
    nv = m.shape[0]
    assert np.linalg.eigvalsh(m).min() > 0
    free = [i for i in range(nv) if i not in linear["idx"][:2]]
    assert np.linalg.eigvalsh(k[np.ix_(free, free)]).min() > 1.0
    a = np.block([[np.zeros((nv, nv)), np.eye(nv)],
                  [-np.linalg.solve(m, k), -np.linalg.solve(m, d)]])  # fmt: skip
    lam = np.linalg.eigvals(a)
    assert lam.real.max() < 1e-9
    osc = lam[lam.imag > 1e-6]
    f_hz = np.sort(np.abs(osc)) / (2 * np.pi)
    zeta = -osc.real / np.abs(osc)
    assert len(f_hz) == 9  # bond-arm spring mode + 8 parasitic modes
    assert 8 < f_hz[0] < 20  # bond arm on its return spring (seed report's ~12 Hz bump)
    assert np.all((f_hz[1:] > 200) & (f_hz[1:] < 3000))
    assert np.all((zeta > 0.002) & (zeta < 0.2))


def test_receptance_looks_like_a_bonder(
    linear: dict[str, np.ndarray], robot: yourdfpy.URDF
) -> None:
    f = np.logspace(0, np.log10(4000), 2000)
    h = _frf(linear, f)
    w2 = (2 * np.pi * f) ** 2
    band = (f > 150) & (f < 3000)
    m = {link.name: link.inertial.mass for link in robot.robot.links if link.inertial}
    # low-frequency known answers: mass lines of x and y, spring line of the bond arm
    at5 = np.argmin(np.abs(f - 5.0))
    assert np.abs(h[0, 0, at5]) * w2[at5] * (m["x_stage"] + m["y_stage"] + m["z_stage"]) == (
        pytest.approx(1.0, rel=0.01)
    )
    assert np.abs(h[1, 1, at5]) * w2[at5] * (m["y_stage"] + m["z_stage"]) == (
        pytest.approx(1.0, rel=0.01)
    )
    assert np.abs(h[2, 2, 0]) * 1.4429 == pytest.approx(1.0, rel=0.05)
    for i in range(3):
        # mass line: |H_ii| w^2 flat at high frequency except near parasitic modes
        level = 20 * np.log10(np.abs(h[i, i]) * w2)
        assert np.ptp(level[band]) > 6, f"no resonance/anti-resonance pair on diagonal {i}"
        for j in range(i + 1, 3):
            coupling = np.abs(h[i, j]) / np.sqrt(np.abs(h[i, i] * h[j, j]))
            db = 20 * np.log10(coupling)
            assert np.allclose(h[i, j], h[j, i])  # reciprocity (collocated B = C^T)
            assert np.median(db) < -20 and db.min() > -200, (i, j)
