"""Tests of bondid.consistency: Pinocchio as the reference, round trips and known answers."""

from __future__ import annotations

import os
from types import SimpleNamespace

import casadi
import numpy as np
import pinocchio as pin
import pytest
import trimesh
import yourdfpy

from bondid.consistency import (
    Hull,
    consistency_report,
    hull_from_points,
    is_consistent,
    is_feasible,
    jacobian_pi_theta,
    link_hull,
    make_resolver,
    pi_from_pseudo_inertia,
    pi_from_theta,
    pi_from_theta_casadi,
    pi_from_urdf,
    project_feasible,
    pseudo_inertia,
    theta_from_pi,
    urdf_from_pi,
)
from bondid.exceptions import ComputationError, ModelError, ParameterError

RNG_SEED = 20261101


def _thetas(n: int = 8) -> np.ndarray:
    return np.random.default_rng(RNG_SEED).normal(scale=0.8, size=(n, 10))


def _random_pis(n: int = 8) -> list[np.ndarray]:
    """Physically consistent bodies (Pinocchio's Inertia.Random() can violate the triangle
    inequality): random m, c and second moment about the CoM Σ_c = B Bᵀ ≻ 0."""
    rng = np.random.default_rng(RNG_SEED)
    out = []
    for _ in range(n):
        B = rng.normal(scale=0.1, size=(3, 3))
        sigma_c = B @ B.T
        inertia_c = np.trace(sigma_c) * np.eye(3) - sigma_c
        m, c = rng.uniform(0.1, 5.0), rng.normal(scale=0.3, size=3)
        out.append(pin.Inertia(m, c, inertia_c).toDynamicParameters())
    return out


# --------------------------------------------------------------------------- pseudo-inertia


def test_pseudo_inertia_matches_pinocchio_and_inverts() -> None:
    pin.seed(RNG_SEED)
    for pi in [*_random_pis(), pin.Inertia.Random().toDynamicParameters()]:
        J = pseudo_inertia(pi)
        J_pin = pin.PseudoInertia.FromDynamicParameters(pi).toMatrix()
        np.testing.assert_allclose(J, J_pin, atol=1e-12)
        np.testing.assert_allclose(pi_from_pseudo_inertia(J), pi, atol=1e-12)


def test_urdf_form_matches_pinocchio_and_round_trips() -> None:
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(5):
        m = rng.uniform(0.1, 5.0)
        c = rng.normal(scale=0.3, size=3)
        R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        inertia_c = R @ np.diag(rng.uniform(0.01, 0.1, size=3)) @ R.T
        pi = pi_from_urdf(m, c, inertia_c)
        np.testing.assert_allclose(
            pi, pin.Inertia(m, c, inertia_c).toDynamicParameters(), atol=1e-13
        )
        m2, c2, inertia_c2 = urdf_from_pi(pi)
        assert m2 == pytest.approx(m, rel=1e-15)
        np.testing.assert_allclose(c2, c, atol=1e-14)
        np.testing.assert_allclose(inertia_c2, inertia_c, atol=1e-14)


def test_consistency_detects_mass_and_triangle_inequality() -> None:
    for pi in _random_pis():
        assert is_consistent(pi)
        assert "physically consistent" in consistency_report(pi)
    # Principal moments 1, 1, 3: 1 + 1 < 3 violates the triangle inequality, I_c still ≻ 0.
    bad = pi_from_urdf(2.0, [0.1, 0.0, 0.0], np.diag([1.0, 1.0, 3.0]))
    assert not is_consistent(bad)
    assert np.min(np.linalg.eigvalsh(pseudo_inertia(bad))) < 0.0
    report = consistency_report(bad, name="wrist")
    assert "triangle inequality" in report and "'wrist'" in report
    assert "positive definite" not in report.split("not consistent")[1]
    neg_mass = np.array(bad)
    neg_mass[0] = -1.0
    assert not is_consistent(neg_mass)
    assert "mass" in consistency_report(neg_mass)
    indefinite = pi_from_urdf(1.0, np.zeros(3), np.diag([-0.1, 1.0, 1.0]))
    assert "not positive definite" in consistency_report(indefinite)
    # Boundary: a point mass (J of rank 1) is not strictly consistent.
    assert not is_consistent(pi_from_urdf(1.0, [0.2, 0.0, 0.0], np.zeros((3, 3))))


# --------------------------------------------------------------------------- log-Cholesky


def test_theta_ordering_follows_pinocchio() -> None:
    # s12 -> Ixy, s23 -> Iyz, s13 -> Ixz (Pinocchio's order, as in verified-facts).
    for k, entry in ((4, 5), (5, 8), (6, 7)):
        theta = np.zeros(10)
        theta[k] = 0.3
        pi_pin = pin.LogCholeskyParameters(theta).toDynamicParameters()
        assert pi_pin[entry] == pytest.approx(-0.3, abs=1e-15)
        np.testing.assert_allclose(pi_from_theta(theta), pi_pin, atol=1e-15)


def test_log_cholesky_matches_pinocchio() -> None:
    for theta in _thetas():
        lc = pin.LogCholeskyParameters(theta)
        pi_ref = lc.toDynamicParameters()
        scale = np.max(np.abs(pi_ref))
        np.testing.assert_allclose(pi_from_theta(theta), pi_ref, rtol=0, atol=1e-10 * scale)
        np.testing.assert_allclose(
            jacobian_pi_theta(theta), lc.calculateJacobian(), rtol=0, atol=1e-10 * scale
        )
        # J = U Uᵀ ≻ 0 for every θ.
        assert is_consistent(pi_from_theta(theta))


def test_theta_round_trips() -> None:
    for theta in _thetas(20):
        np.testing.assert_allclose(theta_from_pi(pi_from_theta(theta)), theta, atol=1e-9)
    for pi in _random_pis():
        np.testing.assert_allclose(pi_from_theta(theta_from_pi(pi)), pi, atol=1e-12)
        theta = theta_from_pi(pi)
        np.testing.assert_allclose(theta[7:], pi[1:4] / pi[0], atol=1e-13)  # c = t
        assert np.exp(2 * theta[0]) == pytest.approx(pi[0], rel=1e-13)  # m = e^{2α}


def test_theta_from_pi_rejects_inconsistent_body() -> None:
    bad = pi_from_urdf(2.0, [0.1, 0.0, 0.0], np.diag([1.0, 1.0, 3.0]))
    with pytest.raises(ParameterError, match=r"'wrist_3_link'.*triangle"):
        theta_from_pi(bad, name="wrist_3_link")


@pytest.mark.parametrize("sym", [casadi.SX, casadi.MX])
def test_casadi_map_matches_numpy_and_jacobians(sym: type) -> None:
    x = sym.sym("theta", 10)
    expr = pi_from_theta_casadi(x)
    assert expr.shape == (10, 1)
    f = casadi.Function("f", [x], [expr, casadi.jacobian(expr, x)])
    h = 1e-6
    for theta in _thetas(4):
        value, jac = (np.array(v) for v in f(theta))
        np.testing.assert_allclose(value.ravel(), pi_from_theta(theta), rtol=0, atol=1e-12)
        jac_ref = jacobian_pi_theta(theta)
        np.testing.assert_allclose(jac, jac_ref, rtol=0, atol=1e-11 * np.max(np.abs(jac_ref)))
        fd = np.column_stack(
            [
                (pi_from_theta(theta + h * e) - pi_from_theta(theta - h * e)) / (2 * h)
                for e in np.eye(10)
            ]
        )
        np.testing.assert_allclose(jac, fd, rtol=0, atol=1e-7 * np.max(np.abs(jac_ref)))


# --------------------------------------------------------------------------- hulls


def _element(origin: np.ndarray | None = None, **geometry: object) -> SimpleNamespace:
    fields = {"box": None, "cylinder": None, "sphere": None, "mesh": None, **geometry}
    return SimpleNamespace(origin=origin, geometry=yourdfpy.Geometry(**fields))


def _pose(xyz: list[float], rpy: list[float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = pin.rpy.rpyToMatrix(np.asarray(rpy, dtype=float))
    T[:3, 3] = xyz
    return T


def test_box_hull_is_exact() -> None:
    T = _pose([0.1, -0.2, 0.3], [0.3, -0.5, 1.1])
    hull = link_hull([_element(T, box=yourdfpy.Box(size=np.array([0.2, 0.4, 0.6])))])
    assert hull is not None
    assert hull.A.shape == (6, 3) and hull.b.shape == (6,) and hull.vertices.shape == (8, 3)
    np.testing.assert_allclose(np.linalg.norm(hull.A, axis=1), 1.0, atol=1e-14)
    centre = T[:3, 3]
    assert hull.contains(centre)
    assert hull.distance(centre) == pytest.approx(0.1, abs=1e-12)  # half the thinnest side
    outside = centre + T[:3, :3] @ np.array([0.0, 0.5, 0.0])  # 0.3 beyond the ±0.2 face
    assert not hull.contains(outside)
    assert hull.distance(outside) == pytest.approx(-0.3, abs=1e-12)
    corner = centre + T[:3, :3] @ np.array([0.2, 0.3, 0.4])  # beyond the (+,+,+) corner
    np.testing.assert_allclose(hull.nearest_point(corner), centre + T[:3, :3] @ [0.1, 0.2, 0.3])
    pts = np.array([centre, outside])
    np.testing.assert_array_equal(hull.contains(pts), [True, False])
    assert hull.contains(centre, margin=0.099) and not hull.contains(centre, margin=0.101)


@pytest.mark.parametrize("n_sides", [6, 24])
def test_cylinder_and_sphere_hulls_are_inscribed(n_sides: int) -> None:
    r, length = 0.05, 0.2
    T = _pose([0.0, 0.1, 0.0], [np.pi / 2, 0.0, 0.0])
    cyl = link_hull(
        [_element(T, cylinder=yourdfpy.Cylinder(radius=r, length=length))], n_sides=n_sides
    )
    assert cyl is not None
    rng = np.random.default_rng(RNG_SEED)
    pts = rng.uniform(-0.1, 0.1, size=(20000, 3)) + T[:3, 3]
    local = (pts - T[:3, 3]) @ T[:3, :3]  # cylinder frame: axis z
    in_hull = cyl.contains(pts)
    in_cyl = (np.hypot(local[:, 0], local[:, 1]) <= r) & (np.abs(local[:, 2]) <= length / 2)
    assert in_hull.sum() > 0.5 * in_cyl.sum()
    assert not np.any(in_hull & ~in_cyl)  # conservative: hull ⊂ cylinder
    local_v = (cyl.vertices - T[:3, 3]) @ T[:3, :3]
    np.testing.assert_allclose(np.hypot(local_v[:, 0], local_v[:, 1]), r, rtol=1e-12)
    assert cyl.A.shape[0] == n_sides + 2  # side faces plus both caps, coplanar facets merged

    sph = link_hull([_element(None, sphere=yourdfpy.Sphere(radius=r))], n_sides=n_sides)
    assert sph is not None
    np.testing.assert_allclose(np.linalg.norm(sph.vertices, axis=1), r, rtol=1e-12)
    assert sph.contains(np.zeros(3)) and not sph.contains([0.0, 0.0, 1.001 * r])


def test_mesh_hull_scale_and_fallbacks(tmp_path: object) -> None:
    path = os.path.join(str(tmp_path), "cube.stl")
    trimesh.creation.box(extents=[1.0, 1.0, 1.0]).export(path)
    mesh = yourdfpy.Mesh(filename="package://demo/cube.stl", scale=np.array([0.2, 0.1, 0.1]))
    resolve = make_resolver(str(tmp_path), {"demo": str(tmp_path)})
    visual_only = yourdfpy.Link(name="l", visuals=[_element(None, mesh=mesh)], collisions=[])
    hull = link_hull(visual_only, resolve)  # no collision element -> visuals
    assert hull is not None
    np.testing.assert_allclose(np.ptp(hull.vertices, axis=0), [0.2, 0.1, 0.1], atol=1e-12)
    assert hull.A.shape == (6, 3)
    assert link_hull(yourdfpy.Link(name="empty")) is None
    with pytest.raises(ModelError, match="resolve"):
        link_hull(visual_only)
    with pytest.raises(ModelError, match="not a file"):
        link_hull(visual_only, lambda f: os.path.join(str(tmp_path), "missing.stl"))
    with pytest.raises(ModelError, match="flat"):
        hull_from_points([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], name="plate")


def test_shrunk_hull() -> None:
    hull = hull_from_points(np.array(np.meshgrid([0, 1], [0, 2], [0, 3])).reshape(3, -1).T)
    small = hull.shrunk(0.25)
    np.testing.assert_allclose(np.ptp(small.vertices, axis=0), [0.5, 1.5, 2.5], atol=1e-12)
    assert small.distance([0.5, 1.0, 1.5]) == pytest.approx(0.25, abs=1e-12)
    with pytest.raises(ComputationError, match="empty"):
        hull.shrunk(0.6)


# --------------------------------------------------------------------------- projection


@pytest.fixture(scope="module")
def ur5() -> tuple[pin.Model, dict[str, Hull | None]]:
    import example_robot_data
    from example_robot_data.robots_loader import UR5Loader, getModelPath

    robots = getModelPath(UR5Loader.path)  # .../share/example-robot-data/robots
    urdf = os.path.join(robots, UR5Loader.path, "urdf", UR5Loader.urdf_filename)
    resolve = make_resolver(
        os.path.dirname(urdf), {"example-robot-data": os.path.dirname(os.path.abspath(robots))}
    )
    model = example_robot_data.load("ur5").model
    robot = yourdfpy.URDF.load(urdf, build_scene_graph=False, load_meshes=False).robot
    links = {link.name: link for link in robot.links}
    child_of = {joint.name: joint.child for joint in robot.joints}
    hulls = {
        model.names[j]: link_hull(links[child_of[model.names[j]]], resolve)
        for j in range(1, model.njoints)
    }
    return model, hulls


def test_ur5_wrist_projection(ur5: tuple[pin.Model, dict[str, Hull | None]]) -> None:
    model, hulls = ur5
    moved = []
    for j in range(1, model.njoints):
        joint = model.names[j]
        hull = hulls[joint]
        assert hull is not None
        pi = model.inertias[j].toDynamicParameters()
        assert is_consistent(pi)
        out = project_feasible(pi, hull, name=joint)
        assert is_feasible(out, hull) and is_consistent(out)
        assert np.array_equal(project_feasible(out, hull), out)  # idempotent
        m, c, inertia_c = urdf_from_pi(pi)
        m2, c2, inertia_c2 = urdf_from_pi(out)
        assert m2 == m
        np.testing.assert_allclose(inertia_c2, inertia_c, atol=1e-15)  # consistent: kept
        margin = 1e-3 * hull.size
        assert hull.distance(c2) >= margin * (1 - 1e-6)
        if hull.distance(c) < 0:
            moved.append(joint)
            # The new CoM is the nearest point of the shrunk hull: no hull point is closer.
            gap = np.linalg.norm(c2 - c)
            assert gap == pytest.approx(-hull.distance(c) + margin, abs=0.2 * margin)
            assert gap < 0.06
        else:
            np.testing.assert_array_equal(out, pi)  # identity on feasible inputs
    assert moved == ["wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]


def test_projection_fixes_triangle_inequality() -> None:
    c = np.array([0.1, -0.05, 0.02])
    bad = pi_from_urdf(2.0, c, np.diag([1.0, 1.0, 3.0]))
    assert not is_consistent(bad) and not is_feasible(bad)
    out = project_feasible(bad)
    assert is_consistent(out) and is_feasible(out)
    m, c2, inertia_c = urdf_from_pi(out)
    assert m == 2.0
    np.testing.assert_allclose(c2, c, atol=1e-15)
    # σ = (1.5, 1.5, -0.5): σ_z clipped to the floor 1e-6 · 1.5, so I_c = diag(1.5 + f, 1.5 + f, 3).
    f = 1e-6 * 1.5
    np.testing.assert_allclose(inertia_c, np.diag([1.5 + f, 1.5 + f, 3.0]), atol=1e-12)
    with pytest.raises(ParameterError, match="mass"):
        project_feasible(pi_from_urdf(0.0, np.zeros(3), np.eye(3)), name="b")


def test_projection_moves_com_into_box_and_keeps_feasible_input() -> None:
    box = hull_from_points(np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T)
    inertia_c = np.diag([0.2, 0.3, 0.4])
    inside = pi_from_urdf(1.5, [0.3, 0.2, -0.1], inertia_c)
    np.testing.assert_array_equal(project_feasible(inside, box), inside)
    outside = pi_from_urdf(1.5, [2.0, 0.5, -3.0], inertia_c)
    out = project_feasible(outside, box, margin_rel=0.01)
    margin = 0.01 * np.sqrt(12.0)
    _, c2, inertia_c2 = urdf_from_pi(out)
    np.testing.assert_allclose(c2, [1 - margin, 0.5, -1 + margin], atol=1e-12)
    np.testing.assert_allclose(inertia_c2, inertia_c, atol=1e-14)
