"""Linearisation against Pinocchio's own algorithms, and the affine structure."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from models import random_pose, sprung_robot

from bondid.linear import build_affine_model
from bondid.linear.parameter_map import ParameterMap
from bondid.model import select_parameters, set_parameter

ROBOTS = ["ur5", "panda"]
TOL_EXACT = 1e-12  # relative, "exact to round-off"


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request):
    doc = sprung_robot(request.param)
    op = random_pose(doc)
    return doc, op, build_affine_model(doc, op)


def _rel(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


def test_mass_matrix_matches_crba(robot):
    doc, _op, am = robot
    model = doc.build_pinocchio_model()
    data = model.createData()
    M = pin.crba(model, data, am.q0)
    M = np.triu(M) + np.triu(M, 1).T
    assert _rel(am.mass_matrix(), M) < TOL_EXACT
    # every massive moving link is parameterised: nothing left outside the basis
    assert np.abs(am.M_rest).max() < TOL_EXACT * np.abs(M).max()


def test_gravity_stiffness_matches_pinocchio(robot):
    doc, _op, am = robot
    model = doc.build_pinocchio_model()
    data = model.createData()
    G = pin.computeGeneralizedGravityDerivatives(model, data, am.q0)
    assert _rel(am.stiffness_matrix() - np.diag(am.stiffness), G) < 1e-12
    assert np.abs(am.G_rest).max() < 1e-12 * np.abs(G).max()


def test_state_matrix_matches_aba_derivatives(robot):
    """[[0, I], [−M⁻¹K, −M⁻¹D]] against computeABADerivatives with springs and dampers as
    joint torques τ(q, v) = g(q0) − K_s (q − q_ref) − D v (so q̈ = 0 at the operating point)."""
    doc, _op, am = robot
    model = doc.build_pinocchio_model()
    data = model.createData()
    q0 = am.q0
    v0 = np.zeros(model.nv)
    tau = pin.computeGeneralizedGravity(model, data, q0).copy()
    ddq_dq, ddq_dv, Minv = pin.computeABADerivatives(model, data, q0, v0, tau)
    Ks, Ds = np.diag(am.stiffness), np.diag(am.damping)
    A_q = ddq_dq - Minv @ Ks  # chain rule: dτ/dq = −K_s
    A_v = ddq_dv - Minv @ Ds
    A, _, _, _ = am.linear_model().state_space()
    n = model.nv
    assert _rel(A[n:, :n], A_q) < 1e-10
    assert _rel(A[n:, n:], A_v) < 1e-10
    np.testing.assert_array_equal(A[:n, n:], np.eye(n))


def test_affine_structure_exact_after_parameter_change(robot):
    """Change every inertial parameter by a few %: the affine model at the mapped π must
    equal a fresh Pinocchio linearisation of the edited URDF."""
    doc, op, am = robot
    names = select_parameters(doc, ["inertial", "joints"])
    pmap = ParameterMap(doc, am, names)
    rng = np.random.default_rng(3)
    p = pmap.p0.copy()
    is_mass = np.array([n.endswith(".mass") for n in names])
    p[is_mass] *= 1 + 0.05 * rng.standard_normal(is_mass.sum())
    edited = doc.copy()
    for n, v in zip(names, p, strict=True):
        set_parameter(edited, n, v)
    fresh = build_affine_model(edited, op)
    mapped = am.with_values(*pmap.values(p))
    assert _rel(mapped.mass_matrix(), fresh.mass_matrix()) < TOL_EXACT
    assert _rel(mapped.stiffness_matrix(), fresh.stiffness_matrix()) < 1e-11


def test_parameter_map_jacobian_matches_finite_differences(robot):
    doc, _op, am = robot
    names = select_parameters(doc, ["all"])
    pmap = ParameterMap(doc, am, names)
    p0 = pmap.p0
    dpi, dk, dd = pmap.jacobian(p0)
    for col in range(len(names)):
        h = 1e-6 * max(1.0, abs(p0[col]))
        up, dn = p0.copy(), p0.copy()
        up[col] += h
        dn[col] -= h
        fd = [(a - b) / (2 * h) for a, b in zip(pmap.values(up), pmap.values(dn), strict=True)]
        np.testing.assert_allclose(dpi[..., col], fd[0], atol=1e-7 * max(1, np.abs(fd[0]).max()))
        np.testing.assert_allclose(dk[:, col], fd[1], atol=1e-9)
        np.testing.assert_allclose(dd[:, col], fd[2], atol=1e-9)


def test_operating_point_with_unknown_joint_is_rejected(robot):
    from bondid.exceptions import OperatingPointError

    doc, _, _ = robot
    with pytest.raises(OperatingPointError, match="nonexistent"):
        build_affine_model(doc, {"nonexistent": 0.1})


def test_mimic_reduction_is_the_congruence_on_every_leading_axis():
    """``reduce_matrices`` gives ``Tᵀ X T`` slice by slice for a matrix and for stacks with
    one and two leading axes (the parameter bases ``(nb, 10, n, n)``)."""
    from bondid.linear.mimic import Coupling, reduce_matrices, reduction

    dofs = ("a", "b", "c", "d")
    T, red = reduction(dofs, {"c": Coupling("a", 0.37), "d": Coupling("b", -1.4)})
    assert red == ("a", "b") and T.shape == (4, 2)
    rng = np.random.default_rng(3)
    mats = {"m": rng.standard_normal((4, 4)), "s": rng.standard_normal((5, 4, 4)),
            "b": rng.standard_normal((2, 3, 4, 4))}  # fmt: skip
    out = reduce_matrices(T, mats)
    for k, X in mats.items():
        flat = X.reshape(-1, 4, 4)
        want = np.stack([T.T @ x @ T for x in flat]).reshape(*X.shape[:-2], 2, 2)
        assert out[k].shape == want.shape
        assert _rel(out[k], want) < TOL_EXACT
